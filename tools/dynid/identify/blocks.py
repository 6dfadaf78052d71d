"""Validation across a whole run: the run (after --from/--to) cut into k equal time blocks, each validated alone as
`dynid validate --from/--to` would validate it, with whether the model was fitted on its samples; then the worst
block, the spread and which blocks were in the fit (`dynid validate --blocks K`; no printing here).

A single held-out window says how the model does there; a robot's run holds postures, speeds and sensor states that
one window may miss (the iCub leg's fit is below CAD on the block after its window and 20 times CAD on the blocks
before and after it). Each block is cut from the run as loaded and evaluated on its own (its own filter edges, its
own CAD offsets and supply estimate), so a block's figures are exactly those of `validate --from T0 --to T1` with
the block's first and last sample times.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError
from ..io.dataset import Dataset
from ..io.derivatives import SavitzkyGolay
from ..io.load import MIN_WINDOW_SAMPLES, apply_window
from .model_file import IdentifiedModel, data_digest
from .validation import evaluate, validation

MIN_BLOCKS = 2  # one block is the single window `validate` already reports


@dataclass(frozen=True)
class TimeBlock:
    """Samples [start, stop) of the run as loaded (after --from/--to), and their first and last times."""

    index: int
    start: int
    stop: int
    t_first: float
    t_last: float


def filter_window_samples(config_derivatives: dict[str, Any], t: np.ndarray) -> int:
    """The samples the configuration's q̇, q̈ filter needs in a window (1 for a method without a fixed window)."""
    options = dict(config_derivatives)
    if options.pop("method", "savgol") != "savgol":
        return 1
    step = float(np.median(np.diff(t)))
    return SavitzkyGolay(**options).window_samples(step)


def time_blocks(t: np.ndarray, k: int, min_samples: int = MIN_WINDOW_SAMPLES,
                what: str = "the data") -> list[TimeBlock]:
    """k blocks of equal duration covering t[0] … t[-1]: block j holds the samples with t in [t0 + jT/k,
    t0 + (j+1)T/k), the last one t[-1] as well. Refused (one line) when k < 2 or a block holds fewer than
    `min_samples` samples."""
    if k < MIN_BLOCKS:
        raise InputError(f"--blocks {k}: give at least {MIN_BLOCKS} blocks (one block is the window `validate` "
                         "reports without --blocks)")
    t0, t1 = float(t[0]), float(t[-1])
    edges = t0 + (t1 - t0) * np.arange(1, k) / k
    bounds = [0, *np.searchsorted(t, edges, side="left").tolist(), int(t.size)]
    blocks = []
    for j in range(k):
        lo, hi = int(bounds[j]), int(bounds[j + 1])
        if hi - lo < min_samples:
            raise InputError(
                f"--blocks {k}: block {j + 1} of {what} ({(t1 - t0) / k:.3g} s each) holds {hi - lo} samples, fewer "
                f"than the {min_samples} the q̇, q̈ filter and a window need; give fewer blocks or a longer span")
        blocks.append(TimeBlock(j, lo, hi, float(t[lo]), float(t[hi - 1])))
    return blocks


def in_sample_share(overlap: float) -> str:
    """The share of a run's samples that are the fit's own, in words: "73 %", or "under 1 %"."""
    return f"{100 * overlap:.0f} %" if overlap >= 0.01 else "under 1 %"


def fitted_mask(identified: IdentifiedModel, data_path: str, t: np.ndarray) -> np.ndarray | None:
    """Which samples (times t of DATA) the model was fitted on: those of a fitted run with DATA's sha256 (or, for
    data without one, its path) inside that run's --from/--to window. None when nothing can tell (a run the model
    file records without sha256 nor path, e.g. a Dataset built in Python)."""
    digest = data_digest(data_path)
    real = os.path.realpath(data_path)
    mask = np.zeros(t.size, dtype=bool)
    known = False
    for run in identified.data:
        if run.sha256 is not None and digest is not None:
            same = run.sha256 == digest
        elif run.path:
            same = os.path.realpath(run.path) == real
        else:
            continue
        known = True
        if same:
            lo, hi = run.reload_window
            mask |= (t >= (-np.inf if lo is None else lo)) & (t <= (np.inf if hi is None else hi))
    return mask if known else None


def _ft_figures(table: dict[str, Any]) -> dict[str, float]:
    """A sensor's Table II as flat figures: identified and CAD mean error norms and their ratio, force and torque."""
    out = {}
    for what in ("force", "torque"):
        i, c = table["identified"][what]["mean"], table["cad"][what]["mean"]
        out[f"{what}_identified"] = i
        out[f"{what}_cad"] = c
        out[f"{what}_identified_vs_cad"] = i / c if c > 0 else float("nan")
    return out


def block_figures(result: dict[str, Any]) -> dict[str, float]:
    """The figures a block is compared by, named `<what>` (flat, for the summary): the overall relative error of
    the predicted inputs or torques and each channel's, the relative torque error, and per F/T sensor the
    identified and CAD error norms and their ratio."""
    figures: dict[str, float] = {}
    relative = result.get("relative_error")
    if relative:
        figures["relative_error.overall"] = relative["overall"]
        for name, v in relative["channels"].items():
            figures[f"relative_error.{name}"] = v["relative"]
    if "relative_torque_error" in result:
        figures["relative_torque_error"] = result["relative_torque_error"]
    for sensor, table in result.get("table_ii_sensors", {}).items():
        for name, v in _ft_figures(table).items():
            figures[f"ft.{sensor}.{name}"] = v
    return figures


def summary(blocks: list[dict[str, Any]]) -> dict[str, Any]:
    """Per figure: the worst block (the largest error), min / median / max over the blocks, and which blocks were
    in the fit."""
    per: dict[str, Any] = {}
    for name in blocks[0]["figures"]:
        values = np.array([b["figures"][name] for b in blocks], dtype=float)
        if not np.any(np.isfinite(values)):
            continue
        worst = int(np.nanargmax(values))
        best = int(np.nanargmin(values))
        per[name] = {"worst_block": worst, "best_block": best, "min": float(np.nanmin(values)),
                     "median": float(np.nanmedian(values)), "max": float(np.nanmax(values)),
                     "worst_in_fit": blocks[worst]["in_fit"]}
    in_fit = [b["index"] for b in blocks if b["in_fit"]]
    return {"figures": per, "blocks_in_fit": in_fit,
            "blocks_outside_fit": [b["index"] for b in blocks if b["in_fit"] is False]}


def validate_blocks(identified: IdentifiedModel, dataset: Dataset, k: int, model_label: str, data_label: str,
                    data_path: str | None = None, fitted: np.ndarray | None = None) -> dict[str, Any]:
    """`validate --blocks K`'s `blocks` (docs/formats.md): every block's validation, exactly as
    `validate --from t_first --to t_last` computes it, its overlap with the fit, and the summary. `fitted`: the
    data's `fitted_mask` where the caller has it (its data's sha256 read once)."""
    t = dataset.t
    need = max(MIN_WINDOW_SAMPLES, filter_window_samples(identified.config.derivatives, t))
    blocks = time_blocks(t, k, need, data_label)
    if fitted is None and data_path is not None:
        fitted = fitted_mask(identified, data_path, t)
    out = []
    for b in blocks:
        part = apply_window(dataset, b.t_first, b.t_last, source=data_label)
        if part.n_samples != b.stop - b.start:  # times strictly increase: a window of the block's own times is it
            raise RuntimeError(f"{data_label}: block {b.index + 1} cut to {part.n_samples} samples, "
                               f"not {b.stop - b.start}")
        ev = evaluate(model_label, data_label, identified, part)
        overlap = None if fitted is None else float(fitted[b.start : b.stop].mean())
        result = validation(ev, model_label, data_label, window=(b.t_first, b.t_last), fit_overlap=overlap)
        entry = {"index": b.index, "from": b.t_first, "to": b.t_last, "samples": b.stop - b.start,
                 "fit_overlap": overlap, "in_fit": None if overlap is None else overlap > 0,
                 "figures": block_figures(result), "validation": result}
        out.append(entry)
    return {"k": k, "span": [float(t[0]), float(t[-1])], "blocks": out, "summary": summary(out)}
