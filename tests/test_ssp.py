"""SSP 1.0 packages (ffrf_fmu/master/ssp.py): the compliant B5 (beam FMU with the shaft in its hub
port, hub drive FMU; docs/cosim.md) written once as a .ssp and run by our master, libcosim and
ecos from that one file; the three run Jacobi with held inputs, the same discrete map, so they
must agree to round-off."""
from __future__ import annotations

import zipfile
from pathlib import Path

import libcosimpy.CosimExecution  # noqa: F401 - the engines are core test dependencies: a broken install fails
import numpy as np
import pytest

from ffrf_fmu.master import ssp

MODELS = Path(__file__).resolve().parent.parent / "models"
H, SPAN = 0.01, 0.5  # 50 steps: the beam starts to turn (shaft moment 0.10 N m, root rate 2.9e-3 rad/s at 0.5 s); equality is the claim


@pytest.fixture(scope="module")
def package(tmp_path_factory):
    from ffrf_fmu.studies.stability import CosimSettings, compliant_b5

    settings = CosimSettings()
    d = tmp_path_factory.mktemp("ssp")
    b5 = compliant_b5.build(MODELS / "haug_beam.toml", d, settings)
    system = compliant_b5.system(b5, settings, H, SPAN)
    return ssp.write_ssp(d / "b5_compliant.ssp", system), system, b5


def test_package_holds_the_system_and_reads_back(package, tmp_path):
    path, system, _ = package
    with zipfile.ZipFile(path) as z:
        names = set(z.namelist())
    assert names == {ssp.SSD, "resources/beam.fmu", "resources/drive.fmu"}
    back = ssp.read_ssp(path, tmp_path)
    assert back.connections == system.connections
    assert back.parameters == system.parameters
    assert back.parameters["beam.hub.coupling.k_rot[3]"] == 300.0  # the shaft stiffness travels with the package
    assert (back.step, back.start, back.stop) == (H, 0.0, SPAN)
    assert any(c.factor == -1.0 for c in back.connections)  # the shaft moment's reaction, a LinearTransformation


def test_the_three_engines_run_the_package_to_round_off(package, tmp_path):
    """Master, libcosim and ecos from the same file: tip deflection, hub speed and shaft torque
    equal to 1e-9 of their peaks (measured: libcosim 0 and ecos 2.4e-15 on the torque; rotation
    entries at round-off level, 1e-23, differ in their last bits, which is why the quantities,
    not the raw entries, are compared)."""
    from ffrf_fmu.studies.stability import compliant_b5

    path, _, b5 = package
    runs = {e: ssp.run_ssp(path, e, compliant_b5.RECORD, work_dir=tmp_path / e) for e in ssp.ENGINES}
    res = {e: compliant_b5._result(b5, r.t, lambda n, r=r: r.columns[n], r.stopped, r.wall) for e, r in runs.items()}
    ours = res["master"]
    assert ours.stopped_early == "" and len(ours.t) == 50 and ours.t[-1] == pytest.approx(SPAN)
    assert np.max(np.abs(ours.speed)) > 2e-3 and np.max(np.abs(ours.torque)) > 0.05  # something happens
    for e in ("libcosim", "ecos"):
        r = res[e]
        assert r.stopped_early == "" and np.allclose(r.t, ours.t, rtol=0, atol=1e-12), e
        for a, b in ((r.deflection, ours.deflection), (r.speed, ours.speed), (r.torque, ours.torque)):
            assert np.max(np.abs(a - b)) <= 1e-9 * np.max(np.abs(b)), (e, np.max(np.abs(a - b)), np.max(np.abs(b)))


def test_bad_systems_are_refused_with_their_cause(package, tmp_path):
    _, system, _ = package
    wrong = [ssp.Connection("beam.hub.t[3]", "drive.drive.speed")]  # an output as a sink
    with pytest.raises(ssp.SspError, match="drive.drive.speed is a output, not an input"):
        ssp.write_ssp(tmp_path / "x.ssp", ssp.System("x", system.components, tuple(wrong)))
    with pytest.raises(ssp.SspError, match="has no variable 'hub.zz'"):
        ssp.write_ssp(tmp_path / "x.ssp", ssp.System("x", system.components, (ssp.Connection("beam.hub.zz", "drive.hub_frame.t[3]"),)))
    twice = [ssp.Connection("beam.hub.t[3]", "drive.hub_frame.t[3]"), ssp.Connection("beam.hub.t[2]", "drive.hub_frame.t[3]")]
    with pytest.raises(ssp.SspError, match="two sources"):
        ssp.write_ssp(tmp_path / "x.ssp", ssp.System("x", system.components, tuple(twice)))
    with pytest.raises(ssp.SspError, match="no component 'motor'"):
        ssp.write_ssp(tmp_path / "x.ssp", ssp.System("x", system.components, (), {"motor.k": 1.0}))
    (tmp_path / "not.ssp").write_text("plain text")
    with pytest.raises(ssp.SspError, match="not an SSP package"):
        ssp.read_ssp(tmp_path / "not.ssp")


def test_cli_writes_a_package_from_port_fields_and_runs_it(package, tmp_path, capsys):
    """`ffrf-fmu system write` with port fields (R, w, dw joined element by element) gives the
    connections of compliant_b5.connections(); `system run` runs it and writes the series."""
    from ffrf_fmu.cli import main
    from ffrf_fmu.studies.stability import compliant_b5

    _, system, b5 = package
    out = tmp_path / "b5.ssp"
    rc = main(["system", "write", str(out), f"--fmu=beam={b5.fmus['beam']}", f"--fmu=drive={b5.fmus['drive']}",
               "--connect=drive.hub_frame.R:beam.hub.R", "--connect=drive.hub_frame.w:beam.hub.w",
               "--connect=drive.hub_frame.dw:beam.hub.dw", "--connect=drive.hub.r:beam.hub.r",
               "--connect=drive.hub.v:beam.hub.v", "--connect=beam.hub.t[3]:drive.hub_frame.t[3]:-1",
               "--set=drive.drive.k=0", "--step=0.01", "--stop=0.05"])
    assert rc == 0
    assert set(ssp.read_ssp(out, tmp_path / "x").connections) == {ssp.Connection(*c) for c in compliant_b5.connections()}
    rc = main(["system", "run", str(out), "--engine=libcosim", "--record=beam.hub.t", f"--out={tmp_path / 'r.csv'}"])
    assert rc == 0 and "libcosim: 5 steps" in capsys.readouterr().out
    head = (tmp_path / "r.csv").read_text().splitlines()
    assert head[0] == "time,beam.hub.t[1],beam.hub.t[2],beam.hub.t[3]" and len(head) == 6
    rc = main(["system", "write", str(tmp_path / "y.ssp"), f"--fmu=beam={b5.fmus['beam']}", "--connect=beam.hub.t:beam.nope",
               "--step=0.01", "--stop=1"])
    assert rc == 2 and "beam.nope" in capsys.readouterr().err


def test_split_beam_package_from_body_ports_fails_alike_in_master_and_libcosim(tmp_path):
    """Two half-beam FMUs joined rigidly by `body_port_connections` (what `system write --ports`
    does) in one package; the hub of A driven through input overrides (the fast spin-up). Plain
    Jacobi in our master and libcosim: the same trajectory to 1e-9 and the same failing step (the
    added-mass instability of docs/stability.md: at H = 2 ms a body refuses its step at 0.044 s)."""
    from ffrf_fmu.studies import stability as st

    s = st.CosimSettings()
    case = st.CosimCase("split", MODELS / "haug_beam.toml", tmp_path / "fmus", s)
    fmus = {k: str(v) for k, v in case.fmus.items()}
    conns = ssp.body_port_connections("A", "cut", "B", "cut", fmus)
    assert len(conns) == 24 and sum(c.factor == -1.0 for c in conns) == 6  # 12 frame/rate values, 6 reactions
    system = ssp.System("split", fmus, tuple(conns), {"A.solver.step": 0.002, "B.solver.step": 0.002}, 0.002, 0.0, 0.06)
    path = ssp.write_ssp(tmp_path / "split.ssp", system)
    record = ["B.tip.r[2]", "A.cut.t[3]"]
    runs = {e: ssp.run_ssp(path, e, record, sources=case._hub_sources("A"), work_dir=tmp_path / e) for e in ("master", "libcosim")}
    m, lc = runs["master"], runs["libcosim"]
    assert m.stopped and lc.stopped and len(m.t) == len(lc.t) and m.t[-1] == pytest.approx(0.044)
    for n in record:
        assert np.max(np.abs(lc.columns[n] - m.columns[n])) <= 1e-9 * np.max(np.abs(m.columns[n])), n
