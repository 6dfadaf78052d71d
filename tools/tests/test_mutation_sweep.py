"""The mutation sweep as a test (issue 31; docs/fuzzing.md "The mutation sweep"): every 8th of the ~4000 mutations
of the monitor configuration and of a CRC-valid coefficient file, replayed through rt_monitor on 20 s of the default
contact run, is refused at load, flagged by the watchdog, or gives the unmutated replay's events. The full sweep:
`.venv/bin/python tools/benchmarks/mutation_sweep.py --append-docs`.

What stays silent is what no monitor can tell from the right value, and it is named here: a model whose friction,
gating or supply tracking is another plausible one (a frictionless joint, a motor never gated, tracking off), and a
PWM zero off by one duty on a motor whose duty stays within ±1 (docs/fuzzing.md)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SPEC = importlib.util.spec_from_file_location("mutation_sweep", ROOT / "tools" / "benchmarks" / "mutation_sweep.py")
sweep_module = importlib.util.module_from_spec(SPEC)
sys.modules["mutation_sweep"] = sweep_module  # its dataclasses look their module up
SPEC.loader.exec_module(sweep_module)

# Plausible in isolation, so nothing at load or at run time can refuse them: the known silent class.
UNDETECTABLE_FIELDS = ("joint_friction", "motor_friction", "motor_friction_on", "gate_joints", "gate_motors",
                       "min_speed", "supply_time_constant", "supply_prior", "supply_gate")


def undetectable(b: dict) -> bool:
    if b["kind"] == "coefficients":
        return b["mutation"].split(" -> ")[0] in UNDETECTABLE_FIELDS
    return "signal MC_PID_VAL" in b["mutation"] and "field 7 0.0 -> -1" in b["mutation"]  # a PWM's offset, by 1 duty


@pytest.fixture(scope="module")
def result(default_experiments: dict, exported: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    work = tmp_path_factory.mktemp("sweep")
    return sweep_module.sweep(work, exported, default_experiments["contact"], every=8, progress=False)


def test_every_mutation_is_refused_flagged_or_harmless(result: dict) -> None:
    c = result["counts"]
    print(f"mutation sweep, every 8th of {result['of']}: " + ", ".join(f"{k} {v}" for k, v in sorted(c.items())))
    assert result["base"]["events"] >= 3 and result["base"]["evaluated"] == 20_000
    assert result["mutations"] > 450 and c.get("refused", 0) > 350 and c.get("flagged", 0) > 0 and c.get("harmless", 0) > 0
    assert c.get("broken", 0) == 0, [b for b in result["silent_or_broken"] if b["class"] == "broken"]
    silent = [b for b in result["silent_or_broken"] if b["class"] == "silent"]
    assert all(undetectable(b) for b in silent), [b["mutation"] for b in silent if not undetectable(b)]


def test_the_sweep_sees_a_silent_change(default_experiments: dict, exported: Path, tmp_path: Path) -> None:
    """Not vacuous: a frictionless model changes the events and is classified silent, not harmless."""
    coef, conf, log = sweep_module.make_inputs(tmp_path, exported, default_experiments["contact"])
    base = sweep_module.replay(coef, conf, log, tmp_path, "base")
    (m,) = [m for m in sweep_module.coefficient_mutations(coef) if m.name == "joint_friction -> 0"]
    changed = tmp_path / "m.dcoef"
    changed.write_bytes(m.coef)
    r = sweep_module.replay(changed, conf, log, tmp_path, "m")
    assert sweep_module.classify(r, base) == "silent" and r.events != base.events
