"""`dynid fit`, `dynid validate`, `dynid detect`: identification, Table II, T² contact detection."""

from __future__ import annotations

import argparse
import warnings
from typing import Any

import numpy as np

from ..config.robot_config import RobotConfig, load_config
from ..detect.t2 import ALPHA
from ..errors import DataError, DataNote, InputError
from ..cluster import executor
from ..identify.fit import (DEFAULT_ESTIMATOR, ESTIMATORS, IV_SETTLED, PSEUDO_INERTIA_ONLY, FitResult, FitSettings,
                            iv_settled)
from ..identify.model_file import IdentifiedModel, load_model
from ..identify.model_sections import DEFAULT_BLOCKS, DEFAULT_N_MODE, N_MODES, BaseSection
from ..identify.plausibility import masses_far_from_cad
from ..identify.run_payloads import apparent_payloads, payload_frame
from ..identify.runs import RunRef, check_distinct_runs, for_workers, input_notes, stream_run
from ..identify.supply import SupplyTracking
from ..identify.blocks import fitted_mask, in_sample_share, validate_blocks
from ..identify.transfer import format_why
from ..identify.validation import evaluate, load_run, validation
from ..io.stream import DatasetFile
from ..paper import PAPER, PAPER_ROBOT
from ..pipeline import DetectorSettings, IdentifySettings, identify
from ..robot.effects import FT_STEP, Effect, check_effect_targets, without_ft_steps
from ..robot.model import RobotModel
from ..robot.outputs import output_channels
from .commands import COMMANDS
from .validate_blocks import block_count, print_blocks
from .common import confidence as alpha
from .common import one_blas_thread
from .common import (bad_rows, expand_data, folder_of_runs_error, json_arg, min_speed_arg, non_negative_float,
                     payload_arg, payloads, plural, positive_int, robot_arg, run_spec, scheduler_address, skipped_rows,
                     window, window_args)

INPUT_WORD = {"pwm": "PWM", "current": "current", "tau": "joint torque"}
GAIN_UNIT = {"pwm": "Nm per unit duty", "current": "Nm per A"}
SHOW_COMBINATIONS = 30  # print every base combination when there are at most this many (else see --json)
SHOW_UNSEEN = 6  # name the combinations a jackknife fold misses when there are at most this many


def known_steps(path: str, model: RobotModel, distributed: object) -> list[Effect]:
    """`--steps-from`: the ft_step effects of an augmented model, each on a sensor of `model` (else one line)."""
    if distributed:
        raise InputError("--steps-from takes the steps out of runs read in memory: not with --workers or --scheduler")
    steps = [e for e in load_model(path).named_effects or () if e.kind == FT_STEP]
    if not steps:
        raise InputError(f"--steps-from {path}: it names no F/T step (ft_step); `dynid gaps --out` writes one that does")
    return check_effect_targets(steps, model, path)


# A fitted channel's residual RMS, in its noise: 0.5-1.8 on the simulated arm, the UR10e, the Panda; 4.1 on the TIAGo's
# fz; 45.6 on the iCub leg's foot ty (the leg sensor's offset steps, docs/robots/icub_leg.md). The leg with its two
# sensors' ports swapped: 855. A fit past this is warned about, not refused: the noise is the configuration's.
UNEXPLAINED_NOISES = 200.0
WORST_REAL_NOISES = 45.6


def cmd_fit(args: argparse.Namespace) -> dict[str, Any]:
    config = load_config(args.robot, args.urdf)
    from_config = args.consistent is None
    if from_config:  # the robot's default (its configuration's fit.consistent; docs/consistency.md#default)
        args.consistent = config.fit_consistent
    if args.cad_pull == "cv" and args.consistent == "off":
        raise InputError("--cad-pull cv weighs the CAD prior of the physically consistent fit: give it with "
                         "--consistent on (or pseudo-inertia)")
    if from_config and args.consistent != "off":
        print(f"--consistent {args.consistent}: {config.name}'s default (its configuration's fit.consistent; "
              "--consistent off for the unconstrained fit)")
    paths, windows = expand_data(args, config)
    refs = [RunRef(p, w, payload, bad_rows(args))
            for p, w, payload in zip(paths, windows, payloads(args, len(paths)))]
    if args.scheduler:  # workers open the files in their own directory
        config, refs = for_workers(config, refs)
    model = RobotModel(config)
    settings = FitSettings(estimator=args.estimator, n_components=args.n_components, min_speed=args.min_speed,
                           blocks=args.blocks, consistent=args.consistent != "off",
                           cad_pull=args.cad_pull == "cv", consistent_sphere=args.consistent != PSEUDO_INERTIA_ONLY)
    detector = DetectorSettings(args.alpha, args.n_mode)
    try:
        runs = [stream_run(ref, model) for ref in refs]  # every run checked before any work; a dataset file streamed
    except DataError as e:
        raise type(e)(folder_of_runs_error(args, config, e)) from None  # a missing file stays one
    check_distinct_runs(paths, runs)
    for path, note in input_notes(config, paths, runs):  # an input in another unit than declared fits: said
        warnings.warn(DataNote(f"{path}: {note}"), stacklevel=2)
    for ref, run in zip(refs, runs):  # the model has no contact: labelled contacts in its data bias it
        share = run.contact_share() if isinstance(run, DatasetFile) else (
            float(np.mean(run.contact != 0)) if run.contact is not None and run.n_samples else None)
        if share:
            warnings.warn(DataNote(f"{ref.path}: {100 * share:.3g} % of the samples are labelled contact (its contact "
                                   "column); the fit takes them as contact-free: leave them out with --from/--to"),
                          stacklevel=2)
    steps = known_steps(args.steps_from, model, args.workers or args.scheduler) if args.steps_from else []
    if steps:  # the fit with known F/T steps: the fit of the measurements with them taken out (in memory)
        runs = [without_ft_steps(model, load_run(ref.path, model, ref.window, ref.payload, ref.bad_rows), steps)
                for ref in refs]
    cluster = executor(args.workers, args.scheduler)
    try:
        if cluster is not None:
            print(f"fitting {plural(len(runs), 'run')} on {cluster.name} ({plural(cluster.workers, 'worker')})")
        done = identify(model, runs, paths, IdentifySettings(settings, detector, args.supply_time_constant,
                                                             estimate_noise=args.noise == "estimate"),
                        cluster=cluster, refs=refs)
    finally:
        if cluster is not None:
            cluster.close()
    model = done.robot or model
    if steps:  # validate, detect and report predict with them; the T² was calibrated on the data without them
        done.model.named_effects = tuple(steps)
    done.model.save(args.out)
    result, identified, detectors = done.fit, done.model, done.detectors
    independent = list(base_section(identified).independent)
    elapsed, elapsed_fit = done.total_time_s, done.fit_time_s
    outs = output_channels(model)
    base = result.base
    names = list(base.combinations())

    print(f"fitted {config.name} on {result.samples} samples"
          + (f" of {len(runs)} runs" if len(runs) > 1 else "")
          + f" in {elapsed:.1f} s ({elapsed_fit:.1f} s the regression) -> {args.out}")
    print_run_uncertainty(result)
    skipped = {p: s for p, ds in zip(paths, runs) if (s := skipped_rows(p, ds.meta)) is not None}
    print(f"  base parameters: rank {base.rank} of {len(model.layout)}; {int(result.identified.sum())} determined (a "
          f"standard error under 10 % of the value or 5 % of its size); the model's estimator {result.chosen}, "
          f"the PLS estimate beside it with ν = {result.cv['n_components']} "
          + (f"(cross-validated on {result.statistics.n_blocks} time blocks)" if args.n_components is None else
             "(--n-components)"))
    if args.estimator == "iv" and result.chosen == "ols" and any(ds.meta.get("payload") for ds in runs):
        print("  note: the model's estimator is OLS, not --estimator iv: IV's instruments leave out the payload run's "
              "known torques, which would bias it (docs/robots/ur10e.md)")
    gains = [i for i, n in enumerate(independent) if n.endswith(".phi_m")]
    unit = " and ".join(GAIN_UNIT[k] for k in sorted({g.input for g in config.actuation if g.input != "torque"}))
    print(f"  motor gains ({unit}) by estimator:" if gains else "  no unknown motor gains in this set-up")
    for name, est in result.estimates.items() if gains else ():
        mark = "*" if name == result.chosen else " "
        values = ", ".join(f"{independent[i].split('.')[0]} {est.beta[i]:.3f}±{est.se[i]:.3f}"
                           for i in gains)
        print(f"   {mark}{name:4s} {values}")
    unit_word = "pair" if any(ref.payload for ref in refs) else "run"
    chosen_units = result.estimates[result.chosen].units
    if gains and chosen_units is not None:
        print(f"  {result.chosen} gains of each {unit_word} alone, and their spread across {unit_word}s (sample std):")
        for i in gains:
            motor = independent[i].split(".")[0]
            each = chosen_units[:, i]
            print(f"    {motor:16s} " + ", ".join(f"{v:.3f}" for v in each) + f"   spread {each.std(ddof=1):.3f}")
    if gains:
        chosen_est = result.estimates[result.chosen]
        print(f"  {result.chosen} gains beside the configuration's nominal ones (a published or datasheet value; "
              "the rows' weights):")
        for i in gains:
            motor = independent[i].split(".")[0]
            nominal = config.motor(motor).nominal_gain
            value, se = chosen_est.beta[i], chosen_est.se[i]
            status = "determined" if result.identified[i] else "NOT determined by these runs (standard error over 10 %)"
            both = (f" (blocks {chosen_est.se_blocks[i]:.3f}, {unit_word}s {chosen_est.se_runs[i]:.3f})"
                    if chosen_est.se_runs is not None else "")
            print(f"    {motor:16s} {value:8.3f} ± {se:.3f}{both}   nominal {nominal:8.3f}   "
                  f"{100 * (value / nominal - 1):+6.1f} %   {status}")
    for name, est in result.estimates.items():
        settled, near = iv_settled(est.detail)
        if not settled:
            step, spread = est.detail.get("last_step"), est.detail.get("start_spread")
            last = "not finite" if step is None else f"{step:.2g}"
            apart = "" if "start_spread" not in est.detail else \
                f", {'not finite' if spread is None else f'{spread:.2g}'} apart from a second start"
            folds = est.detail.get("folds_unsettled") or []
            where = (f"on the jackknife folds without time block(s) {', '.join(map(str, folds))}" if folds else
                     f"in {est.detail['iterations']} iterations (last relative step {last}{apart}; {IV_SETTLED:g} "
                     f"needed{', borderline' if near else ''})")
            print(f"  {name}: the iteration did not settle {where}: its values are the last iterate and its standard "
                  "errors mean nothing")
        elif est.detail.get("folds_dropped"):
            print(f"  {name}: the jackknife fold without time block(s) {', '.join(map(str, est.detail['folds_dropped']))} "
                  "did not settle and is left out of the standard errors")
        if est.detail.get("exact_channels"):
            print(f"  {name}: the model reproduces {', '.join(est.detail['exact_channels'])} to rounding (noise-free "
                  "data?): the detector's variance there is the rounding floor, and any noise on the robot will fire it")
    inertial = set(model.layout.names[model.layout.span("inertial")])
    unexcited = [n for n in base.unidentifiable if n not in inertial]  # inertial ones: structural (CAD kept)
    if unexcited:
        print("  not excited by this run (a joint that never moves, or never one way; an input that never changes); "
              "the model keeps the prior, the nominal gain or zero friction: " + ", ".join(unexcited))
    deficient = result.jackknife.get("rank_deficient", [])
    if deficient:
        unseen = list(dict.fromkeys(c for fold in deficient for c in fold["unseen"]))
        left_out = ", ".join(f"{f['block']} (samples {f['samples'][0]}-{f['samples'][1]})" for f in deficient)
        print(f"  jackknife: {len(deficient)} of {result.jackknife['folds']} folds miss a direction the whole run sees "
              f"(time block left out: {left_out}); the {len(unseen)} combination(s) involved are not determined"
              + (": " + "; ".join(unseen) if len(unseen) <= SHOW_UNSEEN else " (listed in --json under jackknife)"))
    chosen = result.estimates[result.chosen]
    determined = {c: (float(v), float(e)) for c, v, e, ok in zip(names, chosen.beta, chosen.se, result.identified) if ok}
    undetermined = [c for c, ok in zip(names, result.identified) if not ok]
    if base.rank <= SHOW_COMBINATIONS:
        print("  determined by this run (value ± standard error):")
        for c, (v, e) in determined.items():
            print(f"    {c:60s} {v:12.5g} ± {e:.2g}")
        if undetermined:
            print("  not determined by this run (standard error above both, or unseen by a jackknife fold; no value "
                  "given): " + ", ".join(undetermined))
    edges = result.borderline()
    if edges["determined"]:
        print(f"  borderline: {plural(len(edges['determined']), 'combination')} with a standard error on the 10 % "
              "threshold (taken as not determined; another CPU's rounding could count it): "
              + "; ".join(edges["determined"][:SHOW_UNSEEN]) + (" …" if len(edges["determined"]) > SHOW_UNSEEN else ""))
    if edges["rank_cut"]:
        print(f"  borderline: singular value(s) {', '.join(f'{v:.3g}' for v in edges['rank_cut'])} of the largest sit "
              f"on the rank cut {base.rtol:g} (left out of the rank)")
    print_consistent(result.consistent)
    implausible = identified.plausibility or []
    if implausible:
        why = ("--consistent pseudo-inertia lets a centre of mass leave its sphere"
               if args.consistent == PSEUDO_INERTIA_ONLY else
               "--consistent on keeps every body physical and friction dissipative; the data may not determine these "
               "bodies one by one")
        print(f"  WARNING: {len(implausible)} physically implausible estimate(s) ({why}):")
        for w in implausible:
            print(f"    {w['text']}")
    far = masses_far_from_cad(model, result.phi)
    if far:
        how = ("a consistent fit puts what the data leave free where its constraints cost the fit least; --cad-pull cv "
               "weighs a pull to CAD" if result.consistent is not None else "the data may not determine them")
        print(f"  note: {plural(len(far), 'mass', 'masses')} far from CAD, not to be read as measured ({how}): "
              + "; ".join(w["text"] for w in far))
    loads = apparent_payloads(model, result.statistics, base.independent, [ref.payload is not None for ref in refs])
    frame = payload_frame(model)
    for a in loads:  # a run that carries what the others do not, averaged into the robot's parameters: said
        run = run_spec(refs[a.run].path, refs[a.run].window)
        print(f"  WARNING: {run}: its rows ask for {a.mass_kg:+.3g} kg at {frame} beyond what the "
              f"other runs carry (± {a.standard_error_kg:.2g}; the residual {100 * a.residual_drop:.0f} % lower with "
              "it): a load not given, on this run or the others? The fit averages it into the robot's parameters; "
              "give it (--payload MASS[@x,y,z], one per --data) or fit the runs apart")
    rms = np.sqrt(result.residual_variance[result.chosen])
    print("  residual RMS on the identification data (rows at rest left out) / channel noise:")
    print("   " + ", ".join(f"{o.name} {r:.3g} ({r / o.sigma:.2f}×)" for o, r in zip(outs, rms)))
    unexplained = [(o.name, r / o.sigma) for o, r in zip(outs, rms) if r > UNEXPLAINED_NOISES * o.sigma]
    if unexplained:  # the model leaves most of a channel: data that are not the configured robot's, as declared
        print(f"  WARNING: the model leaves {', '.join(f'{n} {x:.0f}×' for n, x in unexplained)} its noise (on the "
              f"bundled real runs at most {WORST_REAL_NOISES:g}×): do the data fit the configuration as declared "
              "(sensor ports or columns swapped, a unit, gravity's direction)?")
    return {"robot": config.name, "out": args.out, "samples": result.samples, "rank": base.rank,
            "n_components": result.cv["n_components"], "estimator": identified.estimator,
            "identified": int(result.identified.sum()), "determined": {c: {"value": v, "standard_error": e}
                                                                     for c, (v, e) in determined.items()},
            "undetermined": undetermined, "unidentifiable": list(base.unidentifiable), "jackknife": result.jackknife,
            "estimators": {k: v.to_json() for k, v in identified.estimators.items()},
            "base": base_section(identified).to_json(), "residual_rms": dict(zip(identified.output_channels, rms.tolist())),
            "thresholds": {k: d.threshold for k, d in detectors.items()}, "fit_time_s": elapsed,
            "plausibility": implausible, "masses_far_from_cad": far, "consistent": result.consistent,
            "apparent_payloads": [{**a.to_json(), "data": run_spec(refs[a.run].path, refs[a.run].window), "frame": frame}
                                  for a in loads],
            "borderline": edges,
            **({"bad_rows": skipped} if skipped else {})}


def base_section(identified: IdentifiedModel) -> BaseSection:
    assert identified.base is not None  # `dynid fit` writes it
    return identified.base


def print_run_uncertainty(result: FitResult) -> None:
    """With several runs (or pairs): the two jackknifes, and what "determined" then takes."""
    jack = result.jackknife
    if jack.get("units", 1) < 2:
        return
    pairs = jack["units"] < jack["runs"]
    unit = "pair" if pairs else "run"
    print(f"  standard errors: the larger of two jackknifes, over {jack['folds']} time blocks (within runs) and over "
          f"the {jack['units']} {unit}s (one left out at a time: what differs between runs); a combination is "
          "determined only when both put it within 10 %")
    for fold in jack.get("unit_rank_deficient", []):
        print(f"  without {unit} {fold['unit'] + 1} the others miss {len(fold['unseen'])} combination(s): not "
              "determined")


def print_consistent(done: dict[str, Any] | None) -> None:
    """The consistent fit's lines: λ, the constraints that bind (docs/consistency.md), or why it failed."""
    if done is None:
        return
    if done["status"] != "solved":
        print(f"  WARNING: {done['reason']}; the model keeps the unconstrained {done['from']} estimate")
        return
    active = done["active"]
    bounds = "" if done.get("sphere", True) else ", pseudo-inertia only"
    print(f"  physically consistent ({done['solver']}, from {done['from']}{bounds}, {done['solve_time_s']:.1f} s): "
          f"pull to CAD λ = {done['lambda']:g} " + (f"(cross-validated over {', '.join(f'{x:g}' for x in lambdas)})"
                                                    if len(lambdas := done['cv']['lambdas']) > 1 else
                                                    "(the data alone: --cad-pull cv weighs a pull to CAD)"))
    binding = [(what, active[key]) for what, key in (("pseudo-inertia at its bound", "pseudo_inertia"),
                                                      ("mass inside its sphere at the bound", "sphere"),
                                                      ("friction at 0", "friction"),
                                                      ("gain at its floor", "gain")) if active[key]]
    if not binding:
        print("    no constraint binds")
    for what, names in binding:
        print(f"    {what}: {', '.join(names)}")


def input_words(config: RobotConfig) -> list[str]:
    """What the set-up's motor rows predict, in words: ["current"], ["PWM"], ["joint torque"], ..."""
    kinds = sorted({"tau" if g.input == "torque" else g.input for g in config.actuation})
    return [f"{INPUT_WORD[k]}s" for k in kinds]


@one_blas_thread
def cmd_validate(args: argparse.Namespace) -> dict[str, Any]:
    ev = evaluate(args.model, args.data, window=window(args), payload=args.payload, bad_rows=bad_rows(args))
    fitted = fitted_mask(ev.identified, args.data, ev.dataset.t)  # the model file knows its runs and windows
    result = validation(ev, args.model, args.data, window=window(args),
                        fit_overlap=None if fitted is None else float(fitted.mean()))
    if args.blocks is not None:  # every block computed (or refused) before anything is printed
        result["blocks"] = validate_blocks(ev.identified, ev.dataset, args.blocks, args.model, args.data, args.data,
                                           fitted)
    print(f"validation of {args.model} on {args.data} ({result['samples']} samples)")
    if (skipped := skipped_rows(args.data, ev.dataset.meta)) is not None:
        result["bad_rows"] = skipped
    if fitted is not None and fitted.any():
        print(f"  note: {in_sample_share(float(fitted.mean()))} of these samples are the fit's own (its run, inside its window): "
              "the figures below are in-sample, not a validation on data the model never saw; validate on another "
              "run or window (--blocks K shows which blocks the fit took)")
    if "contact_fraction" in result:  # the model has no contact: its error includes the contacts'
        print(f"  note: {100 * result['contact_fraction']:.1f} % of these samples are in contact (the run's contact "
              "column): the errors below include the contact forces the model does not predict; validate on a "
              "contact-free run (or a window of one)")
    paper = ev.config.name == PAPER_ROBOT  # the paper's figures describe its arm only
    tables = result.get("table_ii_sensors", {})
    if tables:
        print("  F/T prediction error (norm), mean ± std:    identified            CAD (offsets fitted)   id. vs CAD"
              + ("   paper (id / CAD)" if paper else ""))
    for sensor, table in tables.items():
        if len(tables) > 1:
            print(f"   {sensor}")
        for what, unit, key in (("force", "N", "force_error"), ("torque", "Nm", "torque_error")):
            i, c = table["identified"][what], table["cad"][what]
            change = f"{100 * (i['mean'] / c['mean'] - 1):+6.1f} %" if c["mean"] > 0 else "     -  "
            # significant digits, not decimals: a wrist's torque errors are hundredths of a newton metre
            print(f"    {what:6s} {i['mean']:8.4g} ± {i['std']:<7.3g} {unit:2s} {c['mean']:8.4g} ± {c['std']:<7.3g} {unit:2s}"
                  f"    {change}"
                  + (f"   {PAPER[key][0]} ± {PAPER[key][1]} / {PAPER[key + '_cad'][0]} ± {PAPER[key + '_cad'][1]}"
                     if paper else ""))
    if result.get("why_worse_than_cad"):
        for line in format_why(result["why_worse_than_cad"]):
            print(line)
    print("  per channel: RMS of e = y − ŷ (y smoothed by the derivative filter, as the fit takes it), and against "
          "the channel's noise std")
    for o in ev.outputs:
        entry = result["channels"][o.name]
        line = f"    {o.name:18s} {entry['rms']:10.4g} {o.unit:4s} {entry['ratio_to_noise']:6.2f}× noise"
        if "ratio_to_noise_moving" in entry:
            line += (f"; moving rows {entry['ratio_to_noise_moving']:.2f}× "
                     f"(constant gains {entry['ratio_to_noise_moving_constant_gains']:.2f}×)")
        print(line)
    if "relative_torque_error" in result:
        print(f"  relative torque error ‖τ − τ̂‖ / ‖τ‖: {100 * result['relative_torque_error']:.2f} %")
    relative = result.get("relative_error")
    if relative:
        print("  relative error of the predicted " + " and ".join(input_words(ev.config)) + " (raw, unfiltered): "
              + ", ".join(f"{c} {100 * v['relative']:.2f} %" for c, v in relative["channels"].items()))
        print(f"    overall, each channel weighted by its gain (joint torque), ‖K(y − ŷ)‖ / ‖K y‖: "
              f"{100 * relative['overall']:.2f} %")
    kinds = sorted({o.name.split(".")[0] for o in ev.outputs if o.kind == "input"})
    if kinds:
        print(f"  CAD {' and '.join(INPUT_WORD[k] for k in kinds)} prediction: undefined; a CAD model has no friction "
              "and no motor gains")
    if args.blocks is not None:
        print_blocks(result["blocks"])
    return result


def add_commands(sub: argparse._SubParsersAction) -> None:
    sp = sub.add_parser("fit", help=COMMANDS["fit"].help,
                        description="Fit the model of docs/design.md §3 to one or more experiments (stacked): OLS on the "
                        "base parameters, PLS by NIPALS (ν cross-validated on time blocks) and instrumental variables "
                        "(IDIM-IV, the default: closed-loop data bias OLS and PLS), with jackknife standard errors; "
                        "then calibrate the contact detectors on the same data (the acceleration residuals' T², the momentum "
                        "observer's and their combined level), each time block's residuals through the Φ fitted "
                        "without it (docs/detection.md#out-of-sample). Writes MODEL (JSON).")
    robot_arg(sp)
    sp.add_argument("--data", action="append", required=True, metavar="DATA",
                    help="an experiment (dataset, CSV, candump log, ROS 2 bag, YARP folder, a folder of files the "
                    "configuration's 'files' describes, or a `dynid simulate` "
                    "directory), RUN@FROM:TO for a window of its own, a glob of runs ('runs/*.csv', quoted), a "
                    "folder (every run beneath it) or @LIST (a file naming runs, one a line); repeatable. A dataset "
                    "file is read a window at a time, never whole")
    sp.add_argument("--out", required=True, metavar="MODEL", help="the model file to write")
    sp.add_argument("--steps-from", metavar="GAPS_MODEL", help="take the F/T offset steps (ft_step) that `dynid gaps "
                    "--out` named in GAPS_MODEL as known, with their times and sizes: the fit sees the F/T "
                    "measurements with them taken out, and MODEL carries them (validate, detect and report apply "
                    "them). For a window inside one level of a step, whose size it cannot see")
    where = sp.add_mutually_exclusive_group()
    where.add_argument("--workers", type=positive_int, metavar="N",
                       help="map the runs' time blocks on a Dask LocalCluster of N worker processes started here "
                       "(default: in this process, with a process pool per run)")
    where.add_argument("--scheduler", type=scheduler_address, metavar="ADDRESS",
                       help="map them on a running Dask cluster (e.g. tcp://10.0.0.1:8786); every worker must read "
                       "the runs at the same paths (docs/deployment.md#many-runs-on-a-dask-cluster)")
    window_args(sp)
    payload_arg(sp, repeatable=True)
    sp.add_argument("--estimator", choices=ESTIMATORS, default=DEFAULT_ESTIMATOR,
                    help=f"whose parameters the model keeps (default {DEFAULT_ESTIMATOR}); all three are reported")
    sp.add_argument("--consistent", choices=["on", "off", PSEUDO_INERTIA_ONLY], default=None,
                    help="physically consistent estimation (default: the robot configuration's fit.consistent, off "
                    "where it gives none; on for icub_right_leg_standing, decided by held-out blocks and runs in "
                    "docs/consistency.md#default): the estimator's "
                    "parameters moved the least the data allow so that every body's pseudo-inertia is positive "
                    "semidefinite and its mass inside a sphere about its frame, friction is non-negative and gains "
                    "keep their sign (a semidefinite programme, Clarabel through cvxpy); the model keeps it as "
                    "estimator 'consistent' and the active constraints are printed. pseudo-inertia: the same "
                    "without the sphere (a body may carry mass beyond its reach, e.g. a tool). off: the "
                    "unconstrained estimate")
    sp.add_argument("--cad-pull", choices=["off", "cv"], default="off",
                    help="with --consistent on or pseudo-inertia: a pull of the inertial parameters towards CAD, "
                    "its weight chosen by cross-validation over the time blocks (kept only where it beats no pull by "
                    "a standard error of the folds); default off: the data alone")
    sp.add_argument("--n-components", type=positive_int, metavar="NU", help="PLS latent variables (default: by CV)")
    sp.add_argument("--blocks", type=positive_int, default=DEFAULT_BLOCKS,
                    help=f"time blocks for CV and jackknife (default {DEFAULT_BLOCKS})")
    sp.add_argument("--alpha", type=alpha, default=ALPHA, help=f"T² confidence level (default {ALPHA})")
    sp.add_argument("--n-mode", choices=N_MODES, default=DEFAULT_N_MODE,
                    help="n of the paper's F threshold: dim(e) (default) or ν as the paper writes")
    sp.add_argument("--supply-time-constant", type=non_negative_float, default=SupplyTracking.time_constant_s,
                    metavar="S", help="track each motor's supply (its torque per unit duty) with this time constant "
                    f"when predicting inputs (dynid.identify.supply; default {SupplyTracking.time_constant_s:g} s, 0 = constant gains)")
    sp.add_argument("--noise", choices=["config", "estimate"], default="config",
                    help="the input channels' noise that weights the rows, validation and the detector: the "
                    "configuration's (default), or estimated from a first fit's residuals on moving rows, then refitted")
    min_speed_arg(sp)
    json_arg(sp)
    sp.set_defaults(func=cmd_fit)

    sp = sub.add_parser("validate", help=COMMANDS["validate"].help,
                        description="F/T prediction error (force and torque norms, mean ± std) of the identified and "
                        "the CAD parameters (F/T set-ups), per-channel residual RMS against the noise, and the relative "
                        "error of the predicted inputs or joint torques per channel and overall (current-, PWM- and "
                        "torque-driven set-ups).")
    sp.add_argument("--model", required=True, metavar="MODEL", help="the model `dynid fit` wrote")
    sp.add_argument("--data", required=True, metavar="DATA", help="the run to validate on (one the fit did not see, for "
                    "an honest figure), in any form "
                    "`dynid import` reads (RUN@FROM:TO: a window of it)")
    window_args(sp)
    payload_arg(sp, repeatable=False)
    sp.add_argument("--blocks", type=block_count, metavar="K",
                    help="also validate each of K equal time blocks of the data (after --from/--to), each alone as "
                    "--from/--to its first and last sample would, saying which the model was fitted on (its model "
                    "file's runs and windows); then the worst block per figure and the spread (min / median / max)")
    json_arg(sp)
    sp.set_defaults(func=cmd_validate)
