"""The values a sweep runs over: `KEY=V1,V2,...` items (chart --sweep, study --vary), their
cartesian products, and a combination as `--set` overrides (model.py)."""
from __future__ import annotations

import itertools
from typing import Sequence


class GridError(ValueError):
    """Bad KEY=V1,V2,... items."""


def parse_values(items: Sequence[str], option: str = "--sweep") -> dict[str, list[str]]:
    """["superelements=1,2,4", "terms=linear,gyroscopic"] -> {key: [value texts]} (order kept);
    errors name `option` (the command line option the items came from)."""
    out: dict[str, list[str]] = {}
    for item in items:
        key, sep, values = item.partition("=")
        key = key.strip()
        vals = [v.strip() for v in values.split(",") if v.strip()]
        if not sep or not key or not vals:
            raise GridError(f"{option} {item!r}: expected key=v1,v2,... e.g. superelements=1,2,4")
        if key in out:
            raise GridError(f"{option} {item!r}: key {key!r} given twice")
        out[key] = vals
    return out


def combinations(groups) -> list[dict[str, str]]:
    """Cartesian product of the value lists, as {key: value text} dicts. `groups` is one
    {key: [values]} dict or a list of them (the union of their products, in order)."""
    out = []
    for g in [groups] if isinstance(groups, dict) else list(groups):
        keys = list(g)
        out += [dict(zip(keys, combo)) for combo in itertools.product(*(g[k] for k in keys))]
    return out


def value_overrides(values: dict[str, str]) -> list[str]:
    """{key: value} -> ["key=value", ...] (`--set` overrides)."""
    return [f"{k}={v}" for k, v in values.items()]
