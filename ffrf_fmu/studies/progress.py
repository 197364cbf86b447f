"""A progress bar on a terminal for sweeps (chart, study): runs done / total, wall time, the last run."""
from __future__ import annotations

import sys
import time


class Bar:
    """Runs done / total on a terminal (silent when the stream is not one)."""

    def __init__(self, total: int, label: str, stream=None):
        self.total, self.label, self.stream = total, label, stream or sys.stderr
        self.enabled = self.stream.isatty()
        self.start = time.perf_counter()

    def update(self, done: int, note: str = "") -> None:
        if self.enabled:
            n = int(25 * done / max(self.total, 1))
            self.stream.write(f"\r{self.label} [{'#' * n}{'.' * (25 - n)}] {done}/{self.total} runs "
                              f"wall={time.perf_counter() - self.start:.0f}s {note[:40]:<40}")
            self.stream.flush()

    def close(self) -> None:
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()
