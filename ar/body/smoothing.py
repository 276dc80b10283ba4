"""MediaPipe's temporal filters for pose landmarks (the ``PoseLandmarkFiltering`` subgraph).

Method (mediapipe/util/filtering/one_euro_filter.cc, low_pass_filter.cc and
calculators/util/landmarks_smoothing_calculator*.cc, visibility_smoothing_calculator.cc):

* every coordinate of every landmark has its own one-euro filter: the rate of change
  ``(value − last raw value) · value_scale · frequency`` is low-passed with the alpha of
  ``derivate_cutoff``; the value is low-passed with the alpha of
  ``min_cutoff + beta · |rate|``; ``alpha = 1 / (1 + tau / te)`` with ``tau = 1 / (2π
  cutoff)``, ``te = 1 / frequency``; the frequency comes from the last two timestamps
  (30 Hz before there are two); a timestamp not after the last one returns the value
  unfiltered;
* image landmarks are filtered in pixels (x·W, y·H, z·W) with ``value_scale = 1 /
  object scale``, the object scale being the side of the square through the two
  auxiliary landmarks (2·|aux1 − aux0| pixels); world landmarks in metres with
  ``value_scale = 1``;
* visibilities are low-passed with alpha 0.1;
* a frame without a pose resets every filter.

Constants (:data:`LANDMARKS`, :data:`WORLD`, :data:`AUXILIARY`) are those of the graph in
the mediapipe 0.10.21 wheel; the auxiliary landmarks (which place the next frame's
region) are smoothed even when smoothing is off, as there.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class OneEuroConfig:
    """One-euro parameters (LandmarksSmoothingCalculatorOptions.OneEuroFilter)."""

    min_cutoff: float
    beta: float
    derivate_cutoff: float = 1.0
    frequency: float = 30.0  #: used until two timestamps give the real one
    min_allowed_object_scale: float = 1e-6


#: image landmarks (pixels, value scale 1 / object scale)
LANDMARKS = OneEuroConfig(min_cutoff=0.05, beta=80.0)
#: world landmarks (metres, no value scaling)
WORLD = OneEuroConfig(min_cutoff=0.1, beta=40.0)
#: the two auxiliary landmarks that place the next region
AUXILIARY = OneEuroConfig(min_cutoff=0.01, beta=10.0)
#: VisibilitySmoothingCalculator low_pass_filter alpha
VISIBILITY_ALPHA = 0.1


def _alpha(cutoff: np.ndarray | float, frequency: float) -> np.ndarray | float:
    te = 1.0 / frequency
    tau = 1.0 / (2.0 * np.pi * cutoff)
    return 1.0 / (1.0 + tau / te)


def _low_pass(value: np.ndarray, alpha: np.ndarray | float, stored: np.ndarray | None) -> np.ndarray:
    """MediaPipe's LowPassFilter step in its precisions: float32 state and alpha,
    ``alpha·value`` in float32, ``(1.0 − alpha)·stored`` in double, the sum stored as float32."""
    value = np.asarray(value, np.float32)
    if stored is None:
        return value.copy()
    a = np.asarray(alpha, np.float32)
    return (np.float64(1.0) * (a * value) + (1.0 - a.astype(np.float64)) * stored.astype(np.float64)).astype(np.float32)


class OneEuroFilter:
    """A bank of independent one-euro filters over an array of values (every element its
    own filter, all stamped together), in MediaPipe's precisions (double rates and
    cutoffs, float32 filter states)."""

    def __init__(self, config: OneEuroConfig):
        self.config = config
        self.reset()

    def reset(self) -> None:
        self._last_ns: int | None = None
        self._frequency = float(np.float32(self.config.frequency))
        self._raw: np.ndarray | None = None  # last raw value (float32)
        self._x: np.ndarray | None = None  # last filtered value (float32)
        self._dx: np.ndarray | None = None  # last filtered rate (float32)

    def apply(self, value: np.ndarray, timestamp_s: float, value_scale: float = 1.0) -> np.ndarray:
        value = np.asarray(value, np.float32)
        ns = int(round(timestamp_s * 1e6)) * 1000  # MediaPipe's clock: microseconds, as nanoseconds
        if self._last_ns is not None and ns <= self._last_ns:
            return value.copy()
        if self._last_ns is not None:
            self._frequency = 1.0 / ((ns - self._last_ns) * 1e-9)
        self._last_ns = ns
        f, cfg = self._frequency, self.config
        if self._raw is not None:
            rate = (value.astype(np.float64) - self._raw.astype(np.float64)) * float(np.float32(value_scale)) * f
        else:
            rate = np.zeros(value.shape, np.float64)
        self._dx = _low_pass(rate.astype(np.float32), _alpha(cfg.derivate_cutoff, f), self._dx)
        cutoff = cfg.min_cutoff + cfg.beta * np.abs(self._dx.astype(np.float64))
        self._x = _low_pass(value, _alpha(cutoff, f), self._x)
        self._raw = value
        return self._x.copy()


class LowPassFilter:
    """Exponential smoothing with a fixed ``alpha`` (the first value passes unchanged)."""

    def __init__(self, alpha: float):
        self.alpha = alpha
        self.reset()

    def reset(self) -> None:
        self._x: np.ndarray | None = None

    def apply(self, value: np.ndarray) -> np.ndarray:
        self._x = _low_pass(value, self.alpha, self._x)
        return self._x.copy()


class LandmarkSmoother:
    """Image-landmark smoothing (pixels): a one-euro bank on (N, 3) positions scaled by the
    object, and a low-pass on visibility."""

    def __init__(self, config: OneEuroConfig):
        self.position = OneEuroFilter(config)
        self.visibility = LowPassFilter(VISIBILITY_ALPHA)

    def reset(self) -> None:
        self.position.reset()
        self.visibility.reset()

    def apply(self, xyz: np.ndarray, visibility: np.ndarray, timestamp_s: float,
              object_scale: float | None) -> tuple[np.ndarray, np.ndarray]:
        vis = self.visibility.apply(visibility)
        if object_scale is None:
            return self.position.apply(xyz, timestamp_s), vis
        if object_scale < self.position.config.min_allowed_object_scale:
            return np.asarray(xyz, np.float32).copy(), vis
        return self.position.apply(xyz, timestamp_s, float(np.float32(1.0) / np.float32(object_scale))), vis


__all__ = ["OneEuroConfig", "LANDMARKS", "WORLD", "AUXILIARY", "VISIBILITY_ALPHA", "OneEuroFilter", "LowPassFilter",
           "LandmarkSmoother"]
