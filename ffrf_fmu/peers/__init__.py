"""Peer codes run on our scenes, for the speed/accuracy comparison of benchmarks/peers.py and
`ffrf-fmu chart --peer NAME`.

- `exudyn_beam`: Exudyn's 3D geometrically exact beam (ObjectBeamGeometricallyExact), a
  full-order nonlinear beam in C++ (optional extra `peers`: `pip install -e ".[peers]"`).

A peer is optional: `available(name)` says whether it can run here and, if not, why.
"""
from __future__ import annotations

PEERS = ("exudyn",)
NAMES = {"exudyn": "Exudyn"}  # the peer code's name in chart labels and legends


def available(name: str) -> tuple[bool, str]:
    """(True, version) when the peer's package imports here, else (False, the reason)."""
    if name != "exudyn":
        return False, f"unknown peer {name!r} (known: {', '.join(PEERS)})"
    try:
        import exudyn
    except ImportError as e:
        return False, f"exudyn is not installed ({e}); it is the optional extra `peers`: pip install -e \".[peers]\""
    return True, str(getattr(exudyn, "__version__", "?"))


def runner(name: str):
    """The chart worker function of a peer: f(model_path, scene_name, overrides, values) -> run dict."""
    if name == "exudyn":
        from .exudyn_beam import run_configuration

        return run_configuration
    raise ValueError(f"unknown peer {name!r} (known: {', '.join(PEERS)})")
