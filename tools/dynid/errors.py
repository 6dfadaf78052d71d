"""Errors that end a command with one clear line and a distinct exit code.

Anything the user can get wrong (a file, a column, a flag, a configuration) raises an `InputError`; the CLI
prints its message on one line and exits with `exit_code`. Every other exception is a bug in dynid.
"""

from __future__ import annotations

EXIT_BAD_INPUT = 2


class InputError(Exception):
    """Bad input from the user: a file, a column, a configuration field, a flag."""

    exit_code: int = EXIT_BAD_INPUT

    def __init__(self, message: str) -> None:
        # One line, always: the CLI contract is "one clear line naming the problem".
        super().__init__(" ".join(message.split()))


class ConfigError(InputError):
    """A robot configuration that is wrong or incomplete; the message names the field."""


class DataError(InputError):
    """A data file (CSV, candump log, dataset) that cannot be used as it is."""
