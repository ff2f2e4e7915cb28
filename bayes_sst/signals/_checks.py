"""Plausibility checks of recorded channels against each other."""

from __future__ import annotations

import numpy as np

from bayes_sst.signals._cycles import CycleWindow
from bayes_sst.signals._filters import second_derivative, zero_phase_lowpass
from bayes_sst.signals._noise import white_noise_sd

# A recorded acceleration is trusted when, over the steady window and inside the low-pass band,
# its RMS is within this factor of what the displacement's second derivative plus the
# accelerometer's own noise would give, and the two correlate at least this share as well as
# that noise allows. Measured on 2,100 tests (24 series of the independent generator, three of
# the twin, the variants of a stress test at 100-2000 Hz, payloads, 5x noise): none refused;
# the plain RMS ratio was 0.985-1.020 and the correlation >= 0.998 on the first 580. A dead
# channel (all zeros), a wrong sign or a wrong scale falls far outside.
ACCELERATION_RMS_FACTOR = 1.5
ACCELERATION_MIN_CORRELATION = 0.9


def accelerometer_disagreement(a, u_filtered, cutoff_hz: float, fs: float, window: CycleWindow, *,
                               a_low=None) -> str | None:
    """Why the recorded acceleration a cannot be the deck's, or None when it can.

    Over the steady window, with a_lp = low-pass(a), a_u = u_f'' (signals.second_derivative) and
    n the accelerometer's white noise inside the band (white_noise_sd of a less a_lp, times
    sqrt(2*cutoff/fs)), the expected RMS ratio is e = sqrt(1 + n^2/rms(a_u)^2) and the expected
    correlation 1/e. The channel is refused when rms(a_lp)/rms(a_u) is outside
    [1/ACCELERATION_RMS_FACTOR, e*ACCELERATION_RMS_FACTOR] or its correlation with a_u is below
    ACCELERATION_MIN_CORRELATION/e. Why: the force balance weighs a by Me, so a dead or
    mis-scaled accelerometer moves Me and, through the sine tests' Me-Ke ridge, Ke (a channel of
    zeros gave Ke = -222 kN/m and a between-test spread of Ke of 21794 %); the noise term keeps a
    working but noisy accelerometer on a slow, small test (whose acceleration is mostly noise)
    from being called faulty.

    Why the lower bound leaves e out: noise that does not follow the motion can only add to the
    in-band power, while n, read above the cut-off, can be far too high where the deck rings
    at an oil-column or servo-loop frequency above the band (its motion shows in the second
    differences that white_noise_sd reads). A simulated table whose loop limit-cycled at 53 Hz
    (+-30 m/s^2) read n = 5 m/s^2 against 0.02 of true noise, e = 2.1, and its working channel
    (ratio 1.00, correlation 0.999) was refused under a lower bound of e/ACCELERATION_RMS_FACTOR.
    a_low: low-pass(a) at cutoff_hz when the caller has it already.
    """
    span = slice(window.start, window.stop)
    a = np.asarray(a, dtype=float)
    from_u = second_derivative(np.asarray(u_filtered, dtype=float), fs)[span]
    low = zero_phase_lowpass(a, cutoff_hz, fs) if a_low is None else np.asarray(a_low, dtype=float)
    recorded = low[span]
    noise = white_noise_sd((a - low)[span]) * np.sqrt(min(1.0, 2.0 * cutoff_hz / fs))
    from_u = from_u - from_u.mean()
    recorded = recorded - recorded.mean()
    rms_u = float(np.sqrt(np.mean(from_u**2)))
    rms_a = float(np.sqrt(np.mean(recorded**2)))
    if rms_u <= 0.0:
        return None  # no motion to compare with; the steady-cycle check reports that
    expected = float(np.sqrt(1.0 + (noise / rms_u) ** 2))
    ratio = rms_a / rms_u
    correlation = float(np.dot(recorded, from_u) / (len(from_u) * rms_a * rms_u)) if rms_a > 0.0 else 0.0
    if (1.0 / ACCELERATION_RMS_FACTOR <= ratio <= expected * ACCELERATION_RMS_FACTOR
            and correlation >= ACCELERATION_MIN_CORRELATION / expected):
        return None
    return (f"column 'a' disagrees with the displacement's second derivative inside the {cutoff_hz:.3g} Hz band "
            f"(RMS ratio {ratio:.3g} where its noise allows {expected:.3g}, correlation {correlation:.3f} "
            f"where at least {ACCELERATION_MIN_CORRELATION / expected:.3f} is expected): a dead, reversed or "
            "mis-scaled channel")
