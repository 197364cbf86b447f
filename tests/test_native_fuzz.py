"""The native FMU under AddressSanitizer and UndefinedBehaviorSanitizer, fed random FMI call sequences
(tests/fmi2_fuzz.c, compiled here with the FMU's and the C runtime's sources): calls out of state, unknown
and mistyped references, NaN/inf/huge values, non-rotations, absurd steps and times, states moved between
instances, damaged serialized states, derivatives of anything. No sanitizer report, no leak, no crash, no
status outside fmi2OK..fmi2Error; and the sequences reach stepping, state restores and derivatives (the
counts say so, or the fuzzing proved nothing)."""
from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest
from fmpy import extract, read_model_description

from ffrf_fmu.fmu.builder import build_fmu
from ffrf_fmu.fmu.native import build as native_build

ROOT = Path(__file__).resolve().parent.parent
SCENES = """
[scenes.still]
duration = 0.2
step = 0.01
"""


@pytest.fixture(scope="module")
def fuzz(tmp_path_factory, beam_toml):
    d = tmp_path_factory.mktemp("fuzz")
    (d / "beam.toml").write_text(beam_toml(SCENES, name="fuzz_beam", superelements=1))
    fmu = build_fmu(d / "beam.toml", d / "beam.fmu", scene="still")
    unzip = Path(extract(str(fmu), str(d / "beam")))
    cc = os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")
    exe = d / "fmi2_fuzz"
    cmd = [cc, "-std=c11", "-O1", "-g", "-fsanitize=address,undefined", "-fno-sanitize-recover=undefined",
           "-fno-omit-frame-pointer", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror",
           f"-I{native_build.RUNTIME}", f"-I{native_build.HERE}", *map(str, native_build.sources()),
           str(ROOT / "tests" / "fmi2_fuzz.c"), "-lm", "-o", str(exe)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    return exe, unzip, read_model_description(str(fmu))


def test_random_call_sequences_under_the_sanitizers(fuzz):
    exe, unzip, md = fuzz
    inputs = ",".join(str(v.valueReference) for v in md.modelVariables if v.causality == "input")
    outputs = ",".join(str(v.valueReference) for v in md.modelVariables if v.causality == "output" and v.type == "Real")
    totals = {}
    env = {**os.environ, "ASAN_OPTIONS": "detect_leaks=1:abort_on_error=0", "UBSAN_OPTIONS": "print_stacktrace=1"}
    for seed in range(1, 5):
        done = subprocess.run([str(exe), (unzip / "resources").as_uri(), md.guid, str(seed), "1500", inputs, outputs],
                              capture_output=True, text=True, timeout=900, env=env)
        assert done.returncode == 0, f"seed {seed}: exit {done.returncode}\n{done.stderr[-4000:]}"
        assert "runtime error" not in done.stderr and "Sanitizer" not in done.stderr, done.stderr[-4000:]
        words = done.stdout.split()
        for key, value in zip(words[::2], words[1::2]):
            totals[key] = totals.get(key, 0) + int(value)
    assert totals["steps_ok"] > 100 and totals["restored_ok"] > 10 and totals["derivatives_ok"] > 0, totals
    assert totals["discard"] > 0 and totals["error"] > 0, totals
