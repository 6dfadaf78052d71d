"""A well-formed coefficient file with an absurd value is refused, by the monitor and by dynid, in the same words.

Each case is a CRC-valid file (an exporter bug or a hand edit would make one) that the monitor used to run on in
silence (issue 31): blind (T² NaN, a threshold or Λ of 1e300, a debounce of 2³¹−1) or alarming forever (Λ or the
threshold 1e-300, gravity 0). The loader refuses each with exit 10 + 11 and one line naming the value and its
plausible range (rt_monitor/include/rt_monitor/plausibility.hpp); dynid's reader refuses it with the same line, and
`dynid export` never writes one.
"""

from __future__ import annotations

import copy
import subprocess
from pathlib import Path

import pytest
from test_rt_core import BUILDS, EXIT_BASE, FIXTURE, rt_eval

from dynid.export.coefficients import read_coefficients, unwrap, wrap, write_coefficients
from dynid.export.lcm_coefficients import coefficients_t
from dynid.export.plausible import Implausible, limits

IMPLAUSIBLE = EXIT_BASE + 11


def _lists(v):
    return [_lists(x) for x in v] if isinstance(v, (list, tuple)) else v


def _set(field: str, value, index: tuple[int, ...] = ()):
    """A change of `field` (at `index` within it) to `value`."""
    def change(c: coefficients_t) -> None:
        if not index:
            setattr(c, field, value)
            return
        whole = _lists(getattr(c, field))  # decoded arrays are tuples
        target = whole
        for i in index[:-1]:
            target = target[i]
        target[index[-1]] = value
        setattr(c, field, whole)
    return change


def _tracking(time_constant: float):
    def change(c: coefficients_t) -> None:
        c.supply_time_constant, c.supply_prior = time_constant, 1.0
    return change


def _filter_scaled(c: coefficients_t) -> None:
    filt = _lists(c.filter)
    filt[0] = [2 * w for w in filt[0]]  # value weights that no longer reproduce a constant
    c.filter = filt


# name -> (change, the words of the refusal)
CASES = {
    "rotation 1e200": (_set("rotation", 1e200, (1, 0)), "body r_shoulder_2: its rotation's |RᵀR − I| is inf"),
    "translation 1e300": (_set("translation", 1e300, (2, 1)), "body r_shoulder_3: its joint frame's offset is 1e+300 m"),
    "mass 1e308": (_set("inertial", 1e308, (4, 0)), "body r_elbow_1: its mass is 1e+308 kg"),
    "inertia 1e5": (_set("inertial", 1e5, (6, 9)), "body r_wrist_1: its inertia is 100000 kg m²"),
    "no link has a length": (lambda c: setattr(c, "translation", [[0.0] * 3 for _ in c.translation]),
                             "the chain's length (its joint frames' offsets summed) is 0 m"),
    "the robot has no mass": (lambda c: setattr(c, "inertial", [[0.0] * 10 for _ in c.inertial]),
                              "the robot's total mass |Σm| is 0 kg"),
    "a motor that drives no joint": (lambda c: setattr(c, "motor_velocity", [[0.0] * len(r) for r in c.motor_velocity]),
                                     "motor m0: its largest coupling ratio (it drives no joint) is 0"),
    "an end level of 1e-300": (_set("hysteresis", 1e-300), "the end level (hysteresis, a fraction of T²_α) is 1e-300"),
    "a supply time constant of 1e-300 s": (_tracking(1e-300), "the supply tracking's time constant (0: off) is 1e-300 s"),
    "gravity 0": (_set("gravity", [0.0, 0.0, 0.0]), "gravity |g| is 0 m/s²"),
    "gravity in cm/s²": (_set("gravity", [0.0, 0.0, -981.0]), "gravity |g| is 981 m/s²"),
    "Λ 1e-300": (_set("residual_variance", 1e-300, (2,)), "channel ft.r_arm_ft.fz: its residual's √Λ is 1e-150 N"),
    "Λ 1e300": (_set("residual_variance", 1e300, (7,)), "channel pwm.m1: its residual's √Λ is 1e+150 (duty or A)"),
    "threshold 1e-300": (_set("threshold", 1e-300), "T²_α per channel is 1e-301"),
    "threshold 1e300": (_set("threshold", 1e300), "T²_α per channel is 1e+299"),
    "side threshold 1e300": (_set("ft_threshold", [1e300]), "F/T sensor r_arm_ft: its side threshold per channel"),
    "debounce 2^31-1": (_set("debounce_on", 2**31 - 1), "a debounce count is 2.14748e+09 samples"),
    "gain 1e-300": (_set("divisor", 1e-300, (8,)), "channel pwm.m2: its gain |divisor| is 1e-300"),
    "friction 1e300": (_set("joint_friction", 1e300, (3, 0)), "joint r_elbow: a friction coefficient is 1e+300"),
    "offset 1e300": (_set("ft_offset", 1e300, (0, 4)), "F/T sensor r_arm_ft: an offset is 1e+300 N or Nm"),
    "filter weights": (_filter_scaled, "the filter's value weights' sum is 2"),
    "α 0.01": (_set("alpha", 0.01), "α is 0.01"),
    "supply time constant 1e300": (_tracking(1e300), "the supply tracking's time constant is 1e+300 s"),
    "observer bandwidth 1e300": (_set("observer_bandwidth", 1e300), "the observer's bandwidth is 1e+300 Hz (Nyquist)"),
}


@pytest.fixture(scope="module")
def good() -> coefficients_t:
    return coefficients_t.decode(unwrap(FIXTURE.read_bytes()))


def test_the_fixture_is_plausible(good: coefficients_t) -> None:
    read_coefficients(FIXTURE)  # no exception
    assert {"MaxMass", "MinGravity", "MaxThresholdPerChannel"} <= set(limits())


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("exe", BUILDS, ids=lambda p: p.name)
def test_an_absurd_file_is_refused_in_one_line_by_both_readers(case: str, exe: Path, good: coefficients_t,
                                                              tmp_path: Path) -> None:
    change, words = CASES[case]
    c = copy.deepcopy(good)
    change(c)
    path = tmp_path / "absurd.dcoef"
    path.write_bytes(wrap(c.encode()))  # CRC-valid: the wrapper is fine, a value is not
    done = rt_eval("--coef", str(path), "--check", exe=exe / "rt_monitor" / "rt_eval")
    assert done.returncode == IMPLAUSIBLE, done.stderr
    line = done.stderr.strip()
    assert done.stderr.count("\n") == 1 and words in line and "export the model again" in line, line
    with pytest.raises(Implausible) as refused:
        read_coefficients(path)
    # the same words: the monitor's line is "rt_eval: refused: PATH: …", dynid's "PATH: …"
    assert line.split(f"{path}: ", 1)[1] == str(refused.value).split(f"{path}: ", 1)[1]
    with pytest.raises(Implausible):
        write_coefficients(c, tmp_path / "never.dcoef")
    assert not (tmp_path / "never.dcoef").exists()


def test_the_monitor_refuses_an_absurd_file_at_start_up(good: coefficients_t, tmp_path: Path) -> None:
    c = copy.deepcopy(good)
    c.gravity = [0.0, 0.0, 0.0]
    path = tmp_path / "g0.dcoef"
    path.write_bytes(wrap(c.encode()))
    root = Path(__file__).resolve().parents[2]
    done = subprocess.run([str(root / "build" / "rt_monitor" / "rt_monitor"), "--model", str(path), "--config",
                           str(root / "rt_monitor" / "config" / "icub_right_arm.conf"), "--replay", "/dev/null",
                           "--lcm-url", "memq://"], capture_output=True, text=True, timeout=60)
    assert done.returncode == IMPLAUSIBLE and "gravity |g| is 0 m/s²" in done.stderr, done.stderr
