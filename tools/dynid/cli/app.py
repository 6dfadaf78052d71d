"""The `dynid` command line itself: the parser (only the running command's group is built) and `run`, which
`dynid.cli.main` calls inside its Ctrl-C protection (this module's imports are the heavy ones: numpy, the
configurations).

Bad input of any kind ends with exit code 2 and one line on stderr naming the problem (docs/design.md §7).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import select
import signal
import sys
import warnings
import xml.etree.ElementTree as ET
from typing import TextIO
from collections.abc import Callable

from ..config.robot_config import DEFAULT_ROBOT, bundled_configs
from ..errors import EXIT_BAD_INPUT, DataError, DataNote, InputError, PathError
from ..outputs import staged
from ..version import __version__
from .commands import COMMANDS
from .common import Parser, check_outputs, split_data_windows, write_json

__all__ = ["build_parser", "run"]


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The `dynid` parser. With `command`, only its group's parsers are built (and their modules loaded); the other
    commands stand in by name and help, which is all `dynid --help` shows."""
    p = Parser(
        prog="dynid",
        description="Identify a robot arm's inertia, F/T offsets, friction and motor gains in one regression "
        "(Traversaro et al., Humanoids 2013), and monitor contacts.",
        epilog=f"bundled robots: {', '.join(bundled_configs())}. Bad input exits with code 2.",
    )
    p.add_argument("--version", action="version", version=f"dynid {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND", parser_class=Parser)
    chosen = COMMANDS[command].group if command in COMMANDS else None
    built = False
    for name, c in COMMANDS.items():
        if c.group != chosen:
            sub.add_parser(name, help=c.help)
        elif not built:
            importlib.import_module(f"{__package__}.{c.group}").add_commands(sub)
            built = True
    return p


def _command(argv: list[str]) -> str | None:
    """The command word of argv (the first argument that is not an option), if any."""
    return next((a for a in argv if not a.startswith("-")), None)


def _notes(command: str, default: Callable[..., None]) -> Callable[..., None]:
    """warnings.showwarning that prints a DataNote as one line, 'dynid CMD: note: ...', and leaves the rest."""
    def show(message, category, filename, lineno, file=None, line=None) -> None:  # noqa: ANN001
        if issubclass(category, DataNote):
            sys.stderr.write(f"dynid {command}: note: {message}\n")
        else:
            default(message, category, filename, lineno, file, line)

    return show


def _reader_gone(stream: TextIO) -> bool:
    """Whether `stream` is a pipe whose reading end is closed (poll reports an error on the writing end)."""
    try:
        poll = select.poll()
        poll.register(stream.fileno(), select.POLLOUT)
        return any(events & (select.POLLERR | select.POLLHUP) for _, events in poll.poll(0))
    except (OSError, ValueError, AttributeError):
        return False


def _default_robot_note(args: argparse.Namespace, argv: list[str], error: InputError) -> str:
    """Where data did not fit the robot configuration and none was named, that the default robot's was used: a user of
    another robot who forgot --robot reads the error against a configuration they never chose."""
    given = any(a == "--robot" or a.startswith("--robot=") for a in argv)
    if (not isinstance(error, DataError) or isinstance(error, PathError) or given
            or getattr(args, "robot", None) != DEFAULT_ROBOT
            or getattr(args, "model", None) or getattr(args, "print", None)):  # a model, a coefficient file: their own
        return ""
    return f" (read as {DEFAULT_ROBOT}'s, the default robot: --robot names yours)"


def run(argv: list[str]) -> int:
    """`dynid ARGV`: the exit code. Ctrl-C (KeyboardInterrupt) is dynid.cli.main's to answer."""
    try:  # the command's group is imported here: its modules may need what scripts/setup generates (SetupError)
        parser = build_parser(_command(argv))
    except InputError as e:
        sys.stderr.write(f"dynid {_command(argv)}: error: {e}\n")
        return e.exit_code
    args, unknown = parser.parse_known_args(argv)
    if unknown:  # named by the command they were given to, as its other usage errors are
        sys.stderr.write(f"dynid {args.command}: error: unrecognized arguments: {' '.join(unknown)} (see --help)\n")
        return EXIT_BAD_INPUT
    json_target = getattr(args, "json", None)
    # With --json -, stdout carries the JSON alone: the human report goes to stderr.
    human = contextlib.redirect_stdout(sys.stderr) if json_target == "-" else contextlib.nullcontext()
    try:
        # The command's outputs (--json's too) are put in place together when it succeeds; when it fails, or is
        # interrupted, none is (dynid.outputs).
        stage = None
        with staged() as stage:
            split_data_windows(args)
            check_outputs(args)
            with human, warnings.catch_warnings():
                warnings.simplefilter("always", DataNote)
                warnings.showwarning = _notes(args.command, warnings.showwarning)
                result = args.func(args)
            write_json(result, json_target)
    except InputError as e:
        sys.stderr.write(f"dynid {args.command}: error: {e}{_default_robot_note(args, argv, e)}\n")
        return e.exit_code
    except BrokenPipeError as e:
        if _reader_gone(sys.stdout):
            # The reader of stdout closed it (`dynid spy | head -1`): what it wanted was written. Stop as a tool killed
            # by SIGPIPE would, without a message, and keep the interpreter's final flush off the closed pipe.
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            # The command did not end: none of its outputs was put in place (dynid.outputs), which it says where
            # standard error still has a reader (`2>&1 | head` closed that pipe too: nothing more to say)
            named = sorted(set(stage.labels.values())) if stage is not None else []
            if (named or (stage is not None and stage.ready)) and not _reader_gone(sys.stderr):
                what = ", ".join(named) or ", ".join(sorted({str(path) for _, path in stage.ready}))
                sys.stderr.write(f"dynid {args.command}: standard output closed before the command ended: its "
                                 f"outputs ({what}) were not written\n")
            elif _reader_gone(sys.stderr):
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stderr.fileno())
            return 128 + signal.SIGPIPE
        sys.stderr.write(f"dynid {args.command}: error: {e.strerror or e}\n")  # another pipe than stdout
        return EXIT_BAD_INPUT
    except (OSError, ET.ParseError) as e:
        # A file the readers did not anticipate (unreadable, not XML, a device): still one line, exit 2.
        where = f"{e.filename}: " if getattr(e, "filename", None) else ""
        sys.stderr.write(f"dynid {args.command}: error: {where}{getattr(e, 'strerror', None) or e}\n")
        return EXIT_BAD_INPUT
    return 0

