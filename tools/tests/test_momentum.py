"""The generalized-momentum residuals (dynid.detect.momentum) against independent references: Pinocchio's inverse
dynamics (the identity ṗ = τ + Cᵀq̇ − g on every coordinate, the F/T sensors' included), an exact synthetic plant
with a known external torque and wrench, the simulated arm's recorded contacts, and the acceleration-based
residual on the same data; the static-friction band at rest; `dynid detect --residual momentum` and
`--episodes` end to end."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import dynid

from dynid.config.robot_config import load_config
from dynid.detect import momentum as mo
from dynid.robot.model import RobotModel
from dynid.robot.outputs import output_channels, residuals
from dynid.robot.regressors.rigid_body import rigid_body_regressors
from dynid.robot.regressors.stack import Signals

MODEL = RobotModel(load_config("icub_right_arm"))
CFG = MODEL.config
RATE = 1000.0
BW = 15.0


def _phi(coulomb: float = 0.0) -> np.ndarray:
    rng = np.random.default_rng(3)
    phi = MODEL.cad_parameters()
    for b in MODEL.layout.blocks_of("ft_offset"):
        phi[b.slice] = rng.normal(0.0, 1.0, 6)
    for b in MODEL.layout.blocks_of("joint_friction") + MODEL.layout.blocks_of("motor_friction"):
        phi[b.slice] = [coulomb, coulomb, 0.05, 0.06]
    for m in CFG.motor_names:
        phi[MODEL.layout.block("motor_gain", m).start] = 20.0
    return phi


def _trajectory(seconds: float = 3.0, rest: str | None = None) -> tuple[np.ndarray, ...]:
    t = np.arange(0.0, seconds, 1.0 / RATE)
    n = MODEL.n_joints
    a, w = 0.3 + 0.05 * np.arange(n), 2.0 + 0.3 * np.arange(n)
    q = a * np.sin(w * t[:, None]) + 0.2
    dq = a * w * np.cos(w * t[:, None]) + 0.4  # an offset keeps every joint moving one way (no rest)
    q += 0.4 * t[:, None]
    ddq = -a * w**2 * np.sin(w * t[:, None])
    if rest is not None:
        c = CFG.joints.index(rest)
        q[:, c], dq[:, c], ddq[:, c] = 0.3, 0.0, 0.0
    return t, q, dq, ddq


def _exact_measurements(phi: np.ndarray, q, dq, ddq) -> tuple[dict, dict]:
    """The inputs and wrenches an exact model predicts (y = ŷ: e = 0)."""
    outs = output_channels(MODEL)
    zero = Signals(q, dq, ddq, {m: np.zeros(len(q)) for m in CFG.motor_names}, {},
                   {s.name: np.zeros((len(q), 6)) for s in CFG.ft_sensors})
    y_hat = -residuals(MODEL, phi, zero)  # e = y − ŷ with y = 0
    inputs = {o.motor: y_hat[:, o.row].copy() for o in outs if o.kind == "input"}
    ft = {s.name: y_hat[:, 6 * i : 6 * i + 6].copy() for i, s in enumerate(CFG.ft_sensors)}
    return inputs, ft


def test_identified_pinocchio_reproduces_the_regressor_and_the_momentum_identity() -> None:
    rng = np.random.default_rng(0)
    phi = _phi()
    phi[MODEL.layout.span("inertial")] *= rng.uniform(0.5, 1.5, MODEL.layout.span("inertial").stop)  # not CAD
    pm = mo.identified_pinocchio(MODEL, phi)
    data = pm.createData()
    q, dq, ddq = (rng.uniform(-0.6, 0.6, (4, MODEL.n_joints)) for _ in range(3))
    rb = rigid_body_regressors(MODEL, q, dq, ddq)
    inertial = phi[MODEL.layout.span("inertial")]
    Q, V, A = MODEL.pinocchio_configuration(q), MODEL.pinocchio_velocity(dq), MODEL.pinocchio_velocity(ddq)
    for k in range(4):
        tau = pin.rnea(pm, data, Q[k], V[k], A[k])
        assert np.allclose(tau[MODEL.v_index], rb.tau[k] @ inertial, atol=1e-10)
        for s, v0 in MODEL.sensor_v_index.items():
            assert np.allclose(-tau[v0 : v0 + 6], rb.ft[s][k] @ inertial, atol=1e-10)

        def p(x: np.ndarray, v: np.ndarray) -> np.ndarray:
            M = pin.crba(pm, data, MODEL.pinocchio_configuration(x)[0])
            return (np.triu(M) + np.triu(M, 1).T) @ MODEL.pinocchio_velocity(v)[0]

        h = 1e-6  # ṗ by central differences along the motion, against τ − g + Cᵀq̇ (sensor coordinates included)
        pdot = (p(q[k] + h * dq[k] + h * h / 2 * ddq[k], dq[k] + h * ddq[k])
                - p(q[k] - h * dq[k] + h * h / 2 * ddq[k], dq[k] - h * ddq[k])) / (2 * h)
        C = pin.computeCoriolisMatrix(pm, data, Q[k], V[k])
        g = pin.computeGeneralizedGravity(pm, data, Q[k])
        assert np.allclose(pdot, tau - g + C.T @ V[k], atol=1e-7 * max(1.0, np.abs(pdot).max()))


def test_exact_model_gives_zero_and_a_known_contact_its_low_passed_value() -> None:
    phi = _phi()
    t, q, dq, ddq = _trajectory()
    inputs, ft = _exact_measurements(phi, q, dq, ddq)
    free = mo.momentum_residuals(MODEL, phi, t, q, inputs, {}, ft, bandwidth_hz=BW, dq=dq)
    scale = {"ft": np.abs(ft["r_arm_ft"]).max(), "input": 20.0 * max(np.abs(u).max() for u in inputs.values())}
    settled = t > 0.1
    assert np.abs(free.r[settled, :6]).max() < 2e-3 * scale["ft"]
    assert np.abs(free.r[settled, 6:]).max() < 2e-3 * scale["input"]
    # A contact from 1 s on: 0.8 Nm on the elbow (the motors need that much less) and a wrench at the sensor.
    on = (t >= 1.0).astype(float)
    tau_elbow, wrench = 0.8, np.array([3.0, -2.0, 1.0, 0.2, -0.1, 0.05])
    elbow_motor = next(g for g in CFG.actuation if "r_elbow" in g.joints).motors[0]
    inputs[elbow_motor] = inputs[elbow_motor] - on * tau_elbow / 20.0
    ft["r_arm_ft"] = ft["r_arm_ft"] + on[:, None] * wrench
    hit = mo.momentum_residuals(MODEL, phi, t, q, inputs, {}, ft, bandwidth_hz=BW, dq=dq)
    expected = mo.first_order(t, on, BW)
    elbow = CFG.joints.index("r_elbow")
    assert np.abs(hit.tau_ext[:, elbow] - tau_elbow * expected).max() < 0.01 * tau_elbow
    assert np.abs(hit.r[:, :6] - np.outer(expected, wrench)).max() < 0.01 * np.abs(wrench).max() + 2e-3 * scale["ft"]
    others = [c for c in range(MODEL.n_joints) if c != elbow]
    assert np.abs(hit.tau_ext[settled][:, others]).max() < 0.02 * tau_elbow  # isolated to the elbow
    # the time constant: 1/(2π·15 Hz) = 10.6 ms to 63 %
    k = np.argmax(hit.tau_ext[:, elbow] >= (1 - np.exp(-1)) * tau_elbow)
    assert abs(t[k] - 1.0 - 1 / (2 * np.pi * BW)) < 1.5e-3


def test_a_resting_joint_shows_only_what_lies_outside_its_static_friction_band() -> None:
    coulomb = 0.3
    phi = _phi(coulomb)
    t, q, dq, ddq = _trajectory(rest="r_elbow")
    inputs, ft = _exact_measurements(phi, q, dq, ddq)
    motor = next(g for g in CFG.actuation if "r_elbow" in g.joints).motors[0]
    row = next(o.row for o in output_channels(MODEL) if o.motor == motor)
    for held, outside in ((0.2, 0.0), (-0.25, 0.0), (0.5, 0.2), (-0.45, -0.15)):
        u = dict(inputs)
        u[motor] = inputs[motor] + held / 20.0  # static friction holds `held` Nm
        res = mo.momentum_residuals(MODEL, phi, t, q, u, {}, ft, bandwidth_hz=BW, dq=dq)
        late = t > 0.5
        assert res.at_rest[late, row].all()
        assert np.allclose(res.r[late, row], held, atol=1e-3)  # the torque held, at rest
        assert np.allclose(res.e[late, row], outside, atol=1e-3)  # and only its part outside ±0.3 Nm is a residual


@pytest.mark.parametrize("start", [0.0, 1234.567])  # stamps far from zero round their steps unevenly
def test_causal_velocity_on_uniform_steps_is_the_local_fit(start: float) -> None:
    """The uniform path (one set of weights, the monitor's) gives what the per-window fit in local time gives."""
    t = start + np.arange(3000) * 1e-3
    q = np.column_stack([np.sin(2 * t), np.cos(3 * t) + 0.01 * np.random.default_rng(0).normal(size=t.size)])
    fast = mo.causal_velocity(t, q)
    w = mo.velocity_window_samples(t)
    reference = np.zeros_like(q)
    mo._local_quadratic_slopes(t, q, w, reference)
    np.testing.assert_allclose(fast[w - 1:], reference[w - 1:], rtol=0, atol=1e-9 * np.abs(reference).max())


def test_causal_velocity_is_causal_and_exact_on_a_quadratic() -> None:
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.008, 0.012, 300))  # jittered stamps
    q = (1.0 + 2.0 * t - 0.5 * t**2)[:, None]
    v = mo.causal_velocity(t, q)
    assert np.allclose(v[5:, 0], 2.0 - t[5:], atol=1e-8)
    q2 = q.copy()
    q2[200:] += 1.0  # a later change leaves every earlier estimate alone
    assert np.array_equal(mo.causal_velocity(t, q2)[:200], v[:200])


# ------------------------------------------------------------------------------------------------------------
# The simulated arm (the default experiments)


def test_the_observer_takes_the_robots_own_velocity_never_an_estimate_of_dynids() -> None:
    """velocity.<joint> extras first, then recorded dq columns; a dq that dynid estimated from q is not measured."""
    from dynid.io.dataset import Dataset

    t = np.arange(400) / RATE
    q = np.outer(np.sin(2 * np.pi * t), np.arange(1, MODEL.n_joints + 1) * 0.1)
    dq = np.outer(2 * np.pi * np.cos(2 * np.pi * t), np.arange(1, MODEL.n_joints + 1) * 0.1)
    recorded = Dataset(t=t, joints=CFG.joints, q=q, dq=dq)
    assert mo.measured_velocity(MODEL, recorded) is recorded.dq
    assert mo.measured_velocity(MODEL, recorded.with_derivatives()) is not None  # still the recorded one
    estimated = Dataset(t=t, joints=CFG.joints, q=q).with_derivatives()
    assert estimated.dq is not None and mo.measured_velocity(MODEL, estimated) is None
    extras = {f"velocity.{j}": 2 * dq[:, i] for i, j in enumerate(CFG.joints)}
    both = Dataset(t=t, joints=CFG.joints, q=q, dq=dq, extra=extras)
    np.testing.assert_array_equal(mo.measured_velocity(MODEL, both), 2 * dq)


def test_a_known_payload_joins_the_observers_model(default_experiments: dict[str, Path], default_model: Path) -> None:
    """--payload reaches the momentum residual: the run's payload is added to its body's inertial parameters."""
    from dataclasses import replace

    from dynid.detect.momentum_t2 import run_residuals
    from dynid.identify.model_file import load_model
    from dynid.io.load import apply_window, load_data

    identified = load_model(str(default_model))
    model, phi = identified.robot_model, identified.phi
    ds = load_data(default_experiments["validation"], model.config)
    ds = apply_window(ds, None, float(ds.t[0]) + 2.0, source="validation")
    payload = {"mass": 0.5, "com": [0.0, 0.02, 0.0]}
    carried = run_residuals(model, phi, replace(ds, meta={**ds.meta, "payload": payload}), BW, 0.01, {})
    loaded = np.array(phi, float)
    loaded[model.layout.span("inertial")] += model.payload_parameters(0.5, [0.0, 0.02, 0.0])
    np.testing.assert_allclose(carried.r, run_residuals(model, loaded, ds, BW, 0.01, {}).r, atol=1e-9)
    assert np.abs(carried.r - run_residuals(model, phi, ds, BW, 0.01, {}).r).max() > 0.01


def test_observer_tracks_the_plants_contacts_and_the_acceleration_residual(default_experiments: dict[str, Path],
                                                                           default_model: Path) -> None:
    from dynid.detect.online import raw_signals
    from dynid.detect.visibility import contact_residuals
    from dynid.identify.model_file import load_model
    from dynid.identify.validation import evaluate, load_run
    from dynid.robot.outputs import divisors

    identified = load_model(default_model)
    model, phi = identified.robot_model, identified.phi
    run = default_experiments["contact"]
    ds = load_run(str(run), model, (None, 30.0))
    t, q, inputs, tau, ft = raw_signals(model, ds)
    res = mo.momentum_residuals(model, phi, t, q, inputs, tau, ft, bandwidth_hz=BW, min_speed=identified.min_speed)
    g = divisors(model, phi)
    truth = np.load(run / "truth.npz")
    contact_e = contact_residuals(model, g, {k: truth[k][: t.size] for k in truth.files if k.startswith("extra/contact")})
    reference = mo.first_order(t, contact_e * g, BW)  # the contact's own residual, low-passed at K_O
    accel = mo.first_order(t, evaluate("", str(run), identified=identified, dataset=ds).e_constant * g, BW)
    inside = ds.contact != 0
    for c in (0, 2, 4):  # fx, fz, ty: the channels distal contacts load most
        assert np.corrcoef(res.r[inside, c], reference[inside, c])[0, 1] > 0.99  # measured 0.999, 0.997, 0.999
        assert np.corrcoef(res.r[:, c], accel[:, c])[0, 1] > 0.99  # measured 0.997, 0.995, 0.998
    motors = slice(6, None)
    err = np.sqrt(np.mean((res.r[inside, motors] - reference[inside, motors]) ** 2))
    assert err < 0.6 * np.sqrt(np.mean(reference[inside, motors] ** 2))  # measured 0.30


def test_detect_momentum_end_to_end(default_experiments: dict[str, Path], default_model: Path, tmp_path: Path) -> None:
    """Contact-free: FP ≤ 1.5 % at α = 0.99; contacts: every visible episode found, faster than the monitor's
    acceleration-based detector (median 24-25 ms); events carry the isolation and the estimates."""
    out = tmp_path / "free.json"
    done = dynid("detect", "--model", str(default_model), "--data", str(default_experiments["validation"]),
                 "--json", str(out))
    assert done.returncode == 0, done.stderr
    free = json.loads(out.read_text())
    # the default runs the combined detector (test_detect_combined.py), the momentum one beside it
    assert free["residual"] == "combined" and free["variants"]["momentum"]["fpr"] <= 0.015  # measured 0.81 %
    out = tmp_path / "contact.json"
    done = dynid("detect", "--model", str(default_model), "--data", str(default_experiments["contact"]),
                 "--json", str(out))
    assert done.returncode == 0, done.stderr
    hit = json.loads(out.read_text())
    m = hit["variants"]["momentum"]
    assert m["episodes_detected"] >= 26 and m["delay_s"]["median"] < 0.024  # measured 27/28, 16 ms
    assert m["fpr"] <= 0.015 and m["tpr_by_side"]["distal"] > 0.95  # measured 0.87 %, 99.3 %
    event = max(hit["events"], key=lambda e: e["peak_t2"])
    assert set(event) >= {"onset_s", "end_s", "side", "joint", "tau_ext_nm", "wrench"}
    assert event["side"]["r_arm_ft"] in ("distal", "proximal") and len(event["wrench"]["r_arm_ft"]) == 6


def test_episodes_labels_end_to_end(default_experiments: dict[str, Path], default_model: Path, tmp_path: Path) -> None:
    """--episodes from the run's own contact column gives the same scores; a bad file is one line, exit 2."""
    from dynid.io.dataset import contact_episodes
    from dynid.io.load import load_data

    run = default_experiments["contact"]
    ds = load_data(run, load_config("icub_right_arm"))
    rows = [(float(ds.t[a]), float(ds.t[b - 1])) for a, b in contact_episodes(ds.contact)]
    labels = tmp_path / "episodes.csv"
    labels.write_text("t_start,t_end\n" + "".join(f"{a!r},{b!r}\n" for a, b in rows))
    args = ("detect", "--model", str(default_model), "--data", str(run), "--residual", "acceleration")
    results = []
    for extra in ((), ("--episodes", str(labels), "--label-widening", "0.1")):
        out = tmp_path / f"r{len(results)}.json"
        done = dynid(*args, *extra, "--json", str(out))
        assert done.returncode == 0, done.stderr
        results.append(json.loads(out.read_text()))
    plain, labelled = (r["variants"]["calibrated"] for r in results)
    assert labelled["episodes"] == plain["episodes"] == len(rows)
    assert labelled["tpr"] == pytest.approx(plain["tpr"]) and labelled["fpr"] == pytest.approx(plain["fpr"])
    assert results[1]["episodes_file"]["episodes"] == len(rows)
    shifted = labelled["delay_s_shifted"]
    assert shifted["median"] == pytest.approx(labelled["delay_s"]["median"] - 0.1)
    for text, words in (("t0,t1\n1,2\n", "header"), ("t_start,t_end\n2,1\n", "not after"),
                        ("t_start,t_end\n1,3\n2,4\n", "overlaps"), ("t_start,t_end\n1,x\n", "not two numbers"),
                        ("", "empty"), ("t_start,t_end\n1,nan\n", "finite")):
        bad = tmp_path / "bad.csv"
        bad.write_text(text)
        done = dynid(*args, "--episodes", str(bad))
        assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
        assert words in done.stderr
    done = dynid(*args, "--episodes", str(tmp_path / "missing.csv"))
    assert done.returncode == 2 and "does not exist" in done.stderr
    # Labels in another clock, and a widening that leaves no episode, are refused rather than scored.
    elsewhere = tmp_path / "elsewhere.csv"
    elsewhere.write_text(f"t_start,t_end\n{float(ds.t[-1]) + 10!r},{float(ds.t[-1]) + 20!r}\n")
    for extra, words in ((("--episodes", str(elsewhere)), "hold none of its episodes"),
                         (("--episodes", str(labels), "--label-widening", "100"), "--label-widening 100 s"),
                         (("--label-widening", "100"), "contact column"),
                         (("--calibration-from", "1"), "not with --residual acceleration")):
        done = dynid(*args, *extra)
        assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
        assert words in done.stderr, done.stderr


def test_the_api_detector_uses_the_momentum_residual(default_experiments: dict[str, Path], default_model: Path) -> None:
    import dynid

    detector = dynid.ContactDetector(dynid.load_model(default_model), variant="momentum")
    run = str(default_experiments["validation"])
    result = detector.evaluate(run)  # calibrated on the model's identification run (its first 150 s)
    assert result["fpr"] <= 0.015  # measured 0.81 %
    assert detector.predict(run).mean() == pytest.approx(result["fpr"])
    assert detector._momentum.bandwidth_hz == 15.0 and detector._momentum.threshold > 0  # the lazy calibration


def test_a_bandwidth_above_the_datas_nyquist_is_a_bad_value(default_experiments: dict[str, Path], default_model: Path,
                                                           tmp_path: Path) -> None:
    """Given by the user, a bandwidth the data's rate cannot carry ends the command (exit 2, one line, nothing
    written); only the default, where a slow log cannot carry it, drops the observer with a note."""
    out = tmp_path / "m.dcoef"
    for command in (("detect", "--data", str(default_experiments["contact"])), ("export", "--out", str(out))):
        done = dynid(*command[:1], "--model", str(default_model), *command[1:], "--bandwidth", "600")
        assert done.returncode == 2, done.stdout
        assert done.stderr.strip() == (f"dynid {command[0]}: error: the observer's bandwidth 600 Hz is at or above the "
                                       "data's Nyquist frequency (500 Hz): give a lower --bandwidth"), done.stderr
    assert not out.exists()
