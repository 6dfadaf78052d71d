"""The model file's `observer` section as typed objects: the momentum detector calibrated at fit time, for `detect`
and for `export`'s monitor, and the combined detector's level (dynid.detect.momentum_t2 and dynid.detect.combined build
their detectors from these). The same conventions as dynid.identify.model_sections: frozen dataclasses built once
from the checked JSON (`from_json`) and written back key for key (`to_json`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .model_sections import CROSS_VALIDATED, IN_SAMPLE, Json, Quantiles, _array, _extra

__all__ = ["CombinedCalibration", "MomentumCalibration", "ObserverEntry", "ObserverSection"]


@dataclass(frozen=True)
class MomentumCalibration:
    """The momentum observer's detector as calibrated (dynid.detect.momentum_t2.MomentumDetector is built from it)."""

    bandwidth_hz: float
    variance: np.ndarray  # Λ (n_out,) of the band-clipped observer residuals
    tau_variance: np.ndarray  # (n_joints,) of the external joint torque estimate
    threshold: float
    alpha: float
    min_speed: float
    band_sigmas: float
    ft_thresholds: dict[str, float]
    calibration_samples: int
    velocity_window_s: float
    quantiles: Quantiles | None = None
    extra: Json = field(default_factory=dict, compare=False)  # what `detect --json` adds: variant, rest_threshold

    KEYS = ("bandwidth_hz", "variance", "tau_variance", "threshold", "alpha", "min_speed", "band_sigmas",
            "ft_thresholds", "calibration_samples", "velocity_window_s", "quantiles")

    @classmethod
    def from_json(cls, d: Json) -> MomentumCalibration:
        q = d.get("quantiles")
        return cls(float(d["bandwidth_hz"]), _array(d["variance"]), _array(d["tau_variance"]), float(d["threshold"]),
                   float(d["alpha"]), float(d["min_speed"]), float(d["band_sigmas"]),
                   {k: float(v) for k, v in d["ft_thresholds"].items()}, int(d["calibration_samples"]),
                   float(d["velocity_window_s"]), Quantiles.from_json(q) if q else None, _extra(d, cls.KEYS))

    def to_json(self) -> Json:
        return {**self.extra, "bandwidth_hz": self.bandwidth_hz, "variance": self.variance.tolist(),
                "tau_variance": self.tau_variance.tolist(), "threshold": self.threshold, "alpha": self.alpha,
                "min_speed": self.min_speed, "band_sigmas": self.band_sigmas, "ft_thresholds": self.ft_thresholds,
                "calibration_samples": self.calibration_samples, "velocity_window_s": self.velocity_window_s,
                "quantiles": {} if self.quantiles is None else self.quantiles.to_json()}


@dataclass(frozen=True)
class CombinedCalibration:
    """The combined detector's level (dynid.detect.combined): κ, the α-quantile of T²_m/T²_m,α + T²_c/T²_c,α on
    paired contact-free calibration samples, and that sum's quantiles (κ at another α)."""

    scale: float
    alpha: float
    calibration_samples: int
    quantiles: Quantiles

    @classmethod
    def from_json(cls, d: Json) -> CombinedCalibration:
        return cls(float(d["scale"]), float(d["alpha"]), int(d["calibration_samples"]), Quantiles.from_json(d["quantiles"]))

    def to_json(self) -> Json:
        return {"scale": self.scale, "alpha": self.alpha, "calibration_samples": self.calibration_samples,
                "quantiles": self.quantiles.to_json()}


@dataclass(frozen=True)
class ObserverEntry:
    """How one use's momentum detector was calibrated, and the detector."""

    alpha: float
    bandwidth_hz: float
    velocity_window_s: float
    band_sigmas: float
    measured: bool  # q̇ the data's own (detect) or the monitor's causal estimate (export)
    detector: MomentumCalibration
    calibration: str = IN_SAMPLE  # CROSS_VALIDATED (the fit's folds) or IN_SAMPLE
    in_sample: MomentumCalibration | None = None  # beside a cross-validated one: the fit's own residuals' calibration
    # the `detect` entry's: the combined detector's level on the same samples (a file written before has none)
    combined: CombinedCalibration | None = None

    @classmethod
    def from_json(cls, d: Json) -> ObserverEntry:
        calibration = str(d.get("calibration", IN_SAMPLE))
        if calibration not in (CROSS_VALIDATED, IN_SAMPLE):
            raise ValueError(f"observer calibration is '{calibration}' ({CROSS_VALIDATED} or {IN_SAMPLE})")
        return cls(float(d["alpha"]), float(d["bandwidth_hz"]), float(d["velocity_window_s"]), float(d["band_sigmas"]),
                   bool(d["measured"]), MomentumCalibration.from_json(d["detector"]), calibration,
                   MomentumCalibration.from_json(d["in_sample"]) if d.get("in_sample") else None,
                   CombinedCalibration.from_json(d["combined"]) if d.get("combined") else None)

    def to_json(self) -> Json:
        out = {"alpha": self.alpha, "bandwidth_hz": self.bandwidth_hz, "velocity_window_s": self.velocity_window_s,
               "band_sigmas": self.band_sigmas, "measured": self.measured, "detector": self.detector.to_json(),
               "calibration": self.calibration}
        if self.in_sample is not None:
            out["in_sample"] = self.in_sample.to_json()
        if self.combined is not None:
            out["combined"] = self.combined.to_json()
        return out


@dataclass(frozen=True)
class ObserverSection:
    """`observer`: the momentum detector calibrated at fit time for `detect` and for `export`'s monitor."""

    version: int
    data_sha256: tuple[str | None, ...]
    detect: ObserverEntry | None = None
    monitor: ObserverEntry | None = None

    @classmethod
    def from_json(cls, d: Json) -> ObserverSection:
        return cls(int(d["version"]), tuple(d["data_sha256"]),
                   *(None if d.get(k) is None else ObserverEntry.from_json(d[k]) for k in ("detect", "monitor")))

    def to_json(self) -> Json:
        return {"version": self.version, "data_sha256": list(self.data_sha256),
                **{k: e.to_json() for k, e in (("detect", self.detect), ("monitor", self.monitor)) if e is not None}}

    def entry(self, use: str) -> ObserverEntry | None:
        return self.detect if use == "detect" else self.monitor
