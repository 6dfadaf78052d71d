"""Every `dynid` command: the module of dynid.cli that implements it, and its one-line help.

The entry point builds only the parser of the command it runs, so `dynid fit` does not load what `dynid spy`
needs (and the reverse); `dynid --help` lists them all from this table.
"""

from __future__ import annotations

from typing import NamedTuple


class Command(NamedTuple):
    group: str  # dynid.cli.<group> implements it (its add_commands adds the parser)
    help: str


COMMANDS: dict[str, Command] = {
    "import": Command("data", "CSV (or dataset) -> dataset file, validated against the robot configuration"),
    "structure": Command("data", "parameter layout, numerical rank and identifiable combinations"),
    "simulate": Command("data", "simulate an experiment of the arm, with known truth"),
    "excite": Command("excite", "design an excitation trajectory for the fit (Fourier series, well conditioned)"),
    "fit": Command("identify", "identify inertia, F/T offsets, friction and motor gains in one regression"),
    "fleet": Command("fleet", "runs of many robots of one kind: a model each, compared, the robot that stands out named"),
    "validate": Command("identify", "the paper's Table II on a validation experiment"),
    "detect": Command("detect", "offline T² contact detection (momentum-observer and acceleration residuals combined) against ground truth or labels"),
    "report": Command("report", "the identification report: one HTML page with figures and tables"),
    "export": Command("export", "write the real-time monitor's coefficient file (or --print one), the identified robot as a URDF (--urdf), the robot's CAN bus as a DBC (--dbc) or the monitor's configuration (--monitor-config)"),
    "play": Command("play", "play a recorded run onto the robot's CAN bus (candump log, loopback, SocketCAN) as its bus description says"),
    "gaps": Command(
        "gaps", "where model and data disagree, which missing effect explains it, and the gap after the fix"
    ),
    "spy": Command("spy", "live view of rt_monitor's LCM output: contact events, status counters, rates"),
}
