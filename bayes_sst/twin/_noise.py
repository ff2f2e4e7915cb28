"""Sensor models: what the transducers add to the table's true signals.

* u, displacement transducer: white noise of sd u_white plus quantisation to u_quantum;
* a, accelerometer: white noise of sd a_white on the deck's true acceleration (oil-column
  ringing and friction jolts included), plus, when a_drift > 0, a slow drift: an AR(1)
  process of sd a_drift and correlation time a_drift_correlation_s (a servo or MEMS
  accelerometer's 1/f noise and thermal drift, which sit at a slow test's own frequencies);
* F, load cell: white noise of sd F_white plus a coloured part, an AR(1) process of
  stationary sd F_colored and correlation time F_correlation_s,
  x[n] = phi*x[n-1] + sqrt(1 - phi^2)*F_colored*e[n], phi = exp(-1/(fs*F_correlation_s)).
  Real force residuals are coloured (un-modelled slow effects, signal conditioning), and a
  likelihood that assumes white noise must be tested against that.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Mapping

import numpy as np
from scipy.signal import lfilter


@dataclass(frozen=True)
class SensorNoise:
    """Sensor noise sizes, SI: m, m, m/s^2, N, N, s. SensorNoise.off() is the quiet twin."""

    u_white: float = 20e-6
    u_quantum: float = 2e-6
    a_white: float = 0.03
    F_white: float = 300.0
    F_colored: float = 300.0
    F_correlation_s: float = 0.1
    a_drift: float = 0.0
    a_drift_correlation_s: float = 1.0

    def __post_init__(self):
        for name, value in asdict(self).items():
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"SensorNoise.{name} must be finite and non-negative, got {value!r}")
        if self.F_colored > 0.0 and self.F_correlation_s <= 0.0:
            raise ValueError("SensorNoise.F_correlation_s must be positive when F_colored > 0")
        if self.a_drift > 0.0 and self.a_drift_correlation_s <= 0.0:
            raise ValueError("SensorNoise.a_drift_correlation_s must be positive when a_drift > 0")

    @classmethod
    def off(cls) -> "SensorNoise":
        """No noise and no quantisation: the recorded signals are the simulated ones."""
        return cls(**dict.fromkeys(asdict(cls()), 0.0))

    @property
    def quiet(self) -> bool:
        return not any((self.u_white, self.u_quantum, self.a_white, self.F_white, self.F_colored, self.a_drift))


def resolve_noise(noise) -> SensorNoise:
    """None: the realistic defaults; 'quiet' or False: off; a SensorNoise or a dict of its fields."""
    if noise is None:
        return SensorNoise()
    if noise is False or noise == "quiet":
        return SensorNoise.off()
    if isinstance(noise, SensorNoise):
        return noise
    if isinstance(noise, Mapping):
        return SensorNoise(**noise)
    raise TypeError(f"noise must be None, 'quiet', a SensorNoise or a dict, got {noise!r}")


def ar1(rng: np.random.Generator, n: int, sd: float, correlation_s: float, sample_rate_hz: float) -> np.ndarray:
    """A stationary AR(1) sequence of sd `sd` whose autocorrelation falls as exp(-lag/correlation_s)."""
    e = rng.standard_normal(n)
    if sd == 0.0:
        return np.zeros(n)
    phi = math.exp(-1.0 / (sample_rate_hz * correlation_s))
    # The first value is drawn from the stationary law so the record has no start-up transient.
    x0 = sd * e[0]
    rest = lfilter([sd * math.sqrt(1.0 - phi * phi)], [1.0, -phi], e[1:], zi=[phi * x0])[0]
    return np.concatenate([[x0], rest])


def add_sensor_noise(
    true: Mapping[str, np.ndarray],
    noise: SensorNoise,
    rng: np.random.Generator,
    sample_rate_hz: float,
) -> dict[str, np.ndarray]:
    """Measured u, a, F from the true ones. The draws are made even for zero sizes, so that
    one sensor's setting does not change another sensor's noise for the same generator."""
    n = len(true["u"])
    white = rng.standard_normal((3, n))
    u = true["u"] + noise.u_white * white[0]
    if noise.u_quantum > 0.0:
        u = np.round(u / noise.u_quantum) * noise.u_quantum
    a = true["a"] + noise.a_white * white[1]
    colored = ar1(rng, n, noise.F_colored, noise.F_correlation_s or 1.0, sample_rate_hz)
    force = true["F"] + noise.F_white * white[2] + colored
    if noise.a_drift > 0.0:  # drawn last, so that series without it are unchanged
        a = a + ar1(rng, n, noise.a_drift, noise.a_drift_correlation_s, sample_rate_hz)
    return {"u": u, "a": a, "F": force}
