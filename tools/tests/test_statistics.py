"""The fit's statistics from signals computed a chunk at a time equal those of signals computed at once."""

from __future__ import annotations

import numpy as np

from dynid.config.robot_config import load_config
from dynid.identify.fit import FitSettings, SignalSource, instrument_signals
from dynid.identify.statistics import InMemory, accumulate
from dynid.robot.model import RobotModel
from dynid.robot.regressors.stack import row_weights, signals_from_dataset
from dynid.simulation import SimulationSettings, simulate

ICUB = load_config("icub_right_arm")
MODEL = RobotModel(ICUB)


def test_chunked_signals_give_the_statistics_of_the_whole_record() -> None:
    ds = simulate(ICUB, SimulationSettings(duration=12.0, seed=2)).dataset  # noisy, with disturbance
    settings = FitSettings()
    sig = signals_from_dataset(MODEL, ds, filter_outputs=True)
    inst = instrument_signals(sig, ds.t, settings.instrument_window_s)
    weights = row_weights(MODEL, sig, settings.min_speed) * (row_weights(MODEL, inst, settings.min_speed) > 0)
    whole = accumulate(MODEL, InMemory(sig, weights, inst), n_blocks=3, workers=1)
    # Small chunks, so that most chunk edges sit inside the record and need their margins.
    chunked = accumulate(MODEL, SignalSource(MODEL, ds, settings, instruments=True), n_blocks=3, workers=2, chunk=700)
    assert np.array_equal(whole.rows, chunked.rows)
    for a, b in ((whole.gram, chunked.gram), (whole.cross, chunked.cross), (whole.cross_b, chunked.cross_b)):
        assert np.max(np.abs(a - b)) <= 1e-9 * np.max(np.abs(a))
