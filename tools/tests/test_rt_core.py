"""The real-time core (rt_monitor/) against dynid: cross-language vectors, the online filter, the coefficient
file's checks, and the threshold's promise when the contact-free validation run is replayed through the core."""

from __future__ import annotations

import subprocess
import zlib
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import savgol_coeffs
from conftest import dynid

from dynid.config.robot_config import load_config
from dynid.detect.online import FixedLagSavitzkyGolay, online_signals, online_times, raw_signals
from dynid.detect.t2 import Detector
from dynid.export.capacity import capacity, file_version
from dynid.export.coefficients import read_coefficients, unwrap, wrap
from dynid.export.lcm_coefficients import coefficients_t
from dynid.export.rt_eval_io import detector_columns, raw_samples, read_matrix, run_stream, write_matrix  # noqa: F401 (the other rt tests import them from here)
from dynid.identify.model_file import load_model
from dynid.identify.supply import SupplyTracker
from dynid.io.load import load_data
from dynid.robot.outputs import residuals
from dynid.robot.regressors.stack import Signals

ROOT = Path(__file__).resolve().parents[2]
BUILDS = [b for b in (ROOT / "build", ROOT / "build-asan") if (b / "rt_monitor" / "rt_eval").is_file()]
RT_EVAL = ROOT / "build" / "rt_monitor" / "rt_eval"
FIXTURE = ROOT / "rt_monitor" / "tests" / "data" / "icub_cad.dcoef"
EXIT_BASE = 10  # rt_monitor: kExitBase + LoadError


def without_known_answers(c: coefficients_t) -> coefficients_t:
    """A deliberately edited file, for a test of what the monitor does with it: marked as a CAD export, which carries
    no known answers, so that the loader's known-answer check (which refuses any edit of a fitted file) lets it run."""
    c.estimator, c.n_known, c.known_input, c.known_answer = "cad", 0, [], []
    return c


def rt_eval(*args: str, exe: Path = RT_EVAL) -> subprocess.CompletedProcess:
    assert exe.is_file(), f"{exe} is not built (scripts/setup)"
    return subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=600)


def stream(coef: Path, raw: np.ndarray, work: Path, *options: str) -> np.ndarray:
    """The core's per-sample output rows (`rt_eval OPTIONS --stream`) for the raw samples `raw`."""
    assert RT_EVAL.is_file(), f"{RT_EVAL} is not built (scripts/setup)"
    return run_stream(RT_EVAL, coef, raw, work, *options)


def python_mirror(identified, c: coefficients_t, t: np.ndarray, q: np.ndarray, inputs: dict, ft: dict):
    """dynid's own mirror of the core on raw samples, independent of the C++: the online filter, the residuals with
    constant gains, then the supply tracker over them. (signals, tracker, tracked residuals, ratios)."""
    model = identified.robot_model
    est = FixedLagSavitzkyGolay(c.window, c.order, c.lag, c.sample_period)
    sig = online_signals(model, est, t, q, inputs, {}, ft)
    tracker = SupplyTracker(model, identified.supply_tracking, c.min_speed)
    e, ratio = tracker.apply(residuals(model, identified.phi, sig), sig, online_times(est, t))
    return sig, tracker, e, ratio


def rel_err(a: np.ndarray, b: np.ndarray, scale: np.ndarray) -> float:
    return float(np.max(np.abs(a - b) / scale))


# ---- the online filter -------------------------------------------------------------------------------------


@pytest.mark.parametrize("lag", [0, 7, 15])
def test_fixed_lag_weights_are_scipys_savitzky_golay(lag: int) -> None:
    est = FixedLagSavitzkyGolay(31, 3, lag, 1e-3)
    w = est.weights()
    for d in range(3):  # scipy's coefficients, evaluated at window position 30 − lag, as a dot product
        ref = savgol_coeffs(31, 3, deriv=d, delta=1e-3, pos=30 - lag, use="dot")
        assert np.allclose(w[d], ref, rtol=1e-9, atol=1e-9 * np.abs(ref).max())


def test_fixed_lag_filter_is_exact_on_a_cubic() -> None:
    t = np.arange(200) * 1e-3
    q = 0.3 + 2 * t - 5 * t**2 + 7 * t**3
    est = FixedLagSavitzkyGolay(31, 3, 5, 1e-3)
    value, d1, d2 = est.apply(q[:, None])
    at = t[30 - 5 : 200 - 5]
    assert np.allclose(value[:, 0], 0.3 + 2 * at - 5 * at**2 + 7 * at**3, atol=1e-12)
    assert np.allclose(d1[:, 0], 2 - 10 * at + 21 * at**2, atol=1e-8)
    assert np.allclose(d2[:, 0], -10 + 42 * at, atol=1e-5)


# ---- cross-language equality --------------------------------------------------------------------------------


def vector_states(model, n: int = 600, seed: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """States that cover both signs of every joint velocity, zero velocity (joints, and the coupled shoulder's
    motors), slow joints that gate motor channels, and the coupled shoulder in every sign combination."""
    rng = np.random.default_rng(seed)
    nj = model.n_joints
    lo = np.array([model.joint_limits[j][0] for j in model.config.joints])
    hi = np.array([model.joint_limits[j][1] for j in model.config.joints])
    q = rng.uniform(lo, hi, (n, nj))
    signs = rng.choice([-1.0, 0.0, 1.0], (n, nj))
    signs[: 3**3, :3] = np.array(np.meshgrid(*[[-1.0, 0.0, 1.0]] * 3)).reshape(3, -1).T  # every shoulder combination
    dq = signs * rng.uniform(0.02, 1.5, (n, nj))
    # The coupled shoulder at rest (every motor velocity exactly 0) while the other joints move. (Not a motor
    # at rest by cancellation, q̇_0 = q̇_1 ≠ 0: dynid's q̇ @ Tᵀ may round that to ±1e-17 and take a Coulomb sign.)
    dq[n // 2 : n // 2 + 50, :3] = 0.0
    dq[n // 2 + 50 : n // 2 + 100] *= 0.004  # below min_speed: motor channels gated
    # At rest as a derivative filter gives it: ±1e-15, not 0. Inside the velocity floor, no Coulomb sign on either side.
    dq[n // 2 + 100 : n // 2 + 150, :3] = rng.choice([-1.0, 1.0], (50, 3)) * rng.uniform(1e-16, 1e-10, (50, 3))
    ddq = rng.normal(0, 3.0, (n, nj))
    return q, dq, ddq


def test_core_predicts_what_dynid_predicts(exported: Path, default_model: Path, tmp_path: Path) -> None:
    identified = load_model(default_model)
    model = identified.robot_model
    c = read_coefficients(exported)
    q, dq, ddq = vector_states(model)
    n = q.shape[0]
    rng = np.random.default_rng(4)
    # Measured outputs: arbitrary, of the size real ones have (the residual formula does not care).
    ft = rng.normal(0, 5.0, (n, 6))
    pwm = {m: rng.uniform(-0.5, 0.5, n) for m in ("m0", "m1", "m2", "m3")}
    sig = Signals(q, dq, ddq, pwm, {}, {"r_arm_ft": ft})
    e = residuals(model, identified.phi, sig)
    y = np.column_stack([ft] + [pwm[m] for m in c.motor_names])
    y_hat = y - e
    det = Detector("calibrated", np.asarray(c.residual_variance), c.threshold, c.alpha, c.min_speed, c.n_outputs)
    active = det.active(model, dq)
    t2 = det.t2(model, e, dq)
    assert active.all(axis=1).any() and (~active).any(), "the vectors must exercise the gating both ways"
    assert (np.abs(dq) == 0).any() and (dq > 0).any() and (dq < 0).any()

    write_matrix(tmp_path / "in.mx", np.hstack([q, dq, ddq, y]))
    done = rt_eval("--coef", str(exported), "--predict", str(tmp_path / "in.mx"), str(tmp_path / "out.mx"))
    assert done.returncode == 0, done.stderr
    out = read_matrix(tmp_path / "out.mx")
    no = c.n_outputs
    scale = np.maximum(np.abs(y_hat), np.abs(y)).max(axis=0)  # per channel: the size of what is compared
    assert rel_err(out[:, :no], y_hat, scale) <= 1e-9
    assert rel_err(out[:, no : 2 * no], e, scale) <= 1e-9
    assert np.array_equal(out[:, 2 * no : 3 * no].astype(bool), active)
    assert rel_err(out[:, 3 * no], t2, np.maximum(t2, 1e-12)) <= 1e-9


def test_stream_matches_the_python_mirror(exported: Path, default_model: Path, default_experiments: dict,
                                          tmp_path: Path) -> None:
    identified = load_model(default_model)
    model = identified.robot_model
    c = read_coefficients(exported)
    full = load_data(default_experiments["validation"], model.config)
    t, q, inputs, tau, ft = raw_signals(model, full)
    k = slice(0, 4000)
    t, q, inputs, ft = t[k], q[k], {m: v[k] for m, v in inputs.items()}, {s: v[k] for s, v in ft.items()}
    assert np.array_equal(FixedLagSavitzkyGolay(c.window, c.order, c.lag, c.sample_period).weights(), np.asarray(c.filter))
    tracking = identified.supply_tracking
    assert tracking is not None and c.supply_time_constant == tracking.time_constant_s
    sig, _, e, ratio = python_mirror(identified, c, t, q, inputs, ft)
    pwm = [i for i, k in enumerate(c.channel_kind) if k == 1]
    assert np.ptp(ratio[:, pwm], axis=0).min() > 1e-3  # the tracker moves within these 4 s: the check has teeth
    det = Detector("calibrated", np.asarray(c.residual_variance), c.threshold, c.alpha, c.min_speed, c.n_outputs)
    t2 = det.t2(model, e, sig.dq)

    out = stream(exported, np.hstack([q, ft["r_arm_ft"]] + [inputs[m][:, None] for m in c.motor_names]), tmp_path,
                 "--residual", "acceleration")  # the file selects the combined detector; these are its filter's
    nj, no = c.n_joints, c.n_outputs
    ready = out[:, 0] == 1
    assert not ready[: c.window - 1].any() and ready[c.window - 1 :].all()
    out = out[ready]
    for col, ref in ((1, sig.q), (1 + nj, sig.dq), (1 + 2 * nj, sig.ddq)):
        assert rel_err(out[:, col : col + nj], ref, np.abs(ref).max(axis=0) + 1e-12) <= 1e-9
    y = out[:, 1 + 3 * nj : 1 + 3 * nj + no]
    y_ref = np.column_stack([sig.ft["r_arm_ft"]] + [sig.inputs[m] for m in c.motor_names])
    scale = np.abs(y_ref).max(axis=0)
    assert rel_err(y, y_ref, scale) <= 1e-9
    assert rel_err(out[:, 1 + 3 * nj + 2 * no : 1 + 3 * nj + 3 * no], e, scale) <= 1e-9
    assert rel_err(out[:, 1 + 3 * nj + 3 * no], t2, np.maximum(t2, 1e-12)) <= 1e-9


def test_threshold_keeps_its_promise_online(exported: Path, default_experiments: dict, tmp_path: Path) -> None:
    """Replaying the contact-free validation run through the core: FPR within [0.5, 2] × (1 − α)."""
    c = read_coefficients(exported)
    config = load_config("icub_right_arm")
    ds = load_data(default_experiments["validation"], config)
    assert ds.contact is None or not ds.contact.any(), "the validation run must be contact-free"
    out = stream(exported, raw_samples(ds, c), tmp_path, "--residual", "acceleration")
    out = out[out[:, 0] == 1]
    above = out[:, detector_columns(c)["above"]]
    fpr = float(above.mean())
    print(f"online FPR on the contact-free validation run: {100 * fpr:.3f} % (1 − α = {100 * (1 - c.alpha):.2f} %)")
    assert 0.5 * (1 - c.alpha) <= fpr <= 2 * (1 - c.alpha)


# ---- the coefficient file -----------------------------------------------------------------------------------


def assert_same_coefficients(made: coefficients_t, fixture: coefficients_t, rtol: float = 1e-9) -> None:
    """Every field of two coefficient files equal as values: integers and names exactly, each numeric field to
    `rtol` of its own largest magnitude. The numbers come out of LAPACK (the filter's least squares, the coupling's
    inverse), whose last bits depend on the CPU's kernels: their condition numbers are below 1e4, so 1e-9 is
    rounding times a wide margin, and any real change of the exporter is far above it."""
    for name in coefficients_t.__slots__:
        a, b = getattr(made, name), getattr(fixture, name)
        if isinstance(b, (str, bytes)) or (isinstance(b, list) and b and isinstance(b[0], str)):
            assert a == b, name
            continue
        x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        assert x.shape == y.shape, name
        if np.issubdtype(np.asarray(b).dtype, np.integer):
            assert np.array_equal(x, y), name
            continue
        scale = float(np.max(np.abs(y), initial=0.0))
        assert np.allclose(x, y, rtol=0, atol=rtol * scale), (name, float(np.max(np.abs(x - y), initial=0.0)), scale)


@pytest.mark.numerics
def test_cad_fixture_is_current(tmp_path: Path) -> None:
    """rt_monitor's C++ tests load a committed CAD export; it must hold what this dynid writes, as values (its
    bytes differ from machine to machine in the last bits of a few floats)."""
    out = tmp_path / "cad.dcoef"
    done = dynid("export", "--cad", "--out", str(out))
    assert done.returncode == 0, done.stderr
    assert_same_coefficients(read_coefficients(out), read_coefficients(FIXTURE))


PREVIOUS_VERSION = ROOT / "tools" / "tests" / "data" / "icub_cad_version7.dcoef"  # the CAD fixture before version 8


@pytest.mark.parametrize("exe", BUILDS, ids=lambda p: p.name)
def test_a_previous_version_file_is_refused_saying_what_to_do(exe: Path, tmp_path: Path) -> None:
    """A genuine version-7 file (before the fit's ranges): the monitor and dynid refuse it in one line that says to
    export again; it is never misread."""
    done = rt_eval("--coef", str(PREVIOUS_VERSION), "--check", exe=exe / "rt_monitor" / "rt_eval")
    assert done.returncode == EXIT_BASE + 4, done.stderr
    assert done.stderr.count("\n") == 1 and f"format version 7, this monitor reads {file_version()}: export the model again" in done.stderr
    done = dynid("export", "--print", str(PREVIOUS_VERSION))
    assert done.returncode == 2 and f"format version 7, this dynid reads {file_version()}: export the model again" in done.stderr
    done = subprocess.run([str(exe / "rt_monitor" / "rt_monitor"), "--model", str(PREVIOUS_VERSION), "--config",
                           str(ROOT / "rt_monitor" / "config" / "icub_right_arm.conf"), "--replay", "/dev/null",
                           "--lcm-url", "memq://"], capture_output=True, text=True, timeout=60)
    assert done.returncode == EXIT_BASE + 4 and "export the model again" in done.stderr, done.stderr


@pytest.mark.numerics
def test_the_fixture_comparison_sees_a_real_change() -> None:
    """The value comparison is not blind: a change far below any physical meaning but far above rounding fails."""
    fixture = read_coefficients(FIXTURE)
    changed = read_coefficients(FIXTURE)
    changed.threshold *= 1 + 1e-7
    with pytest.raises(AssertionError, match="threshold"):
        assert_same_coefficients(changed, fixture)


def test_a_cad_export_takes_the_boards_rate(tmp_path: Path) -> None:
    """--rate sets a CAD file's sample period and the filter's window with it (the offline window in seconds);
    a calibrated export takes its data's rate, so --rate without --cad is refused."""
    out = tmp_path / "cad500.dcoef"
    done = dynid("export", "--cad", "--rate", "500", "--out", str(out))
    assert done.returncode == 0, done.stderr
    c, default = read_coefficients(out), read_coefficients(FIXTURE)
    assert c.sample_period == pytest.approx(0.002) and default.sample_period == pytest.approx(0.001)
    assert c.window < default.window
    done = dynid("export", "--model", str(out), "--rate", "500", "--out", str(tmp_path / "x.dcoef"))
    assert done.returncode == 2 and "--rate goes with --cad" in done.stderr


def test_python_codec_and_the_cores_loader_agree(tmp_path: Path) -> None:
    """The coefficient type's Python codec (generated by scripts/setup) and the loader's C++ (generated by the build)
    read the same bytes: the fixture the C++ tests load decodes and encodes back byte for byte, and what the codec
    encodes now passes the loader (its fingerprint and every length). test_lcm_deploy checks the codec is current."""
    fixture = FIXTURE.read_bytes()
    assert _reencode(read_coefficients(FIXTURE)) == fixture
    c = read_coefficients(FIXTURE)
    c.dynid_version += "+reencoded"  # a longer string: every later field moves, and the file is not the fixture
    out = tmp_path / "reencoded.dcoef"
    out.write_bytes(_reencode(c))
    done = rt_eval("--coef", str(out), "--check")
    assert done.returncode == 0 and done.stdout.startswith("ok: icub_right_arm, 7 joints"), done.stderr


def _reencode(c: coefficients_t) -> bytes:
    return wrap(c.encode())


def _bad_files(good: bytes) -> dict[str, tuple[bytes, int, str]]:
    """name -> (bytes, expected exit code, expected message fragment)."""
    payload = unwrap(good)
    bad: dict[str, tuple[bytes, int, str]] = {}
    bad["truncated"] = (good[: len(good) // 2], EXIT_BASE + 2, "truncated")
    flipped = bytearray(good)
    flipped[len(good) // 2] ^= 0x01
    bad["wrong CRC"] = (bytes(flipped), EXIT_BASE + 5, "CRC mismatch")
    bad["wrong version"] = (wrap(payload, version=3), EXIT_BASE + 4, f"format version 3, this monitor reads {file_version()}")
    bad["newer version"] = (wrap(payload, version=file_version() + 1), EXIT_BASE + 4,
                            f"format version {file_version() + 1}, this monitor reads {file_version()}: a newer dynid "
                            "wrote it: build this monitor from that dynid")

    c = coefficients_t.decode(payload)
    nj = capacity().joints + 1  # one above the capacity
    extra = nj - c.n_joints
    c.n_joints = nj
    c.joint_names = list(c.joint_names) + [f"extra{k}" for k in range(extra)]
    c.joint_friction = list(c.joint_friction) + [[0.0] * 4] * extra
    c.motor_velocity = [list(r) + [0.0] * extra for r in c.motor_velocity]
    c.row_map = [list(r) + [0.0] * extra for r in c.row_map]
    c.joint_band = list(c.joint_band) + [[0.0, 0.0]] * extra
    c.tau_map = list(c.tau_map) + [[0.0] * c.n_outputs] * extra
    c.tau_variance = list(c.tau_variance) + [1.0] * extra
    c.accel_tau_variance = list(c.accel_tau_variance) + [0.0] * extra
    c.joint_limits = list(c.joint_limits) + [[-1.0, 1.0]] * extra
    c.fit_range = list(c.fit_range) + [[-1.0, 1.0]] * extra
    bad["too many joints"] = (_reencode(c), EXIT_BASE + 7, f"too many joints: {nj}")

    c = coefficients_t.decode(payload)
    c.inertial = [list(r) for r in c.inertial]
    c.inertial[4][0] = float("nan")
    bad["NaN inside"] = (_reencode(c), EXIT_BASE + 9, "non-finite value in the inertial parameters")

    # The fit's ranges (format version 8): finite, in order, within ±1e6
    for label, value, code, message in (("not finite", [float("nan"), 1.0], 9, "non-finite value in the fit's joint ranges"),
                                        ("out of order", [0.5, -0.5], 11, "the fit's range's lower end"),
                                        ("beyond 1e6", [-2e6, 1.0], 11, "the fit's range's lower end is -2e+06"),
                                        ("upper beyond 1e6", [0.0, 2e6], 11, "the fit's range's upper end is 2e+06")):
        c = coefficients_t.decode(payload)
        c.fit_range = [list(r) for r in c.fit_range]
        c.fit_range[3] = value
        bad[f"fit range {label}"] = (_reencode(c), EXIT_BASE + code, message)

    c = coefficients_t.decode(payload)
    c.supply_time_constant, c.supply_prior = 3.0, 0.0
    bad["supply tracking without a prior"] = (_reencode(c), EXIT_BASE + 8, "the prior positive when it is on")

    c = coefficients_t.decode(payload)
    c.supply_gate = [0.01] * c.n_outputs
    bad["supply gate on an F/T channel"] = (_reencode(c), EXIT_BASE + 8, "the gate of ft.r_arm_ft.fx")

    c = coefficients_t.decode(payload)
    c.supply_time_constant = float("inf")
    bad["infinite supply time constant"] = (_reencode(c), EXIT_BASE + 9, "non-finite value in the supply tracking")

    c = coefficients_t.decode(payload)
    c.residual = 2  # the combined detector without its κ (the CAD fixture carries none)
    bad["combined without κ"] = (_reencode(c), EXIT_BASE + 8, "selects the combined detector but carries no combined_scale")

    c = coefficients_t.decode(payload)
    c.residual, c.combined_scale = 2, float("nan")
    bad["combined κ not a number"] = (_reencode(c), EXIT_BASE + 9, "non-finite combined_scale")

    c = coefficients_t.decode(payload)
    c.residual, c.combined_scale = 3, 1.5
    bad["unknown residual"] = (_reencode(c), EXIT_BASE + 8, "unknown residual 3 (this monitor knows 0 acceleration, 1 "
                               "momentum, 2 combined)")

    c = coefficients_t.decode(payload)
    c.robot_name = "panda_arm"
    bad["another robot"] = (_reencode(c), EXIT_BASE + 10, "exported for robot 'panda_arm', not for 'icub_right_arm'")
    return bad


@pytest.mark.parametrize("exe", BUILDS, ids=[b.name for b in BUILDS])
def test_loader_refuses_bad_files(exe: Path, tmp_path: Path) -> None:
    good = FIXTURE.read_bytes()
    assert rt_eval("--coef", str(FIXTURE), "--robot", "icub_right_arm", "--check",
                   exe=exe / "rt_monitor" / "rt_eval").returncode == 0
    for name, (data, code, message) in _bad_files(good).items():
        path = tmp_path / "bad.dcoef"
        path.write_bytes(data)
        done = rt_eval("--coef", str(path), "--robot", "icub_right_arm", "--check", exe=exe / "rt_monitor" / "rt_eval")
        assert done.returncode == code, f"{name}: exit {done.returncode}, {done.stderr}"
        assert message in done.stderr, f"{name}: {done.stderr}"
        assert len(done.stderr.strip().splitlines()) == 1, f"{name}: one line, got {done.stderr!r}"


def test_python_reader_refuses_what_the_loader_refuses(tmp_path: Path) -> None:
    for name, (data, _, _) in _bad_files(FIXTURE.read_bytes()).items():
        if name in ("truncated", "wrong CRC", "wrong version"):
            path = tmp_path / "bad.dcoef"
            path.write_bytes(data)
            done = dynid("export", "--print", str(path))
            assert done.returncode == 2 and "Traceback" not in done.stderr, f"{name}: {done.stderr}"
            assert len(done.stderr.strip().splitlines()) == 1
    assert zlib.crc32(b"123456789") == 0xCBF43926  # the CRC both sides use (CRC-32/ISO-HDLC)


def test_export_refuses_when_the_calibration_data_are_gone(default_model: Path, tmp_path: Path) -> None:
    import json

    record = json.loads(default_model.read_text())
    record["data"] = [{**record["data"][0], "path": str(tmp_path / "moved")}]
    model = tmp_path / "model.json"
    model.write_text(json.dumps(record))
    done = dynid("export", "--model", str(model), "--out", str(tmp_path / "x.dcoef"))
    assert done.returncode == 2 and "are gone; pass the contact-free data with --data" in done.stderr, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and not (tmp_path / "x.dcoef").exists()
    record["data"] = [{**record["data"][0], "path": json.loads(default_model.read_text())["data"][0]["path"],
                       "sha256": "0" * 64}]
    model.write_text(json.dumps(record))
    done = dynid("export", "--model", str(model), "--out", str(tmp_path / "x.dcoef"))
    assert done.returncode == 2 and "changed since the fit (sha256)" in done.stderr, done.stderr


def test_export_print_and_errors(exported: Path, tmp_path: Path) -> None:
    done = dynid("export", "--print", str(exported))
    assert done.returncode == 0, done.stderr
    for needle in ("robot icub_right_arm", "r_upper_arm", "m1: q̇_m = [-1.625 1.625", "T²: α 0.99",
                   "fixed-lag Savitzky-Golay, window 31"):
        assert needle in done.stdout
    done = dynid("export", "--model", str(tmp_path / "missing.json"), "--out", str(tmp_path / "x.dcoef"))
    assert done.returncode == 2 and "model file not found" in done.stderr
    done = dynid("export")
    assert done.returncode == 2 and "--model MODEL and --out" in done.stderr
    assert not (tmp_path / "x.dcoef").exists()


def test_export_print_says_which_velocity_the_observer_takes_and_a_prismatic_joints_units(exported: Path) -> None:
    from dynid.export.coefficients import describe

    c = read_coefficients(exported)
    assert c.velocity_window > 0 and c.observer_velocity == 0
    text = describe(c)
    assert f"causal q̇ over {c.velocity_window} samples" in text and "measured q̇" not in text
    assert "min speed 0.01 rad/s," in text and " N," not in text.split("momentum observer")[1]
    c.observer_velocity = 1  # a bus that carries q̇ (the UR10e's, the Panda's)
    body = next(i for i in range(c.n_bodies) if c.joint_index[i] == 0)
    c.joint_type = [2 if i == body else k for i, k in enumerate(c.joint_type)]  # prismatic, as TIAGo's torso lift
    text = describe(c)
    assert "the robot's measured q̇ (dq.J on its bus)" in text and "causal q̇" not in text
    assert "(m/s for a prismatic joint)" in text
    first, second = [line for line in text.splitlines() if "τ_ext variance" in line][:2]
    assert first.split("]")[1].startswith(" N, τ_ext") and first.endswith(" N²")
    assert second.split("]")[1].startswith(" Nm, τ_ext") and second.endswith(" Nm²")


def test_contact_run_side_and_detection(exported: Path, default_experiments: dict, tmp_path: Path) -> None:
    """The contact run through the core: distal contacts are detected, and the side named is the skin's."""
    c = read_coefficients(exported)
    ds = load_data(default_experiments["contact"], load_config("icub_right_arm"))
    out = stream(exported, raw_samples(ds, c), tmp_path, "--residual", "acceleration")
    lag = c.lag  # output k is the estimate of sample k − lag
    truth, side = np.zeros(len(out), bool), np.zeros(len(out))
    truth[lag:], side[lag:] = ds.contact[:-lag] != 0, ds.extra["skin.side"][:-lag]
    col = detector_columns(c)
    ready, above, named = out[:, 0] == 1, out[:, col["above"]] == 1, out[:, col["side"]][:, 0]  # the one sensor
    for code, name in ((1, "distal"), (-1, "proximal")):
        sel = ready & truth & (side == code) & above
        assert sel.sum() > 100, f"too few detected {name} samples to judge the side"
        print(f"{name}: TPR {100 * above[ready & truth & (side == code)].mean():.1f} %, "
              f"side right on {100 * (named[sel] == code).mean():.1f} % of the alarmed samples")
        assert (named[sel] == code).mean() >= 0.9
    assert above[ready & truth & (side == 1)].mean() >= 0.9  # the F/T sensor sees every distal contact
    assert above[ready & ~truth].mean() < 0.02
