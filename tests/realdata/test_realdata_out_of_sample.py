"""α out of sample on real robots (issue 30): false positives at α = 0.99 on contact-free data the fit and its
(cross-validated) calibration never saw. Figures and the misses: docs/detection.md#out-of-sample."""

from __future__ import annotations

from pathlib import Path

import pytest

from . import cli, convert
from .leg_support import put_down_onset

UR = convert.REALDATA / "ur10e_mamedov"
LEG = convert.REALDATA / "icub_leg_insitu"
pytestmark = pytest.mark.skipif(not convert.REALDATA.is_dir(), reason=f"no real data at {convert.REALDATA}")


def held_out(result: dict, variant: str = "momentum") -> tuple[float, float | None]:
    oos = result["out_of_sample"]
    assert oos["data_outside_fit_and_calibration"] is True
    v = oos["variants"][variant]
    assert v["calibration"] == "cross-validated"
    return v["fpr"], v["in_sample_calibration_fpr"]


@pytest.mark.skipif(not UR.is_dir(), reason=f"no UR10e data at {UR}")
def test_ur10e_contact_runs_outside_their_episodes(tmp_path: Path) -> None:
    model = tmp_path / "ur.json"
    cli.dynid("fit", "--robot", "ur10e_known_gains", "--urdf", str(UR / "ur10e.urdf"), "--data",
              str(UR / "identification" / "ur-20_02_19_14harm50sec.csv"), "--out", str(model))
    figures = {}
    for name in ("collision_3link", "ur-20_01_22-push_pose_1"):
        run = UR / "contact" / f"{name}.csv"
        result = cli.dynid("detect", "--model", str(model), "--data", str(run), "--episodes",
                           str(UR / "contact" / f"{name}.episodes.csv"), "--label-widening", "0.1")
        figures[name] = held_out(result)
        if name == "collision_3link":
            figures["combined"] = result["out_of_sample"]["variants"]["combined"]["fpr"]
    print(f"UR10e momentum FPR cross-validated / in-sample: {figures}")
    fpr, in_sample = figures["collision_3link"]
    assert fpr <= 0.02 and fpr < in_sample  # measured 1.03 % against 1.35 %
    assert figures["combined"] <= 0.02  # the default detector: measured 1.60 %
    assert figures["ur-20_01_22-push_pose_1"][0] <= 0.02  # measured 0.00 %


def test_panda_last_third(tmp_path: Path) -> None:
    full = tmp_path / "full.csv"
    convert.convert_panda().write(full)
    lines = full.read_text().splitlines()
    n = len(lines) - 1
    train, test = tmp_path / "train.csv", tmp_path / "test.csv"
    train.write_text("\n".join([lines[0], *lines[1 : 1 + 2 * n // 3]]) + "\n")
    test.write_text("\n".join([lines[0], *lines[1 + 2 * n // 3 :]]) + "\n")
    model = tmp_path / "panda.json"
    cli.dynid("fit", "--robot", "panda", "--data", str(train), "--out", str(model))
    result = cli.dynid("detect", "--model", str(model), "--data", str(test))
    momentum, calibrated = held_out(result), held_out(result, "calibrated")
    print(f"Panda last third: momentum {momentum}, calibrated {calibrated} (cross-validated, in-sample)")
    assert momentum[0] <= 0.02  # measured 1.07 % (in-sample calibration 1.21 %)
    assert calibrated[0] <= 0.02 and calibrated[0] < calibrated[1]  # measured 0.73 % against 1.72 %


@pytest.mark.skipif(not (LEG / "dumperLeftLegNoIMU").is_dir(), reason=f"no iCub leg data at {LEG}")
def test_icub_leg_swing_left_out(tmp_path: Path) -> None:
    """Fitted on the swing's first half (14-39.5 s, after the lift-off transient), the second half is held out, up to
    where the stance foot starts to unload (62.4 s, leg_support.py: the right foot touching down, which the README's
    65.6 s put-down and the earlier 65 s end of this window counted as swing). The other way round is not met
    (docs/detection.md#out-of-sample says why) and is not asserted."""
    leg = LEG / "dumperLeftLegNoIMU"
    onset, _ = put_down_onset(leg)
    assert 62.0 <= onset <= 62.8, onset  # measured 62.42 s
    model = tmp_path / "leg.json"
    cli.dynid("fit", "--robot", "icub_right_leg_standing", "--urdf", str(LEG / "iCubGenova02.urdf"), "--data",
              str(leg), "--from", "14", "--to", "39.5", "--consistent", "off", "--out", str(model),  # as measured
              keep_urdf_path=False)
    result = cli.dynid("detect", "--model", str(model), "--data", str(leg), "--from", "39.5", "--to", f"{onset:.2f}",
                       keep_urdf_path=False)
    fpr, in_sample = held_out(result)
    combined = result["out_of_sample"]["variants"]["combined"]["fpr"]
    print(f"iCub leg swing 39.5-{onset:.2f} s: momentum FPR {100 * fpr:.2f} % (in-sample calibration "
          f"{100 * in_sample:.2f} %), combined {100 * combined:.2f} %")
    assert fpr <= 0.02 and combined <= 0.02  # measured 1.00 % (in-sample 0.96 %), combined 0.26 %


@pytest.mark.skipif(not (LEG / "dumperLeftLegNoIMU").is_dir(), reason=f"no iCub leg data at {LEG}")
def test_icub_leg_time_blocks_left_out_and_the_postures_the_fit_never_saw(tmp_path: Path) -> None:
    """The swing (14-62.42 s) in five time blocks, each left out of the fit in turn (tools/benchmarks/out_of_sample.py
    runs all five; docs/detection.md#out-of-sample). An inner block, its postures among the fit's: α holds. The first
    block, whose ankle and hip postures the rest of the swing never takes (r_ankle_roll to -14.9° against -6.8°):
    α does not (the combined detector's FPR about 50 %), and `detect` names those postures beside the figure."""
    leg = LEG / "dumperLeftLegNoIMU"
    edges = (14.0, 23.684, 33.368, 43.052, 52.736, 62.42)
    urdf = ("--urdf", str(LEG / "iCubGenova02.urdf"))
    found = {}
    for k in (0, 2):
        windows = [(a, b) for a, b in ((edges[0], edges[k]), (edges[k + 1], edges[-1])) if b > a]
        data = [x for a, b in windows for x in ("--data", f"{leg}@{a!r}:{b!r}")]
        model = tmp_path / f"leg{k}.json"
        cli.dynid("fit", "--robot", "icub_right_leg_standing", *urdf, *data, "--consistent", "off", "--out", str(model),
                  keep_urdf_path=False)
        found[k] = cli.dynid("detect", "--model", str(model), "--data", str(leg), "--from", repr(edges[k]), "--to",
                             repr(edges[k + 1]), keep_urdf_path=False)["out_of_sample"]
        assert found[k]["data_outside_fit_and_calibration"] is True
    combined = {k: o["variants"]["combined"]["fpr"] for k, o in found.items()}
    print(f"iCub leg blocks left out, combined FPR: {combined}")
    assert combined[2] <= 0.02  # measured 0.00 %
    assert combined[0] > 0.2  # measured 49.6 %: extrapolated, and named
    outside = {o["joint"]: o for o in found[0]["postures_outside_fit"]}
    assert {"r_ankle_roll", "r_ankle_pitch", "r_hip_yaw"} <= set(outside), sorted(outside)
    assert outside["r_ankle_roll"]["here_from_deg"] < outside["r_ankle_roll"]["fit_from_deg"] - 5
