"""`dynid report`: the identification report of issue 4 as one self-contained HTML page.

    dynid report --model MODEL --validation DATA --contact DATA --out REPORT.html
                 [--truth TRUTH.json] [--alpha A] [--n-mode dim|nu] [--window S] [--json FILE]

It holds the paper's Table II and the detection numbers beside the paper's, per-channel residuals against the
noise, T² on the contact-free validation run (the paper's Fig. 3) and on the contact run with the skin's
contacts shaded by side of the F/T sensor (Fig. 4), the ROC with the α point (Fig. 5), predicted against
measured F/T and PWM in a representative window, the motor gains of every estimator, and every base parameter
identified against CAD against true (the truth.json of a `dynid simulate` run, when there is one). Numbers
come from the same functions as `dynid validate` and `dynid detect` (dynid.identify.validation, dynid.detect.evaluation), so they agree.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..detect.evaluation import add_stored_default, detection
from ..errors import DataError
from ..identify.blocks import fitted_mask, in_sample_share
from ..identify.model_file import IdentifiedModel, load_model
from ..identify.validation import Evaluated, cad_ft_residuals, evaluate, load_run, validation
from ..io.bad_rows import DEFAULT_POLICY
from ..io.dataset import atomic_write
from ..io.episodes import episodes_in_data, episodes_mask, read_episodes
from ..paper import PAPER, PAPER_ROBOT
from ..progress import track
from ..robot.outputs import measured_outputs
from ..robot.parameters import WRENCH_FIELDS
from . import html as H
from .params import find_truth, gains_by_estimator, parameter_table, truth_summary

DEFAULT_WINDOW_S = 6.0


def representative_window(t: np.ndarray, e: np.ndarray, sigma: np.ndarray, window_s: float) -> slice:
    """The window whose residual size (mean of e²/σ² over channels) is the median of all windows: neither the
    best nor the worst stretch of the run."""
    n = int(np.searchsorted(t, t[0] + window_s))
    if n <= 0 or n >= t.size:
        return slice(0, t.size)
    count = t.size // n
    energy = np.mean((e[: count * n] / sigma) ** 2, axis=1).reshape(count, n).mean(axis=1)
    k = int(np.argsort(energy)[(count - 1) // 2])
    return slice(k * n, (k + 1) * n)


def raw_outputs(ev: Evaluated, names: list[str]) -> np.ndarray:
    """The measured outputs as recorded (unfiltered), in output-channel order."""
    ds, cols = ev.dataset, []
    for name in names:
        family, _, rest = name.partition(".")
        if family == "ft":
            sensor, field = rest.rsplit(".", 1)
            cols.append(ds.ft[sensor][:, WRENCH_FIELDS.index(field)])
        else:
            cols.append({"pwm": ds.pwm, "current": ds.current, "tau": ds.tau}[family][rest])
    return np.column_stack(cols)


def rates_text(s: dict[str, Any]) -> str:
    tpr = "n/a" if s.get("tpr") is None else f"{100 * s['tpr']:.1f} %"
    line = f"TPR {tpr}, FPR {100 * s['fpr']:.2f} %"
    side = {k: v for k, v in (s.get("tpr_by_side") or {}).items() if v is not None}
    return line + ("".join(f", {k} {100 * v:.1f} %" for k, v in side.items()))


@dataclass(frozen=True)
class ReportSettings:
    """What a report is made of: the model file, a contact-free validation run and, where one exists, a run with
    contact ground truth (a real robot's logs seldom have one: the detection section then shows the validation
    run's false positives only)."""

    model: str
    validation: str
    contact: str | None
    out: str
    truth: str | None = None  # truth.json; default: the one `dynid simulate` wrote beside the data
    alpha: float = 0.99
    n_mode: str = "dim"
    window: float = DEFAULT_WINDOW_S  # s, the predicted-against-measured window
    gaps: str | None = None  # a `dynid gaps --figures DIR` directory to add as a section
    validation_window: tuple[float | None, float | None] = (None, None)  # the data's own seconds (--from/--to)
    contact_window: tuple[float | None, float | None] = (None, None)
    bad_rows: str = DEFAULT_POLICY  # a log's bad rows: refused or skipped (dynid.io.bad_rows)
    episodes: str | None = None  # contact labels for the contact run (`dynid detect --episodes`'s form)


def write_report(args: ReportSettings) -> dict[str, Any]:
    """Evaluate, draw and write the page atomically; returns `dynid report --json`."""
    out = Path(args.out)
    if not out.parent.is_dir():  # before minutes of work, not after
        raise DataError(f"cannot write '{out}': the directory {out.parent} does not exist")
    if out.exists() and not out.is_file():
        raise DataError(f"cannot write '{out}': it exists and is not a regular file")
    gaps_section = None
    if args.gaps:  # read before minutes of work: a bad directory fails at once
        from .gaps_figures import report_section

        gaps_section = report_section(args.gaps)
    identified = load_model(args.model)
    model = identified.robot_model
    gaps_robot = gaps_section[1].get("robot") if gaps_section is not None else None
    if gaps_robot is not None and gaps_robot != model.config.name:
        raise DataError(f"{args.gaps}: the gaps of {gaps_robot}, not of {model.config.name} ({args.model})")
    labels = read_episodes(args.episodes) if args.episodes else None  # a bad file: refused before any work
    if labels is not None and args.contact is None:
        raise DataError("--episodes labels the contact run: give it with --contact")
    ds_val = load_run(args.validation, model, args.validation_window, bad_rows=args.bad_rows)
    ds_con = None
    if args.contact is not None:
        ds_con = load_run(args.contact, model, args.contact_window, bad_rows=args.bad_rows)
        if labels is not None:  # the labels replace the run's own contact column, as in `dynid detect`
            episodes_in_data(ds_con.t, labels, args.episodes)
            ds_con = replace(ds_con, contact=episodes_mask(ds_con.t, labels))
        if ds_con.contact is None:
            raise DataError(f"{args.contact} has no 'contact' column: the contact figure and TPR need the skin's "
                            "ground truth (a `dynid simulate --kind contact` run has one) or labels (--episodes "
                            "LABELS.csv); leave --contact out to report without them")
    truth = find_truth(identified, [args.validation] + ([args.contact] if args.contact else []), args.truth)
    params = parameter_table(identified, truth)
    state: dict[str, Any] = {}

    def evaluate_validation() -> None:
        ev = state["val"] = evaluate(args.model, args.validation, identified, ds_val)
        state["cad_e"] = cad_ft_residuals(ev)
        fitted = fitted_mask(identified, args.validation, ev.dataset.t)
        state["validation"] = validation(ev, args.model, args.validation, state["cad_e"], args.validation_window,
                                         None if fitted is None else float(fitted.mean()))
        state["det_val"] = detection(ev, args.model, args.validation, args.alpha, args.n_mode)
        state["default_skipped"] = add_stored_default(ev, state["det_val"], args.alpha)

    def evaluate_contact() -> None:
        if ds_con is None:
            state["con"] = state["det_con"] = None
            return
        ev = state["con"] = evaluate(args.model, args.contact, identified, ds_con)
        state["det_con"] = detection(ev, args.model, args.contact, args.alpha, args.n_mode)
        if state["default_skipped"] is None:
            add_stored_default(ev, state["det_con"], args.alpha)

    def draw() -> None:
        state["figures"], state["window_s"] = _figures(state, args)

    for step in track([evaluate_validation, evaluate_contact, draw], 3, "report"):
        step()

    v, dv, dc = state["validation"], state["det_val"], state["det_con"]
    ev_val = state["val"]
    units = {o.name: o.unit for o in ev_val.outputs}
    result: dict[str, Any] = {
        "model": args.model, "robot": identified.config.name, "estimator": identified.estimator,
        "out": str(out), "alpha": args.alpha, "n_mode": args.n_mode,
        "validation": v, "detection": {"validation": dv.result, "contact": None if dc is None else dc.result},
        # The paper's figures describe its arm only: no reference rows for another robot.
        "paper": ({k: list(x) if isinstance(x, tuple) else x for k, x in PAPER.items()}
                  if identified.config.name == PAPER_ROBOT else None),
        "truth": truth.path if truth else None, "parameters": params, "truth_check": truth_summary(params),
        "motor_gains": gains_by_estimator(identified, truth), "window_s": state["window_s"],
        "default_skipped": state["default_skipped"],
        "figures": [f[0] for f in state["figures"]],
    }
    html_text = _page(result, identified, units, state["figures"])
    if gaps_section is not None:  # `dynid gaps --figures DIR`: its section goes before the closing tags
        extra, gaps = gaps_section
        html_text = html_text.replace("\n</body></html>", "\n" + "\n".join(extra) + "\n</body></html>")
        result["gaps"] = {"dir": args.gaps, "effects": gaps.get("effects", []), "gap": gaps["gap"]}
    atomic_write(out, lambda f: f.write(html_text.encode("utf-8")))

    return result


def _figures(state: dict[str, Any], args: ReportSettings) -> tuple[list[tuple[str, str, bytes]], list[float]]:
    """(id, caption, PNG) of every figure, and the time window of the traces."""
    from . import figures as figs  # matplotlib: loaded only when a report is drawn

    ev_val, ev_con, dv, dc = state["val"], state["con"], state["det_val"], state["det_con"]
    alpha = args.alpha
    out = []
    t = ev_val.dataset.t
    fpr = {k: s["fpr"] for k, s in dv.result["variants"].items()}
    thresholds = {k: d.threshold for k, d in dv.detectors.items()}
    out.append(("fig-t2-validation", f"T² on the contact-free validation run ({args.validation}) with the threshold "
                f"at α = {alpha:g}, both variants (the paper's Fig. 3)",
                figs.t2_validation(t - t[0], dv.t2, thresholds, fpr, alpha)))
    if ev_con is None:  # no run with contact ground truth
        return _trace_figures(out, state, args)
    tc = ev_con.dataset.t
    rates = {k: rates_text(s) for k, s in dc.result["variants"].items()}
    skin = bool(ev_con.config.can.get("skin"))
    truth = "the skin's contact periods" if skin else "the contact periods of the run's contact column"
    sides = ", distal and proximal of the F/T sensor in two colours" if ev_con.config.ft_sensors else ""
    out.append(("fig-t2-contact", f"T² on the contact run ({args.contact}); {truth} shaded{sides} (the paper's Fig. 4)",
                figs.t2_contact(tc - tc[0], dc.t2, thresholds, ev_con.dataset.contact, dc.side, rates)))
    curves = {k: s["roc"] for k, s in dc.result["variants"].items() if "roc" in s}
    if curves:
        points = {k: (s["fpr"], s["tpr"]) for k, s in dc.result["variants"].items() if k in curves}
        auc = {k: s["auc"] for k, s in dc.result["variants"].items() if k in curves}
        out.append(("fig-roc", f"ROC on the contact run, the operating point at α = {alpha:g} marked "
                    "(the paper's Fig. 5); right: the same on a logarithmic FPR axis", figs.roc(curves, points, auc, alpha)))
    return _trace_figures(out, state, args)


def _trace_figures(out: list, state: dict[str, Any], args: ReportSettings) -> tuple[list[tuple[str, str, bytes]], list[float]]:
    """`out` plus the predicted-against-measured traces of the validation run."""
    from . import figures as figs

    ev_val = state["val"]
    t = ev_val.dataset.t
    names = [o.name for o in ev_val.outputs]
    sigma = np.array([o.sigma for o in ev_val.outputs])
    w = representative_window(t, ev_val.e, sigma, args.window)
    y = measured_outputs(ev_val.model, ev_val.signals)[w]
    predicted = y - ev_val.e[w]
    ft_rows = [o.row for o in ev_val.outputs if o.kind == "ft"]
    cad = {} if state["cad_e"] is None else {r: y[:, r] - state["cad_e"][w][:, k] for k, r in enumerate(ft_rows)}
    tw = t[w] - t[0]
    out.append(("fig-traces", f"Predicted against measured outputs on the validation run, {tw[0]:.1f}–{tw[-1]:.1f} s "
                "(the window of median residual size); grey: as recorded; blue: the identified model; red dashed: "
                f"the CAD parameters (F/T only: a CAD model predicts no {input_words(ev_val)})",
                figs.traces(tw, names, [o.unit for o in ev_val.outputs], raw_outputs(ev_val, names)[w], predicted, cad)))
    return out, [float(tw[0]), float(tw[-1])]


def _page(r: dict[str, Any], identified: IdentifiedModel, units: dict[str, str],
          figures: list[tuple[str, str, bytes]]) -> str:
    base = identified.base
    data = ", ".join(H.esc(p) for p in identified.data_paths)
    alpha = r["alpha"]
    shown = {fid: H.figure(fid, png, caption) for fid, caption, png in figures}
    v = r["validation"]
    words = input_words(identified)
    sections = [
        f"<p>Model <code>{H.esc(r['model'])}</code> of <b>{H.esc(r['robot'])}</b>, estimator "
        f"<b>{H.esc(r['estimator'])}</b>, fitted on {data}: base-parameter rank {H.esc(None if base is None else base.rank)}, "
        f"{0 if base is None else int(base.identified.sum())} combinations determined; PLS ν = "
        f"{H.esc(identified.n_components)}. "
        f"Validation run <code>{H.esc(v['data'])}</code> ({v['samples']} samples), "
        + (f"contact run <code>{H.esc(r['detection']['contact']['data'])}</code>. " if r["detection"]["contact"]
           else "no run with contact ground truth. ")
        + (f"True parameters from <code>{H.esc(r['truth'])}</code>." if r["truth"] else "No true parameters known.")
        + "</p>",
        "<h2>Prediction error (the paper's Table II)</h2>",
        (f"<p class=\"note\">{in_sample_share(v['fit_overlap'])} of the validation run's samples are the fit's own (its "
         "run, inside its window): the figures below are in-sample, not a validation on data the model never saw. "
         "Validate on another run or window.</p>" if v.get("fit_overlap") else ""),
        (f"<p class=\"note\">{100 * v['contact_fraction']:.1f} % of the validation run's samples are in contact (its "
         "contact column): the errors below include the contact forces the model does not predict, and the false "
         "positives below count its contacts as false. Validate on a contact-free run (or a window of one).</p>"
         if v.get("contact_fraction") else ""),
        _tables_ii(v, r["paper"]),
        ("<p class=\"note\">Norm of the F/T prediction error on the validation run. CAD: the URDF inertia with the "
         "F/T offsets that fit it best on the identification data."
         + (" Paper: the real iCub arm (Traversaro et al. 2013)." if r["paper"] else "") + "</p>")
        if "table_ii" in v or v.get("table_ii_sensors") else "",
        _relative_errors(v),
        "<h3>Per channel</h3>", H.channels(v, units),
        f"<p class=\"note\">The CAD model has no friction and no motor gains: its {words} prediction is undefined.</p>",
        "<h2>Contact detection</h2>",
        H.detection(r["detection"]["validation"], r["detection"]["contact"], r["paper"], alpha)
        if r["detection"]["contact"] else H.false_positives(r["detection"]["validation"], alpha),
        f"<p class=\"note\">α = {alpha:g}. <i>combined</i> (`dynid detect`'s default, and the monitor's): the "
        "momentum observer's and the acceleration residuals' T², each over its level, summed, over κ; "
        "<i>momentum</i>: the observer's T² alone; both from the detectors the model file keeps"
        + (f" (not shown: {H.esc(r['default_skipped'])})" if r.get("default_skipped") else "")
        + ". <i>calibrated</i>: the acceleration residuals' T², motor channels at "
        "rest left out, Λ and the threshold from cross-validated residuals of the identification data. The figures "
        "draw the two acceleration variants' T², as the paper's. <i>paper</i>: diagonal Λ and the F "
        f"threshold with n = {'dim(e)' if r['n_mode'] == 'dim' else 'ν'}."
        + (f" Distal contacts show in the F/T, proximal ones only in the {words}." if "table_ii" in v else "") + "</p>",
        shown["fig-t2-validation"], shown.get("fig-t2-contact", ""), shown.get("fig-roc", ""),
        "<h2>Predicted against measured</h2>", shown["fig-traces"],
        "<h2>Motor gains by estimator</h2>", H.gains(r["motor_gains"], r["estimator"]),
        "<p class=\"note\">Closed-loop data bias least squares and PLS towards small gains; instrumental variables "
        "(iv) remove that bias.</p>",
        "<h2>Base parameters: identified, CAD, true</h2>",
        "<p class=\"note\">Each base parameter is the combination shown (the data determine only those). ± se: "
        "jackknife standard error over time blocks; determined: the fit's flag (standard error small against the "
        "value). CAD is undefined (—) for combinations with friction, gains or no CAD value.</p>",
        _truth_note(r["truth_check"]),
        H.parameters(r["parameters"], r["truth"] is not None) if r["parameters"] else
        "<p class=\"note\">This model file holds no base-parameter statistics: an augmented model of <code>dynid "
        "gaps</code> (its named effects refitted with the standard model) carries its Φ only; the report of the "
        "<code>dynid fit</code> model it started from has them.</p>",
    ]
    return H.page(f"dynid identification report: {r['robot']}", sections)


def input_words(source: Any) -> str:  # an Evaluated or an IdentifiedModel: anything with a `config`
    """What the motor rows predict, in words: "PWM", "current", "joint torque" (several joined by "and")."""
    kinds = sorted({g.input for g in source.config.actuation})
    return " and ".join({"pwm": "PWM", "current": "current", "torque": "joint torque"}[k] for k in kinds) or "input"


def _truth_note(check: dict[str, Any] | None) -> str:
    if not check:
        return ""
    return (f"<p>Against the truth, the {check['determined']} determined combinations are off by "
            f"<span data-key=\"truth_check/rms_error_in_se\" data-value=\"{check['rms_error_in_se']!r}\">"
            f"{check['rms_error_in_se']:.2f}</span> standard errors RMS; "
            f"<span data-key=\"truth_check/within_2se\" data-value=\"{check['within_2se']!r}\" data-scale=\"100.0\">"
            f"{100 * check['within_2se']:.0f}</span> % lie within 2 se (honest errors: about 1 and 95 %).</p>")


def _relative_errors(v: dict[str, Any]) -> str:
    """`dynid validate`'s relative errors of the predicted inputs or torques, ‖K(y − ŷ)‖ / ‖K y‖: the figure of a
    robot without an F/T sensor (the Panda's torques, the UR10e's currents), beside Table II where there is one."""
    rel = v.get("relative_error")
    if not rel:
        return ""
    key = "validation/relative_error"
    rows = [H.text("overall") + H.num(rel["overall"], ".2f", f"{key}/overall", 100.0)]
    rows += [H.text(c) + H.num(x["relative"], ".2f", f"{key}/channels/{c}/relative", 100.0)
             for c, x in rel["channels"].items()]
    filtered = v.get("relative_torque_error")
    note = (f" Filtered (both sides through the derivative filter, as the fit sees them): "
            f"{100 * filtered:.2f} %." if filtered is not None else "")
    return ("<h3>Relative error of the predicted inputs and torques</h3>"
            + H.table(["channel", "‖K(y − ŷ)‖ / ‖K y‖, %"], rows)
            + f"<p class=\"note\">Against the {H.esc(rel.get('measured', 'raw'))} measurements, K "
            f"{H.esc(rel.get('weights', ''))}.{note}</p>")


def _tables_ii(v: dict[str, Any], paper: dict[str, Any] | None) -> str:
    """Table II, one per F/T sensor when the configuration has several."""
    sensors = list(v.get("table_ii_sensors", {}))
    if not sensors:
        return "<p class=\"note\">No F/T sensor: no Table II.</p>" if "table_ii" not in v else H.table_ii(v, paper)
    if len(sensors) == 1:
        return H.table_ii(v, paper)
    return "\n".join(f"<h3>{H.esc(s)}</h3>" + H.table_ii(v, None, s) for s in sensors)
