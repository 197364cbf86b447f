"""Checked reading of TOML tables: typed access where every failure names the file, the dotted
key and what was expected, and `--set key=value` overrides written into the raw tables first (so
they are checked with the rest); and writing raw tables back as TOML text. model.py reads and
writes model files with it."""
from __future__ import annotations

import json
import math
import re
import sys
from typing import Any, Sequence


def _tomllib():
    """tomllib (tomli before Python 3.11), imported when a value is parsed: `ffrf-fmu --help` imports
    this module for ModelError and needs no TOML parser."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover - Python 3.10
        import tomli as tomllib
    return tomllib


class ModelError(ValueError):
    """A model file (or an override) is malformed; the message names file, key and expectation."""


REQUIRED = object()
_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+\Z")


def positive(x: float) -> bool:
    return 0.0 < x < math.inf


def nonnegative(x: float) -> bool:
    return 0.0 <= x < math.inf


def finite(x: float) -> bool:
    return math.isfinite(x)


def join(path: str, key: str | int) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    key = key if _BARE_KEY.match(key) else '"' + key.replace('"', '\\"') + '"'
    return f"{path}.{key}" if path else key


def nearest(key: str, known) -> str | None:
    import difflib  # (here: only a misspelt key needs it, not every run that loads a model)

    lower = {k.lower(): k for k in known}
    hit = difflib.get_close_matches(key.lower(), list(lower), n=1, cutoff=0.5)
    return lower[hit[0]] if hit else None


def toml_type(v: Any) -> str:
    names = {bool: "boolean", int: "integer", float: "float", str: "string", list: "array", dict: "table"}
    return names.get(type(v), type(v).__name__)


class Reader:
    """Typed access to the raw TOML tables; every failure names file, dotted key, expectation."""

    def __init__(self, file: str, origins: dict[str, str]):
        self.file, self.origins = file, origins

    def fail(self, path: str, message: str):
        note = f" (set by --set {self.origins[path]})" if path in self.origins else ""
        raise ModelError(f"{self.file}: {path}: {message}{note}")

    def expected(self, path: str, what: str, value: Any):
        self.fail(path, f"expected {what}, got {value!r} ({toml_type(value)})")

    def table(self, value: Any, path: str, known: dict | None, required: Sequence[str] = ()) -> dict:
        """Check `value` is a table with only `known` keys (None: any key) and all `required` ones."""
        if not isinstance(value, dict):
            self.expected(path, "a table", value)
        for k in value if known is not None else ():
            if k not in known:
                near = nearest(k, known)
                hint = f"; did you mean {join(path, near)}?" if near else ""
                self.fail(join(path, k), f"unknown key{hint} (known keys here: {', '.join(known)})")
        for k in required:
            if k not in value:
                self.fail(join(path, k), f"missing; expected {known[k]}")
        return value

    def _value(self, t: dict, path: str, key: str, what: str, default: Any):
        if key in t:
            return t[key], False
        if default is REQUIRED:
            self.fail(join(path, key), f"missing; expected {what}")
        return default, True

    def real(self, t, path, key, what, default=REQUIRED, ok=finite) -> float:
        v, is_default = self._value(t, path, key, what, default)
        if is_default:
            return v
        if isinstance(v, bool) or not isinstance(v, (int, float)) or math.isnan(v) or not ok(v):
            self.expected(join(path, key), what, v)
        return float(v)

    def integer(self, t, path, key, what, default=REQUIRED, low=0) -> int:
        v, is_default = self._value(t, path, key, what, default)
        if is_default:
            return v
        if isinstance(v, bool) or not isinstance(v, int) or v < low:
            self.expected(join(path, key), what, v)
        return v

    def boolean(self, t, path, key, what, default=REQUIRED) -> bool:
        v, is_default = self._value(t, path, key, what, default)
        if not is_default and not isinstance(v, bool):
            self.expected(join(path, key), what, v)
        return v

    def string(self, t, path, key, what, default=REQUIRED, choices: Sequence[str] | None = None) -> str:
        v, is_default = self._value(t, path, key, what, default)
        if is_default:
            return v
        if not isinstance(v, str) or (choices is not None and v not in choices):
            self.expected(join(path, key), what, v)
        return v

    def vec3(self, t, path, key, what, default=REQUIRED, unit=False) -> tuple[float, float, float]:
        """Three finite numbers; unit=True: not all zero, returned normalized."""
        v, is_default = self._value(t, path, key, what, default)
        if is_default:
            return v
        ok = isinstance(v, list) and len(v) == 3
        ok = ok and all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v)
        norm = math.sqrt(sum(x * x for x in v)) if ok else 0.0
        if not ok or (unit and norm == 0.0):
            self.expected(join(path, key), what, v)
        return tuple(float(x) / norm for x in v) if unit else tuple(float(x) for x in v)

    def port_name(self, ports: dict, path: str, name: Any) -> str:
        if name not in ports:
            near = nearest(str(name), ports)
            hint = f"; did you mean {near!r}?" if near else ""
            self.fail(path, f"expected the name of a body port, got {name!r}{hint} (ports: {', '.join(ports) or 'none'})")
        return name


def parse_override_value(text: str) -> Any:
    """A TOML value (`8`, `2e-3`, `"gyroscopic"`, `[0, 0, -9.81]`); anything else is a bare string."""
    tomllib = _tomllib()
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def apply_overrides(raw: dict, overrides: Sequence[str], file: str, aliases: dict[str, tuple[str, ...]],
                    retired: dict[str, str] | None = None) -> dict[str, str]:
    """Write `key=value` overrides into the raw tables (validated with the rest afterwards).

    aliases: short keys -> dotted paths ("scenes.*" = every scene); retired: short keys no longer
    accepted -> the message that names what to write instead. Returns {dotted path: override text},
    so that a message about an overridden key says so.
    """
    origins: dict[str, str] = {}
    for text in overrides:
        key, sep, value_text = text.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ModelError(f"{file}: --set {text!r}: expected key=value, e.g. step=1e-3")
        if "." in key:
            targets = (key,)
        elif retired and key in retired:
            raise ModelError(f"{file}: --set {text}: {retired[key]}")
        elif key in aliases:
            targets = aliases[key]
        else:
            near = nearest(key, aliases)
            hint = f"did you mean {near}? " if near else ""
            raise ModelError(
                f"{file}: --set {text}: unknown key {key!r}; {hint}(short keys: {', '.join(aliases)}; "
                "or a dotted path such as body.section.EI2 or scenes.spinup.step)"
            )
        value = parse_override_value(value_text.strip())
        for target in targets:
            parts = target.split(".")
            if parts[:2] == ["scenes", "*"]:  # scene keys apply to every scene
                scenes = raw.get("scenes")
                paths = [["scenes", name, *parts[2:]] for name in (scenes if isinstance(scenes, dict) else ())]
            else:
                paths = [parts]
            for p in paths:
                node, shown = raw, ""
                for i, part in enumerate(p):
                    if isinstance(node, list):
                        if not (part.isdigit() and int(part) < len(node)):
                            raise ModelError(f"{file}: --set {text}: {shown} is an array of {len(node)}; "
                                             f"expected an index 0..{len(node) - 1}, got {part!r}")
                        part = int(part)
                    elif not isinstance(node, dict):
                        raise ModelError(f"{file}: --set {text}: {shown} is not a table")
                    shown = join(shown, part)
                    if i == len(p) - 1:
                        node[part] = value
                    else:
                        if isinstance(node, dict):
                            node.setdefault(part, {})
                        node = node[part]
                origins[shown] = text
    return origins


# ------------------------------------------------------------------------------ writing
def toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v) if math.isfinite(v) else {math.inf: "inf", -math.inf: "-inf"}.get(v, "nan")
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string is a TOML basic string
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + " }"
    raise ModelError(f"cannot write {type(v).__name__} {v!r} to a model file")


def toml_key(k: str) -> str:
    return k if _BARE_KEY.match(k) else json.dumps(k)


def toml_text(raw: dict, comment: str = "") -> str:
    """The TOML text of raw tables (what a reader of this module reads, e.g. a model's {"body": {...},
    "scenes": {...}}): a table per dict of dicts, inline tables inside arrays; `comment` on top."""
    lines = [f"# {c}" for c in comment.splitlines()]

    def table(path: list[str], t: dict) -> None:
        scalars = {k: v for k, v in t.items() if not isinstance(v, dict)}
        if path and (scalars or not t):
            lines.append(f"[{'.'.join(toml_key(p) for p in path)}]")
        lines.extend(f"{toml_key(k)} = {toml_value(v)}" for k, v in scalars.items())
        for k, v in t.items():
            if isinstance(v, dict):
                table([*path, k], v)

    table([], raw)
    return "\n".join(lines) + "\n"
