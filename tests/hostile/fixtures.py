"""The good files the sweep spoils, made once per session through the command lines, as scripts/main makes them.

tools/tests/conftest.py's session fixtures are the default 300 s and 120 s runs and the full fit (three to four
minutes on a shared machine), more than this whole sweep may take; so this builds the same chain on short runs:
a 1 s contact run (its data.csv, dataset.npz and truth), a 10 s identification run, one fit (OLS, two blocks: a
valid model file in seconds; 4 s gave a negative motor gain, which the fit now refuses), one export, the run as a candump log through `boards`, and that log through
`rt_monitor` as an LCM log. Independent steps run side by side.
"""

from __future__ import annotations

import shutil
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from .run import ROOT, Outcome, program, run_dynid, run_program

MONITOR_CONF = ROOT / "rt_monitor" / "config" / "icub_right_arm.conf"
ROBOT_YAML = ROOT / "tools" / "dynid" / "config" / "robots" / "icub_right_arm.yaml"


@dataclass(frozen=True)
class Fixtures:
    root: Path
    run: Path  # a `dynid simulate --kind contact` directory, 1 s
    csv: Path  # its data.csv
    npz: Path  # its dataset.npz
    ident: Path  # a `dynid simulate --kind identification` directory, 4 s
    model: Path  # `dynid fit` of ident
    coef: Path  # `dynid export` of the model
    log: Path  # the contact run as a candump log (`boards --sink candump:`)
    conf: Path  # the bundled arm's rt_monitor configuration
    lcmlog: Path  # the log through `rt_monitor --replay`, published to a file:// LCM log

    def names(self) -> dict[str, str]:
        """The `{name}` of every file, for the cases' argument templates."""
        return {k: str(v) for k, v in self.__dict__.items()}

    @property
    def csv_lines(self) -> list[str]:
        return self.csv.read_text().splitlines()


def _ok(what: str, done: Outcome) -> None:
    if done.code != 0:
        raise RuntimeError(f"the sweep's fixture '{what}' failed (exit {done.code}): {done.stderr.strip()}")


def build(root: Path) -> Fixtures:
    fx = Fixtures(root, root / "run", root / "run" / "data.csv", root / "run" / "dataset.npz", root / "ident",
                  root / "model.json", root / "model.dcoef", root / "run.log", root / "monitor.conf",
                  root / "events.lcmlog")
    shutil.copy(MONITOR_CONF, fx.conf)

    def dynid(what: str, *args: str) -> None:
        _ok(what, run_dynid(list(args), root, timeout=600))

    with ThreadPoolExecutor(2) as pool:
        contact = pool.submit(dynid, "contact run", "simulate", "--kind", "contact", "--duration", "1",
                              "--seed", "3", "--out", str(fx.run))
        pool.submit(dynid, "identification run", "simulate", "--kind", "identification", "--duration", "10",
                    "--out", str(fx.ident)).result()
        fitted = pool.submit(dynid, "fit", "fit", "--data", str(fx.ident), "--estimator", "ols", "--blocks", "2",
                             "--out", str(fx.model))
        contact.result()
        _ok("candump log", run_program(program("boards"), ["--config", str(fx.conf), "--data", str(fx.run),
                                                            "--sink", f"candump:{fx.log}"], root))
        fitted.result()
    dynid("export", "export", "--model", str(fx.model), "--out", str(fx.coef))
    _ok("LCM log", run_program(program("rt_monitor"), ["--model", str(fx.coef), "--config", str(fx.conf), "--replay",
                                                        str(fx.log), "--lcm-url", f"file://{fx.lcmlog}?mode=w"], root))
    return fx
