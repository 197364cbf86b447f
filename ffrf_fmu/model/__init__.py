"""Model files: a body (beam, superelements, ports) and named scenes, as frozen dataclasses.

The TOML format is documented in docs/model-format.md; `load_model` parses, applies
`--set key=value` overrides and validates, raising `ModelError` that names the file, the key
and what was expected (the checked reading itself is checked_toml.py). One idea a module:
schema.py the dataclasses, keys.py each table's keys and what they expect, body.py a beam's
[body], solid.py a solid's, scene.py the scenes; the names are imported here, as
`ffrf_fmu.model.X`, where they always were.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any, Sequence

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

from ..checked_toml import ModelError, Reader, apply_overrides, toml_text
from ..section import Section
from .body import _parse_beam, body_damping
from .keys import _NAME, BODY_KEYS, OVERRIDE_ALIASES, RETIRED_ALIASES, TOP_KEYS
from .schema import (INITIAL_STATES, METRIC_KINDS, PART_CAUSALITIES, PART_INDEX, Body, Drive, Initial, Load, Metrics,
                     Model, PointMass, Port, ReferenceOptions, RotationDrive, Scene, SolidFrame, SolidSpec,
                     TimeFunction, TranslationDrive, Unbalance)
from .scene import _parse_scene, reduction_options, scene_body, steady_spin_drive
from .solid import SHELL_ELEMENTS, SOLID_ELEMENTS, _parse_solid

__all__ = [
    "load_model", "write_model", "ModelError", "tomllib", "Section", "body_damping", "reduction_options",
    "scene_body", "steady_spin_drive", "INITIAL_STATES", "METRIC_KINDS", "PART_CAUSALITIES", "PART_INDEX",
    "SHELL_ELEMENTS", "SOLID_ELEMENTS", "Body", "Drive", "Initial", "Load", "Metrics", "Model", "PointMass", "Port",
    "ReferenceOptions", "RotationDrive", "Scene", "SolidFrame", "SolidSpec", "TimeFunction", "TranslationDrive",
    "Unbalance",
]


def load_model(path, overrides: Sequence[str] = ()) -> Model:
    """Read a TOML model file, apply `--set key=value` overrides, validate, return a Model."""
    file = str(path)
    try:
        raw = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as e:
        raise ModelError(f"{file}: cannot read the model file: {e.strerror or e}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise ModelError(f"{file}: not valid TOML: {e}") from None
    r = Reader(file, apply_overrides(raw, overrides, file, OVERRIDE_ALIASES, RETIRED_ALIASES))
    r.table(raw, "", TOP_KEYS, required=("body", "scenes"))
    default_name = re.sub(r"\W", "_", Path(path).stem)
    body = _parse_body(r, raw["body"], default_name if _NAME.match(default_name) else "body", file)
    scenes = r.table(raw["scenes"], "scenes", None)
    if not scenes:
        r.fail("scenes", "expected at least one scene table [scenes.NAME]")
    return Model(body, tuple(_parse_scene(r, body, name, t) for name, t in scenes.items()), file)


def _parse_body(r: Reader, t: Any, default_name: str, file: str) -> Body:
    """[body] by its kind: a beam (body.py) or a solid (solid.py)."""
    b = "body"
    kind = r.string(r.table(t, b, None), b, "kind", BODY_KEYS["kind"], "beam", ("beam", "solid"))
    return (_parse_solid if kind == "solid" else _parse_beam)(r, t, default_name, file)


def write_model(raw: dict, path, comment: str = "") -> Model:
    """Write the raw tables as a model file and load it back (a ModelError names what is wrong)."""
    Path(path).write_text(toml_text(raw, comment), encoding="utf-8")
    return load_model(path)
