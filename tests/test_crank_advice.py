"""`ffrf-fmu advise models/conrod_crank.toml --system crank --tolerance 1% --check` (studies/crank_advice.py;
docs/inertia-terms.md, "The conrod in a crank drive"): the advice from the drive's kinematics and its check
against the converged monolithic reference. Shortened to 3 ms (the run-up and the first firing, 2.5-2.71 ms,
with 0.29 ms of its ringing; the full 7.5 ms with four firings takes ~50 s and is measured in the docs): the
rules' inputs are the same (crank speed, gas pulse, the modes), only the bending's build-up from revolution to
revolution near the 2 omega resonance is cut, which makes W1 a smaller but still leading term."""
from __future__ import annotations

import json
from pathlib import Path

MODEL = Path(__file__).resolve().parents[1] / "models" / "conrod_crank.toml"


def test_the_crank_drive_advice_holds_one_percent(capsys):
    """Modes: the gas pulse sin^4 over 60 deg at 5000 rad/s lasts 209.4 us, its highest harmonic 2 omega / width =
    9549 Hz; MODE_BAND 3 x that is 28.65 kHz, between the conrod's 12th (27.22 kHz) and 13th (29.05 kHz) free-free
    modes: 12. Step: the period error at 9549 Hz gives h <= 3.73 us, 2.5 us the largest nice step dividing 3 ms.
    Terms: linear and gyroscopic 1.3 % from full, W1 left out 1.32 % (2.3 % at 7.5 ms), above TERM_SHARE x 1 % / 4 =
    0.125 % by a factor 10, so `full` with W1 (measured on 3 ms; Coriolis 0.18 %, close to the threshold, is not
    asserted). The check must resolve (the reference's refinements each move it by < 0.1 %; measured 3.2e-6 and
    1.9e-4) and hold 1 % on both the axial and the bending deformation (measured 0.019 % and 0.009 %; at 7.5 ms
    0.027 % and 0.034 %)."""
    from ffrf_fmu.cli import build_parser

    parser = build_parser()
    args = parser.parse_args(["advise", str(MODEL), "--system", "crank", "--tolerance", "1%", "--check",
                              "--duration", "3e-3", "--json"])
    code = args.run(args)
    out = json.loads(capsys.readouterr().out)
    advice, check = out["advice"], out["check"]
    assert (advice["modes"], advice["step"], advice["terms"]) == (12, 2.5e-6, "full"), advice
    assert "inertia_W1" in advice["full_terms"], advice
    assert check["resolved"] and check["within_tolerance"] and code == 0, check
    assert check["axial"] < 0.01 and check["bending"] < 0.01, check
    assert check["reference"]["step"] < advice["step"] and check["reference"]["modes"] > advice["modes"], check


def test_a_body_not_of_the_crank_drive_is_refused(capsys):
    """--system crank on a model without the drive's ports: exit 2 naming them."""
    from ffrf_fmu.cli import build_parser

    model = MODEL.parent / "witteveen_beam.toml"
    args = build_parser().parse_args(["advise", str(model), "--system", "crank", "--tolerance", "1%"])
    assert args.run(args) == 2
    assert "big_eye" in capsys.readouterr().err
