"""Impulse of a load window under generalized-alpha, on the scalar model of the scheme (docs/equations.md,
"Loads between steps"): m v' = F on [t_start, t_end), integrated with the first-order generalized-alpha
of runtime/integrator.py (rho_inf = 0.8, h = 20 ms), the load applied at each step's end as

  - point:     its value at the step's end (the former rule),
  - shortened: its value just before the step's end, the steps shortened to land on the window's ends,
  - mean:      its mean over the step (the rule the runs use),

and the impulse it gave against F (t_end - t_start). Also the start: a window from t = 0 with the load in
the initial rates (a consistent start) or not.

    python benchmarks/load_windows.py
"""
import numpy as np

RHO = 0.8
AM = (3 - RHO) / (2 * (1 + RHO))
AF = 1 / (1 + RHO)
GAMMA = 0.5 + AM - AF


def impulse(times, force, yd0=0.0):
    """v(T) of m v' = force(t0, t1) per step (m = 1), from rest; yd0 the initial rate (the load at t = 0)."""
    v, a, yd = 0.0, yd0, yd0
    for t0, t1 in zip(times[:-1], times[1:]):
        h, yd1 = t1 - t0, force(t0, t1)
        a1 = (AF * yd1 + (1 - AF) * yd - (1 - AM) * a) / AM
        v += h * ((1 - GAMMA) * a + GAMMA * a1)
        a, yd = a1, yd1
    return v


def main():
    h, T = 0.02, 4.0
    grid = np.linspace(0.0, T, int(round(T / h)) + 1)
    print(f"rho_inf = {RHO}, h = {h} s: impulse / (F x length) - 1")
    print(f"{'window [s]':>18} {'point':>10} {'shortened':>10} {'mean':>10}")
    for ts, te in ((1.0, 1.5), (1.03, 1.53), (1.011, 1.049), (1.005, 1.017)):
        point = lambda t0, t1: 1.0 if ts <= t1 < te else 0.0  # noqa: E731
        before = lambda t0, t1: 1.0 if ts - 1e-12 <= t0 and t1 <= te + 1e-12 else 0.0  # noqa: E731
        mean = lambda t0, t1: max(0.0, min(t1, te) - max(t0, ts)) / (t1 - t0)  # noqa: E731
        events = np.unique(np.concatenate([grid, [ts, te]]))
        exact = te - ts
        print(f"{f'[{ts:g}, {te:g})':>18} {impulse(grid, point) / exact - 1:>10.2e} "
              f"{impulse(events, before) / exact - 1:>10.2e} {impulse(grid, mean) / exact - 1:>10.2e}")
    mean0 = lambda t0, t1: max(0.0, min(t1, 0.5) - max(t0, 0.0)) / (t1 - t0)  # noqa: E731
    print(f"window [0, 0.5) with the mean: load not in the initial rates {impulse(grid, mean0) / 0.5 - 1:.2e}, "
          f"in them (a consistent start) {impulse(grid, mean0, 1.0) / 0.5 - 1:.2e}")


if __name__ == "__main__":
    main()
