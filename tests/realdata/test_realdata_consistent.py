"""Physically consistent estimation on the real robots (docs/consistency.md): the iCub leg standing on one foot and
the UR10e. With `--consistent on` no body is implausible; its validation error against the unconstrained fit's:
Table II per sensor for the leg, the K-weighted relative current error on `ptp_10_points` (samples 700–4200) for the
UR10e. Skipped, with the reason, where the data are absent."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from . import cli, convert

LEG = convert.REALDATA / "icub_leg_insitu"
DUMP = LEG / "dumperLeftLegNoIMU"
UR = convert.REALDATA / "ur10e_mamedov"
SENSORS = ("r_leg_ft_sensor", "r_foot_ft_sensor")


def dynid(*args: str) -> dict:
    return cli.dynid(*args, keep_urdf_path=False)


@pytest.fixture(scope="module")
def leg(tmp_path_factory: pytest.TempPathFactory) -> dict:
    if not DUMP.is_dir():
        pytest.skip(f"no real iCub leg data at {LEG}")
    out = {}
    for mode in ("off", "on", "pseudo-inertia"):
        path = tmp_path_factory.mktemp("leg") / f"{mode}.json"
        # "on" is the leg's default (its configuration's fit.consistent): fitted without the flag
        flag = () if mode == "on" else ("--consistent", mode)
        fit = dynid("fit", "--robot", "icub_right_leg_standing", "--urdf", str(LEG / "iCubGenova02.urdf"), "--data",
                    str(DUMP), "--from", "23", "--to", "47", *flag, "--out", str(path))
        val = dynid("validate", "--model", str(path), "--data", str(DUMP), "--from", "47", "--to", "58.5")
        out[mode] = (fit, val["table_ii_sensors"], path)
    return out


def test_the_legs_default_is_the_consistent_fit(leg: dict) -> None:
    assert leg["on"][0]["consistent"]["status"] == "solved"
    assert leg["on"][0]["consistent"]["sphere"] is True
    assert leg["off"][0]["consistent"] is None


def test_leg_consistent_generalises_better_on_the_held_out_blocks(leg: dict) -> None:
    """docs/consistency.md#default, the leg's first fold (tools/benchmarks/consistency_default.py): fitted on 23-47 s,
    validated on the three blocks of 14-65 s that share no sample with the fit. The leg sensor's torque: the
    consistent fit's worst block is a sixth of the unconstrained fit's; no channel's worst or median block is worse
    by more than 1 %."""
    figures = {}
    for mode in ("off", "on"):
        blocks = dynid("validate", "--model", str(leg[mode][2]), "--data", str(DUMP), "--from", "14", "--to", "65",
                       "--blocks", "6")["blocks"]["blocks"]
        held = [b for b in blocks if b["fit_overlap"] == 0]
        assert [round(b["from"], 1) for b in held] == [14.0, 48.0, 56.5]
        figures[mode] = {n: np.array([b["figures"][n] for b in held]) for n in held[0]["figures"]}
    torque = "ft.r_leg_ft_sensor.torque_identified"
    # measured: worst 17.13 Nm off (14-22.5 s), 2.73 Nm on; 56.5-65 s: 13.12 against 2.50 Nm
    assert figures["off"][torque].max() == pytest.approx(17.1, rel=0.1)
    assert figures["on"][torque].max() == pytest.approx(2.73, rel=0.1)
    assert figures["on"][torque][[0, 2]] == pytest.approx([2.73, 2.50], rel=0.1)
    for sensor in SENSORS:
        for what in ("force", "torque"):
            name = f"ft.{sensor}.{what}_identified"
            off, on = figures["off"][name], figures["on"][name]
            assert on.max() <= 1.01 * off.max() and np.median(on) <= 1.01 * np.median(off), (name, off, on)


def test_leg_consistent_has_no_implausible_body(leg: dict) -> None:
    assert leg["off"][0]["plausibility"], "the unconstrained leg used to be implausible (docs/robots/icub_leg.md)"
    fit = leg["on"][0]
    assert fit["consistent"]["status"] == "solved"
    assert fit["plausibility"] == [], [w["text"] for w in fit["plausibility"]]


def error(tables: dict, sensor: str, what: str) -> float:
    return tables[sensor]["identified"][what]["mean"]


@pytest.mark.parametrize("sensor,what", [("r_leg_ft_sensor", "force"), ("r_foot_ft_sensor", "force"),
                                         ("r_foot_ft_sensor", "torque")])
def test_leg_table_ii_at_least_as_good(leg: dict, sensor: str, what: str) -> None:
    off, on = error(leg["off"][1], sensor, what), error(leg["on"][1], sensor, what)
    print(f"{sensor} {what}: unconstrained {off:.4g}, consistent {on:.4g}")
    assert on <= off * 1.001, (sensor, what, off, on)


@pytest.mark.xfail(strict=True, reason="measured: the consistent leg's r_leg_ft_sensor torque error is 0.158 Nm "
                   "against the unconstrained 0.141 Nm (+12 %), and the same with J ⪰ 0 alone (the test below): the "
                   "unphysical bodies were fitting something no body can (docs/consistency.md)")
def test_leg_table_ii_torque_of_the_leg_sensor_at_least_as_good(leg: dict) -> None:
    off, on = error(leg["off"][1], "r_leg_ft_sensor", "torque"), error(leg["on"][1], "r_leg_ft_sensor", "torque")
    assert on <= off * 1.001, (off, on)


def test_leg_no_physical_leg_reaches_the_unconstrained_torque_of_the_leg_sensor(leg: dict) -> None:
    """Why the test above fails: with the sphere dropped (every J ⪰ 0, nothing more: the weakest constraint any mass
    distribution meets) the leg sensor's torque error is that of the full consistent fit, not the unconstrained one's.
    No physical set of the six bodies' parameters fits these data as the unphysical one does."""
    off, on = error(leg["off"][1], "r_leg_ft_sensor", "torque"), error(leg["on"][1], "r_leg_ft_sensor", "torque")
    psd = error(leg["pseudo-inertia"][1], "r_leg_ft_sensor", "torque")
    print(f"r_leg_ft_sensor torque: unconstrained {off:.4g}, consistent {on:.4g}, pseudo-inertia only {psd:.4g}")
    assert leg["pseudo-inertia"][0]["consistent"]["sphere"] is False
    assert psd > 1.1 * off  # measured 0.158 against 0.141 Nm
    assert psd == pytest.approx(on, rel=0.02)


def test_ur10e_consistent_is_physical_and_as_good_on_ptp(tmp_path: Path) -> None:
    if not UR.is_dir():
        pytest.skip(f"no real UR10e data at {UR}")
    robot = ("--robot", "ur10e_known_gains", "--urdf", str(UR / "ur10e.urdf"))
    errors, fits = {}, {}
    for mode in ("off", "on"):
        path = tmp_path / f"{mode}.json"
        fits[mode] = dynid("fit", *robot, "--data", str(UR / "identification/ur-20_02_19_14harm50sec.csv"),
                           "--consistent", mode, "--out", str(path))
        val = dynid("validate", "--model", str(path), "--data", str(UR / "validation/ur-20_01_17-ptp_10_points.csv"),
                    "--from", "1149.041", "--to", "1186.451")  # samples 700-4200 of the file
        errors[mode] = val["relative_error"]["overall"]
    print(f"ptp relative error: unconstrained {100 * errors['off']:.3f} %, consistent {100 * errors['on']:.3f} %")
    assert fits["off"]["plausibility"], "the unconstrained UR10e used to have implausible bodies"
    assert fits["on"]["plausibility"] == []
    # at least as good to the figure's printed precision (0.01 percentage point)
    assert errors["on"] <= errors["off"] + 1e-4
