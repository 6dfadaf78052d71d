"""The monitor's momentum observer (rt_monitor/src/momentum.cpp, core.cpp) against dynid's (dynid.detect.momentum,
on Pinocchio's crba, Coriolis matrix and gravity): sample by sample on the default runs, the coefficient file's
observer section, T²'s promise through the core, and the contact events' external torques."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_rt_core import EXIT_BASE, RT_EVAL, detector_columns, raw_samples, read_matrix, rt_eval, write_matrix

from dynid.config.robot_config import load_config
from dynid.detect.momentum import causal_velocity_weights, friction_band, momentum_residuals
from dynid.detect.momentum_t2 import BAND_SIGMAS, MomentumDetector
from dynid.detect.online import raw_signals
from dynid.export.capacity import file_version
from dynid.export.coefficients import read_coefficients, unwrap, wrap
from dynid.export.lcm_coefficients import coefficients_t
from dynid.identify.model_file import load_model
from dynid.identify.validation import load_run
from dynid.robot.model import RobotModel

SECONDS = 20.0  # of each run, through both: the agreement is per sample, not statistical


def stream_momentum(coef: Path, raw: np.ndarray, work: Path) -> dict[str, np.ndarray]:
    """`rt_eval --residual momentum --stream`: the core's observer outputs per raw sample."""
    c = read_coefficients(coef)
    nj, no = c.n_joints, c.n_outputs
    write_matrix(work / "in.mx", raw)
    done = rt_eval("--coef", str(coef), "--residual", "momentum", "--stream", str(work / "in.mx"), str(work / "out.mx"))
    assert done.returncode == 0, done.stderr
    y = read_matrix(work / "out.mx")
    col = detector_columns(c)
    obs = col["r"]  # the observer's columns follow the detector's
    return {"ready": y[:, 0] > 0, "dq": y[:, 1 + nj : 1 + 2 * nj], "e": y[:, 1 + 3 * nj + 2 * no : col["t2"]],
            "t2": y[:, col["t2"]], "above": y[:, col["above"]] > 0,
            "r": y[:, obs : obs + no], "tau_ext": y[:, obs + no : obs + no + nj], "joint": y[:, obs + no + nj]}


def python_observer(model_path: Path, coef: coefficients_t, run: Path, seconds: float = SECONDS):
    """dynid's observer on the first `seconds` of `run`, as the coefficient file configures the monitor's."""
    identified = load_model(model_path)
    model = identified.robot_model
    ds = load_run(str(run), model)
    n = int(round(seconds / coef.sample_period))
    t, q, inputs, tau, ft = raw_signals(model, ds)
    cut = lambda d: {k: np.asarray(v)[:n] for k, v in d.items()}  # noqa: E731
    band = friction_band(model, identified.phi, identified.base, BAND_SIGMAS)
    res = momentum_residuals(model, identified.phi, t[:n], q[:n], cut(inputs), cut(tau), cut(ft), None,
                             bandwidth_hz=coef.observer_bandwidth, min_speed=coef.min_speed, band=band,
                             tracking=identified.supply_tracking)
    return res, raw_samples(ds, coef)[:n]


@pytest.mark.parametrize("kind", ["validation", "contact"])
def test_core_observer_is_dynids_sample_by_sample(exported: Path, default_model: Path, default_experiments: dict,
                                                  kind: str, tmp_path: Path) -> None:
    c = read_coefficients(exported)
    assert c.velocity_window > 0, "the default export carries the observer"
    res, raw = python_observer(default_model, c, default_experiments[kind])
    core = stream_momentum(exported, raw, tmp_path)
    ready = core["ready"]
    # ready once the q̇ estimator's window is full; dynid's observer starts there too (r = 0 before)
    assert np.argmax(ready) == c.velocity_window - 1 and ready[c.velocity_window - 1 :].all()
    assert np.all(res.r[~ready] == 0)
    scale = np.std(res.r[ready], axis=0)
    for name, ours in (("r", res.r), ("e", res.e)):
        err = np.max(np.abs(core[name][ready] - ours[ready]), axis=0) / scale
        assert np.all(err < 1e-7), f"{name}: largest difference per channel, in channel stds: {err}"
    assert np.max(np.abs(core["dq"][ready] - res.dq[ready])) < 1e-9
    moved = np.std(res.tau_ext, axis=0) > 0  # joints with a row (the iCub arm's wrist has none)
    err = np.max(np.abs(core["tau_ext"][:, moved] - res.tau_ext[:, moved])) / np.max(np.std(res.tau_ext[:, moved], axis=0))
    assert err < 1e-7
    assert np.all(core["tau_ext"][:, ~moved] == 0)
    # T² with the file's Λ: the same statistic as dynid's detector
    det = MomentumDetector(c.observer_bandwidth, np.asarray(c.observer_variance), np.asarray(c.tau_variance),
                           c.observer_threshold, c.alpha, c.min_speed, BAND_SIGMAS, {}, 1)
    t2 = det.t2(res.e)
    np.testing.assert_allclose(core["t2"][ready], t2[ready], rtol=1e-6, atol=1e-9 * np.median(t2))
    # the same alarms, but for at most one sample that lies on the threshold itself
    assert np.sum(core["above"][ready] != (t2 > c.observer_threshold)[ready]) <= 1
    # the isolated joint: the most distal one whose |τ_ext| exceeds isolation_sigmas of its noise (momentum_t2)
    significant = np.abs(res.tau_ext) > c.isolation_sigmas * np.sqrt(np.asarray(c.tau_variance))
    expected = np.where(significant.any(axis=1), significant.shape[1] - 1 - np.argmax(significant[:, ::-1], axis=1), -1)
    assert np.sum(core["joint"][ready] != expected[ready]) <= 1
    assert (expected[ready] >= 0).any(), "no sample isolates a joint: the comparison says nothing"


def test_observer_threshold_keeps_its_promise_through_the_core(exported: Path, default_experiments: dict,
                                                               tmp_path: Path) -> None:
    """T²_α of the file's observer, calibrated on the identification run, on the held-out contact-free validation
    run through the core: the per-sample false-positive rate α promises (1 %), within 1.5 %."""
    c = read_coefficients(exported)
    ds = load_run(str(default_experiments["validation"]), RobotModel(load_config("icub_right_arm")))
    core = stream_momentum(exported, raw_samples(ds, c), tmp_path)
    settled = core["ready"].copy()
    settled[: c.velocity_window + int(5 / (2 * np.pi * c.observer_bandwidth * c.sample_period))] = False
    fpr = float(np.mean(core["above"][settled]))
    assert fpr <= 0.015, f"false positives {fpr:.2%} at α = {c.alpha}"
    assert fpr > 0.001, "a threshold no sample ever crosses: the statistic is not the calibrated one"


def test_observer_section_is_checked(exported: Path, tmp_path: Path) -> None:
    """A file that selects the observer without carrying one, a bandwidth of 0, a negative band, or one of the
    format before the observer: refused by the loader (exit 10 + reason) and by dynid's reader, with one line."""
    good = exported.read_bytes()
    c = coefficients_t.decode(unwrap(good))

    def variant(name: str, change) -> Path:
        d = coefficients_t.decode(unwrap(good))
        change(d)
        p = tmp_path / f"{name}.dcoef"
        p.write_bytes(wrap(d.encode()))
        return p

    def none(d):
        d.residual, d.velocity_window, d.velocity_filter = 1, 0, []

    def zero_bandwidth(d):
        d.observer_bandwidth = 0.0

    def negative_band(d):
        d.joint_band[0] = [-0.1, 0.0]

    cases = {"none": (none, "selects the momentum residual but carries no observer"),
             "bandwidth": (zero_bandwidth, "momentum observer settings out of range"),
             "band": (negative_band, "r_shoulder_pitch: its static-friction band must be ≥ 0")}
    for name, (change, message) in cases.items():
        done = rt_eval("--coef", str(variant(name, change)), "--check")
        assert done.returncode == EXIT_BASE + 8, (name, done.stderr)
        assert message in done.stderr and done.stderr.count("\n") == 1, (name, done.stderr)
    old = tmp_path / "v3.dcoef"
    old.write_bytes(wrap(unwrap(good), version=3))
    done = rt_eval("--coef", str(old), "--check")
    assert done.returncode == EXIT_BASE + 4
    assert f"format version 3, this monitor reads {file_version()}: export the model again" in done.stderr
    with pytest.raises(Exception, match=f"format version 3, this dynid reads {file_version()}"):
        read_coefficients(old)
    # the observer's q̇ weights are the causal quadratic slope dynid uses
    np.testing.assert_allclose(c.velocity_filter, causal_velocity_weights(c.velocity_window, c.sample_period),
                               rtol=0, atol=1e-9)
    assert RT_EVAL.is_file()


def test_observer_visibility_scales_with_the_contact(exported: Path, default_experiments: dict) -> None:
    """The live summary's 'visible' for an observer file: no contact is visible when the plant's contact records are
    zeroed, every one when they are a thousand times stronger, and in between the default run's."""
    from dynid.detect.visibility import observer_visibility

    c = read_coefficients(exported)
    c.residual = 1
    model = RobotModel(load_config("icub_right_arm"))
    truth = dict(np.load(default_experiments["contact"] / "truth.npz"))
    contact = [k for k in truth if k.startswith("extra/contact.")]

    def visible(scale: float) -> int:
        scaled = {**truth, **{k: scale * np.asarray(truth[k], float) for k in contact}}
        return sum(v.visible for v in observer_visibility(model, c, scaled))

    episodes = len(observer_visibility(model, c, truth))
    assert visible(0.0) == 0
    assert visible(1e3) == episodes
    assert 0 < visible(1.0) < episodes
