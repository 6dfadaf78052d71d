"""What a case of the hostile-input sweep is: a program, its arguments, the bad input, and the verdict expected."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .fixtures import Fixtures

# Writes a case's hostile input(s) into its input directory, from the session's good files.
Maker = Callable[["Fixtures", Path], None]


@dataclass(frozen=True)
class Case:
    """One run of one program on one bad input.

    `args` are templates: `{in}` is the case's input directory (what `make` wrote), `{out}` its output
    directory, and every other `{name}` a file of the session's `Fixtures` (`{run}`, `{csv}`, `{model}`, ...).
    A refusal (`code` not 0) must leave both directories as they were.
    """

    name: str
    program: str  # "dynid", "rt_monitor" or "boards"
    args: tuple[str, ...]
    code: int  # the exit code expected: 2 for dynid's bad input, the documented one for rt_monitor and boards
    says: str = ""  # words of the one line on stderr ("" with code 0: nothing on stderr)
    make: Maker | None = None
    synopsis: bool = False  # a C program's usage error: its one error line, then the synopsis (test_cli_help.py)
    prints: str = ""  # with code 0: words stdout must hold (a counter of what was skipped)
    warns: str = ""  # words of the program's one "warning:" line on stderr ("": none), e.g. where the skipped lines are
    creates: tuple[str, ...] = field(default_factory=tuple)  # with code 0: what it writes into {out}
    as_root: bool = True  # False: skipped when run as root (root reads a file of mode 000)


def dynid(name: str, *args: str, says: str, make: Maker | None = None, code: int = 2) -> Case:
    return Case(name, "dynid", args, code, says, make)


def unreadable(case: Case) -> Case:
    """The case on a file of mode 000 (its maker's work, then chmod): skipped as root, who reads it anyway."""
    return replace(case, as_root=False)


def monitor(name: str, *args: str, code: int, says: str, make: Maker | None = None, synopsis: bool = False,
            prints: str = "", warns: str = "") -> Case:
    return Case(name, "rt_monitor", args, code, says, make, synopsis, prints, warns=warns)


def boards(name: str, *args: str, code: int, says: str, make: Maker | None = None, synopsis: bool = False) -> Case:
    return Case(name, "boards", args, code, says, make, synopsis)


def accepted(case: Case, *creates: str, says: str = "", prints: str = "") -> Case:
    """A control: the same harness on an input that is fine (or only skipped in part), which must be accepted and
    write `creates`: it shows the sweep would see an output if a refusal left one."""
    return Case(case.name, case.program, case.args, 0, says, case.make, False, prints, case.warns, creates)
