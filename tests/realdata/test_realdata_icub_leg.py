"""The real iCub standing on its left foot (shared/realdata/icub_leg_insitu): the yarpdatadumper folder read as the
robot wrote it, the right leg's two F/T sensors fitted with the base at the stance sole, Table II per sensor
against CAD on swing time left out of the fit, the gap workflow's report of the step no model term explains, and
every command over the run without a traceback. The figures are in docs/robots/icub_leg.md."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from . import cli, convert

LEG = convert.REALDATA / "icub_leg_insitu"
DUMP = LEG / "dumperLeftLegNoIMU"
pytestmark = pytest.mark.skipif(not DUMP.is_dir(), reason=f"no real iCub leg data at {LEG}")

ROBOT = ("--robot", "icub_right_leg_standing", "--urdf", str(LEG / "iCubGenova02.urdf"))
FIT_WINDOW = ("--from", "23", "--to", "47")  # the swing while the ankle rests on its 30° stop
# the figures below are the unconstrained fit's (docs/robots/icub_leg.md); the leg's default is --consistent on
UNCONSTRAINED = ("--consistent", "off")
VALIDATION_WINDOW = ("--from", "47", "--to", "58.5")  # the rest of that swing: left out of the fit
SENSORS = ("r_leg_ft_sensor", "r_foot_ft_sensor")


def run(*args: str) -> subprocess.CompletedProcess:
    return cli.run(*args, keep_urdf_path=False)  # the test's --urdf is the only URDF found


def dynid(*args: str) -> dict:
    return cli.dynid(*args, keep_urdf_path=False)


@pytest.fixture(scope="module")
def fitted(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("leg") / "leg.json"
    dynid("fit", *ROBOT, "--data", str(DUMP), *FIT_WINDOW, *UNCONSTRAINED, "--out", str(out))
    return out


def test_the_dumper_folder_is_one_dataset(tmp_path: Path) -> None:
    result = dynid("import", *ROBOT, "--data", str(DUMP), "--out", str(tmp_path / "leg.npz"))
    assert result["samples"] > 7000
    ports = result["yarp"]["ports"]
    assert set(ports) == {"icub/left_leg/stateExt:o", "icub/right_leg/stateExt:o", "icub/right_leg/analog:o",
                          "icub/right_foot/analog:o"}
    assert all(0.009 < p["median_interval_s"] < 0.011 and p["max_interval_s"] < 0.02 for p in ports.values())


def test_each_sensor_beats_cad_on_left_out_swing(fitted: Path) -> None:
    v = dynid("validate", "--model", str(fitted), "--data", str(DUMP), *VALIDATION_WINDOW)
    tables = v["table_ii_sensors"]
    assert set(tables) == set(SENSORS)
    for sensor in SENSORS:
        for what in ("force", "torque"):
            ident, cad = tables[sensor]["identified"][what]["mean"], tables[sensor]["cad"][what]["mean"]
            print(f"{sensor} {what}: identified {ident:.4g}, CAD {cad:.4g} ({100 * (ident / cad - 1):+.1f} %)")
            assert ident < cad, (sensor, what)


def test_the_base_at_the_sole_beats_the_pelvis(tmp_path: Path, fitted: Path) -> None:
    """With the base at root_link (the pelvis, which tilts while the robot balances) gravity is wrong by the tilt."""
    text = (Path(__file__).resolve().parents[2] / "tools/dynid/config/robots/icub_right_leg_standing.yaml").read_text()
    text = text.split("\ncan:")[0] + "\n"  # the bus (the last section) carries the standing leg's joints
    pelvis = tmp_path / "pelvis.yaml"
    pelvis.write_text(text.replace("base_link: l_sole", "base_link: root_link")
                      .replace("joints: [l_hip_pitch, l_hip_roll, l_hip_yaw, l_knee, l_ankle_pitch, l_ankle_roll,\n", "joints: [")
                      .replace("    - {port: icub/left_leg/stateExt:o", "    # ")
                      .replace("urdf: {supplied: iCubGenova02.urdf}", f"urdf: {{path: {LEG / 'iCubGenova02.urdf'}}}"))
    model = tmp_path / "pelvis.json"
    dynid("fit", "--robot", str(pelvis), "--data", str(DUMP), *FIT_WINDOW, *UNCONSTRAINED, "--out", str(model))
    at_pelvis = dynid("validate", "--model", str(model), "--data", str(DUMP), *VALIDATION_WINDOW)["table_ii_sensors"]
    at_sole = dynid("validate", "--model", str(fitted), "--data", str(DUMP), *VALIDATION_WINDOW)["table_ii_sensors"]
    force = {s: (at_sole[s]["identified"]["force"]["mean"], at_pelvis[s]["identified"]["force"]["mean"]) for s in SENSORS}
    print("force error, base at l_sole vs root_link: " + ", ".join(f"{s} {a:.3f} vs {b:.3f} N" for s, (a, b) in force.items()))
    assert force["r_leg_ft_sensor"][0] < force["r_leg_ft_sensor"][1]


def test_the_gap_workflow_locates_the_step(tmp_path: Path) -> None:
    """No library effect is accepted that makes a channel worse on held-out blocks; the step of the leg sensor while
    the ankle rests on its stop is named with its change points (`ft_step`, issue 34; test_realdata_steps.py has its
    figures), and what the fix leaves is located with the joints held there."""
    g = dynid("gaps", *ROBOT, "--data", str(DUMP), "--from", "14", "--to", "65", "--out", str(tmp_path / "aug.json"))
    for e in g["effects"]:
        assert e["name"] != "ft_gain"  # it lowers the total but makes fy and tz worse on held-out blocks
    gap = {x["channel"]: x for x in g["gap"]}
    # the rule of dynid.gaps.selection.worse_channels: no channel's held-out RMS up by over 5 % and over its noise σ
    # (measured: the step's refit moves the leg sensor's fy, which it does not touch, 25.49 → 25.82× noise, +1.3 %)
    assert all(x["after_over_noise"] <= 1.05 * x["before_over_noise"]
               or x["after_over_noise"] - x["before_over_noise"] <= 1.0 for x in gap.values())
    steps = [ep for ep in g["episodes"] if any(c.startswith("ft.r_leg_ft_sensor.") for c in ep["channels"])]
    assert steps, g["episodes"]
    held = {h["joint"]: h for ep in steps for h in ep["held_joints"]}
    assert held["r_ankle_pitch"]["limit_deg"] == pytest.approx(30.0)
    named = [e["parameters"] for e in g["effects"] if e["name"] == "ft_step" and e["in_model"]
             and e["where"] == "sensor r_leg_ft_sensor"]
    assert any(20 < p["from_s"] < 32 and 50 < p.get("to_s", 0) < 62 for p in named), g["effects"]


@pytest.mark.parametrize(
    "args",
    [
        ("structure",),
        ("import", "--from", "13", "--to", "66"),
        ("fit", "--from", "23", "--to", "47"),  # the window that once ended in a LinAlgError
        ("fit", "--from", "14", "--to", "65", "--noise", "estimate"),
        ("fit",),  # the whole run, both feet on the ground at its ends
        ("fit", "--from", "5", "--to", "12"),  # standing still: nothing moves
        ("fit", "--from", "70", "--to", "80"),  # a window past the end
        ("fit", "--from", "47", "--to", "23"),  # a reversed one
        ("gaps", "--from", "14", "--to", "30"),  # shorter than the gap workflow's 2000 samples
        ("detect", "--from", "47", "--to", "65"),
        ("validate", "--from", "47", "--to", "65"),
        ("export",),
        ("report",),  # no contact labels in these logs: the report without --contact
    ],
)
def test_every_command_ends_in_a_result_or_one_line(tmp_path: Path, fitted: Path, args: tuple[str, ...]) -> None:
    command, rest = args[0], list(args[1:])
    if command == "report":
        call = [command, "--model", str(fitted), "--validation", str(DUMP), "--out", str(tmp_path / "out.html")]
    elif command in ("validate", "detect", "export"):
        call = [command, "--model", str(fitted)]
        if command != "export":
            call += ["--data", str(DUMP)]
        call += ["--out", str(tmp_path / "out.dcoef")] if command == "export" else []
    elif command == "structure":
        call = [command, *ROBOT]
    else:
        call = [command, *ROBOT, "--data", str(DUMP)]
        call += ["--out", str(tmp_path / ("out.npz" if command == "import" else "out.json"))]
    done = run(*call, *rest)
    assert "Traceback" not in done.stderr, done.stderr
    assert done.returncode in (0, 2), done.stderr
    if done.returncode == 2:
        assert len(done.stderr.strip().splitlines()) == 1, done.stderr
        assert not list(tmp_path.glob("out.*")), "a refused command left a file behind"
