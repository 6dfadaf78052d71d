"""Re-rooting a URDF tree at another link: a humanoid standing on one foot as a fixed-base chain from its sole.

A URDF is a tree hung from one root link, and a fixed-base model fixes that root. When the robot stands on a foot,
the link that is still is the sole, so the tree is turned over: every joint on the path from the new root up to
the old one is reversed (its parent becomes its child).

URDF puts a joint's motion after its `<origin>` and makes the child link's frame the joint's frame, so a reversed
revolute joint cannot keep its old child's frame. With T_PC(q) = O Rot(a, q) the old placement of child C in
parent P, the reversed joint must give T_CP(q) = Rot(a, -q) O⁻¹, whose motion comes first. The old parent P
therefore takes the joint's frame as its own (P' = P·O), and then T_CP'(q) = Rot(-a, q): origin identity, axis
negated, the same joint value q. Everything expressed in P (its inertial, visual and collision origins and the
origins of its other children) is re-expressed in P'; a link further up the path composes these shifts (S below).
The new root keeps its frame, so gravity given in it means what it says.

Links off the path keep their frames, so F/T sensors off the path measure exactly as before. A sensor joint on the
path would swap its proximal and distal sides (and its measurement's sign and frame); it is refused by
`RobotModel`, not converted.
"""

from __future__ import annotations

import copy
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin

from ..errors import ConfigError


def path_to_root(root: ET.Element, link: str) -> list[ET.Element]:
    """The joints from `link` up to the URDF's root, nearest first."""
    parent_joint = {j.find("child").get("link"): j for j in root.findall("joint")}
    path, seen = [], {link}
    while link in parent_joint:
        joint = parent_joint[link]
        path.append(joint)
        link = joint.find("parent").get("link")
        if link in seen:  # a malformed URDF: a cycle would loop forever
            raise ConfigError(f"the URDF's joints form a cycle through link '{link}'")
        seen.add(link)
    return path


def reroot(tree: ET.ElementTree, new_root: str) -> tuple[ET.ElementTree, tuple[str, ...]]:
    """A copy of `tree` whose root is the link `new_root`, and the names of the joints that were reversed."""
    tree = copy.deepcopy(tree)
    root = tree.getroot()
    links = {lk.get("name"): lk for lk in root.findall("link")}
    if new_root not in links:
        raise ConfigError(f"cannot re-root the URDF at '{new_root}': no such link")
    path = path_to_root(root, new_root)
    reversed_joints = {id(j) for j in path}

    shift: dict[str, pin.SE3] = {new_root: pin.SE3.Identity()}  # S_L: the new frame of link L in its old frame
    for joint in path:
        child, parent = joint.find("child").get("link"), joint.find("parent").get("link")
        origin = _origin(joint)
        s_child = shift[child]
        _set_origin(joint, s_child.inverse())
        axis = joint.find("axis")
        if joint.get("type") in ("revolute", "continuous", "prismatic"):
            a = np.array([float(v) for v in (axis.get("xyz") if axis is not None else "1 0 0").split()])
            if axis is None:
                axis = ET.SubElement(joint, "axis")
            axis.set("xyz", _text(-a))
        joint.find("child").set("link", parent)
        joint.find("parent").set("link", child)
        shift[parent] = origin  # the reversed joint's frame becomes the old parent's frame

    for name, s in shift.items():
        if name == new_root or _is_identity(s):
            continue
        inverse = s.inverse()
        link = links[name]
        for element in [link.find("inertial"), *link.findall("visual"), *link.findall("collision")]:
            if element is not None:
                _set_origin(element, inverse * _origin(element))
        for joint in root.findall("joint"):
            if id(joint) not in reversed_joints and joint.find("parent").get("link") == name:
                _set_origin(joint, inverse * _origin(joint))
    return tree, tuple(j.get("name") for j in path)


def _origin(element: ET.Element) -> pin.SE3:
    origin = element.find("origin")
    if origin is None:
        return pin.SE3.Identity()
    xyz = np.array([float(v) for v in origin.get("xyz", "0 0 0").split()])
    rpy = np.array([float(v) for v in origin.get("rpy", "0 0 0").split()])
    return pin.SE3(pin.rpy.rpyToMatrix(rpy), xyz)


def _set_origin(element: ET.Element, placement: pin.SE3) -> None:
    origin = element.find("origin")
    if origin is None:
        origin = ET.Element("origin")
        element.insert(0, origin)
    origin.set("xyz", _text(placement.translation))
    origin.set("rpy", _text(pin.rpy.matrixToRpy(placement.rotation)))


def _is_identity(s: pin.SE3) -> bool:
    return bool(np.allclose(s.homogeneous, np.eye(4), atol=1e-15))


def _text(v: np.ndarray) -> str:
    return " ".join(repr(float(x)) for x in v)
