"""The signals a candidate test would give the likelihood, built without running it.

A candidate's record is the commanded motion itself: rest, a raised-cosine ramp over one
cycle, n steady cycles, a ramp out, rest (the virtual table's command layout),

    u = A e(t) y(w t),  v = A (e' y + e y' w),  a = A (e'' y + 2 e' y' w + e y'' w^2),

with the noise-free model force F = Me a + Ke u + (Ce |v|^alpha + Fmu) sign(v). It then goes
through bayes_sst.signals.prepare_test exactly like a recorded test (low-pass, smoothed
velocity, steady-cycle window, decimation, reversal band), so its regressors, kept samples
and sample pairs are those the fit would see. The servo loop's small tracking error and the
sensor noise are left out: the residual model (AR(1) per test) carries them.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Mapping

import numpy as np

from bayes_sst.design._candidates import Candidate, waveform
from bayes_sst.io import TestRecord, TestSpec
from bayes_sst.signals import PreparedTest, SignalOptions, prepare_test

RAMP_CYCLES = 1.0
REST_S = 0.5


def _envelope(t: np.ndarray, t_ramp: float, t_hold: float):
    """Raised-cosine envelope e(t) (0 -> 1 over t_ramp, 1 for t_hold, back to 0) and e', e''."""
    k = math.pi / t_ramp
    down = t_ramp + t_hold
    rising = (t >= 0) & (t < t_ramp)
    falling = (t > down) & (t <= down + t_ramp)
    tr, tf = np.where(rising, t, 0.0), np.where(falling, t - down, 0.0)
    e = np.where(rising, 0.5 * (1 - np.cos(k * tr)), np.where((t >= t_ramp) & (t <= down), 1.0, 0.0))
    e = np.where(falling, 0.5 * (1 + np.cos(k * tf)), e)
    de = np.where(rising, 0.5 * k * np.sin(k * tr), np.where(falling, -0.5 * k * np.sin(k * tf), 0.0))
    d2e = np.where(rising, 0.5 * k * k * np.cos(k * tr), np.where(falling, -0.5 * k * k * np.cos(k * tf), 0.0))
    return e, de, d2e


def candidate_record(candidate: Candidate, *, n_cycles: int, sample_rate_hz: float,
                     coefficients: Mapping[str, float], test_id: str = "C") -> TestRecord:
    """The noise-free record of a candidate (module docstring), columns t, u, F, a."""
    f, amplitude = candidate.frequency_hz, candidate.amplitude_m
    duration = 2 * REST_S + (n_cycles + 2 * RAMP_CYCLES) / f
    t = np.arange(int(math.ceil(duration * sample_rate_hz)) + 1) / sample_rate_hz
    w = 2 * math.pi * f
    local = t - REST_S
    e, de, d2e = _envelope(local, RAMP_CYCLES / f, n_cycles / f)
    y, dy, d2y = waveform(candidate.kind, w * local)
    u = amplitude * e * y
    v = amplitude * (de * y + e * dy * w)
    a = amplitude * (d2e * y + 2 * de * dy * w + e * d2y * w * w)
    force = (coefficients["Me"] * a + coefficients["Ke"] * u
             + (coefficients["Ce"] * np.abs(v) ** coefficients["alpha"] + coefficients["Fmu"]) * np.sign(v))
    spec = TestSpec(id=test_id, file=f"{test_id}.csv", kind=candidate.kind, frequency_hz=f, amplitude_m=amplitude)
    return TestRecord(spec, {"t": t, "u": u, "F": force, "a": a})


def candidate_test(candidate: Candidate, *, n_cycles: int, sample_rate_hz: float,
                   coefficients: Mapping[str, float], options: SignalOptions = SignalOptions(),
                   test_id: str = "C", accelerometer: bool = True) -> PreparedTest:
    """The PreparedTest the fit would build from the candidate's record.

    accelerometer=False leaves `a` out of the record, as on a table recorded without one: the
    fit then derives a from u and gives the test the wider reversal band
    (SignalOptions.band_for), and so does the candidate."""
    record = candidate_record(candidate, n_cycles=n_cycles, sample_rate_hz=sample_rate_hz,
                              coefficients=coefficients, test_id=test_id)
    if not accelerometer:
        record = TestRecord(record.spec, {k: v for k, v in record.columns.items() if k != "a"})
    # the record is noise-free by construction (an added test's noise enters its simulated
    # response): no accelerometer noise to estimate, and none for the moments' correction to
    # draw through the signal treatment again for every simulated response
    return prepare_test(record, replace(options, accelerometer_noise=False), source=f"candidate {candidate.describe()}")
