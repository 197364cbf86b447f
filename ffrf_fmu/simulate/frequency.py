"""The dominant frequency of a sampled series: the frequency w of the least-squares sinusoid with a
linear trend,

    y(t) ~ a sin(w tau) + b cos(w tau) + c + d u,    tau = t - t_0,  u = tau / tau_max,

searched in a band. A least-squares fit resolves a frequency from a couple of periods, where the peak
of a periodogram, shifted by the window's leakage and the trend, could not. With the coefficients
eliminated (variable projection), the misfit is a function of w alone,

    r(w) = |y - A(w) x(w)|^2 = |y|^2 - x(w) . A(w)^T y,    A(w)^T A(w) x(w) = A(w)^T y,

A(w) = [sin(w tau), cos(w tau), 1, u] (N x 4), and the estimate is its minimum:

1. Search: r on GRID frequencies spread evenly over the band. Every w-dependent entry of A^T A and
   A^T y is a sum S_x(w) = sum_n x_n exp(i w tau_n) with x = y, 1, u, and x = 1 at 2 w for the
   sin^2 = (1 - cos 2wt) / 2, sin cos, cos^2 sums. For evenly spaced samples tau_n = n dt and grid
   frequencies w_g = w_0 + g dw, g n = (g^2 + n^2 - (g - n)^2) / 2 turns S_x(w_g) into a convolution
   (the chirp z-transform, Bluestein's algorithm), done by FFT for all g at once: O((N + G) log(N + G))
   in place of the O(N G) of the sums themselves, which remain the path for uneven samples. Up to
   DIRECT_SUMS_MAX samples the sums themselves are cheaper (`grid_sums`): with g = q p + r,
   exp(i w_g tau_n) = exp(i w_0 tau_n) exp(i q dw tau_n)^p exp(i dw tau_n)^r makes them one matrix
   product of sqrt(G) x N and N x sqrt(G) factors, where the chirp z-transform's first call in a
   process imports numpy.fft (about 0.9 ms; B1 at 40 ms has N = 125 samples after its spin-up).
2. Refinement: in the bracket of the grid's best point and its two neighbours the minimum is a zero of

       r'(w) = -2 sum_n e_n tau_n (a cos(w tau_n) - b sin(w tau_n)),    e = y - A x

   (the derivative of x(w) drops out as x minimizes r: the envelope theorem). Its sign at the grid's
   best point gives the half of the bracket where r' changes sign; the Illinois variant of regula
   falsi closes on the zero to FREQUENCY_XTOL (superlinear, a handful of fits). Where r' does not change
   sign there (the minimum on the band's edge, or r not unimodal in the bracket), a golden-section
   search of r in the whole bracket decides.

numpy only: scipy costs more to import than a run (and np.array of a list of rows, not np.stack, whose
Python layer costs more than the small products here).
"""
from __future__ import annotations

import math

import numpy as np

GRID = 400  # frequencies of the first search, spread evenly over the band (ends included)
FREQUENCY_XTOL = 1e-9  # Hz: the refined frequency's bracket (far below any metric's tolerance)
EVEN_REL = 1e-9  # samples count as evenly spaced when each is this close to t_0 + n dt (of the window)
MAX_REFINE = 100  # fits of the refinement (it takes about ten; a bound, not a budget)
# evenly spaced samples up to which the grid's sums are summed (`grid_sums`), beyond by chirp z-transform:
# the first call in a process, 400 frequencies, best of 3 at load 6.3: 126 samples 0.33 against 1.16 ms
# (numpy.fft's import), 512 samples 0.99 against 1.20 ms, 1024 samples 2.30 against 1.47 ms
DIRECT_SUMS_MAX = 512


def dominant_frequency(t: np.ndarray, y: np.ndarray, f_min: float, f_max: float) -> float:
    """The frequency [Hz] of the least-squares sinusoid plus a linear trend to y(t), searched in
    [f_min, f_max] (module doc: grid search of the misfit, then the zero of its derivative)."""
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    if t.ndim != 1 or t.shape != y.shape or t.size < 5:
        raise ValueError(f"dominant_frequency: t and y must be 1-D of one length >= 5, got {t.shape}, {y.shape}")
    if not t[-1] > t[0]:
        raise ValueError(f"dominant_frequency: the samples span no time (t from {t[0]} to {t[-1]})")
    if not 0.0 < f_min < f_max:
        raise ValueError(f"dominant_frequency: band [{f_min}, {f_max}] Hz: expected 0 < f_min < f_max")
    fit = TrendFit(t, y)
    grid = np.linspace(f_min, f_max, GRID)
    i = int(np.argmax(fit.grid_scores(grid)))  # least misfit
    return fit.minimum(grid[max(i - 1, 0)], grid[i], grid[min(i + 1, GRID - 1)])


class TrendFit:
    """The series y(t) with the trend's columns [1, u] projected out once: with Q an orthonormal basis
    of them and P = I - Q Q^T, the fit at w is the 2 x 2 problem of (P sin, P cos) against P y, whose
    residual is the 4-column fit's, r(w) = |P y|^2 - score(w), score = b^T G^{-1} b with
    G = [P s, P c]^T [P s, P c] and b = [s, c]^T P y."""

    def __init__(self, t: np.ndarray, y: np.ndarray):
        self.tau = t - t[0]
        n = self.tau.size
        u = self.tau / self.tau[-1]
        v = u - u.mean()
        self.Q = np.array([np.full(n, 1.0 / np.sqrt(n)), v / np.linalg.norm(v)])  # (2, N), orthonormal rows
        self.u, self.n = u, n
        self.Py = y - (self.Q @ y) @ self.Q
        self.Py2 = float(self.Py @ self.Py)
        self._F = np.ascontiguousarray(np.array([self.Q[0], self.Q[1], self.Py]).T)  # (N, 3)
        self._X = np.empty((5, n))  # sin, cos, tau sin, tau cos of the fit's frequency; w tau

    def grid_scores(self, grid: np.ndarray) -> np.ndarray:
        """score(w) (class doc; r = |P y|^2 - score) at each frequency of `grid` (evenly spaced, Hz)."""
        tau, n = self.tau, self.n
        w0, dw = 2 * np.pi * grid[0], 2 * np.pi * (grid[-1] - grid[0]) / (grid.size - 1)
        dt = tau[-1] / (n - 1)
        if np.max(np.abs(tau - dt * np.arange(n))) <= EVEN_REL * tau[-1]:
            sums = grid_sums if n <= DIRECT_SUMS_MAX else chirp_z_pair
            s1, s2 = sums(np.array([self.Py, self.Q[0], self.Q[1]]), w0 * dt, dw * dt, grid.size)
        else:  # uneven samples: the sums themselves
            e = np.exp(1j * np.outer(2 * np.pi * grid, tau))
            s1, s2 = np.array([self.Py, self.Q[0], self.Q[1]]) @ e.T, (e * e).sum(axis=1)
        b, q1, q2 = s1
        Gss = 0.5 * (n - s2.real) - q1.imag**2 - q2.imag**2
        Gcc = 0.5 * (n + s2.real) - q1.real**2 - q2.real**2
        Gsc = 0.5 * s2.imag - q1.imag * q1.real - q2.imag * q2.real
        bs, bc = b.imag, b.real
        return (Gcc * bs * bs - 2 * Gsc * bs * bc + Gss * bc * bc) / (Gss * Gcc - Gsc * Gsc)

    def __call__(self, f: float) -> tuple[float, float]:
        """(r, dr/df) at f [Hz] (module doc, step 2), from the products of [s, c, tau s, tau c] with
        [s, c] and [q1, q2, P y] (two matrix products; the residual e = P y - x0 P s - x1 P c enters
        only through them)."""
        X = self._X
        np.multiply(2 * np.pi * f, self.tau, out=X[4])
        np.sin(X[4], out=X[0])
        np.cos(X[4], out=X[1])
        np.multiply(X[0], self.tau, out=X[2])
        np.multiply(X[1], self.tau, out=X[3])
        (ss, _), (sc, cc), (ts_s, ts_c), (tc_s, tc_c) = (X[:4] @ X[:2].T).tolist()
        (s1, s2, sy), (c1, c2, cy), (ts1, ts2, tsy), (tc1, tc2, tcy) = (X[:4] @ self._F).tolist()
        g00, g01, g11 = ss - s1 * s1 - s2 * s2, sc - s1 * c1 - s2 * c2, cc - c1 * c1 - c2 * c2
        det = g00 * g11 - g01 * g01
        x0, x1 = (g11 * sy - g01 * cy) / det, (g00 * cy - g01 * sy) / det
        k1, k2 = x0 * s1 + x1 * c1, x0 * s2 + x1 * c2  # Q^T (x0 s + x1 c): e = P y - x0 s - x1 c + Q k
        e_ts = tsy - x0 * ts_s - x1 * ts_c + k1 * ts1 + k2 * ts2
        e_tc = tcy - x0 * tc_s - x1 * tc_c + k1 * tc1 + k2 * tc2
        slope = -2.0 * (x0 * e_tc - x1 * e_ts)  # dr/dw = -2 sum_n e_n tau_n (x0 cos - x1 sin)
        return self.Py2 - (x0 * sy + x1 * cy), 2 * np.pi * slope

    def minimum(self, lo: float, mid: float, hi: float) -> float:
        """The minimum of r in [lo, hi], mid the grid's best point inside (module doc, step 2)."""
        _, g_mid = self(mid)
        if g_mid == 0.0:
            return float(mid)
        a, b = (mid, hi) if g_mid < 0 else (lo, mid)
        ga, gb = (g_mid, self(b)[1]) if g_mid < 0 else (self(a)[1], g_mid)
        if not (ga < 0.0 < gb):
            return self.golden(lo, hi)
        side, last = 0, mid
        for _ in range(MAX_REFINE):  # Illinois: regula falsi, the end kept twice in a row has its value halved
            if b - a <= FREQUENCY_XTOL:
                break
            x = b - gb * (b - a) / (gb - ga)
            if not a < x < b:
                x = 0.5 * (a + b)
            if abs(x - last) < 0.5 * FREQUENCY_XTOL:  # the step is below the tolerance: probe half of it
                # beyond x, away from the end it is closer to (Brent's rule): a sign change closes the bracket
                x = x + 0.5 * FREQUENCY_XTOL if x - a < b - x else x - 0.5 * FREQUENCY_XTOL
            last = x
            gx = self(x)[1]
            if gx == 0.0:
                return float(x)
            if gx < 0.0:
                a, ga = x, gx
                if side == -1:
                    gb *= 0.5
                side = -1
            else:
                b, gb = x, gx
                if side == 1:
                    ga *= 0.5
                side = 1
        return float(0.5 * (a + b))

    def golden(self, lo: float, hi: float) -> float:
        """Golden-section search of r in [lo, hi] to FREQUENCY_XTOL."""
        g = (math.sqrt(5.0) - 1.0) / 2.0
        a, b = hi - g * (hi - lo), lo + g * (hi - lo)
        fa, fb = self(a)[0], self(b)[0]
        while hi - lo > FREQUENCY_XTOL:
            if fa < fb:
                hi, b, fb = b, a, fa
                a = hi - g * (hi - lo)
                fa = self(a)[0]
            else:
                lo, a, fa = a, b, fb
                b = lo + g * (hi - lo)
                fb = self(b)[0]
        return float(0.5 * (lo + hi))


def grid_sums(x: np.ndarray, a0: float, da: float, m: int) -> tuple[np.ndarray, np.ndarray]:
    """chirp_z_pair's sums by the sums themselves: with k = q p + r (r < q, q = ceil(sqrt(m))),
    exp(i a_k n) = exp(i a0 n) exp(i q da n)^p exp(i da n)^r, so sum_n x[j, n] exp(i a_k n) is the
    product of the rows x[j] exp(i a0 n) exp(i q da n)^p with the columns exp(i da n)^r; the doubled
    frequencies' of their squares. 3 N exponentials and their powers by repeated products (round-off
    of a power p eps, p < sqrt(m): about the FFT's eps log2(size))."""
    n = np.arange(x.shape[-1], dtype=float)
    q = math.isqrt(m - 1) + 1
    outer = _powers(q * da * n, -(-m // q)) * _unit(a0 * n)  # (p, N)
    inner = _powers(da * n, q).T  # (N, q)
    # one product per row (a single one of all rows would go to threaded BLAS)
    s1 = np.array([(outer * row) @ inner for row in x.astype(complex)]).reshape(x.shape[0], -1)[:, :m]
    s2 = ((outer * outer) @ (inner * inner)).reshape(-1)[:m]
    return s1, s2


def _unit(angles: np.ndarray) -> np.ndarray:
    """exp(i angles) from their cosines and sines (numpy's complex exp takes twice as long)."""
    out = np.empty(angles.shape, dtype=complex)
    np.cos(angles, out=out.real)
    np.sin(angles, out=out.imag)
    return out


def _powers(angles: np.ndarray, count: int) -> np.ndarray:
    """exp(i p angles) for p < count, (count, N), by repeated products of exp(i angles)."""
    out = np.empty((count, angles.size), dtype=complex)
    out[0] = 1.0
    out[1:] = _unit(angles)
    return np.cumprod(out, axis=0, out=out)


def chirp_z_pair(x: np.ndarray, a0: float, da: float, m: int) -> tuple[np.ndarray, np.ndarray]:
    """(sum_n x[j, n] exp(i a_k n), sum_n exp(2 i a_k n)), a_k = a0 + k da, k = 0..m-1, for the rows
    x[j] of x (J, N): shapes (J, m) and (m,). Bluestein's chirp z-transform: exp(i da k n) =
    exp(i da k^2 / 2) exp(i da n^2 / 2) exp(-i da (k - n)^2 / 2) makes the sum over n a convolution
    with the chirp exp(-i da j^2 / 2), j = k - n in [1 - N, m - 1], done by FFT; the doubled frequencies'
    chirp and weights are the squares of the first's."""
    n = x.shape[-1]
    size = _fast_size(n + m - 1)  # no wrap-around
    k = np.arange(max(n, m), dtype=float)
    chirp = np.exp(-0.5j * da * k * k)
    pre = np.exp(1j * a0 * k[:n]) * np.conj(chirp[:n])
    a = np.zeros((x.shape[0] + 1, size), dtype=complex)
    a[:-1, :n] = x * pre
    a[-1, :n] = pre * pre
    b = np.zeros((2, size), dtype=complex)
    b[0, :m], b[0, size - n + 1:] = chirp[:m], chirp[1:n][::-1]  # j = 0..m-1, then -(n-1)..-1 (even in j)
    b[1] = b[0] * b[0]
    fa, fb = np.fft.fft(a), np.fft.fft(b)
    fa[:-1] *= fb[0]
    fa[-1] *= fb[1]
    conv = np.fft.ifft(fa)[:, :m]
    post = np.conj(chirp[:m])
    return conv[:-1] * post, conv[-1] * (post * post)


def _fast_size(n: int) -> int:
    """The least 2^a 3^b 5^c >= n (a size the FFT does fast)."""
    best, p5 = 1 << max(n - 1, 0).bit_length(), 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            v = p35
            while v < n:
                v *= 2
            best = min(best, v)
            p35 *= 3
        p5 *= 5
    return best
