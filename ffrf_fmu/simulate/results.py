"""A run's result: the time series under the FMU's variable names (one column per output
variable, then the energies and the Newton iterations), the free body's recorded state, the summary,
and the files written from them (CSV, JSON)."""
from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from ..runtime.data import BodyData
from ..runtime.outputs import ENERGY_FIELDS as ENERGIES, OUTPUT_FIELDS, field_shape, port_variables, row_columns


def variable_names(port: str) -> list[str]:
    """FMU variable names of one port's outputs (docs/fmu.md), in the columns order of
    BodySystem.port_array."""
    return [name for fld in OUTPUT_FIELDS for name in port_variables(port, fld)]


def column_names(body: BodyData) -> list[str]:
    """The columns of a run's rows (record): runtime/outputs.py row_columns of the body's ports."""
    return row_columns([p.name for p in body.ports])


@dataclass
class SimulationResult:
    t: np.ndarray
    columns: dict[str, np.ndarray]
    summary: dict
    body: BodyData = field(repr=False)

    def port(self, name: str, fld: str) -> np.ndarray:
        """(nt, 3) or (nt, 3, 3) series of one port field."""
        series = np.ascontiguousarray(np.array([self.columns[n] for n in port_variables(name, fld)]).T)  # (np.stack(.., -1))
        return series.reshape(series.shape[:-1] + field_shape(fld))

    def write_csv(self, path) -> None:
        names = ["time"] + list(self.columns)
        data = np.column_stack([self.t] + [self.columns[k] for k in self.columns])
        # names like hub.R[1,1] hold the delimiter: quoted (RFC 4180), a CSV reader sees one field each
        header = ",".join(f'"{n}"' if "," in n else n for n in names)
        np.savetxt(path, data, delimiter=",", header=header, comments="", fmt="%.10g")

    def write_summary(self, path) -> None:
        with open(path, "w") as fh:
            json.dump(self.summary, fh, indent=2)
            fh.write("\n")


# a free body's state beyond its ports (metrics kind "momentum"): CM, inertia about it, momenta; the
# runtime (free_body_state) and the full-order reference (reference.solver.mass_properties) record it
FREE_BODY_FIELDS = {"cm": (3,), "J_cm": (3, 3), "p": (3,), "h_cm": (3,)}


def free_body_keys(name: str) -> list[str]:
    """Column names of one FREE_BODY_FIELDS series: body.cm[1..3], body.J_cm[1,1..3,3], ..."""
    if FREE_BODY_FIELDS[name] == (3,):
        return [f"body.{name}[{i + 1}]" for i in range(3)]
    return [f"body.{name}[{i + 1},{j + 1}]" for i in range(3) for j in range(3)]


def free_body_columns(cm, J_cm, p, h_cm) -> dict[str, np.ndarray]:
    """The columns of the series cm, J_cm, p, h_cm ((nt, 3) or (nt, 3, 3)), named by free_body_keys."""
    out = {}
    for name, series in zip(FREE_BODY_FIELDS, (cm, J_cm, p, h_cm)):
        out |= dict(zip(free_body_keys(name), np.asarray(series).reshape(len(series), -1).T))
    return out


def free_body_series(result: SimulationResult, name: str) -> np.ndarray:
    """One FREE_BODY_FIELDS series of a result, (nt, 3) or (nt, 3, 3); a clear error when the run did
    not record it (standalone runs of scenes with metrics kind 'momentum' and the reference do; an FMU
    has no such outputs)."""
    keys = free_body_keys(name)
    if any(k not in result.columns for k in keys):
        raise KeyError(f"the free-body metrics need body.{name}, which this run did not record (standalone runs "
                       "of scenes with metrics kind 'momentum' and the reference record it; an FMU does not)")
    return np.ascontiguousarray(np.array([result.columns[k] for k in keys]).T).reshape((len(result.t),) + FREE_BODY_FIELDS[name])
