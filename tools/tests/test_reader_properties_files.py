"""Property tests of the file readers (issue 22): the dataset file, the robot configuration, the model file.

As in test_reader_properties.py: any input ends in a result or in an `InputError` with one line
(property_support.outcome), and a result is one the commands can use (checked below for each reader). Inputs start
from a valid file and are changed member by member, field by field, then byte by byte:

- dataset (.npz): members dropped, added, replaced by arrays of other dtypes (object arrays among them: a reader
  must never unpickle), shapes and values; format markers and meta changed; the archive compressed, truncated,
  bit-flipped; an array header that claims more data than the archive holds;
- robot configuration: lines of the bundled icub_right_arm.yaml dropped, repeated, moved, re-indented, values
  replaced; any subtree of its mapping replaced by another YAML value; random YAML documents;
- model file: any subtree of a real fitted model file (data/fitted_model_icub.json: `dynid fit` of a 20 s
  `dynid simulate` run of the iCub arm, its configuration source given by bundled name and its URDF path left out
  so that it stands alone) replaced, removed or retyped; the JSON text damaged.

Run: `.venv/bin/python -m pytest -q tools/tests/test_reader_properties_files.py`.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import warnings
import zipfile
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from dynid.config.robot_config import BUNDLED_DIR, RobotConfig, load_config
from dynid.identify.model_file import IdentifiedModel, load_model
from dynid.io.dataset import Dataset
from dynid.io.load import load_data
from dynid.robot.model import RobotModel
from property_support import Case, damaged, examples, outcome, regressions

ICUB = load_config("icub_right_arm")
MODEL_FILE = Path(__file__).parent / "data" / "fitted_model_icub.json"


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("props")


def put(workdir: Path, name: str, raw: bytes) -> Path:
    path = workdir / name
    path.write_bytes(raw)
    return path


# JSON-like values, with the numbers that break conversions: huge integers, non-finite floats.
SCALARS = (st.none() | st.booleans() | st.integers() | st.sampled_from([0, -1, 10**400, 2**63, -(2**63) - 1])
           | st.floats() | st.text(max_size=12))
VALUES = st.recursive(SCALARS, lambda inner: st.lists(inner, max_size=4)
                      | st.dictionaries(st.text(max_size=8), inner, max_size=4), max_leaves=12)


def paths(tree: Any, prefix: tuple = ()) -> list[tuple]:
    """Every path (a tuple of keys and indices) into a JSON-like tree, the root () first."""
    out = [prefix]
    if isinstance(tree, dict):
        for k, v in tree.items():
            out += paths(v, (*prefix, k))
    elif isinstance(tree, list):
        for i, v in enumerate(tree[:8]):  # the first elements of a long list stand for the rest
            out += paths(v, (*prefix, i))
    return out


@st.composite
def edited_tree(draw: st.DrawFn, tree: Any, steps: list[str]) -> Any:
    """`tree` with 1-3 subtrees replaced by another value, removed, retyped or given an extra key."""
    for _ in range(draw(st.integers(1, 3))):
        # A section first, then a place in it: every section gets its share, not only the long arrays.
        top = draw(st.sampled_from(sorted(tree))) if isinstance(tree, dict) and tree else None
        where = draw(st.sampled_from(paths(tree) if top is None else paths(tree[top], (top,))))
        kind = draw(st.sampled_from(["replace", "remove", "list", "string", "extra"]))
        steps.append(f"{kind} {'.'.join(map(str, where)) or '(root)'}")
        if not where:
            tree = draw(VALUES) if kind == "replace" else tree
            continue
        parent = tree
        for key in where[:-1]:
            parent = parent[key]
        key = where[-1]
        if kind == "replace":
            parent[key] = draw(VALUES)
        elif kind == "remove":
            del parent[key]
        elif kind == "list":
            parent[key] = [parent[key]]
        elif kind == "string":
            parent[key] = str(parent[key])
        elif isinstance(parent[key], dict):
            parent[key][draw(st.text(max_size=8))] = draw(VALUES)
    return tree


# ----------------------------------------------------------------------------------------------------------
# The dataset file (.npz)


def icub_dataset(seed: int, n: int) -> Dataset:
    rng = np.random.default_rng(seed)
    j = len(ICUB.joints)
    derivatives = seed % 2 == 1  # recorded dq, ddq in every other file
    return Dataset(t=0.001 * np.arange(n), joints=ICUB.joints, q=rng.uniform(-0.3, 0.3, (n, j)),
                   dq=rng.normal(0, 1, (n, j)) if derivatives else None,
                   ddq=rng.normal(0, 1, (n, j)) if derivatives else None,
                   pwm={m: rng.uniform(-1, 1, n) for m in ICUB.motor_names}, ft={"r_arm_ft": rng.normal(0, 5, (n, 6))},
                   contact=rng.integers(0, 2, n), extra={"temperature": rng.normal(40, 1, n)},
                   meta={"robot": ICUB.name, "source": "property test"})


def npz_bytes(members: dict[str, np.ndarray], compressed: bool = False) -> bytes:
    out = io.BytesIO()
    (np.savez_compressed if compressed else np.savez)(out, **members)
    return out.getvalue()


def huge_member(shape: tuple[int, ...]) -> bytes:
    """A .npy member whose header claims `shape` float64 values, followed by 16 bytes of data only."""
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": shape})
    return header.getvalue() + bytes(16)


ODD_ARRAYS: list[Any] = [
    np.array([{"a": 1}], dtype=object), np.array(1 + 2j), np.array(["x", "y"]), np.array(b"bytes"), np.array(5.0),
    np.zeros((0,)), np.zeros((2, 3, 4)), np.array([np.nan, np.inf]), np.array([True, False]),
    np.array([2**64 - 1], dtype=np.uint64), np.array([1.0], dtype=np.float16), np.array(["2020-01"], dtype="M8[M]"),
    np.zeros(2, dtype=[("a", "<f8")]), np.array(np.inf), np.array(np.nan), np.array(2), np.array(0), np.array("1"),
    np.array("[" * 5000), np.array('{"a": NaN}'), np.array("[]"), np.array(["", "a"]), np.array([[1.0]]),
]


ODD_META = ["", "x", "[]", "null", '{"a": NaN}', '{"a": Infinity}', "[" * 5000, '{"a": ' + "1" * 5000 + "}",
            '{"robot": 5}', '{"derivatives": []}', '{"rows": "x"}', '{"rows": [1]}', '{"rows": [0.5, 2]}', "\ud800"]


@st.composite
def dataset_file(draw: st.DrawFn) -> Case:
    seed, n = draw(st.integers(0, 2**32 - 1)), draw(st.integers(100, 110))
    with np.load(io.BytesIO(npz_bytes(_members(icub_dataset(seed, n))))) as z:
        members = {k: z[k] for k in z.files}
    steps: list[str] = []
    for kind in draw(st.lists(st.sampled_from(["drop", "add", "replace", "reshape", "value", "retype", "meta"]),
                              max_size=3)):
        key = draw(st.sampled_from(sorted(members))) if members else "t"
        steps.append(f"{kind} {key}")
        if kind == "meta":
            members["meta"] = np.array(draw(st.sampled_from(ODD_META) | VALUES.map(lambda v: json.dumps(v))))
            steps[-1] = f"meta {str(members['meta'])[:40]!r}"
        elif kind == "drop":
            members.pop(key, None)
        elif kind == "add":
            members[draw(st.sampled_from(["foo", "pwm/", "extra/x", "ft/other", "tau/r_elbow", "contact"]))] = (
                draw(st.sampled_from(ODD_ARRAYS)))
        elif kind == "replace":
            members[key] = draw(st.sampled_from(ODD_ARRAYS))
        elif kind == "reshape" and key in members and members[key].ndim:
            members[key] = members[key].reshape(-1) if members[key].ndim > 1 else members[key][: members[key].size // 2]
        elif kind == "value" and key in members and members[key].dtype.kind == "f" and members[key].size:
            a = members[key].copy()
            a.flat[draw(st.integers(0, a.size - 1))] = draw(st.sampled_from([np.nan, np.inf, -1e308, 1e300, 0.0]))
            members[key] = a
        elif kind == "retype" and key in members:
            dtype = draw(st.sampled_from(["i8", "u1", "f4", "c16", "U8", "?", "O"]))
            with contextlib.suppress(ValueError, TypeError, OverflowError), warnings.catch_warnings():
                warnings.simplefilter("ignore")  # a name is no number; complex to real, nan to int
                members[key] = members[key].astype(dtype)
    raw = npz_bytes(members, compressed=draw(st.booleans()))
    if draw(st.booleans()):  # an array header that claims far more data than the member holds
        key = draw(st.sampled_from(sorted(members) or ["t"]))
        shape = draw(st.sampled_from([(10**12,), (2**40, 7), (2**62,), (10**6,)]))
        steps.append(f"member {key} claims shape {shape}")
        out = io.BytesIO()
        with zipfile.ZipFile(io.BytesIO(raw)) as src, zipfile.ZipFile(out, "w") as dst:
            for info in src.infolist():
                dst.writestr(info, huge_member(shape) if info.filename == f"{key}.npy" else src.read(info))
        raw = out.getvalue()
    return draw(damaged(Case(raw, steps), text=False))


def _members(ds: Dataset) -> dict[str, np.ndarray]:
    """The members of the dataset file `Dataset.save` writes."""
    buffer = io.BytesIO()
    with mock.patch("dynid.io.dataset.atomic_write", lambda _path, write: write(buffer)):
        ds.save("unused.npz")
    with np.load(io.BytesIO(buffer.getvalue())) as z:
        return {k: z[k] for k in z.files}


def rewritten(raw: bytes, name: str, data: bytes) -> bytes:
    """The archive `raw` with member `name` replaced by `data` (stored, as np.savez writes)."""
    out = io.BytesIO()
    with zipfile.ZipFile(io.BytesIO(raw)) as src, zipfile.ZipFile(out, "w") as dst:
        for info in src.infolist():
            dst.writestr(info, data if info.filename == name else src.read(info))
    return out.getvalue()


def dataset_regressions() -> list[Case]:
    """The dataset files of the defects found (docs/fuzzing.md): each failed before its fix."""
    members = _members(icub_dataset(1, 100))
    plain, packed = npz_bytes(members), npz_bytes(members, compressed=True)
    flip = packed.find(b"t.npy") + 45  # inside the deflated data of member t
    central = packed.find(b"PK\x01\x02")  # the first member's central directory entry
    meta = {"deep": "[" * 5000, "digits": '{"a": ' + "1" * 5000 + "}", "rows": '{"rows": "x"}'}
    return [
        Case(rewritten(plain, "t.npy", huge_member((10**12,))), ["a header claiming 10^12 values: MemoryError"]),
        Case(npz_bytes({**members, "format_version": np.array(np.inf)}), ["format_version inf: OverflowError"]),
        Case(packed[:flip] + bytes([packed[flip] ^ 0x10]) + packed[flip + 1 :], ["a flipped deflate bit: zlib.error"]),
        Case(packed[: central + 10] + b"\x63\x00" + packed[central + 12 :],
             ["compression method 99: NotImplementedError"]),
        Case(packed[: central + 8] + bytes([packed[central + 8] | 1]) + packed[central + 9 :],
             ["the encrypted flag: RuntimeError"]),
        *(Case(npz_bytes({**members, "meta": np.array(text)}), [f"meta {kind}: an exception, or a TypeError in slice"])
          for kind, text in meta.items()),
    ]


def never_unpickle(*_args: object, **_kwargs: object) -> None:
    raise AssertionError("a dataset file was unpickled")


@settings(max_examples=examples(200))
@given(case=dataset_file())
@regressions(*dataset_regressions())
def test_dataset_file(case: Case, workdir: Path) -> None:
    path = put(workdir, "data.npz", case.raw)
    with mock.patch("pickle.load", never_unpickle), mock.patch("pickle.loads", never_unpickle):
        ds = outcome(lambda: load_data(path, ICUB))
    if ds is not None:
        ds.validate()
        assert ds.joints == ICUB.joints
        if ds.n_samples > 1:  # what --from/--to do with it (dynid.io.load.apply_window)
            ds.slice(1, None).validate()


# ----------------------------------------------------------------------------------------------------------
# The robot configuration (YAML)

ICUB_YAML = (BUNDLED_DIR / "icub_right_arm.yaml").read_bytes()
ODD_YAML_VALUES = [b"", b"~", b"-1", b"0", b"1e400", b"-.inf", b".nan", b"1" + b"0" * 400, b"[]", b"{}", b"[1, 2]",
                   b"true", b"'x'", b'"\\x00"', b"[[1, 2], [3]]", b"&a [*a]", b"!!python/object:os.system {}",
                   b"[" * 200, b"[" * 3000, b"{a: 1, a: 2}", b"r_elbow", b"m0", b"can0", b"ft.x.fx rad",
                   b"q.r_elbow deg", b"2001-13-45", b"1" * 5000, b"0x" + b"f" * 5000, b"!!binary x"]


def config_ok(cfg: RobotConfig) -> None:
    """What the commands rely on in a loaded configuration."""
    assert cfg.joints and all(isinstance(j, str) and j for j in cfg.joints) and len(set(cfg.joints)) == len(cfg.joints)
    assert len(set(cfg.motor_names)) == len(cfg.motor_names)
    assert cfg.urdf.is_file() and cfg.gravity.shape == (3,) and np.isfinite(cfg.gravity).all()
    for m in cfg.motors:
        assert math.isfinite(m.nominal_gain) and m.nominal_gain > 0
    for g in cfg.actuation:
        assert g.joints and g.coupling.shape == (len(g.motors) or len(g.joints), len(g.joints))
        assert np.isfinite(g.coupling).all()
    sensors = (x for s in cfg.ft_sensors for x in (s.force_noise, s.torque_noise))
    for value in (cfg.noise.pwm, cfg.noise.current, cfg.noise.torque, cfg.noise.encoder_step,
                  *cfg.noise.per_channel.values(), *sensors):
        assert math.isfinite(value) and value > 0
    for s in cfg.can.get("strain", []):
        assert all(math.isfinite(x) and x > 0 for x in s["full_scale"])


@st.composite
def config_text(draw: st.DrawFn) -> Case:
    lines = ICUB_YAML.splitlines()
    steps: list[str] = []
    for kind in draw(st.lists(st.sampled_from(["drop", "repeat", "swap", "indent", "dedent", "value"]), max_size=3)):
        i = draw(st.integers(0, len(lines) - 1))
        steps.append(f"{kind} line {i + 1}")
        if kind == "drop":
            del lines[i]
        elif kind == "repeat":
            lines.insert(i, lines[i])
        elif kind == "swap":
            j = draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
        elif kind == "indent":
            lines[i] = b"  " + lines[i]
        elif kind == "dedent":
            lines[i] = lines[i].lstrip()
        elif kind == "value" and b":" in lines[i]:
            key = lines[i].split(b":", 1)[0]
            lines[i] = key + b": " + draw(st.sampled_from(ODD_YAML_VALUES))
            steps[-1] += f": {lines[i]!r}"
    return draw(damaged(Case(b"\n".join(lines) + b"\n", steps)))


@st.composite
def config_tree(draw: st.DrawFn) -> Case:
    steps: list[str] = []
    tree = draw(edited_tree(yaml.safe_load(ICUB_YAML), steps))
    return Case(yaml.safe_dump(tree, sort_keys=False, allow_unicode=True).encode("utf-8", "surrogatepass"), steps)


def random_yaml(value: Any) -> Case:
    return Case(yaml.safe_dump(value, allow_unicode=True).encode("utf-8", "surrogatepass"), ["random document"])


def config_regressions() -> list[Case]:
    """The configurations of the defects found (docs/fuzzing.md): each failed before its fix."""
    text = ICUB_YAML.decode()

    def edit(old: str, new: str, why: str) -> Case:
        assert old in text
        return Case(text.replace(old, new, 1).encode(), [why])

    return [
        edit("pwm: 0.002", "pwm: 2001-13-45", "a date that is none: ValueError out of PyYAML"),
        edit("pwm: 0.002", "pwm: 1" + "0" * 400, "an integer too large for a float: OverflowError"),
        edit("pwm: 0.002", "pwm: " + "[" * 3000, "arrays nested 3000 deep: RecursionError in PyYAML"),
        edit("- [1.0,    0.0,   0.0]", "- [1" + "0" * 400 + ", 0.0, 0.0]", "a coupling of 400 digits: OverflowError"),
        edit("full_scale: [200.0,", "full_scale: [.inf,", "an infinite full scale: accepted, F/T values nan"),
        edit("    motors: [m3]\n", "    motors: [m3]\n  - {name: none, input: torque, joints: []}\n",
             "an actuation group of no joint: accepted, a 0x0 coupling"),
    ]


@settings(max_examples=examples(150))
@given(case=config_text() | config_tree() | VALUES.map(random_yaml))
@regressions(*config_regressions())
def test_robot_configuration(case: Case, workdir: Path) -> None:
    cfg = outcome(lambda: load_config(put(workdir, "robot.yaml", case.raw)))
    if cfg is not None:
        config_ok(cfg)


# ----------------------------------------------------------------------------------------------------------
# The model file (JSON)

MODEL_JSON = MODEL_FILE.read_bytes()
ACCESSORS = ("config", "phi", "effects", "supply_tracking", "min_speed", "output_channels", "residual_variance")
_ROBOT_MODELS: dict[str, RobotModel] = {}


def robot_model(m: IdentifiedModel) -> RobotModel:
    """The model's RobotModel, built once per configuration text (Pinocchio takes ~0.1 s)."""
    if m.config.digest not in _ROBOT_MODELS:
        _ROBOT_MODELS[m.config.digest] = RobotModel(m.config)
    return _ROBOT_MODELS[m.config.digest]


@st.composite
def model_file(draw: st.DrawFn) -> Case:
    steps: list[str] = []
    tree = draw(edited_tree(json.loads(MODEL_JSON), steps))
    raw = json.dumps(tree).encode("utf-8", "surrogatepass")
    return draw(damaged(Case(raw, steps))) if draw(st.integers(0, 3)) == 0 else Case(raw, steps)


def model_regressions() -> list[Case]:
    """The model files of the defects found (docs/fuzzing.md): each failed before its fix."""

    def edit(why: str, change: Any) -> Case:
        tree = json.loads(MODEL_JSON)
        change(tree)
        return Case(json.dumps(tree).encode(), [why])

    return [
        edit("robot a list: AttributeError", lambda t: t.update(robot=[t["robot"]])),
        edit("no outputs.residual_variance: KeyError", lambda t: t["outputs"].pop("residual_variance")),
        edit("outputs.residual_variance in a list: shape (1, 10), accepted",
             lambda t: t["outputs"].update(residual_variance=[t["outputs"]["residual_variance"]])),
        edit("outputs.residual_variance text: ValueError", lambda t: t["outputs"].update(residual_variance=[""] * 10)),
        edit("a parameter of 400 digits: TypeError", lambda t: t["parameters"].update({"m0.phi_m": 10**400})),
        edit("supply_tracking of 400 digits: OverflowError", lambda t: t["supply_tracking"].update(gate=10**400)),
        edit("an effect's coefficients text: ValueError", lambda t: t.update(effects=[
            {"kind": "spring", "where": "joint r_elbow", "parameters": {"stiffness": 1, "rest": 0},
             "coefficients": ["x"]}])),
        Case(b"[" * 100_000, ["arrays nested 100 000 deep: RecursionError"]),
        Case(MODEL_JSON.replace(b'"format_version": 1', b'"format_version": 1' + b"0" * 5000),
             ["an integer of 5000 digits: ValueError"]),
    ]


@settings(max_examples=examples(150))
@given(case=model_file())
@regressions(*model_regressions())
def test_model_file(case: Case, workdir: Path) -> None:
    m = outcome(lambda: load_model(put(workdir, "model.json", case.raw)))
    if m is None:
        return
    for name in ACCESSORS:
        if name == "phi" and outcome(lambda: m.config) is not None:
            m._model = outcome(lambda: robot_model(m))
        value = outcome(lambda: getattr(m, name))
        if name == "residual_variance" and value is not None:
            assert value.shape == (len(m.output_channels),) and np.isfinite(value).all()
