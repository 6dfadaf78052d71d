"""CSV import/export (docs/design.md §4): exact round trips, and one clear line for every bad input."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import yaml

from dynid.config.robot_config import load_config
from dynid.errors import DataError
from dynid.io.csv_format import read_csv, required_columns, write_csv
from dynid.io.dataset import Dataset
from dynid.io.load import MIN_SAMPLES, load_data

CFG = load_config("icub_right_arm")
JOINTS = CFG.joints
N = 6


def base_table() -> tuple[list[str], list[list[str]]]:
    """A valid CSV of the iCub arm (header, rows of cells): q, pwm, F/T, small values in radians."""
    header = ["t"] + [f"q.{j}" for j in JOINTS] + [f"pwm.{m}" for m in CFG.motor_names]
    header += [f"ft.r_arm_ft.{c}" for c in ("fx", "fy", "fz", "tx", "ty", "tz")]
    rng = np.random.default_rng(1)
    rows = []
    for i in range(N):
        values = [0.001 * i] + list(rng.uniform(-0.5, 0.5, len(header) - 1))
        rows.append([repr(float(v)) for v in values])
    return header, rows


def render(header: list[str], rows: list[list[str]]) -> str:
    return "\n".join([",".join(header)] + [",".join(r) for r in rows]) + "\n"


def write(tmp_path: Path, text: str | bytes, name: str = "data.csv") -> Path:
    path = tmp_path / name
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    return path


def col(header: list[str], name: str) -> int:
    return header.index(name)


def dataset_columns_equal(a: Dataset, b: Dataset) -> bool:
    ca, cb = a.columns(), b.columns()
    return [n for n, _ in ca] == [n for n, _ in cb] and all(
        np.array_equal(x, y) for (_, x), (_, y) in zip(ca, cb, strict=True)
    )


# ----------------------------------------------------------------------------------------------------------
# Good input


def test_reads_the_base_table(tmp_path: Path) -> None:
    header, rows = base_table()
    ds = read_csv(write(tmp_path, render(header, rows)), CFG)
    assert ds.n_samples == N and ds.joints == JOINTS
    assert ds.q.shape == (N, 7) and ds.dq is None and ds.ddq is None
    assert list(ds.pwm) == list(CFG.motor_names) and ds.ft["r_arm_ft"].shape == (N, 6)
    assert ds.q[2, 3] == float(rows[2][col(header, "q.r_elbow")])
    assert ds.ft["r_arm_ft"][4, 5] == float(rows[4][col(header, "ft.r_arm_ft.tz")])
    assert ds.meta["robot"] == "icub_right_arm" and ds.meta["config_digest"] == CFG.digest


def full_dataset(n: int = 50) -> Dataset:
    rng = np.random.default_rng(7)
    t = np.cumsum(rng.uniform(0.0005, 0.0015, n))
    return Dataset(
        t=t,
        joints=JOINTS,
        q=rng.uniform(-1, 1, (n, 7)),
        dq=rng.standard_normal((n, 7)),
        ddq=rng.standard_normal((n, 7)) * 1e3,
        pwm={m: rng.uniform(-1, 1, n) for m in CFG.motor_names},
        current={"m0": rng.standard_normal(n)},
        tau={"r_elbow": rng.standard_normal(n) * 1e-9},
        ft={"r_arm_ft": rng.standard_normal((n, 6)) * [100, 100, 100, 1, 1, 1]},
        contact=rng.integers(0, 2, n),
        extra={"contact_side": rng.integers(0, 3, n).astype(float), "effort.x": np.full(n, -0.0)},
    )


def test_round_trip_csv_dataset_npz_dataset_csv_is_exact(tmp_path: Path) -> None:
    first = tmp_path / "a.csv"
    write_csv(full_dataset(), first)
    ds1 = read_csv(first, CFG)
    ds1.save(tmp_path / "a.npz")
    ds2 = Dataset.load(tmp_path / "a.npz")
    second = tmp_path / "b.csv"
    write_csv(ds2, second)
    assert first.read_bytes() == second.read_bytes()
    assert dataset_columns_equal(ds1, ds2) and ds2.meta == ds1.meta
    assert dataset_columns_equal(ds1, full_dataset())  # every float survived the text form bit for bit


def test_write_csv_uses_design_column_order(tmp_path: Path) -> None:
    path = tmp_path / "o.csv"
    write_csv(full_dataset(3), path)
    header = path.read_text().splitlines()[0].split(",")
    kinds = [h.split(".")[0] for h in header]
    order = ["t", "q", "dq", "ddq", "pwm", "current", "tau", "ft", "contact", "contact_side", "effort"]
    assert sorted(kinds, key=order.index) == kinds
    assert header[1:8] == [f"q.{j}" for j in JOINTS]
    assert path.read_text().splitlines()[1].split(",")[header.index("contact")] in ("0", "1")


def test_column_order_in_the_file_does_not_matter(tmp_path: Path) -> None:
    header, rows = base_table()
    perm = list(reversed(range(len(header))))
    shuffled = render([header[i] for i in perm], [[r[i] for i in perm] for r in rows])
    a = read_csv(write(tmp_path, render(header, rows), "a.csv"), CFG)
    b = read_csv(write(tmp_path, shuffled, "b.csv"), CFG)
    assert dataset_columns_equal(a, b)


def test_extras_contact_and_text_variants(tmp_path: Path) -> None:
    header, rows = base_table()
    header += ["contact", "contact_side", "effort.arm_1_joint"]
    for i, r in enumerate(rows):
        r += [["0", "2", "-1", "0", "0.5", "0"][i], str(i % 3), " 1.5e-3 "]
    text = "\ufeff" + render(header, rows).replace("\n", "\r\n") + "\r\n\r\n"  # BOM, CRLF, trailing blank lines
    ds = read_csv(write(tmp_path, text), CFG)
    assert ds.contact.dtype == np.uint8 and ds.contact.tolist() == [0, 1, 1, 0, 1, 0]
    assert list(ds.extra) == ["contact_side", "effort.arm_1_joint"]
    assert ds.extra["effort.arm_1_joint"][0] == 1.5e-3


def test_dq_without_ddq_is_accepted(tmp_path: Path) -> None:
    header, rows = base_table()
    header += [f"dq.{j}" for j in JOINTS]
    for r in rows:
        r += ["0.25"] * 7
    ds = read_csv(write(tmp_path, render(header, rows)), CFG)
    assert ds.dq is not None and ds.ddq is None and np.all(ds.dq == 0.25)


def test_require_all_false_accepts_missing_inputs_but_not_missing_q(tmp_path: Path) -> None:
    header, rows = base_table()
    keep = [i for i, h in enumerate(header) if h == "t" or h.startswith("q.")]
    path = write(tmp_path, render([header[i] for i in keep], [[r[i] for i in keep] for r in rows]))
    ds = read_csv(path, CFG, require_all=False)
    assert ds.pwm == {} and ds.ft == {}
    with pytest.raises(DataError, match=r"pwm\.m0 is missing"):
        read_csv(path, CFG)
    keep = keep[:-1]
    path = write(tmp_path, render([header[i] for i in keep], [[r[i] for i in keep] for r in rows]), "b.csv")
    with pytest.raises(DataError, match=r"q\.r_wrist_yaw is missing"):
        read_csv(path, CFG, require_all=False)


def test_joint_limits_accept_radians(tmp_path: Path) -> None:
    header, rows = base_table()
    limits = {j: (-1.0, 1.0) for j in JOINTS}
    assert read_csv(write(tmp_path, render(header, rows)), CFG, joint_limits=limits).n_samples == N


def test_current_and_torque_groups_are_required(tmp_path: Path) -> None:
    """A variant of the iCub arm whose shoulder is current-driven and whose elbow has a joint torque sensor."""
    spec = yaml.safe_load(Path(CFG.source).read_text())
    spec["name"] = "mixed_inputs"
    spec["urdf"] = {"path": str(CFG.urdf)}
    spec["actuation"] = [
        {**spec["actuation"][0], "input": "current"},
        {"name": "elbow", "input": "torque", "joints": ["r_elbow"]},
    ]
    del spec["motors"]["m3"], spec["can"]
    cfg_path = tmp_path / "mixed.yaml"
    cfg_path.write_text(yaml.safe_dump(spec))
    cfg = load_config(cfg_path)
    needed = [c for c, _ in required_columns(cfg)]
    assert "current.m0" in needed and "tau.r_elbow" in needed and "pwm.m0" not in needed
    header, rows = base_table()
    keep = [i for i, h in enumerate(header) if h != "pwm.m3"]
    header = [header[i].replace("pwm.", "current.") for i in keep]
    rows = [[r[i] for i in keep] for r in rows]
    with pytest.raises(
        DataError,
        match=r"tau.r_elbow is missing: the configuration mixed_inputs drives actuation group 'elbow' by joint torque",
    ):
        read_csv(write(tmp_path, render(header, rows)), cfg)
    header.append("tau.r_elbow")
    for r in rows:
        r.append("1.0")
    ds = read_csv(write(tmp_path, render(header, rows), "b.csv"), cfg)
    assert list(ds.current) == ["m0", "m1", "m2"] and list(ds.tau) == ["r_elbow"]


def test_load_data_dispatches_csv(tmp_path: Path) -> None:
    header, rows = base_table()
    # load_data wants a run a command can use (MIN_SAMPLES): the table's rows over again, 1 ms apart.
    rows = [[repr(0.001 * i)] + rows[i % N][1:] for i in range(MIN_SAMPLES)]
    assert load_data(write(tmp_path, render(header, rows)), CFG).n_samples == MIN_SAMPLES


def test_read_speed(tmp_path: Path) -> None:
    """50 000 rows x 26 columns in well under a second here; the bound is loose for slow CI machines."""
    n = 50_000
    header = ["t"] + [f"q.{j}" for j in JOINTS] + [f"dq.{j}" for j in JOINTS] + [f"pwm.{m}" for m in CFG.motor_names]
    header += [f"ft.r_arm_ft.{c}" for c in ("fx", "fy", "fz", "tx", "ty", "tz")] + ["contact"]
    data = np.random.default_rng(0).uniform(-0.9, 0.9, (n, len(header)))
    data[:, 0] = np.arange(n) * 1e-3
    path = tmp_path / "big.csv"
    np.savetxt(path, data, fmt="%.17g", delimiter=",", header=",".join(header), comments="")
    start = time.perf_counter()
    ds = read_csv(path, CFG)
    elapsed = time.perf_counter() - start
    assert ds.n_samples == n and len(ds.column_names()) == len(header) == 26
    assert elapsed < 5.0, f"reading {n} rows took {elapsed:.2f} s"


# ----------------------------------------------------------------------------------------------------------
# Bad input: each raises DataError with one line naming the problem

Table = tuple[list[str], list[list[str]]]


def set_cell(name: str, row: int, value: str) -> Callable[[Table], Table]:
    def edit(table: Table) -> Table:
        header, rows = table
        rows[row - 1][header.index(name)] = value
        return header, rows

    return edit


def rename(old: str, new: str) -> Callable[[Table], Table]:
    def edit(table: Table) -> Table:
        header, rows = table
        header[header.index(old)] = new
        return header, rows

    return edit


def drop(*names: str) -> Callable[[Table], Table]:
    def edit(table: Table) -> Table:
        header, rows = table
        keep = [i for i, h in enumerate(header) if h not in names]
        return [header[i] for i in keep], [[r[i] for i in keep] for r in rows]

    return edit


def add(name: str, value: str = "0.0") -> Callable[[Table], Table]:
    def edit(table: Table) -> Table:
        header, rows = table
        return header + [name], [r + [value] for r in rows]

    return edit


def times(*values: str) -> Callable[[Table], Table]:
    def edit(table: Table) -> Table:
        header, rows = table
        for r, v in zip(rows, values, strict=False):
            r[0] = v
        return header, rows

    return edit


def short_row(row: int) -> Callable[[Table], Table]:
    def edit(table: Table) -> Table:
        header, rows = table
        rows[row - 1] = rows[row - 1][:-1]
        return header, rows

    return edit


def long_row(row: int) -> Callable[[Table], Table]:
    def edit(table: Table) -> Table:
        header, rows = table
        rows[row - 1] = rows[row - 1] + ["1.0"]
        return header, rows

    return edit


def degrees(table: Table) -> Table:
    header, rows = table
    rows[3][header.index("q.r_elbow")] = "95.0"
    return header, rows


def partial_dq(table: Table) -> Table:
    header, rows = table
    names = [f"dq.{j}" for j in JOINTS if j != "r_wrist_pitch"]
    return header + names, [r + ["0.0"] * len(names) for r in rows]


TABLE_CASES = {
    "duplicate column": (add("q.r_elbow"), ["q.r_elbow", "appears twice", "columns 5 and 19"]),
    "empty column name": (add(""), ["column 19", "empty name"]),
    "non-numeric cell": (set_cell("q.r_elbow", 3, "abc"), ["row 3 (line 4)", "q.r_elbow", "'abc' is not a number"]),
    "empty cell": (set_cell("pwm.m1", 2, ""), ["row 2 (line 3)", "pwm.m1", "not a number"]),
    "nan": (set_cell("q.r_elbow", 4, "nan"), ["q.r_elbow", "nan", "row 4 (line 5)", "finite"]),
    "inf": (set_cell("ft.r_arm_ft.fz", 2, "-inf"), ["ft.r_arm_ft.fz", "-inf", "row 2 (line 3)"]),
    "short row": (short_row(3), ["row 3 (line 4)", "17 fields", "18 columns"]),
    "long first row": (long_row(1), ["row 1 (line 2)", "19 fields", "18 columns"]),
    "t missing": (rename("t", "time"), ["column t", "missing", "time"]),
    "t repeats": (
        times("0", "0.001", "0.001"),
        ["t is not strictly increasing", "row 3 (line 4)", "0.001 s follows 0.001 s"],
    ),
    "t goes back": (times("0", "0.002", "0.001"), ["not strictly increasing", "row 3", "0.001 s follows 0.002 s"]),
    "unknown joint q": (
        rename("q.r_elbow", "q.r_elbw"),
        ["unknown joint 'r_elbw'", "column q.r_elbw", "did you mean 'r_elbow'", "icub_right_arm has: r_shoulder_pitch"],
    ),
    "unknown joint dq": (add("dq.elbow"), ["unknown joint 'elbow'", "column dq.elbow"]),
    "unknown joint ddq": (add("ddq.knee"), ["unknown joint 'knee'", "column ddq.knee"]),
    "unknown joint tau": (add("tau.r_knee"), ["unknown joint 'r_knee'", "column tau.r_knee"]),
    "unknown motor pwm": (add("pwm.m9"), ["unknown motor 'm9'", "column pwm.m9", "m0, m1, m2, m3"]),
    "unknown motor current": (add("current.m7"), ["unknown motor 'm7'", "column current.m7"]),
    "unknown ft sensor": (
        add("ft.l_arm_ft.fx"),
        ["unknown F/T sensor 'l_arm_ft'", "column ft.l_arm_ft.fx", "r_arm_ft"],
    ),
    "unknown ft channel": (
        add("ft.r_arm_ft.fq"),
        ["unknown F/T channel 'fq'", "ft.r_arm_ft.fq", "fx, fy, fz, tx, ty, tz"],
    ),
    "ft without channel": (add("ft.r_arm_ft"), ["ft.r_arm_ft", "names no channel"]),
    "prefix without name": (add("q."), ["'q.'", "names nothing"]),
    "missing q": (drop("q.r_elbow"), ["q.r_elbow is missing", "every joint"]),
    "missing pwm": (
        drop("pwm.m3"),
        ["column pwm.m3 is missing: the configuration icub_right_arm drives actuation group 'elbow' by pwm"],
    ),
    "missing ft sensor": (
        drop(*[f"ft.r_arm_ft.{c}" for c in ("fx", "fy", "fz", "tx", "ty", "tz")]),
        ["ft.r_arm_ft.fx is missing: the configuration icub_right_arm has the F/T sensor r_arm_ft", "ft.r_arm_ft.tz"],
    ),
    "partial ft": (drop("ft.r_arm_ft.ty"), ["r_arm_ft lacks", "ft.r_arm_ft.ty", "all six"]),
    "partial dq": (partial_dq, ["dq is given for some joints only", "dq.r_wrist_pitch", "every joint or for none"]),
    "pwm in board counts": (
        set_cell("pwm.m0", 5, "1333"),
        ["pwm.m0 reaches 1333 at row 5 (line 6)", "duty fractions in [-1, 1] are expected, not board counts"],
    ),
}


@pytest.mark.parametrize("case", TABLE_CASES, ids=list(TABLE_CASES))
def test_bad_table_raises_one_line(tmp_path: Path, case: str) -> None:
    edit, words = TABLE_CASES[case]
    path = write(tmp_path, render(*edit(base_table())))
    with pytest.raises(DataError) as info:
        read_csv(path, CFG)
    message = str(info.value)
    assert "\n" not in message and message.startswith(str(path))
    for w in words:
        assert w in message, f"{w!r} not in {message!r}"


def test_degrees_are_refused_with_limits(tmp_path: Path) -> None:
    path = write(tmp_path, render(*degrees(base_table())))
    limits = {j: (-1.0, 1.0) for j in JOINTS}
    assert read_csv(path, CFG).n_samples == N  # without limits there is nothing to compare with
    with pytest.raises(DataError) as info:
        read_csv(path, CFG, joint_limits=limits)
    message = str(info.value)
    assert "q.r_elbow reaches 95 at row 4" in message and "looks like degrees, radians are expected" in message
    assert "\n" not in message


FILE_CASES = {
    "empty file": (b"", ["the file is empty"]),
    "blank file": (b"\n\n  \n", ["the file is empty"]),
    "first line empty": (b"\nt,q.r_elbow\n0,1\n", ["first line is empty"]),
    "header only": (b"t,x\n", ["header but no data rows"]),
    "no header": (b"0.0,0.1,0.2\n0.001,0.1,0.2\n", ["no header", "first line is data"]),
    "semicolons": (b"t;q.a;q.b\n0;1;2\n", ["separated by commas"]),
    "binary": (b"\xff\xfe\x00\x01garbage\n\x00\x9f", ["not UTF-8"]),
}


@pytest.mark.parametrize("case", FILE_CASES, ids=list(FILE_CASES))
def test_bad_file_raises_one_line(tmp_path: Path, case: str) -> None:
    content, words = FILE_CASES[case]
    with pytest.raises(DataError) as info:
        read_csv(write(tmp_path, content), CFG)
    message = str(info.value)
    assert "\n" not in message
    for w in words:
        assert w in message, f"{w!r} not in {message!r}"


def test_blank_line_between_rows(tmp_path: Path) -> None:
    header, rows = base_table()
    lines = render(header, rows).splitlines()
    lines.insert(3, "")
    with pytest.raises(DataError, match="line 4 is empty"):
        read_csv(write(tmp_path, "\n".join(lines) + "\n"), CFG)


def test_non_utf8_cell(tmp_path: Path) -> None:
    header, rows = base_table()
    text = render(header, rows).encode().replace(rows[1][2].encode(), b"0.\xff1", 1)
    with pytest.raises(DataError, match=r"row 2 \(line 3\), column q.r_shoulder_roll: .* is not a number"):
        read_csv(write(tmp_path, text), CFG)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(DataError, match=r"not found: .*nope\.csv"):
        read_csv(tmp_path / "nope.csv", CFG)
    with pytest.raises(DataError, match="not a file"):
        read_csv(tmp_path, CFG)


def test_write_csv_refuses_names_that_break_the_format(tmp_path: Path) -> None:
    ds = full_dataset(3)
    ds.extra["a,b"] = np.zeros(3)
    with pytest.raises(DataError, match="commas"):
        write_csv(ds, tmp_path / "x.csv")
    assert not list(tmp_path.iterdir())
