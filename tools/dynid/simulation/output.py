"""The files of a simulated experiment, in one directory (`dynid simulate --out DIR`).

    dataset.npz   what the boards recorded, as a dynid dataset (the input of fit, validate, detect, gaps)
    data.csv      the same signals as a CSV of docs/design.md §4 (plus skin.side/skin.patch in the contact kind)
    truth.json    the true parameters by name (Φ of the identification model), the plant's own values, the
                  hidden effects with every parameter, the contact episodes and the realism counters
    truth.npz     the true signals sample by sample, as a dynid dataset: q, q̇, q̈ from the integrator, the
                  applied PWMs, the true F/T wrench (no offset, no noise), and extra columns for the offset
                  track, the contact's share of each F/T channel and joint torque, the supply factors, the
                  stuck friction coordinates and the reference

DIR is new, empty, or the output of an earlier `dynid simulate`, whose four files are replaced (as `fit --out`
replaces a model file; anything else in it is left as it is). A directory holding anything else is refused
(`check_output_dir`): a recorded run's `data.csv` would be overwritten, and a YARP or logger folder given a
`dataset.npz` would read as the simulated run from then on. Each file is written atomically, `dataset.npz` last (a
run without it is not a run); within a `dynid` command all are put in place together at its end, and a command that
fails or is interrupted leaves DIR as it was (dynid.outputs). Any dynid command that takes DATA accepts the
directory and reads its dataset.npz.
"""

from __future__ import annotations

import contextlib
import json
from pathlib import Path
from typing import BinaryIO

from ..errors import DataError
from ..io.csv_format import write_csv
from ..io.dataset import SIMULATION_DATASET, TRUTH_FORMAT, atomic_write
from ..outputs import output_dir
from .experiment import Simulation

FILES = {"dataset": SIMULATION_DATASET, "csv": "data.csv", "truth": "truth.json", "truth_signals": "truth.npz"}


def is_simulation_dir(out: Path) -> bool:
    """Whether `out` holds an earlier `dynid simulate` output: its truth.json says so (a dataset.npz alone does not:
    `import --out DIR/dataset.npz` of a simulated run would make any folder look like one)."""
    with contextlib.suppress(OSError, ValueError, KeyError, TypeError, AttributeError):
        return json.loads((out / FILES["truth"]).read_text(encoding="utf-8")).get("format") == TRUTH_FORMAT
    return False


def check_output_dir(out_dir: str | Path) -> None:
    """Refuse a DIR that `write_simulation` must not write to: a file, or a directory that holds anything but an
    earlier simulation's output."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise DataError(f"cannot write to '{out}': it exists and is not a directory")
    if not out.is_dir():
        return
    try:
        held = sorted(p.name for p in out.iterdir())
    except OSError as e:
        raise DataError(f"cannot write to '{out}': {e.strerror or e}") from None
    if held and not is_simulation_dir(out):
        shown = ", ".join(held[:3]) + (f" and {len(held) - 3} more" if len(held) > 3 else "")
        raise DataError(f"cannot write to '{out}': it holds {shown}, not an earlier `dynid simulate` run, which the "
                        f"run's files ({', '.join(FILES.values())}) would replace or take over; give a new or empty "
                        "directory")


def write_simulation(sim: Simulation, out_dir: str | Path) -> dict[str, str]:
    out = Path(out_dir)
    check_output_dir(out)
    output_dir(out)  # removed again, with its parents made, if the command fails (dynid.outputs)
    paths = {key: out / name for key, name in FILES.items()}
    sim.truth_signals.save(paths["truth_signals"])
    text = json.dumps(sim.truth, indent=1, allow_nan=False).encode() + b"\n"

    def write(f: BinaryIO) -> None:
        f.write(text)

    atomic_write(paths["truth"], write)
    write_csv(sim.dataset, paths["csv"])
    sim.dataset.save(paths["dataset"])  # last: its presence means the run completed
    return {key: str(p) for key, p in paths.items()}
