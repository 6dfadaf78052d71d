"""The simulated plant's figures in the README: consistency with the model, and what each hidden effect breaks.

    .venv/bin/python tools/benchmarks/simulation_report.py

Noise-free runs of 20 s (consistency) and 8 s (effects, each against the same run without it); residuals are
A Φ − b with the true Φ on the true q̇, q̈ (dynid.simulation.consistency), max |r| per group of rows, samples
whose friction sticks excluded. tools/tests/test_simulation_physics.py asserts bounds on the same quantities.
"""

from __future__ import annotations

import numpy as np

from dynid.config.robot_config import load_config
from dynid.robot.model import RobotModel
from dynid.robot.parameters import WRENCH_FIELDS
from dynid.simulation import CATALOG, SimulationSettings, parse_effect, simulate
from dynid.simulation.consistency import model_residuals, worst

ICUB = load_config("icub_right_arm")
MODEL = RobotModel(ICUB)
GROUPS = {
    "F/T (N, Nm)": [f"ft.r_arm_ft.{c}" for c in WRENCH_FIELDS],
    "shoulder motors (Nm)": ["motor.m0", "motor.m1", "motor.m2"],
    "elbow (Nm)": ["joint.r_elbow"],
}


def row(label: str, r: dict[str, np.ndarray]) -> str:
    return f"| {label} | " + " | ".join(f"{worst(r, rows):.1e}" for rows in GROUPS.values()) + " |"


def main() -> None:
    print("| noise-free run | " + " | ".join(GROUPS) + " |\n|---|---|---|---|")
    for kind in ("identification", "contact"):
        sim = simulate(ICUB, SimulationSettings(kind=kind, duration=20.0, noise=False))
        stuck = np.mean([v > 0 for k, v in sim.truth_signals.extra.items() if k.startswith("stuck.")], axis=1).mean()
        print(row(f"{kind}, contact share removed (stuck coordinate-samples {100 * stuck:.0f} %)",
                  model_residuals(MODEL, sim, with_contact=True)))
    bodies = tuple(b.name for b in MODEL.bodies)
    settings = dict(duration=8.0, noise=False)
    print(row("identification 8 s, no effect (the baseline)", model_residuals(MODEL, simulate(ICUB, SimulationSettings(**settings)))))
    for name in CATALOG:
        effect = parse_effect(name, ICUB, bodies)
        sim = simulate(ICUB, SimulationSettings(effects=(effect,), **settings))
        target = f" on {effect.target}" if effect.target else ""
        print(row(f"`{name}`{target} (defaults)", model_residuals(MODEL, sim)))


if __name__ == "__main__":
    main()
