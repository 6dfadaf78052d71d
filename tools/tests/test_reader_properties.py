"""Property tests of the text readers (issue 22): CSV with a header, headerless CSV, candump log.

Any file given to `dynid.io.load.load_data` ends either in a `Dataset` or in an `InputError` with one line
(property_support.outcome). A file that is accepted must say what the file says: its numbers are compared with an
independent reading of the file by the rules of docs/design.md §4 and dynid.io.csv_format (`reference_table`), so
a reader that silently drops, shifts or invents a row fails too. Inputs start from a valid file of a bundled arm
and are damaged on purpose: columns dropped, repeated, moved or renamed, cells replaced by text or by numbers at
the edge of a float, rows moved, then bytes (property_support.damaged). Examples that once failed are kept as
`@example`s. Run: `.venv/bin/python -m pytest -q tools/tests/test_reader_properties.py`.
"""

from __future__ import annotations

import re
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dynid.config.robot_config import RobotConfig, load_config
from dynid.io.candump import write_candump
from dynid.io.csv_format import _NUMBER
from dynid.io.dataset import FT_CHANNELS, Dataset
from dynid.io.load import load_data
from property_support import BOM, ODD_CELLS, Case, damaged, examples, outcome, regressions

ICUB = load_config("icub_right_arm")
# Joint limits as the commands pass them (RobotModel.joint_limits of the bundled URDF), so that the unit check runs.
ICUB_LIMITS: dict[str, tuple[float, float]] = {
    "r_shoulder_pitch": (-1.6668, 0.1745), "r_shoulder_roll": (0.0, 2.8065), "r_shoulder_yaw": (-0.6458, 1.3963),
    "r_elbow": (0.2618, 1.85), "r_wrist_prosup": (-1.0472, 1.0472), "r_wrist_pitch": (-1.3963, 0.4363),
    "r_wrist_yaw": (-0.3491, 0.4363),
}
ROWS = st.integers(100, 120)  # at least the 100 samples a command needs, so that valid files stay valid


@pytest.fixture(scope="module")
def ur10e(tmp_path_factory: pytest.TempPathFactory) -> RobotConfig:
    """The bundled UR10e (a headerless log through `columns:`); its URDF is the user's, any file stands for it."""
    urdf = tmp_path_factory.mktemp("urdf") / "ur10e.urdf"
    urdf.write_text("<robot name='stand-in'/>")
    return load_config("ur10e", urdf=urdf)


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("props")


def put(workdir: Path, name: str, raw: bytes) -> Path:
    path = workdir / name
    path.write_bytes(raw)
    return path


# ----------------------------------------------------------------------------------------------------------
# The reference reading of a CSV: slow, plain Python, the documented rules only


def reference_table(raw: bytes, header: bool) -> tuple[list[str], np.ndarray] | None:
    """(header names, values) of a CSV as docs/design.md §4 defines it, or None for a file the rules refuse.

    UTF-8 with an optional BOM; lines end in LF or CRLF; trailing blank lines are ignored, blank lines between
    rows are not; every row has as many cells as the first line, each a number (csv_format._NUMBER).
    """
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        return None
    text = text.removeprefix("\ufeff")
    lines = [line.removesuffix("\r") for line in text.split("\n")]
    while lines and not lines[-1].strip():
        lines.pop()
    names: list[str] = []
    if header:
        if not lines:
            return None
        names = [n.strip() for n in lines.pop(0).split(",")]
        names = [n[1:-1].strip() if len(n) >= 2 and n[0] == n[-1] == '"' else n for n in names]
    if not lines:
        return None
    width = len(names) if header else len(lines[0].split(","))
    rows = []
    for line in lines:
        cells = line.split(",")
        if len(cells) != width or not all(_NUMBER.fullmatch(c) for c in cells):
            return None
        rows.append([float(c) for c in cells])
    return names, np.array(rows, dtype=float).reshape(len(rows), width)


def assert_says_what_the_file_says(ds: Dataset, names: Sequence[str], table: np.ndarray) -> None:
    """Every column of the dataset is the file's column of that name (contact as 0/1), and none is lost."""
    ds.validate()
    held = ds.column_names()
    assert sorted(held) == sorted(names), (held, names)
    for name, values in ds.columns():
        expected = table[:, list(names).index(name)]
        if name == "contact":
            expected = (expected != 0).astype(np.uint8)
        assert np.array_equal(values, expected), name


# ----------------------------------------------------------------------------------------------------------
# Valid tables, then damaged


def icub_table(seed: int, n: int, dq: bool, contact: bool) -> tuple[list[str], list[list[str]]]:
    """A valid CSV of the iCub arm: every required column, within the joint limits, in file order."""
    rng = np.random.default_rng(seed)
    header = ["t"] + [f"q.{j}" for j in ICUB.joints] + (["dq." + j for j in ICUB.joints] if dq else [])
    header += [f"pwm.{m}" for m in ICUB.motor_names] + [f"ft.r_arm_ft.{c}" for c in FT_CHANNELS]
    header += (["contact"] if contact else []) + ["temperature"]
    t = rng.uniform(0, 100) + np.cumsum(rng.uniform(0.0005, 0.0015, n))
    lo = np.array([ICUB_LIMITS[j][0] for j in ICUB.joints])
    hi = np.array([ICUB_LIMITS[j][1] for j in ICUB.joints])
    cols = [t[:, None], rng.uniform(lo, hi, (n, len(lo)))]
    cols += [rng.normal(0, 0.5, (n, len(lo)))] if dq else []
    cols += [rng.uniform(-1, 1, (n, 4)), rng.normal(0, 5, (n, 6))]
    cols += [rng.integers(0, 2, (n, 1))] if contact else []
    cols += [rng.normal(40, 2, (n, 1))]
    values = np.hstack(cols)
    return header, [[repr(float(v)) for v in row] for row in values]


COLUMN_NAMES = st.sampled_from([
    "t", "q.r_elbw", "q.", "q.r_elbow", "dq.r_elbow", "ft.r_arm_ft", "ft.r_arm_ft.fq", "ft.l_arm_ft.fx", "pwm.m9",
    "current.m0", "tau.r_elbow", "contact", "", " ", '"t"', "extra", "q.r_elbow;", "é", "\x1b[31m", "t\tq",
]) | st.text(max_size=8)


@st.composite
def mutated_table(
    draw: st.DrawFn, header: list[str], rows: list[list[str]]
) -> tuple[list[str], list[list[str]], list[str]]:
    """0-3 edits of a table's columns, cells and rows (each row a list of cells; a row [] is a blank line), and
    their names."""
    header, rows, steps = list(header), [list(r) for r in rows], []
    for kind in draw(st.lists(st.sampled_from(
        ["drop", "repeat", "move", "rename", "cell", "cells", "drop_row", "repeat_row", "swap_rows", "long_row",
         "short_row", "blank_row", "quote"]), max_size=3)):
        c = draw(st.integers(0, len(header) - 1)) if header else 0
        r = draw(st.integers(0, len(rows) - 1)) if rows else 0
        steps.append(f"{kind} column {c} row {r}")
        if kind == "drop" and len(header) > 1:
            del header[c]
            rows = [row[:c] + row[c + 1 :] for row in rows]
        elif kind == "repeat":
            header.insert(c, header[c])
            rows = [row[:c] + row[c : c + 1] + row[c:] for row in rows]
        elif kind == "move":
            to = draw(st.integers(0, len(header) - 1))
            order = list(range(len(header)))
            order.insert(to, order.pop(c))
            header = [header[i] for i in order]
            rows = [[row[i] for i in order] if len(row) == len(order) else row for row in rows]
        elif kind == "rename":
            header[c] = draw(COLUMN_NAMES)
        elif kind == "cell" and rows and c < len(rows[r]):
            rows[r][c] = draw(st.sampled_from(ODD_CELLS) | st.text(max_size=6))
        elif kind == "cells" and rows:  # a whole column of one odd value
            value = draw(st.sampled_from(ODD_CELLS))
            rows = [row[:c] + [value] + row[c + 1 :] for row in rows]
        elif kind == "drop_row" and len(rows) > 1:
            del rows[r]
        elif kind == "repeat_row" and rows:
            rows.insert(r, rows[r])
        elif kind == "swap_rows" and len(rows) > 1:
            s = draw(st.integers(0, len(rows) - 1))
            rows[r], rows[s] = rows[s], rows[r]
        elif kind == "long_row" and rows:
            rows[r] = rows[r] + ["1.0"]
        elif kind == "short_row" and rows:
            rows[r] = rows[r][:-1]
        elif kind == "blank_row":
            rows.insert(r, [])
        elif kind == "quote":
            header = [f'"{h}"' for h in header]
    return header, rows, steps


def render(header: list[str] | None, rows: list[list[str]]) -> bytes:
    lines = ([",".join(header)] if header is not None else []) + [",".join(row) for row in rows]
    return ("\n".join(lines) + "\n").encode("utf-8", errors="surrogatepass")


@st.composite
def icub_csv(draw: st.DrawFn, damage: bool = True) -> Case:
    header, rows = icub_table(draw(st.integers(0, 2**32 - 1)), draw(ROWS), draw(st.booleans()), draw(st.booleans()))
    header, rows, steps = draw(mutated_table(header, rows))
    case = Case(render(header, rows), steps)
    return draw(damaged(case)) if damage else case


def lone_cr_and_blank_line(lines: list[str]) -> bytes:
    """Data lines 1 and 2 joined by a lone CR, then a blank line: numpy's parser (a CR ends a line, blank lines
    are skipped) found as many rows as there are LFs, so the file was accepted, its rows shifted."""
    return ("\n".join([*lines[:1], lines[1] + "\r" + lines[2], "", *lines[3:]]) + "\n").encode()


def csv_regressions() -> list[Case]:
    """The CSVs of the defects found (docs/fuzzing.md): each failed before its fix."""
    header, rows = icub_table(7, 100, dq=False, contact=False)
    lines = [",".join(header)] + [",".join(r) for r in rows]
    return [
        Case(lone_cr_and_blank_line(lines), ["a lone CR and a blank line: accepted with rows shifted"]),
        Case(render(["q.\x1b[2Jr_elbow" if h == "q.r_elbow" else h for h in header], rows),
             ["an ESC sequence in a column name: printed raw to the terminal in the message"]),
    ]


@settings(max_examples=examples(200))
@given(case=icub_csv())
@regressions(*csv_regressions())
def test_csv_with_a_header(case: Case, workdir: Path) -> None:
    ds = outcome(lambda: load_data(put(workdir, "data.csv", case.raw), ICUB, joint_limits=ICUB_LIMITS))
    if ds is not None:
        reference = reference_table(case.raw, header=True)
        assert reference is not None, "a file the format refuses was accepted"
        assert_says_what_the_file_says(ds, *reference)


@settings(max_examples=examples(60))
@given(case=icub_csv(damage=False), bom=st.booleans())
def test_csv_line_endings_and_bom_do_not_change_the_data(case: Case, bom: bool, workdir: Path) -> None:
    """A CSV reads the same with LF or CRLF line ends, with or without a BOM (docs/design.md §4: UTF-8)."""
    crlf = case.raw.replace(b"\n", b"\r\n")
    a = outcome(lambda: load_data(put(workdir, "lf.csv", case.raw), ICUB, joint_limits=ICUB_LIMITS))
    other = BOM + crlf if bom else crlf
    b = outcome(lambda: load_data(put(workdir, "crlf.csv", other), ICUB, joint_limits=ICUB_LIMITS))
    assert (a is None) == (b is None)
    if a is not None and b is not None:
        assert all(np.array_equal(x, y) for (_, x), (_, y) in zip(a.columns(), b.columns(), strict=True))


# ----------------------------------------------------------------------------------------------------------
# Headerless CSV through the configuration's `columns:` (the bundled UR10e)


def ur10e_rows(seed: int, n: int, width: int) -> list[list[str]]:
    """A valid headerless log of the UR10e: `width` of its columns, as its controller writes them."""
    rng = np.random.default_rng(seed)
    t = rng.uniform(0, 1e4) + 0.002 * np.arange(n)
    values = rng.uniform(-2, 2, (n, width))
    values[:, 0] = t
    return [[f"{v:.6g}" if k else repr(float(v)) for k, v in enumerate(row)] for row in values]


@st.composite
def ur10e_csv(draw: st.DrawFn) -> Case:
    width = draw(st.sampled_from([25, 31]))  # the UR's two log widths (the configuration lists 31 columns)
    rows = ur10e_rows(draw(st.integers(0, 2**32 - 1)), draw(ROWS), width)
    _, rows, steps = draw(mutated_table(["_"] * width, rows))
    return draw(damaged(Case(render(None, rows), [f"{width} columns", *steps])))


@settings(max_examples=examples(150))
@given(case=ur10e_csv())
@regressions(Case(lone_cr_and_blank_line([",".join(r) for r in ur10e_rows(3, 100, 25)]),
                  ["a lone CR and a blank line: accepted with rows shifted"]))
def test_headerless_csv(case: Case, ur10e: RobotConfig, workdir: Path) -> None:
    ds = outcome(lambda: load_data(put(workdir, "ur.csv", case.raw), ur10e))
    if ds is not None:
        reference = reference_table(case.raw, header=False)
        assert reference is not None, "a file the format refuses was accepted"
        _, table = reference
        described = ur10e.columns[: table.shape[1]]
        keep = [i for i, c in enumerate(described) if c.name != "_"]
        scaled = table[:, keep] * np.array([described[i].scale for i in keep])
        assert_says_what_the_file_says(ds, [described[i].name for i in keep], scaled)


# ----------------------------------------------------------------------------------------------------------
# candump -L log (the iCub arm's CAN mapping)


def icub_log(seed: int, n: int) -> bytes:
    """A valid candump log of the iCub arm, as `dynid import` of a CAN log expects it (write_candump)."""
    rng = np.random.default_rng(seed)
    lo = np.array([ICUB_LIMITS[j][0] for j in ICUB.joints])
    hi = np.array([ICUB_LIMITS[j][1] for j in ICUB.joints])
    ds = Dataset(t=0.001 * np.arange(n), joints=ICUB.joints, q=rng.uniform(lo, hi, (n, len(lo))),
                 pwm={m: rng.uniform(-1, 1, n) for m in ICUB.motor_names}, ft={"r_arm_ft": rng.normal(0, 5, (n, 6))},
                 contact=rng.integers(0, 2, n))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "base.log"
        write_candump(ds, ICUB, path, t0=float(rng.uniform(0, 2e9)))
        return path.read_bytes()


_FRAME = re.compile(rb"^\((?P<t>[^)]*)\) (?P<bus>\S+) (?P<id>[^#]+)#(?P<data>.*)$")
ODD_FIELDS = {
    "t": [b"1.5", b"99999999999999999999.000000", b"9223372036854.775807", b"1700000000.0000001", b"-1.000000",
          b"0.000000", b""],
    "bus": [b"can\xff", b"can9", b"vcan0", b"\xe2\x82\xac"],
    "id": [b"FFF", b"7FF", b"800", b"12345678", b"1", b"xyz", b"00A"],
    "data": [b"ABC", b"A", b"00112233445566778899", b"R", b"zz", b"", b"0011223344556677"],
}


@st.composite
def icub_candump(draw: st.DrawFn) -> Case:
    lines = icub_log(draw(st.integers(0, 2**32 - 1)), draw(ROWS)).splitlines()
    steps = []
    for kind in draw(st.lists(st.sampled_from(["field", "drop", "repeat", "swap", "shift", "reverse", "sort_bus"]),
                              max_size=4)):
        i = draw(st.integers(0, len(lines) - 1))
        m = _FRAME.match(lines[i])
        steps.append(f"{kind} line {i}")
        if kind == "field" and m:
            name = draw(st.sampled_from(sorted(ODD_FIELDS)))
            parts = {k: m.group(k) for k in ("t", "bus", "id", "data")}
            parts[name] = draw(st.sampled_from(ODD_FIELDS[name]))
            lines[i] = b"(%s) %s %s#%s" % (parts["t"], parts["bus"], parts["id"], parts["data"])
            steps[-1] += f": {lines[i]!r}"
        elif kind == "drop":
            del lines[i : i + draw(st.integers(1, 40))]
        elif kind == "repeat":
            lines.insert(i, lines[i])
        elif kind == "swap":
            j = draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
        elif kind == "shift" and m:  # the same frame, stamped up to 2 ms earlier or later
            sec, _, frac = m.group("t").partition(b".")
            us = int(sec) * 1_000_000 + int(frac or b"0") + draw(st.integers(-2000, 2000))
            lines[i] = b"(%d.%06d)" % divmod(max(us, 0), 1_000_000) + lines[i][m.end("t") + 1 :]
        elif kind == "reverse":
            lines.reverse()
        elif kind == "sort_bus":  # as if the buses were logged one after the other
            lines.sort(key=lambda line: line.split(b" ")[1] if b" " in line else b"")
        if not lines:
            break
    return draw(damaged(Case(b"\n".join(lines) + b"\n", steps)))


def log_regressions() -> list[Case]:
    """The logs of the defects found (docs/fuzzing.md): each failed before its fix."""
    lines = icub_log(3, 100).splitlines()
    first = lines[0].split(b")")[0] + b")"
    torque = [i for i, line in enumerate(lines) if b" 3DB#" in line]
    late = [*lines]
    late.insert(torque[50], late.pop(torque[10]))
    return [
        Case(b"\n".join([lines[0].replace(b" can0 ", b" can\xff ").replace(b" can1 ", b" can\xff "), *lines[1:]]),
             ["a bus name that is no UTF-8: UnicodeDecodeError"]),
        Case(b"\n".join([*lines, first + b" can0 123#ABC"]), ["three hex digits of payload: ValueError"]),
        Case(b"\n".join([*lines, b"(99999999999999999999.000000) can0 123#00"]), ["20-digit seconds: OverflowError"]),
        Case(b"\n".join(late), ["one strain frame 40 samples late in the file: a dataset whose time ran backwards"]),
    ]


@settings(max_examples=examples(100))
@given(case=icub_candump())
@regressions(*log_regressions())
def test_candump_log(case: Case, workdir: Path) -> None:
    ds = outcome(lambda: load_data(put(workdir, "run.log", case.raw), ICUB))
    if ds is not None:
        ds.validate()  # finite, strictly increasing time, the shapes of the configuration
        assert ds.joints == ICUB.joints and ds.t[0] == 0.0
        assert set(ds.pwm) == set(ICUB.motor_names) and set(ds.ft) == {"r_arm_ft"}
