"""The advisor's calibration constants (advise.py), in one place, each with the runs it was
calibrated or checked on; docs/accuracy.md (section 4) has the derivations and the measurements.

A constant that comes from a measurement says which: benchmark, configuration, step, spin rate,
the measured number and how the constant follows from it. Changing one changes every advice:
tests/test_advise.py checks the rules on data not used for their calibration.
"""
from __future__ import annotations

# Error budget: the chain (geometric stiffening) may take CHAIN_SHARE of the tolerance; the step
# gets what the chain leaves up to RESERVE x tolerance (the rest is kept for the modal truncation
# and what the estimates miss). A choice, not a measurement.
CHAIN_SHARE = 0.85
RESERVE = 0.9
# Stiffened superelements (docs/equations.md, "Geometric stiffening"): each superelement carries its
# own centrifugal axial force, so a single one has the Southwell stiffening of the whole beam. What
# it still misses grows with the spin against its own first free-free frequency omega_se, which is
# Witteveen's in-superelement centrifugal indicator (Omega/omega_se)^2 (docs/inertia-terms.md): the
# predicted error of the peak deflection is STIFFENED_ERROR x (Omega_max/omega_se)^2.
# Calibration, on ONE point: B1, 1 SE, 2 modes, h = 10 ms, 4 rad/s, omega_se = 18.55 rad/s: +0.16 %
# measured for (4/18.55)^2 = 0.0465, i.e. 0.034; rounded up to 0.04. Checked on data not used here
# (tests/test_advise.py): B3 1 SE at 8, 12, 14 rad/s (measured 0.44 %, 0.78 %, 1.03 %; predicted
# 0.74 %, 1.67 %, 2.28 %: an upper bound, 1.7-2.2 x) and generated bodies (other length and stiffness).
STIFFENED_ERROR = 0.04
# Stiffening on when the spin's Southwell ratio (Omega/omega_1)^2 reaches 1 % (the stiffening
# changes the first frequency by more than ~0.5 %: NEGLIGIBLE of docs/inertia-terms.md). A threshold
# derived from the Southwell law, not fitted.
STIFFENING_SIGMA = 0.01
# The stiffened law is checked up to Omega/omega_se = 0.75 (B3 at 14 rad/s, 1 SE).
SPIN_RATIO_CHECKED = 0.75
# Step: B1's measured step error of the maximum deflection is 2.1 x the integrator's relative
# period error at the spin rate, for 2 and 4 superelements alike (0.115 % at h = 20 ms, 0.46 % at
# 40 ms; h^2). A one-mode model integrated with the same scheme predicts 20 x less: the step error
# comes from the large-rotation kinematics of the frames, not from the modal dynamics. Calibrated on
# the B1 chart (docs/chart_b1.csv, docs/accuracy.md section 4).
STEP_ERROR_FACTOR = 2.1
# Through the FMU with communication step = internal step, the hub motion is extrapolated over each
# communication step from (R, w) at its start (docs/fmu.md): the angular acceleration is missed over
# the step. Measured on B1 (5 SE): +0.024 % (8 ms), +0.10 % (16 ms), +0.41 % (32 ms): h^2, 2.9 x
# the period error at the spin rate on top of the standalone step error (2 SE: +0.41 % at 32 ms too).
FMU_INPUT_FACTOR = 2.9
# Modes above MODE_BAND x the highest excitation frequency respond quasi-statically and are dropped;
# at least MIN_MODES (the first bending pair, which carries the static response to distributed
# inertial loads) are kept. Choices (a dynamic amplification below 1.13 at a third of a mode's
# frequency), not fitted.
MODE_BAND = 3.0
MIN_MODES = 2
# Resolve the drive's time scale (a spin-up's T) with at least this many steps: on B1 (T = 15 s)
# Newton converges at h = 40 ms (T/375) with 2 and 4 superelements and fails at 50 ms (T/300) and
# above (the B1 chart of 2026-11-22, docs/accuracy.md section 2). An empirical robustness limit of that
# chart's Newton: today's runs B1 through at 50 and 100 ms and fails at 200 ms (tests/test_stability.py,
# T = 7.5 s), so the limit is conservative by about 4 x (docs/accuracy.md section 4.3).
STEPS_PER_DRIVE_TIME = 400
MAX_SUPERELEMENTS = 32  # the chain search stops here (a cap, with a warning in the advice)
# Geometric nonlinearity inside a superelement (its elastic kinematics are linear): the steady deflection
# inside one superelement, theta = u_max / (N L), costs NONLINEAR_ERROR x theta^2 of the response.
# Calibration, ONE point: coned_beam (3 deg cone, 2 rad/s), the converged chain against the linear FE
# beam: -1.2 % at theta = 5.2 % (docs/inertia-terms.md), i.e. 4.4 (the softening's amplification
# 1.9 included). Checked: 0.3 deg cone, theta = 0.53 %: predicted 1.2e-4, measured 8e-5.
NONLINEAR_ERROR = 4.4
# Per-step cost against 1 superelement `linear`, per backend (benchmarks/term_cost.py on disk_rotor, 2 modes,
# h = 10 ms, CPU, best of 3, ratios within one run). The advisor prices with the backend that will run.
# numpy (`python benchmarks/term_cost.py --backend numpy`, 2026-11-25): linear x 1.14 / 1.40 / 1.68 with 2 / 4 / 8
# superelements, i.e. 0.13 per added superelement up to 4 (the step's fixed Python and LU overhead dominates
# a short chain); gyroscopic x 1.35 and full x 2.71 at 1 SE (full x 2.95 at 2 SE).
# native (C runtime; `python benchmarks/term_cost.py --backend native`, 2026-11-27, load ~1): linear x 1.14 with
# 2 superelements, i.e. 0.14 per added one; gyroscopic x 0.91, full x 1.03 at 1 SE (x 1.69 at 2 SE): in compiled
# code the inertia products cost little next to the iteration matrix. Its dense LU grows as the cube of the
# unknowns: x 5.8 / 43 at 4 / 8 SE in that run, above the linear rule.
LINEAR_COST_PER_SE = {"numpy": 0.13, "native": 0.14}
TERM_COST = {"numpy": {"linear": 1.0, "gyroscopic": 1.35, "full": 2.71},
             "native": {"linear": 1.0, "gyroscopic": 0.91, "full": 1.03}}
