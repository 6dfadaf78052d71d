"""`dynid gaps` on short simulated runs with hidden effects: the right effect, at the right place, with its
parameter within 20 % of the simulator's truth (truth.json), and the gap closed to the noise floor; nothing named
on a control run; an effect outside the library reported as unexplained, not misnamed."""

from __future__ import annotations

import json
import re
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from conftest import dynid, dynid_executable

pytestmark = pytest.mark.numerics

DURATION = "45"  # s: each case costs ~1 s of simulation and ~3-4 s of analysis (idle machine, 2026-11-28)

# One simulated run per case (same arm, robot seed 0), one effect per run: combining effects on channels that do
# not share a row was tried and weakens the claim (F/T gain + armature on m3: the F/T gain's freedom moves the
# elbow inertias, armature came out 0.0155 for 0.03), so only the "two" case combines, on purpose. Magnitudes are the plant's defaults where those are visible on 45 s of this slow reaching motion, larger where
# they are not (README "Model gaps" has the sensitivity table: armature 0.01 kg m², load friction 0.05 and delays
# up to ~40 ms hide in the noise or in the standard model here).
CASES = {
    # short runs first (the pool takes the cases in this order): an F/T offset step at 5 s and back at 10 s, and the
    # control run of the same arm and length
    "ft_step": ["ft_step:from_s=5,to_s=10"],
    "control_short": [],
    "control": [],
    "cogging": ["cogging"],
    "ft_drift": ["ft_drift"],
    "spring": ["spring"],
    "stribeck": ["stribeck:joint=r_shoulder_pitch,excess=2,velocity=0.05"],
    "pwm_deadzone": ["pwm_deadzone"],
    "base_tilt": ["base_tilt"],
    "load_friction": ["load_friction:coefficient=0.15"],
    "pwm_delay": ["pwm_delay:ms=100"],
    "ft_gain": ["ft_gain"],
    "armature": ["armature:inertia=0.03"],
    "two": ["cogging:motor=m3", "spring:joint=r_shoulder_yaw,stiffness=1.0"],
    "outside": ["drag"],  # quadratic drag on r_elbow: not in the library
    # the elbow's own Stribeck, 3× its Coulomb level (joint + motor m3: 0.565 Nm on the seed-0 arm), fast and slow
    "stribeck_elbow": ["stribeck:joint=r_elbow,excess=3,velocity=0.1"],
    "stribeck_slow": ["stribeck:joint=r_elbow,excess=3,velocity=0.02"],
    # against the session's fitted model (`--model`, its inertias held): 0.3 kg 5 cm into the hand, off the wrist
    # centre (at the hand's origin a mass does not move with the wrist: hand, wrist and forearm would be one)
    "payload": ["payload:link=r_hand,mass=0.3,x=0.05"],
    # a joint-side pulley 10 % off: the pitch's column (named), the yaw's (not: below), the yaw's on a plant
    # without noise and disturbance (the candidate's shape)
    "coupling": ["coupling_error:joint=r_shoulder_pitch,error=0.1"],
    "coupling_yaw": ["coupling_error:joint=r_shoulder_yaw,error=0.1"],
    "coupling_yaw_clean": ["coupling_error:joint=r_shoulder_yaw,error=0.1"],
}
SIMULATE = {"coupling_yaw_clean": ["--duration", "30", "--noise", "none", "--disturbance", "none"],
            "ft_step": ["--duration", "15"], "control_short": ["--duration", "15"]}
FT = [f"ft.r_arm_ft.{c}" for c in ("fx", "fy", "fz", "tx", "ty", "tz")]
PWM = [f"pwm.m{i}" for i in range(4)]


@pytest.fixture(scope="module")
def gaps(tmp_path_factory: pytest.TempPathFactory):
    """gaps(case[, model, *extra]) -> (result, truth, stdout) of `dynid gaps` on the case's run (simulated once),
    against `model` if given (its inertias held). Every case's simulation and plain `dynid gaps` start at once, two
    at a time (each is one process on one core of this 2-core machine); a test waits only for what it reads."""
    root = tmp_path_factory.mktemp("gaps")
    lock = threading.Lock()
    cache: dict[tuple, tuple[dict, dict, str]] = {}

    def analyse(case: str, model: Path | None, extra: tuple[str, ...], n: int) -> tuple[dict, dict, str]:
        out = root / case
        result = root / f"{case}{'.given' if model else ''}{n}.json"
        given = ("--model", str(model)) if model else ()
        done = dynid("gaps", "--data", str(out), *given, *extra, "--json", str(result))
        assert done.returncode == 0, done.stderr
        return json.loads(result.read_text()), json.loads((out / "truth.json").read_text()), done.stdout

    def simulate_and_analyse(case: str) -> tuple[dict, dict, str]:
        effects = [a for e in CASES[case] for a in ("--effect", e)]
        done = dynid("simulate", "--kind", "identification", "--duration", DURATION, *SIMULATE.get(case, []),
                     *effects, "--out", str(root / case))
        assert done.returncode == 0, done.stderr
        return analyse(case, None, (), 0)

    pool = ThreadPoolExecutor(max_workers=2)
    plain = {case: pool.submit(simulate_and_analyse, case) for case in CASES}

    def get(case: str, model: Path | None = None, *extra: str) -> tuple[dict, dict, str]:
        first = plain[case].result()  # the run exists once its plain analysis is done
        if model is None and not extra:
            return first
        key = (case, model, *extra)
        with lock:
            if key not in cache:
                cache[key] = analyse(case, model, extra, len(cache) + 1)
            return cache[key]

    get.root = root
    yield get
    pool.shutdown(wait=True, cancel_futures=True)


def test_a_forked_command_writes_what_the_executable_writes(gaps, tmp_path: Path) -> None:
    """The tests' forked commands (conftest.dynid) are the executable's: `dynid gaps` run through the interpreter on
    the control run writes the same report and the same JSON (but its own seconds) as the forked one did."""
    result, _, stdout = gaps("control_short")  # the 15 s control run: the comparison, not the analysis, is the point
    out = tmp_path / "control.json"
    done = dynid_executable("gaps", "--data", str(gaps.root / "control_short"), "--json", str(out))
    assert done.returncode == 0, done.stderr
    alone = json.loads(out.read_text())
    timing = re.compile(r"\(\d+\.\d s;")
    assert timing.sub("(s;", done.stdout) == timing.sub("(s;", stdout)
    assert {k: v for k, v in alone.items() if k != "seconds"} == {k: v for k, v in result.items() if k != "seconds"}


def _truth(truth: dict, name: str) -> dict:
    return next(e for e in truth["effects"] if e["name"] == name)


def _gap(result: dict, channel: str) -> dict:
    return next(g for g in result["gap"] if g["channel"] == channel)


def _named(result: dict) -> list[tuple[str, str]]:
    return [(e["name"], e["where"]) for e in result["effects"]]


def _effect(result: dict, name: str) -> dict:
    return next(e for e in result["effects"] if e["name"] == name)


def test_control_names_nothing(gaps) -> None:
    result, _, stdout = gaps("control")
    assert result["effects"] == []
    assert "named: nothing" in stdout


def _stribeck_static(truth: dict) -> float:
    """The simulator's extra static torque: excess × the joint's mean Coulomb friction."""
    e = _truth(truth, "stribeck")
    coulomb = truth["plant"]["joint_friction"][e["target"]][:2]
    return float(e["excess"]) * (coulomb[0] + coulomb[1]) / 2


# (case, effect, where, estimated parameter, its truth key (None: computed), channels it acts on, bound after/floor)
# The floor of a channel is max(its noise σ, its held-out RMS in the control run of the same arm): with supply
# tracking that is σ everywhere but on pwm.m0 (the shoulder pitch, 1.37 σ with no hidden effect; without supply
# tracking pwm.m0/m1 sat at 1.8–2.4 σ), so there 1.3× is judged against what the standard model achieves without
# the effect. The dead-zone's one-column form (sign u) leaves the filtered zero crossings: pwm.m3 1.06× noise.
EXPECTED = [
    ("cogging", "cogging", "motor m3", "amplitude", "amplitude", ["pwm.m3"], 1.3),
    ("spring", "spring", "joint r_elbow", "stiffness", "stiffness", ["pwm.m3"], 1.3),
    ("stribeck", "stribeck", "joint r_shoulder_pitch", "static_torque", None, ["pwm.m0"], 1.3),
    ("pwm_deadzone", "pwm_deadzone", "motor m3", "width", "width", ["pwm.m3"], 1.3),
    ("ft_drift", "ft_drift", "sensor r_arm_ft", "force", "force", FT, 1.3),
    ("base_tilt", "base_tilt", "base", "degrees", "degrees", FT + PWM, 1.3),
    ("load_friction", "load_friction", "motor m3", "coefficient", "coefficient", ["pwm.m3"], 1.3),
    ("pwm_delay", "pwm_delay", "pwm stream", "ms", "ms", PWM, 1.3),
    ("armature", "armature", "motor m3", "inertia", "inertia", ["pwm.m3"], 1.3),
    ("ft_gain", "ft_gain", "sensor r_arm_ft", None, None, FT, 1.3),
    ("coupling", "coupling_error", "joint r_shoulder_pitch", "error", "error", ["pwm.m0"], 1.3),
]


@pytest.mark.parametrize("case, effect, where, parameter, truth_key, channels, bound", EXPECTED,
                         ids=[f"{c}:{e}" for c, e, *_ in EXPECTED])
def test_hidden_effect_is_named_and_closed(gaps, case: str, effect: str, where: str, parameter: str | None,
                                           truth_key: str | None, channels: list[str], bound: float) -> None:
    result, truth, stdout = gaps(case)
    control, _, _ = gaps("control")
    assert (effect, where) in _named(result), stdout
    assert len(result["effects"]) == len(CASES[case]), stdout  # nothing else named
    # what is named is not also ruled out (gaps.json listed the named armature among them: a walkthrough)
    assert not {r["effect"] for r in result["ruled_out"]} & {f"{e['name']} on {e['where']}" for e in result["effects"]}
    named = _effect(result, effect)
    assert named["where"] == where and named["confident"], stdout
    if parameter is not None:  # ft_gain: see test_ft_gain_matrix_is_not_identifiable
        estimate = named["parameters"][parameter]
        true = float(_truth(truth, effect)[truth_key]) if truth_key else _stribeck_static(truth)
        if effect == "ft_drift":  # named by its size ‖(dfx, dfy, dfz)‖; simulated as `force` on each axis
            true *= np.sqrt(3)
        assert abs(abs(estimate) - true) <= 0.2 * true, (estimate, true)
    floors = {c: max(1.0, _gap(control, c)["after_over_noise"]) for c in channels}
    for c in channels:
        g = _gap(result, c)
        assert g["after_over_noise"] <= bound * floors[c], (g, floors[c])
    # the fix lowered the held-out error of its channels together (an effect on every row, a base tilt, may move
    # a little error between channels in the refit)
    assert sum(_gap(result, c)["after_over_noise"] ** 2 for c in channels) < sum(_gap(result, c)["before_over_noise"] ** 2 for c in channels)
    # the gap was real: on its most affected channel the effect added at least half a noise σ (in quadrature) to
    # what the same arm leaves without it (the control run; below σ where the filtered noise is: pwm.m3 0.42×).
    # Measured: armature 0.03 kg m² adds 0.84 σ on pwm.m3, Stribeck on the shoulder 1.36 σ on pwm.m0, the others more
    excess = max((_gap(result, c)["before_over_noise"] ** 2 - _gap(control, c)["after_over_noise"] ** 2) for c in channels)
    assert excess >= 0.25, excess


def test_ft_step_is_named_at_its_change_points(gaps) -> None:
    """A hidden F/T offset step (3 N per force axis, 0.15 Nm per torque axis, random signs) from 5 s to 10 s of a
    15 s run: named on the sensor, its change points within 50 ms and every axis' size within 10 % of the truth,
    every channel it touches better on held-out blocks; the control run of the same arm and length names nothing."""
    result, truth, stdout = gaps("ft_step")
    true = _truth(truth, "ft_step")
    steps = [e for e in result["effects"] if e["name"] == "ft_step"]
    assert len(steps) == 1 and steps[0]["confident"] and steps[0]["where"] == "sensor r_arm_ft", stdout
    p = steps[0]["parameters"]
    assert abs(p["from_s"] - true["from_s"]) <= 0.05 and abs(p["to_s"] - true["to_s"]) <= 0.05, p
    for axis in ("fx", "fy", "fz", "tx", "ty", "tz"):
        assert abs(p[f"d{axis}"] - true[f"d{axis}"]) <= 0.1 * abs(true[f"d{axis}"]), (axis, p, true)
    assert all(v["after_over_noise"] < v["before_over_noise"] for v in steps[0]["held_out"].values())
    assert set(steps[0]["held_out"]) == set(FT)
    assert [c["at_s"] for c in steps[0]["change_points"]] == [p["from_s"], p["to_s"]]
    segments = result["ft_steps"]["r_arm_ft"]
    assert len(segments) == 1 and segments[0]["from_s"] == p["from_s"] and segments[0]["to_s"] == p["to_s"]
    assert "the offset steps from 5.0" in stdout
    control, _, control_stdout = gaps("control_short")
    assert control["effects"] == [] and "named: nothing" in control_stdout
    assert control["ft_steps"] == {}


def test_declared_steps_are_taken_as_known(gaps) -> None:
    """`--steps 5,10,9999` on the step's run: the step from 5 s to 10 s and the one from 10 s to the end, declared (in
    the model whatever their held-out gain); the first has the true sizes within 10 %, the second ~nothing. The point
    beyond the data is said and left out (it made the step before it run "to 9999 s": a walkthrough)."""
    result, truth, stdout = gaps("ft_step", None, "--steps", "5,10,9999")
    assert "outside the data" in stdout and "9999 s" in stdout
    true = _truth(truth, "ft_step")
    declared = [e for e in result["effects"] if e.get("declared")]
    assert [(e["parameters"]["from_s"], e["parameters"].get("to_s")) for e in declared] == [(5.0, 10.0), (10.0, None)]
    assert all(e["in_model"] and e["name"] == "ft_step" for e in declared)
    for axis in ("fx", "fy", "fz", "tx", "ty", "tz"):
        assert abs(declared[0]["parameters"][f"d{axis}"] - true[f"d{axis}"]) <= 0.1 * abs(true[f"d{axis}"])
        assert abs(declared[1]["parameters"][f"d{axis}"]) <= 0.1 * abs(true[f"d{axis}"])
    assert "declared: ft_step on sensor r_arm_ft" in stdout
    assert not any(e["name"] == "ft_step" and not e.get("declared") for e in result["effects"])  # not searched


@pytest.mark.parametrize("steps, words", [("24.4,abc", "separated by commas"), ("61.2,24.4", "must increase"),
                                          ("nan", "finite"), ("", "separated by commas")])
def test_bad_steps_are_one_line_exit_2(tmp_path: Path, steps: str, words: str) -> None:
    done = dynid("gaps", "--data", str(tmp_path / "run.csv"), "--steps", steps)
    assert done.returncode == 2 and words in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr


def test_simulated_step_needs_its_times_in_order(tmp_path: Path) -> None:
    done = dynid("simulate", "--kind", "identification", "--effect", "ft_step:from_s=10,to_s=5", "--out", str(tmp_path / "s"))
    assert done.returncode == 2 and "needs 0 <= from_s < to_s" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and not (tmp_path / "s").exists()


def test_nonlinear_parameters_found_by_search(gaps) -> None:
    result, truth, _ = gaps("cogging")
    period = result["effects"][0]["parameters"]["period_deg"]
    assert abs(period - _truth(truth, "cogging")["period_deg"]) <= 0.2 * _truth(truth, "cogging")["period_deg"]
    result, truth, _ = gaps("ft_drift")
    tau = result["effects"][0]["parameters"]["tau"]
    assert abs(tau - _truth(truth, "ft_drift")["tau"]) <= 0.2 * _truth(truth, "ft_drift")["tau"]
    result, truth, _ = gaps("base_tilt")
    assert result["effects"][0]["parameters"]["axis"] == _truth(truth, "base_tilt")["axis"]


def test_two_effects_on_different_joints_are_both_named(gaps) -> None:
    result, truth, stdout = gaps("two")
    assert sorted(_named(result)) == [("cogging", "motor m3"), ("spring", "joint r_shoulder_yaw")], stdout
    stiffness = _effect(result, "spring")["parameters"]["stiffness"]
    # measured 0.78 on this run: part of a shoulder spring is absorbed by the refitted gravity terms
    assert abs(stiffness - 1.0) <= 0.25


def _coordinate_coulomb(truth: dict, joint: str) -> float:
    """Mean Coulomb level of a joint's friction coordinate: a directly driven joint's motor turns with it, so its
    motor friction adds (dynid.simulation.actuation), and the simulator's Stribeck excess scales the sum."""
    from dynid.config.robot_config import load_config

    config = load_config("icub_right_arm")
    group = next(g for g in config.actuation if joint in g.joints)
    level = float(np.mean(truth["plant"]["joint_friction"][joint][:2]))
    if not group.coupled and group.motors:
        level += float(np.mean(truth["plant"]["motor_friction"][group.motors[0]][:2]))
    return level


def test_elbow_stribeck_is_named_and_its_gap_shrinks(gaps) -> None:
    """A large elbow Stribeck (v_s 0.1 rad/s): named on the elbow with static torque and velocity within 20 % of the
    truth, and the refit that carries it shrinks pwm.m3 (before the columns were scaled to unit norm, a candidate
    this narrow could be kept by the selection and dropped by the refit: "after" showed no change)."""
    result, truth, stdout = gaps("stribeck_elbow")
    assert _named(result)[0] == ("stribeck", "joint r_elbow"), stdout
    # With supply tracking the curve's small misfit near the stops can show, and an armature then takes under 10 % of
    # what the Stribeck took there (0.0041 kg m² on the Python plant's run; nothing on the C++ plant's): whatever comes
    # beside the Stribeck is reported tentative, as secondary to it, never named with confidence
    assert [(e["name"], e["where"]) for e in result["effects"] if e["confident"]] == [("stribeck", "joint r_elbow")], stdout
    assert all(not e["confident"] and e["secondary_to"] == "stribeck on joint r_elbow"
               for e in result["effects"][1:]), stdout
    p = _effect(result, "stribeck")["parameters"]
    true = _truth(truth, "stribeck")
    static = float(true["excess"]) * _coordinate_coulomb(truth, "r_elbow")
    assert abs(p["static_torque"] - static) <= 0.2 * static, (p, static)
    assert abs(p["velocity"] - float(true["velocity"])) <= 0.2 * float(true["velocity"]), p
    g = _gap(result, "pwm.m3")
    assert g["after_over_noise"] < 0.5 * g["before_over_noise"], g  # measured 5.67 → 0.97 (the tentative armature left out)


def test_slow_stribeck_is_not_misnamed(gaps) -> None:
    """The same Stribeck at v_s 0.02 rad/s: the plant then sticks through most of the curve, the rows at rest are
    left out, and what the moving rows show near the cut (the derivative filter smearing stops and breakaways) is
    LESS friction than Coulomb. The fit must not name that as a Stribeck effect (it did: −126 Nm at 0.0045 rad/s);
    whatever is named must shrink its channels, and pwm.m3 is reported unexplained."""
    result, _, stdout = gaps("stribeck_slow")
    assert not [e for e in result["effects"] if e["name"] == "stribeck" and e["parameters"]["static_torque"] <= 0], stdout
    if result["effects"]:
        assert sum(g["after_over_noise"] ** 2 for g in result["gap"]) < sum(g["before_over_noise"] ** 2 for g in result["gap"])
    assert "unexplained:" in stdout and "pwm.m3" in stdout.split("unexplained:")[1].splitlines()[0], stdout


def test_effect_outside_library_is_reported_unexplained(gaps) -> None:
    """Quadratic drag on the elbow: the closest library shape (a Stribeck curve) may be selected, but only as
    'tentative' (it removes too little of the excess); the residual is reported unexplained."""
    result, _, stdout = gaps("outside")
    assert not [e for e in result["effects"] if e["confident"]], stdout
    assert "unexplained:" in stdout
    assert _gap(result, "pwm.m3")["after_over_noise"] > 1.3


def test_ft_gain_is_estimated_trace_free(gaps) -> None:
    """The F/T gain error is named and its gap closed (above), but its matrix is not recoverable from arm motion:
    a common scale of the sensor is a scale of every inertia and motor gain (hence the trace-free estimate), and,
    nearly, force-vs-torque scales trade against the inertias beyond the sensor. So its parameter is not compared
    to the truth (README "Model gaps", known limits); the estimate is a full trace-free 6×6 matrix."""
    result, _, _ = gaps("ft_gain")
    E = np.array(_effect(result, "ft_gain")["parameters"]["matrix"])
    assert E.shape == (6, 6) and abs(np.trace(E)) < 1e-9 * np.abs(E).max()
    assert np.abs(E[~np.eye(6, dtype=bool)]).max() > 0  # cross-talk estimated, not only gains


def test_payload_is_named_against_the_given_model(gaps, default_model: Path, tmp_path: Path) -> None:
    """Against the session's fitted model (its inertias held, the rest refitted): the control run names nothing,
    the payload run names a payload on the right link with its mass and centre within 20 % of the truth, closes
    its channels' gap to ≤ 1.3× the floor, and the augmented model carries it in the link's inertial parameters,
    which export takes as a standard model's (nothing for the monitor to refuse)."""
    control, _, stdout = gaps("control", default_model)
    assert control["effects"] == [], stdout
    result, truth, stdout = gaps("payload", default_model)
    assert _named(result) == [("payload", "link r_hand")], stdout
    named = _effect(result, "payload")
    true = _truth(truth, "payload")
    assert named["confident"], stdout
    p = named["parameters"]
    assert abs(p["mass"] - true["mass"]) <= 0.2 * true["mass"], (p, true)
    com, true_com = np.array([p["com_x"], p["com_y"], p["com_z"]]), np.array([true[a] for a in "xyz"])
    assert np.linalg.norm(com - true_com) <= 0.2 * np.linalg.norm(true_com), (p, true)
    for g in result["gap"]:  # every channel: the F/T sees the weight, the shoulder and elbow carry it
        floor = max(1.0, _gap(control, g["channel"])["after_over_noise"])
        assert g["after_over_noise"] <= 1.3 * floor, (g, floor)
    assert max(g["before_over_noise"] for g in result["gap"]) > 5  # the gap was plain before: F/T 6.8–18× noise

    out = tmp_path / "augmented.json"
    done = dynid("gaps", "--model", str(default_model), "--data", str(Path(result["data"])), "--out", str(out))
    assert done.returncode == 0, done.stderr
    augmented, given = json.loads(out.read_text()), json.loads(default_model.read_text())
    assert augmented["effects"] == []  # folded into Φ, recorded beside
    assert augmented["gaps"]["in_inertial_parameters"][0]["where"] == "link r_hand"
    added = augmented["parameters"]["r_hand.m"] - given["parameters"]["r_hand.m"]
    assert abs(added - p["mass"]) < 1e-9, (added, p["mass"])
    done = dynid("export", "--model", str(out), "--out", str(tmp_path / "augmented.dcoef"))
    assert done.returncode == 0, done.stderr


def test_ft_gain_matrix_against_the_given_model(gaps, default_model: Path) -> None:
    """With the inertias held at a given model's, the wrench's scale is fixed and E is the sensor's own error: the
    gains (diagonal), the columns of the forces and the rows of the torques come within 20 % of the simulator's E
    (measured 6 %, 6 %, 13 %). The force rows' cross-talk FROM the torques is not: the torques at the sensor vary
    by tenths of a Nm, so 1 % of them is a few mN against 0.15 N of force noise."""
    result, truth, stdout = gaps("ft_gain", default_model)
    assert _named(result) == [("ft_gain", "sensor r_arm_ft")], stdout
    E = np.array(_effect(result, "ft_gain")["parameters"]["matrix"])
    E_true = np.array(_truth(truth, "ft_gain")["matrix"])

    def rel(a: np.ndarray, b: np.ndarray) -> float:
        return float(np.linalg.norm(a - b) / np.linalg.norm(b))

    assert rel(np.diag(E), np.diag(E_true)) <= 0.2
    assert rel(E[:, :3], E_true[:, :3]) <= 0.2
    assert rel(E[3:], E_true[3:]) <= 0.2
    control, _, _ = gaps("control", default_model)
    for c in FT:
        assert _gap(result, c)["after_over_noise"] <= 1.3 * max(1.0, _gap(control, c)["after_over_noise"])


def test_supply_tracking_lowers_the_floor(gaps) -> None:
    """The second pass, on inputs corrected by the first pass's supply estimate, takes the shoulder's PWM residual
    of the control run down to where the standard model has nothing left to explain (measured pwm.m0 1.82 → 1.37,
    pwm.m1 2.19 → 0.82× noise); the estimated supply ratios move (the plant's supply varies 3 %), and nothing is
    named either way."""
    tracked, _, tracked_stdout = gaps("control")
    constant, _, stdout = gaps("control", None, "--no-supply-tracking")
    assert "two passes" in tracked_stdout and tracked["supply"] is not None
    assert constant["supply"] is None and "two passes" not in stdout
    assert tracked["effects"] == [] and constant["effects"] == []
    for c in ("pwm.m0", "pwm.m1"):
        assert _gap(tracked, c)["after_over_noise"] < 0.8 * _gap(constant, c)["after_over_noise"], c
    for c in PWM:
        assert _gap(tracked, c)["after_over_noise"] <= 1.3 * _gap(constant, c)["after_over_noise"], c
    spans = [hi - lo for lo, hi in tracked["supply"]["ratio_range"].values()]
    assert len(spans) == 4 and min(spans) > 0.01, tracked["supply"]
    assert tracked["supply"]["first_pass"]["effects"] == []


def test_coupling_column_candidate_has_the_effect_shape(gaps) -> None:
    """The yaw's column 10 % off is not named on the realistic plant: it moves the shoulder rows' held-out error by
    under the 20 % bar (its leak is the small yaw motor's torque; README), and nothing wrong is named with
    confidence. The candidate has the effect's shape all the same: on a plant without noise and disturbance, fitted
    by least squares beside the standard model, it recovers the error within 20 % (measured 0.105), and the
    all-entries candidate, a gain change, is spanned (θ = 0)."""
    from dataclasses import replace as dc_replace

    from dynid.config.robot_config import load_config
    from dynid.gaps import workflow
    from dynid.gaps.selection import Design, weighted_columns
    from dynid.identify.validation import load_run
    from dynid.robot.effect_library import coupling_error
    from dynid.robot.model import RobotModel

    result, _, stdout = gaps("coupling_yaw")
    assert not [e for e in result["effects"] if e["confident"] and e["name"] != "coupling_error"], stdout
    result, truth, _ = gaps("coupling_yaw_clean")
    model = RobotModel(load_config("icub_right_arm"))
    ctx, A, b, w = workflow._collect(model, load_run(result["data"], model), 8)
    phi = workflow._analyse(model, ctx, A, b, w, workflow.Settings(supply=None), None)["_augmented"]["phi"]
    inertial = model.layout.span("inertial")
    ctx = dc_replace(ctx, phi=phi, rigid=A[:, :, inertial] @ phi[inertial])
    Aw = A * w[:, :, None]
    s, V = np.linalg.eigh(np.einsum("nri,nrj->ij", Aw, Aw))
    design = Design(Aw @ V[:, s > 1e-10 * s.max()], b * w, np.linspace(0, len(b), 6).astype(int))
    column = next(c for c in coupling_error(ctx) if c.where == "joint r_shoulder_yaw")
    error = design.fit(weighted_columns(column.values, w))[0][-1]
    true = float(_truth(truth, "coupling_error")["error"])
    assert abs(error - true) <= 0.2 * true, (error, true)
    whole = next(c for c in coupling_error(ctx) if c.where == "group shoulder")
    assert design.fit(weighted_columns(whole.values, w))[0][-1] == 0.0


def test_coupling_error_of_this_shoulder_is_a_gain_change() -> None:
    """The plant's default coupling error scales every ratio entry of T (not 0, not ±1) by 1 + e. For the iCub
    shoulder T = [[1,0,0],[-r,r,0],[-r,r,r]] that is T' = (1+e)T − e·E₀₀, and T'ᵀτ = Tᵀ diag(1, 1+e, 1+e) τ:
    exactly a gain change of m1 and m2, which the standard model fits. So the all-entries candidate (kept for robots
    with known gains) cannot be named here; one joint's column (a joint-side pulley) can (EXPECTED above)."""
    from dynid.config.robot_config import load_config

    g = next(g for g in load_config("icub_right_arm").actuation if g.name == "shoulder")
    e = 0.07
    T = g.coupling
    ratio = ~np.isclose(np.abs(T), 1.0) & (T != 0)
    T_true = T.copy()
    T_true[ratio] *= 1 + e
    tau = np.random.default_rng(1).normal(size=(3, 50))
    assert np.allclose(T_true.T @ tau, T.T @ np.diag([1, 1 + e, 1 + e]) @ tau)


def test_bad_input_is_one_line_exit_2(tmp_path: Path) -> None:
    done = dynid("gaps", "--data", str(tmp_path / "missing.npz"))
    assert done.returncode == 2
    assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr


def test_given_model_on_clean_validation_run(default_model: Path, default_experiments: dict[str, Path]) -> None:
    """The session's fitted model on the contact-free validation run (no hidden effect): nothing named, the given
    model's gap printed per channel, JSON on stdout with `--json -`."""
    done = dynid("gaps", "--model", str(default_model), "--data", str(default_experiments["validation"]), "--json", "-")
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert result["effects"] == []
    assert result["given_model"] == str(default_model)
    assert all(g["given_model_rms"] > 0 and g["before_rms"] > 0 for g in result["gap"])
    assert "given" in done.stderr  # the human table went to stderr
