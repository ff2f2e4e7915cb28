"""The breakaway check: does the friction at each velocity reversal rise above its kinetic level?

Static friction above kinetic friction (stiction) lives where the table rests at a reversal.
Where the friction falls to its kinetic level over a Stribeck velocity of a few mm/s, the
reversal view's Stribeck column reads it (_diagnose.REVERSAL_EFFECTS). Where it drops at once
(stick until |F_A - Ke*u| exceeds Fs, then kinetic friction: the Karnopp model), nothing in the
moving samples differs from Coulomb friction, and that column sees nothing: the twin with
Fs/Fk = 1.4 and a Stribeck velocity of 0.5 mm/s scored it 0.3 +- 2.9 nats at 200 Hz and
0.4 +- 0.5 at 1 kHz. What remains is the force the resting table holds just before it breaks
away, Fs instead of Fk. Per test j, at the record rate,

    r(t) = F - Me*a - Ke*u - Ce*|v|^alpha*sign(v)          (the friction, plus noise)

swings at a reversal from +Fk through the rest to -Fs and on to -Fk (signs of the new
direction), so with h = min(80 ms, T/20)

    d_i = (range of r over |t - t_i| <= h  -  range of r over |t - t_i - T/4| <= h)/(L_j*Fmu_j) - 2

is about Fs/Fk - 1 for each reversal i at t_i (an extreme of u); the mid-stroke window, where
the table slides at its kinetic level, holds the noise's own range, and L_j is the test's
friction load. The window is short so that Ke*u and Me*a hardly change within it: their errors
then cancel in the range (a sine test fixes only Ke - (2 pi f)^2*Me, and per-test values 8-32 %
off in Ke put a peak-based first version 0.5-2 from zero). Me and Ke are the population's, Ce
and Fmu each test's. excess = the tests' mean of d (weighted by reversals), excess_se from the
scatter of the per-test means. Only tests with a recorded acceleration enter: a derived one
rounds off the breakaway.

The check reads any reversal dynamics the base model lacks: a force delay or a specimen
ringing after each reversal read 0.1-1.8 (so it selects only where no other effect was), a
clean valve-generator table (Stribeck peak 1.02-1.05) up to 0.092 at z 5.7, LuGre's clean
tables up to 0.83 at z 1.6. Stiction: the twin's Karnopp 1.4 reads 0.20-0.23 at 1 kHz (z 7) and
0.06-0.08 at 200 Hz (the peak falls between samples). docs/diagnosis.md has the table; hence
the thresholds below.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from bayes_sst.diagnosis._engine import ModelFit
from bayes_sst.effects import EffectData
from bayes_sst.io import Series
from bayes_sst.signals._filters import time_derivative, zero_phase_lowpass

# the excess, as a share of the kinetic friction, and its z that select stiction by this check
BREAKAWAY_EXCESS = 0.15
BREAKAWAY_Z = 5.0
WINDOW_S = 0.08
WINDOW_PERIODS = 0.05
# the velocity for r: a light low-pass of u, at least this cut-off (Hz) or 6 test frequencies
VELOCITY_CUTOFF_HZ = 30.0
MIN_TESTS = 3


def _reversal_indices(u: np.ndarray, frequency_hz: float, fs: float, lo: int, hi: int) -> np.ndarray:
    """Record indices in [lo, hi) of the extremes of u: sign changes of the velocity of u
    smoothed at 3 test frequencies, which noise cannot split into several crossings."""
    smooth = zero_phase_lowpass(u, min(3.0 * frequency_hz, 0.4 * fs), fs)
    v = time_derivative(smooth, fs)
    i = np.nonzero(np.sign(v[lo + 1:hi]) != np.sign(v[lo:hi - 1]))[0] + lo
    return i


def _test_excess(u, F, a, frequency_hz, fs, lo, hi, coefficients, alpha) -> list[float]:
    """d_i (in N) of every reversal of one test whose windows fit inside the record."""
    # sensor offsets need no removing: a constant in F, u or a shifts r by a constant, which
    # neither range sees, and the velocity and the reversals come from derivatives of u
    Me, Ke, Ce = coefficients["Me"], coefficients["Ke"], coefficients["Ce"]
    v = time_derivative(zero_phase_lowpass(u, min(max(VELOCITY_CUTOFF_HZ, 6.0 * frequency_hz), 0.4 * fs), fs), fs)
    r = F - Me * a - Ke * u - Ce * np.abs(v) ** alpha * np.sign(v)
    period = 1.0 / frequency_hz
    h = max(int(round(min(WINDOW_S, WINDOW_PERIODS * period) * fs)), 2)
    quarter = int(round(0.25 * period * fs))
    excess = []
    for i in _reversal_indices(u, frequency_hz, fs, lo, hi):
        q = i + quarter
        if i - h < 0 or q + h + 1 > len(r):
            continue
        around, mid = r[i - h:i + h + 1], r[q - h:q + h + 1]
        excess.append(float(np.ptp(around) - np.ptp(mid)))
    return excess


def breakaway_check(series: Series, tests: Sequence[EffectData], fit: ModelFit) -> dict[str, Any] | None:
    """The module docstring's excess over the tests with a recorded acceleration, or None
    where fewer than MIN_TESTS have one."""
    names = list(fit.names)
    per_test = {}
    counts = []
    for j, test in enumerate(tests):
        if not test.acceleration_measured:
            continue
        record = series.test(test.id)
        columns = record.columns
        if "a" not in columns:
            continue
        # Me and Ke: the population's (plus the payload). The resting table's force F - Ke*u
        # needs Ke itself, and a sine test fixes only Ke - (2 pi f)^2*Me: the per-test values
        # of a valve-generator series were 8-32 % off in Ke, which put d 0.5-2 from zero
        coefficients = {"Me": fit.coefficient("Me") + test.payload_kg, "Ke": fit.coefficient("Ke"),
                        **{n: float(fit.theta[j, names.index(n)]) for n in ("Ce", "Fmu")}}
        kinetic = coefficients["Fmu"] * test.friction_load
        if kinetic <= 0:
            continue
        lo, hi = int(test.index.min()), int(test.index.max()) + 1
        d = _test_excess(np.asarray(columns["u"], float), np.asarray(columns["F"], float),
                         np.asarray(columns["a"], float), test.frequency_hz, test.sample_rate_hz,
                         lo, hi, coefficients, fit.alpha)
        if d:
            per_test[test.id] = float(np.mean(d)) / kinetic - 2.0
            counts.append(len(d))
    if len(per_test) < MIN_TESTS:
        return None
    values = np.array(list(per_test.values()))
    weights = np.array(counts, dtype=float)
    excess = float(np.sum(weights * values) / weights.sum())
    excess_se = float(np.std(values, ddof=1) / np.sqrt(len(values)))
    z = excess / excess_se if excess_se > 0 else 0.0
    return {"excess": excess, "excess_se": excess_se, "z": z, "tests": len(values),
            "reversals": int(weights.sum()), "positive_share": float(np.mean(values > 0)),
            "per_test": per_test, "selectable": bool(excess >= BREAKAWAY_EXCESS and z >= BREAKAWAY_Z),
            "thresholds": {"excess": BREAKAWAY_EXCESS, "z": BREAKAWAY_Z}}
