"""`dynid fit --consistent`'s default, per robot (docs/consistency.md#default): the configuration's `fit.consistent`,
off where it gives none, decided for each bundled robot by held-out blocks and runs
(tools/benchmarks/consistency_default.py; tests/realdata/test_realdata_consistent.py asserts the leg's row). Here:
each bundled configuration says its decision, the field is validated, and the command line and the API resolve
it, an explicit --consistent winning. An 8 s simulated run fitted with OLS on 3 blocks keeps it to seconds."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
import yaml
from conftest import dynid as forked_dynid

import dynid
from dynid.config.robot_config import CONSISTENT_MODES, bundled_configs, load_config, resolve_config_path
from dynid.errors import ConfigError
from dynid.identify.fit import PSEUDO_INERTIA_ONLY

# The decision of docs/consistency.md#default: on where the consistent fit generalises measurably better
DECIDED = {"icub_right_arm": "off", "icub_right_leg_standing": "on", "panda": "off", "tiago_wrist": "off",
           "ur10e": "off", "ur10e_known_gains": "off"}
ARM = resolve_config_path("icub_right_arm")
SHORT = ("--estimator", "ols", "--blocks", "3")  # IV does not settle on 8 s (test_consistent_fit's poor run)


def run(*args: str) -> subprocess.CompletedProcess:
    return forked_dynid(*args)  # forked from the preloaded server (conftest)


def arm_with(tmp_path: Path, fit_section: str) -> Path:
    """The bundled arm with its `fit:` section replaced."""
    text = ARM.read_text()
    start = text.index("\nfit:\n")
    end = text.index("\nnoise:\n")
    path = tmp_path / "arm.yaml"
    path.write_text(text[:start] + "\n" + fit_section + "\n" + text[end:])
    return path


@pytest.fixture(scope="module")
def short_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("short") / "run"
    done = run("simulate", "--kind", "identification", "--duration", "8", "--seed", "3", "--out", str(out))
    assert done.returncode == 0, done.stderr
    return out


def test_every_bundled_robot_states_its_decision() -> None:
    assert sorted(bundled_configs()) == sorted(DECIDED)
    assert CONSISTENT_MODES == ("off", "on", PSEUDO_INERTIA_ONLY)
    for name, mode in DECIDED.items():
        raw = yaml.safe_load(resolve_config_path(name).read_text())
        assert raw["fit"]["consistent"] == mode, name  # written as a quoted string, never YAML 1.1's boolean
        assert load_config(name, urdf=ARM).fit_consistent == mode, name  # any file stands in for a supplied URDF


def test_the_field_is_validated(tmp_path: Path) -> None:
    assert load_config(arm_with(tmp_path, "fit: {consistent: on}")).fit_consistent == "on"  # YAML 1.1: True
    assert load_config(arm_with(tmp_path, "fit: {consistent: off}")).fit_consistent == "off"
    assert load_config(arm_with(tmp_path, "fit: {consistent: pseudo-inertia}")).fit_consistent == PSEUDO_INERTIA_ONLY
    assert load_config(arm_with(tmp_path, "fit: {}")).fit_consistent == "off"
    with pytest.raises(ConfigError, match=r"field 'fit.consistent' must be one of off, on, pseudo-inertia, got 'psd'"):
        load_config(arm_with(tmp_path, "fit: {consistent: psd}"))
    with pytest.raises(ConfigError, match=r"field 'fit.consistant' is not a known setting \(did you mean 'consistent'"):
        load_config(arm_with(tmp_path, "fit: {consistant: on}"))
    done = run("fit", "--robot", str(arm_with(tmp_path, "fit: {consistent: 3}")), "--data", str(tmp_path / "none"),
               "--out", str(tmp_path / "m.json"))
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "fit.consistent" in done.stderr, done.stderr
    assert not (tmp_path / "m.json").exists()


def test_the_command_line_takes_the_robots_default_and_the_flag_wins(tmp_path: Path, short_run: Path) -> None:
    robot = str(arm_with(tmp_path, 'fit: {consistent: "on"}'))
    default, off = tmp_path / "default.json", tmp_path / "off.json"
    done = run("fit", "--robot", robot, "--data", str(short_run), *SHORT, "--out", str(default))
    assert done.returncode == 0, done.stderr
    assert "--consistent on: icub_right_arm's default (its configuration's fit.consistent" in done.stdout
    record = json.loads(default.read_text())
    assert record["settings"]["consistent"] is True and record["consistent"]["status"] == "solved"
    done = run("fit", "--robot", robot, "--data", str(short_run), *SHORT, "--consistent", "off", "--out", str(off))
    assert done.returncode == 0, done.stderr
    assert "default" not in done.stdout.splitlines()[0]
    record = json.loads(off.read_text())
    assert record["settings"]["consistent"] is False and record["consistent"] is None
    # --cad-pull cv needs a consistent fit: the robot's default gives it, --consistent off refuses it
    done = run("fit", "--robot", robot, "--data", str(short_run), *SHORT, "--consistent", "off", "--cad-pull", "cv",
               "--out", str(off))
    assert done.returncode == 2 and "--cad-pull cv weighs the CAD prior" in done.stderr


def test_the_api_takes_the_robots_default(tmp_path: Path, short_run: Path) -> None:
    robot = arm_with(tmp_path, 'fit: {consistent: "on"}')
    model = dynid.DynamicsModel(robot=robot, estimator="ols", blocks=3)
    assert model.get_params()["consistent"] is None
    model.fit(str(short_run))
    assert model.model_.settings.consistent is True and model.model_.consistent is not None
    # the bundled arm's default is off
    assert load_config("icub_right_arm").fit_consistent == "off"
    with pytest.raises(dynid.InputError, match="cad_pull weighs the CAD prior"):
        dynid.DynamicsModel(consistent=None, cad_pull=True).fit(str(short_run))
