"""`dynid fit` on real robots, through the command line: the Panda from joint torques, the TIAGo's hand from a
real, untared wrist F/T sensor. The figures are in the README ("Checked against")."""

from __future__ import annotations

from pathlib import Path

import pytest

from . import cli, convert

HERE = Path(__file__).parent
pytestmark = pytest.mark.skipif(not convert.REALDATA.is_dir(), reason=f"no real data at {convert.REALDATA}")


dynid = cli.dynid


PANDA = convert.REALDATA / "panda_gaz2019" / "rbt_log"  # the loggers' folders, read through the configurations'
TIAGO = convert.REALDATA / "tiago_wrist_ft" / "dynamic"  # `files:` fields as a user gives them to every command


def test_panda_fit_on_two_thirds_predicts_the_last_third(tmp_path: Path) -> None:
    """Gaz et al. 2019 report a 1.41 % relative torque error for their fitted model (on the fitted data); dynid's
    fit of the first 2/3 predicts the held-out last 1/3 with 1.47 % (1.18 % on the fitted 2/3)."""
    train, test = f"{PANDA}@:13.9189", f"{PANDA}@13.92:"  # samples 0-13695 and 13696-20543: 2/3 and 1/3
    model = tmp_path / "panda.json"
    fit = dynid("fit", "--robot", "panda", "--data", train, "--out", str(model))
    assert fit["samples"] == 13696
    assert fit["rank"] == 71
    held_out = dynid("validate", "--model", str(model), "--data", test)
    fitted = dynid("validate", "--model", str(model), "--data", train)
    print(f"Panda: relative torque error {100 * held_out['relative_torque_error']:.2f} % on the held-out last 1/3, "
          f"{100 * fitted['relative_torque_error']:.2f} % on the fitted 2/3 (Gaz et al. 2019: 1.41 %)")
    assert held_out["relative_torque_error"] < 0.016  # measured 1.47 %
    # The held-out third is contact-free. Its positions stall for a few samples at a time: the observer takes the
    # log's recorded dq, and neither alarms often nor estimates external torques the joints never carried.
    detected = dynid("detect", "--model", str(model), "--data", test, "--residual", "momentum")
    momentum = detected["variants"]["momentum"]
    peak = max(abs(v) for e in detected["events"] for v in e["tau_ext_nm"].values())
    print(f"Panda held-out third: momentum FPR {100 * momentum['fpr']:.2f} %, largest event torque {peak:.1f} Nm")
    assert momentum["fpr"] <= 0.02  # measured 1.07 % (1.21 % when the split was two CSV files; 1.91 % with q̇ from q)
    assert peak < 15.0  # measured 8.5 Nm (80 Nm with q̇ estimated from q)


def test_tiago_hand_mass_com_and_offsets_and_what_the_run_cannot_identify(tmp_path: Path) -> None:
    """The authors' static fit gives 0.79 kg for the hand, the URDF 1.032 kg. The slow motion determines the mass,
    the first moment along the sensor's axis and the six offsets (tx and ty near zero, known to a few mNm: determined
    against their channels' readings); the rest must be named, not printed."""
    train = f"{TIAGO}@9.2106:67.9006"  # protocol.yaml's rows 921-6790
    fit = dynid("fit", "--robot", "tiago_wrist", "--urdf", str(convert.TIAGO_URDF), "--data", train, "--out",
                str(tmp_path / "tiago.json"))
    assert fit["samples"] == 6790 - 921 + 1
    determined = fit["determined"]
    mass = determined["wrist_ft_link.m"]
    print(f"TIAGo: hand mass {mass['value']:.3f} ± {mass['standard_error']:.3f} kg (authors 0.79, URDF 1.032)")
    assert abs(mass["value"] - 0.79) < 0.03 and mass["standard_error"] < 0.03  # measured 0.795 ± 0.013 kg
    assert {"wrist_ft_link.mcz", *(f"ft.wrist_ft.offset.{c}" for c in ("fx", "fy", "fz", "tx", "ty", "tz"))} <= set(determined)
    assert abs(determined["ft.wrist_ft.offset.ty"]["value"]) < 0.01  # a value near 0: its own 10 % would never hold
    # Rotational inertia needs angular accelerations this run does not have.
    inertia = {f"wrist_ft_link.I{a}" for a in ("xx", "xy", "yy", "xz", "yz", "zz")}
    assert inertia <= set(fit["undetermined"]) and not inertia & set(determined)
