"""The `ffrf-fmu` command end to end, through `python -m ffrf_fmu` as a user would run it."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ffrf_fmu.model import load_model

ROOT = Path(__file__).resolve().parent.parent


def run(*args):
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.run([sys.executable, "-m", "ffrf_fmu", *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)


# First bending frequency of the body with its motion-driven port parts fixed, against the
# closed forms of docs/background.md: B1 cantilever (hub clamped) 0.4640 Hz, B2
# hinged-free (root on the spherical joint) 1.7435 Hz, both Euler-Bernoulli. 0.5 % covers what
# the model adds to the closed form: shear flexibility and rotary inertia (B1's are small: the
# beam is slender) and the modal truncation of 6 modes per superelement.
def test_info_prints_a_solid_s_reduction_quality():
    """`info` on a solid prints the reduction quality report (reduction_quality.py): frequencies with MAC, and the
    effective mass clamped at each port, the full FE model's beside the reduced body's."""
    out = run("info", "models/haug_solid.toml")
    assert out.returncode == 0, out.stderr
    assert "full -> reduced [Hz] (MAC)" in out.stdout
    lines = out.stdout.splitlines()
    head = next(i for i, s in enumerate(lines) if "effective mass clamped at a port" in s and "full FE model / reduced" in s)
    for port, line in zip(("hub", "tip"), lines[head + 1 : head + 3]):
        pairs = [tuple(map(float, p.split("/"))) for p in line.split(":")[1].split()]
        assert line.strip().startswith(port) and len(pairs) == 6 and all(0 <= a <= 1 and 0 <= b <= 1 for a, b in pairs)


@pytest.mark.parametrize("model, first_hz", [("haug_beam.toml", 0.4640), ("spherical_beam.toml", 1.7435)])
def test_info_json(model, first_hz):
    out = run("info", f"models/{model}", "--json")
    assert out.returncode == 0, out.stderr
    info = json.loads(out.stdout)
    body = load_model(ROOT / "models" / model).body
    # one entry per superelement of the model file, each with the file's modes on its own FE mesh
    assert len(info["superelements"]) == body.superelements >= 1
    for se in info["superelements"]:
        assert se["orthogonality_error"] < 1e-10  # U^T M Y = 0 (eq. 74) to round-off
        assert se["n_modes"] == body.modes
        assert se["n_fe_dofs"] == 6 * (body.elements_per_superelement + 1)
        assert se["n_reduced_dofs"] == 12 + body.modes
    assert info["frequencies_hz"][0] == pytest.approx(first_hz, rel=5e-3)


def test_info_text():
    out = run("info", "models/haug_beam.toml", "--scene", "hub_free", "--set", "superelements=2")
    assert out.returncode == 0, out.stderr
    assert "2 superelements x 8 elements" in out.stdout
    assert "port hub: node 0, translation motion, rotation force" in out.stdout


def test_bad_file_exits_2_with_message(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text((ROOT / "models" / "haug_beam.toml").read_text().replace("EI2 = 566.0", "EI2 = -566.0"))
    out = run("info", str(bad))
    assert out.returncode == 2
    assert out.stderr.startswith(f"ffrf-fmu: error: {bad}: body.section.EI2: expected a positive")
    assert "Traceback" not in out.stderr

    out = run("info", str(tmp_path / "missing.toml"))
    assert out.returncode == 2 and "ffrf-fmu: error:" in out.stderr and "Traceback" not in out.stderr


def test_every_command_is_in_cli_and_build_fmu_is_build():
    """All argparse code is in cli/: build, validate and the reference's convergence study are
    subcommands, and build_fmu.py is `build` under its own name."""
    from ffrf_fmu.cli import build_parser, command_parser

    commands = set(build_parser()._subparsers._group_actions[0].choices)
    assert {"info", "simulate", "build", "validate", "chart", "study", "advise", "stability", "convergence"} <= commands
    args = command_parser("build", prog="build_fmu.py").parse_args(["m.toml", "-o", "B.fmu"])
    assert (args.model, args.output, args.run.__name__) == ("m.toml", "B.fmu", "build")


def test_convergence_command_prints_the_study():
    """`ffrf-fmu convergence` on one coarse run (4 elements, 50 ms): B1's maximum transverse tip
    deflection within 2 % of ODIN's 16-element 0.5333 m (measured 0.53206 m, -0.23 %)."""
    out = run("convergence", "--elements", "4", "--steps", "0.05")
    assert out.returncode == 0, out.stderr
    row = next(line.split() for line in out.stdout.splitlines() if line.split()[:2] == ["4", "0.05"])
    assert float(row[2]) == pytest.approx(0.5333, rel=0.02)


# imported by no `ffrf-fmu simulate` of a beam whose reduced body is cached and whose C runtime is compiled:
# scipy (the reduction's), numpy.ma (np.unique and np.setdiff1d import it), the email package (importlib.metadata
# parses distributions' METADATA with it), difflib (a misspelt key's suggestion), subprocess and tempfile (a
# compile of the runtime, a cache that cannot be written)
NOT_ON_THE_SIMULATE_PATH = ("scipy", "numpy.ma", "email", "importlib.metadata", "difflib", "subprocess", "tempfile")


def test_simulate_of_a_cached_beam_imports_only_what_it_runs(tmp_path):
    """The second of two `ffrf-fmu simulate` runs of B1 (the first compiles the C runtime and caches the
    body where they are missing) imports none of NOT_ON_THE_SIMULATE_PATH; the first one's list shows the
    check sees an import (it compiles or reduces in a fresh cache: subprocess, scipy)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "FFRF_FMU_CACHE_DIR": str(tmp_path)}
    code = ("import runpy, sys\nsys.argv = ['ffrf-fmu', 'simulate', 'models/haug_beam.toml', '--set', 'duration=0.2']\n"
            "try:\n    runpy.run_module('ffrf_fmu', run_name='__main__')\nexcept SystemExit as e:\n    assert not e.code\n"
            f"print(sorted(m for m in {NOT_ON_THE_SIMULATE_PATH!r} if m in sys.modules), file=sys.stderr)\n")
    runs = [subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True,
                           timeout=300) for _ in range(2)]
    assert all(r.returncode == 0 for r in runs), runs[0].stderr + runs[1].stderr
    assert "'scipy'" in runs[0].stderr.splitlines()[-1]
    assert runs[1].stderr.splitlines()[-1] == "[]", runs[1].stderr
