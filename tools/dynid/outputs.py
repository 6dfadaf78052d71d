"""A command's outputs: each written whole or not at all, all put in place together, none left by a command that
fails or is interrupted.

`atomic_write` writes one file: to a temporary file beside it (the same directory, so the same file system), flushed
to disk, then renamed over it, so that a reader sees the old file or the new one whole. Within `staged()`, around
every `dynid` command (dynid.cli), the renames wait for the end: when the command succeeds, its outputs are put in
place together; when it fails or is interrupted, its temporary files are removed and the files it would have
replaced are left as they were. (A fit used to write its model and then fail on its --json, exit 2 with the model
left behind; `dynid fleet` interrupted left the robots' models without the page.) Once a Ctrl-C came
(dynid.interrupt.requested), even one that something swallowed, nothing is put in place.

`output_dir` makes an output directory; in a staged command, the directories it made are removed again (when
empty) if the command fails. `written_by` hands another program (`boards`, writing `dynid play`'s candump log) a
path to write an output at, in a directory of its own beside the output: the program's own temporary files stay
in there (boards killed by the Ctrl-C left its p.log.XXXXXX beside the log), and it is removed whatever happens.
`probe` creates and removes a temporary file where an output will be written: the check
before any work (dynid.cli.common.check_outputs) that it can be written at all (os.access says yes for root
anywhere: /proc, a read-only mount).

Layer: above errors and interrupt; the standard library only.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

from .errors import DataError
from .interrupt import requested, sigint_held


@dataclass
class Staging:
    """The outputs of one command, until it ends: put in place (`commit`) or discarded (`discard`)."""

    pid: int = field(default_factory=os.getpid)
    ready: list[tuple[Path, Path]] = field(default_factory=list)  # (temporary, output), in the order written
    temporaries: list[Path] = field(default_factory=list)  # every temporary file or directory made, ready or not
    made: list[Path] = field(default_factory=list)  # output directories made, parents first
    labels: dict[str, str] = field(default_factory=dict)  # an output's real path -> how the command names it
    inputs: dict[str, str] = field(default_factory=dict)  # a file the command reads (real path) -> what it is
    closed: bool = False

    def commit(self) -> None:
        """Put every output in place, in the order written. Each file an output replaces is first linked to a backup
        beside it: should a rename fail (rare: the same directory as the temporary file made before), the outputs
        put in place are taken back and the files they replaced restored, and the rest discarded."""
        with sigint_held():
            if self.closed or self.pid != os.getpid():  # a forked child never commits its parent's outputs
                return
            if self.ready and requested():  # a Ctrl-C came and was swallowed somewhere: the command was interrupted
                self.discard()
                raise KeyboardInterrupt
            placed: list[tuple[Path, Path | None]] = []  # (output, the backup of the file it replaced)
            failed = None
            try:
                for tmp, failed in self.ready:
                    backup = None
                    if failed.is_file():
                        backup = failed.with_name(f".{failed.name}.{os.getpid()}.bak")
                        try:
                            os.link(failed, backup)
                            self.temporaries.append(backup)
                        except OSError:  # no hard links here (vfat, some network mounts): replaced without one
                            backup = None
                    os.replace(tmp, failed)
                    placed.append((failed, backup))
            except OSError as e:
                for output, backup in reversed(placed):
                    with contextlib.suppress(OSError):
                        if backup is None:
                            output.unlink()
                        else:
                            os.replace(backup, output)
                self.discard()
                raise DataError(f"cannot write {_named(failed, self)}: {e.strerror or e}") from None
            self._remove_temporaries()
            self.closed = True

    def discard(self) -> None:
        """Remove every temporary file and directory, and the output directories made (when empty)."""
        with sigint_held():
            if self.closed or self.pid != os.getpid():
                return
            self._remove_temporaries()
            for d in reversed(self.made):
                with contextlib.suppress(OSError):
                    d.rmdir()
            self.closed = True

    def _remove_temporaries(self) -> None:
        for tmp in self.temporaries:
            if tmp.is_dir() and not tmp.is_symlink():
                shutil.rmtree(tmp, ignore_errors=True)
            else:
                with contextlib.suppress(OSError):
                    tmp.unlink()


_current: Staging | None = None


def _active() -> Staging | None:
    """The command's staging, in the process that opened it (a forked worker writes as if unstaged)."""
    s = _current
    return s if s is not None and not s.closed and s.pid == os.getpid() else None


@contextlib.contextmanager
def staged() -> Iterator[Staging]:
    """Stage the outputs written in the block: put in place when it ends without an exception, discarded when it
    raises (KeyboardInterrupt included). Within an open staging, the block joins it."""
    global _current
    outer = _active()
    if outer is not None:
        yield outer
        return
    s = _current = Staging()
    try:
        yield s
        s.commit()
    except BaseException:
        s.discard()
        raise
    finally:
        if _current is s and s.closed:  # else (interrupted on the way) discard_unfinished has it
            _current = None


def discard_unfinished() -> None:
    """Discard a staging that an interrupt left open (a Ctrl-C between the end of the block and its commit)."""
    s = _current
    if s is not None and s.pid == os.getpid():
        s.discard()


def label(path: str | Path, name: str) -> None:
    """Name the output `path` as the command does ('--json'): messages about it say so."""
    s = _active()
    if s is not None:
        s.labels[os.path.realpath(path)] = name


def note_input(path: str | Path, what: str) -> None:
    """Name a file the command reads that no option of its names outright ('the robot configuration', its URDF): an
    output on it is refused (exit 2, nothing written) instead of replacing it."""
    s = _active()
    if s is not None and str(path):
        s.inputs.setdefault(os.path.realpath(path), what)


def _named(path: Path, s: Staging | None) -> str:
    name = s.labels.get(os.path.realpath(path)) if s is not None else None
    return f"'{path}'" + (f" ({name})" if name else "")


def _umask() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return umask


def _check_target(path: Path, s: Staging | None) -> None:
    if not path.name or not path.parent.is_dir():
        raise DataError(f"cannot write {_named(path, s)}: the directory {path.parent} does not exist")
    if path.exists() and not path.is_file():  # never replace a directory, a device or a pipe
        raise DataError(f"cannot write {_named(path, s)}: it exists and is not a regular file")
    if s is not None and (what := s.inputs.get(os.path.realpath(path))):
        raise DataError(f"cannot write {_named(path, s)}: it is {what}, which the command reads")


def atomic_write(path: str | Path, write: Callable[[BinaryIO], None]) -> None:
    """Write a file through `write(binary_file)` so that `path` is either the old file or the complete new one (in
    a staged command: put in place when the command succeeds). On any failure the temporary file is removed."""
    path = Path(path)
    s = _active()
    _check_target(path, s)
    try:
        with sigint_held():  # the temporary file is known to the staging from the moment it exists
            fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
            tmp = Path(name)
            if s is not None:
                s.temporaries.append(tmp)
    except OSError as e:
        raise DataError(f"cannot write {_named(path, s)}: {e.strerror or e}") from None
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the file the usual permissions
        if s is not None:
            s.ready.append((tmp, path))
        else:
            os.replace(tmp, path)
    except BaseException as e:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(e, OSError):
            raise DataError(f"cannot write {_named(path, s)}: {e.strerror or e}") from None
        raise


@contextlib.contextmanager
def written_by(path: str | Path) -> Iterator[Path]:
    """A path at which another program writes the output `path`: a file in a new directory beside it, put in place
    as atomic_write's are when the block ends without an exception (at the command's end, in a staged command).
    Whatever the program leaves in that directory (its own temporary files, if it is killed) goes with it."""
    path = Path(path)
    s = _active()
    _check_target(path, s)
    try:
        with sigint_held():
            d = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp"))
            if s is not None:
                s.temporaries.append(d)
    except OSError as e:
        raise DataError(f"cannot write {_named(path, s)}: {e.strerror or e}") from None
    inner = d / path.name
    try:
        yield inner
        if not inner.is_file():
            raise DataError(f"cannot write {_named(path, s)}: nothing was written")
        if s is not None:
            s.ready.append((inner, path))
        else:
            os.replace(inner, path)
            shutil.rmtree(d, ignore_errors=True)
    except BaseException as e:
        shutil.rmtree(d, ignore_errors=True)
        if isinstance(e, OSError):
            raise DataError(f"cannot write {_named(path, s)}: {e.strerror or e}") from None
        raise


def output_dir(path: str | Path) -> Path:
    """Make the output directory `path` and its missing parents; in a staged command, those made are removed
    again (when empty) if the command fails."""
    path = Path(path)
    missing = [p for p in (path, *path.parents) if not p.exists()][::-1]  # parents first
    s = _active()
    if s is not None:
        s.made.extend(missing)  # known before they exist: an interrupt between the two leaves none
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise DataError(f"cannot create the output directory {_named(path, s)}: {e.strerror or e}") from None
    return path


def probe(directory: str | Path, as_directory: bool = False) -> str | None:
    """Why no file (or, `as_directory`, no directory) can be created in `directory`, or None: one is created, as
    atomic_write creates its temporary file, and removed."""
    try:
        with sigint_held():
            if as_directory:
                os.rmdir(tempfile.mkdtemp(dir=directory, prefix=".dynid-probe.", suffix=".tmp"))
            else:
                fd, name = tempfile.mkstemp(dir=directory, prefix=".dynid-probe.", suffix=".tmp")
                os.close(fd)
                os.unlink(name)
    except OSError as e:
        return e.strerror or str(e)
    return None
