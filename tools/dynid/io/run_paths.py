"""Many runs named at once: `--data` takes a run, a glob, a folder of runs, or `@LIST` (a file of such, one a line).

A run is a data file (.csv, .txt, .npz, .log, .mcap, .db3), a `dynid simulate` directory, a YARP dumper folder,
a rosbag2 folder (with its metadata.yaml) or a folder the caller's `run_folder` accepts (a logger's folder of files
that the robot's configuration describes: dynid.io.file_set). A folder that is none of these stands for every run
beneath it, in sorted order, at any depth (README and LICENSE files, whatever their suffix, a run's episode labels
`*.episodes.csv`, and anything else are passed over); a glob for every path it matches,
sorted, each expanded the same way. In a list file, blank lines and `#` comments are skipped and relative paths
are relative to the list's folder. A glob, folder or list that yields no run is refused with one line.

A run may be named `NAME=PATH` (`dynid fleet`: the robot it was recorded on); unnamed, it belongs to the folder
that holds it (a fleet laid out one folder per robot).
"""

from __future__ import annotations

import glob
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..errors import DataError, PathError
from .dataset import SIMULATION_DATASET
from .yarp import is_dumper_folder

DATA_SUFFIXES = (".csv", ".txt", ".npz", ".log", ".mcap", ".db3")
EPISODES_SUFFIX = ".episodes.csv"  # a run's contact labels beside it (docs/formats.md, "Episodes CSV")
_GLOB = set("*?[")


@dataclass(frozen=True)
class NamedRun:
    path: str
    name: str  # the NAME of NAME=PATH, else the name of the folder holding the run


RunFolder = Callable[[Path], bool]  # a folder that is one run of the robot's own form


def is_run(path: Path, run_folder: RunFolder | None = None) -> bool:
    if path.is_file():  # a README_cpp.txt or a LICENSE.txt beside the runs is no run, nor a run's episode labels
        name = path.name.lower()
        return (path.suffix.lower() in DATA_SUFFIXES and not name.startswith(("readme", "license"))
                and not name.endswith(EPISODES_SUFFIX))
    return path.is_dir() and ((path / SIMULATION_DATASET).is_file() or (path / "metadata.yaml").is_file()
                              or is_dumper_folder(path) or (run_folder is not None and run_folder(path)))


def _folder(path: Path, run_folder: RunFolder | None) -> list[Path]:
    out: list[Path] = []
    for entry in sorted(path.iterdir()):
        if is_run(entry, run_folder):
            out.append(entry)
        elif entry.is_dir():
            out.extend(_folder(entry, run_folder))
    return out


def expand(spec: str, base: Path | None = None, run_folder: RunFolder | None = None) -> list[Path]:
    """The runs `spec` names (module docstring), in order."""
    if spec.startswith("@"):
        listing = Path(spec[1:]) if base is None or Path(spec[1:]).is_absolute() else base / spec[1:]
        try:
            lines = listing.read_text().splitlines()
        except (OSError, UnicodeDecodeError) as e:
            raise DataError(f"--data {spec}: cannot read the list of runs: {getattr(e, 'strerror', None) or e}") from None
        out = [run for line in lines if (entry := line.split("#", 1)[0].strip())
               for run in expand(entry, listing.parent, run_folder)]
        if not out:
            raise DataError(f"--data {spec}: the list names no run")
        return out
    path = Path(spec) if base is None or Path(spec).is_absolute() else base / spec
    if _GLOB & set(spec):
        matches = [Path(m) for m in sorted(glob.glob(str(path)))]
        out = [run for m in matches
               for run in ([m] if is_run(m, run_folder) else _folder(m, run_folder) if m.is_dir() else [])]
        if not out:
            raise DataError(f"--data {spec}: the pattern matches no run")
        return out
    if path.is_dir() and not is_run(path, run_folder):
        out = _folder(path, run_folder)
        if not out:
            raise DataError(f"--data {spec}: the folder holds no run (data files {', '.join(DATA_SUFFIXES)}, "
                            "`dynid simulate` directories, YARP or rosbag2 folders)")
        return out
    return [path]  # a run, or a missing path: the reader names the problem


def expand_all(specs: list[str]) -> list[str]:
    """Every `--data` expanded, in order; a run named twice is refused (it would count twice)."""
    out = [str(p) for spec in specs for p in expand(spec)]
    seen: set[str] = set()
    for p in out:
        key = str(Path(p).resolve())
        if key in seen:
            raise PathError(f"--data: the run {p} is named twice")
        seen.add(key)
    return out


def expand_named(specs: list[str], run_folder: RunFolder | None = None) -> list[NamedRun]:
    """`expand_all` with each run's robot: NAME of NAME=PATH, else the folder that holds the run."""
    out = []
    for spec in specs:
        name, eq, rest = spec.partition("=")
        named = bool(eq) and name and not Path(spec).exists() and "/" not in name
        for p in expand(rest if named else spec, run_folder=run_folder):
            # the folder as given, not where a symlink in it points (a lab's runs linked from a shared store)
            out.append(NamedRun(str(p), name if named else (Path(os.path.abspath(p)).parent.name or str(p))))
    expand_all([r.path for r in out])  # the duplicate check
    return out
