"""The report's parameter table: each base parameter identified, from the CAD model, and true where known.

A base parameter is a combination β = Φ_b + K Φ_d, stored in the model file as text ('a + 0.27·b − 3·c',
`BaseParameters.combinations`). The CAD and the true value of a combination are that same combination of the
CAD and the true Φ; K is read back from the text (six significant digits, plenty for a table). A combination
is undefined for the CAD model when any of its terms is (friction and motor gains have no CAD value); the F/T
offsets of the CAD column are the ones `dynid fit` fitted to the CAD inertia, as `dynid validate` uses them.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..identify.model_file import IdentifiedModel
from ..identify.validation import cad_phi
from ..io.dataset import TRUTH_FORMAT, beside_run

TRUTH_FILE = "truth.json"  # written by `dynid simulate` next to the data (dynid.simulation.output)


def parse_combination(text: str) -> list[tuple[float, str]]:
    """'a + 0.5·b - 2·c' -> [(1, 'a'), (0.5, 'b'), (-2, 'c')]."""
    tokens = text.split()
    if not tokens or len(tokens) % 2 != 1:
        raise DataError(f"model file: unreadable base-parameter combination '{text}'")
    terms = [(1.0, tokens[0])]
    for sign, term in zip(tokens[1::2], tokens[2::2]):
        coefficient, _, name = term.partition("·")
        if sign not in "+-" or not name:
            raise DataError(f"model file: unreadable base-parameter combination '{text}'")
        try:
            terms.append(((1.0 if sign == "+" else -1.0) * float(coefficient), name))
        except ValueError:
            raise DataError(f"model file: unreadable base-parameter combination '{text}'") from None
    return terms


def combine(terms: list[tuple[float, str]], values: dict[str, float]) -> float | None:
    """The combination of named values; None when a term has no (finite) value."""
    total = 0.0
    for k, name in terms:
        v = values.get(name)
        if v is None or not np.isfinite(v):
            return None
        total += k * v
    return total


@dataclass(frozen=True)
class Truth:
    path: str
    parameters: dict[str, float]


def read_truth(path: Path, robot: str) -> Truth:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as e:
        raise DataError(f"cannot read {path}: {e.strerror or e}") from None
    except (UnicodeDecodeError, json.JSONDecodeError):
        raise DataError(f"{path}: not a dynid truth file (not JSON)") from None
    if not isinstance(data, dict) or data.get("format") != TRUTH_FORMAT or not isinstance(data.get("parameters"), dict):
        raise DataError(f"{path}: not a dynid truth file (no 'format: {TRUTH_FORMAT}' with 'parameters')")
    if data.get("robot") != robot:
        raise DataError(f"{path} holds the truth of '{data.get('robot')}', not of the model's robot '{robot}'")
    params = {k: float(v) for k, v in data["parameters"].items() if isinstance(v, (int, float))}
    return Truth(str(path), params)


def find_truth(identified: IdentifiedModel, data_paths: list[str], explicit: str | None) -> Truth | None:
    """The truth to compare with: --truth if given, else the truth.json beside the identification data (the
    model file's record), else beside a report's data. Only a truth of the model's robot is taken."""
    robot = identified.config.name
    beside = _truth_beside(identified.data_paths, robot)  # the plant the model was fitted on, where its data still is
    if explicit:
        path = Path(explicit)
        if not path.is_file():
            raise DataError(f"truth file not found: {path}")
        truth = read_truth(path, robot)
        if beside is not None and truth.parameters != beside.parameters:
            raise DataError(f"{path} holds another {robot}'s truth than the model was fitted on ({beside.path}, beside "
                            "its data): each simulated arm draws its own parameters")
        return truth
    return beside or _truth_beside(data_paths, robot)


def _truth_beside(data_paths: list[str], robot: str) -> Truth | None:
    for c in data_paths:
        path = beside_run(c, TRUTH_FILE)
        if path.is_file():
            try:
                return read_truth(path, robot)
            except DataError:
                continue  # a stray or foreign truth file beside the data: not this model's, not an error
    return None


def parameter_table(identified: IdentifiedModel, truth: Truth | None) -> list[dict[str, Any]]:
    """One row per base parameter: combination, identified value ± standard error, identified flag, CAD, true."""
    base = identified.base
    if base is None:  # an augmented model of `dynid gaps`: its Φ, without the fit's base-parameter statistics
        return []
    model = identified.robot_model
    cad = dict(zip(model.layout.names, cad_phi(model, identified, missing=float("nan")).tolist()))
    rows = []
    for text, name, value, se, ok in zip(base.combinations, base.independent, base.values, base.standard_errors,
                                         base.identified):
        terms = parse_combination(text)
        if terms[0][1] != name:
            raise DataError(f"{identified.path}: base parameter '{name}' does not lead its combination '{text}'")
        true = combine(terms, truth.parameters) if truth else None
        rows.append({"name": name, "combination": text, "identified": float(value), "standard_error": float(se),
                     "determined": bool(ok), "cad": combine(terms, cad), "true": true,
                     "error_in_se": None if true is None or se <= 0 else (float(value) - true) / float(se)})
    return rows


def gains_by_estimator(identified: IdentifiedModel, truth: Truth | None) -> list[dict[str, Any]]:
    """Every motor gain by every estimator the fit ran (the closed-loop bias shows here), with the truth."""
    names = [n for n in identified.robot_model.layout.names if n.endswith(".phi_m")]
    independent = list(identified.base.independent) if identified.base is not None else []
    rows = []
    for n in names:
        if n not in independent:
            continue
        i = independent.index(n)
        row: dict[str, Any] = {"name": n, "true": truth.parameters.get(n) if truth else None, "estimators": {}}
        for est, rec in identified.estimators.items():
            row["estimators"][est] = {"value": float(rec.values[i]), "standard_error": float(rec.standard_errors[i])}
        rows.append(row)
    return rows


def truth_summary(rows: list[dict[str, Any]]) -> dict[str, Any] | None:
    """How far the determined combinations are from the truth, in their own standard errors (honest errors give
    an RMS near 1 and about 95 % within 2 se)."""
    z = np.array([r["error_in_se"] for r in rows if r["determined"] and r["error_in_se"] is not None])
    if z.size == 0:
        return None
    return {"determined": int(z.size), "rms_error_in_se": float(np.sqrt(np.mean(z**2))),
            "within_2se": float(np.mean(np.abs(z) <= 2.0))}
