"""The run-up of models/jeffcott_runup.toml against the analytic Jeffcott rotor: runs the scene (the reduced
body, 20000 steps), integrates the Jeffcott equation m z'' + k z = m e (psi'^2 - i psi'') exp(i psi) with the
same Wu-Haug speed profile (scipy solve_ivp, z = y + i z the disc's lateral deflection), prints both peaks and
draws docs/jeffcott_runup.png (docs/inertia-terms.md, "The Jeffcott rotor").

    python models/data/jeffcott/runup.py [docs/jeffcott_runup.png]
"""
import sys
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

ROOT = Path(__file__).resolve().parents[3]
MODEL = ROOT / "models" / "jeffcott_runup.toml"
E, D, L, RHO = 2.1e11, 0.020, 0.75, 7850.0  # the shaft (models/jeffcott_rotor.toml)
M_DISC, ME, K_BEARING = 5.5504, 5.5504e-4, 1.0e7


def jeffcott_constants() -> tuple[float, float]:
    """k [N/m] of the shaft (48 EI / L^3) in series with the two bearings, and the modal mass [kg]: the disc
    plus 17/35 of the shaft (Rayleigh, the static deflection shape of a central load on pinned ends)."""
    EI = E * np.pi * D**4 / 64
    k = 1.0 / (L**3 / (48 * EI) + 1.0 / (2 * K_BEARING))
    return k, M_DISC + 17.0 / 35.0 * RHO * np.pi * D**2 / 4 * L


def haug_speed(t, omega, T):
    """psi, psi', psi'' of the Wu-Haug spin-up (docs/model-format.md, haug_spinup)."""
    tau = np.minimum(t / T, 1.0)
    psi = np.where(t < T, omega * T * (tau**2 / 2 + (np.cos(2 * np.pi * tau) - 1) / (2 * np.pi) ** 2),
                   omega * T * (t / T - 0.5))
    dpsi = np.where(t < T, omega * (tau - np.sin(2 * np.pi * tau) / (2 * np.pi)), omega)
    ddpsi = np.where(t < T, omega / T * (1 - np.cos(2 * np.pi * tau)), 0.0)
    return psi, dpsi, ddpsi


def jeffcott_runup(omega, T, duration, t_eval):
    """|z(t)| of the undamped Jeffcott rotor run up with the Wu-Haug profile (an independent solver)."""
    k, m = jeffcott_constants()

    def rhs(t, s):
        psi, dpsi, ddpsi = haug_speed(t, omega, T)
        f = ME * (dpsi**2 - 1j * ddpsi) * np.exp(1j * psi)
        z, v = s[0] + 1j * s[1], s[2] + 1j * s[3]
        a = (f - k * z) / m
        return [v.real, v.imag, a.real, a.imag]

    sol = solve_ivp(rhs, (0.0, duration), [0.0, 0.0, 0.0, 0.0], t_eval=t_eval, rtol=1e-9, atol=1e-13, method="DOP853")
    return np.hypot(sol.y[0], sol.y[1])


def main(out=None):
    from ffrf_fmu.simulate import run_scene

    from ffrf_fmu.model import load_model

    sc = load_model(MODEL).scene("runup")
    terms = sc.terms + (f" ({' + '.join(sc.full_terms)})" if sc.terms == "full" else "")
    res = run_scene(str(MODEL))
    t = res.t
    r_ffrf = np.hypot(res.columns["disc.r[2]"], res.columns["disc.r[3]"])
    omega, T = 340.0, 10.0
    _, speed, _ = haug_speed(t, omega, T)
    r_sdof = jeffcott_runup(omega, T, t[-1], t)
    k, m = jeffcott_constants()
    wc = np.sqrt(k / m)
    for name, r in (("reduced body", r_ffrf), ("Jeffcott ODE", r_sdof)):
        i = int(np.argmax(r))
        print(f"{name}: peak {r[i] * 1e3:.4f} mm at t = {t[i]:.4f} s, Omega = {speed[i]:.2f} rad/s "
              f"({speed[i] / wc:.4f} x sqrt(k/m) = {wc:.2f} rad/s)")
    if out:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 4))
        ax.plot(speed, r_ffrf * 1e3, label=f"reduced body (jeffcott_runup.toml, terms {terms})")
        ax.plot(speed, r_sdof * 1e3, "--", label="Jeffcott ODE, same run-up")
        ax.axvline(wc, color="k", lw=0.8, ls=":", label=f"sqrt(k/m) = {wc:.1f} rad/s")
        ax.set_xlabel("spin speed [rad/s]")
        ax.set_ylabel("disc lateral deflection [mm]")
        ax.set_title("Jeffcott rotor run-up, 68 rad/s^2 at the critical speed, m e = 5.55e-4 kg m")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
