"""Sufficient statistics of the weighted stacked system, accumulated a chunk at a time, per time block.

Every estimator of `dynid.identify.regression` works from these, so memory is bounded by p² per block whatever the
length of the experiment (an hour at 1 kHz is 36 million rows of A; it is never stacked):

- ``gram[k, c]`` = [A b]ᵀ W² [A b] over the rows of channel c in time block k, (p+1, p+1): summed over
  channels it is the whole system's; per channel it gives each output's residual variance for any Φ;
- ``cross[k, c]`` = Zᵀ W² A and ``cross_b[k, c]`` = Zᵀ W² b over the rows of channel c in block k, where Z is the
  regressor along an instrument trajectory (the IV estimator's raw instruments);
- ``rows[k, c]``: how many rows of channel c block k kept (rows at rest have weight 0 and count for nothing).

Blocks are contiguous stretches of time: cross-validation holds one out, the jackknife drops one at a time.
The work is spread over processes (fork) a block range each; the statistics add up exactly.
"""

from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from threadpoolctl import threadpool_limits

from ..progress import track
from ..robot.model import RobotModel
from ..robot.regressors.stack import DEFAULT_CHUNK, RowChannel, Signals, row_channels, weighted_rows

MIN_BLOCK_SAMPLES = 200


@dataclass
class Statistics:
    parameter_names: tuple[str, ...]
    channels: tuple[RowChannel, ...]
    block_samples: np.ndarray  # (B + 1,) sample index where each block starts, then the end
    gram: np.ndarray  # (B, r, p+1, p+1)
    rows: np.ndarray  # (B, r)
    cross: np.ndarray | None = None  # (B, r, p, p)
    cross_b: np.ndarray | None = None  # (B, r, p)
    block_run: np.ndarray | None = None  # (B,) the run each block belongs to (None: all to run 0)

    def __post_init__(self) -> None:
        if self.block_run is None:
            self.block_run = np.zeros(self.n_blocks, dtype=int)

    @property
    def n_runs(self) -> int:
        return int(self.block_run.max()) + 1 if self.n_blocks else 0

    def run_blocks(self, run: int) -> np.ndarray:
        """(B,) bool: the blocks of run `run`."""
        return self.block_run == run

    @property
    def n_blocks(self) -> int:
        return self.gram.shape[0]

    @property
    def p(self) -> int:
        return self.gram.shape[-1] - 1

    def system(self, keep: np.ndarray | slice | None = None) -> np.ndarray:
        """[A b]ᵀW²[A b] of the whole system over the blocks `keep` (all by default)."""
        return self.gram[slice(None) if keep is None else keep].sum(axis=(0, 1))

    def total(self, keep: np.ndarray | None = None) -> Statistics:
        """The statistics summed over the blocks `keep` (bool or indices; all by default), as one block."""
        k = slice(None) if keep is None else keep
        return Statistics(
            self.parameter_names, self.channels, self.block_samples[[0, -1]],
            self.gram[k].sum(axis=0)[None], self.rows[k].sum(axis=0)[None],
            None if self.cross is None else self.cross[k].sum(axis=0)[None],
            None if self.cross_b is None else self.cross_b[k].sum(axis=0)[None],
        )

    def of_blocks(self, keep: np.ndarray) -> Statistics:
        """The statistics of the blocks `keep` (bool), runs renumbered in order (e.g. one pair of runs)."""
        runs = np.unique(self.block_run[keep])
        sub = lambda a: None if a is None else a[keep]  # noqa: E731
        sizes = np.diff(self.block_samples)[keep]
        return Statistics(self.parameter_names, self.channels, np.concatenate([[0], np.cumsum(sizes)]),
                          self.gram[keep], self.rows[keep], sub(self.cross), sub(self.cross_b),
                          np.searchsorted(runs, self.block_run[keep]))

    def __add__(self, other: Statistics) -> Statistics:
        """Statistics of two sets of runs, merged: their blocks side by side, `other`'s runs numbered after these.

        The merge concatenates and never adds, so it is exact, and associative: (a + b) + c and a + (b + c) hold the
        same arrays bit for bit. Every solve sums the blocks it keeps in block order (`system`), so a fit depends on
        which runs were merged in which order, never on how the merges were grouped (on a cluster, in a reduction
        tree, or one run at a time)."""
        if other.parameter_names != self.parameter_names:
            raise ValueError("statistics of different parameter layouts")
        cat = lambda a, b: None if a is None or b is None else np.concatenate([a, b])  # noqa: E731
        end = self.block_samples[-1]
        return Statistics(
            self.parameter_names, self.channels, np.concatenate([self.block_samples, other.block_samples[1:] + end]),
            np.concatenate([self.gram, other.gram]), np.concatenate([self.rows, other.rows]),
            cat(self.cross, other.cross), cat(self.cross_b, other.cross_b),
            np.concatenate([self.block_run, other.block_run + self.n_runs]),
        )


def block_edges(n_samples: int, n_blocks: int) -> np.ndarray:
    n_blocks = max(1, min(n_blocks, n_samples // MIN_BLOCK_SAMPLES))
    return np.linspace(0, n_samples, n_blocks + 1).round().astype(int)


# The job a forked worker reads (fork shares it without pickling the Pinocchio model).
_JOB: dict = {}


def _accumulate_blocks(first: int, last: int) -> tuple[np.ndarray, ...]:
    # One BLAS thread per worker: the workers already fill the cores, and OpenBLAS threads spinning against
    # each other cost a third of the time on a 2-core machine.
    with threadpool_limits(limits=1, user_api="blas"):
        return _accumulate(first, last)


def _accumulate(first: int, last: int) -> tuple[np.ndarray, ...]:
    return accumulate_blocks(_JOB["model"], _JOB["source"], _JOB["edges"], first, last, _JOB["chunk"],
                             _JOB["label"] if _JOB["progress"] else "")


def accumulate_blocks(model: RobotModel, source: SignalChunks, edges: np.ndarray, first: int, last: int,
                      chunk: int = DEFAULT_CHUNK, progress: str = "") -> tuple[np.ndarray | None, ...]:
    """(gram, rows, cross, cross_b) of blocks [first, last) of `source`, a chunk at a time (also a Dask task's
    work: dynid.identify.runs); `progress`: the label of a progress line over the blocks ("" for none)."""
    r, p = len(row_channels(model)), len(model.layout)
    nb = last - first
    gram, rows = np.zeros((nb, r, p + 1, p + 1)), np.zeros((nb, r))
    cross, cross_b = np.zeros((nb, r, p, p)), np.zeros((nb, r, p))
    with_instruments = False
    # The chunks' rows are written into the same two buffers chunk after chunk (dynid.robot.regressors.stack
    # .weighted_rows: fresh ones cost a third of the statistics' time in page faults)
    longest = min(chunk, int(np.max(np.diff(edges[first : last + 1])))) if nb else 0
    rows_buffer = np.empty((r, longest, p + 1))
    instruments_buffer: np.ndarray | None = None
    blocks = range(first, last)
    for k in track(blocks, nb, progress) if progress else blocks:
        for lo in range(edges[k], edges[k + 1], chunk):
            sig, inst, w = source(lo, min(lo + chunk, edges[k + 1]))
            # Channel-major, contiguous: one batched product per chunk instead of r strided ones.
            X = weighted_rows(model, sig, w, out=rows_buffer)  # (r, n, p+1): [W A | W b]
            rows[k - first] += (w > 0).sum(axis=0)
            Zw = None
            if inst is not None:
                with_instruments = True
                if instruments_buffer is None:
                    instruments_buffer = np.empty_like(rows_buffer)
                Zw = weighted_rows(model, inst, w, out=instruments_buffer)[:, :, :p]
            add_channel_products(X, Zw, gram[k - first], cross[k - first], cross_b[k - first])
    return gram, rows, (cross if with_instruments else None), (cross_b if with_instruments else None)


def add_channel_products(X: np.ndarray, Z: np.ndarray | None, gram: np.ndarray, cross: np.ndarray,
                         cross_b: np.ndarray) -> None:
    """gram[c] += XcᵀXc and, with instruments, [cross | cross_b][c] += ZcᵀXc, channel by channel over the columns
    that are not zero on the chunk's rows of that channel only: a channel's regressor touches the bodies beyond its
    joint or sensor and its own motor's friction and gain (the default arm: a fifth of the products), so the rest
    are exact zeros. Two to three times faster than the full batched products, the same sums but for the order
    their blocks are added in (docs/benchmarks.md#compiled-kernels)."""
    p = gram.shape[-1] - 1
    for c in range(X.shape[0]):
        ix = np.flatnonzero(X[c].any(axis=0))
        if ix.size == 0:
            continue
        Xc = X[c][:, ix]
        gram[c][np.ix_(ix, ix)] += Xc.T @ Xc
        if Z is None:
            continue
        iz = np.flatnonzero(Z[c].any(axis=0))
        if iz.size == 0:
            continue
        zx = Z[c][:, iz].T @ Xc  # Zᵀ W² [A b] on the non-zero columns
        a = ix < p  # the regressor's columns, then b's
        cross[c][np.ix_(iz, ix[a])] += zx[:, a]
        if not a.all():
            cross_b[c][iz] += zx[:, ~a][:, 0]


class SignalChunks(Protocol):
    """Rows [lo, hi) of an experiment as (signals, instrument signals or None, row weights (hi − lo, r))."""

    n_samples: int

    def __call__(self, lo: int, hi: int) -> tuple[Signals, Signals | None, np.ndarray]: ...


@dataclass
class InMemory:
    """`SignalChunks` over signals already computed for the whole experiment."""

    sig: Signals
    weights: np.ndarray
    instruments: Signals | None = None

    @property
    def n_samples(self) -> int:
        return self.sig.q.shape[0]

    def __call__(self, lo: int, hi: int) -> tuple[Signals, Signals | None, np.ndarray]:
        s = slice(lo, hi)
        return self.sig.slice(s), None if self.instruments is None else self.instruments.slice(s), self.weights[s]


def accumulate(
    model: RobotModel,
    source: SignalChunks,
    n_blocks: int = 10,
    workers: int | None = None,
    chunk: int = DEFAULT_CHUNK,
    label: str = "building regressors",
) -> Statistics:
    """Statistics of the experiment `source` yields a chunk at a time (`InMemory` for signals at hand).

    Instrument signals, where the source gives them, add the IV cross products."""
    n = source.n_samples
    edges = block_edges(n, n_blocks)
    nb = len(edges) - 1
    workers = max(1, min(workers or os.cpu_count() or 1, nb))
    _JOB.update(model=model, source=source, edges=edges, chunk=chunk, label=label)
    try:
        if workers == 1:
            _JOB["progress"] = True
            parts = [_accumulate_blocks(0, nb)]
        else:
            _JOB["progress"] = False  # the parent shows progress, a block at a time
            ctx = multiprocessing.get_context("fork")
            with ProcessPoolExecutor(workers, mp_context=ctx) as pool:
                futures = [pool.submit(_accumulate_blocks, k, k + 1) for k in range(nb)]
                for _ in track(as_completed(futures), nb, label):
                    pass
                parts = [f.result() for f in futures]
    finally:
        _JOB.clear()
    return assemble(model, edges, parts)


def assemble(model: RobotModel, edges: np.ndarray, parts: list[tuple[np.ndarray | None, ...]]) -> Statistics:
    """One run's statistics from its blocks' parts (`accumulate_blocks`), in block order."""
    gram = np.concatenate([x[0] for x in parts])
    rows = np.concatenate([x[1] for x in parts])
    with_instruments = all(x[2] is not None for x in parts)
    cross = np.concatenate([x[2] for x in parts]) if with_instruments else None
    cross_b = np.concatenate([x[3] for x in parts]) if with_instruments else None
    return Statistics(model.layout.names, row_channels(model), edges, gram, rows, cross, cross_b)
