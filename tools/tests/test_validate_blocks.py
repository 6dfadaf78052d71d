"""`dynid validate --blocks K` (dynid.identify.blocks): every time block of a run validated alone, as `validate
--from/--to` validates the same samples; which blocks the model was fitted on, read from the model file's runs and
windows; the worst block and the spread; and every bad --blocks refused in one line with exit 2."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from dynid import DynamicsModel
from dynid.cli import main
from dynid.errors import InputError
from dynid.identify.blocks import fitted_mask, time_blocks
from dynid.identify.model_file import load_model
from dynid.identify.model_sections import DataRun

RTOL = 1e-9  # the same arithmetic on the same samples; only BLAS kernels may differ in the last bits


def validate(tmp_path: Path, name: str, *args: str) -> dict:
    out = tmp_path / f"{name}.json"
    assert main(["validate", *args, "--json", str(out)]) == 0
    return json.loads(out.read_text())


def close(a: object, b: object, where: str = "") -> None:
    """Every number of two validation results alike (to RTOL), every other field equal."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), where
        for k in a:
            close(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            close(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and not isinstance(a, bool):
        assert b == pytest.approx(a, rel=RTOL, abs=1e-300), where
    else:
        assert a == b, where


@pytest.mark.numerics
def test_each_block_is_the_window_of_its_samples(default_model: Path, default_experiments: dict[str, Path],
                                                 tmp_path: Path) -> None:
    data = str(default_experiments["validation"])
    whole = validate(tmp_path, "blocks", "--model", str(default_model), "--data", data, "--blocks", "3")
    blocks = whole["blocks"]
    assert blocks["k"] == 3 and len(blocks["blocks"]) == 3
    # the blocks cover the run, in order, without a shared sample, in three equal durations
    assert sum(b["samples"] for b in blocks["blocks"]) == whole["samples"]
    durations = [b["to"] - b["from"] for b in blocks["blocks"]]
    assert max(durations) - min(durations) < 3 * (blocks["span"][1] - blocks["span"][0]) / whole["samples"]
    for b in blocks["blocks"]:
        alone = validate(tmp_path, f"block{b['index']}", "--model", str(default_model), "--data", data,
                         "--from", repr(b["from"]), "--to", repr(b["to"]))
        assert alone["samples"] == b["samples"]
        close(alone, b["validation"], f"block {b['index']}")
        # a validation run the model never saw: no block is in the fit
        assert b["fit_overlap"] == 0.0 and b["in_fit"] is False
    # the summary is the blocks' own figures: worst = the largest, median and best as numpy finds them
    for name, s in blocks["summary"]["figures"].items():
        values = np.array([b["figures"][name] for b in blocks["blocks"]])
        assert s["max"] == values.max() and s["min"] == values.min() and s["median"] == np.median(values)
        assert blocks["blocks"][s["worst_block"]]["figures"][name] == values.max()
    assert "relative_error.overall" in blocks["summary"]["figures"]
    assert any(n.endswith("torque_identified_vs_cad") for n in blocks["summary"]["figures"])
    assert blocks["summary"]["blocks_in_fit"] == [] and blocks["summary"]["blocks_outside_fit"] == [0, 1, 2]


def test_the_fitted_run_is_in_the_fit(default_model: Path, default_experiments: dict[str, Path]) -> None:
    """Through the API: the identification run, fitted whole, is in the fit on every block."""
    model = DynamicsModel.load(default_model)
    result = model.validate(str(default_experiments["identification"]), blocks=2)
    assert [b["fit_overlap"] for b in result["blocks"]["blocks"]] == [1.0, 1.0]
    assert result["blocks"]["summary"]["blocks_in_fit"] == [0, 1]
    with pytest.raises(InputError, match="at least 2 blocks"):
        model.validate(str(default_experiments["identification"]), blocks=1)


def test_the_fit_overlap_follows_the_model_files_windows(default_model: Path,
                                                         default_experiments: dict[str, Path]) -> None:
    """A model fitted on [2, 5] s of a run: the samples of that run inside it, none of another run."""
    identified = load_model(default_model)
    run = identified.data[0]
    windowed = replace(identified, data=(replace(run, window=(2.0, 5.0)),))
    t = np.arange(0.0, 10.0, 0.001)
    mask = fitted_mask(windowed, str(default_experiments["identification"]), t)
    assert mask is not None and np.array_equal(mask, (t >= 2.0) & (t <= 5.0))
    other = fitted_mask(windowed, str(default_experiments["validation"]), t)
    assert other is not None and not other.any()
    unknown = replace(identified, data=(DataRun(path=""),))
    assert fitted_mask(unknown, str(default_experiments["validation"]), t) is None


def test_time_blocks_cover_the_run_once() -> None:
    t = np.cumsum(np.full(1000, 0.01)) + 3.0
    blocks = time_blocks(t, 4)
    assert [b.stop - b.start for b in blocks] == [250, 250, 250, 250]
    assert blocks[0].start == 0 and blocks[-1].stop == t.size
    assert all(a.stop == b.start for a, b in zip(blocks, blocks[1:]))
    with pytest.raises(InputError, match="holds 100 samples, fewer than the 101"):
        time_blocks(t, 10, min_samples=101)


@pytest.mark.parametrize("given, message", [
    (("--blocks", "1"), "must be at least 2"),
    (("--blocks", "0"), "must be at least 2"),
    (("--blocks", "-3"), "must be at least 2"),
    (("--blocks", "two"), "is not an integer"),
    (("--blocks", "30", "--from", "1", "--to", "3"), "fewer than the"),  # shorter than a window and the filter allow
    (("--blocks", "4", "--from", "1", "--to", "1.3"), "fewer than the"),
])
def test_bad_blocks_is_one_line_and_exit_2(default_model: Path, default_experiments: dict[str, Path],
                                           tmp_path: Path, capsys: pytest.CaptureFixture, given: tuple,
                                           message: str) -> None:
    out = tmp_path / "v.json"
    args = ["validate", "--model", str(default_model), "--data", str(default_experiments["validation"]), *given,
            "--json", str(out)]
    try:
        code = main(args)
    except SystemExit as e:  # argparse's usage error: one line, exit 2 (dynid.cli.common.Parser)
        code = e.code
    captured = capsys.readouterr()
    assert code == 2
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and "Traceback" not in captured.err, captured.err
    assert captured.out == "" and not out.exists()  # nothing printed of a half-done validation, nothing written


def test_the_text_names_the_worst_and_the_best_block(default_model: Path, default_experiments: dict[str, Path],
                                                     capsys: pytest.CaptureFixture) -> None:
    assert main(["validate", "--model", str(default_model), "--data", str(default_experiments["validation"]),
                 "--from", "10", "--to", "30", "--blocks", "2"]) == 0
    text = capsys.readouterr().out
    assert "every block: 2 blocks of 10 s over 10.00–30.00 s" in text
    assert "block  1  10.00–20.00 s" in text and "block  2  20.00–30.00 s" in text
    worst = [line for line in text.splitlines() if "relative error, overall" in line and "worst" in line]
    assert len(worst) == 1 and "best" in worst[0] and "in fit: no" in worst[0]
    assert text.rstrip().endswith("blocks in the fit: none")
