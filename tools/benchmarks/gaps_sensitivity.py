"""Benchmark: the smallest size of each hidden effect that `dynid gaps` names reliably (README "Model gaps").

For each effect of the library, up a ladder of magnitudes (default target: the elbow, motor m3, the F/T sensor),
over seeds k = 0..S-1 (experiment seed and true arm both k): simulate a short identification run with the
effect hidden, run the gap workflow in-process, and count a success when the effect is named, at the right place,
with confidence. A magnitude is reliable with ≥ `need` successes of S; a rung stops early once that is out of
reach. The size is also given relative to the noise: the excess of the held-out RMS over the same seed's control
run, √(before² − control²), on the effect's most affected channel, in units of that channel's noise σ.

Bounded: short runs (30 s), early stops, and a wall-clock budget after which the remaining effects are reported as
not measured. Results are written atomically to --json after every effect.

    .venv/bin/python tools/benchmarks/gaps_sensitivity.py [--seeds 5] [--need 4] [--duration 30]
        [--budget-min 40] [--only cogging,spring] [--ladder-scale 0.25] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from dynid.config.robot_config import load_config
from dynid.gaps.workflow import run
from dynid.robot.model import RobotModel
from dynid.simulation import SimulationSettings, parse_effect, simulate

# effect -> (spec template with {m}, the ladder of m, the unit of m, the parameter the ladder scales)
LADDERS: dict[str, tuple[str, tuple[float, ...], str]] = {
    "stribeck": ("stribeck:excess={m},velocity=0.1", (2.0, 4.0, 8.0), "× Coulomb (velocity 0.1 rad/s)"),
    "spring": ("spring:stiffness={m}", (0.1, 0.2, 0.4), "Nm/rad"),
    "cogging": ("cogging:amplitude={m}", (0.04, 0.08, 0.16), "Nm (period 5°)"),
    "pwm_deadzone": ("pwm_deadzone:width={m}", (0.01, 0.02, 0.04), "duty"),
    "ft_drift": ("ft_drift:force={m},torque={m2}", (0.5, 1.0, 2.0), "N (torque m/20 Nm, τ 60 s)"),
    "armature": ("armature:inertia={m}", (0.02, 0.04, 0.08), "kg m²"),
    "load_friction": ("load_friction:coefficient={m}", (0.1, 0.2, 0.4), "Nm/Nm"),
    "pwm_delay": ("pwm_delay:ms={m}", (50.0, 100.0, 200.0), "ms"),
    "base_tilt": ("base_tilt:degrees={m}", (1.0, 2.0, 4.0), "deg (about x)"),
    "ft_gain": ("ft_gain:gain={m},crosstalk={m2}", (0.015, 0.03, 0.06), "gain std (cross-talk m/3)"),
}
SECOND = {"ft_drift": 1 / 20, "ft_gain": 1 / 3}  # the second parameter as a share of m


def _where(effect) -> str:
    kind = effect.spec.target
    if effect.kind == "base_tilt":
        return "base"
    if effect.kind == "pwm_delay":
        return "pwm stream"
    return f"{kind} {effect.target}"


def _trial(config, model: RobotModel, spec: str | None, seed: int, duration: float) -> tuple[dict, str | None]:
    bodies = tuple(b.name for b in model.bodies)
    effects = (parse_effect(spec, config, bodies),) if spec else ()
    sim = simulate(config, SimulationSettings(duration=duration, seed=seed, robot_seed=seed, effects=effects))
    result = run(model, sim.dataset, log=lambda *a: None)
    return result, (_where(effects[0]) if effects else None)


def _excess(result: dict, control: dict) -> float:
    """√(before² − control²) on the most affected channel, in noise units."""
    best = 0.0
    for g, c in zip(result["gap"], control["gap"]):
        best = max(best, float(np.sqrt(max(g["before_over_noise"] ** 2 - c["before_over_noise"] ** 2, 0.0))))
    return best


def _write(path: Path | None, data: dict) -> None:
    if path is None:
        return
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    with os.fdopen(fd, "w") as f:
        json.dump(data, f, indent=1)
    os.replace(tmp, path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--need", type=int, default=4)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--budget-min", type=float, default=40.0)
    ap.add_argument("--only", default="", help="comma-separated effects (default: all)")
    ap.add_argument("--ladder-scale", type=float, default=1.0, help="multiply every rung (to bracket lower)")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    started = time.perf_counter()
    config = load_config("icub_right_arm")
    model = RobotModel(config)
    controls = {}
    for seed in range(args.seeds):
        controls[seed] = _trial(config, model, None, seed, args.duration)[0]
    false_named = sum(bool([e for e in c["effects"] if e["confident"]]) for c in controls.values())
    out: dict = {"seeds": args.seeds, "need": args.need, "duration_s": args.duration,
                 "control_runs_naming_something": false_named, "effects": {}}
    print(f"control: {false_named} of {args.seeds} seeds name something")
    chosen = [e for e in LADDERS if not args.only or e in args.only.split(",")]
    for name in chosen:
        template, ladder, unit = LADDERS[name]
        row: dict = {"unit": unit, "rungs": [], "smallest_reliable": None}
        for m in (float(x) * args.ladder_scale for x in ladder):
            if time.perf_counter() - started > 60 * args.budget_min:
                row["stopped"] = "budget"
                break
            spec = template.format(m=m, m2=m * SECOND.get(name, 0.0))
            hits, misses, excess, named_as = 0, 0, [], []
            for seed in range(args.seeds):
                result, where = _trial(config, model, spec, seed, args.duration)
                ok = any(e["name"] == name and e["where"] == where and e["confident"] for e in result["effects"])
                hits, misses = hits + ok, misses + (not ok)
                excess.append(_excess(result, controls[seed]))
                named_as.append([f"{e['name']} on {e['where']}" for e in result["effects"]])
                if hits >= args.need or misses > args.seeds - args.need:
                    break
            rung = {"magnitude": m, "spec": spec, "hits": hits, "tried": hits + misses,
                    "excess_over_noise": float(np.median(excess)), "named": named_as}
            row["rungs"].append(rung)
            print(f"{name:14s} {m:8g} {unit:28s} {hits}/{hits + misses} named, excess {rung['excess_over_noise']:.2f} σ")
            if hits >= args.need:
                row["smallest_reliable"] = rung
                break
        out["effects"][name] = row
        out["seconds"] = time.perf_counter() - started
        _write(args.json, out)
    print("\n| effect | smallest size named reliably | its excess residual (× noise) | named / tried |")
    print("|---|---|---|---|")
    for name, row in out["effects"].items():
        r = row["smallest_reliable"]
        if r is None:
            top = row["rungs"][-1] if row["rungs"] else None
            print(f"| {name} | > {top['magnitude']:g} {row['unit']} (largest tried) | {top['excess_over_noise']:.2f} | "
                  f"{top['hits']}/{top['tried']} |" if top else f"| {name} | not measured (budget) | | |")
        else:
            print(f"| {name} | {r['magnitude']:g} {row['unit']} | {r['excess_over_noise']:.2f} | {r['hits']}/{r['tried']} |")
    print(f"({out.get('seconds', 0):.0f} s)")


if __name__ == "__main__":
    main()
