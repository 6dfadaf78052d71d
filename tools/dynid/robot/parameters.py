"""The parameter vector Φ, written down once, by name.

Φ = [φ of every body (10 each) | F/T offsets (6 per sensor) | joint friction (4 per actuated joint)
     | motor friction (4 per motor of a coupled group) | motor gains (1 per motor whose gain is unknown)]

Names (every tool prints and exports by them):

- inertial, about the body frame, in Pinocchio's ``Inertia.toDynamicParameters()`` order:
  ``<body>.m``, ``<body>.mcx|mcy|mcz`` (first moments m·c), ``<body>.Ixx|Ixy|Iyy|Ixz|Iyz|Izz`` (inertia about the
  frame origin). A body is named after its URDF link; an F/T sensor splits a link chain into a proximal and a
  distal body (for the iCub: ``r_shoulder_3`` and ``r_upper_arm``).
- F/T offsets: ``ft.<sensor>.offset.fx|fy|fz|tx|ty|tz``.
- friction, asymmetric Coulomb and viscous: ``<joint or motor>.fc_pos|fc_neg|fv_pos|fv_neg``, meaning
  τ_f = fc_pos·[q̇>0] − fc_neg·[q̇<0] + fv_pos·max(q̇,0) + fv_neg·min(q̇,0); all four are positive for a
  physical friction.
- motor gains: ``<motor>.phi_m`` (Nm per unit of input: PWM duty or A).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

INERTIAL_FIELDS: tuple[str, ...] = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
WRENCH_FIELDS: tuple[str, ...] = ("fx", "fy", "fz", "tx", "ty", "tz")
FRICTION_FIELDS: tuple[str, ...] = ("fc_pos", "fc_neg", "fv_pos", "fv_neg")

BlockKind = Literal["inertial", "ft_offset", "joint_friction", "motor_friction", "motor_gain"]
BLOCK_ORDER: tuple[BlockKind, ...] = ("inertial", "ft_offset", "joint_friction", "motor_friction", "motor_gain")


@dataclass(frozen=True)
class ParameterBlock:
    """A contiguous run of Φ that belongs to one thing (a body, a sensor, a joint, a motor)."""

    kind: BlockKind
    owner: str
    start: int
    names: tuple[str, ...]

    @property
    def stop(self) -> int:
        return self.start + len(self.names)

    @property
    def slice(self) -> slice:
        return slice(self.start, self.stop)


class ParameterLayout:
    """Names and positions of every entry of Φ."""

    def __init__(
        self,
        bodies: tuple[str, ...],
        ft_sensors: tuple[str, ...],
        friction_joints: tuple[str, ...],
        friction_motors: tuple[str, ...],
        gain_motors: tuple[str, ...],
    ) -> None:
        owners: dict[BlockKind, tuple[tuple[str, tuple[str, ...]], ...]] = {
            "inertial": tuple((b, tuple(f"{b}.{f}" for f in INERTIAL_FIELDS)) for b in bodies),
            "ft_offset": tuple((s, tuple(f"ft.{s}.offset.{f}" for f in WRENCH_FIELDS)) for s in ft_sensors),
            "joint_friction": tuple((j, tuple(f"{j}.{f}" for f in FRICTION_FIELDS)) for j in friction_joints),
            "motor_friction": tuple((m, tuple(f"{m}.{f}" for f in FRICTION_FIELDS)) for m in friction_motors),
            "motor_gain": tuple((m, (f"{m}.phi_m",)) for m in gain_motors),
        }
        blocks: list[ParameterBlock] = []
        start = 0
        for kind in BLOCK_ORDER:
            for owner, names in owners[kind]:
                blocks.append(ParameterBlock(kind, owner, start, names))
                start += len(names)
        self.blocks: tuple[ParameterBlock, ...] = tuple(blocks)
        self.names: tuple[str, ...] = tuple(n for b in blocks for n in b.names)
        self._index = {n: i for i, n in enumerate(self.names)}
        self._blocks = {(b.kind, b.owner): b for b in blocks}
        if len(self._index) != len(self.names):
            raise ValueError("parameter names must be unique (a body named like a joint or motor?)")

    def __len__(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        return self._index[name]

    def block(self, kind: BlockKind, owner: str) -> ParameterBlock:
        return self._blocks[(kind, owner)]

    def blocks_of(self, kind: BlockKind) -> tuple[ParameterBlock, ...]:
        return tuple(b for b in self.blocks if b.kind == kind)

    def span(self, kind: BlockKind) -> slice:
        """The slice of Φ holding every block of one kind (blocks of a kind are contiguous)."""
        bs = self.blocks_of(kind)
        if not bs:
            return slice(0, 0)
        return slice(bs[0].start, bs[-1].stop)

    def owners(self, kind: BlockKind) -> tuple[str, ...]:
        return tuple(b.owner for b in self.blocks_of(kind))
