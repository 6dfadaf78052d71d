"""Runs read a window of rows at a time, and written a chunk at a time: a log never has to fit in memory.

A dataset file (`dynid.io.dataset`) is an uncompressed zip of ``.npy`` members, one per signal, each a C-ordered
array of N rows. `DatasetFile` finds where each member's rows start in the file and reads rows [lo, hi) of every
member with one positioned read each (`os.preadv`: no shared file position, so threads of one process may read
the same file at once). Each window is checked as `load_data` checks a whole file (finite values, time strictly
increasing, also across the window's first row, units, values within ±1e6) and errors name the file's own rows.

`DatasetWriter` writes a dataset file a chunk at a time: each member goes to a temporary ``.npy`` file whose header
holds the final shape, and the zip is assembled member by member at the end (copied in blocks), then moved into
place atomically. So a ten-hour log is simulated or tiled in pieces (tools/benchmarks/long_log.py) and fitted in
pieces, and neither step ever holds it.

`open_run` is the streaming twin of `load_data`: a stored dataset file (or a `dynid simulate` directory) opens as
a `DatasetFile`; every other form (CSV, candump, YARP, a compressed archive) is read whole, as before.
"""

from __future__ import annotations

import bisect
import contextlib
import json
import math
import os
import shutil
import struct
import tempfile
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..config.robot_config import RobotConfig
from ..errors import DataError
from .dataset import (_ZIP_MAGIC, CHANNEL_FAMILIES, FORMAT_NAME, FORMAT_VERSION, SIMULATION_DATASET, Dataset,
                      _check_members, check_units)
from .load import MIN_WINDOW_SAMPLES, check_matches_config, check_plausible, check_values, load_data

HEAD_ROWS = 5_000  # rows read at opening: the configuration's checks and the median sample period
_LOCAL_HEADER = struct.Struct("<4s22xHH")  # zip local file header: signature, …, name length, extra length
_ROW_MEMBERS = ("t", "q", "dq", "ddq", "contact")


class NotStreamable(Exception):
    """The file is a dataset, but not one whose rows can be read in place (a compressed member, or a column-major
    one of more than two dimensions): it is read whole instead."""


class DatasetFile:
    """Rows [lo, hi) of a dataset file, read on demand. Quacks like `Dataset` where a fit needs it:
    `n_samples`, `joints`, `meta`, `duration`, `slice(lo, hi)` → `Dataset`, `times(lo, hi)`, `median_step()`."""

    def __init__(self, path: str | Path, joint_limits: Mapping[str, tuple[float, float]] | None = None) -> None:
        self.path = Path(path)
        self.joint_limits = dict(joint_limits) if joint_limits else None
        self._fd: int | None = None
        self._pid = -1
        try:
            _check_members(self.path)
            self._members, small, self._fortran = self._index()
        except (zipfile.BadZipFile, OSError, ValueError, EOFError) as e:
            raise DataError(f"{self.path}: not a dynid dataset (.npz) or a corrupt one: {e}") from None
        if str(small.get("format", "")) != FORMAT_NAME:
            raise DataError(f"{self.path}: not a dynid dataset (no '{FORMAT_NAME}' format marker)")
        try:
            version = int(small["format_version"])
        except (KeyError, TypeError, ValueError, OverflowError):
            raise DataError(f"{self.path}: dataset has no valid format_version") from None
        if not 1 <= version <= FORMAT_VERSION:
            raise DataError(f"{self.path}: dataset format version {version} is not supported (this dynid reads "
                            f"1..{FORMAT_VERSION})")
        try:
            self.meta: dict[str, Any] = json.loads(str(small["meta"]))
            self.joints: tuple[str, ...] = tuple(str(j) for j in small["joints"])
        except (KeyError, ValueError, RecursionError):
            raise DataError(f"{self.path}: corrupt dataset: member 'meta' or 'joints' is missing or not readable") from None
        if not isinstance(self.meta, dict) or "t" not in self._members or "q" not in self._members:
            raise DataError(f"{self.path}: corrupt dataset: no t or q member, or meta is not a JSON object")
        n = self._members["t"][2][0]
        for name, (_, _, shape) in self._members.items():
            if shape[0] != n:
                raise DataError(f"{self.path}: corrupt dataset: member '{name}' has {shape[0]} rows, t has {n}")
        self.lo, self.hi = 0, n
        self._row0 = self.meta.get("rows", [0, n])[0] if isinstance(self.meta.get("rows"), list) else 0

    # ------------------------------------------------------------------------------------------------------
    # The file

    def _index(self) -> tuple[dict[str, tuple[int, np.dtype, tuple[int, ...]]], dict[str, np.ndarray], set[str]]:
        """Each row member's (data offset, dtype, shape); the small members (format, meta, joints) read whole; the
        two-dimensional members stored column-major (a lab's own writer: numpy keeps a transposed array's order)."""
        members: dict[str, tuple[int, np.dtype, tuple[int, ...]]] = {}
        small: dict[str, np.ndarray] = {}
        fortran_members: set[str] = set()
        with zipfile.ZipFile(self.path) as archive, open(self.path, "rb") as raw:
            for info in archive.infolist():
                name = info.filename.removesuffix(".npy")
                if name in ("format", "format_version", "meta", "joints"):
                    with archive.open(info) as f:
                        small[name] = np.lib.format.read_array(f, allow_pickle=False)
                    continue
                if info.compress_type != zipfile.ZIP_STORED:
                    raise NotStreamable(name)
                raw.seek(info.header_offset)
                signature, name_len, extra_len = _LOCAL_HEADER.unpack(raw.read(_LOCAL_HEADER.size))
                if signature != _ZIP_MAGIC:
                    raise ValueError(f"member '{name}': no local header at its offset")
                raw.seek(info.header_offset + _LOCAL_HEADER.size + name_len + extra_len)
                version = np.lib.format.read_magic(raw)
                read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                        else np.lib.format.read_array_header_2_0)
                shape, fortran, dtype = read(raw)
                if fortran and len(shape) > 2:
                    raise NotStreamable(name)
                if fortran and len(shape) == 2:
                    fortran_members.add(name)
                family, _, channel = name.partition("/")
                if not (name in _ROW_MEMBERS or (family in CHANNEL_FAMILIES and channel)) or not shape:
                    raise ValueError(f"unknown member '{name}'")
                if dtype.kind not in "fiub":
                    raise ValueError(f"member '{name}' is not numeric ({dtype})")
                members[name] = (raw.tell(), dtype, tuple(shape))
        return members, small, fortran_members

    def __getstate__(self) -> dict[str, Any]:  # a Dask worker reopens the file itself: no descriptor travels
        state = dict(self.__dict__)
        state["_fd"], state["_pid"] = None, -1
        return state

    def __del__(self) -> None:
        if self._fd is not None and self._pid == os.getpid():
            with contextlib.suppress(OSError):
                os.close(self._fd)

    def _read(self, name: str, lo: int, hi: int) -> np.ndarray:
        if self._fd is None or self._pid != os.getpid():  # opened per process (a fork inherits no position)
            self._fd, self._pid = os.open(self.path, os.O_RDONLY), os.getpid()
        offset, dtype, shape = self._members[name]
        if name in self._fortran:  # column by column: rows [lo, hi) of each column are contiguous
            out = np.empty((hi - lo, shape[1]), dtype=dtype)
            for j in range(shape[1]):
                out[:, j] = self._pread(name, offset + (j * shape[0] + lo) * dtype.itemsize, hi - lo, dtype, hi)
            return out
        row = dtype.itemsize * math.prod(shape[1:])
        out = np.empty((hi - lo, *shape[1:]), dtype=dtype)
        self._fill(name, memoryview(out).cast("B") if out.size else memoryview(b""), offset + lo * row, hi)
        return out

    def _pread(self, name: str, at: int, count: int, dtype: np.dtype, hi: int) -> np.ndarray:
        out = np.empty(count, dtype=dtype)
        self._fill(name, memoryview(out).cast("B") if out.size else memoryview(b""), at, hi)
        return out

    def _fill(self, name: str, view: memoryview, at: int, hi: int) -> None:
        done = 0
        while done < len(view):
            got = os.preadv(self._fd, [view[done:]], at + done)
            if got <= 0:
                raise DataError(f"{self.path}: member '{name}' ends before row {hi} (a truncated file)")
            done += got

    # ------------------------------------------------------------------------------------------------------
    # What a fit reads

    @property
    def n_samples(self) -> int:
        return self.hi - self.lo

    @property
    def duration(self) -> float:
        return float(self._read("t", self.hi - 1, self.hi)[0] - self._read("t", self.lo, self.lo + 1)[0])

    def times(self, lo: int, hi: int) -> np.ndarray:
        return self._read("t", self.lo + lo, self.lo + hi)

    def contact_share(self) -> float | None:
        """The share of this window's samples labelled contact (the `contact` member, one byte a sample), None without
        the member."""
        if "contact" not in self._members or self.n_samples == 0:
            return None
        return float(np.count_nonzero(self._read("contact", self.lo, self.hi)) / self.n_samples)

    def joint_extrema(self, chunk: int = 1 << 16) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) of each joint's position over this window, `chunk` rows at a time (q alone: one member)."""
        lo, hi = np.full(len(self.joints), np.inf), np.full(len(self.joints), -np.inf)
        for a in range(self.lo, self.hi, chunk):
            q = self._read("q", a, min(a + chunk, self.hi))
            lo, hi = np.minimum(lo, q.min(axis=0)), np.maximum(hi, q.max(axis=0))
        return lo, hi

    def median_step(self) -> float:
        """The median sample period of the first `HEAD_ROWS` rows (the whole log's, for a log sampled evenly)."""
        return float(np.median(np.diff(self.times(0, min(self.n_samples, HEAD_ROWS)))))

    def slice(self, start: int, stop: int) -> Dataset:
        """Rows [start, stop) of this window, read from disk and checked; `meta["rows"]` names the file's rows."""
        lo, hi = self.lo + max(0, int(start)), self.lo + min(int(stop), self.n_samples)
        if hi <= lo:
            raise DataError(f"rows [{start}, {stop}) select no sample of a dataset of {self.n_samples}")
        families: dict[str, dict[str, np.ndarray]] = {f: {} for f in CHANNEL_FAMILIES}
        for name in self._members:
            family, _, channel = name.partition("/")
            if family in families:
                families[family][channel] = self._read(name, lo, hi)
        read = lambda n: self._read(n, lo, hi) if n in self._members else None  # noqa: E731
        meta = {**self.meta, "rows": [self._row0 + lo, self._row0 + hi]}
        where = f"{self.path}, rows {lo + 1}-{hi}"
        try:
            ds = Dataset(t=read("t"), joints=self.joints, q=read("q"), dq=read("dq"), ddq=read("ddq"),
                         contact=read("contact"), meta=meta, **families).validate()
            if lo > 0 and not ds.t[0] > self._read("t", lo - 1, lo)[0]:
                raise DataError(f"t is not strictly increasing at row {lo + 1}")
            check_units(ds, self.joint_limits, row=lambda i: f"row {lo + i + 1}")
            check_values(ds, row_offset=lo)
        except DataError as e:
            raise DataError(f"{where}: corrupt dataset: {e}") from None
        return ds

    def window(self, start: float | None, stop: float | None, source: str = "") -> DatasetFile:
        """The rows with start <= t <= stop (`--from/--to`), found by bisection on the file's t column."""
        if start is None and stop is None:
            return self
        where = f"{source}: " if source else ""
        times = _Column(self)
        span = f"the data run from {times[0]:.6g} s to {times[len(times) - 1]:.6g} s"
        if start is not None and stop is not None and stop <= start:
            raise DataError(f"{where}--to {stop:g} s must come after --from {start:g} s")
        lo = 0 if start is None else bisect.bisect_left(times, start)
        hi = len(times) if stop is None else bisect.bisect_right(times, stop)
        if hi - lo < MIN_WINDOW_SAMPLES:
            what = "no sample" if hi <= lo else f"only {hi - lo} samples"
            raise DataError(
                f"{where}the window --from {'start' if start is None else f'{start:g} s'} --to "
                f"{'end' if stop is None else f'{stop:g} s'} holds {what} (at least {MIN_WINDOW_SAMPLES} needed); {span}")
        view = object.__new__(DatasetFile)
        view.__dict__.update(self.__getstate__())
        view.lo, view.hi = self.lo + lo, self.lo + hi
        view.meta = {**self.meta, "window": [start, stop]}  # as apply_window records it, for the model file
        return view


class _Column:
    """t of a `DatasetFile` as a sequence for `bisect`: one positioned read per probe."""

    def __init__(self, run: DatasetFile) -> None:
        self.run = run

    def __len__(self) -> int:
        return self.run.n_samples

    def __getitem__(self, i: int) -> float:
        return float(self.run.times(i, i + 1)[0])


Run = Dataset | DatasetFile


def open_run(path: str | Path, config: RobotConfig, joint_limits: Mapping[str, tuple[float, float]] | None = None,
             require_all: bool = True) -> Run:
    """A run for `config`, streamed from disk when it is a stored dataset file (or a `dynid simulate`
    directory), else read whole by `load_data`. The checks `load_data` makes on a whole file are made here on its
    first rows, and on every window as it is read."""
    p = Path(path)
    file = p / SIMULATION_DATASET if p.is_dir() and (p / SIMULATION_DATASET).is_file() else p
    if not is_dataset_file(file):
        return load_data(p, config, joint_limits=joint_limits, require_all=require_all)
    try:
        run = DatasetFile(file, joint_limits)
    except NotStreamable:
        return load_data(p, config, joint_limits=joint_limits, require_all=require_all)
    head = run.slice(0, min(run.n_samples, HEAD_ROWS))
    check_matches_config(head, config, require_all=require_all, source=str(file))
    # the count is the file's, the rest its first rows'
    check_plausible(head, str(file), n_samples=run.n_samples, config=config)
    return run


def is_dataset_file(path: Path) -> bool:
    """A zip archive: a dataset file, or nothing dynid reads (`DatasetFile` says which)."""
    try:
        with open(path, "rb") as f:
            return f.read(4) == _ZIP_MAGIC
    except OSError:
        return False


class DatasetWriter:
    """A dataset file of `n_samples` rows written a chunk (a `Dataset` with the first chunk's channels) at a time.

    ``with DatasetWriter(path, n) as out: out.write(chunk) …``: the file appears, complete, when the block ends
    without an error and every row was written; otherwise nothing is left behind."""

    def __init__(self, path: str | Path, n_samples: int, meta: dict[str, Any] | None = None) -> None:
        self.path = Path(path)
        if not self.path.parent.is_dir():
            raise DataError(f"cannot write '{self.path}': the directory {self.path.parent} does not exist")
        self.n = int(n_samples)
        self.meta = dict(meta or {})
        self.written = 0
        self.joints: tuple[str, ...] = ()
        self._files: dict[str, Any] = {}
        self._tmp = Path(tempfile.mkdtemp(dir=self.path.parent, prefix=f".{self.path.name}."))

    def __enter__(self) -> DatasetWriter:
        return self

    def __exit__(self, kind: type | None, *_: object) -> None:
        try:
            if kind is None:
                self._finish()
        finally:
            for f in self._files.values():
                f.close()
            shutil.rmtree(self._tmp, ignore_errors=True)

    def write(self, chunk: Dataset) -> None:
        chunk.validate()
        arrays = {"t": chunk.t, "q": chunk.q, "dq": chunk.dq, "ddq": chunk.ddq, "contact": chunk.contact}
        for family in CHANNEL_FAMILIES:
            arrays.update({f"{family}/{k}": v for k, v in getattr(chunk, family).items()})
        arrays = {k: np.ascontiguousarray(v) for k, v in arrays.items() if v is not None}
        if not self._files:
            self.joints = chunk.joints
            for name, a in arrays.items():
                f = open(self._tmp / f"{len(self._files)}.npy", "wb")
                np.lib.format.write_array_header_1_0(f, {"descr": np.lib.format.dtype_to_descr(a.dtype),
                                                         "fortran_order": False, "shape": (self.n, *a.shape[1:])})
                self._files[name] = f
        if set(arrays) != set(self._files) or chunk.joints != self.joints:
            raise DataError(f"{self.path}: a chunk with other channels than the first one's")
        if self.written + chunk.n_samples > self.n:
            raise DataError(f"{self.path}: more than the {self.n} rows announced")
        for name, a in arrays.items():
            a.tofile(self._files[name])
        self.written += chunk.n_samples

    def _finish(self) -> None:
        if self.written != self.n:
            raise DataError(f"{self.path}: {self.written} rows written of the {self.n} announced")
        small = {"format": np.array(FORMAT_NAME), "format_version": np.array(FORMAT_VERSION, dtype=np.int64),
                 "meta": np.array(json.dumps(self.meta, sort_keys=True)), "joints": np.array(self.joints, dtype=str)}
        target = self._tmp / "out.npz"
        with zipfile.ZipFile(target, "w", zipfile.ZIP_STORED, allowZip64=True) as archive:
            for name, value in small.items():
                with archive.open(f"{name}.npy", "w") as f:
                    np.lib.format.write_array(f, value, allow_pickle=False)
            for name, f in self._files.items():
                f.close()
                archive.write(f.name, f"{name}.npy")
        with open(target, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(target, self.path)
