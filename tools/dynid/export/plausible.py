"""A coefficient file's values against physics and the sensors' ranges, as the monitor's loader checks them.

The limits live in one place, `rt_monitor/include/rt_monitor/plausibility.hpp`, parsed here; the checks mirror the
loader's (`rt_monitor/src/coefficient_checks.cpp`) in the same order with the same words, so that `dynid export`
refuses to write a file the monitor would refuse, `dynid export --print` says why a file is refused, and a test holds
the two readers to one answer on every mutation (tools/tests/test_plausible.py).
"""

from __future__ import annotations

import math
import re
from functools import lru_cache
from pathlib import Path

from ..errors import DataError
from .lcm_coefficients import coefficients_t

HEADER = Path(__file__).resolve().parents[3] / "rt_monitor" / "include" / "rt_monitor" / "plausibility.hpp"
_LINE = re.compile(r"constexpr\s+double\s+k(\w+)\s*=\s*([-+0-9.eE]+)\s*;")


@lru_cache(maxsize=1)
def limits(header: Path = HEADER) -> dict[str, float]:
    """{'MaxTranslation': 10.0, …}: every `constexpr double kName = value;` of the header."""
    try:
        return {name: float(v) for name, v in _LINE.findall(header.read_text())}
    except OSError as e:
        raise RuntimeError(f"the monitor's plausibility header is missing ({header}: {e.strerror})") from None


def _num(v: float) -> str:
    """A number as C++'s default ostream writes it (%g, 6 significant digits)."""
    return f"{v:g}"


class Implausible(DataError):
    """A well-formed coefficient file holding a value no robot has."""


def _refuse(what: str, value: float, lo: float, hi: float, unit: str) -> None:
    u = f" {unit}" if unit else ""
    raise Implausible(f"{what} is {_num(value)}{u}, outside the plausible {_num(lo)} to {_num(hi)}{u} "
                      "(rt_monitor/include/rt_monitor/plausibility.hpp): an exporter bug or an edited file; export the "
                      "model again")


def _within(v: float, lo: float, hi: float) -> bool:
    return lo <= v <= hi  # False for NaN, as in C++


def _sigma_range(P: dict[str, float], c: coefficients_t, i: int) -> tuple[float, float, str]:
    """A residual's plausible standard deviation on output channel i: an input (duty or A), a force or a torque."""
    if c.channel_kind[i] == 1:
        return P["MinInputSigma"], P["MaxInputSigma"], "(duty or A)"
    if c.channel_kind[i] == 0 and i % 6 < 3:
        return P["MinForceSigma"], P["MaxForceSigma"], "N"
    return P["MinTorqueSigma"], P["MaxTorqueSigma"], "Nm"


def _moment(w: list[float], period: float, power: int) -> tuple[float, float]:
    """Σ w[s]·(s·T)^power over a filter's weights (oldest first) and the same of |w[s]|: a derivative filter on a
    ramp gives 1, a curvature filter on a parabola 2."""
    terms = [x * (s * period) ** power for s, x in enumerate(w)]
    return sum(terms), sum(abs(x) for x in terms)


def check_plausible(c: coefficients_t) -> None:
    """Raise Implausible naming the first value outside its range (the loader's order and words)."""
    P = limits()
    for i in range(c.n_bodies):
        body = f"body {c.body_names[i]}"
        R = c.rotation[i]
        rt_r = max(abs(sum(R[3 * m + r] * R[3 * m + k] for m in range(3)) - (1.0 if r == k else 0.0))
                   for r in range(3) for k in range(3))
        norm = math.sqrt(sum(a * a for a in c.axis[i]))
        if not rt_r <= P["RotationTolerance"]:
            _refuse(f"{body}: its rotation's |RᵀR − I|", rt_r, 0, P["RotationTolerance"], "")
        if c.joint_type[i] != 0 and not abs(norm - 1) <= P["RotationTolerance"]:
            _refuse(f"{body}: its joint axis' norm", norm, 1 - P["RotationTolerance"], 1 + P["RotationTolerance"], "")
        for v in c.translation[i]:
            if not _within(v, -P["MaxTranslation"], P["MaxTranslation"]):
                _refuse(f"{body}: its joint frame's offset", v, -P["MaxTranslation"], P["MaxTranslation"], "m")
        p = c.inertial[i]
        if not _within(p[0], -P["MaxMass"], P["MaxMass"]):
            _refuse(f"{body}: its mass", p[0], -P["MaxMass"], P["MaxMass"], "kg")
        for v in p[1:4]:
            if not _within(v, -P["MaxFirstMoment"], P["MaxFirstMoment"]):
                _refuse(f"{body}: its first moment m·c", v, -P["MaxFirstMoment"], P["MaxFirstMoment"], "kg m")
        for v in p[4:10]:
            if not _within(v, -P["MaxInertia"], P["MaxInertia"]):
                _refuse(f"{body}: its inertia", v, -P["MaxInertia"], P["MaxInertia"], "kg m²")
    length = sum(math.sqrt(sum(v * v for v in c.translation[i])) for i in range(c.n_bodies))
    mass = sum(c.inertial[i][0] for i in range(c.n_bodies))
    if not length >= P["MinChainLength"]:
        _refuse("the chain's length (its joint frames' offsets summed)", length, P["MinChainLength"],
                P["MaxTranslation"] * c.n_bodies, "m")
    if not abs(mass) >= P["MinTotalMass"]:  # by magnitude: an unconstrained fit's full φ need not sum positive
        _refuse("the robot's total mass |Σm|", abs(mass), P["MinTotalMass"], P["MaxMass"] * c.n_bodies, "kg")
    for j in range(c.n_joints):
        lo, hi = c.joint_limits[j]
        if not (lo < hi and _within(lo, -P["MaxJointRange"], P["MaxJointRange"])
                and _within(hi, -P["MaxJointRange"], P["MaxJointRange"])):
            _refuse(f"joint {c.joint_names[j]}: its range's lower limit", lo, -P["MaxJointRange"], hi, "rad or m")
    g = math.sqrt(sum(x * x for x in c.gravity))
    if not _within(g, P["MinGravity"], P["MaxGravity"]):
        _refuse("gravity |g|", g, P["MinGravity"], P["MaxGravity"], "m/s²")
    for k in range(c.n_motors):
        for v in c.motor_velocity[k][: c.n_joints]:
            if not _within(v, -P["MaxRatio"], P["MaxRatio"]):
                _refuse(f"motor {c.motor_names[k]}: a coupling ratio", v, -P["MaxRatio"], P["MaxRatio"], "")
        largest = max((abs(v) for v in c.motor_velocity[k][: c.n_joints]), default=0.0)
        if not largest >= P["MinRatio"]:
            _refuse(f"motor {c.motor_names[k]}: its largest coupling ratio (it drives no joint)", largest, P["MinRatio"],
                    P["MaxRatio"], "")
        for v in c.motor_friction[k]:
            if not _within(v, -P["MaxFriction"], P["MaxFriction"]):
                _refuse(f"motor {c.motor_names[k]}: a friction coefficient", v, -P["MaxFriction"], P["MaxFriction"],
                        "Nm or Nm·s/rad")
    for j in range(c.n_joints):
        for v in c.joint_friction[j]:
            if not _within(v, -P["MaxFriction"], P["MaxFriction"]):
                _refuse(f"joint {c.joint_names[j]}: a friction coefficient", v, -P["MaxFriction"], P["MaxFriction"],
                        "Nm or Nm·s/rad")
    for s in range(c.n_sensors):
        for v in c.ft_offset[s]:
            if not _within(v, -P["MaxOffset"], P["MaxOffset"]):
                _refuse(f"F/T sensor {c.sensor_names[s]}: an offset", v, -P["MaxOffset"], P["MaxOffset"], "N or Nm")
    for i in range(c.n_outputs):
        ch = f"channel {c.channel_names[i]}"
        for v in c.row_map[i][: c.n_joints]:
            if not _within(v, -P["MaxRatio"], P["MaxRatio"]):
                _refuse(f"{ch}: a row-map entry", v, -P["MaxRatio"], P["MaxRatio"], "")
        d = abs(c.divisor[i])
        if not _within(d, P["MinGain"], P["MaxGain"]):
            _refuse(f"{ch}: its gain |divisor|", d, P["MinGain"], P["MaxGain"], "")
        lo, hi, unit = _sigma_range(P, c, i)
        sigma = math.sqrt(c.residual_variance[i]) if c.residual_variance[i] >= 0 else float("nan")
        if not _within(sigma, lo, hi):
            _refuse(f"{ch}: its residual's √Λ", sigma, lo, hi, unit)
    per = c.threshold / max(c.n_outputs, 1)
    if not _within(per, P["MinThresholdPerChannel"], P["MaxThresholdPerChannel"]):
        _refuse("T²_α per channel", per, P["MinThresholdPerChannel"], P["MaxThresholdPerChannel"], "")
    for s in range(c.n_sensors):
        if not _within(c.ft_threshold[s] / 6, P["MinThresholdPerChannel"], P["MaxThresholdPerChannel"]):
            _refuse(f"F/T sensor {c.sensor_names[s]}: its side threshold per channel", c.ft_threshold[s] / 6,
                    P["MinThresholdPerChannel"], P["MaxThresholdPerChannel"], "")
    most = P["MaxDebounceSeconds"] / c.sample_period
    if c.debounce_on > most or c.debounce_off > most:
        _refuse("a debounce count", float(max(c.debounce_on, c.debounce_off)), 1, most, "samples (10 s at this file's period)")
    if not _within(c.min_speed, 0, P["MaxMinSpeed"]):
        _refuse("min_speed", c.min_speed, 0, P["MaxMinSpeed"], "rad/s")
    if not _within(c.alpha, P["MinAlpha"], 1):
        _refuse("α", c.alpha, P["MinAlpha"], 1, "")
    if not _within(c.supply_time_constant, 0, P["MaxSupplyTimeConstant"]):
        _refuse("the supply tracking's time constant", c.supply_time_constant, 0, P["MaxSupplyTimeConstant"], "s")
    if c.supply_time_constant > 0 and not c.supply_time_constant >= P["MinSupplyPeriods"] * c.sample_period:
        _refuse("the supply tracking's time constant (0: off)", c.supply_time_constant,
                P["MinSupplyPeriods"] * c.sample_period, P["MaxSupplyTimeConstant"], "s")
    if not _within(c.hysteresis, P["MinHysteresis"], 1):
        _refuse("the end level (hysteresis, a fraction of T²_α)", c.hysteresis, P["MinHysteresis"], 1, "")
    for r, name in enumerate(("value", "slope", "curvature")):
        w = c.filter[r][: c.window]
        total, size, want = sum(w), sum(abs(x) for x in w), 1.0 if r == 0 else 0.0
        if not abs(total - want) <= P["FilterSumTolerance"] * max(1.0, size):
            _refuse(f"the filter's {name} weights' sum", total, want, want, "")
        if r > 0:  # the derivatives of a ramp (slope 1) and of a parabola (curvature 2)
            value, size = _moment(w, c.sample_period, r)
            if not abs(value - r) <= P["FilterSumTolerance"] * max(1.0, size):
                _refuse(f"the filter's {name} on {'t' if r == 1 else 't²'}", value, r, r, "")
    for k in range(c.n_effects):
        p, e = c.effect_param[k], f"effect {k}"
        stribeck = c.effect_kind[k] == 1
        most = P["MaxEffectTorque"] if stribeck else P["MaxStiffness"]
        if not _within(p[0], -most, most):
            _refuse(e + (": its extra static torque" if stribeck else ": its stiffness"), p[0], -most, most,
                    "Nm" if stribeck else "Nm/rad")
        if stribeck and not _within(p[1], 0, P["MaxStribeckVelocity"]):
            _refuse(f"{e}: its Stribeck velocity", p[1], 0, P["MaxStribeckVelocity"], "rad/s")
        if not stribeck and not _within(p[1], -P["MaxRest"], P["MaxRest"]):
            _refuse(f"{e}: its rest position", p[1], -P["MaxRest"], P["MaxRest"], "rad")
    for j in range(c.n_joints):
        sigma = math.sqrt(c.accel_tau_variance[j]) if c.accel_tau_variance[j] >= 0 else float("nan")
        if not _within(sigma, 0, P["MaxTauSigma"]):
            _refuse(f"joint {c.joint_names[j]}: its τ_ext noise", sigma, 0, P["MaxTauSigma"], "Nm")
    if not _within(c.isolation_sigmas, 0, P["MaxIsolationSigmas"]):
        _refuse("the isolation level", c.isolation_sigmas, 0, P["MaxIsolationSigmas"], "standard deviations")
    if c.velocity_window > 0:
        w = c.velocity_filter[: c.velocity_window]
        if not abs(sum(w)) <= P["FilterSumTolerance"] * max(1.0, sum(abs(x) for x in w)):
            _refuse("the observer's q̇ weights' sum", sum(w), 0, 0, "")
        value, size = _moment(w, c.sample_period, 1)
        if not abs(value - 1.0) <= P["FilterSumTolerance"] * max(1.0, size):
            _refuse("the observer's q̇ weights on t", value, 1, 1, "")
        nyquist = 0.5 / c.sample_period
        if not _within(c.observer_bandwidth, P["MinObserverBandwidth"], nyquist):
            _refuse("the observer's bandwidth", c.observer_bandwidth, P["MinObserverBandwidth"], nyquist, "Hz (Nyquist)")
        for i in range(c.n_outputs):
            lo, hi, unit = _sigma_range(P, c, i)
            sigma = math.sqrt(c.observer_variance[i]) if c.observer_variance[i] >= 0 else float("nan")
            if not _within(sigma, lo, hi):
                _refuse(f"channel {c.channel_names[i]}: the observer's √Λ", sigma, lo, hi, unit)
        n = max(c.n_outputs, 1)
        for what, t in (("the observer's T²_α per channel", c.observer_threshold),
                        ("the observer's rest T²_α per channel", c.observer_rest_threshold)):
            if not _within(t / n, P["MinThresholdPerChannel"], P["MaxThresholdPerChannel"]):
                _refuse(what, t / n, P["MinThresholdPerChannel"], P["MaxThresholdPerChannel"], "")
        for j in range(c.n_joints):
            sigma = math.sqrt(c.tau_variance[j]) if c.tau_variance[j] >= 0 else float("nan")
            if not _within(sigma, 0, P["MaxTauSigma"]):
                _refuse(f"joint {c.joint_names[j]}: the observer's τ_ext noise", sigma, 0, P["MaxTauSigma"], "Nm")
        if c.combined_scale != 0 and not _within(c.combined_scale, P["MinCombinedScale"], P["MaxCombinedScale"]):
            _refuse("the combined detector's κ", c.combined_scale, P["MinCombinedScale"], P["MaxCombinedScale"], "")
