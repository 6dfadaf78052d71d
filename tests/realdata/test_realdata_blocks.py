"""Every-block validation on real runs. The iCub leg (shared/realdata/icub_leg_insitu; docs/robots/icub_leg.md):
fitted on the documented 23–47 s, `validate --blocks 6` over 14–65 s finds what the single held-out window hides,
the leg sensor's torque error 20 times CAD's on the blocks before and after the step `dynid gaps` reports (issue
34), and below CAD on the held-out block after the fit. The UR10e (docs/robots/ur10e.md): every block of
ptp_10_points, the worst where the arm rests."""

from __future__ import annotations

from pathlib import Path

import pytest

from . import cli, convert

LEG = convert.REALDATA / "icub_leg_insitu"
DUMP = LEG / "dumperLeftLegNoIMU"
UR = convert.REALDATA / "ur10e_mamedov"
needs_leg = pytest.mark.skipif(not DUMP.is_dir(), reason=f"no real iCub leg data at {LEG}")
needs_ur = pytest.mark.skipif(not UR.is_dir(), reason=f"no real UR10e data at {UR}")

ROBOT = ("--robot", "icub_right_leg_standing", "--urdf", str(LEG / "iCubGenova02.urdf"))
TORQUE = "ft.r_leg_ft_sensor.torque_identified"


@pytest.fixture(scope="module")
def blocks(tmp_path_factory: pytest.TempPathFactory) -> dict:
    model = tmp_path_factory.mktemp("leg") / "leg.json"
    # the unconstrained fit, whose failure outside its window this asserts (the leg's default is --consistent on:
    # docs/consistency.md#default, whose table tools/tests/test_consistency_default.py and
    # tests/realdata/test_realdata_consistent.py check)
    cli.dynid("fit", *ROBOT, "--data", str(DUMP), "--from", "23", "--to", "47", "--consistent", "off", "--out", str(model),
              keep_urdf_path=False)
    return cli.dynid("validate", "--model", str(model), "--data", str(DUMP), "--from", "14", "--to", "65",
                     "--blocks", "6", keep_urdf_path=False)["blocks"]


@needs_leg
def test_the_worst_block_is_outside_the_fit(blocks: dict) -> None:
    rows = blocks["blocks"]
    assert [round(b["from"], 2) for b in rows] == [14.0, 22.5, 31.0, 39.5, 48.0, 56.5]
    # in the fit: 23–47 s of the run; block 2 (22.5–31 s) and block 4 (39.5–48 s) partly
    assert [b["in_fit"] for b in rows] == [False, True, True, True, False, False]
    assert rows[1]["fit_overlap"] == pytest.approx(0.94, abs=0.01)
    assert rows[3]["fit_overlap"] == pytest.approx(0.88, abs=0.01)
    assert blocks["summary"]["blocks_in_fit"] == [1, 2, 3]
    torque = blocks["summary"]["figures"][TORQUE]
    # measured: 17.13 Nm on 14–22.5 s (CAD 0.73), 13.12 Nm on 56.5–65 s (CAD 0.81),
    # 0.133 Nm on 48–56.5 s (CAD 0.20)
    assert torque["worst_block"] == 0 and torque["worst_in_fit"] is False
    assert torque["max"] == pytest.approx(17.1, rel=0.1)
    assert rows[5]["figures"][TORQUE] == pytest.approx(13.1, rel=0.1)
    assert torque["best_block"] == 4 and torque["min"] == pytest.approx(0.133, rel=0.1)
    for k in (0, 5):
        assert rows[k]["figures"]["ft.r_leg_ft_sensor.torque_cad"] < 1.0
        assert rows[k]["figures"]["ft.r_leg_ft_sensor.torque_identified_vs_cad"] > 10
    assert rows[4]["figures"]["ft.r_leg_ft_sensor.torque_identified_vs_cad"] < 0.8
    assert torque["median"] < 0.5


@needs_ur
def test_every_block_of_the_ur10e_point_to_point_run(tmp_path: Path) -> None:
    identification = UR / "identification" / "ur-20_02_19_14harm50sec.csv"
    model = tmp_path / "plain.json"
    urdf = ("--urdf", str(convert.UR10E_URDF))
    cli.dynid("fit", "--robot", "ur10e_known_gains", *urdf, "--data", str(identification), "--out", str(model),
              keep_urdf_path=False)
    ptp = str(UR / "validation" / "ur-20_01_17-ptp_10_points.csv")
    whole = cli.dynid("validate", "--model", str(model), "--data", ptp, "--blocks", "5", keep_urdf_path=False)
    rows, overall = whole["blocks"]["blocks"], whole["blocks"]["summary"]["figures"]["relative_error.overall"]
    assert [b["in_fit"] for b in rows] == [False] * 5  # another run than the fit's
    # measured: 25.8 % on the first block (mostly rest), 4.78 % at best (block 4), median 12.8 % (32.7 % and 12.9 %
    # while the filtered q̇ at rest was rounding noise, not 0, and the Coulomb columns took its sign)
    assert overall["worst_block"] == 0 and overall["max"] == pytest.approx(0.258, rel=0.1)
    assert overall["best_block"] == 3 and overall["min"] == pytest.approx(0.0478, rel=0.1)
    assert overall["median"] == pytest.approx(0.128, rel=0.1)
    # validated on the run it was fitted on, every block is in the fit
    fitted = cli.dynid("validate", "--model", str(model), "--data", str(identification), "--blocks", "3",
                       keep_urdf_path=False)
    assert [b["fit_overlap"] for b in fitted["blocks"]["blocks"]] == [1.0, 1.0, 1.0]


PANDA = convert.REALDATA / "panda_gaz2019"
TIAGO = convert.REALDATA / "tiago_wrist_ft"


@pytest.mark.skipif(not PANDA.is_dir(), reason=f"no real Panda data at {PANDA}")
def test_every_block_of_the_panda_run(tmp_path: Path) -> None:
    """docs/robots/panda.md: fitted on the first 2/3 (t ≤ 13.9189 s), the two held-out blocks inside the fitted
    blocks' spread; the worst block is a fitted one."""
    data = PANDA / "rbt_log"  # the logger's folder of files, as panda.yaml's `files:` describes it
    model = tmp_path / "panda.json"
    cli.dynid("fit", "--robot", "panda", "--data", str(data), "--to", "13.9189", "--out", str(model))
    blocks = cli.dynid("validate", "--model", str(model), "--data", str(data), "--blocks", "6")["blocks"]
    rows, torque = blocks["blocks"], blocks["summary"]["figures"]["relative_torque_error"]
    assert [b["in_fit"] for b in rows] == [True] * 4 + [False] * 2
    # measured: 1.76 % worst (block 1, fitted), 0.94 % best (block 3), 1.41 and 1.51 % on the held-out blocks
    assert torque["worst_block"] == 0 and torque["max"] == pytest.approx(0.0176, rel=0.1)
    assert torque["min"] == pytest.approx(0.0094, rel=0.1)
    for k, measured in ((4, 0.0141), (5, 0.0151)):
        assert rows[k]["figures"]["relative_torque_error"] == pytest.approx(measured, rel=0.1)


@pytest.mark.skipif(not TIAGO.is_dir(), reason=f"no real TIAGo data at {TIAGO}")
def test_every_block_of_the_tiago_run(tmp_path: Path) -> None:
    """docs/robots/tiago_wrist.md: fitted on protocol.yaml's rows 921–6790, identified below CAD on every block."""
    data = TIAGO / "dynamic"  # PAL's four CSVs, as tiago_wrist.yaml's `files:` describes them
    model = tmp_path / "tiago.json"
    cli.dynid("fit", "--robot", "tiago_wrist", "--urdf", str(convert.TIAGO_URDF), "--data", str(data),
              "--from", "9.2106", "--to", "67.9006", "--out", str(model), keep_urdf_path=False)
    blocks = cli.dynid("validate", "--model", str(model), "--data", str(data), "--blocks", "8",
                       keep_urdf_path=False)["blocks"]
    rows, figures = blocks["blocks"], blocks["summary"]["figures"]
    assert [b["in_fit"] for b in rows] == [True] * 7 + [False]
    # measured: force 0.665 N worst (block 3), torque 0.0362 Nm worst (block 1); identified/CAD at most 0.49
    assert figures["ft.wrist_ft.force_identified"]["worst_block"] == 2
    assert figures["ft.wrist_ft.force_identified"]["max"] == pytest.approx(0.665, rel=0.1)
    assert figures["ft.wrist_ft.torque_identified"]["worst_block"] == 0
    assert figures["ft.wrist_ft.torque_identified"]["max"] == pytest.approx(0.0362, rel=0.1)
    for what in ("force", "torque"):
        assert figures[f"ft.wrist_ft.{what}_identified_vs_cad"]["max"] < 0.6
