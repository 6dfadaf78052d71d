"""`dynid export --urdf OUT.urdf`: the identified robot as a URDF, and a side file for what URDF cannot hold.

The URDF is the configuration's own (its icub-models model, its path, or the supplied file the model file names),
with these changes and nothing else (the rest is kept byte for byte; see `_splice`):

- every link of an identified body gets a new `<inertial>`: mass, origin xyz = the centre of mass, rpy 0, and the
  inertia about the centre of mass in the link's axes. The values are the physically consistent full set nearest
  CAD that reproduces the identified base parameters (physical_set.py). A body is a Pinocchio joint's rigid set of
  links (fixed joints, locked joints): each of its links keeps its own `<inertial>`, in its own frame, and their sum
  is the body's identified set. An F/T sensor's proximal and distal sub-bodies are the links on either side of the
  sensor's fixed joint. Links the data do not reach (above the first moving joint) keep CAD.
- every actuated joint gets `<dynamics damping friction>`: URDF's friction model is symmetric (τ = −friction·sgn(q̇)
  − damping·q̇), so it gets the symmetric part of dynid's asymmetric one: friction = (fc_pos + fc_neg)/2 and
  damping = (fv_pos + fv_neg)/2 (a negative one is written as 0, and the side file says so).

The side file (OUT.dynamics.yaml, docs/formats.md) holds the asymmetric friction of every joint and motor, the
motor gains, the coupling, the F/T offsets, how the inertial set was chosen, and the provenance.

A configuration with its base below the URDF's root (re-rooted, dynid.robot.reroot) is written in the URDF's
original tree: inertias are per link, in the link's original frame, so they do not depend on the root.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import yaml

from ..errors import DataError, InputError
from ..identify.model_file import IdentifiedModel, file_digest
from ..identify.plausibility import implausible, masses_far_from_cad
from ..io.dataset import atomic_write
from ..robot.model import RobotModel
from ..robot.parameters import FRICTION_FIELDS, WRENCH_FIELDS
from ..version import __version__
from .physical_set import (PHYSICAL_TOL, LinkPart, NotReproducible, PhysicalSet, nearest_physical_set,
                           transform_matrix)

SIDE_FORMAT = "dynid-urdf-dynamics"
SIDE_VERSION = 1
NOT_REPRODUCIBLE = ("the identified base parameters are not reproduced by any physically consistent full set (the "
                    "unconstrained fit gave them); fit with the physically consistent estimator, or export the "
                    "nearest physical set with its residual by --nearest-physical")


def side_file(urdf_out: str | Path) -> Path:
    """OUT.urdf -> OUT.dynamics.yaml (any other name gets .dynamics.yaml appended)."""
    p = Path(urdf_out)
    return p.with_suffix(".dynamics.yaml") if p.suffix == ".urdf" else p.with_name(p.name + ".dynamics.yaml")


@dataclass
class UrdfExport:
    urdf: Path
    side: Path
    physical: PhysicalSet
    identified_links: list[str]
    cad_links: list[str]
    base_relative_error: float  # max |β(written) − β̂| / max |β̂| over the inertial base combinations
    rerooted: bool
    notes: list[str] = field(default_factory=list)
    moved_links: list[str] = field(default_factory=list)  # the identified links whose written values are not the URDF's


# ------------------------------------------------------------------------------------------------ the links


def link_inertial_parameters(link: ET.Element) -> np.ndarray:
    """φ of a URDF <link>'s <inertial>, about the link frame (zero without one)."""
    inertial = link.find("inertial")
    if inertial is None:
        return np.zeros(10)
    origin = inertial.find("origin")
    xyz = _floats(origin.get("xyz", "0 0 0") if origin is not None else "0 0 0")
    rpy = _floats(origin.get("rpy", "0 0 0") if origin is not None else "0 0 0")
    mass_el = inertial.find("mass")
    mass = float(mass_el.get("value", "0")) if mass_el is not None else 0.0
    i = inertial.find("inertia")
    get = (lambda k: float(i.get(k, "0"))) if i is not None else (lambda k: 0.0)
    ic = np.array([[get("ixx"), get("ixy"), get("ixz")], [get("ixy"), get("iyy"), get("iyz")],
                   [get("ixz"), get("iyz"), get("izz")]])
    R = pin.rpy.rpyToMatrix(rpy)
    return pin.Inertia(mass, xyz, R @ ic @ R.T).toDynamicParameters()


def link_parts(robot: RobotModel, tree: ET.ElementTree) -> list[LinkPart]:
    """Every URDF link of an identified body, with its placement map into the body's frame and its CAD φ.

    The placement of link L's original frame in body joint j's frame is computed at the neutral configuration of
    both models (the original URDF, and dynid's split, reduced and maybe re-rooted one), through the base link,
    which both share: jM_L = (bM_j)⁻¹ · bM_L. Checked: the links' CAD sets add up to each body's CAD set."""
    root = tree.getroot()
    links = {lk.get("name"): lk for lk in root.findall("link")}
    original = pin.buildModelFromXML(ET.tostring(root, encoding="unicode"))
    od = original.createData()
    pin.framesForwardKinematics(original, od, pin.neutral(original))
    red = robot.pin_model
    rd = red.createData()
    pin.framesForwardKinematics(red, rd, pin.neutral(red))
    base = robot.config.base_link
    o_base = od.oMf[original.getFrameId(base, pin.FrameType.BODY)]
    r_base = rd.oMf[red.getFrameId(base, pin.FrameType.BODY)]
    body_of_joint = {b.joint_id: k for k, b in enumerate(robot.bodies)}
    parts: list[LinkPart] = []
    for f in red.frames:
        if f.type != pin.FrameType.BODY or f.parentJoint == 0 or f.name not in links:
            continue
        k = body_of_joint[f.parentJoint]
        b_joint = r_base.inverse() * rd.oMi[f.parentJoint]
        b_link = o_base.inverse() * od.oMf[original.getFrameId(f.name, pin.FrameType.BODY)]
        placement = b_joint.inverse() * b_link
        parts.append(LinkPart(f.name, k, transform_matrix(placement.homogeneous),
                              link_inertial_parameters(links[f.name]), f.name == robot.bodies[k].name))
    cad = robot.cad_inertial_parameters
    for k, body in enumerate(robot.bodies):
        total = sum((p.A @ p.cad for p in parts if p.body == k), np.zeros(10))
        scale = max(1.0, float(np.abs(cad[10 * k : 10 * k + 10]).max()))
        if not any(p.body == k and p.carries_body_frame for p in parts) or \
                np.abs(total - cad[10 * k : 10 * k + 10]).max() > 1e-9 * scale:
            raise DataError(f"cannot map the body '{body.name}' onto the URDF's links (its links' inertials do not add "
                            "up to the body's): an unsupported URDF structure")
    return parts


def base_map(identified: IdentifiedModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The base-parameter map B (β = B Φ) of the fit, its inertial columns' part, and the base standard errors."""
    layout = identified.robot_model.layout
    base = identified.base
    if base is None:
        raise DataError(f"{identified.path}: the model's base section is unusable (it has none)")
    try:
        ind = [layout.index(n) for n in base.independent]
        dep = [layout.index(n) for n in base.dependent]
    except (KeyError, ValueError) as e:
        raise DataError(f"{identified.path}: the model's base section is unusable ({e.__class__.__name__})") from None
    B = np.zeros((len(ind), len(layout)))
    B[np.arange(len(ind)), ind] = 1.0
    if dep:
        B[:, dep] += base.K
    sigma = base.standard_errors if base.standard_errors.size else np.ones(len(ind))
    if sigma.size != len(ind) or not np.all(np.isfinite(sigma)):
        sigma = np.ones(len(ind))
    return B, B[:, layout.span("inertial")], sigma


# ------------------------------------------------------------------------------------------------ export


def export_urdf(identified: IdentifiedModel, out: str | Path, allow_residual: bool = False) -> UrdfExport:
    """Write OUT.urdf and its side file (see the module docstring); NotReproducible becomes one line (exit 2)."""
    robot = identified.robot_model
    source = robot.config.urdf
    text = source.read_text(encoding="utf-8")
    tree = ET.ElementTree(ET.fromstring(text))
    parts = link_parts(robot, tree)
    phi = identified.phi
    inertial = robot.layout.span("inertial")
    B, B_in, sigma = base_map(identified)
    rows = np.flatnonzero(np.abs(B_in).max(axis=1) > 0)
    try:
        physical = nearest_physical_set(parts, phi[inertial], B_in[rows], sigma[rows], allow_residual)
    except NotReproducible as failed:
        if identified.consistent is not None:  # its bodies are physical: their split over the URDF's links is not found
            own = nearest_physical_set(parts, phi[inertial], B_in[rows], sigma[rows], own=True)
            why = ("its bodies sit on the boundary of the physical set" if own.min_eigenvalue >= -PHYSICAL_TOL else
                   "a body's difference to CAD on its own link alone is not physical: the body is far lighter or "
                   "heavier than the URDF's links of it")
            raise InputError(f"the solver ({failed}) finds no split of this consistent fit's bodies over the URDF's "
                             f"links that reproduces its base parameters exactly ({why}); export the nearest one, with "
                             "its residual, by --nearest-physical") from None
        raise InputError(NOT_REPRODUCIBLE) from None
    def written_set(found: PhysicalSet) -> tuple[dict[str, np.ndarray], np.ndarray, list[str]]:
        """Each link's φ, the bodies' full set and what is implausible about it (a link's mass out of its reach)."""
        links = {p.link: found.links.get(p.link, p.cad) for p in parts}
        bodies = np.concatenate([sum((p.A @ links[p.link] for p in parts if p.body == k), np.zeros(10))
                                 for k in range(len(robot.bodies))])
        full = np.array(phi, float)
        full[inertial] = bodies
        # a link's placement; gravity's direction is the fit's to say (`dynid fit`), and the same for either set
        return links, bodies, [f"the written set: {p['text']}" for p in implausible(robot, full)
                               if p["problem"] != "gravity"]

    written, bodies, odd = written_set(physical)
    if odd and identified.consistent is not None:
        # The solver's nearest-CAD set satisfies the cone but not the links' reach (an inaccurate solve put wrist_3's
        # centre of mass 13 m out); the consistent fit's own set is physical by construction: written where plausible
        own = nearest_physical_set(parts, phi[inertial], B_in[rows], sigma[rows], own=True)
        own_written, own_bodies, own_odd = written_set(own)
        if own.min_eigenvalue >= -PHYSICAL_TOL and not own_odd:
            why = "; ".join(o.removeprefix("the written set: ") for o in odd)
            own.notes.append(f"the nearest-CAD search gave an implausible set ({why}; solver status "
                             f"{physical.status}): the consistent fit's own set is written instead")
            physical, written, bodies, odd = own, own_written, own_bodies, []
    beta_hat = B_in[rows] @ phi[inertial]
    relative = float(np.abs(B_in[rows] @ bodies - beta_hat).max(initial=0.0) / max(np.abs(beta_hat).max(initial=0.0),
                                                                                  1e-300))
    identified_links = [p.link for p in parts if p.variable]
    moved_links = [p.link for p in parts if p.variable and _moved(written[p.link], p.cad)]
    cad_links = [lk.get("name") for lk in tree.getroot().findall("link") if lk.get("name") not in identified_links]

    inertials = {name: _inertial_xml(written[name]) for name in identified_links}
    notes = list(physical.notes)
    if physical.status not in ("optimal", "the model's own set"):
        notes.append(f"the solver's status: {physical.status}")
    if odd:  # physical, but not what the link can be: the base parameters alone do not place its mass
        notes += odd + (["`dynid fit --consistent on` identifies a set in which every link is physical and its mass "
                         "within the link's reach"] if identified.consistent is None else [])
    full = np.array(phi, float)
    full[inertial] = bodies
    notes += [f"the written set: {w['text']}" for w in masses_far_from_cad(robot, full)]
    dynamics, joint_rows = _joint_dynamics(identified, notes)
    urdf_text = _splice(text, inertials, dynamics)
    side = side_file(out)
    record = _side_record(identified, Path(out), source, physical, relative, identified_links, cad_links,
                          joint_rows, robot, notes, moved_links)
    side_text = yaml.safe_dump(record, sort_keys=False, width=120)
    had_side = side.exists()
    atomic_write(side, lambda f: f.write(side_text.encode()))
    try:
        atomic_write(Path(out), lambda f: f.write(urdf_text.encode()))
    except BaseException:
        if not had_side:  # no side file without its URDF
            side.unlink(missing_ok=True)
        raise
    return UrdfExport(Path(out), side, physical, identified_links, cad_links, relative,
                      bool(robot.reversed_joints), notes, moved_links)


def _moved(phi: np.ndarray, cad: np.ndarray) -> bool:
    """The written link differs from the URDF's by more than the conic solver's noise: 0.1 % of its mass, of its mass
    times its extent, and of that times its extent again for the inertias."""
    m = max(float(cad[0]), float(phi[0]), 1e-9)
    length = max(float(np.linalg.norm(cad[1:4])) / m, 0.01)
    scale = np.r_[m, np.full(3, m * length), np.full(6, m * length**2)]
    return bool(np.max(np.abs(phi - cad) / scale) > 1e-3)


def _inertial_xml(phi: np.ndarray) -> dict[str, Any]:
    m = float(phi[0])
    if m <= 0:
        return {"mass": 0.0, "com": np.zeros(3), "inertia": np.zeros((3, 3))}
    inertia = pin.Inertia.FromDynamicParameters(np.asarray(phi, float))
    return {"mass": m, "com": np.array(inertia.lever), "inertia": np.array(inertia.inertia)}


def _joint_dynamics(identified: IdentifiedModel, notes: list[str]) -> tuple[dict[str, tuple[float, float]],
                                                                             dict[str, dict[str, float]]]:
    """URDF <dynamics> (damping, friction) per actuated joint, and the side file's rows."""
    layout, params = identified.robot_model.layout, identified.parameters
    urdf: dict[str, tuple[float, float]] = {}
    rows: dict[str, dict[str, float]] = {}
    for joint in layout.owners("joint_friction"):
        f = {k: params[f"{joint}.{k}"] for k in FRICTION_FIELDS}
        damping, friction = (f["fv_pos"] + f["fv_neg"]) / 2, (f["fc_pos"] + f["fc_neg"]) / 2
        for what, value in (("damping", damping), ("friction", friction)):
            if value < 0:
                notes.append(f"{joint}: the symmetric {what} {value:.6g} is negative; the URDF says 0")
        urdf[joint] = (max(damping, 0.0), max(friction, 0.0))
        rows[joint] = {**f, "urdf_damping": urdf[joint][0], "urdf_friction": urdf[joint][1]}
    return urdf, rows


def _side_record(identified: IdentifiedModel, out: Path, source: Path, physical: PhysicalSet, relative: float,
                 identified_links: list[str], cad_links: list[str], joint_rows: dict[str, dict[str, float]],
                 robot: RobotModel, notes: list[str], moved: list[str]) -> dict[str, Any]:
    config, params, layout = robot.config, identified.parameters, robot.layout
    motors: dict[str, Any] = {}
    coupling: dict[str, Any] = {}
    for g in config.actuation:
        if g.coupled:
            coupling[g.name] = {"joints": list(g.joints), "motors": list(g.motors),
                                "matrix": np.asarray(g.coupling, float).tolist()}
        for mo in g.motors:
            mc = config.motor(mo)
            row: dict[str, Any] = {"group": g.name, "input": g.input}
            if g.input != "torque":
                if mc.known_gain is not None:
                    row.update(gain=float(mc.known_gain), gain_source="known (configuration)")
                else:
                    row.update(gain=params[f"{mo}.phi_m"], gain_source="identified")
            if mo in layout.owners("motor_friction"):
                row["friction"] = {k: params[f"{mo}.{k}"] for k in FRICTION_FIELDS}
            motors[mo] = row
    ft = {s.name: {"joint": s.joint, "offset": {k: params[f"ft.{s.name}.offset.{k}"] for k in WRENCH_FIELDS}}
          for s in config.ft_sensors}
    model_path = Path(identified.path) if identified.path else None
    record: dict[str, Any] = {
        "format": SIDE_FORMAT,
        "format_version": SIDE_VERSION,
        "urdf": out.name,
        "robot": config.name,
        "provenance": {
            "dynid_version": __version__,
            "model": {"path": str(model_path.resolve()) if model_path else None,
                      "sha256": file_digest(model_path) if model_path and model_path.is_file() else None},
            "source_urdf": {"path": str(source.resolve()), "sha256": file_digest(source)},
            "estimator": identified.estimator,
        },
        "tree": {"base_link": config.base_link, "rerooted": bool(robot.reversed_joints),
                 "note": "written in the URDF's original tree; inertias are per link in link frames"},
        "inertial": {
            "method": "nearest CAD in scaled parameters (mass m, first moments m·L, inertias m·L²) subject to the "
                      "identified base parameters and J ⪰ 0 per link (cvxpy, Clarabel)",
            "distance_to_cad": physical.distance,
            "min_scaled_pseudo_inertia_eigenvalue": physical.min_eigenvalue,
            "base_relative_error": relative,
            "solver_status": physical.status,
            "identified_links": identified_links,
            "moved_links": [lk for lk in identified_links if lk in moved],
            "cad_links": "every other link keeps the source URDF's <inertial>",
        },
        "friction_model": "tau_f = fc_pos*[dq>0] - fc_neg*[dq<0] + fv_pos*max(dq,0) + fv_neg*min(dq,0); "
                          "the URDF's <dynamics> holds friction = (fc_pos+fc_neg)/2, damping = (fv_pos+fv_neg)/2",
        "joints": joint_rows,
        "motors": motors,
        "coupling": coupling,
        "ft_sensors": ft,
    }
    if identified.named_effects:
        record["effects"] = [e.as_dict() for e in identified.named_effects]
    if notes:
        record["notes"] = notes
    return _plain(record)


def _plain(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return _plain(x.tolist())
    if isinstance(x, (np.floating, float)):
        return float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    return x


# ------------------------------------------------------------------------------------------------ the text


def _num(x: float) -> str:
    return repr(float(x)) if x != 0 else "0"


def _inertial_text(v: dict[str, Any], indent: str, step: str) -> str:
    c, i = v["com"], v["inertia"]
    inner = indent + step
    return (f"<inertial>\n{inner}<origin xyz=\"{_num(c[0])} {_num(c[1])} {_num(c[2])}\" rpy=\"0 0 0\"/>\n"
            f"{inner}<mass value=\"{_num(v['mass'])}\"/>\n"
            f"{inner}<inertia ixx=\"{_num(i[0, 0])}\" ixy=\"{_num(i[0, 1])}\" ixz=\"{_num(i[0, 2])}\" "
            f"iyy=\"{_num(i[1, 1])}\" iyz=\"{_num(i[1, 2])}\" izz=\"{_num(i[2, 2])}\"/>\n{indent}</inertial>")


def _dynamics_text(damping: float, friction: float) -> str:
    return f"<dynamics damping=\"{_num(damping)}\" friction=\"{_num(friction)}\"/>"


def _element(text: str, tag: str, name: str | None, start: int = 0, end: int | None = None) -> tuple[int, int, bool]:
    """(start, end, self_closing) of the first <tag> (with name="name" if given) in text[start:end]; (-1, -1, _)
    when there is none."""
    end = len(text) if end is None else end
    named = rf"[^>]*?\bname\s*=\s*([\"']){re.escape(name)}\1" if name is not None else ""
    m = re.compile(rf"<{tag}\b{named}[^>]*?(/?)>", re.S).search(text, start, end)
    if m is None:
        return -1, -1, False
    if m.group(m.lastindex) == "/":
        return m.start(), m.end(), True
    close = text.find(f"</{tag}>", m.end(), end)
    if close < 0:
        return -1, -1, False
    return m.start(), close + len(f"</{tag}>"), False


def _indent_at(text: str, pos: int) -> str:
    line = text.rfind("\n", 0, pos) + 1
    lead = text[line:pos]
    return lead if not lead.strip() else ""


def _splice(text: str, inertials: dict[str, dict[str, Any]], dynamics: dict[str, tuple[float, float]]) -> str:
    """The URDF text with new <inertial>s and <dynamics>, every other byte kept; checked against the same change made
    on the parsed tree (canonical XML), and made on the tree instead where the text is too unusual to splice."""
    edits: list[tuple[int, int, str]] = []
    try:
        for kind, items in (("link", inertials), ("joint", dynamics)):
            for name, value in items.items():
                s, e, closed = _element(text, kind, name)
                if s < 0:
                    raise ValueError(name)
                outer = _indent_at(text, s)
                step = "  "
                child = "inertial" if kind == "link" else "dynamics"
                new = _inertial_text(value, outer + step, step) if kind == "link" else _dynamics_text(*value)
                if closed:
                    opening = text[s:e][:-2].rstrip() + ">"
                    edits.append((s, e, f"{opening}\n{outer}{step}{new}\n{outer}</{kind}>"))
                    continue
                cs, ce, _ = _element(text, child, None, s, e)
                if cs >= 0:
                    if kind == "link":
                        new = _inertial_text(value, _indent_at(text, cs) or outer + step, step)
                    edits.append((cs, ce, new))
                else:
                    close = e - len(f"</{kind}>")
                    edits.append((close, close, f"{step}{new}\n{outer}" if _indent_at(text, close) == outer else new))
    except ValueError:
        edits = []
    out = text
    for s, e, new in sorted(edits, reverse=True):
        out = out[:s] + new + out[e:]
    expected = _tree_edit(text, inertials, dynamics)
    if edits and _canonical(out) == _canonical(expected):
        return out
    return expected


def _tree_edit(text: str, inertials: dict[str, dict[str, Any]], dynamics: dict[str, tuple[float, float]]) -> str:
    parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
    root = ET.fromstring(text, parser=parser)
    for link in root.findall("link"):
        v = inertials.get(link.get("name"))
        if v is None:
            continue
        old = link.find("inertial")
        new = ET.fromstring(_inertial_text(v, "", ""))
        if old is not None:
            link.insert(list(link).index(old), new)
            link.remove(old)
        else:
            link.append(new)
    for joint in root.findall("joint"):
        d = dynamics.get(joint.get("name"))
        if d is None:
            continue
        old = joint.find("dynamics")
        new = ET.fromstring(_dynamics_text(*d))
        if old is not None:
            joint.insert(list(joint).index(old), new)
            joint.remove(old)
        else:
            joint.append(new)
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _canonical(text: str) -> str:
    body = re.sub(r"^\s*<\?xml[^>]*\?>", "", text)
    return ET.canonicalize(body, strip_text=True, with_comments=False)


def _floats(text: str) -> np.ndarray:
    return np.array([float(v) for v in text.split()])
