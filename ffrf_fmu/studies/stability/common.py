"""What every stability map shares: its table DIR/map.csv and its time series DIR/series.npz. (Its
runs go through the sweep layer, sweep.sweep_into, into the result store in DIR: a rerun repeats
no finished run.)"""
from __future__ import annotations

from pathlib import Path
import numpy as np

from ..table import read_rows, write_rows

MAP_CSV, SERIES = "map.csv", "series.npz"
TEXT_COLUMNS = ("model", "terms", "failure", "benchmark", "scene", "case", "scheme", "verdict")


def write_map(out_dir, rows: list[dict], series: dict[str, np.ndarray]) -> None:
    out_dir = Path(out_dir)
    write_rows(out_dir / MAP_CSV, rows)
    np.savez_compressed(out_dir / SERIES, **series)


def read_map(path) -> list[dict]:
    """map.csv rows, cells parsed (table.parse)."""
    return read_rows(path, text=TEXT_COLUMNS)


def is_true(v) -> bool:
    return v is True or v == "True" or v == 1.0
