"""The experiment dataset: one in-memory structure, one on-disk format, and the loader of every data form.

Every data source (a CSV of docs/design.md §4, a candump log, a simulation) becomes a `Dataset`; identification,
validation, detection and the gap workflow only ever see a `Dataset`.

On-disk format (version 1)
--------------------------
An uncompressed ``numpy.savez`` archive (``.npz``) read with ``allow_pickle=False``; every member is a plain
numeric or unicode array::

    format          ()          str      "dynid-dataset"
    format_version  ()          int64    1
    meta            ()          str      JSON object (robot name, config digest, source file, notes, ...)
    joints          (J,)        str      column order of q, dq, ddq
    t               (N,)        float64  s, strictly increasing
    q               (N, J)      float64  rad (m for prismatic joints)
    dq, ddq         (N, J)      float64  optional: absent when not recorded and not yet estimated
    contact         (N,)        uint8    optional: ground truth, 0/1
    pwm/<motor>     (N,)        float64  duty fraction in [-1, 1]
    current/<motor> (N,)        float64  A
    tau/<joint>     (N,)        float64  Nm, measured joint torque
    ft/<sensor>     (N, 6)      float64  [fx fy fz tx ty tz], N and Nm
    extra/<name>    (N,)        float64  any other column, kept verbatim

The members of a channel family keep their order in the archive. A reader refuses a file whose
``format_version`` is newer than the one it knows. Files are written atomically (a temporary file in the
same directory, then ``os.replace``): a crash never leaves a half-written dataset.

Rows in messages are 1-based sample numbers.
"""

from __future__ import annotations

import inspect
import json
import math
import zipfile
import zlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import DataError, PathError
from ..outputs import atomic_write  # re-exported: where the writers have always imported it from
from .derivatives import estimate_derivatives

if TYPE_CHECKING:
    pass

FORMAT_NAME = "dynid-dataset"
FORMAT_VERSION = 1
FT_CHANNELS: tuple[str, ...] = ("fx", "fy", "fz", "tx", "ty", "tz")
CHANNEL_FAMILIES: tuple[str, ...] = ("pwm", "current", "tau", "ft", "extra")

_ZIP_MAGIC = b"PK\x03\x04"
SIMULATION_DATASET = "dataset.npz"  # what a `dynid simulate` output directory holds for DATA
TRUTH_FORMAT = "dynid-truth"  # its truth.json's "format"


def _row(i: int) -> str:
    return f"row {i + 1}"


@dataclass
class Dataset:
    """One experiment, sampled at times `t`, with the joint order of the robot configuration.

    Optional signals are ``None`` (dq, ddq, contact) or absent from their dict (pwm, current, tau, ft, extra).
    """

    t: np.ndarray  # (N,) s, strictly increasing
    joints: tuple[str, ...]  # column order of q/dq/ddq (the configuration's joint order)
    q: np.ndarray  # (N, J) rad (m for prismatic)
    dq: np.ndarray | None = None  # recorded or estimated; None when absent
    ddq: np.ndarray | None = None
    pwm: dict[str, np.ndarray] = field(default_factory=dict)  # motor -> (N,) duty in [-1, 1]
    current: dict[str, np.ndarray] = field(default_factory=dict)  # motor -> (N,) A
    tau: dict[str, np.ndarray] = field(default_factory=dict)  # joint -> (N,) Nm
    ft: dict[str, np.ndarray] = field(default_factory=dict)  # sensor -> (N, 6) [fx fy fz tx ty tz]
    contact: np.ndarray | None = None  # (N,) uint8 0/1 ground truth
    extra: dict[str, np.ndarray] = field(default_factory=dict)  # any other numeric column, verbatim
    meta: dict[str, Any] = field(default_factory=dict)  # JSON-able provenance

    def __post_init__(self) -> None:
        # Normalise types once so every consumer can rely on float64 arrays and a tuple of names.
        self.joints = tuple(self.joints)
        self.t = np.asarray(self.t, dtype=float)
        self.q = np.asarray(self.q, dtype=float)
        if self.dq is not None:
            self.dq = np.asarray(self.dq, dtype=float)
        if self.ddq is not None:
            self.ddq = np.asarray(self.ddq, dtype=float)
        for family in CHANNEL_FAMILIES:
            setattr(self, family, {str(k): np.asarray(v, dtype=float) for k, v in getattr(self, family).items()})
        if self.contact is not None:
            self.contact = (np.asarray(self.contact) != 0).astype(np.uint8)
        self.meta = dict(self.meta)

    # ------------------------------------------------------------------------------------------------------
    # Shape and content

    @property
    def n_samples(self) -> int:
        return int(self.t.shape[0])

    @property
    def n_joints(self) -> int:
        return len(self.joints)

    @property
    def duration(self) -> float:
        """t[-1] - t[0], s (0 for a single sample)."""
        return float(self.t[-1] - self.t[0]) if self.n_samples else 0.0

    def median_step(self) -> float:
        """The median sample period, s (1 for a single sample)."""
        return float(np.median(np.diff(self.t))) if self.n_samples > 1 else 1.0

    def times(self, start: int, stop: int) -> np.ndarray:
        """t of rows [start, stop) (what `dynid.io.stream.DatasetFile` reads from disk)."""
        return self.t[start:stop]

    def column_names(self) -> list[str]:
        """CSV column names (docs/design.md §4) of every signal held, in the canonical order."""
        return [name for name, _ in self.columns()]

    def columns(self) -> list[tuple[str, np.ndarray]]:
        """(CSV column name, (N,) values) for every signal held, in the order of `column_names`."""
        cols: list[tuple[str, np.ndarray]] = [("t", self.t)]
        for kind, values in (("q", self.q), ("dq", self.dq), ("ddq", self.ddq)):
            if values is not None:
                cols += [(f"{kind}.{j}", values[:, i]) for i, j in enumerate(self.joints)]
        cols += [(f"pwm.{m}", v) for m, v in self.pwm.items()]
        cols += [(f"current.{m}", v) for m, v in self.current.items()]
        cols += [(f"tau.{j}", v) for j, v in self.tau.items()]
        cols += [(f"ft.{s}.{c}", v[:, k]) for s, v in self.ft.items() for k, c in enumerate(FT_CHANNELS)]
        if self.contact is not None:
            cols.append(("contact", self.contact))
        return cols + list(self.extra.items())

    def validate(self) -> Dataset:
        """Check shapes, finiteness and strictly increasing time; raise `DataError` naming the first problem.

        Returns the dataset itself, so that ``Dataset(...).validate()`` chains.
        """
        if self.t.ndim != 1 or self.t.size == 0:
            raise DataError(f"t must be a non-empty 1-D array, got shape {self.t.shape}")
        n = self.n_samples
        if not self.joints or len(set(self.joints)) != len(self.joints) or not all(self.joints):
            raise DataError(f"joints must be distinct non-empty names, got {list(self.joints)}")
        for name, values in (("q", self.q), ("dq", self.dq), ("ddq", self.ddq)):
            if values is not None and values.shape != (n, self.n_joints):
                raise DataError(f"{name} must have shape ({n}, {self.n_joints}) (samples, joints), got {values.shape}")
        for family in CHANNEL_FAMILIES:
            shape = (n, 6) if family == "ft" else (n,)
            for key, values in getattr(self, family).items():
                if not key:
                    raise DataError(f"{family} has a channel with an empty name")
                if values.shape != shape:
                    raise DataError(f"{family}.{key} must have shape {shape}, got {values.shape}")
        unknown = [j for j in self.tau if j not in self.joints]
        if unknown:
            raise DataError(f"tau.{unknown[0]} names a joint that is not in the dataset's joints {list(self.joints)}")
        if self.contact is not None and self.contact.shape != (n,):
            raise DataError(f"contact must have shape ({n},), got {self.contact.shape}")
        for name, values in self.columns():
            bad = np.flatnonzero(~np.isfinite(values))
            if bad.size:
                raise DataError(f"{name} is {values[bad[0]]} at {_row(int(bad[0]))}: every value must be finite")
        steps = np.flatnonzero(np.diff(self.t) <= 0)
        if steps.size:
            i = int(steps[0]) + 1
            raise DataError(
                f"t is not strictly increasing at {_row(i)}: "
                f"{float(self.t[i])!r} s follows {float(self.t[i - 1])!r} s at {_row(i - 1)}"
            )
        try:
            json.dumps(self.meta, allow_nan=False)
        except (TypeError, ValueError) as e:
            raise DataError(f"meta must be JSON-serialisable: {e}") from None
        return self

    # ------------------------------------------------------------------------------------------------------
    # Derived datasets

    def slice(self, start: int | None, stop: int | None) -> Dataset:
        """Rows [start, stop) as a new dataset (Python slice semantics, negative indices allowed).

        ``meta["rows"]`` records the rows of the original dataset that were kept, composed over repeated slices.
        """
        lo, hi, _ = slice(start, stop).indices(self.n_samples)
        if hi <= lo:
            raise DataError(f"rows [{start}, {stop}) select no sample of a dataset of {self.n_samples}")
        rows = slice(lo, hi)
        meta = dict(self.meta)
        offset = meta.get("rows", [0, self.n_samples])[0]
        meta["rows"] = [offset + lo, offset + hi]
        return Dataset(
            t=self.t[rows].copy(),
            joints=self.joints,
            q=self.q[rows].copy(),
            dq=None if self.dq is None else self.dq[rows].copy(),
            ddq=None if self.ddq is None else self.ddq[rows].copy(),
            pwm={k: v[rows].copy() for k, v in self.pwm.items()},
            current={k: v[rows].copy() for k, v in self.current.items()},
            tau={k: v[rows].copy() for k, v in self.tau.items()},
            ft={k: v[rows].copy() for k, v in self.ft.items()},
            contact=None if self.contact is None else self.contact[rows].copy(),
            extra={k: v[rows].copy() for k, v in self.extra.items()},
            meta=meta,
        )

    def with_derivatives(self, estimator: str | Callable[..., Any] | None = None, **options: Any) -> Dataset:
        """A copy whose missing dq and/or ddq are estimated from q; recorded ones are kept.

        Parameters
        ----------
        estimator
            None for the default method of `dynid.io.derivatives.estimate_derivatives`, a method name passed to
            it, or a callable ``f(t, q, **options)`` returning an object with ``dq`` and ``ddq`` attributes.
        options
            Passed to the estimator.

        ``meta["derivatives"]`` records where each came from: ``"recorded"`` or the estimator's name.
        """
        if self.dq is not None and self.ddq is not None:  # nothing to estimate; keep any earlier record
            meta = {"derivatives": {"dq": "recorded", "ddq": "recorded"}, **self.meta}
            return replace(self, meta=meta)
        if callable(estimator):
            method = getattr(estimator, "__name__", type(estimator).__name__)
            result = estimator(self.t, self.q, **options)
        else:
            if estimator is None:  # the estimator's own default method, recorded by name
                estimator = inspect.signature(estimate_derivatives).parameters["method"].default
            method = str(estimator)
            result = estimate_derivatives(self.t, self.q, method=method, **options)
        dq = self.dq if self.dq is not None else np.asarray(result.dq, dtype=float)
        ddq = self.ddq if self.ddq is not None else np.asarray(result.ddq, dtype=float)
        if dq.shape != self.q.shape or ddq.shape != self.q.shape:
            raise ValueError(f"estimator {method} returned shapes {dq.shape}, {ddq.shape}; expected {self.q.shape}")
        meta = dict(self.meta)
        meta["derivatives"] = {
            "dq": "recorded" if self.dq is not None else method,
            "ddq": "recorded" if self.ddq is not None else method,
            **({"options": json.loads(json.dumps(options, default=str))} if options else {}),
        }
        return replace(self, dq=dq, ddq=ddq, meta=meta)

    # ------------------------------------------------------------------------------------------------------
    # Disk

    def save(self, path: str | Path) -> None:
        """Write the dataset (format in the module docstring) atomically; validates first."""
        self.validate()
        arrays: dict[str, np.ndarray] = {
            "format": np.array(FORMAT_NAME),
            "format_version": np.array(FORMAT_VERSION, dtype=np.int64),
            "meta": np.array(json.dumps(self.meta, sort_keys=True)),
            "joints": np.array(self.joints, dtype=str),
            "t": self.t,
            "q": self.q,
        }
        if self.dq is not None:
            arrays["dq"] = self.dq
        if self.ddq is not None:
            arrays["ddq"] = self.ddq
        if self.contact is not None:
            arrays["contact"] = self.contact
        for family in CHANNEL_FAMILIES:
            arrays.update({f"{family}/{k}": v for k, v in getattr(self, family).items()})
        atomic_write(path, lambda f: np.savez(f, **arrays))

    @classmethod
    def load(cls, path: str | Path) -> Dataset:
        """Read a dataset file; a missing, corrupt or foreign file raises `DataError` with one line."""
        path = Path(path)
        if not path.is_file():
            raise PathError(f"dataset file not found: {path}")
        with open(path, "rb") as f:
            if f.read(4) != _ZIP_MAGIC:
                raise DataError(f"{path}: not a dynid dataset (.npz): the file is not a zip archive")
        try:
            _check_members(path)
            with np.load(path, allow_pickle=False) as z:
                members = {name: z[name] for name in z.files}
        # zlib.error: a corrupt deflated member; NotImplementedError, RuntimeError: a compression method zipfile
        # does not have, an encrypted member (flipped bits in a member's flags).
        except (zipfile.BadZipFile, zlib.error, NotImplementedError, RuntimeError, OSError, EOFError) as e:
            raise DataError(f"{path}: not a dynid dataset (.npz) or a corrupt one: {e}") from None
        except ValueError as e:  # object arrays (pickles) are refused
            raise DataError(f"{path}: not a dynid dataset: {e}") from None
        if str(members.get("format", "")) != FORMAT_NAME:
            raise DataError(f"{path}: not a dynid dataset (no '{FORMAT_NAME}' format marker)")
        try:
            version = int(members["format_version"])
        except (KeyError, TypeError, ValueError, OverflowError):  # OverflowError: an infinite version
            raise DataError(f"{path}: dataset has no valid format_version") from None
        if version > FORMAT_VERSION or version < 1:
            raise DataError(
                f"{path}: dataset format version {version} is not supported (this dynid reads 1..{FORMAT_VERSION})"
            )
        try:
            return cls._from_members(members).validate()
        except DataError as e:
            raise DataError(f"{path}: corrupt dataset: {e}") from None

    @classmethod
    def _from_members(cls, m: dict[str, np.ndarray]) -> Dataset:
        for key in ("t", "q", "joints", "meta"):
            if key not in m:
                raise DataError(f"member '{key}' is missing")
        for key, value in m.items():
            if not isinstance(value, np.ndarray):
                raise DataError(f"member '{key}' is not an array")
            if key not in ("format", "meta", "joints") and value.dtype.kind not in "fiub":
                raise DataError(f"member '{key}' is not numeric ({value.dtype})")
        try:
            meta = json.loads(str(m["meta"]))
        # ValueError: JSONDecodeError, or an integer of more than 4300 digits; RecursionError: arrays nested deep
        except (ValueError, RecursionError):
            raise DataError("member 'meta' is not JSON") from None
        if not isinstance(meta, dict):
            raise DataError("member 'meta' is not a JSON object")
        rows = meta.get("rows", [0, 0])  # what `slice` composes: text there ended a --from/--to in a TypeError
        if not (isinstance(rows, list) and len(rows) == 2 and all(type(r) is int and r >= 0 for r in rows)):
            raise DataError(f"member 'meta': rows must be [start, stop] sample numbers, got {str(rows)[:40]}")
        if m["joints"].ndim != 1 or m["joints"].dtype.kind != "U":
            raise DataError(f"member 'joints' must be a list of names, got {m['joints'].dtype} {m['joints'].shape}")
        families: dict[str, dict[str, np.ndarray]] = {f: {} for f in CHANNEL_FAMILIES}
        for key, value in m.items():
            family, _, name = key.partition("/")
            if family in families and name:
                families[family][name] = value
            elif key not in ("format", "format_version", "meta", "joints", "t", "q", "dq", "ddq", "contact"):
                raise DataError(f"unknown member '{key}'")
        return cls(
            t=m["t"],
            joints=tuple(str(j) for j in m["joints"]),
            q=m["q"],
            dq=m.get("dq"),
            ddq=m.get("ddq"),
            contact=m.get("contact"),
            meta=meta,
            **families,
        )


_MAX_DEFLATE_RATIO = 1032  # what zlib's deflate can expand to at most, per compressed byte


def _check_members(path: Path) -> None:
    """Refuse a member whose array header claims more data than the member can hold, before numpy reads it.

    numpy allocates the array an .npy header describes before it reads the data: one flipped bit in a shape asked
    for terabytes (MemoryError). Object arrays are refused here too, unread. Raises ValueError naming the member.
    """
    on_disk = path.stat().st_size
    with zipfile.ZipFile(path) as archive:
        for info in archive.infolist():
            ratio = 1 if info.compress_type == zipfile.ZIP_STORED else _MAX_DEFLATE_RATIO
            room = min(info.file_size, ratio * min(info.compress_size, on_disk))
            with archive.open(info.filename) as f:
                version = np.lib.format.read_magic(f)
                if version not in ((1, 0), (2, 0)):  # what np.savez writes for numeric and unicode arrays
                    raise ValueError(f"member '{info.filename}' has an .npy header of version {version}")
                read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
                shape, _, dtype = read(f)
                if dtype.hasobject:
                    raise ValueError(f"member '{info.filename}' holds Python objects, which are never loaded")
                if math.prod(shape) * dtype.itemsize > room - f.tell():
                    raise ValueError(f"member '{info.filename}' claims shape {shape} of {dtype}, more than it holds")


# ----------------------------------------------------------------------------------------------------------
# Helpers shared by the readers and writers


def beside_run(data: str | Path, name: str) -> Path:
    """The file `name` that `dynid simulate` writes next to a run's data (truth.json, truth.npz), for DATA given
    as the run's directory or one of its files."""
    p = Path(data)
    return (p if p.is_dir() else p.parent) / name


def contact_episodes(contact: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) sample ranges where the skin's ground truth (or any mask) is non-zero."""
    edges = np.flatnonzero(np.diff(np.r_[0, (np.asarray(contact) != 0).astype(np.int8), 0]))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def check_units(
    dataset: Dataset,
    joint_limits: Mapping[str, tuple[float, float]] | None = None,
    row: Callable[[int], str] = _row,
) -> None:
    """Refuse values in the wrong unit: PWM as board counts, joint angles in degrees.

    Parameters
    ----------
    joint_limits
        joint -> (lower, upper), e.g. `RobotModel.joint_limits`. A joint beyond its limits by more than
        0.2 rad plus 10 % of its range is taken to be in degrees. Joints with non-finite limits are skipped.
    row
        Formats a 0-based sample index for the message (the CSV reader adds the file line).
    """
    for motor, values in dataset.pwm.items():
        if values.size and np.max(np.abs(values)) > 1.0:
            i = int(np.argmax(np.abs(values)))
            raise DataError(
                f"pwm.{motor} reaches {values[i]:g} at {row(i)}: "
                "duty fractions in [-1, 1] are expected, not board counts"
            )
    for k, joint in enumerate(dataset.joints):
        if joint_limits is None or joint not in joint_limits:
            continue
        lower, upper = (float(x) for x in joint_limits[joint])
        if not (np.isfinite(lower) and np.isfinite(upper)) or upper <= lower:
            continue
        margin = 0.2 + 0.1 * (upper - lower)
        q = dataset.q[:, k]
        excess = np.maximum(lower - q, q - upper)
        i = int(np.argmax(excess))
        if excess[i] > margin:
            # beyond a turn, degrees (or another unit); within one, a posture the joint cannot take
            why = ("it looks like degrees, radians are expected (metres for a prismatic joint)"
                   if abs(q[i]) > 2 * np.pi else
                   "not a posture this joint reaches (another robot's or joint's column, or a wrong offset?)")
            raise DataError(
                f"q.{joint} reaches {q[i]:g} at {row(i)}, outside its limits [{lower:g}, {upper:g}] by more than "
                f"{margin:.3g}: {why}"
            )
