"""`dynid detect`'s out-of-sample account: whether the data lie outside the runs the model was fitted and calibrated
on, and each variant's false-positive rate there beside the in-sample calibration's (docs/detection.md)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..identify.model_sections import CROSS_VALIDATED, IN_SAMPLE
from ..identify.transfer import postures_text


def _overlap(a: tuple, b: tuple) -> bool:
    """Two windows [from, to] of a run's seconds (None: open) share some time."""
    lo = max(-np.inf if a[0] is None else a[0], -np.inf if b[0] is None else b[0])
    hi = min(np.inf if a[1] is None else a[1], np.inf if b[1] is None else b[1])
    return lo < hi


def _inside(t: np.ndarray, w: tuple) -> np.ndarray:
    return (t >= (-np.inf if w[0] is None else w[0])) & (t <= (np.inf if w[1] is None else w[1]))


def out_of_sample(identified, data: str, data_window: tuple, calibration_paths: list[str], calibration_given: bool,
                  calibration_window: tuple, variants: dict[str, dict[str, Any]],
                  t: np.ndarray | None = None) -> dict[str, Any]:
    """`detect --json`'s `out_of_sample`: whether DATA (in its --from/--to window) lies outside the runs, and their
    windows, the model was fitted and calibrated on (sha256), what Λ and T²_α were calibrated on, and per variant the
    FPR on DATA's contact-free samples (an out-of-sample figure where DATA is outside) beside the FPR the in-sample
    calibration gives on them. With DATA's times `t`, the share of its samples inside those windows (a window that
    touches the fit's by a sample is in-sample by that sample, not by all of its)."""
    from ..identify.model_file import data_digest

    digest = data_digest(data)
    seen = [(run.sha256, run.window or (None, None)) for run in identified.data if run.sha256 is not None]
    if calibration_given:
        seen += [(data_digest(p), calibration_window) for p in calibration_paths]
    same = [w for d, w in seen if digest is not None and d == digest]
    outside = digest is not None and not any(_overlap(w, data_window) for w in same)
    share = None
    if t is not None and np.size(t) and digest is not None:
        inside = np.zeros(np.size(t), dtype=bool)
        for w in same:
            inside |= _inside(np.asarray(t, float), w)
        share = float(inside.mean())
        outside = share == 0.0
    det = identified.detector
    calibration = {"calibrated": det.calibration if det is not None else IN_SAMPLE}
    for name in ("combined", "momentum"):
        if name in variants:
            calibration[name] = "given runs" if calibration_given else (
                CROSS_VALIDATED if identified.folds is not None else IN_SAMPLE)
    per = {}
    for name in ("combined", "momentum", "calibrated"):
        if name in variants:
            v = variants[name]
            per[name] = {"calibration": calibration[name], "fpr": v.get("fpr"),
                         "in_sample_calibration_fpr": v.get("in_sample_fpr")}
    return {"data_outside_fit_and_calibration": outside, "share_in_fit_and_calibration": share, "variants": per}


def print_out_of_sample(o: dict[str, Any]) -> None:
    if o.get("postures_outside_fit"):
        print("  note: postures the fit never saw: " + postures_text(o["postures_outside_fit"]) + ": the model is "
              "extrapolated there, and α holds on data like the fit's (docs/detection.md#out-of-sample)")
    share = o.get("share_in_fit_and_calibration")
    if o["data_outside_fit_and_calibration"]:
        where = "outside the fit and calibration"
    elif share is not None and share < 1.0:
        percent = 100 * share
        shown = f"{percent:.2g}" if percent < 99 else f"{percent:.1f}"  # never '1e+02'
        where = f"of which {shown} % was fitted or calibrated on (partly in-sample)"
    else:
        where = "among the runs fitted or calibrated on (an in-sample figure)"
    for name, v in o["variants"].items():
        if v["fpr"] is None:
            continue
        line = f"  {name}: FPR {100 * v['fpr']:.2f} % on data {where}, Λ and T²_α {v['calibration']}"
        if v["in_sample_calibration_fpr"] is not None:
            line += f"; calibrated in-sample: {100 * v['in_sample_calibration_fpr']:.2f} %"
        print(line)
