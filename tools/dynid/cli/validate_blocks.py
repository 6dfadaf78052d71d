"""`dynid validate --blocks K`: every time block of the run beside the single window, as text (the numbers are
dynid.identify.blocks')."""

from __future__ import annotations

import argparse
from typing import Any


def block_count(text: str) -> int:
    """--blocks K: an integer of 2 or more (one block is the single window validate reports anyway)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not an integer") from None
    if value < 2:
        raise argparse.ArgumentTypeError(f"must be at least 2 (one block is the window validate reports without "
                                         f"--blocks), got {value}")
    return value


def _in_fit(block: dict[str, Any]) -> str:
    overlap = block["fit_overlap"]
    if overlap is None:
        return "unknown"
    if overlap == 0:
        return "no"
    return "yes" if overlap == 1 else f"{100 * overlap:.0f} %"


def _span(block: dict[str, Any]) -> str:
    return f"{block['from']:.2f}–{block['to']:.2f} s"


def _number(value: float) -> str:
    return f"{value:.4g}"


def _headline_figures(blocks: dict[str, Any]) -> list[tuple[str, str, str]]:
    """(figure, label, unit) of the figures the text shows: the overall relative error, the relative torque error,
    and per F/T sensor the identified force and torque error norms (the CAD one beside each)."""
    names = blocks["blocks"][0]["figures"]
    shown = []
    if "relative_error.overall" in names:
        shown.append(("relative_error.overall", "relative error, overall", "%"))
    if "relative_torque_error" in names:
        shown.append(("relative_torque_error", "relative torque error", "%"))
    for name in names:
        if name.startswith("ft.") and name.endswith(("force_identified", "torque_identified")):
            sensor, what = name[3:].rsplit(".", 1)
            shown.append((name, f"{sensor} {what.split('_')[0]}", "N" if what.startswith("force") else "Nm"))
    return shown


def _value(figures: dict[str, float], name: str, unit: str) -> str:
    v = figures[name]
    if unit == "%":
        return f"{100 * v:.2f} %"
    cad = figures.get(name.replace("_identified", "_cad"))
    return f"{_number(v)} {unit}" + (f" (CAD {_number(cad)})" if cad is not None else "")


def print_blocks(blocks: dict[str, Any]) -> None:
    rows = blocks["blocks"]
    lo, hi = blocks["span"]
    print(f"  every block: {blocks['k']} blocks of {(hi - lo) / blocks['k']:.3g} s over {lo:.2f}–{hi:.2f} s, each "
          "validated alone (as --from/--to its first and last sample)")
    shown = _headline_figures(blocks)
    for block in rows:
        print(f"    block {block['index'] + 1:2d}  {_span(block):18s} {block['samples']:7d} samples  in fit: "
              f"{_in_fit(block)}")
        for name, label, unit in shown:
            print(f"      {label:42s} {_value(block['figures'], name, unit)}")
        channels = [n for n in block["figures"] if n.startswith("relative_error.") and n != "relative_error.overall"]
        if channels:
            print("      per channel: " + ", ".join(f"{n.split('.', 1)[1]} {100 * block['figures'][n]:.2f} %"
                                                    for n in channels))
    summary = blocks["summary"]
    print("  per figure over the blocks: the worst block, the median, the best block")
    figures = summary["figures"]
    ratios = [(n, f"{n[3:].rsplit('.', 1)[0]} {n.rsplit('.', 1)[1].split('_')[0]} identified / CAD", "×")
              for n in figures if n.endswith("_identified_vs_cad")]
    for name, label, unit in [*shown, *ratios]:
        if name not in figures:
            continue
        s = figures[name]
        worst, best = rows[s["worst_block"]], rows[s["best_block"]]
        scale, suffix = (100.0, " %") if unit == "%" else (1.0, f" {unit}" if unit != "×" else "×")
        print(f"    {label:42s} worst {_number(scale * s['max'])}{suffix} on block {worst['index'] + 1} "
              f"({_span(worst)}, in fit: {_in_fit(worst)}); median {_number(scale * s['median'])}{suffix}; best "
              f"{_number(scale * s['min'])}{suffix} on block {best['index'] + 1} ({_span(best)}, in fit: "
              f"{_in_fit(best)})")
    in_fit = summary["blocks_in_fit"]
    print("  blocks in the fit: " + (", ".join(f"{i + 1} ({_in_fit(rows[i])})" for i in in_fit) if in_fit else
                                     "none" if rows[0]["fit_overlap"] is not None else
                                     "unknown (the model file names no run to compare)"))
