"""Example partner FMUs for co-simulation with the body FMUs.

`build_hub_drive(dest)`: the B5 hub drive (hub inertia, motor, PI speed controller tracking the
Wu-Haug spin-up profile, torsional shaft to the beam root), a pythonfmu FMU whose script is
`hub_drive_slave.py`. Its `hub` port follows docs/fmu.md, so
`master.CoSimulation.connect_ports("beam", "hub", "drive", "hub")` joins it to a beam FMU whose hub
rotation is force-driven (models/haug_beam.toml, scene hub_free). Parameters (`drive.J`, `drive.k`,
`drive.c`, `drive.Kp`, `drive.Ki`, `profile.omega`, `profile.T`, `solver.substep`) are FMU
parameters: change them with start values, no rebuild.

`build_road_profile(dest)`: the road heights under the four wheels of a vehicle body (a sin^4 bump
under one wheel), the far ends of the car body's compliant mounts (`road_profile_slave.py`,
`car_body_system.py`). `build_spin_drive(dest)`: a prescribed Wu-Haug spin-up about X with a
rotating unbalance force, the partner of the Jeffcott rotor run-up (`spin_drive_slave.py`,
`rotor_system.py`). Both have no inputs (exact signals) and only standard library code.

Each partner script is a `partner_slave.PartnerSlave` (its parameters, variables and FMU state
written once); `build_script_fmu` ships that module beside the script in the FMU.
"""
from __future__ import annotations

import hashlib
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
HUB_DRIVE_SOURCE = HERE / "hub_drive_slave.py"


def build_hub_drive(dest) -> Path:
    """Build the hub drive FMU into `dest` (a .fmu file name or a directory); returns its path."""
    return build_script_fmu(HUB_DRIVE_SOURCE, "HubDrive", "hub_drive", dest)


def build_road_profile(dest) -> Path:
    """Build the road profile FMU (road_profile_slave.py) into `dest` (.fmu name or directory)."""
    return build_script_fmu(HERE / "road_profile_slave.py", "RoadProfile", "road_profile", dest)


def build_spin_drive(dest) -> Path:
    """Build the spin drive FMU (spin_drive_slave.py) into `dest` (.fmu name or directory)."""
    return build_script_fmu(HERE / "spin_drive_slave.py", "SpinDrive", "spin_drive", dest)


PARTNER_SOURCE = HERE / "partner_slave.py"
PARTNER_IMPORT = "from ffrf_fmu.examples.partner_slave import PartnerSlave"


def script_names(source: Path, stem: str) -> tuple[str, str, str]:
    """(module, class, partner module) names of a pythonfmu script's FMU, unique per version of its
    source and of partner_slave.py, which it ships."""
    digest = hashlib.sha256(Path(source).read_bytes() + PARTNER_SOURCE.read_bytes()).hexdigest()[:10]
    camel = "".join(w.capitalize() for w in stem.split("_"))
    return f"ffrf_{stem}_{digest}", f"Ffrf{camel}_{digest}", f"ffrf_partner_{digest}"


def build_script_fmu(source: Path, class_name: str, stem: str, dest) -> Path:
    """Build the pythonfmu FMU of script `source` (its slave class `class_name`, a PartnerSlave) into
    `dest` (a .fmu file name or a directory, then STEM.fmu), module and class renamed with the digest,
    partner_slave.py shipped beside it under its own digest name."""
    from pythonfmu import FmuBuilder

    module, cls, partner = script_names(source, stem)
    text = Path(source).read_text(encoding="utf-8")
    if PARTNER_IMPORT not in text:
        raise ValueError(f"{source}: a partner script imports its slave as {PARTNER_IMPORT!r}")
    text = text.replace(f"class {class_name}(PartnerSlave):", f"class {cls}(PartnerSlave):")
    text = text.replace(PARTNER_IMPORT, f"from {partner} import PartnerSlave")
    dest = Path(dest)
    if dest.suffix != ".fmu":
        dest = dest / f"{stem}.fmu"
    dest.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=f"ffrf_{stem}_") as tmp:
        script = Path(tmp) / f"{module}.py"
        script.write_text(text, encoding="utf-8")
        shipped = Path(tmp) / f"{partner}.py"
        shipped.write_bytes(PARTNER_SOURCE.read_bytes())
        saved = list(sys.path)
        try:
            out = FmuBuilder.build_FMU(script, dest=dest, project_files=[shipped],
                                       canHandleVariableCommunicationStepSize=True,
                                       canGetAndSetFMUstate=True, canSerializeFMUstate=True,
                                       canBeInstantiatedOnlyOncePerProcess=False)
        finally:
            sys.path[:] = saved
            sys.modules.pop(module, None)
            sys.modules.pop(partner, None)
    return Path(out)
