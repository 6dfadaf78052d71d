"""What the reader property tests (test_reader_properties*.py) share: the property itself and byte mutations.

The property (issue 22): any input to a reader ends either in a result or in an `InputError` whose message is one
line, never in another exception, a warning or a silently wrong result. `outcome` runs a reader under that rule;
the mutation strategies start from a valid file and damage it the way files get damaged (truncated, bits flipped,
another encoding, another line ending, bytes inserted), so that most inputs get past the first check.

Examples per test: the count each test names, or DYNID_HYPOTHESIS_EXAMPLES for a longer search by hand (the
profile in conftest.py then draws new examples each run instead of the fixed ones CI runs).
"""

from __future__ import annotations

import os
import unicodedata
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TypeVar

from hypothesis import event, example
from hypothesis import strategies as st

from dynid.errors import InputError

T = TypeVar("T")
F = TypeVar("F", bound=Callable[..., None])


def examples(default: int) -> int:
    """Examples for one test: `default`, or DYNID_HYPOTHESIS_EXAMPLES when set (a longer search by hand)."""
    return int(os.environ.get("DYNID_HYPOTHESIS_EXAMPLES") or default)


def check_message(e: InputError) -> str:
    """An InputError's message as the CLI prints it: one line, not empty, no control character."""
    message = str(e)
    assert message.strip(), f"{type(e).__name__} with an empty message"
    assert len(message.splitlines()) == 1 and message == message.strip(), f"not one line: {message!r}"
    controls = [c for c in message if unicodedata.category(c) == "Cc"]
    assert not controls, f"control characters {controls!r} in the message: {message!r}"
    return message


def outcome(call: Callable[[], T]) -> T | None:
    """`call()`'s result, or None after an `InputError` with a one-line message (`check_message`).

    Any other exception propagates (the property fails), and so does any warning: it is turned into an error, as
    a numpy overflow or an invalid value in a reader would silently put inf or nan into a result.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            result = call()
        except InputError as e:
            check_message(e)
            event("refused")  # --hypothesis-show-statistics tells how many examples got how far
            return None
    event("accepted")
    return result


@dataclass
class Case:
    """One input file and how it was made: shown short when a property fails (a file is often 50 kB)."""

    raw: bytes
    steps: list[str] = field(default_factory=list)

    def __repr__(self) -> str:
        head = self.raw if len(self.raw) <= 300 else self.raw[:300] + b"..."
        return f"Case({head!r}, steps={self.steps}, {len(self.raw)} bytes)"

    def _repr_pretty_(self, p: object, cycle: bool) -> None:  # how hypothesis prints an example
        p.text(repr(self))  # type: ignore[attr-defined]


def regressions(*cases: Case) -> Callable[[F], F]:
    """`@example(case=...)` for each case: the inputs of the defects found (docs/fuzzing.md), each of which failed
    before its fix, run first on every run (`--hypothesis-profile dynid-regressions`: only them)."""

    def apply(test: F) -> F:
        for case in reversed(cases):
            test = example(case=case).via("regression")(test)
        return test

    return apply


# ----------------------------------------------------------------------------------------------------------
# Byte mutations of a whole file

BOM = b"\xef\xbb\xbf"


@st.composite
def damaged(draw: st.DrawFn, case: Case, text: bool = True) -> Case:
    """`case` with 0-3 byte-level mutations; `text` adds those of a text file (BOM, line endings, encodings)."""
    kinds = ["truncate", "flip", "insert", "delete", "random"]
    if text:
        kinds += ["bom", "crlf", "cr", "latin1", "nul", "no_final_newline", "blank_line", "tab"]
    raw, steps = case.raw, list(case.steps)
    for kind in draw(st.lists(st.sampled_from(kinds), max_size=3)):
        at = draw(st.integers(0, max(len(raw) - 1, 0)))
        steps.append(f"{kind}@{at}")
        if kind == "truncate":
            raw = raw[:at]
        elif kind == "flip" and raw:
            raw = raw[:at] + bytes([raw[at] ^ (1 << draw(st.integers(0, 7)))]) + raw[at + 1 :]
        elif kind == "insert":
            raw = raw[:at] + draw(st.binary(min_size=1, max_size=8)) + raw[at:]
        elif kind == "delete":
            raw = raw[:at] + raw[at + draw(st.integers(1, 16)) :]
        elif kind == "random":
            raw = draw(st.binary(max_size=256))
        elif kind == "bom":
            raw = BOM + raw
        elif kind == "crlf":
            raw = raw.replace(b"\r\n", b"\n").replace(b"\n", b"\r\n")
        elif kind == "cr":  # a lone carriage return (old Mac line ending) at one line end
            end = raw.find(b"\n", at)
            raw = raw if end < 0 else raw[:end] + b"\r" + raw[end + 1 :]
        elif kind == "latin1":  # a byte that is not UTF-8 (ISO 8859-1 'é')
            raw = raw[:at] + b"\xe9" + raw[at:]
        elif kind == "nul":
            raw = raw[:at] + b"\x00" + raw[at:]
        elif kind == "no_final_newline":
            raw = raw.rstrip(b"\r\n")
        elif kind == "blank_line":
            end = raw.find(b"\n", at)
            raw = raw if end < 0 else raw[: end + 1] + b"\n" + raw[end + 1 :]
        elif kind == "tab":
            raw = raw[:at] + b"\t" + raw[at:]
    return Case(raw, steps)


# Cell texts that are no plain decimal number, or one at the edge of what a float holds.
ODD_CELLS: tuple[str, ...] = (
    "", " ", "x", "nan", "NaN", "inf", "-inf", "Infinity", "1e999", "-1e999", "1e308", "1e-320", "0x10", "1_000",
    "1,5", "1.2.3", "--1", "+", ".", "e5", "1e", "5.", ".5", "+.5", " 7 ", '"1.0"', "١", "１", "1\x00", "\x1b[2J",
    "9" * 400, "true", "None",
)
