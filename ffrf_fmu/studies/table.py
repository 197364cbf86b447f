"""The tables studies write (chart.csv, study.csv, map.csv): one row per run, read back with
numbers and booleans parsed.

A file is written whole or not at all (a temporary file renamed over the old one), so a sweep
killed while writing leaves the previous table. Floats are written with `float_format`
(6 significant digits unless a caller asks for more), None as an empty cell.
"""
from __future__ import annotations

import csv
import io
import os
import re
from pathlib import Path
from typing import Any, Sequence

_INT = re.compile(r"[-+]?\d+")


def columns(rows: Sequence[dict], first: Sequence[str] = (), last: Sequence[str] = ()) -> list[str]:
    """first, then every other key in order of appearance, then last."""
    fixed = set(first) | set(last)
    middle = list(dict.fromkeys(k for r in rows for k in r if k not in fixed))
    return [*first, *middle, *last]


def cell(v: Any, float_format: str = ".6g") -> Any:
    if v is None:
        return ""
    if isinstance(v, float):
        return format(v, float_format)
    return v


def write_rows(path, rows: Sequence[dict], fields: Sequence[str] | None = None, float_format: str = ".6g") -> None:
    """Write the rows (keys not in `fields` are left out; default: every key, `columns(rows)`)."""
    fields = list(fields) if fields is not None else columns(rows)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=fields, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: cell(r.get(k), float_format) for k in fields})
    replace_text(Path(path), buf.getvalue())


def parse(v: str, text: bool = False) -> Any:
    """A cell back: "" -> None, True/False -> bool, an integer -> int, a number -> float, else the
    text (always the text when `text`)."""
    if v == "":
        return None
    if text:
        return v
    if v in ("True", "False"):
        return v == "True"
    if _INT.fullmatch(v):
        return int(v)
    try:
        return float(v)
    except ValueError:
        return v


def read_rows(path, text: Sequence[str] = ()) -> list[dict]:
    """The rows of a table, cells parsed (`parse`); the columns in `text` stay texts."""
    keep = set(text)
    with open(path, newline="", encoding="utf-8") as fh:
        return [{k: parse(v, k in keep) for k, v in raw.items()} for raw in csv.DictReader(fh)]


def replace_text(path: Path, text: str) -> None:
    """Write whole or not at all (a temporary file renamed over the old one)."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)
