"""`dynid export --model MODEL --urdf OUT.urdf` (issue 21): the identified robot as a URDF that Pinocchio loads, whose
`rnea` reproduces the model's rigid-body predictions on the validation run to round-off; its side file; bad input.

The round trip needs a model whose base parameters some physical full set reproduces. The default fit is the
unconstrained one until the physically consistent fit is the default (issue 21, item 1): then its export is refused
(exit 2, one line), and the round trip runs on `physical_model` of it, the model with the nearest physical set
(what a consistent fit hands on). Once the default fit is consistent, the default model itself takes the round trip.
"""

from __future__ import annotations

import hashlib
import json
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml
from conftest import dynid

from dynid.export.physical_set import PHYSICAL_TOL
from dynid.export.urdf_check import physical_model, round_trip
from dynid.identify.model_file import load_model
from dynid.identify.validation import load_run
from dynid.robot.regressors.stack import signals_from_dataset

TOLERANCE = 1e-9  # relative, per channel
STRIDE = 100  # every 100th sample of the 300 s validation run: 3000 states


@pytest.fixture(scope="module")
def exportable(default_model: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, bool]:
    """A model that `export --urdf` takes without --nearest-physical, and whether it is the default model itself."""
    out = tmp_path_factory.mktemp("urdf") / "probe.urdf"
    if dynid("export", "--model", str(default_model), "--urdf", str(out)).returncode == 0:
        return default_model, True
    path = out.with_name("physical.json")
    physical_model(load_model(default_model)).save(path)
    return path, False


def signals(model_path: Path, run: Path):
    identified = load_model(model_path)
    sig = signals_from_dataset(identified.robot_model, load_run(str(run), identified.robot_model))
    return identified, sig.q[::STRIDE], sig.dq[::STRIDE], sig.ddq[::STRIDE]


def test_urdf_round_trip_on_the_simulated_arm(exportable: tuple[Path, bool], default_experiments: dict[str, Path],
                                              tmp_path: Path) -> None:
    model, _ = exportable
    out = tmp_path / "arm.urdf"
    done = dynid("export", "--model", str(model), "--urdf", str(out), "--json", str(tmp_path / "r.json"))
    assert done.returncode == 0, done.stderr
    result = json.loads((tmp_path / "r.json").read_text())
    # physical to the conic solver's tolerance: the set is projected with cvxpy, whose round-off differs by CPU
    assert result["base_relative_error"] < 1e-12 and result["min_scaled_pseudo_inertia_eigenvalue"] > -PHYSICAL_TOL
    identified, q, dq, ddq = signals(model, default_experiments["validation"])
    errors = round_trip(identified, out, q, dq, ddq)
    print("URDF round trip, simulated arm (max relative error per channel): "
          + ", ".join(f"{k} {v:.1e}" for k, v in errors.items()))
    assert {f"plain.tau.{j}" for j in identified.config.joints} <= set(errors)
    assert {f"split.ft.r_arm_ft.{k}" for k in ("fx", "fy", "fz", "tx", "ty", "tz")} <= set(errors)
    assert max(errors.values()) < TOLERANCE, errors

    # Every identified link is physical as written (principal moments ≥ 0, triangle inequality, positive mass).
    urdf = pin.buildModelFromUrdf(str(out))
    for link in result["identified_links"]:
        inertia = urdf.inertias[urdf.frames[urdf.getFrameId(link, pin.FrameType.BODY)].parentJoint]
        moments = np.linalg.eigvalsh(np.array(inertia.inertia))
        assert inertia.mass > 0 and moments.min() >= 0 and moments[0] + moments[1] >= moments[2] * (1 - 1e-12)

    # Only the identified links' <inertial> and the actuated joints' <dynamics> changed; the rest is verbatim.
    source = identified.config.urdf.read_text(encoding="utf-8")
    written = out.read_text(encoding="utf-8")
    assert _without(source, result["identified_links"], identified.config.joints) == \
        _without(written, result["identified_links"], identified.config.joints)
    assert written.splitlines()[:5] == source.splitlines()[:5]  # the header and its comments, byte for byte

    # The side file: the asymmetric friction, the gains, the coupling, the offsets and the provenance.
    side = yaml.safe_load(out.with_suffix(".dynamics.yaml").read_text())
    p = identified.parameters
    assert side["format"] == "dynid-urdf-dynamics" and side["urdf"] == "arm.urdf"
    assert side["provenance"]["model"]["sha256"] == hashlib.sha256(model.read_bytes()).hexdigest()
    for joint, row in side["joints"].items():
        assert row["fc_pos"] == p[f"{joint}.fc_pos"] and row["fv_neg"] == p[f"{joint}.fv_neg"]
        dynamics = ET.fromstring(written).find(f"joint[@name='{joint}']/dynamics")
        assert float(dynamics.get("damping")) == max((p[f"{joint}.fv_pos"] + p[f"{joint}.fv_neg"]) / 2, 0.0)
        assert float(dynamics.get("friction")) == max((p[f"{joint}.fc_pos"] + p[f"{joint}.fc_neg"]) / 2, 0.0)
    assert side["motors"]["m0"]["gain"] == p["m0.phi_m"] and "friction" in side["motors"]["m0"]
    assert side["coupling"]["shoulder"]["matrix"][1] == [-1.625, 1.625, 0.0]
    assert side["ft_sensors"]["r_arm_ft"]["offset"]["fz"] == p["ft.r_arm_ft.offset.fz"]


def _without(text: str, links: list[str], joints: tuple[str, ...]) -> str:
    root = ET.fromstring(text)
    for link in root.findall("link"):
        if link.get("name") in links and link.find("inertial") is not None:
            link.remove(link.find("inertial"))
    for joint in root.findall("joint"):
        if joint.get("name") in joints and joint.find("dynamics") is not None:
            joint.remove(joint.find("dynamics"))
    return ET.canonicalize(ET.tostring(root, encoding="unicode"), strip_text=True)


def test_an_unphysical_fit_is_refused_or_exported_nearest_with_its_residual(
        exportable: tuple[Path, bool], default_model: Path, default_experiments: dict[str, Path],
        tmp_path: Path) -> None:
    if exportable[1]:
        pytest.skip("the default fit is physically consistent: nothing to refuse")
    out = tmp_path / "arm.urdf"
    done = dynid("export", "--model", str(default_model), "--urdf", str(out))
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "physically consistent" in done.stderr and "--nearest-physical" in done.stderr
    assert not list(tmp_path.iterdir())  # nothing written

    done = dynid("export", "--model", str(default_model), "--urdf", str(out), "--nearest-physical", "--json", "-")
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert result["nearest_physical"] and result["notes"] and "standard errors RMS" in result["notes"][0]
    assert result["min_scaled_pseudo_inertia_eigenvalue"] > -PHYSICAL_TOL
    identified, q, dq, ddq = signals(default_model, default_experiments["validation"])
    errors = round_trip(identified, out, q, dq, ddq)
    print(f"nearest physical set: base residual {result['notes'][0]}; rnea against the unconstrained model's "
          f"predictions, max relative error {max(errors.values()):.3g}")
    assert max(errors.values()) < 0.2  # near the identified model, not equal to it


def test_bad_input_is_one_line_and_writes_nothing(exportable: tuple[Path, bool], tmp_path: Path) -> None:
    model = exportable[0]
    cases = [
        (("--urdf", str(tmp_path / "missing" / "a.urdf")), "does not exist"),
        (("--urdf", str(model)), "the input --model"),
        (("--urdf", str(tmp_path)), "not a regular file"),
    ]
    for args, says in cases:
        done = dynid("export", "--model", str(model), *args)
        assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1 and says in done.stderr, done.stderr
    done = dynid("export", "--model", str(model), "--nearest-physical", "--out", str(tmp_path / "c.dcoef"))
    assert done.returncode == 2 and "--nearest-physical goes with" in done.stderr

    # A model whose robot URDF is gone: its configuration names a file beside it that was deleted.
    data = json.loads(model.read_text())
    urdf = tmp_path / "arm.urdf"
    urdf.write_bytes(load_model(model).config.urdf.read_bytes())
    text = data["robot"]["config_text"].replace("urdf: {icub_models: iCubGenova04}", "urdf: {path: arm.urdf}")
    config = tmp_path / "arm.yaml"
    config.write_text(text)
    data["robot"].update(config_source=str(config), config_text=text, urdf=str(urdf),
                         config_digest=hashlib.sha256(text.encode()).hexdigest())
    moved = tmp_path / "moved.json"
    moved.write_text(json.dumps(data))
    urdf.unlink()
    before = set(tmp_path.iterdir())
    done = dynid("export", "--model", str(moved), "--urdf", str(tmp_path / "out.urdf"))
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "the robot's URDF cannot be found" in done.stderr and "DYNID_URDF_PATH" in done.stderr
    assert set(tmp_path.iterdir()) == before


def test_a_rerooted_configuration_is_written_in_the_original_tree(tmp_path: Path) -> None:
    """The iCub standing on its left sole (the URDF re-rooted there, tests/test_reroot.py's set-up): the exported
    URDF keeps the original tree (root_link the root), and re-rooted again by the configuration it reproduces the
    model's joint torques and both right-leg F/T wrenches. The model is synthetic: every body's CAD set scaled by
    its own factor (physical), with the structural base parameters of the chain."""
    from dataclasses import replace

    from test_reroot import _config

    from dynid.export.urdf import export_urdf
    from dynid.identify.model_file import IdentifiedModel, robot_record
    from dynid.identify.model_sections import BaseSection
    from dynid.robot.model import RobotModel
    from dynid.robot.regressors.base import base_parameters_from_factor, exciting_signals, triangular_factor
    from dynid.robot.regressors.rigid_body import rigid_body_regressors

    config = _config(tmp_path)
    robot = RobotModel(config)
    assert robot.reversed_joints  # re-rooted at l_sole
    span = robot.layout.span("inertial")
    phi = np.zeros(len(robot.layout))
    factors = np.linspace(0.8, 1.2, len(robot.bodies))
    phi[span] = robot.cad_inertial_parameters * np.repeat(factors, 10)
    # The base parameters of everything the rigid bodies predict: every joint torque and both sensors' wrenches
    # (the configuration has no actuation, so its own stacked system holds the F/T rows alone).
    sig = exciting_signals(robot, n_samples=300, seed=0)
    reg = rigid_body_regressors(robot, sig.q, sig.dq, sig.ddq)
    A = np.concatenate([reg.tau.reshape(-1, span.stop)] + [f.reshape(-1, span.stop) for f in reg.ft.values()])
    names = robot.layout.names
    base = base_parameters_from_factor(triangular_factor([(A, np.zeros(A.shape[0]))], span.stop), names[span])
    independent = tuple(names[i] for i in base.independent)
    section = BaseSection(base.rank, independent, independent, tuple(names[i] for i in base.dependent), base.K,
                          base.base(phi[span]), np.ones(base.rank), np.ones(base.rank, bool))
    identified = IdentifiedModel(robot_record(config), dict(zip(names, phi.tolist())), base=section)
    identified._config, identified._model = config, robot
    out = tmp_path / "standing.urdf"
    done = export_urdf(identified, out)
    assert done.rerooted and done.base_relative_error < 1e-12
    tree = ET.parse(out).getroot()
    children = {j.find("child").get("link") for j in tree.findall("joint")}
    assert [lk.get("name") for lk in tree.findall("link") if lk.get("name") not in children] == ["root_link"]
    sig = exciting_signals(robot, n_samples=200, seed=3)  # other states than the base parameters were found on
    errors = round_trip(identified, out, sig.q, sig.dq, sig.ddq)
    assert not any(k.startswith("plain.") for k in errors)  # the plain reading needs the URDF's own root
    assert {"split.ft.r_leg_ft.fz", "split.ft.r_foot_ft.tz"} <= set(errors)
    assert max(errors.values()) < TOLERANCE, errors
    # Re-rooted again by the configuration, the URDF as written carries the model's base parameters.
    again = RobotModel(replace(config, urdf=out)).cad_inertial_parameters
    assert np.abs(base.base(again) - base.base(phi[span])).max() < 1e-9 * np.abs(base.base(phi[span])).max()


def test_a_physical_model_on_the_cone_s_boundary_still_reproduces_exactly(
        exportable: tuple[Path, bool], default_model: Path, default_experiments: dict[str, Path],
        tmp_path: Path) -> None:
    """A consistent fit may leave a body on the boundary of J ⪰ 0 (a point mass: the hand's ten parameters all
    identified). Its own full set is physical, so the export must take it and reproduce it to round-off, though the
    solver finds no strict interior there."""
    from dynid.export.physical_set import PHYSICAL_TOL
    from dynid.export.urdf import base_map, export_urdf

    identified = physical_model(load_model(default_model))
    layout = identified.robot_model.layout
    for body in ("r_hand", "r_forearm"):
        names = layout.block("inertial", body).names
        m, h = identified.parameters[names[0]], np.array([identified.parameters[n] for n in names[1:4]])
        c = h / m
        inertia = m * (c @ c * np.eye(3) - np.outer(c, c))  # a point mass at the centre of mass
        point = [m, *h, inertia[0, 0], inertia[0, 1], inertia[1, 1], inertia[0, 2], inertia[1, 2], inertia[2, 2]]
        identified.parameters.update(zip(names, point))
    B = base_map(identified)[0]
    identified.base = replace(identified.base, values=B @ identified.phi)
    done = export_urdf(identified, tmp_path / "point.urdf")
    # Physical as the exporter defines it (PHYSICAL_TOL, the solver's round-off): on the boundary the solver's last
    # iterate falls on either side by its last bits (−6e-12 on one CPU's kernels, an "optimal_inaccurate" solve).
    assert done.base_relative_error < 1e-12 and done.physical.min_eigenvalue > -PHYSICAL_TOL
    _, q, dq, ddq = signals(exportable[0], default_experiments["validation"])
    errors = round_trip(identified, tmp_path / "point.urdf", q[::10], dq[::10], ddq[::10])
    assert max(errors.values()) < TOLERANCE, errors


def test_the_splice_keeps_every_other_byte_and_falls_back_to_the_tree_when_the_text_is_unusual() -> None:
    from dynid.export.urdf import _splice

    inertial = {"mass": 2.0, "com": np.array([0.1, 0.0, -0.2]), "inertia": np.diag([0.01, 0.02, 0.03])}
    text = """<?xml version="1.0"?>
<!-- a comment the splice keeps -->
<robot name="r">
  <link name="a"/>
  <link name='b'>
    <visual><geometry><box size="1 1 1"/></geometry></visual>
  </link>
  <link name="c">
    <inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
  </link>
  <joint name="j1" type="revolute"><parent link="a"/><child link="b"/><dynamics damping="0.0"/></joint>
  <joint name="j2" type="revolute">
    <parent link="b"/><child link="c"/>
  </joint>
</robot>
"""
    out = _splice(text, {"a": inertial, "b": inertial, "c": inertial}, {"j1": (0.5, 0.25), "j2": (1.0, 2.0)})
    assert out.startswith('<?xml version="1.0"?>\n<!-- a comment the splice keeps -->\n<robot name="r">\n')
    root = ET.fromstring(out)
    for link in root.findall("link"):
        assert float(link.find("inertial/mass").get("value")) == 2.0
        assert link.find("inertial/origin").get("xyz") == "0.1 0 -0.2"
    assert root.find("link[@name='b']/visual/geometry/box") is not None
    assert [(j.find("dynamics").get("damping"), j.find("dynamics").get("friction")) for j in root.findall("joint")] \
        == [("0.5", "0.25"), ("1.0", "2.0")]
    # A comment that looks like the element: the text is not spliced blindly; the tree is edited instead.
    tricky = text.replace("<!-- a comment the splice keeps -->", '<!-- <link name="c"><inertial/></link> -->')
    root = ET.fromstring(_splice(tricky, {"c": inertial}, {}))
    assert float(root.find("link[@name='c']/inertial/mass").get("value")) == 2.0


def test_the_api_writes_the_same_urdf(exportable: tuple[Path, bool], tmp_path: Path) -> None:
    import dynid as api

    done = api.export_urdf(api.load_model(exportable[0]), tmp_path / "api.urdf")
    assert done.base_relative_error < 1e-12 and (tmp_path / "api.dynamics.yaml").is_file()
    cli = tmp_path / "cli.urdf"
    assert dynid("export", "--model", str(exportable[0]), "--urdf", str(cli)).returncode == 0
    assert (tmp_path / "api.urdf").read_text() == cli.read_text()
