"""Contact episodes of the `contact` experiment, and the skin's ground truth.

A patch of skin covers one or more links (the configuration's `can.skin`, or one patch per body without it).
An episode pushes on a random point of a random patch: onset after a random gap (1–4 s), duration 0.3–3 s,
magnitude 2–15 N, raised-cosine ramps of 30 ms at both ends. The point lies on a cylinder of radius 3 cm around
the segment from the link's origin to twice its centre of mass (where the link's material is), and the force
pushes inward, tilted up to 30° from the surface normal. The side of the F/T sensor is physics: a force on a
body beyond the sensor is `distal`, else `proximal`; the configured side of a patch must agree.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..config.robot_config import RobotConfig
from ..errors import ConfigError
from .plant import BodySite, RigidBodyPlant

RAMP_S = 0.03
FORCE_RANGE_N = (2.0, 15.0)
DURATION_RANGE_S = (0.3, 3.0)
SKIN_RADIUS_M = 0.03


@dataclass(frozen=True)
class Patch:
    name: str
    links: tuple[str, ...]
    side: str  # distal | proximal of the (first) F/T sensor


@dataclass(frozen=True)
class Episode:
    onset: float  # s
    end: float  # s
    patch: int  # index into the patches (0-based)
    link: str
    side: str
    point: np.ndarray  # (3,) link frame, m
    force: np.ndarray  # (3,) link frame, N (direction × magnitude)

    def as_dict(self, patches: list[Patch]) -> dict:
        return {
            "onset_s": self.onset, "end_s": self.end, "patch": patches[self.patch].name, "link": self.link,
            "side": self.side, "point_m": self.point.tolist(), "force_n": self.force.tolist(),
            "magnitude_n": float(np.linalg.norm(self.force)),
        }


def skin_patches(config: RobotConfig, plant: RigidBodyPlant) -> list[Patch]:
    sensor = config.ft_sensors[0].name if config.ft_sensors else None

    def side(link: str) -> str:
        return plant.side_of(plant.sites[link], sensor) if sensor else "proximal"

    skin = config.can.get("skin", [])
    if not skin:
        return [Patch(link, (link,), side(link)) for link in plant.sites]
    patches = []
    for entry in skin:
        links = tuple(entry.get("links") or [entry["patch"]])
        for link in links:
            if link not in plant.sites:
                raise ConfigError(
                    f"{config.name}: skin patch '{entry['patch']}' covers '{link}', which is not a body of the chain "
                    f"(bodies: {', '.join(plant.sites)})"
                )
            if sensor and side(link) != entry["side"]:
                raise ConfigError(
                    f"{config.name}: skin patch '{entry['patch']}' says it is {entry['side']} of {sensor}, but its "
                    f"link '{link}' is {side(link)}"
                )
        patches.append(Patch(entry["patch"], links, entry["side"]))
    return patches


def _surface_point(com: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A point of the link's skin and the inward force direction, link frame."""
    axis_vec = 2.0 * com
    length = np.linalg.norm(axis_vec)
    axis = axis_vec / length if length > 1e-6 else np.array([0.0, 0.0, 1.0])
    radial = np.cross(axis, rng.normal(size=3))
    radial /= np.linalg.norm(radial)
    point = rng.uniform(0.2, 1.0) * axis_vec + SKIN_RADIUS_M * radial
    tilt = np.cross(radial, rng.normal(size=3))
    tilt /= np.linalg.norm(tilt)
    angle = rng.uniform(0.0, np.deg2rad(30.0))
    direction = -(np.cos(angle) * radial + np.sin(angle) * tilt)
    return point, direction


def draw_episodes(
    duration: float, patches: list[Patch], plant: RigidBodyPlant, coms: dict[str, np.ndarray], rng: np.random.Generator,
    start: float = 2.0,
) -> list[Episode]:
    episodes, t = [], start
    while True:
        t += rng.uniform(1.0, 4.0)
        length = rng.uniform(*DURATION_RANGE_S)
        if t + length > duration - 0.5:
            return episodes
        p = int(rng.integers(len(patches)))
        link = patches[p].links[int(rng.integers(len(patches[p].links)))]
        point, direction = _surface_point(coms[link], rng)
        episodes.append(Episode(t, t + length, p, link, patches[p].side, point, direction * rng.uniform(*FORCE_RANGE_N)))
        t += length


def timeline(episodes: list[Episode], t: np.ndarray, sites: list[BodySite]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per sample: the contact's site index (−1: none), its wrench in the link frame (N, 6), the episode (−1)."""
    n = t.shape[0]
    site_index = np.full(n, -1)
    wrench = np.zeros((n, 6))
    episode = np.full(n, -1)
    names = [s.link for s in sites]
    for i, e in enumerate(episodes):
        inside = (t > e.onset) & (t < e.end)
        if not inside.any():
            continue
        edge = np.minimum(t[inside] - e.onset, e.end - t[inside])
        profile = np.where(edge < RAMP_S, 0.5 - 0.5 * np.cos(np.pi * edge / RAMP_S), 1.0)
        site_index[inside] = names.index(e.link)
        episode[inside] = i
        f = profile[:, None] * e.force
        wrench[inside] = np.hstack([f, np.cross(e.point, f)])
    return site_index, wrench, episode


def contact_force(site: BodySite, wrench: np.ndarray) -> pin.Force:
    """The contact wrench (link frame) as a force on the plant joint that carries the link."""
    return site.placement.act(pin.Force(wrench))
