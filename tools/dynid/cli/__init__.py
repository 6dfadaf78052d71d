"""The `dynid` command line (docs/design.md §7): one thin module per command group (parse, call the library,
print), and `main`, the entry point.

A command that starts from a robot takes `--robot` (a configuration file or a bundled name; default icub_right_arm;
one that reads a model takes the model's robot). Bad input of any
kind ends with exit code 2 and one line on stderr naming the problem; Ctrl-C with one line, "dynid COMMAND:
interrupted", and exit code 130. `--json FILE` writes the command's result for machines ('-' for stdout); its fields
are documented in docs/formats.md. The cli may import every layer below it; nothing imports the cli.

This module is kept light (the standard library and dynid.interrupt only): the `dynid` console script imports it before it calls
`main`, and a Ctrl-C in an import made here would end the command with a traceback. The command line itself
(dynid.cli.app: numpy, the configurations, the command's group, 0.5 s and more) is imported inside `main`, where
Ctrl-C is handled from its first line.
"""

from __future__ import annotations

import sys
from typing import Any

from ..interrupt import interruptible

__all__ = ["build_parser", "main"]

EXIT_INTERRUPTED = 130  # 128 + SIGINT, as a shell reports a program that SIGINT ended


def main(argv: list[str] | None = None) -> int:
    """`dynid ARGV`: the exit code (the console script's and `python -m dynid`'s entry point)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        with interruptible():  # a Ctrl-C is never swallowed, and no output is put in place after one
            from .app import run  # the heavy imports, under the same protection as the command

            return run(argv)
    except KeyboardInterrupt:
        outputs = sys.modules.get("dynid.outputs")  # not loaded: the command staged nothing
        if outputs is not None:
            outputs.discard_unfinished()
        command = next((a for a in argv if not a.startswith("-")), None)
        sys.stderr.write(f"dynid{' ' + command if command else ''}: interrupted\n")
        return EXIT_INTERRUPTED


def __getattr__(name: str) -> Any:
    if name == "build_parser":  # PEP 562: loaded on first use, as dynid's own names are
        from .app import build_parser

        return build_parser
    raise AttributeError(f"module 'dynid.cli' has no attribute {name!r}")
