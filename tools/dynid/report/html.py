"""The report page: one self-contained HTML file (inline CSS, figures as base64 PNG, no script, no link out).

Every number a table shows carries its full-precision value (`data-value`), its place in the `dynid report
--json` result (`data-key`: keys and list indices joined by '/') and the factor it is shown with (`data-scale`,
e.g. 100 for a percentage), so a reader or a test can check the page against the JSON, not the rounded text.
"""

from __future__ import annotations

import base64
import html
from typing import Any

CSS = """
body { font-family: sans-serif; margin: 2em auto; max-width: 1100px; color: #222; line-height: 1.4; }
h1 { font-size: 1.6em; } h2 { font-size: 1.25em; border-bottom: 1px solid #ccc; margin-top: 2em; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th { background: #f3f3f3; } td.l, th.l { text-align: left; }
td.combo { text-align: left; font-family: monospace; font-size: 0.8em; max-width: 34em; word-break: break-word; }
tr.undetermined td { color: #888; }
figure { margin: 1em 0; } figure img { max-width: 100%; border: 1px solid #eee; }
figcaption { font-size: 0.9em; color: #444; }
.note { color: #555; font-size: 0.9em; }
"""


def esc(x: Any) -> str:
    return html.escape(str(x), quote=True)


def num(value: float | None, fmt: str, key: str | None = None, scale: float = 1.0) -> str:
    """A table cell with a number (shown as `fmt` of value·scale, e.g. 100 for %); '—' for None. `key` is its
    place in the JSON result."""
    attrs = f' data-key="{esc(key)}"' if key else ""
    if value is None:
        return f"<td{attrs}>—</td>"
    if scale != 1.0:
        attrs += f' data-scale="{scale!r}"'
    return f'<td{attrs} data-value="{value!r}">{format(value * scale, fmt)}</td>'


def text(value: Any, cls: str = "l") -> str:
    return f'<td class="{cls}">{esc(value)}</td>'


def table(header: list[str], rows: list[str], left: int = 1) -> str:
    ths = "".join(f'<th class="l">{esc(h)}</th>' if i < left else f"<th>{esc(h)}</th>" for i, h in enumerate(header))
    return f"<table><thead><tr>{ths}</tr></thead><tbody>{''.join(rows)}</tbody></table>"


def figure(fig_id: str, png: bytes, caption: str) -> str:
    data = base64.b64encode(png).decode("ascii")
    return (f'<figure id="{esc(fig_id)}"><img alt="{esc(caption)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{esc(caption)}</figcaption></figure>")


def page(title: str, sections: list[str]) -> str:
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"><title>{esc(title)}</title>"
            f"<style>{CSS}</style></head><body><h1>{esc(title)}</h1>\n" + "\n".join(sections) + "\n</body></html>\n")


# ------------------------------------------------------------------------------------------------------------
# The report's tables


def table_ii(v: dict[str, Any], paper: dict[str, Any] | None, sensor: str | None = None) -> str:
    """Table II (of one F/T `sensor` of several, else the first's); the paper's columns only when `paper` is given
    (the paper's own arm)."""
    rows = []
    prefix = "validation/table_ii" if sensor is None else f"validation/table_ii_sensors/{sensor}"
    if sensor is not None:
        v = {"table_ii": v["table_ii_sensors"][sensor]}
    for what, unit, key in (("force", "N", "force_error"), ("torque", "Nm", "torque_error")):
        cells = [text(f"{what} error norm ({unit})")]
        for source in ("identified", "cad"):
            for stat in ("mean", "std"):
                cells.append(num(v["table_ii"][source][what][stat], ".3f", f"{prefix}/{source}/{what}/{stat}"))
        if paper is not None:
            cells += [num(paper[k][i], ".2f", f"paper/{k}/{i}") for k in (key, key + "_cad") for i in (0, 1)]
        ident, cad = v["table_ii"]["identified"][what]["mean"], v["table_ii"]["cad"][what]["mean"]
        cells.append(num(ident / cad if cad else None, ".2f"))
        if paper is not None:
            cells.append(num(paper[key][0] / paper[key + "_cad"][0], ".2f"))
        rows.append("<tr>" + "".join(cells) + "</tr>")
    if paper is None:
        return table(["", "identified mean", "± std", "CAD mean", "± std", "identified / CAD"], rows)
    return table(["", "identified mean", "± std", "CAD mean", "± std", "paper identified", "± std", "paper CAD",
                  "± std", "identified / CAD", "paper: identified / CAD"], rows)


def channels(v: dict[str, Any], units: dict[str, str]) -> str:
    rows = []
    for name, c in v["channels"].items():
        k = f"validation/channels/{name}"
        cad = text("undefined (no friction, no gains)", "l") if "cad" in c else text("", "l")
        rows.append(f"<tr>{text(name)}{text(units[name])}{num(c['rms'], '.4g', k + '/rms')}"
                    f"{num(c['noise_std'], '.4g', k + '/noise_std')}{num(c['ratio_to_noise'], '.2f', k + '/ratio_to_noise')}"
                    f"{num(c['mean'], '.3g', k + '/mean')}{cad}</tr>")
    return table(["channel", "unit", "RMS of e", "noise std", "RMS / noise", "mean of e", "CAD prediction"], rows, 2)


def detection(det_val: dict[str, Any], det_con: dict[str, Any], paper: dict[str, Any] | None, alpha: float) -> str:
    rows = []
    for variant, s in det_con["variants"].items():
        v, k, kv = det_val["variants"][variant], f"detection/contact/variants/{variant}", f"detection/validation/variants/{variant}"
        side = s.get("tpr_by_side") or {}
        delay = s.get("delay_s") or {}
        rows.append(
            f"<tr>{text(variant)}{num(s['threshold'], '.4g', k + '/threshold')}{num(v['fpr'], '.2f', kv + '/fpr', 100)}"
            f"{num(s.get('tpr'), '.1f', k + '/tpr', 100)}{num(s.get('fpr'), '.2f', k + '/fpr', 100)}"
            f"{num(s.get('auc'), '.3f', k + '/auc')}{num(side.get('distal'), '.1f', k + '/tpr_by_side/distal', 100)}"
            f"{num(side.get('proximal'), '.1f', k + '/tpr_by_side/proximal', 100)}"
            f"<td>{s.get('episodes_detected', '—')}/{s.get('episodes', '—')}</td>"
            f"{num(delay.get('median'), '.0f', k + '/delay_s/median', 1e3)}{num(delay.get('p90'), '.0f', k + '/delay_s/p90', 1e3)}</tr>")
    if paper is not None:  # the paper's figures describe its own arm only
        rows.append(f"<tr>{text('paper (real iCub arm)')}<td>—</td><td>—</td>{num(paper['tpr'], '.0f', 'paper/tpr', 100)}"
                    f"{num(paper['fpr'], '.0f', 'paper/fpr', 100)}" + "<td>—</td>" * 6 + "</tr>")
    return table(["variant", "threshold", f"FPR % validation (promise {100 * (1 - alpha):.0f} %)", "TPR % contact run",
                  "FPR % contact run", "AUC", "TPR % distal", "TPR % proximal", "episodes detected",
                  "delay median (ms)", "delay p90 (ms)"], rows)


def false_positives(det_val: dict[str, Any], alpha: float) -> str:
    """The detection table without a contact run: each variant's threshold and false positives on validation."""
    rows = [f"<tr>{text(variant)}{num(v['threshold'], '.4g', f'detection/validation/variants/{variant}/threshold')}"
            f"{num(v['fpr'], '.2f', f'detection/validation/variants/{variant}/fpr', 100)}</tr>"
            for variant, v in det_val["variants"].items()]
    return (table(["variant", "threshold", f"FPR % validation (promise {100 * (1 - alpha):.0f} %)"], rows)
            + "<p class=\"note\">No run with contact ground truth was given (--contact): no TPR, ROC or delays.</p>")


def gains(rows_in: list[dict[str, Any]], chosen: str) -> str:
    if not rows_in:
        return "<p class=\"note\">No motor gains in this model.</p>"
    estimators = list(rows_in[0]["estimators"])
    truth = any(r["true"] is not None for r in rows_in)
    rows = []
    for i, r in enumerate(rows_in):
        cells = [text(r["name"])]
        for est in estimators:
            e = r["estimators"][est]
            cells += [num(e["value"], ".4g", f"motor_gains/{i}/estimators/{est}/value"),
                      num(e["standard_error"], ".2g", f"motor_gains/{i}/estimators/{est}/standard_error")]
            if truth:
                off = None if not r["true"] else (e["value"] - r["true"]) / r["true"]
                cells.append(num(off, "+.1f", None, 100))
        if truth:
            cells.append(num(r["true"], ".4g", f"motor_gains/{i}/true"))
        rows.append("<tr>" + "".join(cells) + "</tr>")
    header = ["gain"]
    for est in estimators:
        header += [est + (" (model)" if est == chosen else ""), "± se"] + (["error %"] if truth else [])
    return table(header + (["true"] if truth else []), rows)


def parameters(rows_in: list[dict[str, Any]], has_truth: bool) -> str:
    rows = []
    for i, r in enumerate(rows_in):
        k = f"parameters/{i}"
        cls = "" if r["determined"] else ' class="undetermined"'
        cells = (f"{text(i + 1, 'l')}{text(r['name'])}<td class=\"combo\">{esc(r['combination'])}</td>"
                 f"{num(r['identified'], '.5g', k + '/identified')}{num(r['standard_error'], '.2g', k + '/standard_error')}"
                 f"{text('yes' if r['determined'] else 'no', 'l')}{num(r['cad'], '.5g', k + '/cad')}")
        if has_truth:
            cells += f"{num(r['true'], '.5g', k + '/true')}{num(r['error_in_se'], '+.1f', k + '/error_in_se')}"
        rows.append(f"<tr{cls}>{cells}</tr>")
    header = ["#", "base parameter", "combination", "identified", "± se", "determined", "CAD"]
    return table(header + (["true", "(identified − true) / se"] if has_truth else []), rows, 3)
