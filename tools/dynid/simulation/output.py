"""The files of a simulated experiment, in one directory (`dynid simulate --out DIR`).

    dataset.npz   what the boards recorded, as a dynid dataset (the input of fit, validate, detect, gaps)
    data.csv      the same signals as a CSV of docs/design.md §4 (plus skin.side/skin.patch in the contact kind)
    truth.json    the true parameters by name (Φ of the identification model), the plant's own values, the
                  hidden effects with every parameter, the contact episodes and the realism counters
    truth.npz     the true signals sample by sample, as a dynid dataset: q, q̇, q̈ from the integrator, the
                  applied PWMs, the true F/T wrench (no offset, no noise), and extra columns for the offset
                  track, the contact's share of each F/T channel and joint torque, the supply factors, the
                  stuck friction coordinates and the reference

Each file is written atomically; the directory itself may hold the files of an earlier run until each is
replaced. Any dynid command that takes DATA accepts the directory and reads its dataset.npz.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import BinaryIO

from ..errors import DataError
from ..io.csv_format import write_csv
from ..io.dataset import SIMULATION_DATASET, atomic_write
from .experiment import Simulation

FILES = {"dataset": SIMULATION_DATASET, "csv": "data.csv", "truth": "truth.json", "truth_signals": "truth.npz"}


def write_simulation(sim: Simulation, out_dir: str | Path) -> dict[str, str]:
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise DataError(f"cannot write to '{out}': it exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise DataError(f"cannot create the output directory '{out}': {e.strerror or e}") from None
    paths = {key: out / name for key, name in FILES.items()}
    sim.truth_signals.save(paths["truth_signals"])
    text = json.dumps(sim.truth, indent=1, allow_nan=False).encode() + b"\n"

    def write(f: BinaryIO) -> None:
        f.write(text)

    atomic_write(paths["truth"], write)
    write_csv(sim.dataset, paths["csv"])
    sim.dataset.save(paths["dataset"])  # last: its presence means the run completed
    return {key: str(p) for key, p in paths.items()}
