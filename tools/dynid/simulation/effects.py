"""Hidden effects: physics the plant can include and the standard identification model does not.

Each effect is named on the command line as ``NAME`` or ``NAME:key=value,key=value``. Its target (a joint, a
motor, a link, a sensor, a coupled group) defaults to one that exists in any configuration, and every
parameter has a realistic default. The truth file lists each effect with all its values, so the gap workflow
can be scored against it.

Where an effect acts tells which recorded signals it may change:

- ``sensor`` effects alter only a measurement (the motion, the PWMs and every other channel are bit-identical);
- ``actuator`` effects change the torque of one motor or joint: the model's residual grows on that row only;
- ``body`` effects change the dynamics of the whole chain (a payload, the direction of gravity).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from ..config.robot_config import RobotConfig
from ..errors import InputError

Target = Literal["joint", "motor", "link", "sensor", "group", "none"]
Stage = Literal["sensor", "actuator", "body"]


@dataclass(frozen=True)
class EffectKind:
    name: str
    target: Target
    stage: Stage
    summary: str
    defaults: dict[str, float | str] = field(default_factory=dict)  # parameter -> default (str: a choice)
    units: dict[str, str] = field(default_factory=dict)


CATALOG: dict[str, EffectKind] = {
    e.name: e
    for e in (
        EffectKind("stribeck", "joint", "actuator", "Stribeck friction: extra breakaway friction at low speed",
                   {"excess": 1.0, "velocity": 0.02}, {"excess": "× the joint's Coulomb friction", "velocity": "rad/s"}),
        EffectKind("spring", "joint", "actuator", "position-dependent spring or cable torque, -k (q - rest)",
                   {"stiffness": 0.3, "rest": "mid"}, {"stiffness": "Nm/rad", "rest": "rad, or 'mid' of the range"}),
        EffectKind("armature", "motor", "actuator", "rotor inertia reflected through the coupling (Tᵀ J T q̈)",
                   {"inertia": 0.01}, {"inertia": "kg m², joint-scale motor coordinate"}),
        EffectKind("payload", "link", "body", "an unmodelled point mass rigidly attached to a link",
                   {"mass": 0.3, "x": 0.0, "y": 0.0, "z": 0.0}, {"mass": "kg", "x": "m, link frame", "y": "m", "z": "m"}),
        EffectKind("ft_drift", "sensor", "sensor", "F/T offset drift: thermal (1 - exp(-t/tau)) or linear in time",
                   {"force": 2.0, "torque": 0.1, "tau": 60.0, "shape": "thermal"},
                   {"force": "N at the end of the drift (per force axis, random signs)", "torque": "Nm", "tau": "s",
                    "shape": "thermal|linear"}),
        EffectKind("pwm_delay", "none", "sensor", "the PWM stream lags the encoder stream",
                   {"ms": 3.0}, {"ms": "ms (rounded to whole samples)"}),
        EffectKind("pwm_deadzone", "motor", "actuator", "a PWM dead-zone: |duty| below the width drives nothing",
                   {"width": 0.02}, {"width": "duty fraction"}),
        EffectKind("coupling_error", "group", "actuator", "the true coupling ratio differs from the configured one",
                   {"error": 0.03, "joint": "all"},
                   {"error": "relative error of the coupling entries other than 0 and ±1",
                    "joint": "only the entries of this joint's column (a joint-side pulley), or 'all'"}),
        EffectKind("load_friction", "motor", "actuator", "Coulomb friction that grows with the transmitted torque",
                   {"coefficient": 0.05}, {"coefficient": "Nm of Coulomb friction per Nm of motor torque"}),
        EffectKind("cogging", "motor", "actuator", "cogging: a position-periodic motor torque",
                   {"amplitude": 0.15, "period_deg": 5.0}, {"amplitude": "Nm", "period_deg": "degrees of motor coordinate"}),
        EffectKind("base_tilt", "none", "body", "a base tilt: gravity not where the URDF says",
                   {"degrees": 2.0, "axis": "x"}, {"degrees": "deg", "axis": "x|y|z of the URDF root frame"}),
        EffectKind("ft_step", "sensor", "sensor",
                   "F/T offset step: the offset moves by d at from_s and back at to_s (a cable pulled taut in a posture)",
                   {"force": 3.0, "torque": 0.15, "from_s": 10.0, "to_s": 20.0},
                   {"force": "N (per force axis, random signs)", "torque": "Nm", "from_s": "s from the run's start",
                    "to_s": "s (after from_s; past the run's end: the offset stays)"}),
        EffectKind("ft_gain", "sensor", "sensor", "F/T gain and cross-talk errors: measured = (I + E) w",
                   {"gain": 0.03, "crosstalk": 0.01}, {"gain": "std of the diagonal of E", "crosstalk": "std off the diagonal"}),
        # Outside the gap library on purpose: the test of an effect it cannot name.
        EffectKind("drag", "joint", "actuator", "quadratic drag (a dragged cable or hose), -c q̇|q̇|",
                   {"coefficient": 2.0}, {"coefficient": "Nm per (rad/s)²"}),
    )
}

_CHOICES = {"shape": ("thermal", "linear"), "axis": ("x", "y", "z")}
# What a parameter may be, physically: (effect, parameter) -> (lowest, whether it may equal it, highest or None).
# An amplitude drawn with random signs, a friction, an inertia or a stiffness is not negative; a velocity, a time
# constant, a period and a mass are positive (the plant divided by them, or diverged on them, with a traceback).
_RANGES: dict[tuple[str, str], tuple[float, bool, float | None]] = {
    ("stribeck", "excess"): (0.0, True, None), ("stribeck", "velocity"): (0.0, False, None),
    ("spring", "stiffness"): (0.0, True, None), ("armature", "inertia"): (0.0, True, None),
    ("payload", "mass"): (0.0, False, None),
    ("ft_drift", "force"): (0.0, True, None), ("ft_drift", "torque"): (0.0, True, None),
    ("ft_drift", "tau"): (0.0, False, None), ("pwm_delay", "ms"): (0.0, True, None),
    ("pwm_deadzone", "width"): (0.0, True, 1.0), ("coupling_error", "error"): (-1.0, False, None),
    ("load_friction", "coefficient"): (0.0, True, 1.0),
    ("cogging", "amplitude"): (0.0, True, None), ("cogging", "period_deg"): (0.0, False, None),
    ("base_tilt", "degrees"): (-90.0, False, 90.0),
    ("ft_step", "force"): (0.0, True, None), ("ft_step", "torque"): (0.0, True, None),
    ("ft_gain", "gain"): (0.0, True, None), ("ft_gain", "crosstalk"): (0.0, True, None),
    ("drag", "coefficient"): (0.0, True, None),
}
_NAMES = ("joint",)  # parameters that name a part of the arm (coupling_error's column), checked in parse_effect


@dataclass(frozen=True)
class Effect:
    """One hidden effect switched on: its kind, its target and every parameter value."""

    kind: str
    target: str | None
    params: dict[str, float | str]

    @property
    def spec(self) -> EffectKind:
        return CATALOG[self.kind]

    def as_dict(self) -> dict:
        return {"name": self.kind, "stage": self.spec.stage, "target": self.target, **self.params}


def default_target(target: Target, config: RobotConfig, bodies: tuple[str, ...]) -> str | None:
    """A target that exists in every configuration: the most distal actuated thing."""
    driven = [j for g in config.actuation for j in g.joints]
    if target == "joint":
        return driven[-1] if driven else config.joints[-1]
    if target == "motor":
        return config.motor_names[-1] if config.motor_names else None
    if target == "link":
        return bodies[-1]
    if target == "sensor":
        return config.ft_sensors[0].name if config.ft_sensors else None
    if target == "group":
        coupled = [g.name for g in config.actuation if g.coupled and g.motors]
        return coupled[0] if coupled else None
    return None


def parse_effect(text: str, config: RobotConfig, bodies: tuple[str, ...]) -> Effect:
    """``NAME[:key=value,...]`` -> Effect; one `InputError` line for any mistake."""
    name, _, rest = text.partition(":")
    name = name.strip()
    if name not in CATALOG:
        raise InputError(f"unknown hidden effect '{name}' (known: {', '.join(CATALOG)})")
    spec = CATALOG[name]
    target_key = spec.target if spec.target != "none" else None
    params: dict[str, float | str] = dict(spec.defaults)
    target = default_target(spec.target, config, bodies)
    for item in filter(None, (p.strip() for p in rest.split(","))):
        key, eq, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not eq or not value:
            raise InputError(f"effect '{name}': expected key=value, got '{item}'")
        if key == target_key:
            target = value
            continue
        if key not in spec.defaults:
            allowed = ([target_key] if target_key else []) + list(spec.defaults)
            raise InputError(f"effect '{name}' has no parameter '{key}' (known: {', '.join(allowed)})")
        default = spec.defaults[key]
        if key in _NAMES:  # a name, checked against the target below
            params[key] = value
            continue
        if isinstance(default, str) and key in _CHOICES:
            if value not in _CHOICES[key]:
                raise InputError(f"effect '{name}': {key} must be one of {', '.join(_CHOICES[key])}, got '{value}'")
            params[key] = value
            continue
        try:
            number = float(value)
        except ValueError:
            raise InputError(f"effect '{name}': {key} must be a number, got '{value}'") from None
        if number != number or number in (float("inf"), float("-inf")):
            raise InputError(f"effect '{name}': {key} must be finite, got '{value}'")
        if (name, key) in _RANGES:
            lo, closed, hi = _RANGES[name, key]
            if number < lo or (number == lo and not closed) or (hi is not None and number >= hi):
                allowed = (f"{'at least' if closed else 'above'} {lo:g}"
                           + (f" and below {hi:g}" if hi is not None else ""))
                raise InputError(f"effect '{name}': {key} must be {allowed}, got '{value}'")
        params[key] = number
    _check_target(name, spec.target, target, config, bodies)
    if name == "ft_step" and not 0 <= float(params["from_s"]) < float(params["to_s"]):
        raise InputError(f"effect 'ft_step': needs 0 <= from_s < to_s, got from_s={params['from_s']:g}, "
                         f"to_s={params['to_s']:g}")
    if name == "coupling_error" and params["joint"] != "all":
        joints = next(g.joints for g in config.actuation if g.name == target)
        if params["joint"] not in joints:
            raise InputError(f"effect 'coupling_error': joint '{params['joint']}' is not in group {target} "
                             f"(its joints: {', '.join(joints)}, or all)")
    return Effect(name, target, params)


def _check_target(name: str, kind: Target, target: str | None, config: RobotConfig, bodies: tuple[str, ...]) -> None:
    known: tuple[str, ...]
    if kind == "none":
        return
    if kind == "joint":
        known = tuple(j for g in config.actuation for j in g.joints)
    elif kind == "motor":
        known = config.motor_names
    elif kind == "link":
        known = bodies
    elif kind == "sensor":
        known = tuple(s.name for s in config.ft_sensors)
    else:
        known = tuple(g.name for g in config.actuation if g.coupled and g.motors)
    if target is None or target not in known:
        what = f"'{target}'" if target else "nothing"
        raise InputError(
            f"effect '{name}' targets {what}, which is not a {kind} it can act on in {config.name} "
            f"(known: {', '.join(known) or 'none'})"
        )


def catalog_text() -> str:
    """Human listing for `dynid simulate --list-effects`."""
    lines = []
    for e in CATALOG.values():
        target = f"{e.target}=NAME, " if e.target != "none" else ""
        params = ", ".join(f"{k}={v} ({e.units.get(k, '')})" for k, v in e.defaults.items())
        lines.append(f"{e.name:15s} [{e.stage}] {e.summary}\n{'':17s}{target}{params}")
    return "\n".join(lines)
