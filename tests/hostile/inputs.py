"""Bad inputs, each made from one of the session's good files (tests/hostile/fixtures.py) into a case's input
directory. Every maker is a `Maker`: f(fixtures, input_dir)."""

from __future__ import annotations

import copy
import json
import random
import struct
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .case import Maker
from .fixtures import ROBOT_YAML, Fixtures

Table = tuple[list[str], list[list[str]]]  # a CSV's header and rows of cells


def garbage(n: int, seed: int) -> bytes:
    """n bytes of binary garbage (a fixed seed: every run spoils the same way)."""
    return random.Random(seed).randbytes(n)


def raw(name: str, data: bytes) -> Maker:
    return lambda fx, d: (d / name).write_bytes(data)


def directory(name: str) -> Maker:
    return lambda fx, d: (d / name).mkdir()


def dangling(name: str) -> Maker:
    """A symbolic link to nothing: a path that exists as a name and cannot be opened."""
    return lambda fx, d: (d / name).symlink_to(d / "gone")


def mode_000(attr: str, name: str) -> Maker:
    """A session file copied and made unreadable (chmod 000)."""
    def make(fx: Fixtures, d: Path) -> None:
        (d / name).write_bytes(getattr(fx, attr).read_bytes())
        (d / name).chmod(0)
    return make


def copy_of(attr: str, name: str) -> Maker:
    return lambda fx, d: (d / name).write_bytes(getattr(fx, attr).read_bytes())


def spoiled(attr: str, name: str, spoil: Callable[[bytes], bytes]) -> Maker:
    """A session file's bytes, spoiled: truncated, bit-flipped, padded."""
    return lambda fx, d: (d / name).write_bytes(spoil(getattr(fx, attr).read_bytes()))


def flip(offset: float, mask: int = 0x10) -> Callable[[bytes], bytes]:
    """One byte's bits flipped at a fraction of the file (0.5: the middle) or, for an int, at that offset."""
    def spoil(b: bytes) -> bytes:
        i = int(offset * len(b)) if isinstance(offset, float) else int(offset) % len(b)
        return b[:i] + bytes([b[i] ^ mask]) + b[i + 1:]
    return spoil


def cut(fraction: float) -> Callable[[bytes], bytes]:
    return lambda b: b[: int(len(b) * fraction)]


# ---- CSV -------------------------------------------------------------------------------------------------------


def table(fx: Fixtures, rows: int | None = None) -> Table:
    lines = fx.csv_lines
    body = lines[1:] if rows is None else lines[1 : rows + 1]
    return lines[0].split(","), [line.split(",") for line in body]


def render(header: list[str], rows: list[list[str]]) -> str:
    return "\n".join([",".join(header)] + [",".join(r) for r in rows]) + "\n"


def csv(edit: Callable[[list[str], list[list[str]]], Table] | None = None, rows: int | None = None,
        name: str = "data.csv") -> Maker:
    """The session's CSV (its first `rows` rows), edited."""
    def make(fx: Fixtures, d: Path) -> None:
        header, body = table(fx, rows)
        if edit:
            header, body = edit(header, body)
        (d / name).write_text(render(header, body))
    return make


def csv_text(spoil: Callable[[bytes], bytes], name: str = "data.csv") -> Maker:
    return spoiled("csv", name, spoil)


def drop(column: str) -> Callable[[list[str], list[list[str]]], Table]:
    def edit(h: list[str], rows: list[list[str]]) -> Table:
        i = h.index(column)
        return h[:i] + h[i + 1 :], [r[:i] + r[i + 1 :] for r in rows]
    return edit


def rename(old: str, new: str) -> Callable[[list[str], list[list[str]]], Table]:
    return lambda h, rows: ([new if c == old else c for c in h], rows)


def duplicate(column: str) -> Callable[[list[str], list[list[str]]], Table]:
    def edit(h: list[str], rows: list[list[str]]) -> Table:
        i = h.index(column)
        return h + [column], [r + [r[i]] for r in rows]
    return edit


def cell(column: str, row: int, value: str) -> Callable[[list[str], list[list[str]]], Table]:
    def edit(h: list[str], rows: list[list[str]]) -> Table:
        rows[row][h.index(column)] = value
        return h, rows
    return edit


def column(name: str, f: Callable[[int, float], float]) -> Callable[[list[str], list[list[str]]], Table]:
    """Every cell of a column through f(row, value): t in milliseconds, degrees, board counts."""
    def edit(h: list[str], rows: list[list[str]]) -> Table:
        i = h.index(name)
        for k, r in enumerate(rows):
            r[i] = repr(f(k, float(r[i])))
        return h, rows
    return edit


def reordered(h: list[str], rows: list[list[str]]) -> Table:
    order = list(range(len(h)))
    random.Random(1).shuffle(order)
    return [h[i] for i in order], [[r[i] for i in order] for r in rows]


def headerless(declared: str) -> Maker:
    """robot.yaml: the bundled arm with a `columns:` field declaring t in `declared`; data.csv: the session's CSV
    without its header, t in milliseconds."""
    def unit(name: str) -> str:
        kind = name.split(".")[0]
        if name == "t":
            return declared
        if kind == "ft":
            return "Nm" if name.endswith((".tx", ".ty", ".tz")) else "N"
        return {"q": "rad", "pwm": "duty"}.get(kind, "1")

    def make(fx: Fixtures, d: Path) -> None:
        header, rows = table(fx)
        columns = "".join(f"  - {name} {unit(name)}\n" for name in header)
        (d / "robot.yaml").write_text(ROBOT_YAML.read_text() + "\ncolumns:\n" + columns)
        i = header.index("t")
        (d / "data.csv").write_text("".join(",".join(r[:i] + [repr(float(r[i]) * 1000)] + r[i + 1 :]) + "\n"
                                            for r in rows))
    return make


# ---- dataset files ---------------------------------------------------------------------------------------------


def npz(**changes: Any) -> Maker:
    """The session's dataset.npz with members replaced (None removes one; a callable maps the old value)."""
    def make(fx: Fixtures, d: Path) -> None:
        with np.load(fx.npz) as z:
            members = {k: z[k] for k in z.files}
        for key, value in changes.items():
            key = key.replace("__", "/")
            if value is None:
                members.pop(key, None)
            else:
                members[key] = value(members[key]) if callable(value) else value
        np.savez(d / "d.npz", **members)
    return make


def first_rows(n: int) -> Maker:
    """The dataset's first n samples, every member cut alike."""
    def make(fx: Fixtures, d: Path) -> None:
        with np.load(fx.npz) as z:
            size = z["t"].shape[0]
            members = {k: (z[k][:n] if z[k].ndim and z[k].shape[0] == size else z[k]) for k in z.files}
        np.savez(d / "d.npz", **members)
    return make


def truth_npz(fx: Fixtures, d: Path) -> None:
    """A dataset file of another kind: the simulator's truth.npz (its own channels), named as a dataset."""
    (d / "d.npz").write_bytes((fx.run / "truth.npz").read_bytes())


def foreign_npz(fx: Fixtures, d: Path) -> None:
    np.savez(d / "d.npz", a=np.arange(10), b=np.ones((3, 3)))


def pickled_npz(fx: Fixtures, d: Path) -> None:
    np.savez(d / "d.npz", a=np.array([{"x": 1}], dtype=object))


# ---- model files -----------------------------------------------------------------------------------------------


def model(edit: Callable[[dict[str, Any]], None]) -> Maker:
    def make(fx: Fixtures, d: Path) -> None:
        document = json.loads(fx.model.read_text())
        edit(document)
        (d / "m.json").write_text(json.dumps(document))
    return make


DELETE = object()  # setting(key, DELETE) removes the key; setting(key, None) makes it JSON null


def setting(key: str, value: Any) -> Callable[[dict[str, Any]], None]:
    """One section (or a dotted path into one) set to a value, or deleted."""
    def edit(document: dict[str, Any]) -> None:
        *path, last = key.split(".")
        node = document
        for k in path:
            node = node[k]
        if value is DELETE:
            del node[last]
        else:
            node[last] = copy.deepcopy(value)
    return edit


def another_robot(document: dict[str, Any]) -> None:
    """The model made to say it is the Panda's: its name, the Panda's configuration embedded with its digest."""
    import hashlib

    text = (ROBOT_YAML.parent / "panda.yaml").read_text()
    document["robot"].update(name="panda", config_text=text, config_source="/nonexistent/panda.yaml",
                             config_digest=hashlib.sha256(text.encode()).hexdigest(), urdf=None)


# ---- coefficient files -----------------------------------------------------------------------------------------


def with_crc(b: bytes) -> bytes:
    """The wrapper's CRC made right again: a forged file gets past it to the loader's other checks."""
    return b[:-4] + struct.pack("<I", zlib.crc32(b[:-4]) & 0xFFFFFFFF)


def coef(edit: Callable[[Any], None]) -> Maker:
    """The session's coefficient file decoded, a field changed, encoded and wrapped again (a valid CRC)."""
    def make(fx: Fixtures, d: Path) -> None:
        from dynid.export.coefficients import read_coefficients, wrap

        c = read_coefficients(fx.coef)
        edit(c)
        (d / "c.dcoef").write_bytes(wrap(c.encode()))
    return make


def coef_field(name: str, value: Any) -> Callable[[Any], None]:
    return lambda c: setattr(c, name, value)


# ---- candump logs, monitor configurations, LCM logs ------------------------------------------------------------


def candump(edit: Callable[[str], str], every: int = 7, name: str = "run.log") -> Maker:
    """The session's candump log with every `every`-th line edited."""
    def make(fx: Fixtures, d: Path) -> None:
        lines = fx.log.read_text().splitlines()
        out = [edit(line) if i % every == min(3, every - 1) else line for i, line in enumerate(lines)]
        (d / name).write_bytes(("\n".join(out) + "\n").encode("utf-8", "surrogateescape"))
    return make


def candump_lines(edit: Callable[[list[str]], list[str]], name: str = "run.log") -> Maker:
    return lambda fx, d: (d / name).write_text("\n".join(edit(fx.log.read_text().splitlines())) + "\n")


def stamp(text: str) -> Callable[[str], str]:
    return lambda line: text + line[line.index(")") + 1 :]


def conf(edit: Callable[[list[str]], list[str]]) -> Maker:
    """The bundled arm's monitor configuration, edited, as bad.conf."""
    return lambda fx, d: (d / "bad.conf").write_text("\n".join(edit(fx.conf.read_text().splitlines())) + "\n")


def append(*lines: str) -> Callable[[list[str]], list[str]]:
    return lambda ls: ls + list(lines)


def set_key(key: str, value: str) -> Callable[[list[str]], list[str]]:
    return lambda ls: [f"{key} {value}" if line.startswith(key + " ") else line for line in ls]


def without(prefix: str) -> Callable[[list[str]], list[str]]:
    return lambda ls: [line for line in ls if not line.startswith(prefix)]


def replace(old: str, new: str) -> Callable[[list[str]], list[str]]:
    return lambda ls: [line.replace(old, new) for line in ls]


def lcm_foreign(fx: Fixtures, d: Path) -> None:
    """An LCM log whose messages on the monitor's channels are of another type."""
    import lcm

    log = lcm.EventLog(str(d / "log.lcmlog"), "w", overwrite=True)
    for i in range(20):
        log.write_event(i * 1000, "DYNID_STATUS", b"not a monitor_status_t at all")
        log.write_event(i * 1000 + 1, "DYNID_CONTACT", garbage(40, i))
    log.close()


def lcm_damaged(fx: Fixtures, d: Path) -> None:
    """The session's LCM log with every third message's payload damaged (its fingerprint's first byte flipped), then
    its tail with a byte flipped every 97 bytes: damaged messages, then damaged framing."""
    import lcm

    source = lcm.EventLog(str(fx.lcmlog), "r")
    out = lcm.EventLog(str(d / "log.lcmlog"), "w", overwrite=True)
    for k, event in enumerate(source):
        data = bytearray(event.data)
        if k % 3 == 1:
            data[0] ^= 0x55
        out.write_event(event.timestamp, event.channel, bytes(data))
    source.close()
    out.close()
    tail = bytearray(fx.lcmlog.read_bytes()[-2000:])
    for i in range(0, len(tail), 97):
        tail[i] ^= 0x55
    with open(d / "log.lcmlog", "ab") as f:
        f.write(bytes(tail))


def many(*makers: Maker) -> Maker:
    def make(fx: Fixtures, d: Path) -> None:
        for m in makers:
            m(fx, d)
    return make


def utf16(b: bytes) -> bytes:
    return b.decode().encode("utf-16")


def with_nul(b: bytes) -> bytes:
    return b[:2000] + b"\x00" + b[2000:]


def latin1_cell(b: bytes) -> bytes:
    return b[:2000] + b"\xff\xfe" + b[2000:]
