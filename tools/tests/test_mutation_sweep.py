"""The mutation sweep as a test (issue 31; docs/fuzzing.md "The mutation sweep"): every 8th of the ~4000 mutations
of the monitor configuration and of a CRC-valid coefficient file, replayed through rt_monitor on 20 s of the default
contact run, is refused at load, flagged by the watchdog, or gives the unmutated replay's events. The full sweep:
`.venv/bin/python tools/benchmarks/mutation_sweep.py --append-docs`.

Nothing may stay silent. The coefficient file's known answers (format version 7, dynid.export.known_answers) refuse
what used to: a model whose friction, gating, supply tracking, static-friction band or side threshold is another
plausible one, which nothing else at the monitor could tell from the right value (docs/fuzzing.md)."""

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

# The sweep of 8092ff7 (before the known answers) found these silent: each changed the events, exit 0, no word.
FORMERLY_SILENT = ("joint_friction -> 0", "joint_friction -> tiny", "joint_friction -> negative", "gate_joints -> 0",
                   "gate_motors -> 0", "min_speed -> 0", "min_speed -> tiny", "supply_time_constant -> 0",
                   "supply_prior -> tiny", "supply_prior -> huge", "supply_gate -> 0", "residual -> 0",
                   "joint_band -> 0", "joint_band -> tiny", "motor_band -> 0", "motor_band -> tiny",
                   "observer_ft_threshold -> tiny", "observer_ft_threshold -> huge")


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
    silent = [b["mutation"] for b in result["silent_or_broken"] if b["class"] == "silent"]
    assert not silent, silent


def test_the_classifier_sees_a_silent_change() -> None:
    """Not vacuous: a replay that exits 0 without a word but with other events, or fewer samples, is silent."""
    base = sweep_module.Replay(0, "", ((1, 100, (1,)), (2, 900, (0,))), 20_000, 0)
    more = sweep_module.Replay(0, "", base.events + ((1, 1500, (-1,)),), 20_000, 0)
    fewer = sweep_module.Replay(0, "", base.events, 19_000, 0)
    assert sweep_module.classify(more, base) == sweep_module.classify(fewer, base) == "silent"
    assert sweep_module.classify(base, base) == "harmless"
    assert sweep_module.classify(sweep_module.Replay(7, "", (), 20_000, 1), base) == "flagged"


def test_what_was_silent_is_refused_by_the_known_answers(default_experiments: dict, exported: Path,
                                                          tmp_path: Path) -> None:
    """Each mutation the sweep found silent before the known answers is now refused at load, in one line that says
    the core does not reproduce the file (or, the residual switched, that the answers do not fit the detector)."""
    coef, conf, log = sweep_module.make_inputs(tmp_path, exported, default_experiments["contact"])
    base = sweep_module.replay(coef, conf, log, tmp_path, "base")
    mutations = {m.name: m for m in sweep_module.coefficient_mutations(coef)}
    for name in FORMERLY_SILENT:
        changed = tmp_path / "m.dcoef"
        changed.write_bytes(mutations[name].coef)
        r = sweep_module.replay(changed, conf, log, tmp_path, "m")
        assert sweep_module.classify(r, base) == "refused", (name, r.code, r.stderr)
        assert r.code == 22 and "does not reproduce the file's known answers" in r.stderr or \
            r.code == 18 and "known answers of" in r.stderr, (name, r.code, r.stderr)
