"""The report's figures, drawn with matplotlib's Agg canvas (headless: no pyplot, no display) as PNG bytes.

Long traces are drawn as a min/max envelope over ~2000 bins: a 1 kHz run of minutes has more samples than
the figure has pixels, and the envelope keeps every peak of T² that could cross the threshold.
"""

from __future__ import annotations

import io
from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from ..io.dataset import contact_episodes

COLORS = {"combined": "#2ca02c", "momentum": "#8c564b", "calibrated": "#1f77b4", "paper": "#d62728", "distal": "#ff7f0e",
          "proximal": "#9467bd"}
BINS = 2000


def png(fig: Figure, dpi: int = 96) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    return buf.getvalue()


def envelope(t: np.ndarray, y: np.ndarray, bins: int = BINS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, min, max) of y over `bins` equal runs of samples (the raw samples when there are fewer)."""
    if y.size <= 2 * bins:
        return t, y, y
    edges = np.linspace(0, y.size, bins + 1).astype(int)
    return t[edges[:-1]], np.minimum.reduceat(y, edges[:-1]), np.maximum.reduceat(y, edges[:-1])


def _t2_axis(ax, t: np.ndarray, t2: np.ndarray, threshold: float, variant: str, label: str) -> None:
    tt, lo, hi = envelope(t, np.maximum(t2, 1e-3))
    ax.fill_between(tt, lo, hi, color=COLORS[variant], linewidth=0.6, step="post")
    ax.axhline(threshold, color="k", linestyle="--", linewidth=1.0, label=f"threshold {threshold:.3g}")
    ax.set_yscale("log")
    ax.set_ylabel("T²")
    ax.set_title(label, fontsize=10, loc="left")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(True, which="major", alpha=0.3)


def t2_validation(t: np.ndarray, t2: dict[str, np.ndarray], thresholds: dict[str, float],
                  fpr: dict[str, float], alpha: float) -> bytes:
    """Fig. 3: T² on the contact-free validation run with each variant's threshold."""
    fig = Figure(figsize=(10, 2.4 * len(t2)))
    axes = fig.subplots(len(t2), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (variant, values) in zip(axes, t2.items()):
        _t2_axis(ax, t, values, thresholds[variant], variant,
                 f"{variant}: false-positive rate {100 * fpr[variant]:.2f} % (promised {100 * (1 - alpha):.0f} %)")
    axes[-1].set_xlabel("time (s)")
    return png(fig)


def t2_contact(t: np.ndarray, t2: dict[str, np.ndarray], thresholds: dict[str, float], contact: np.ndarray,
               side: np.ndarray | None, rates: dict[str, str]) -> bytes:
    """Fig. 4: T² on the contact run, the skin's contact periods shaded by side of the F/T sensor."""
    fig = Figure(figsize=(10, 2.6 * len(t2)))
    axes = fig.subplots(len(t2), 1, sharex=True, squeeze=False)[:, 0]
    truth = contact != 0
    sides = {"distal": truth & (side > 0), "proximal": truth & (side < 0)} if side is not None else {"contact": truth}
    for ax, (variant, values) in zip(axes, t2.items()):
        for name, mask in sides.items():
            for a, b in contact_episodes(mask):
                ax.axvspan(t[a], t[min(b, t.size - 1)], color=COLORS.get(name, "#aaaaaa"), alpha=0.25, linewidth=0)
        _t2_axis(ax, t, values, thresholds[variant], variant, f"{variant}: {rates[variant]}")
        handles, labels = ax.get_legend_handles_labels()
        handles += [Patch(color=COLORS.get(n, "#aaaaaa"), alpha=0.25) for n in sides]
        labels += [f"contact, {n}" if n != "contact" else "contact" for n in sides]
        ax.legend(handles, labels, loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time (s)")
    return png(fig)


def roc(curves: dict[str, dict], points: dict[str, tuple[float, float]], auc: dict[str, float], alpha: float) -> bytes:
    """Fig. 5 as PNG (`roc_figure`)."""
    return png(roc_figure(curves, points, auc, alpha))


def roc_figure(curves: dict[str, dict], points: dict[str, tuple[float, float]], auc: dict[str, float],
               alpha: float) -> Figure:
    """Fig. 5: ROC of each variant with its operating point at α marked; linear and logarithmic FPR."""
    fig = Figure(figsize=(10, 4.2))
    axes = fig.subplots(1, 2)
    for ax, scale in zip(axes, ("linear", "log")):
        for variant, c in curves.items():
            fpr, tpr = np.asarray(c["fpr"]), np.asarray(c["tpr"])
            if scale == "log":
                keep = fpr > 0
                fpr, tpr = fpr[keep], tpr[keep]
            ax.plot(fpr, tpr, color=COLORS[variant], label=f"{variant} (AUC {auc[variant]:.3f})")
            x, y = points[variant]
            ax.plot([max(x, 1e-5)], [y], "o", color=COLORS[variant], markeredgecolor="k",
                    label=f"{variant} at α = {alpha:g}: TPR {100 * y:.1f} %, FPR {100 * x:.2f} %")
        chance = np.logspace(-5, 0, 200)  # TPR = FPR: a straight segment between its ends is no diagonal on a log axis
        ax.plot(chance, chance, ":", color="grey", linewidth=0.8, gid="chance")
        ax.set_xscale(scale)
        if scale == "log":
            ax.set_xlim(1e-4, 1)
        else:
            ax.set_xlim(0, 1)
        ax.set_ylim(0, 1.01)
        ax.set_xlabel("false-positive rate" + (" (log)" if scale == "log" else ""))
        ax.set_ylabel("true-positive rate")
        ax.grid(True, alpha=0.3)
    axes[1].legend(loc="lower right", fontsize=8)
    return fig


def traces(t: np.ndarray, names: Sequence[str], units: Sequence[str], raw: np.ndarray, predicted: np.ndarray,
           cad: dict[int, np.ndarray]) -> bytes:
    """Predicted against measured outputs in a window: one panel per channel (raw measurement in grey)."""
    n = len(names)
    cols = 2
    rows = (n + cols - 1) // cols
    fig = Figure(figsize=(11, 1.9 * rows))
    axes = fig.subplots(rows, cols, sharex=True, squeeze=False).ravel()
    for k, ax in enumerate(axes):
        if k >= n:
            ax.set_visible(False)
            continue
        ax.plot(t, raw[:, k], color="#999999", linewidth=0.5, label="measured")
        ax.plot(t, predicted[:, k], color=COLORS["calibrated"], linewidth=1.0, label="identified model")
        if k in cad:
            ax.plot(t, cad[k], color=COLORS["paper"], linewidth=0.9, linestyle="--", label="CAD")
        ax.set_title(f"{names[k]} ({units[k]})", fontsize=9, loc="left")
        ax.tick_params(labelsize=8)
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=7)
    for ax in axes[-cols:]:
        ax.set_xlabel("time (s)", fontsize=8)
    fig.tight_layout()
    return png(fig)
