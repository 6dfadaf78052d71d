"""Offline (non-causal) estimation of joint velocities and accelerations from sampled positions.

Identification needs q̇ and q̈, but robots log positions only (or a velocity of unknown filtering). Offline we
can look at samples on both sides of each instant, so the estimators here are non-causal and lag-free.

Two methods:

- ``"savgol"`` (`SavitzkyGolay`, the default): a polynomial fitted by least squares to a sliding window of
  samples, differentiated analytically. When the time stamps are uniform it is scipy's `savgol_filter` (its
  weights, computed here without importing scipy.signal); when they are jittered (real logs), the polynomial is
  fitted in the *actual* time offsets of the window's samples, because assuming a uniform step turns the jitter into
  position noise (v·δt, far above encoder resolution).
- ``"adaptive"`` (`AdaptiveWindow`): the end-fit first-order adaptive window of Janabi-Sharifi, Hayward and Chen
  (1995), which the reference paper used: per sample, the longest window in which a straight line stays within
  ±d of every sample, so it averages over long windows where motion is slow and short ones where it is fast.

All inputs are validated; anything unusable raises `ValueError` with one sentence naming the problem and the
offending sample, which the caller turns into an exit code.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.polynomial import legendre

__all__ = [
    "Derivatives",
    "SavitzkyGolay",
    "AdaptiveWindow",
    "estimate_derivatives",
    "METHODS",
    "UNIFORM_RTOL",
]

# Steps count as uniform when max |dt - median dt| <= UNIFORM_RTOL * median dt. Treating such steps as uniform
# misplaces a sample by at most 1e-6 * dt per step, so by 15 ns at the end of a 31-sample window at 1 kHz: at
# 10 rad/s that is 1.5e-7 rad, 600x below a 16-bit encoder step (9.6e-5 rad). Float64 stamps such as k*0.001 over
# hours of data stay far inside it (rounding ~1e-10 relative). Anything looser takes the exact jitter-aware path,
# which is correct for uniform data too, only slower.
UNIFORM_RTOL = 1e-6

# Centres per chunk of the jitter-aware fit: the largest temporaries are (chunk, window, n_joints) float64,
# i.e. 8192 * 31 * 7 * 8 B = 14 MB, so memory stays bounded whatever N is.
_CHUNK = 8192


@dataclass(frozen=True)
class Derivatives:
    """Smoothed positions and their first two time derivatives, each with the shape of the input q.

    Attributes
    ----------
    q : np.ndarray
        Smoothed positions, rad.
    dq : np.ndarray
        Velocities, rad/s.
    ddq : np.ndarray
        Accelerations, rad/s².
    """

    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray


# --------------------------------------------------------------------------------------------------------------
# Input validation
# --------------------------------------------------------------------------------------------------------------


def _validate(t: Any, q: Any) -> tuple[np.ndarray, np.ndarray, bool]:
    """Return t (N,), q (N, n) as float64, and whether q was 1-D; raise ValueError on unusable input."""
    try:
        t = np.asarray(t, dtype=float)
        q = np.asarray(q, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"time stamps and positions must be numeric arrays ({exc}).") from None
    if t.ndim != 1:
        raise ValueError(f"time stamps must be a 1-D array of shape (N,), got shape {t.shape}.")
    if q.ndim not in (1, 2):
        raise ValueError(f"positions must be an array of shape (N,) or (N, n_joints), got shape {q.shape}.")
    if q.shape[0] != t.shape[0]:
        raise ValueError(
            f"positions have {q.shape[0]} samples but there are {t.shape[0]} time stamps (shape {q.shape} "
            f"against {t.shape})."
        )
    squeeze = q.ndim == 1
    q2 = q[:, None] if squeeze else q
    bad_t = ~np.isfinite(t)
    if bad_t.any():
        k = int(np.argmax(bad_t))
        raise ValueError(f"time stamp at sample {k} is not finite (t={float(t[k])}).")
    bad_q = ~np.isfinite(q2)
    if bad_q.any():
        k, j = (int(v) for v in np.unravel_index(int(np.argmax(bad_q)), q2.shape))
        raise ValueError(f"position of joint {j} at sample {k} is not finite (q={float(q2[k, j])}).")
    if t.size >= 2:
        steps = np.diff(t)
        bad = steps <= 0
        if bad.any():
            k = int(np.argmax(bad)) + 1
            raise ValueError(
                f"time stamps are not strictly increasing at sample {k} "
                f"(t={float(t[k])!r} after t={float(t[k - 1])!r})."
            )
    return t, q2, squeeze


def _median_step(t: np.ndarray) -> float:
    return float(np.median(np.diff(t)))


def _is_uniform(t: np.ndarray, dt: float) -> bool:
    return bool(np.max(np.abs(np.diff(t) - dt)) <= UNIFORM_RTOL * dt)


def _shaped(squeeze: bool, *arrays: np.ndarray | None) -> Derivatives:
    if squeeze:
        arrays = tuple(None if a is None else a[:, 0] for a in arrays)
    return Derivatives(*arrays)


# --------------------------------------------------------------------------------------------------------------
# Savitzky-Golay
# --------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SavitzkyGolay:
    """Savitzky-Golay differentiation: local polynomial least squares over a sliding window of samples.

    Parameters
    ----------
    window_s : float
        Window length in seconds. The window holds the odd number of samples nearest to
        ``window_s / median step``. The default, 0.031 s (31 samples at 1 kHz), minimises the q̈ error for 1 kHz,
        16-bit encoder data of arm motions up to 2 Hz (tests/test_derivatives.py, cubic fit): q̈ RMS error 0.38
        rad/s² at 21 samples, 0.26 at 25, 0.194 at 31, 0.200 at 35, 0.29 at 45, 0.52 at 61 (shorter windows
        amplify quantisation noise, longer ones bias the 2 Hz component). q̇ alone would prefer ~61 samples, but
        at 31 its error is already 1.4e-3 rad/s RMS (0.02 % of the velocity RMS), while q̈ is the noisier input
        of the regressor.
    polyorder : int
        Degree of the local polynomial, at least 2 so that q̈ is not identically zero. With a window that is
        symmetric about the sample, degrees 2k and 2k+1 give the same q and q̈, and degrees 2k-1 and 2k the
        same q̇; 3 is the usual choice.

    Notes
    -----
    Uniform time stamps (see `UNIFORM_RTOL`) use one set of weights for every interior sample: what
    `scipy.signal.savgol_filter` computes, to 1e-12 of scale at the default window and degree and 1e-9 at high degree,
    where scipy's own weights lose digits and these do not. Otherwise the polynomial of each window is fitted in the
    actual offsets ``t_j - t_i`` of its samples. At both ends, the samples of the first
    (last) half window take the polynomial of the first (last) full window, evaluated at their own time: the
    same as ``savgol_filter(mode="interp")``, so edge values are fits, not extrapolated padding.
    """

    window_s: float = 0.031
    polyorder: int = 3
    # The interior of a uniform run correlated by FFT, for long windows (the IV instruments' 201 samples: 5.6× faster
    # a chunk), to about 1e-15 of the data's scale; off where a resting joint's q̇ must be exactly 0, as the
    # regressor's friction sign takes it (`_uniform_poly_fit`).
    fft: bool = False

    def __post_init__(self) -> None:
        if not (np.isfinite(self.window_s) and self.window_s > 0):
            raise ValueError(
                f"Savitzky-Golay window_s must be a positive number of seconds, got {self.window_s!r}."
            )
        if isinstance(self.polyorder, bool) or not isinstance(self.polyorder, (int, np.integer)):
            raise ValueError(f"Savitzky-Golay polyorder must be an integer, got {self.polyorder!r}.")
        if self.polyorder < 2:
            raise ValueError(f"Savitzky-Golay polyorder must be at least 2 to estimate q̈, got {self.polyorder}.")

    def window_samples(self, dt: float) -> int:
        """Number of samples (odd) in the window for a median step of `dt` seconds."""
        # Rounded first: a window of exactly 200 steps must not become 199 because one median step came out
        # as 1.0000000000012 ms (consecutive chunks of one record would then filter differently).
        x = round(self.window_s / dt, 6)
        return max(1, 2 * int(np.floor((x - 1.0) / 2.0 + 0.5)) + 1)

    def __call__(self, t: np.ndarray, q: np.ndarray) -> Derivatives:
        """Estimate smoothed q, q̇ and q̈.

        Parameters
        ----------
        t : np.ndarray
            (N,) time stamps in seconds, strictly increasing; jitter is allowed.
        q : np.ndarray
            (N, n) or (N,) positions.

        Returns
        -------
        Derivatives
            q, dq, ddq with the shape of the input `q`.

        Raises
        ------
        ValueError
            On non-finite values, shape mismatch, non-increasing time, or fewer samples than the window.
        """
        return self._fit(t, q, derivatives=True)

    def smooth(self, t: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The smoothed values alone: `self(t, x).q`, the same numbers, without the derivatives' work and memory
        (what dynid.robot.regressors.stack.signals_from_dataset passes the measured channels through)."""
        return self._fit(t, x, derivatives=False).q

    def _fit(self, t: np.ndarray, q: np.ndarray, derivatives: bool) -> Derivatives:
        t, q2, squeeze = _validate(t, q)
        if t.size < 2:
            raise ValueError(f"need at least {self.polyorder + 2} samples to estimate derivatives, got {t.size}.")
        dt = _median_step(t)
        w = self.window_samples(dt)
        if w <= self.polyorder:
            raise ValueError(
                f"Savitzky-Golay window of {self.window_s} s spans only {w} samples at the median step of "
                f"{dt:.6g} s; a degree-{self.polyorder} fit needs at least {self.polyorder + 1 + self.polyorder % 2} "
                f"(odd), so lengthen window_s (the configuration's derivatives.window_s)."
            )
        if t.size < w:
            raise ValueError(
                f"only {t.size} samples, fewer than the {w}-sample Savitzky-Golay window ({self.window_s} s at "
                f"the median step of {dt:.6g} s)."
            )
        if _is_uniform(t, dt):
            out = list(_uniform_poly_fit(q2, w, self.polyorder, dt, derivatives, self.fft))
        else:
            try:
                out = list(_local_poly_fit(t, q2, w, self.polyorder))
            except np.linalg.LinAlgError:
                # A gap in t many windows long leaves a window's samples in two tight clusters: the fit is singular.
                # numpy's "Singular matrix" was all a user saw (issue 22's sweep); name the gap instead.
                k = int(np.argmax(np.diff(t)))
                raise ValueError(
                    f"t jumps by {t[k + 1] - t[k]:.6g} s after sample {k + 1} ({(t[k + 1] - t[k]) / dt:.3g} median "
                    "steps): the derivative filter cannot bridge the gap; cut the run there (--from/--to)"
                ) from None
        return _shaped(squeeze, *out)


def _legendre_derivatives(p: int) -> tuple[np.ndarray, np.ndarray]:
    """Coefficient maps of the Legendre basis' derivatives: P_k'(u) = Σ_l D1[k, l] P_l(u), the same for P_k''."""
    eye = np.eye(p + 1)
    d1 = np.stack([np.pad(legendre.legder(row, 1), (0, 1)) for row in eye])
    d2 = np.stack([np.pad(legendre.legder(row, 2), (0, 2)) for row in eye])
    return d1, d2


def _uniform_poly_fit(q: np.ndarray, w: int, p: int, dt: float, derivatives: bool = True, fft: bool = False
                      ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Savitzky-Golay on uniform steps: `scipy.signal.savgol_filter(q, w, p, deriv=k, delta=dt, axis=0,
    mode="interp")` for k = 0, 1, 2 (test_derivatives compares the two), one set of weights for the interior and one
    per edge sample, in the Legendre basis of `_local_poly_fit`. scipy.signal is not imported: its 0.35 s import was
    an eighth of `dynid detect` (docs/benchmarks.md#compiled-kernels).

    With `fft` the interior is correlated through FFTs (`_fft_correlate`): O(log N) a sample rather than O(w), the
    same numbers to about 1e-15 of the data's scale, but a window of one constant reading no longer gives exactly 0.

    Returns q, dq, ddq, each (N, n); without `derivatives`, q and None twice.
    """
    from scipy.ndimage import correlate1d as direct

    correlate1d = _fft_correlate if fft else direct

    n_samples = q.shape[0]
    h = w // 2
    scale = h * dt  # the window's half-span in seconds: u = (t - t_centre) / scale ∈ [-1, 1]
    u = (np.arange(w) - h) / h
    V = legendre.legvander(u, p)  # (w, p+1)
    d1, d2 = _legendre_derivatives(p)
    # Value, d/dt and d²/dt² of each basis polynomial at every position e of the window: (p+1, w, 3).
    ev = np.stack([V.T, d1 @ V.T / scale, d2 @ V.T / scale**2], axis=2)
    # weights[j, e, k]: sample j's weight in the k-th derivative of the window's fit at position e.
    weights = (V @ np.linalg.solve(V.T @ V, ev.reshape(p + 1, -1))).reshape(w, w, 3)
    value = correlate1d(q, weights[:, h, 0], axis=0, mode="constant")  # the interior: centred windows
    # The first and last h samples take the first and last full window's fit, at their own positions.
    value[:h] = np.einsum("jn,je->en", q[:w], weights[:, :h, 0])
    value[n_samples - h:] = np.einsum("jn,je->en", q[n_samples - w:], weights[:, w - h:, 0])
    if not derivatives:
        return value, None, None
    # The derivatives are taken from the steps of q, d_i = q_{i+1} − q_i, with weights b_i = Σ_{j>i} a_j (Σ_j a_j = 0
    # exactly in theory): y = Σ a_j q_j = Σ b_i d_i. A window of one constant reading (a quantised encoder at rest)
    # then gives exactly 0, where Σ a_j q_j gave q·(the rounding of Σ a_j), ±1e-13 rad/s, and friction's sign(q̇)
    # followed it; and no large terms cancel.
    steps = np.diff(q, axis=0)
    on_steps = np.cumsum(weights[::-1, :, 1:], axis=0)[::-1][1:]  # (w − 1, w, 2): b for q̇ and q̈
    out = np.empty((2, *q.shape))
    for k in (1, 2):
        # even length 2h, origin 0: output n is Σ_i b_i d_{n−h+i}, the window centred on sample n (the last sample,
        # which the N − 1 steps leave out, is an edge sample: the block below fills it)
        out[k - 1, :n_samples - 1] = correlate1d(steps, on_steps[:, h, k - 1], axis=0, mode="constant")
    out[:, :h] = np.einsum("in,iek->ken", steps[:w - 1], on_steps[:, :h])
    out[:, n_samples - h:] = np.einsum("in,iek->ken", steps[n_samples - w:], on_steps[:, w - h:])
    return value, out[0], out[1]


def _fft_correlate(x: np.ndarray, kernel: np.ndarray, axis: int = 0, mode: str = "constant") -> np.ndarray:
    """`scipy.ndimage.correlate1d(x, kernel, axis=0, mode="constant")` where the kernel fits inside x (the windows
    `_uniform_poly_fit` fills by FFT): the full convolution with the reversed kernel, shifted to correlate1d's origin
    (the kernel's sample len // 2 on the output's)."""
    assert axis == 0 and mode == "constant"
    n, m = x.shape[0], kernel.size
    size = 1 << int(np.ceil(np.log2(n + m - 1)))
    full = np.fft.irfft(np.fft.rfft(x, size, axis=0) * np.fft.rfft(kernel[::-1], size)[:, None], size, axis=0)
    start = m - 1 - m // 2
    return full[start : start + n]


def _local_poly_fit(
    t: np.ndarray, q: np.ndarray, w: int, p: int, chunk: int = _CHUNK
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Savitzky-Golay on arbitrary stamps: per sample, a degree-p fit over w neighbours in their true times.

    Returns q, dq, ddq, each (N, n). Vectorised over chunks of `chunk` samples to bound memory.
    """
    n_samples, n_joints = q.shape
    h = w // 2
    # Window of sample i: samples [s_i, s_i + w); s_i = i - h inside, clamped at both ends (mode="interp").
    starts = np.clip(np.arange(n_samples) - h, 0, n_samples - w)
    t_win = sliding_window_view(t, w)  # (N-w+1, w) views, no copy
    q_win = sliding_window_view(q, w, axis=0)  # (N-w+1, n, w)
    d1, d2 = _legendre_derivatives(p)
    out = np.empty((3, n_samples, n_joints))
    for a in range(0, n_samples, chunk):
        idx = np.arange(a, min(a + chunk, n_samples))
        s = starts[idx]
        tw = t_win[s]  # (m, w)
        # Expand about the window's middle sample, scaled by its half-span so u ∈ [-1, 1], in the Legendre basis:
        # the Gram matrix is then near-diagonal (condition ~2p+1), so the normal equations are as accurate as a QR
        # and much cheaper (they agree with an independent lstsq to ~1e-12 relative at degree 7, where scipy's own
        # savgol coefficients already drift by 1e-5 relative).
        tc = tw[:, h]
        scale = 0.5 * (tw[:, -1] - tw[:, 0])
        u = (tw - tc[:, None]) / scale[:, None]
        V = legendre.legvander(u, p)  # (m, w, p+1)
        Vt = V.transpose(0, 2, 1)
        gram = Vt @ V  # (m, p+1, p+1)
        # Value, d/dt and d²/dt² of each basis polynomial at the sample's own offset (0 inside the record).
        b0 = legendre.legvander((t[idx] - tc) / scale, p)  # (m, p+1)
        ev = np.stack([b0, (b0 @ d1.T) / scale[:, None], (b0 @ d2.T) / (scale**2)[:, None]], axis=2)
        # Per-sample filter weights (m, w, 3) = V (VᵀV)⁻¹ E, shared by all joints: solving for 3 right-hand sides
        # instead of forming (VᵀV)⁻¹Vᵀ keeps the batched solve cheap.
        filt = V @ np.linalg.solve(gram, ev)
        qw = q_win[s]  # (m, n, w)
        out[0, idx] = (qw @ filt[:, :, :1])[..., 0]
        # q̇ and q̈ about the window's middle reading (their weights sum to 0): exactly 0 on a constant window, as on
        # uniform steps (`_uniform_poly_fit`)
        out[1:, idx] = ((qw - qw[:, :, h:h + 1]) @ filt[:, :, 1:]).transpose(2, 0, 1)
    return out[0], out[1], out[2]


# --------------------------------------------------------------------------------------------------------------
# Adaptive window (Janabi-Sharifi, Hayward, Chen 1995)
# --------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class AdaptiveWindow:
    """End-fit first-order adaptive windowing (FOAW), Janabi-Sharifi, Hayward and Chen (1995).

    Parameters
    ----------
    d : float
        Tolerance of the window test, rad: every sample of the window must lie within ±d of the line. Use the
        encoder quantisation step (two quantised samples differ from the truth by up to one step between them),
        or a bound on the position noise.
    max_window : int
        Largest window extent n, in samples from the estimated sample to a window end.
    causal : bool
        False (default, offline): the window spans n samples on both sides, the line passes through the
        estimated sample, and its slope is the end-point difference ``(q[k+n] - q[k-n]) / (t[k+n] - t[k-n])``;
        this is lag-free. True: the paper's classic backward window, the line through ``q[k-n]`` and ``q[k]``
        (it lags by about n/2 samples).

    Notes
    -----
    For each sample the window grows, n = 1, 2, ..., max_window, until some sample in it lies farther than d
    from the line; the estimate is the slope at the last n that passed (n = 1 always counts). Both variants
    anchor the line at the estimated sample, so "every sample within ±d" is a running interval of admissible
    slopes, updated in O(1) per step: the whole estimator costs O(N · max_window), vectorised over samples.
    Near the ends of the record the window is cut to the available samples (it becomes one-sided).

    q̈ applies the same estimator to q̇. The tolerance between two velocities is the sum of their error bounds,
    d / T each for a slope over a window of duration T (its end points are each off by up to d/2). q is
    returned as given: every line passes through its sample, so the estimator does not smooth positions.

    On fast motion the windows stay short (the line test fails after a few samples), so this estimator is
    noisier than `SavitzkyGolay`; it is here because the reference paper used it.
    """

    d: float
    max_window: int = 50
    causal: bool = False

    def __post_init__(self) -> None:
        if not (np.isfinite(self.d) and self.d > 0):
            raise ValueError(f"adaptive window tolerance d must be a positive number (rad), got {self.d!r}.")
        if isinstance(self.max_window, bool) or not isinstance(self.max_window, (int, np.integer)):
            raise ValueError(f"adaptive window max_window must be an integer, got {self.max_window!r}.")
        if self.max_window < 1:
            raise ValueError(f"adaptive window max_window must be at least 1, got {self.max_window}.")

    def __call__(self, t: np.ndarray, q: np.ndarray) -> Derivatives:
        """Estimate q, q̇ and q̈ (see the class notes); raises ValueError on unusable input."""
        t, q2, squeeze = _validate(t, q)
        if t.size < 3:
            raise ValueError(f"need at least 3 samples to estimate velocity and acceleration, got {t.size}.")
        # Per-sample error bound d/2 makes the pairwise tolerance exactly the paper's ±d.
        dq, span = _foaw(t, q2, np.full(q2.shape, 0.5 * self.d), self.max_window, self.causal)
        ddq, _ = _foaw(t, dq, self.d / span, self.max_window, self.causal)
        return _shaped(squeeze, q2.copy(), dq, ddq)


def _foaw(
    t: np.ndarray, y: np.ndarray, eps: np.ndarray, max_window: int, causal: bool, chunk: int = 4096
) -> tuple[np.ndarray, np.ndarray]:
    """End-fit adaptive-window slope of y (N, n) against t, with per-sample error bounds eps (N, n).

    Sample j fits the line through (t_k, y_k) when |y_j - line(t_j)| <= eps_j + eps_k. Returns the slope (N, n)
    and the duration (s) of the window it came from. Runs in chunks of `chunk` samples plus a `max_window` halo
    on each side, so every window inside the chunk sees exactly the samples it would see in the whole record,
    while the work arrays stay cache-sized and a chunk stops as soon as all its windows have.
    """
    n_samples = t.size
    slope = np.empty(y.shape)
    span = np.empty(y.shape)
    for a in range(0, n_samples, chunk):
        b = min(a + chunk, n_samples)
        lo, hi = max(a - max_window, 0), min(b + max_window, n_samples)
        s, d = _foaw_block(t[lo:hi], y[lo:hi], eps[lo:hi], max_window, causal)
        slope[a:b], span[a:b] = s[a - lo : b - lo], d[a - lo : b - lo]
    if causal:
        # The first sample has no past: give it its forward difference.
        slope[0] = (y[1] - y[0]) / (t[1] - t[0])
        span[0] = t[1] - t[0]
    return slope, span


def _foaw_block(
    t: np.ndarray, y: np.ndarray, eps: np.ndarray, max_window: int, causal: bool
) -> tuple[np.ndarray, np.ndarray]:
    """`_foaw` on one block; windows are clamped at the block's ends. Written with slices and in-place ops
    (no gathers), since every step touches the whole block."""
    n_samples = t.size
    lo = np.full(y.shape, -np.inf)
    hi = np.full(y.shape, np.inf)
    slope = np.zeros(y.shape)
    span = np.ones(y.shape)
    alive = np.ones(y.shape, dtype=bool)
    s = np.empty(y.shape)
    work = np.empty(y.shape)
    half = np.empty(y.shape)

    def tighten(rows: slice, others: slice) -> None:
        # Sample j fits a line through (t_k, y_k) of slope s iff s ∈ [(y_j - y_k)/τ ∓ (eps_j + eps_k)/|τ|], with
        # τ = t_j - t_k: each new sample only narrows the running interval [lo, hi] of admissible slopes.
        inv = (1.0 / (t[others] - t[rows]))[:, None]
        c = np.subtract(y[others], y[rows], out=work[rows])
        c *= inv
        h = np.add(eps[others], eps[rows], out=half[rows])
        # Quantised data often sit exactly at ±d; the 1e-9 slack makes such ties fit despite rounding.
        h *= np.abs(inv) * (1.0 + 1e-9)
        np.maximum(lo[rows], np.subtract(c, h, out=s[rows]), out=lo[rows])
        np.minimum(hi[rows], np.add(c, h, out=c), out=hi[rows])

    for m in range(1, min(max_window, n_samples - 1) + 1):
        tighten(slice(m, None), slice(None, -m))  # backward: sample k - m, for k >= m
        if not causal:
            tighten(slice(None, -m), slice(m, None))  # forward: sample k + m, for k <= N-1-m
        # End-point slope; ends are clamped where a side has run out of samples: jb = max(k-m, 0),
        # jf = min(k+m, N-1) (non-causal) or k (causal).
        dur = np.empty(n_samples)
        if causal:
            s[:] = y
            dur[:] = t
        else:
            s[: n_samples - m], s[n_samples - m :] = y[m:], y[-1]
            dur[: n_samples - m], dur[n_samples - m :] = t[m:], t[-1]
        s[m:] -= y[:-m]
        s[:m] -= y[0]
        dur[m:] -= t[:-m]
        dur[:m] -= t[0]
        # Rows whose window could not grow (no sample left on either side) have dur = 0: they stop here.
        stuck = slice(0, m) if causal else slice(max(n_samples - m, 0), m)
        dur[stuck] = np.inf
        s /= dur[:, None]
        if m == 1:
            alive[:] = True  # n = 1 always counts
        else:
            alive &= s >= lo
            alive &= s <= hi
        alive[stuck] = False
        np.copyto(slope, s, where=alive)
        np.copyto(span, dur[:, None], where=alive)
        if not alive.any():
            break
    return slope, span


# --------------------------------------------------------------------------------------------------------------
# Entry point
# --------------------------------------------------------------------------------------------------------------

METHODS: dict[str, type] = {"savgol": SavitzkyGolay, "adaptive": AdaptiveWindow}


def estimate_derivatives(t: np.ndarray, q: np.ndarray, method: str = "savgol", **options: Any) -> Derivatives:
    """Estimate smoothed q, q̇ and q̈ from time-stamped positions, offline (non-causal).

    Parameters
    ----------
    t : np.ndarray
        (N,) time stamps in seconds, strictly increasing (jitter allowed).
    q : np.ndarray
        (N, n) or (N,) joint positions, rad.
    method : str
        ``"savgol"`` (`SavitzkyGolay`, default) or ``"adaptive"`` (`AdaptiveWindow`, needs ``d``).
    **options
        Fields of the method's dataclass, e.g. ``window_s=0.05`` or ``d=2*np.pi/65536``.

    Returns
    -------
    Derivatives
        q, dq, ddq with the shape of `q`.

    Raises
    ------
    ValueError
        On an unknown method or option, or unusable data (see `SavitzkyGolay.__call__`).
    """
    if method not in METHODS:
        raise ValueError(f"unknown derivative method {method!r}; choose one of {', '.join(map(repr, METHODS))}.")
    cls = METHODS[method]
    fields = set(cls.__dataclass_fields__)
    unknown = sorted(set(options) - fields)
    if unknown:
        raise ValueError(
            f"unknown option(s) {', '.join(unknown)} for derivative method {method!r}; "
            f"it takes {', '.join(sorted(fields))}."
        )
    if method == "adaptive" and "d" not in options:
        raise ValueError(
            "derivative method 'adaptive' needs the position noise bound d (rad), e.g. the encoder step."
        )
    return cls(**options)(t, q)
