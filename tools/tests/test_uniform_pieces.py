"""A logged run that misses samples, as the monitor takes it (dynid.detect.online.uniform_pieces): up to three missing
samples in a row bridged by linear interpolation, as rt_monitor's sample clock bridges them (kMaxBridge); the run cut
where more are missing (the monitor restarts its filter there); each row's original index kept for the folds."""

from __future__ import annotations

import numpy as np

from dynid.detect.online import MAX_BRIDGE, uniform_pieces
from dynid.io.dataset import Dataset

DT = 1e-3


def run_with_gaps(missing: dict[int, int], n: int = 400) -> Dataset:
    """n samples at DT, with `missing[k]` samples left out after row k; q and a torque linear in t (bridging exact)."""
    t = [0.0]
    for k in range(1, n):
        t.append(t[-1] + DT * (1 + missing.get(k - 1, 0)))
    t = np.array(t) + 0.01 * DT * np.sin(np.arange(n))  # logging jitter well under the gap rule
    return Dataset(t=t, joints=("j1", "j2"), q=np.column_stack([2 * t, -t]), tau={"j1": 3 * t + 1, "j2": 0 * t},
                   contact=(np.arange(n) % 7 == 0).astype(np.uint8))


def test_short_gaps_are_bridged_linearly_and_keep_their_original_rows() -> None:
    ds = run_with_gaps({100: 1, 250: MAX_BRIDGE})
    (piece, origin), = uniform_pieces(ds, DT)
    assert piece.n_samples == ds.n_samples + 1 + MAX_BRIDGE
    assert piece.meta["bridged_samples"] == 1 + MAX_BRIDGE
    assert np.abs(np.diff(piece.t) - DT).max() < 0.05 * DT  # one sample per period again
    np.testing.assert_allclose(piece.q[:, 0], 2 * piece.t, rtol=0, atol=1e-12)  # interpolated where it was missing
    np.testing.assert_allclose(piece.tau["j1"], 3 * piece.t + 1, rtol=0, atol=1e-12)
    # original rows in order; a bridged row points at the row before it
    assert origin[0] == 0 and origin[-1] == ds.n_samples - 1 and np.all(np.diff(origin) >= 0)
    assert np.array_equal(np.flatnonzero(np.diff(origin) == 0), [100, 251, 252, 253])
    assert np.array_equal(piece.contact, ds.contact[origin])


def test_a_longer_gap_cuts_the_run() -> None:
    ds = run_with_gaps({150: MAX_BRIDGE + 1, 300: 1})
    pieces = uniform_pieces(ds, DT)
    assert [p.n_samples for p, _ in pieces] == [151, ds.n_samples - 151 + 1]
    (first, o1), (second, o2) = pieces
    assert o1[-1] == 150 and o2[0] == 151  # the cut is after row 150: nothing bridged across it
    assert second.meta["bridged_samples"] == 1 and first.meta["bridged_samples"] == 0


def test_a_run_without_gaps_is_itself() -> None:
    ds = run_with_gaps({})
    (piece, origin), = uniform_pieces(ds, DT)
    assert piece is ds and np.array_equal(origin, np.arange(ds.n_samples))


def test_the_folds_follow_each_piece_to_its_original_samples() -> None:
    """PieceFolds: a piece's rows take the Φ of the fold block their original sample is in (a bridged row, the block
    of the row before it), as FoldsSection.segments gives them for the whole run."""
    from dynid.detect.online import PieceFolds
    from dynid.identify.model_sections import FoldsSection

    ds = run_with_gaps({80: 1, 150: MAX_BRIDGE + 1, 300: 1})  # bridged, cut, bridged
    pieces = uniform_pieces(ds, DT)
    blocks = [(0, 120), (120, 260), (260, 400)]
    folds = FoldsSection(np.zeros(3, int), np.array(blocks), np.array([[1.0], [2.0], [3.0]]))
    mapped = PieceFolds(folds, [o for _, o in pieces], [0] * len(pieces))
    phi = np.array([0.0])
    for i, (piece, origin) in enumerate(pieces):
        segments = mapped.segments(i, piece.n_samples, phi)
        assert [lo for lo, _, _ in segments][0] == 0 and segments[-1][1] == piece.n_samples  # the whole piece
        assert all(a[1] == b[0] for a, b in zip(segments, segments[1:]))  # contiguous
        for lo, hi, phi_k in segments:  # every row's original sample is in the block whose Φ it takes
            k = int(phi_k[0]) - 1
            assert np.all((origin[lo:hi] >= blocks[k][0]) & (origin[lo:hi] < blocks[k][1]))
