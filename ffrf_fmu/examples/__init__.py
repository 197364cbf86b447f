"""Example partner FMUs for co-simulation with the body FMUs.

`build_hub_drive(dest)`: the B5 hub drive (hub inertia, motor, PI speed controller tracking the
Wu-Haug spin-up profile, torsional shaft to the beam root), a pythonfmu FMU whose script is
`hub_drive_slave.py`. Its `hub` port follows docs/fmu.md, so
`master.CoSimulation.connect_ports("beam", "hub", "drive", "hub")` joins it to a beam FMU whose hub
rotation is force-driven (models/haug_beam.toml, scene hub_free). Parameters (`drive.J`, `drive.k`,
`drive.c`, `drive.Kp`, `drive.Ki`, `profile.omega`, `profile.T`, `solver.substep`) are FMU
parameters: change them with start values, no rebuild.
"""
from __future__ import annotations

import hashlib
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
HUB_DRIVE_SOURCE = HERE / "hub_drive_slave.py"


def hub_drive_names() -> tuple[str, str]:
    """(module, class) names of the hub drive FMU: unique per version of its source, so that two
    builds from different code never collide in one process (docs/fmu.md)."""
    digest = hashlib.sha256(HUB_DRIVE_SOURCE.read_bytes()).hexdigest()[:10]
    return f"ffrf_hub_drive_{digest}", f"FfrfHubDrive_{digest}"


def build_hub_drive(dest) -> Path:
    """Build the hub drive FMU into `dest` (a .fmu file name or a directory); returns its path."""
    from pythonfmu import FmuBuilder

    module, cls = hub_drive_names()
    text = HUB_DRIVE_SOURCE.read_text(encoding="utf-8").replace("class HubDrive(Fmi2Slave):", f"class {cls}(Fmi2Slave):")
    dest = Path(dest)
    if dest.suffix != ".fmu":
        dest = dest / "hub_drive.fmu"
    dest.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="ffrf_hub_drive_") as tmp:
        script = Path(tmp) / f"{module}.py"
        script.write_text(text, encoding="utf-8")
        saved = list(sys.path)
        try:
            out = FmuBuilder.build_FMU(script, dest=dest, canHandleVariableCommunicationStepSize=True,
                                       canGetAndSetFMUstate=True, canSerializeFMUstate=True,
                                       canBeInstantiatedOnlyOncePerProcess=False)
        finally:
            sys.path[:] = saved
            sys.modules.pop(module, None)
    return Path(out)
