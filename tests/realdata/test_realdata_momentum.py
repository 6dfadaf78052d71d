"""The momentum detector on the real runs (docs/detection.md): UR10e collisions and pushes against the model-free
episode labels beside the runs, and the iCub leg's right foot on the ground. Each figure asserted is the one
measured, with a small margin; the issue's targets that are not reached are named in docs/detection.md."""

from __future__ import annotations

from pathlib import Path

import pytest

from . import convert
from .cli import dynid

UR = convert.REALDATA / "ur10e_mamedov"
LEG_ROOT = convert.REALDATA / "icub_leg_insitu"
LEG = LEG_ROOT / "dumperLeftLegNoIMU"


@pytest.fixture(scope="module")
def ur_model(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if not UR.is_dir():
        pytest.skip(f"no real UR10e data at {UR}")
    out = tmp_path_factory.mktemp("ur") / "ur.json"
    dynid("fit", "--robot", "ur10e_known_gains", "--urdf", str(convert.UR10E_URDF), "--data",
          str(UR / "identification" / "ur-20_02_19_14harm50sec.csv"), "--out", str(out))
    return out


def ur_detect(model: Path, name: str) -> dict:
    return dynid("detect", "--model", str(model), "--data", str(UR / "contact" / f"{name}.csv"), "--episodes",
                 str(UR / "contact" / f"{name}.episodes.csv"), "--label-widening", "0.1")


def test_ur10e_collisions(ur_model: Path) -> None:
    """All 11 episodes, FP outside them under 2 %; the onsets sit one or two samples (8-16 ms) after the model-free
    deviation's own crossing (the labels' start + 0.1 s), one at 344 ms: the issue's "every onset within 100 ms
    of the label" is not reached (docs/detection.md). The thresholds are calibrated out of sample (cross-validated
    residuals), so they sit higher than the fit's own residuals would put them: 104 ms and 1.35 % in-sample."""
    result = ur_detect(ur_model, "collision_3link")
    m = result["variants"]["momentum"]
    print("UR10e collision_3link:", {k: (v["episodes_detected"], v["fpr"], v["delay_s"]) for k, v in
                                     result["variants"].items()})
    assert result["episodes_file"]["episodes"] == 11
    assert m["episodes_detected"] == 11 and m["fpr"] <= 0.02  # measured 11/11, 1.03 %
    assert m["delay_s"]["median"] <= 0.125  # measured 114 ms (14 ms after labels' start + 0.1 s)
    assert m["delay_s"]["max"] <= 0.36  # measured 344 ms
    assert result["variants"]["calibrated"]["fpr"] > m["fpr"]  # today's: 3.00 % on this run


def test_ur10e_pushes_on_the_resting_arm(ur_model: Path) -> None:
    """The pushes found while the arm rests: 3 of 4 with out-of-sample thresholds (4 of 4 in-sample, at the cost of
    the FP rate the collision run shows); today's calibrated detector leaves resting joints out: 2/4."""
    result = ur_detect(ur_model, "ur-20_01_22-push_pose_1")
    m = result["variants"]["momentum"]
    print("UR10e push_pose_1:", {k: (v["episodes_detected"], v["fpr"], v["tpr"]) for k, v in result["variants"].items()})
    assert m["episodes"] == 4 and m["episodes_detected"] >= 3  # measured 3/4
    assert m["fpr"] <= 0.02  # measured 0.00 %
    assert m["tpr"] >= 0.25  # measured 29.2 % of the labelled samples (labels widened by 0.1 s)
    events = result["events"]
    assert events and all(len(e["tau_ext_nm"]) == 6 and e["joint"] is not None for e in events)


def test_ur10e_fitted_on_its_excitation_runs_finds_every_push_and_collision(tmp_path: Path) -> None:
    """Fitted on the four unloaded excitation runs (as a lab fits on the excitation data it has), the default
    (combined) detector finds all 4 pushes and all 11 collisions, under 2 % outside them; on the 14-harmonic run
    alone the pushes give 3 of 4 (above): its friction band is wider. The monitor's test fits the same way."""
    if not UR.is_dir():
        pytest.skip(f"no real UR10e data at {UR}")
    model = tmp_path / "ur4.json"
    runs = sorted((UR / "identification").glob("ur-*.csv"))
    runs = [r for r in runs if "Load" not in r.name]  # the loaded run carries a payload the fit is not told of
    assert len(runs) == 4
    dynid("fit", "--robot", "ur10e_known_gains", "--urdf", str(convert.UR10E_URDF),
          *[a for r in runs for a in ("--data", str(r))], "--out", str(model))
    pushes, collisions = ur_detect(model, "ur-20_01_22-push_pose_1"), ur_detect(model, "collision_3link")
    for name, result in (("push_pose_1", pushes), ("collision_3link", collisions)):
        print(f"UR10e {name}, fitted on four runs:",
              {k: (v["episodes_detected"], v["fpr"]) for k, v in result["variants"].items()})
    p, c = pushes["variants"]["combined"], collisions["variants"]["combined"]
    assert p["episodes_detected"] == p["episodes"] == 4 and p["fpr"] <= 0.02  # measured 4/4, 0.00 %
    assert c["episodes_detected"] == c["episodes"] == 11 and c["fpr"] <= 0.02  # measured 11/11, 1.77 %
    assert pushes["variants"]["momentum"]["episodes_detected"] == 4  # measured 4/4


@pytest.mark.skipif(not LEG.is_dir(), reason=f"no iCub leg run at {LEG}")
def test_icub_leg_right_foot_on_the_ground(tmp_path: Path) -> None:
    """Fitted and calibrated on the swing (14-65 s); labels: both feet down before 13.1 s and after 65.6 s."""
    model = tmp_path / "leg.json"
    dynid("fit", "--robot", "icub_right_leg_standing", "--urdf", str(LEG_ROOT / "iCubGenova02.urdf"), "--data",
          str(LEG), "--from", "14", "--to", "65", "--consistent", "off", "--out", str(model))  # as measured
    labels = tmp_path / "episodes.csv"
    labels.write_text("t_start,t_end\n0,13.1\n65.6,1000\n")
    result = dynid("detect", "--model", str(model), "--data", str(LEG), "--episodes", str(labels), "--calibration",
                   str(LEG), "--calibration-from", "14", "--calibration-to", "65")
    m = result["variants"]["momentum"]
    print("iCub leg:", {k: (v["tpr"], v["fpr"]) for k, v in result["variants"].items()})
    assert m["tpr"] >= 0.99  # measured 99.2 %
    assert m["fpr"] <= 0.03  # measured 2.70 % over 13.1-65.6 s (1.12 % on 14-65 s): the 2 % target is not reached
    assert result["variants"]["paper"]["fpr"] > 0.05  # the paper's variant: 7.7 %
