"""The augmented model of `dynid gaps --out`: its file round trip, its export to the monitor (Stribeck and spring
evaluated by the C++ core as dynid evaluates them), a replay on a run with the hidden effects, the refusal of an
effect the monitor lacks, and the figures drawn from the result's numbers."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import dynid
from test_rt_core import detector_columns, raw_samples, read_matrix, rel_err, rt_eval, stream, vector_states, write_matrix

from dynid.export.coefficients import read_coefficients
from dynid.identify.model_file import load_model
from dynid.robot.effects import Effect, augmented_residuals, effect_rows
from dynid.robot.outputs import residuals
from dynid.robot.regressors.stack import Signals

pytestmark = pytest.mark.numerics


@pytest.fixture(scope="module")
def augmented(default_model: Path, hidden_effects_runs: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The session's two runs with a hidden Stribeck (elbow) and spring (shoulder yaw): `dynid gaps` on the first,
    given the session's standard model; both monitors exported; the second run replays."""
    root = tmp_path_factory.mktemp("gapsexport")
    runs = hidden_effects_runs
    aug, figs = root / "augmented.json", root / "figures"
    done = dynid("gaps", "--model", str(default_model), "--data", str(runs["fit"]), "--out", str(aug),
                 "--figures", str(figs), "--json", str(root / "gaps.json"))
    assert done.returncode == 0, done.stderr
    coef = {}
    for name, model in (("standard", default_model), ("augmented", aug)):
        coef[name] = root / f"{name}.dcoef"
        done = dynid("export", "--model", str(model), "--out", str(coef[name]))
        assert done.returncode == 0, done.stderr
    return {"root": root, "runs": runs, "model": aug, "figures": figs, "coef": coef, "stdout": done.stdout,
            "result": json.loads((root / "gaps.json").read_text())}


def test_augmented_model_round_trip(augmented: dict, default_model: Path) -> None:
    result = augmented["result"]
    written = [e for e in result["effects"] if e["in_model"]]
    # named (confident) effects are written; a tentative one (rounding-dependent armature on m3, say) is reported only
    assert all(e["confident"] for e in written) and all(e["in_model"] for e in result["effects"] if e["confident"])
    assert {(e["name"], e["where"]) for e in written} == {("stribeck", "joint r_elbow"),
                                                         ("spring", "joint r_shoulder_yaw")}
    m = load_model(augmented["model"])
    raw = json.loads(augmented["model"].read_text())
    assert raw["format_version"] == 2
    effects = {e.kind: e for e in m.effects}
    assert len(m.effects) == len(written)
    for e in written:  # what was printed and written to --json is what the model file holds
        loaded = effects[e["name"]]
        assert loaded.where == e["where"]
        for k, v in e["parameters"].items():
            assert loaded.parameters[k] == pytest.approx(v, rel=1e-12)
        assert loaded.standard_errors == e["standard_errors"]
    s, k = effects["stribeck"], effects["spring"]
    assert 0 < s.standard_errors["static_torque"] < 0.2 * s.parameters["static_torque"]
    assert s.standard_errors["velocity"] is None  # searched, not regressed
    assert 0 < k.standard_errors["stiffness"] < 0.2 * k.parameters["stiffness"]
    assert raw["effects"][0]["units"]  # the plant's units, named
    # the standard parts are a full model: same layout as the given one, and validate/detect accept the file
    given = load_model(default_model)
    assert set(m.parameters) == set(given.parameters)
    assert not np.allclose(m.phi, given.phi)  # refitted on the run
    done = dynid("validate", "--model", str(augmented["model"]), "--data", str(augmented["runs"]["replay"]))
    assert done.returncode == 0, done.stderr
    # detect at an α other than the calibrated one reads the calibrated T²'s stored quantiles (as for `dynid fit`)
    assert raw["detector"]["calibrated_t2_quantiles"]["levels"]
    done = dynid("detect", "--model", str(augmented["model"]), "--data", str(augmented["runs"]["replay"]),
                 "--alpha", "0.95")
    assert done.returncode == 0, done.stderr
    # On the unseen replay run, with rows at rest left out (where static friction holds what no model says, as
    # the fit and the detector leave them out): the elbow's motor (m3) carries the Stribeck torque, and the
    # augmented model predicts it.
    from dynid.identify.validation import evaluate
    from dynid.robot.regressors.stack import rows_at_rest

    rms = {}
    for name, path in (("augmented", augmented["model"]), ("standard", default_model)):
        ev = evaluate(str(path), str(augmented["runs"]["replay"]))
        c = [o.name for o in ev.outputs].index("pwm.m3")
        moving = ~rows_at_rest(ev.model, ev.signals.dq, 0.01)[:, c]
        rms[name] = float(np.sqrt(np.mean(ev.e[moving, c] ** 2)))
    print(f"pwm.m3 residual RMS on the replay run, moving rows: standard {rms['standard']:.4g}, augmented "
          f"{rms['augmented']:.4g} duty")
    assert rms["augmented"] < 0.7 * rms["standard"]
    # an augmented model is not a starting point for another gap analysis
    done = dynid("gaps", "--model", str(augmented["model"]), "--data", str(augmented["runs"]["replay"]))
    assert done.returncode == 2 and "already an augmented model" in done.stderr


def test_effect_rows_are_the_candidate_columns() -> None:
    """dynid.robot.effects's closed forms (the monitor's) against the gap library's own columns times θ."""
    from dynid.config.robot_config import load_config
    from dynid.robot.effect_library import Context, spring, stribeck
    from dynid.robot.model import RobotModel

    model = RobotModel(load_config("icub_right_arm"))
    q, dq, ddq = vector_states(model, n=400, seed=11)
    dq[:, 6] = np.linspace(-0.2, 0.2, 400)  # the elbow through the Stribeck range, both signs and zero
    sig = Signals(q, dq, ddq, {m: np.zeros(400) for m in ("m0", "m1", "m2", "m3")}, {}, {})
    ctx = Context(model, sig, np.arange(400) * 1e-3)
    cs = next(c for c in stribeck(ctx, (0.04,)) if c.where == "joint r_elbow")
    ck = next(c for c in spring(ctx) if c.where == "joint r_shoulder_pitch")
    effects = [Effect("stribeck", "joint r_elbow", {"static_torque": 0.3, "velocity": 0.04}),
               Effect("spring", "joint r_shoulder_pitch", {"stiffness": 1.7, "rest": float(q[:, 0].mean())})]
    expected = cs.values[:, :, 0] * 0.3 + ck.values[:, :, 0] * 1.7
    got = effect_rows(model, effects, sig)
    assert np.abs(expected).max() > 0.1
    assert np.allclose(got, expected, rtol=0, atol=1e-12)


def test_core_predicts_the_augmented_model(augmented: dict, tmp_path: Path) -> None:
    """rt_eval's prediction with the effects equals dynid's augmented prediction to 1e-9, on states that put the
    elbow in the Stribeck range and the shoulder yaw over its travel."""
    m = load_model(augmented["model"])
    model = m.robot_model
    c = read_coefficients(augmented["coef"]["augmented"])
    assert c.n_effects == 2 and sorted(c.effect_kind) == [1, 2]
    q, dq, ddq = vector_states(model, n=600, seed=5)
    n = q.shape[0]
    dq[:200, 6] = np.linspace(-0.25, 0.25, 200)  # through ±5 Stribeck velocities and exactly zero
    rng = np.random.default_rng(6)
    ft = rng.normal(0, 5.0, (n, 6))
    pwm = {mm: rng.uniform(-0.5, 0.5, n) for mm in c.motor_names}
    sig = Signals(q, dq, ddq, pwm, {}, {"r_arm_ft": ft})
    e = augmented_residuals(model, m.phi, m.effects, sig)
    e_std = residuals(model, m.phi, sig)
    y = np.column_stack([ft] + [pwm[mm] for mm in c.motor_names])
    y_hat = y - e
    write_matrix(tmp_path / "in.mx", np.hstack([q, dq, ddq, y]))
    done = rt_eval("--coef", str(augmented["coef"]["augmented"]), "--predict", str(tmp_path / "in.mx"),
                   str(tmp_path / "out.mx"))
    assert done.returncode == 0, done.stderr
    out = read_matrix(tmp_path / "out.mx")
    no = c.n_outputs
    scale = np.maximum(np.abs(y_hat), np.abs(y)).max(axis=0)
    err = rel_err(out[:, :no], y_hat, scale)
    print(f"C++ against dynid's augmented prediction: max relative error {err:.2e}")
    assert err <= 1e-9
    # ... and the effects matter on these states far above that tolerance (m3: the elbow; m2: the coupled
    # shoulder's motor row that carries the yaw, T⁻ᵀ)
    m3, m2 = c.channel_names.index("pwm.m3"), c.channel_names.index("pwm.m2")
    for ch in (m2, m3):
        assert np.max(np.abs(e[:, ch] - e_std[:, ch])) / scale[ch] > 1e-3


def _replay(coef: Path, run: Path, tmp_path: Path) -> tuple[np.ndarray, float]:
    from dynid.config.robot_config import load_config
    from dynid.io.load import load_data

    c = read_coefficients(coef)
    ds = load_data(run, load_config("icub_right_arm"))
    out = stream(coef, raw_samples(ds, c), tmp_path)
    out = out[out[:, 0] == 1]
    nj, no = c.n_joints, c.n_outputs
    e = out[:, 1 + 3 * nj + 2 * no : 1 + 3 * nj + 3 * no]
    dq = out[:, 1 + nj : 1 + 2 * nj]
    m3 = c.channel_names.index("pwm.m3")  # the elbow's channel, gated on the elbow alone
    assert c.gate_joints[m3] == 1 << c.joint_names.index("r_elbow") and c.gate_motors[m3] == 0
    moving = np.abs(dq[:, c.joint_names.index("r_elbow")]) >= c.min_speed
    return float(np.sqrt(np.mean(e[moving, m3] ** 2))), float(out[:, detector_columns(c)["above"]].mean())


def test_replay_with_hidden_effects(augmented: dict, tmp_path: Path) -> None:
    """A new contact-free run of the arm with the hidden Stribeck and spring, through the core: the standard
    monitor (fitted and calibrated before the effects were known) raises false alarms far above 1 − α; the
    augmented one keeps near its promise, and its elbow residual shrinks."""
    run = augmented["runs"]["replay"]
    c_std, c_aug = (read_coefficients(augmented["coef"][k]) for k in ("standard", "augmented"))
    e3_std, fpr_std = _replay(augmented["coef"]["standard"], run, tmp_path)
    e3_aug, fpr_aug = _replay(augmented["coef"]["augmented"], run, tmp_path)
    print(f"replay: FPR standard {100 * fpr_std:.2f} %, augmented {100 * fpr_aug:.2f} % (1 − α = "
          f"{100 * (1 - c_aug.alpha):.0f} %); pwm.m3 residual RMS while the elbow moves {e3_std:.4g} → {e3_aug:.4g} duty")
    assert fpr_aug < 0.2 * fpr_std
    # Not the promised 1 − α: refitted on 40 s, the shoulder's m0/m1 residuals the library cannot explain remain
    # (README, "Model gaps"); measured 3.3 %.
    assert fpr_aug <= 5 * (1 - c_aug.alpha) and c_std.alpha == c_aug.alpha
    assert e3_aug < 0.6 * e3_std


def test_export_refuses_an_effect_the_monitor_lacks(augmented: dict, tmp_path: Path) -> None:
    record = json.loads(augmented["model"].read_text())
    record["effects"].append({"kind": "cogging", "where": "motor m3", "parameters": {"amplitude": 0.05,
                              "period_deg": 8.0}, "coefficients": [0.03, 0.04], "search": {"period_deg": 8.0}})
    bad = tmp_path / "cogging.json"
    bad.write_text(json.dumps(record))
    done = dynid("export", "--model", str(bad), "--out", str(tmp_path / "x.dcoef"))
    assert done.returncode == 2, done.stderr
    assert "does not implement effect 'cogging' (on motor m3)" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr
    assert not (tmp_path / "x.dcoef").exists()


def test_figures_plot_the_results_numbers(augmented: dict) -> None:
    """Every figure's plotted data are the result's numbers: the gap bars, and each finding's profile."""
    from dynid.report.gaps_figures import build, findings

    figs = augmented["figures"]
    result = json.loads((figs / "gaps.json").read_text())
    index = json.loads((figs / "figures.json").read_text())
    assert [i["file"] for i in index][0] == "gap.png"
    for i in index:
        assert (figs / i["file"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    found = findings(result)
    assert ("pwm.m2", "r_shoulder_yaw", "explained") in found  # the spring, through the coupled shoulder
    assert ("pwm.m3", "r_elbow") in [(c, j) for c, j, _ in found]  # the Stribeck
    built = {name: fig for name, _, fig in build(result)}
    assert sorted(built) == sorted(i["file"] for i in index)

    def heights(ax, gid: str) -> list[float]:
        return [p.get_height() for p in ax.patches if p.get_gid() == gid]

    ax = built["gap.png"].axes[0]
    assert heights(ax, "before") == pytest.approx([g["before_over_noise"] for g in result["gap"]])
    assert heights(ax, "after") == pytest.approx([g["after_over_noise"] for g in result["gap"]])
    prof = result["profile"]["channels"]["pwm.m3"]
    speed, rev, pos, time = built["finding_pwm.m3.png"].axes
    line = {ln.get_gid(): ln for ln in speed.lines if ln.get_gid()}
    expect = [np.nan if v is None else v for v in prof["joints"]["r_elbow"]["speed"]["before"]]
    assert np.allclose(line["before"].get_ydata(), expect, equal_nan=True)
    assert heights(rev, "after") == pytest.approx(prof["joints"]["r_elbow"]["reversal"]["after"])
    line = {ln.get_gid(): ln for ln in time.lines if ln.get_gid()}
    assert np.allclose(line["after"].get_ydata(), [np.nan if v is None else v for v in prof["time"]["after"]],
                       equal_nan=True)
    # the finding is real: the elbow's Stribeck residual is largest at low speed, and the fix removes most of it
    before = [v for v in prof["joints"]["r_elbow"]["speed"]["before"] if v is not None]
    after = [v for v in prof["joints"]["r_elbow"]["speed"]["after"] if v is not None]
    assert before[0] == max(before) and after[0] < 0.75 * before[0]


def test_report_shows_the_gaps_figures(augmented: dict, tmp_path: Path) -> None:
    """`dynid report --gaps DIR`'s section: every figure of DIR, the named effects and the gap table; a directory
    that is not a gaps result is refused at once, in one line."""
    import base64

    from dynid.report.gaps_figures import report_section

    figs = augmented["figures"]
    html, result = report_section(str(figs))
    page = "\n".join(html)
    for i in json.loads((figs / "figures.json").read_text()):
        assert base64.b64encode((figs / i["file"]).read_bytes()).decode() in page
    assert "stribeck" in page and "joint r_elbow" in page and "spring" in page
    assert page.count("<tr>") >= len(result["gap"]) + len(result["effects"])
    done = dynid("report", "--model", "m.json", "--validation", "v", "--contact", "c", "--out",
                 str(tmp_path / "r.html"), "--gaps", str(tmp_path))
    assert done.returncode == 2 and "not a `dynid gaps --figures` directory" in done.stderr, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1


def test_report_takes_the_augmented_model(augmented: dict, tmp_path: Path) -> None:
    """`dynid gaps --help` says report accepts the augmented model: it did not ("lacks its 'base' section"). Its
    page now has every section but the base-parameter table, which it says it lacks and why."""
    out = tmp_path / "r.html"
    done = dynid("report", "--model", str(augmented["model"]), "--validation", str(augmented["runs"]["replay"]),
                 "--out", str(out), "--json", str(tmp_path / "r.json"))
    assert done.returncode == 0, done.stderr
    assert json.loads((tmp_path / "r.json").read_text())["parameters"] == []
    assert "holds no base-parameter statistics" in out.read_text()
    # why its momentum and combined variants are missing, as `dynid detect` says it (not "detect calibrates them")
    assert "an augmented model (named effects) has no momentum residual yet" in out.read_text()


def test_report_takes_a_text_parameter_and_refuses_another_robots_gaps(augmented: dict, tmp_path: Path) -> None:
    """A limit step names its joint (a text parameter): the section formatted it as a number, a traceback (the iCub
    leg's gaps, a walkthrough). And a folder of another robot's gaps went into the page unchecked."""
    import shutil

    from dynid.report.gaps_figures import report_section

    figs = tmp_path / "figs"
    shutil.copytree(augmented["figures"], figs)
    result = json.loads((figs / "gaps.json").read_text())
    assert result["robot"] == "icub_right_arm"
    result["effects"].append({"name": "limit_step", "where": "sensor r_arm_ft", "parameters": {"joint": "r_elbow",
                              "at_deg": 30.0}, "standard_errors": {"at_deg": 0.5}, "cv_gain": 0.3})
    (figs / "gaps.json").write_text(json.dumps(result))
    page = "\n".join(report_section(str(figs))[0])
    assert "joint r_elbow, at_deg 30 ± 0.5" in page
    result["robot"] = "panda"
    (figs / "gaps.json").write_text(json.dumps(result))
    done = dynid("report", "--model", str(augmented["model"]), "--validation", str(augmented["runs"]["replay"]),
                 "--out", str(tmp_path / "r.html"), "--gaps", str(figs))
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "the gaps of panda, not of icub_right_arm" in done.stderr and not (tmp_path / "r.html").exists()


def test_a_finding_figure_for_every_channel_a_motors_effect_helps() -> None:
    """An effect on a motor (armature, load friction: the UR10e's) helped its own input channel, and no figure showed
    it: only channels with an effect on one of their joints, or left unexplained, had one (a walkthrough: one figure of
    five)."""
    from dynid.report.gaps_figures import findings

    speed = {"speed": {"before": [2.0, 1.0], "after": [1.0, 1.0]}}
    result = {"effects": [{"where": "motor wrist_1"}, {"where": "joint elbow_joint"}],
              "profile": {"channels": {f"current.{j}": {"joints": {f"{j}_joint": speed}}
                                       for j in ("wrist_1", "elbow", "wrist_2")}},
              "gap": [{"channel": "current.wrist_1", "before_over_noise": 3.0, "after_over_noise": 1.1},
                      {"channel": "current.elbow", "before_over_noise": 3.0, "after_over_noise": 1.1},
                      {"channel": "current.wrist_2", "before_over_noise": 1.1, "after_over_noise": 1.05}]}
    assert [(c, why) for c, _, why in findings(result)] == [("current.wrist_1", "explained"),
                                                             ("current.elbow", "explained")]


def test_a_refit_worse_than_the_given_model_is_said_not_called_unexplained() -> None:
    """`gaps --model` on a short run: the refit (inertias held) left the Panda's joint 5 at 1.46× its noise where the
    given model had 0.67×, and the report called the channel unexplained (a walkthrough). The given model explains it:
    the refit is said to be worse there, and `--out` warns (tools/dynid/cli/gaps.py)."""
    from dynid.gaps.workflow import format_report, worse_than_given

    def gap(channel: str, given: float, after: float) -> dict:
        return {"channel": channel, "unit": "Nm", "given_model_rms": given / 10, "before_rms": after / 10,
                "after_rms": after / 10, "given_model_over_noise": given, "before_over_noise": after,
                "after_over_noise": after}

    result = {"effects": [], "ruled_out": [], "gap": [gap("tau.j5", 0.67, 1.46), gap("tau.j2", 2.2, 2.29),
                                                      gap("tau.j6", 0.69, 0.99)],
              "not_tried": [], "given_model": "panda.json", "seconds": 0.7}
    assert [g["channel"] for g in worse_than_given(result)] == ["tau.j5"]  # j6: worse, but within the noise
    text = format_report(result)
    assert "the refit is worse than the given model on tau.j5 (1.46× against its 0.67×)" in text
    assert "unexplained: tau.j2 2.29× its noise floor" in text and "tau.j5 1.46×" not in text.split("unexplained")[1]


def test_figures_into_a_reused_folder_keep_only_this_results(augmented: dict, tmp_path: Path) -> None:
    """`--figures DIR` twice: the first run's findings stayed beside the second's, unreferenced (a walkthrough)."""
    import shutil

    from dynid.report.gaps_figures import write_figures

    figs = tmp_path / "figs"
    shutil.copytree(augmented["figures"], figs)
    (figs / "finding_pwm.m9.png").write_bytes(b"an earlier run's")
    result = json.loads((figs / "gaps.json").read_text())
    written = write_figures(result, str(figs))
    assert not (figs / "finding_pwm.m9.png").exists()
    assert sorted(p.name for p in figs.glob("*.png")) == sorted(written)
