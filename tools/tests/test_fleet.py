"""`dynid fleet` (issue 33): twelve simulated robots of the default arm, robot seeds 0-11, robot 7's elbow worn (its
friction doubled, `dynid simulate --friction-scale r_elbow=2`); it is named, and no other robot is. The page renders
in headless Chromium."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from conftest import dynid
from dynid.config.robot_config import load_config
from dynid.simulation import SimulationSettings, simulate
from dynid.simulation.output import write_simulation

ROBOTS = 12
WORN = 7
SECONDS = 20.0


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> dict:
    root = tmp_path_factory.mktemp("fleet")
    config = load_config("icub_right_arm")
    for i in range(ROBOTS):
        worn = (("r_elbow", 2.0),) if i == WORN else ()
        sim = simulate(config, SimulationSettings(duration=SECONDS, seed=i, robot_seed=i, friction_scale=worn))
        write_simulation(sim, root / "runs" / f"arm{i:02d}" / "run")  # one folder per robot names it
    done = dynid("fleet", "--data", str(root / "runs"), "--out", str(root / "out"), "--blocks", "5",
                 "--json", str(root / "fleet.json"))
    assert done.returncode == 0, done.stderr
    return {"root": root, "stdout": done.stdout, "result": json.loads((root / "fleet.json").read_text())}


def test_the_worn_joint_is_named_and_no_other_robot(fleet: dict) -> None:
    r = fleet["result"]
    assert r["robots"] == [f"arm{i:02d}" for i in range(ROBOTS)]
    assert [o["robot"] for o in r["outliers"]] == [f"arm{WORN:02d}"]
    (named,) = r["outliers"][0]["groups"]
    assert named["group"] == "friction r_elbow" and named["statistic"] > r["bound"]
    assert any(g["group"] == "scale" for g in r["groups"])  # tested, and named nowhere: the gains absorb a scale
    # Each of its four coefficients is well above the others' median (doubled, give or take the fleet's spread)
    assert all(1.3 < x < 3.0 for x in named["ratio_to_median"])
    assert "STANDS OUT: arm07: friction r_elbow" in fleet["stdout"]
    # Every robot has its model, and the comparison carries each robot's value and standard error
    for robot, path in r["models"].items():
        assert json.loads(Path(path).read_text())["robot"]["name"] == "icub_right_arm"
    elbow = [p for p in r["parameters"] if p["group"] == "friction r_elbow"]
    assert len(elbow) == 4 and all(len(p["values"]) == ROBOTS == len(p["standard_errors"]) for p in elbow)
    # The truth agrees: the worn robot's elbow friction is doubled in truth.json, the others' as drawn
    truth = json.loads((fleet["root"] / "runs" / f"arm{WORN:02d}" / "run" / "truth.json").read_text())
    assert truth["friction_scale"] == {"r_elbow": 2.0}
    values = np.array([elbow[0]["values"][f"arm{i:02d}"] for i in range(ROBOTS)])
    assert values.argmax() == WORN


def test_a_fleet_into_a_directory_that_holds_files_is_refused(fleet: dict) -> None:
    """A walkthrough's second fleet into the first one's directory left the first's models beside its own, unread by
    its page; refused before any fit, nothing written."""
    out = fleet["root"] / "out"
    before = sorted(p.relative_to(out) for p in out.rglob("*"))
    done = dynid("fleet", "--data", str(fleet["root"] / "runs"), "--out", str(out))
    assert done.returncode == 2 and "it holds files already" in done.stderr, done.stderr
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == before


def test_a_fleet_needs_three_robots_and_says_so(fleet: dict, tmp_path: Path) -> None:
    runs = fleet["root"] / "runs"
    done = dynid("fleet", "--data", f"a={runs / 'arm00' / 'run'}", "--data", f"b={runs / 'arm01' / 'run'}",
                 "--out", str(tmp_path / "out"))
    assert done.returncode == 2 and "at least 3" in done.stderr and not (tmp_path / "out").exists()


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(CHROMIUM is None, reason="no chromium (scripts/setup installs Debian's chromium as root)")
def test_the_fleet_page_renders_in_headless_chromium(fleet: dict, tmp_path: Path) -> None:
    from test_report import OFFLINE

    page = fleet["root"] / "out" / "fleet.html"
    shot = tmp_path / "fleet.png"
    done = subprocess.run([CHROMIUM, *OFFLINE, f"--user-data-dir={tmp_path / 'profile'}", "--window-size=1200,1800",
                           f"--screenshot={shot}", page.as_uri()], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and shot.is_file(), done.stderr[-2000:]
    from PIL import Image

    pixels = np.asarray(Image.open(shot).convert("RGB"), dtype=float)
    assert pixels.shape[:2] == (1800, 1200) and pixels.std() > 20
    # The worn robot's cell is marked (the page's pink), and the figures are there
    assert np.any(np.all(np.abs(pixels - [246, 200, 200]) < 3, axis=-1))
    text = page.read_text()
    assert text.count("<img") == 4 and "arm07</b>: friction r_elbow" in text  # scale, friction, gains, F/T offsets


def test_runs_linked_from_a_shared_store_belong_to_the_folder_given(fleet: dict, tmp_path: Path) -> None:
    """A folder per robot whose runs are symlinks into a shared store: each robot is the folder the link is in, not
    the one it points to (a walkthrough's three robots were merged into one named after the store); and one recording
    given as two robots' is refused before any fit."""
    from dynid.io.run_paths import expand_named

    runs = fleet["root"] / "runs"
    lab = tmp_path / "lab"
    for robot, source in (("robot_a", "arm00"), ("robot_b", "arm01"), ("robot_c", "arm02")):
        (lab / robot).mkdir(parents=True)
        (lab / robot / "run").symlink_to(runs / source / "run")
    assert [r.name for r in expand_named([str(lab)])] == ["robot_a", "robot_b", "robot_c"]
    (lab / "robot_d").mkdir()
    (lab / "robot_d" / "run").symlink_to(runs / "arm00" / "run")  # robot_a's run again, linked
    done = dynid("fleet", "--data", str(lab), "--out", str(tmp_path / "out"))
    assert done.returncode == 2 and "is named twice" in done.stderr and "default robot" not in done.stderr
    (lab / "robot_d" / "run").unlink()
    shutil.copytree(runs / "arm00" / "run", lab / "robot_d" / "run")  # ... and copied
    done = dynid("fleet", "--data", str(lab), "--out", str(tmp_path / "out"))
    assert done.returncode == 2 and "hold the same samples" in done.stderr, done.stderr
    assert not (tmp_path / "out").exists()


def test_a_negative_coefficient_is_drawn_where_it_can_be_seen() -> None:
    """A panel of friction coefficients was on a log axis whenever its first coefficient was positive on every robot:
    another's negative value (the outlier, e.g. a fit that made friction feed energy) vanished from the figure."""
    from dynid.report.fleet import group_figure

    robots = ["a", "b", "c", "d"]

    def coefficient(name: str, values: list[float]) -> dict:
        return {"kind": "friction", "group": "friction j1", "name": f"j1.{name}", "log_scale": min(values) > 0,
                "values": dict(zip(robots, values)), "standard_errors": dict(zip(robots, [0.01] * 4))}

    result = {"robots": robots, "outliers": [],
              "parameters": [coefficient("fc_pos", [0.5, 0.52, 0.48, 0.51]), coefficient("fv_pos", [0.2, 0.21, -0.3, 0.19])]}
    ax = group_figure(result, "friction", "t").axes[0]
    assert ax.get_yscale() == "linear"
    low, high = ax.get_ylim()
    assert low < -0.3 / 0.2 < high  # the negative coefficient over its median's magnitude, inside the axis
    result["parameters"][1] = coefficient("fv_pos", [0.2, 0.21, 0.3, 0.19])
    assert group_figure(result, "friction", "t").axes[0].get_yscale() == "log"


# ---- a scale is named once, as a scale ------------------------------------------------------------------------------

PANDAS = 8
SCALED, WORN_PANDA, LOADED = 2, 4, 6
FRICTION = [(0.8, 0.6), (0.8, 0.6), (0.6, 0.4), (0.6, 0.4), (0.3, 0.2), (0.3, 0.2), (0.2, 0.1)]  # Nm, Nm s/rad


@pytest.fixture(scope="module")
def panda_fleet(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """Eight synthetic Pandas (torques of the plant's truth), friction drawn within ±5 % per coefficient; robot 2's
    torques read 1.3 times too large (a torque sensor's gain), robot 4's joint 4 friction doubled (worn), robot 6
    carrying 2 kg its runs do not declare."""
    from synthetic_panda import panda_run

    from dynid.robot.model import RobotModel

    root = tmp_path_factory.mktemp("pandas")
    model = RobotModel(load_config("panda"))
    rng = np.random.default_rng(0)
    for i in range(PANDAS):
        friction = [[c * rng.uniform(0.95, 1.05) for c in (fc, fc, fv, fv)] for fc, fv in FRICTION]
        if i == WORN_PANDA:
            friction[3] = [2 * c for c in friction[3]]
        folder = root / "runs" / f"panda{i}"
        folder.mkdir(parents=True)
        panda_run(model, 10 + i, 15.0, friction=friction, scale=1.3 if i == SCALED else 1.0,
                  load_kg=2.0 if i == LOADED else 0.0).save(folder / "run.npz")
    done = dynid("fleet", "--robot", "panda", "--data", str(root / "runs"), "--out", str(root / "out"),
                 "--json", str(root / "fleet.json"))
    assert done.returncode == 0, done.stderr
    return {"stdout": done.stdout, "result": json.loads((root / "fleet.json").read_text()), "root": root}


def test_a_scaled_robot_is_named_as_a_scale_not_as_friction_on_every_joint(panda_fleet: dict) -> None:
    """Every torque of robot 2 read ×1.3: it was named for friction on every joint (a walkthrough, on the UR10e's
    currents). Its gravity torques say scale; its friction, the scale taken out, is the fleet's; robot 4's worn joint
    is still named, as friction."""
    r = panda_fleet["result"]
    named = {o["robot"]: [g["group"] for g in o["groups"]] for o in r["outliers"]}
    # The loaded robot's gravity torques are larger too, named `scale` (the message allows a load); its friction, as
    # measured the fleet's, is not named, though the scale taken out makes it look low (a walkthrough's UR10e with
    # 2.8 kg: friction named on four joints)
    stat = {g["group"]: g["statistic"] for g in r["groups"]}
    loaded = f"panda{LOADED}"
    print(f"scale: S {stat['scale'][f'panda{SCALED}']:.1f} (×1.3 torques), {stat['scale'][loaded]:.1f} (2 kg); the loaded "
          f"robot's friction |S| ≤ {max(abs(v[loaded]) for g, v in stat.items() if g.startswith('friction')):.1f}, the "
          f"bound {r['bound']:.2f}")
    assert named == {f"panda{SCALED}": ["scale"], f"panda{WORN_PANDA}": ["friction panda_joint4"],
                     loaded: ["scale"]}, named
    (scale,) = next(o["groups"] for o in r["outliers"] if o["robot"] == f"panda{SCALED}")
    assert scale["ratio_to_median"][0] == pytest.approx(1.3, rel=0.02)
    assert f"STANDS OUT: panda{SCALED}: scale" in panda_fleet["stdout"]
    # the reason named has its figure: c_r robot by robot (it had none; the friction panels showed raw ratios alone)
    assert r["scale"]["values"][f"panda{SCALED}"] == pytest.approx(1.3, rel=0.02)
    assert '<figure id="fig-scale">' in (panda_fleet["root"] / "out" / "fleet.html").read_text()
