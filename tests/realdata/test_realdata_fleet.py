"""A fleet of UR10e "robots" (the four unloaded identification runs and a copy of one with every current read 1.3 times
too large): the scaled one is named once, as a scale, where it was named for friction on all six joints (a
walkthrough). docs/validation.md#a-fleet."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from . import cli, convert

UR = convert.REALDATA / "ur10e_mamedov"
RUNS = ("ur-20_02_05-20sec_8harm.csv", "ur-20_02_10-30sec_12harm.csv", "ur-20_02_12-50sec_12harm.csv",
        "ur-20_02_19_14harm50sec.csv")
CURRENTS = slice(13, 19)  # the logs' current columns (the configuration's `columns`)


@pytest.mark.skipif(not UR.is_dir(), reason=f"no UR10e data at {UR}")
def test_ur10e_currents_read_in_another_scale_are_a_scale(tmp_path: Path) -> None:
    for i, name in enumerate(RUNS):
        (tmp_path / "runs" / f"ur{i}").mkdir(parents=True)
        (tmp_path / "runs" / f"ur{i}" / "run.csv").write_bytes((UR / "identification" / name).read_bytes())
    log = np.loadtxt(UR / "identification" / RUNS[3], delimiter=",")
    log[:, CURRENTS] *= 1.3
    (tmp_path / "runs" / "ur4").mkdir()
    np.savetxt(tmp_path / "runs" / "ur4" / "run.csv", log, delimiter=",", fmt="%.6f")
    result = cli.dynid("fleet", "--robot", "ur10e_known_gains", "--urdf", str(UR / "ur10e.urdf"), "--data",
                       str(tmp_path / "runs"), "--out", str(tmp_path / "out"))
    named = {o["robot"]: o["groups"] for o in result["outliers"]}
    assert list(named) == ["ur4"] and [g["group"] for g in named["ur4"]] == ["scale"], named
    assert named["ur4"][0]["ratio_to_median"][0] == pytest.approx(1.3, rel=0.03)
