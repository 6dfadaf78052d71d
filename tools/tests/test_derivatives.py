"""Tests of dynid.io.derivatives: accuracy on analytic signals (uniform and jittered stamps), real Panda data, edges,
exactness against scipy and brute force, and the ValueError contract.

Bounds are the figures measured when these tests were written, times a modest margin (~1.5-2); the measured
values are in the comments next to each bound.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.polynomial import polynomial as P
import pytest
from scipy.signal import savgol_filter

import dynid.io.derivatives as deriv
from dynid.io.derivatives import AdaptiveWindow, Derivatives, SavitzkyGolay, estimate_derivatives

STEP = 2 * np.pi / 65536  # 16-bit encoder, rad
DT = 1e-3
N = 20_001  # 20 s at 1 kHz
N_JOINTS = 7
EDGE = 50  # samples left out at each end of the interior error figures (edges have their own test)
# shared/ sits beside the checkout (<parent>/main, <parent>/shared), as CI clones it.
PANDA = Path(__file__).resolve().parents[3] / "shared" / "realdata" / "panda_gaz2019" / "rbt_log"


class Motion:
    """Per joint, four sines: 0.1-2 Hz, 0.3-1 rad, the 2 Hz one the smallest (peak |q̇| 24 rad/s, |q̈| 220)."""

    def __init__(self, seed: int = 7) -> None:
        rng = np.random.default_rng(seed)
        freq = np.sort(rng.uniform(0.1, 2.0, (4, N_JOINTS)), axis=0)
        freq[-1] = 2.0
        self.amp = np.sort(rng.uniform(0.3, 1.0, (4, N_JOINTS)), axis=0)[::-1]
        self.omega = 2 * np.pi * freq
        self.phase = rng.uniform(0, 2 * np.pi, (4, N_JOINTS))

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        q, dq, ddq = (np.zeros((t.size, N_JOINTS)) for _ in range(3))
        for a, w, p in zip(self.amp, self.omega, self.phase):
            s, c = np.sin(w * t[:, None] + p), np.cos(w * t[:, None] + p)
            q += a * s
            dq += a * w * c
            ddq -= a * w**2 * s
        return q, dq, ddq


def quantise(q: np.ndarray) -> np.ndarray:
    return np.round(q / STEP) * STEP


def errors(est: np.ndarray, ref: np.ndarray, sl: slice = slice(EDGE, -EDGE)) -> tuple[float, float]:
    e = est[sl] - ref[sl]
    return float(np.sqrt(np.mean(e**2))), float(np.max(np.abs(e)))


@pytest.fixture(scope="module")
def uniform():
    t = np.arange(N) * DT
    q, dq, ddq = Motion()(t)
    return t, quantise(q), dq, ddq


@pytest.fixture(scope="module")
def jittered():
    # Like the Panda log, whose steps spread over 0.7-1.6 ms around a 1 ms median: here uniform ±0.3 ms.
    t = np.arange(N) * DT + np.random.default_rng(3).uniform(-3e-4, 3e-4, N)
    q, dq, ddq = Motion()(t)
    return t, quantise(q), dq, ddq


# ----------------------------------------------------------------------------------------------------------------
# Savitzky-Golay: exactness
# ----------------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("window, polyorder", [(5, 2), (5, 3), (31, 3), (31, 5), (61, 2), (61, 4)])
def test_jitter_aware_fit_reproduces_savgol_filter_on_uniform_steps(uniform, window, polyorder):
    t, q, _, _ = uniform
    mine = deriv._local_poly_fit(t, q, window, polyorder)
    for k in range(3):
        ref = savgol_filter(q, window, polyorder, deriv=k, delta=DT, axis=0, mode="interp")
        # Measured <= 6e-9 relative; scipy's own coefficients lose digits at high degree, not this fit.
        np.testing.assert_allclose(mine[k], ref, rtol=0, atol=1e-7 * np.max(np.abs(ref)))


@pytest.mark.parametrize("window, polyorder", [(5, 2), (5, 3), (31, 3), (31, 5), (61, 2), (61, 4), (151, 3)])
def test_uniform_steps_are_savgol_filter(uniform, window, polyorder):
    """The uniform path (its own weights, scipy.signal not imported) is scipy's savgol_filter, edges included."""
    t, q, _, _ = uniform
    out = SavitzkyGolay(window_s=window * DT, polyorder=polyorder)(t, q)
    for k, mine in enumerate((out.q, out.dq, out.ddq)):
        ref = savgol_filter(q, window, polyorder, deriv=k, delta=DT, axis=0, mode="interp")
        # Measured <= 2e-9 of scale (61, 4): scipy's Vandermonde coefficients lose digits at high degree, these
        # do not (the exactness test below).
        np.testing.assert_allclose(mine, ref, rtol=0, atol=1e-8 * np.max(np.abs(ref)))


@pytest.mark.parametrize("window", [31, 201])
def test_the_fft_interior_is_the_direct_correlation(uniform, window):
    """`fft=True` (the IV instruments' long window) gives the direct path's numbers to rounding on the interior, which
    it correlates by FFT (both paths fit the edges the same way), and sums the same windows (a one-sample shift fails
    at 0.2)."""
    t, q, _, _ = uniform
    q = q + 5.0  # an offset: FFT rounding scales with the data, not with the output
    direct = SavitzkyGolay(window_s=window * DT)(t, q)
    fft = SavitzkyGolay(window_s=window * DT, fft=True)(t, q)
    for mine, ref in zip((fft.q, fft.dq, fft.ddq), (direct.q, direct.dq, direct.ddq)):
        # measured ≤ 1.3e-15 of scale on a 4500-sample chunk
        np.testing.assert_allclose(mine, ref, rtol=0, atol=1e-13 * np.max(np.abs(ref)))


@pytest.mark.parametrize("window, polyorder", [(31, 3), (61, 4), (31, 7)])
def test_polynomial_of_the_filters_degree_is_differentiated_exactly_on_uniform_stamps(window, polyorder):
    """Where scipy's own weights drift (degree 7: 3e-7 of scale in q̈), the uniform path stays at rounding."""
    t = 5.0 + np.arange(600) * DT
    c = np.random.default_rng(1).normal(size=(polyorder + 1, 2))
    x = t - 5.3
    exact = [P.polyval(x, P.polyder(c, k)).T for k in range(3)]
    out = SavitzkyGolay(window_s=window * DT, polyorder=polyorder)(t, exact[0])
    for mine, want, tol in zip((out.q, out.dq, out.ddq), exact, (1e-13, 1e-11, 1e-9)):
        np.testing.assert_allclose(mine, want, rtol=0, atol=tol * np.max(np.abs(want)))


def test_cubic_is_differentiated_exactly_on_jittered_stamps_including_edges():
    rng = np.random.default_rng(0)
    t = 5.0 + np.arange(400) * DT + rng.uniform(-3e-4, 3e-4, 400)  # offset start: fit must not assume t0 = 0
    c = np.array([[0.3, -1.0], [2.0, 0.5], [-4.0, 3.0], [7.0, -2.0]])  # q_j = Σ c[k, j] (t - 5)^k
    x = (t - 5.0)[:, None]
    q = c[0] + c[1] * x + c[2] * x**2 + c[3] * x**3
    dq = c[1] + 2 * c[2] * x + 3 * c[3] * x**2
    ddq = 2 * c[2] + 6 * c[3] * x
    out = SavitzkyGolay(window_s=0.031, polyorder=3)(t, q)
    np.testing.assert_allclose(out.q, q, atol=1e-10)
    np.testing.assert_allclose(out.dq, dq, atol=1e-8)
    np.testing.assert_allclose(out.ddq, ddq, atol=1e-5)


@pytest.mark.parametrize("jitter", [0.0, 3e-4])
def test_a_window_of_one_constant_reading_has_exactly_zero_derivatives(jitter):
    """A quantised encoder at rest: q̇ and q̈ are 0, not ±1e-13 (friction takes sign(q̇)). The run starts and ends at
    rest (the edge windows) and rests twice between moves; a large offset (5 rad) makes rounding visible."""
    rng = np.random.default_rng(2)
    t = 3.0 + np.arange(1500) * DT + rng.uniform(-jitter, jitter, 1500)
    move = np.clip(np.sin(np.linspace(-0.5, 3 * np.pi + 0.5, 1500)), 0, None) ** 2  # flat where the sine is below 0
    q = 5.0 + np.round(np.column_stack([move, -2 * move]) / 1e-3) * 1e-3
    out = SavitzkyGolay(window_s=0.031, polyorder=3)(t, q)
    win = np.lib.stride_tricks.sliding_window_view(q, 31, axis=0)
    rest = np.all(win == win[:, :, :1], axis=2)  # (N − 30, n): the window centred on sample i + 15 is constant
    rows, cols = np.nonzero(rest)
    assert len(rows) > 400 and set(cols) == {0, 1}
    assert np.all(out.dq[rows + 15, cols] == 0.0) and np.all(out.ddq[rows + 15, cols] == 0.0)
    for edge in (slice(0, 15), slice(-15, None)):  # the first and last windows are constant too
        assert np.all(out.dq[edge] == 0.0) and np.all(out.ddq[edge] == 0.0)
    moving = np.abs(np.diff(q[:, 0])) > 0
    assert np.count_nonzero(out.dq[1:][moving, 0]) == np.count_nonzero(moving)


def test_chunking_does_not_change_the_jitter_aware_fit(jittered):
    t, q, _, _ = jittered
    one = deriv._local_poly_fit(t[:3000], q[:3000], 31, 3, chunk=10**6)
    many = deriv._local_poly_fit(t[:3000], q[:3000], 31, 3, chunk=7)
    np.testing.assert_array_equal(np.stack(one), np.stack(many))


def test_uniform_stamps_take_scipy_fast_path_and_jittered_ones_do_not(uniform, jittered, monkeypatch):
    calls = []
    real = deriv._local_poly_fit
    monkeypatch.setattr(deriv, "_local_poly_fit", lambda *a, **k: calls.append(1) or real(*a, **k))
    # Uniform even far from t = 0, where k*dt carries float rounding (~1e-13 s, well inside 1e-6 relative).
    t, q, _, _ = uniform
    SavitzkyGolay()(1.0e4 + t[:2000], q[:2000])
    assert calls == []
    tj, qj, _, _ = jittered
    SavitzkyGolay()(tj[:2000], qj[:2000])
    assert calls == [1]


# ----------------------------------------------------------------------------------------------------------------
# Savitzky-Golay: accuracy on the analytic motion, 16-bit quantised, 1 kHz
# ----------------------------------------------------------------------------------------------------------------


def test_analytic_uniform_error_bounds(uniform):
    t, q, dq, ddq = uniform
    out = estimate_derivatives(t, q)
    assert isinstance(out, Derivatives)
    assert out.q.shape == out.dq.shape == out.ddq.shape == q.shape
    rms, mx = errors(out.dq, dq)
    assert rms < 2.5e-3 and mx < 1.2e-2  # measured 1.40e-3, 6.0e-3 rad/s (velocity RMS 6.0 rad/s)
    rms, mx = errors(out.ddq, ddq)
    assert rms < 0.35 and mx < 1.5  # measured 0.194, 0.80 rad/s² (acceleration RMS 59 rad/s²)
    rms, _ = errors(out.q, Motion()(t)[0])
    # measured 7.6e-6 rad: the fit removes most of the quantisation noise (STEP/√12 = 2.8e-5 rad RMS)
    assert rms < 1.5e-5


def test_default_window_is_the_acceleration_optimum(uniform):
    """The 31 ms default balances quantisation noise (short windows) against bias on the 2 Hz component."""
    t, q, dq, ddq = uniform
    ddq_rms = {w: errors(SavitzkyGolay(window_s=w * DT)(t, q).ddq, ddq)[0] for w in (21, 31, 45)}
    # measured q̈ RMS: 21 samples 0.38, 25: 0.26, 31: 0.194, 35: 0.200, 45: 0.29, 61: 0.52 rad/s²
    assert ddq_rms[31] < 0.75 * ddq_rms[21]
    assert ddq_rms[31] < 0.8 * ddq_rms[45]
    assert SavitzkyGolay().window_samples(DT) == 31


def test_jittered_stamps_keep_the_error_bounds_and_naive_savgol_does_not(jittered):
    t, q, dq, ddq = jittered
    out = estimate_derivatives(t, q, window_s=0.031)
    dq_rms, dq_max = errors(out.dq, dq)
    ddq_rms, ddq_max = errors(out.ddq, ddq)
    assert dq_rms < 2.5e-3 and dq_max < 1.2e-2  # measured 1.39e-3, 6.1e-3 rad/s: as good as uniform stamps
    assert ddq_rms < 0.35 and ddq_max < 1.5  # measured 0.193, 0.82 rad/s²
    # Naive: scipy's savgol_filter on the same samples, assuming the median step.
    dt = float(np.median(np.diff(t)))
    naive_dq = savgol_filter(q, 31, 3, deriv=1, delta=dt, axis=0, mode="interp")
    naive_ddq = savgol_filter(q, 31, 3, deriv=2, delta=dt, axis=0, mode="interp")
    # measured naive: q̇ RMS 5.4e-2 rad/s (39x worse), q̈ RMS 5.3 rad/s² (27x worse)
    assert errors(naive_dq, dq)[0] > 15 * dq_rms
    assert errors(naive_ddq, ddq)[0] > 15 * ddq_rms


def test_edges_stay_bounded(uniform, jittered):
    for t, q, dq, ddq in (uniform, jittered):
        out = SavitzkyGolay()(t, q)
        for sl in (slice(0, 15), slice(-15, None)):  # the half windows fitted by the first/last full window
            rms, mx = errors(out.dq, dq, sl)
            assert mx < 2e-2  # measured max 1.07e-2 rad/s, at the very first/last sample; interior max 6e-3
            rms, mx = errors(out.ddq, ddq, sl)
            assert mx < 4.0  # measured max 2.1 rad/s²; interior max 0.8


def test_one_dimensional_positions_give_one_dimensional_outputs(uniform):
    t, q, _, _ = uniform
    out = SavitzkyGolay()(t[:500], q[:500, 2])
    full = SavitzkyGolay()(t[:500], q[:500])
    assert out.dq.shape == (500,)
    np.testing.assert_allclose(out.ddq, full.ddq[:, 2], rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("stamps", ["uniform", "jittered"])
def test_smooth_is_the_calls_value_to_the_bit(stamps, request):
    """`smooth` (the measured channels' filter in signals_from_dataset) skips the derivatives, not a digit of q."""
    t, q, _, _ = request.getfixturevalue(stamps)
    sg = SavitzkyGolay()
    np.testing.assert_array_equal(sg.smooth(t[:3000], q[:3000]), sg(t[:3000], q[:3000]).q)
    np.testing.assert_array_equal(sg.smooth(t[:3000], q[:3000, 1]), sg(t[:3000], q[:3000, 1]).q)
    with pytest.raises(ValueError, match="fewer than"):
        sg.smooth(t[:5], q[:5])


# ----------------------------------------------------------------------------------------------------------------
# Real data: Franka Emika Panda log (Gaz et al. 2019), 1 kHz with jittered stamps and dropped samples
# ----------------------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def panda():
    files = [PANDA / f"exciting_traj_{n}.txt" for n in ("time", "positions", "velocity")]
    missing = [f.name for f in files if not f.is_file()]
    if missing:
        pytest.skip(f"Panda log not found under {PANDA} ({', '.join(missing)})")
    t, q, v = (np.loadtxt(f) for f in files)
    return t, q.reshape(-1, 7), v.reshape(-1, 7)


def test_panda_velocity_agrees_with_the_robots_own(panda):
    t, q, v = panda
    sl = slice(EDGE, -EDGE)
    v_rms = np.sqrt(np.mean(v[sl] ** 2, axis=0))
    est = SavitzkyGolay()(t, q)
    rel = np.sqrt(np.mean((est.dq[sl] - v[sl]) ** 2, axis=0)) / v_rms
    assert np.all(rel < 0.05)  # measured 0.030-0.034 per joint (0.031 overall), velocity RMS 0.67-0.91 rad/s
    dt = float(np.median(np.diff(t)))
    naive = savgol_filter(q, 31, 3, deriv=1, delta=dt, axis=0, mode="interp")
    rel_naive = np.sqrt(np.mean((naive[sl] - v[sl]) ** 2, axis=0)) / v_rms
    assert np.all(rel_naive > 2 * rel)  # measured 0.098 overall: the stamps carry real timing


# ----------------------------------------------------------------------------------------------------------------
# Adaptive window (Janabi-Sharifi et al. 1995)
# ----------------------------------------------------------------------------------------------------------------


def _foaw_brute_force(t, y, d, max_window, causal):
    """The definition, sample by sample: grow n until a sample leaves ±d of the line; keep the last slope."""
    n = t.size
    out = np.empty(n)
    for k in range(n):
        slope = None
        for m in range(1, max_window + 1):
            b = max(k - m, 0)
            f = k if causal else min(k + m, n - 1)
            if m > k and (causal or m > n - 1 - k):
                break
            s = (y[f] - y[b]) / (t[f] - t[b])
            fits = np.all(np.abs(y[b : f + 1] - y[k] - s * (t[b : f + 1] - t[k])) <= d * (1 + 1e-9))
            if m == 1 or fits:
                slope = s
            if not fits:
                break
        out[k] = slope if slope is not None else (y[1] - y[0]) / (t[1] - t[0])
    return out


@pytest.mark.parametrize("causal", [False, True])
def test_adaptive_window_matches_its_definition(causal):
    rng = np.random.default_rng(5)
    t = np.arange(600) * DT + rng.uniform(-3e-4, 3e-4, 600)
    y = quantise(0.5 * np.sin(2 * np.pi * 0.7 * t) + 0.2 * t**2)
    ref = _foaw_brute_force(t, y, STEP, 20, causal)
    for chunk in (4096, 45):  # one block, and many blocks with halos
        fast, _ = deriv._foaw(t, y[:, None], np.full((600, 1), STEP / 2), 20, causal, chunk=chunk)
        np.testing.assert_allclose(fast[:, 0], ref, rtol=1e-9, atol=1e-9)
    # A short, slow record: windows reach both ends of the record before max_window.
    ts, ys = t[:25], quantise(1e-3 * np.sin(2 * np.pi * t[:25]))
    fast, _ = deriv._foaw(ts, ys[:, None], np.full((25, 1), STEP / 2), 30, causal)
    np.testing.assert_allclose(fast[:, 0], _foaw_brute_force(ts, ys, STEP, 30, causal), rtol=1e-9, atol=1e-9)


def test_adaptive_window_is_exact_on_a_line_and_uses_long_windows_there():
    t = np.arange(300) * DT + np.random.default_rng(1).uniform(-3e-4, 3e-4, 300)
    q = np.column_stack([0.2 + 1.5 * t, -0.7 * t])
    out = estimate_derivatives(t, q, method="adaptive", d=STEP, max_window=40)
    np.testing.assert_allclose(out.dq, np.broadcast_to([1.5, -0.7], q.shape), atol=1e-9)
    np.testing.assert_allclose(out.ddq, 0.0, atol=1e-6)
    _, span = deriv._foaw(t, q, np.full(q.shape, STEP / 2), 40, False)
    assert np.median(span) > 0.075  # a full 81-sample window wherever the record allows it


def test_adaptive_window_error_bounds_and_lag(uniform):
    t, q, dq, ddq = uniform
    sl = slice(0, 5000)  # 5 s is plenty and keeps the test fast
    out = AdaptiveWindow(d=STEP, max_window=50)(t[sl], q[sl])
    rms, mx = errors(out.dq, dq[sl])
    # measured 1.3e-2, 4.8e-2 rad/s: about 10x Savitzky-Golay on this fast motion (short windows, d/2Δt noise)
    assert rms < 2.5e-2 and mx < 8e-2
    rms, _ = errors(out.ddq, ddq[sl])
    assert rms < 2.0  # measured 1.1 rad/s²
    causal = AdaptiveWindow(d=STEP, max_window=50, causal=True)(t[sl], q[sl])
    assert errors(causal.dq, dq[sl])[0] > 3 * errors(out.dq, dq[sl])[0]  # the backward window lags (measured 6.4x)


# ----------------------------------------------------------------------------------------------------------------
# Bad input: one ValueError each, with a specific message
# ----------------------------------------------------------------------------------------------------------------


def _t_q(n: int = 200):
    t = np.arange(n) * DT
    return t, np.column_stack([np.sin(t), np.cos(t)])


@pytest.mark.parametrize("method, options", [("savgol", {}), ("adaptive", {"d": STEP})])
def test_bad_input_raises_value_error(method, options):
    t, q = _t_q()

    def check(tt, qq, match):
        with pytest.raises(ValueError, match=match):
            estimate_derivatives(tt, qq, method=method, **options)

    t_dup = t.copy()
    t_dup[123] = t_dup[122]
    check(t_dup, q, r"not strictly increasing at sample 123 \(t=0\.122")
    t_back = t.copy()
    t_back[50] = 0.0
    check(t_back, q, r"not strictly increasing at sample 50 ")
    check(t, q[:-1], r"positions have 199 samples but there are 200 time stamps")
    check(t.reshape(-1, 1), q, r"time stamps must be a 1-D array")
    check(t, q[:, :, None], r"positions must be an array of shape")
    q_nan = q.copy()
    q_nan[77, 1] = np.nan
    check(t, q_nan, r"position of joint 1 at sample 77 is not finite")
    t_inf = t.copy()
    t_inf[9] = np.inf
    check(t_inf, q, r"time stamp at sample 9 is not finite")
    check(t[:2], q[:2], r"samples")
    check(["a", "b"], q[:2], r"numeric")


def test_savgol_specific_errors():
    t, q = _t_q()
    with pytest.raises(ValueError, match=r"only 20 samples, fewer than the 31-sample Savitzky-Golay window"):
        estimate_derivatives(t[:20], q[:20])
    with pytest.raises(ValueError, match=r"spans only 3 samples .* needs at least 5 \(odd\), so lengthen window_s"):
        estimate_derivatives(t * 10, q)  # 100 Hz data with the 31 ms default window
    with pytest.raises(ValueError, match=r"polyorder must be at least 2"):
        SavitzkyGolay(polyorder=1)
    with pytest.raises(ValueError, match=r"window_s must be a positive"):
        SavitzkyGolay(window_s=-0.01)


def test_method_and_option_errors():
    t, q = _t_q()
    with pytest.raises(ValueError, match=r"unknown derivative method 'kalman'"):
        estimate_derivatives(t, q, method="kalman")
    with pytest.raises(ValueError, match=r"unknown option\(s\) window for derivative method 'savgol'"):
        estimate_derivatives(t, q, window=31)
    with pytest.raises(ValueError, match=r"needs the position noise bound d"):
        estimate_derivatives(t, q, method="adaptive")
    with pytest.raises(ValueError, match=r"tolerance d must be a positive"):
        AdaptiveWindow(d=0.0)
    with pytest.raises(ValueError, match=r"max_window must be at least 1"):
        AdaptiveWindow(d=STEP, max_window=0)
