"""`ffrf-fmu validate`: one scene through the FMU under fmpy and standalone, every output compared.

    ffrf-fmu validate MODEL.toml --scene NAME [--comm-step H] [--report DIR] [--set k=v ...]
    ffrf-fmu validate Body.fmu --model MODEL.toml --scene NAME [...]
    ffrf-fmu validate MODEL.toml --fmi 3 ...     (the FMU built for FMI 3.0; an .fmu may be either version)

Given a model file, the FMU is built from it first (into DIR). Given an .fmu, the model file is
required (--model): the standalone reference needs the body, which an FMU deliberately does not
carry (it holds reduced matrices only), and the scene needs its drives and loads. The FMU's
reduced data is checked against the one the model gives (`fmu_matches_model` in the report).

The FMU runs under fmpy through the scene's inputs (fmu/run.py: the input table on the
communication grid, the FMU's own rule in between); the run must reach the scene's duration
(simulate_fmu stops early on fmi2Discard without raising). Every FMU output is
compared at the communication points with the standalone run of the same body under the FMU's input rule
(simulate.run_input_rule: the same sampled inputs, the same extrapolation and internal steps; like for like,
so the two agree to the Newton tolerance), per group (`port.part`, e.g.
`tip.r`, and the energies together): max_abs_diff, and max_rel_diff = max_abs_diff / max |standalone| of
the group. A group passes when max_rel_diff <= rtol (default 1e-3; groups whose standalone
values stay below `atol` pass on the absolute difference). The scene's benchmark metrics
(simulate.metrics, e.g. the maximum tip deflection of eq. 92) are computed from both runs. What the input
rule costs against the exact inputs at every step's end (simulate.run_scene) is reported apart, with the
rule's bound (`input_sampling`), never part of the verdict.

Times (report `wall_time_s`): the standalone runs go first, on the backend the FMU steps on (the time is the
one under the FMU's rule); the FMU's is the whole fmpy run.
"""
from __future__ import annotations

import json
from pathlib import Path

# numpy is imported by the functions that compute (the CLI reads the tolerances below without it)
DEFAULT_RTOL = 1e-3
DEFAULT_ATOL = 1e-9


class ValidationError(RuntimeError):
    """The validation could not run (bad arguments, missing model)."""


def _groups(names):
    """FMU output names -> {group: [names]}: `port.part` for port fields (e.g. tip.r), `energies`
    for the four energies together (scaled by the largest of them: a negligible energy, such as
    the elastic kinetic energy of B1, is judged against the energy level of the body)."""
    from .fmu.variables import parse_port_variable

    groups: dict[str, list[str]] = {}
    for n in names:
        if n.startswith("solver."):
            continue
        if n.startswith("energy."):
            g = "energies"
        else:
            try:
                port, fld, _ = parse_port_variable(n)
                g = f"{port}.{fld}"
            except ValueError:  # probes: one group each
                g = n.partition("[")[0]
        groups.setdefault(g, []).append(n)
    return groups


def common_span(fmu_t, ref_t) -> np.ndarray:
    """Mask of the FMU's times inside the reference's time span: past a reference that stopped early
    np.interp would hold its last value, and a comparison there would be against a value never computed."""
    import numpy as np

    fmu_t = np.asarray(fmu_t, dtype=float)
    return fmu_t <= ref_t[-1] + 1e-9 * max(1.0, abs(ref_t[-1]))


def compare(fmu_t, fmu_cols: dict, ref_t, ref_cols: dict, names, rtol: float, atol: float) -> dict:
    """Per-group differences at the FMU's communication points inside the reference's span (the
    reference interpolated); each group says up to which time it was compared (compared_until)."""
    import numpy as np

    out = {}
    inside = common_span(fmu_t, ref_t)
    fmu_t = np.asarray(fmu_t, dtype=float)[inside]
    for g, members in _groups(names).items():
        diff = 0.0
        scale = 0.0
        for n in members:
            ref = np.interp(fmu_t, ref_t, ref_cols[n])
            diff = max(diff, float(np.max(np.abs(np.asarray(fmu_cols[n])[inside] - ref))))
            scale = max(scale, float(np.max(np.abs(ref_cols[n]))))
        rel = diff / scale if scale > atol else 0.0
        passed = bool(diff <= atol) if scale <= atol else bool(rel <= rtol)
        out[g] = {"max_abs_diff": diff, "max_rel_diff": rel, "scale": scale, "passed": passed,
                  "compared_until": float(fmu_t[-1])}
    return out


def same_body(a, b, rtol: float = 1e-10) -> bool:
    """Same reduced data (ports, node positions, every superelement matrix) to round-off."""
    import numpy as np

    if [(p.name, p.node, p.translation, p.rotation) for p in a.ports] != \
            [(p.name, p.node, p.translation, p.rotation) for p in b.ports]:
        return False
    if len(a.superelements) != len(b.superelements) or not np.allclose(a.node_positions, b.node_positions):
        return False
    for x, y in zip(a.superelements, b.superelements):
        for key in ("K", "M", "G", "J0", "x_cm", "X_B"):
            u, v = np.asarray(getattr(x, key)), np.asarray(getattr(y, key))
            if u.shape != v.shape or not np.allclose(u, v, rtol=rtol, atol=rtol * max(np.max(np.abs(v)), 1e-300)):
                return False
    return True


def native_same_body(fmu_path, body, rtol: float = 1e-10) -> bool:
    """A native FMU's runtime images hold the reduced data of `body` (K, M, mass, J0, X_B) to round-off."""
    import zipfile

    import numpy as np

    from .fmu.native.resource import images
    from .fmu.run import NATIVE_RESOURCE
    from .runtime.layout import SuperelementStack
    from .runtime.native.image import unpack

    with zipfile.ZipFile(fmu_path) as z:
        imgs = images(z.read(NATIVE_RESOURCE))
    stack = SuperelementStack.of(body)
    for image in imgs.values():
        arrays = unpack(image)
        for key in ("K", "M", "mass", "J0", "X_B"):
            u, v = np.asarray(arrays[key]), np.asarray(getattr(stack, key))
            if u.shape != v.shape or not np.allclose(u, v, rtol=rtol, atol=rtol * max(np.max(np.abs(v)), 1e-300)):
                return False
    return bool(imgs)


def fmu_backend(fmu_path) -> str:
    """The backend the FMU steps on: native for a native FMU (fmu/native: the C runtime); for a pythonfmu FMU
    its resources' config (numpy for FMUs built before the choice, and for those built for the retired
    numba backend)."""
    import zipfile

    from .fmu.core import CONFIG_FILE
    from .fmu.run import is_native

    if is_native(fmu_path):
        return "native"
    with zipfile.ZipFile(fmu_path) as z:
        backend = json.loads(z.read(f"resources/{CONFIG_FILE}")).get("backend", "numpy")
    return backend if backend == "native" else "numpy"


def input_sampling(scene, H: float, sampled, continuous, names, model) -> dict:
    """What the FMU's input rule itself costs, reported beside the validation (never part of its verdict): the
    standalone run under the FMU's rule (`sampled`, simulate.run_input_rule) against the one with the exact inputs
    at every step's end (`continuous`, simulate.run), per output group, and per driven part the bound of the
    rule's input error (simulate.rule_error: second order in H; a compliant part's spring force error relative
    to that port's largest force here; docs/fmu.md, "Validation against the standalone run")."""
    import numpy as np

    from .simulate import rule_error

    groups = {g: {k: d[k] for k in ("max_abs_diff", "max_rel_diff", "scale")}
              for g, d in compare(sampled.t, sampled.columns, continuous.t, continuous.columns, names,
                                  np.inf, DEFAULT_ATOL).items()}
    parts = rule_error(scene, H, {p.name: (p.translation, p.rotation, dict(p.coupling)) for p in model.body.ports})
    for row in parts.values():
        if groups.get(row.get("group"), {}).get("scale", 0.0) > 0:
            row["force_error_bound_rel"] = row["force_error_bound"] / groups[row["group"]]["scale"]
    return {"comm_step": H, "groups": groups, "drives": parts,
            "note": "the standalone run under the FMU's input rule against the exact inputs at every step's end: "
                    "the input sampling's own error (not part of the verdict)"}


def validate(source, *, scene: str | None = None, model=None, overrides=(), comm_step: float | None = None,
             report_dir=None, rtol: float = DEFAULT_RTOL, atol: float = DEFAULT_ATOL, plots: bool = True,
             fmi: int = 2) -> dict:
    """Run the validation; returns the report (also written to report_dir/report.json). An .fmu may be FMI 2.0
    or 3.0; from a model file the FMU is built for FMI version `fmi` (2 or 3)."""
    import tempfile

    from .fmu.builder import build_fmu
    from .fmu.run import fmu_body, run_fmu
    from .model import load_model
    from .simulate import metrics, run_input_rule, run_scene, scene_inputs

    source = Path(source)
    report_dir = Path(report_dir) if report_dir else None
    if report_dir:
        report_dir.mkdir(parents=True, exist_ok=True)
    if source.suffix == ".fmu":
        if model is None:
            raise ValidationError(
                f"{source}: an FMU carries no model file (only reduced data): give the model with --model "
                "MODEL.toml for the scene and the standalone reference"
            )
        model_path = Path(model)
        fmu_path = source
        built = False
    else:
        model_path = source
        m0 = load_model(model_path, overrides)
        sc0 = m0.scene(scene)
        out_dir = report_dir or Path(tempfile.mkdtemp(prefix="ffrf_validate_"))
        fmu_path = build_fmu(model_path, out_dir / f"{m0.body.name}.fmu", scene=sc0.name, overrides=overrides,
                                    fmi=fmi)
        built = True
    mdl = load_model(model_path, overrides)
    sc = mdl.scene(scene)
    H = float(comm_step) if comm_step else sc.step
    fmu_data = fmu_body(fmu_path)
    ports = lambda b: [(p.name, p.node, p.translation, p.rotation) for p in b.ports]
    if not built:
        from .reduction import reduce_scene_body

        scene_body = reduce_scene_body(mdl.body, sc).data
        if ports(fmu_data) != ports(scene_body):
            raise ValidationError(
                f"{fmu_path}: the FMU's ports {ports(fmu_data)} differ from those of scene {sc.name!r} of "
                f"{model_path}: {ports(scene_body)} (build the FMU for this scene: ffrf-fmu build --scene {sc.name})"
            )

    backend = fmu_backend(fmu_path)
    continuous = run_scene(mdl, sc.name, backend=backend)  # the exact inputs at every step's end
    body = continuous.body
    ref = run_input_rule(body, sc, H, origin=mdl.body.origin, backend=backend)  # the inputs the FMU sees
    wall_ref = ref.summary["wall_time_s"]
    from .fmu.run import is_native

    matches = native_same_body(fmu_path, body) if is_native(fmu_path) else same_body(fmu_data, body)

    from fmpy import read_model_description

    run = run_fmu(fmu_path, sc, scene_inputs(body, sc, load_interval=(0.0, H)), H)  # loads held over (t, t + H]
    t_fmu, fmu_cols, reached, wall_fmu, log = run.t, run.columns, run.reached, run.wall_time_s, run.log
    from .fmu.run import scalar_names  # FMI 3.0 arrays by their elements, named as in FMI 2.0

    outputs = [n for v in read_model_description(str(fmu_path)).modelVariables if v.causality == "output"
               for n in scalar_names(v)]
    ref_ok = bool(ref.summary.get("completed", True))
    compared = [n for n in outputs if n in ref.columns]
    groups = compare(t_fmu, fmu_cols, ref.t, ref.columns, compared, rtol, atol)
    sampling = input_sampling(sc, H, ref, continuous, compared, mdl)

    # benchmark metrics of both runs (from port signals: the FMU side uses its own port values)
    fmu_result = run.result(body)
    metric_rows = {}
    m_fmu, m_ref = {}, {}
    if reached and ref_ok:  # a metric of a run that stopped early is not the scene's metric: not compared
        try:
            m_fmu, m_ref = metrics(fmu_result, sc), metrics(ref, sc)
        except Exception as e:  # noqa: BLE001 - metrics are informative, never block the report
            m_fmu, m_ref = {"error": str(e)}, {}
    for k, v in m_ref.items():
        if isinstance(v, float) and isinstance(m_fmu.get(k), float):
            metric_rows[k] = {"fmu": m_fmu[k], "standalone": v,
                              "rel_diff": abs(m_fmu[k] - v) / abs(v) if v else abs(m_fmu[k])}
    # an FMU of another model fails even when its outputs happen to agree within the tolerance
    passed = reached and ref_ok and matches and all(g["passed"] for g in groups.values())
    report = {
        "passed": passed,
        "fmu": str(fmu_path),
        "fmu_built_from_model": built,
        "fmu_matches_model": matches,
        "model": str(model_path),
        "overrides": list(overrides),
        "scene": sc.name,
        "duration": sc.duration,
        "internal_step": sc.step,
        "comm_step": H,
        "fmu_reached_stop_time": reached,
        "fmu_t_end": float(t_fmu[-1]),
        "standalone_completed": ref_ok,
        "standalone_failure": ref.summary.get("failure"),
        "tolerances": {"rtol": rtol, "atol": atol,
                       "rule": "group passes when max_abs_diff / max|standalone| <= rtol "
                               "(absolute max_abs_diff <= atol when max|standalone| <= atol)"},
        "groups": groups,
        "input_sampling": sampling,
        "metrics": metric_rows,
        "backend": {"fmu": backend, "standalone": ref.summary["backend"]},
        "wall_time_s": {"fmu": wall_fmu, "standalone": wall_ref,
                        "ratio_fmu_over_standalone": wall_fmu / wall_ref if wall_ref > 0 else None,
                        "note": "fmu: the whole fmpy run; standalone: the steps and their recording (simulate.run)"},
        "fmu_log": log[-50:],
        "input_treatment": "inputs sampled at the communication points; FMU and standalone run extrapolate motion "
                           "inputs with v, a (w, dw) and hold force inputs over each communication step (docs/fmu.md)",
    }
    if not matches:
        report["warning"] = ("the FMU's reduced data differs from what the model gives: it was built from another "
                             "model (validation FAILED whatever the outputs)")
    if report_dir:
        (report_dir / "report.json").write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
        if plots:
            report["plots"] = write_plots(report_dir, t_fmu, fmu_cols, ref, compared, sc, fmu_result)
            (report_dir / "report.json").write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    return report


def write_plots(report_dir: Path, t_fmu, fmu_cols, ref, compared, scene, fmu_result) -> list[str]:
    """DIR/port_<name>.png (each output part: both runs and their difference), DIR/energies.png,
    DIR/tip_deflection.png (eq. 92, both runs) for beams with a hub and a tip."""
    import numpy as np

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .simulate import elastic_tip, end_ports

    written = []

    def save(fig, name):
        fig.tight_layout()
        fig.savefig(report_dir / name, dpi=100)
        plt.close(fig)
        written.append(name)

    groups = _groups(compared)
    inside = common_span(t_fmu, ref.t)  # differences only where the standalone run has values
    t_in = t_fmu[inside]
    ports: dict[str, list[str]] = {}
    for g in groups:
        if g != "energies":
            ports.setdefault(g.split(".")[0], []).append(g)
    for port, gs in ports.items():
        fig, axes = plt.subplots(len(gs), 2, figsize=(12, 2.6 * len(gs)), squeeze=False, sharex=True)
        for row, g in enumerate(gs):
            for n in groups[g]:
                ref_i = np.interp(t_in, ref.t, ref.columns[n])
                line, = axes[row, 0].plot(ref.t, ref.columns[n], lw=1.2, label=f"{n} standalone")
                axes[row, 0].plot(t_fmu, fmu_cols[n], "--", lw=1.0, color=line.get_color(), label=f"{n} FMU")
                axes[row, 1].plot(t_in, fmu_cols[n][inside] - ref_i, lw=1.0, color=line.get_color(), label=n)
            axes[row, 0].set_ylabel(g)
            axes[row, 0].legend(fontsize=6, ncol=3, loc="best")
            axes[row, 1].set_ylabel(f"{g}: FMU - standalone")
            for ax in axes[row]:
                ax.grid(True, alpha=0.3)
        axes[-1, 0].set_xlabel("time [s]")
        axes[-1, 1].set_xlabel("time [s]")
        fig.suptitle(f"port {port}: FMU (dashed) vs standalone, scene {scene.name}")
        save(fig, f"port_{port}.png")
    energies = groups.get("energies", [])
    if energies:
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
        for n in energies:
            line, = a1.plot(ref.t, ref.columns[n], lw=1.2, label=f"{n} standalone")
            a1.plot(t_fmu, fmu_cols[n], "--", color=line.get_color(), label=f"{n} FMU")
            a2.plot(t_in, fmu_cols[n][inside] - np.interp(t_in, ref.t, ref.columns[n]), color=line.get_color(), label=n)
        a1.set_ylabel("energy [J]")
        a2.set_ylabel("FMU - standalone [J]")
        a2.set_xlabel("time [s]")
        for ax in (a1, a2):
            ax.legend(fontsize=7)
            ax.grid(True, alpha=0.3)
        save(fig, "energies.png")
    try:
        hub, tip = end_ports(ref.body)
        if hub != tip:
            d_ref, d_fmu = elastic_tip(ref, hub, tip), elastic_tip(fmu_result, hub, tip)
            fig, ax = plt.subplots(figsize=(10, 4))
            for i, c in enumerate("xyz"):
                line, = ax.plot(ref.t, d_ref[:, i], label=f"d_{c} standalone")
                ax.plot(t_fmu, d_fmu[:, i], "--", color=line.get_color(), label=f"d_{c} FMU")
            ax.set_xlabel("time [s]")
            ax.set_ylabel(f"elastic {tip} displacement seen from {hub} [m] (eq. 92)")
            ax.legend(fontsize=8)
            ax.grid(True, alpha=0.3)
            save(fig, "tip_deflection.png")
    except (KeyError, ValueError):
        pass
    return written
