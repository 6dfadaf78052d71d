"""`dynid report`: the identification report as one self-contained HTML page (dynid.report.page.page)."""

from __future__ import annotations

import argparse
from typing import Any

from ..detect.t2 import ALPHA
from ..identify.blocks import in_sample_share
from ..identify.model_sections import DEFAULT_N_MODE, N_MODES
from ..paper import PAPER
from ..report.page import DEFAULT_WINDOW_S, ReportSettings, rates_text, write_report
from .commands import COMMANDS
from .common import confidence as alpha
from .common import json_arg, one_blas_thread, positive_float, split_data_window, window_args


@one_blas_thread
def cmd_report(args: argparse.Namespace) -> dict[str, Any]:
    validation, validation_own = split_data_window(args.validation)  # RUN@FROM:TO, as every command takes it
    contact, contact_own = split_data_window(args.contact) if args.contact else (None, None)
    shared = (args.t_from, args.t_to)
    result = write_report(ReportSettings(args.model, validation, contact, args.out, args.truth, args.alpha, args.n_mode,
                                         args.window, args.gaps, validation_own or shared, contact_own or shared,
                                         args.bad_rows, args.episodes))
    v, params = result["validation"], result["parameters"]
    dv, dc = result["detection"]["validation"], result["detection"]["contact"]

    print(f"report of {args.model} ({result['robot']}) -> {result['out']}")
    if overlap := result["validation"].get("fit_overlap"):
        print(f"  note: {in_sample_share(overlap)} of the validation run's samples are the fit's own: its figures are "
              "in-sample, not a validation on data the model never saw (the page says so)")
    if "table_ii" in v:
        t = v["table_ii"]
        paper = f" (paper {PAPER['force_error'][0]} / {PAPER['force_error_cad'][0]} N)" if result["paper"] else ""
        for sensor, t in v.get("table_ii_sensors", {"": t}).items():
            print(f"  force error{' of ' + sensor if sensor else ''} {t['identified']['force']['mean']:.3f} N "
                  f"identified, {t['cad']['force']['mean']:.3f} N CAD{paper}")
    for variant, s in (dc["variants"] if dc else dv["variants"]).items():
        rates = f"contact run: {rates_text(s)}; " if dc else "no contact run; "
        print(f"  {variant:10s} {rates}validation FPR {100 * dv['variants'][variant]['fpr']:.2f} %")
    determined = sum(r["determined"] for r in params)
    print(f"  {len(result['figures'])} figures, {len(params)} base parameters ({determined} determined)"
          + (f", truth from {result['truth']}" if result['truth'] else ", no truth found"))
    return result


def add_commands(sub: argparse._SubParsersAction) -> None:
    sp = sub.add_parser("report", help=COMMANDS["report"].help,
                        description="Table II and the detection numbers beside the paper's, T² on the validation "
                        "and the contact runs, the ROC, predicted against measured outputs, and every base parameter "
                        "identified against CAD against true, as one self-contained HTML file.")
    sp.add_argument("--model", required=True, metavar="MODEL", help="a model file of `dynid fit`")
    sp.add_argument("--validation", required=True, metavar="DATA", help="a contact-free validation run (RUN@FROM:TO: "
                    "a window of it; --from/--to apply to both runs that give none)")
    sp.add_argument("--contact", metavar="DATA", help="a run with 'contact' ground truth (the skin's, a labelled "
                    "column, or --episodes): TPR, ROC and delays; without it, the detection section shows false "
                    "positives only")
    sp.add_argument("--episodes", metavar="LABELS.csv", help="contact labels for --contact (t_start,t_end a row, in "
                    "the data's own seconds, as `dynid detect --episodes` reads them), replacing its contact column")
    sp.add_argument("--out", required=True, metavar="REPORT.html", help="the page to write (atomically)")
    sp.add_argument("--truth", metavar="TRUTH.json", help="true parameters (default: the truth.json of `dynid "
                    "simulate` beside the identification data, else beside --validation or --contact)")
    sp.add_argument("--alpha", type=alpha, default=ALPHA, help=f"T² confidence level (default {ALPHA})")
    sp.add_argument("--n-mode", choices=N_MODES, default=DEFAULT_N_MODE, help="n of the paper's F threshold")
    sp.add_argument("--window", type=positive_float, default=DEFAULT_WINDOW_S, metavar="S",
                    help=f"length of the predicted-against-measured window (default {DEFAULT_WINDOW_S:g} s)")
    sp.add_argument("--gaps", metavar="DIR", help="add the model-gap section: the figures and numbers of "
                    "`dynid gaps --figures DIR`")
    window_args(sp)
    json_arg(sp)
    sp.set_defaults(func=cmd_report)
