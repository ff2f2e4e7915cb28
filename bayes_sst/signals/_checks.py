"""Plausibility checks of recorded channels against each other."""

from __future__ import annotations

import numpy as np

from bayes_sst.signals._cycles import CycleWindow
from bayes_sst.signals._filters import time_derivative, zero_phase_lowpass

# A recorded acceleration is trusted when, over the steady window and inside the low-pass band,
# its RMS is within this factor of the displacement's second derivative and the two correlate
# at least this well. Measured on 580 tests (24 series of the independent generator, two of the
# twin, three with stiction): RMS ratio 0.985-1.020, correlation >= 0.998. A dead channel
# (all zeros), a wrong sign or a wrong scale falls far outside.
ACCELERATION_RMS_FACTOR = 1.5
ACCELERATION_MIN_CORRELATION = 0.9


def accelerometer_disagreement(a, u_filtered, cutoff_hz: float, fs: float, window: CycleWindow) -> str | None:
    """Why the recorded acceleration a cannot be the deck's, or None when it can.

    Compares low-pass(a) with d^2/dt^2 of the low-passed displacement over the steady window:
    the RMS ratio r = rms(a_lp)/rms(u_f'') must lie within [1/ACCELERATION_RMS_FACTOR,
    ACCELERATION_RMS_FACTOR] and the correlation must reach ACCELERATION_MIN_CORRELATION.
    Why: the force balance weighs a by Me, so a dead or mis-scaled accelerometer moves Me and,
    through the sine tests' Me-Ke ridge, Ke (a channel of zeros gave Ke = -222 kN/m and a
    between-test spread of Ke of 21794 %).
    """
    span = slice(window.start, window.stop)
    from_u = time_derivative(time_derivative(np.asarray(u_filtered, dtype=float), fs), fs)[span]
    recorded = zero_phase_lowpass(np.asarray(a, dtype=float), cutoff_hz, fs)[span]
    from_u = from_u - from_u.mean()
    recorded = recorded - recorded.mean()
    rms_u = float(np.sqrt(np.mean(from_u**2)))
    rms_a = float(np.sqrt(np.mean(recorded**2)))
    if rms_u <= 0.0:
        return None  # no motion to compare with; the steady-cycle check reports that
    ratio = rms_a / rms_u
    correlation = float(np.dot(recorded, from_u) / (len(from_u) * rms_a * rms_u)) if rms_a > 0.0 else 0.0
    if 1.0 / ACCELERATION_RMS_FACTOR <= ratio <= ACCELERATION_RMS_FACTOR and correlation >= ACCELERATION_MIN_CORRELATION:
        return None
    return (f"column 'a' disagrees with the displacement's second derivative inside the {cutoff_hz:.3g} Hz band "
            f"(RMS ratio {ratio:.3g}, correlation {correlation:.3f}; a working accelerometer gives about 1 and "
            f"above {ACCELERATION_MIN_CORRELATION})")
