"""Errors that end a command with one clear line and a distinct exit code.

Anything the user can get wrong (a file, a column, a flag, a configuration) raises an `InputError`; the CLI
prints its message on one line and exits with `exit_code`. Every other exception is a bug in dynid.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager

EXIT_BAD_INPUT = 2
# Control characters left once whitespace is folded: a file's bytes quoted in a message (a NUL or an ESC in a CSV
# header, a candump bus name) must not reach the terminal as they are, as the C readers escape them too.
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")


class InputError(Exception):
    """Bad input from the user: a file, a column, a configuration field, a flag."""

    exit_code: int = EXIT_BAD_INPUT

    def __init__(self, message: str) -> None:
        # One line, always: the CLI contract is "one clear line naming the problem"; other control characters are
        # shown as \xNN.
        line = " ".join(message.split())
        super().__init__(_CONTROL.sub(lambda m: f"\\x{ord(m.group()):02x}", line) or type(self).__name__)


class ConfigError(InputError):
    """A robot configuration that is wrong or incomplete; the message names the field."""


class DataError(InputError):
    """A data file (CSV, candump log, dataset) that cannot be used as it is."""


class PathError(DataError):
    """A file as the command line names it: not there, or named twice (nothing about how it would have been read)."""


class SetupError(InputError, ImportError):
    """A module scripts/setup generates is missing (a clone run without the set-up). An ImportError too: it is raised
    where that module is imported."""


@contextmanager
def made_by_setup(package: str, what: str) -> Iterator[None]:
    """Around the import of a module from `package` (`what` it is), which scripts/setup generates: where it is
    missing, a SetupError that says so in one line rather than a ModuleNotFoundError from deep inside. Any other
    missing module is raised as it is (a broken install is not a missing set-up)."""
    try:
        yield
    except ModuleNotFoundError as e:
        if e.name != package and not (e.name or "").startswith(package + "."):
            raise
        raise SetupError(f"{what} ({package}) is not generated: run scripts/setup") from None


class DataNote(UserWarning):
    """Not an error: something the data did that the user should know (a window cut where the run ends). The CLI
    prints it once on standard error as "dynid CMD: note: ..."; library callers see a warning."""
