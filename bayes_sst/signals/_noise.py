"""Sensor noise levels read off a recorded channel."""

from __future__ import annotations

import numpy as np

# The errors-in-variables correction for the accelerometer's noise (the fit's
# inference._statistics.acceleration_noise_correction and the diagnosis's engine):
# draws of the noise through the signal treatment per test; the correction's own Monte Carlo
# error is then about sqrt(2/(24 n)) of it, under 1 % for a hundred kept samples
NOISE_DRAWS = 24
# the correction leaves at least this share of the noise's energy in the direction of `a` that
# the other regressors do not explain
NOISE_KEEP = 0.1
# sd of a standard normal from the median absolute deviation
MAD_TO_SD = 1.482602218505602
MIN_SAMPLES = 50
# a channel's noise is read where the speed is at least this share of its peak
NOISE_SPEED_SHARE = 0.6


def white_noise_sd(x, where=None) -> float:
    """sd of the white noise on a sampled channel, from its second differences:

        d_t = x_(t+1) - 2 x_t + x_(t-1),   var(d) = 6 sigma^2 for white noise of sd sigma,
        sigma = 1.4826 * median|d - median(d)| / sqrt(6).

    Why second differences: a motion sampled well above its frequency is nearly a straight line
    over three samples, so d is the noise; a 3 Hz sine at 200 Hz still leaves 1 % of its
    amplitude in d, so callers pass the record less its low-pass (prepare_test: at the analysis
    cut-off), which leaves the noise's second differences all but whole. Why the median: the
    friction step of an accelerometer at each velocity reversal puts a few large d per cycle,
    which an ordinary sd would count as noise. Noise that is coloured
    below the sample rate (an anti-alias filter, a slow drift) shows less in d than it holds, so
    this reads low for it, never high.

    where (same length as x): use only the d centred on these samples, when at least
    MIN_SAMPLES of them are marked.
    """
    x = np.asarray(x, dtype=float)
    if x.size < 5:
        return 0.0
    d = x[2:] - 2.0 * x[1:-1] + x[:-2]
    if where is not None:
        chosen = np.asarray(where, dtype=bool)[1:-1]
        if chosen.sum() >= MIN_SAMPLES:
            d = d[chosen]
    return float(MAD_TO_SD * np.median(np.abs(d - np.median(d))) / np.sqrt(6.0))


def mid_stroke_noise_sd(above_band, speed) -> float:
    """white_noise_sd of a channel less its low-pass (above_band), over the samples where the
    speed is at least NOISE_SPEED_SHARE of its peak (the 99.5th percentile of |speed|). Why
    mid-stroke: the friction step and a triangle's turn put the channel's own sharp features
    near the reversals."""
    speed = np.abs(np.asarray(speed, dtype=float))
    return white_noise_sd(above_band, where=speed >= NOISE_SPEED_SHARE * float(np.percentile(speed, 99.5)))
