"""The body FMU's state (fmi2GetFMUstate and its kin): a complete snapshot of an instance, and its bytes
(fmi2SerializeFMUstate).

`FmuState` is the state half of `core.BodyCoSim` (a mixin over the instance's values, mode, times,
failure and body; a restored body is made by `parameters.Parameters._make_system`).
"""
from __future__ import annotations

import io
import json

import numpy as np

STATE_VERSION = 1


class FmuState:
    """The FMU's state (see the module docstring)."""

    def get_state(self) -> dict:
        """A complete snapshot (arrays are copies): values, mode, time, body integrator state
        (which includes the body's Newton iteration matrix: a restored run takes bit-identical
        steps)."""
        sys_state = None if self.system is None else self.system.get_state()
        return {
            "version": STATE_VERSION,
            "values": self.values.copy(),
            "mode": self.mode,
            "start_time": self.start_time,
            "failure": self.failure,
            "system": None if sys_state is None else sys_state.copy(),
            "initialized_with": None if self._initialized_with is None else self._initialized_with.copy(),
        }

    def set_state(self, state: dict) -> None:
        if state.get("version") != STATE_VERSION:
            raise ValueError(f"FMU state version {state.get('version')!r} is not {STATE_VERSION}")
        values = np.asarray(state["values"], dtype=float)
        if values.shape != self.values.shape:
            raise ValueError(f"FMU state has {values.size} values, this FMU has {self.values.size}")
        self.values = values.copy()
        self.mode = str(state["mode"])
        self.start_time = float(state["start_time"])
        self.failure = str(state["failure"])
        self.discarded = ""  # a restored state is a fresh start from its time
        self.last_step = None  # derivatives need a doStep from it
        iw = state.get("initialized_with")
        self._initialized_with = None if iw is None else np.asarray(iw, dtype=float).copy()
        if state["system"] is None:
            self.system = None
            self._system_params = None
        else:
            self._make_system().set_state(np.asarray(state["system"], dtype=float))

    @staticmethod
    def state_to_bytes(state: dict) -> bytes:
        buf = io.BytesIO()
        arrays = {
            "values": state["values"],
            "meta": np.array(json.dumps({k: state[k] for k in ("version", "mode", "start_time", "failure")})),
        }
        if state["system"] is not None:
            arrays["system"] = state["system"]
        if state["initialized_with"] is not None:
            arrays["initialized_with"] = state["initialized_with"]
        np.savez(buf, **arrays)
        return buf.getvalue()

    @staticmethod
    def state_from_bytes(blob: bytes) -> dict:
        with np.load(io.BytesIO(bytes(blob)), allow_pickle=False) as z:
            state = json.loads(str(z["meta"]))
            state["values"] = z["values"].copy()
            state["system"] = z["system"].copy() if "system" in z.files else None
            state["initialized_with"] = z["initialized_with"].copy() if "initialized_with" in z.files else None
        return state
