"""Sensor noise levels read off a recorded channel."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from bayes_sst.signals._cycles import fourier_columns

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


# binomial difference stencils: d = sum_k c_k x_(t+k) has var(d) = sum c_k^2 sigma^2 for white
# noise of sd sigma, and passes a component of angular frequency w (rad/sample) with gain
# (2 sin(w/2))^order
DIFFERENCE_STENCILS = {2: (1.0, -2.0, 1.0), 4: (1.0, -4.0, 6.0, -4.0, 1.0)}


def white_noise_sd(x, where=None, order: int = 2) -> float:
    """sd of the white noise on a sampled channel, from its differences of the given order
    (2 or 4); for order 2:

        d_t = x_(t+1) - 2 x_t + x_(t-1),   var(d) = 6 sigma^2 for white noise of sd sigma,
        sigma = 1.4826 * median|d - median(d)| / sqrt(6);

    order 4 uses (1, -4, 6, -4, 1), var(d) = 70 sigma^2.

    Why second differences: a motion sampled well above its frequency is nearly a straight line
    over three samples, so d is the noise; a 3 Hz sine at 200 Hz still leaves 1 % of its
    amplitude in d, so callers pass the record less its low-pass (prepare_test: at the analysis
    cut-off), which leaves the noise's second differences all but whole. Why the median: the
    friction step of an accelerometer at each velocity reversal puts a few large d per cycle,
    which an ordinary sd would count as noise. Noise that is coloured
    below the sample rate (an anti-alias filter, a slow drift) shows less in d than it holds, so
    this reads low for it, never high.

    Why order 4: the motion a record keeps above the analysis band (a servo loop's and an oil
    column's response, tens of Hz) is real, and the force carries it too; a second difference
    at 200 Hz passes a 30 Hz component at 0.34 of its noise-normalised gain, a fourth at 0.08.
    Measured on the fastest quarter of the tests (2-3 Hz at 200 Hz): order 2 read the virtual
    table's 0.030 m/s^2 as 0.037-0.046 and an independent simulator's 0.079 as 0.196, order 4 as
    0.031-0.032 and 0.088; at 500-1024 Hz both read within 1.5 %.

    where (same length as x): use only the d centred on these samples, when at least
    MIN_SAMPLES of them are marked.
    """
    if order not in DIFFERENCE_STENCILS:
        raise ValueError(f"white_noise_sd: order must be one of {sorted(DIFFERENCE_STENCILS)}, got {order!r}")
    stencil = np.asarray(DIFFERENCE_STENCILS[order])
    x = np.asarray(x, dtype=float)
    if x.size < 5:
        return 0.0
    width = len(stencil)
    # summed from the last tap: for order 2 this is x[2:] - 2 x[1:-1] + x[:-2] as it always was
    d = sum(c * x[k : x.size - width + 1 + k] for k, c in reversed(list(enumerate(stencil))))
    if where is not None:
        half = width // 2
        chosen = np.asarray(where, dtype=bool)[half : x.size - half]
        if chosen.sum() >= MIN_SAMPLES:
            d = d[chosen]
    return float(MAD_TO_SD * np.median(np.abs(d - np.median(d))) / np.sqrt(np.sum(stencil**2)))


def mid_stroke_noise_sd(above_band, speed, order: int = 2) -> float:
    """white_noise_sd (differences of the given order) of a channel less its low-pass
    (above_band), over the samples where the speed is at least NOISE_SPEED_SHARE of its peak
    (the 99.5th percentile of |speed|). Why mid-stroke: the friction step and a triangle's turn
    put the channel's own sharp features near the reversals."""
    speed = np.abs(np.asarray(speed, dtype=float))
    return white_noise_sd(above_band, where=speed >= NOISE_SPEED_SHARE * float(np.percentile(speed, 99.5)),
                          order=order)


# coloured-noise estimate (coloured_noise_excess): read bins on each side of a bin in its
# running median, and how far above the white level the band's median must stand, in its own
# sampling sds, before the excess counts
EXCESS_SMOOTHING_BINS = 3
# bins next to a harmonic (or to zero) left out of the estimate: the motion's slow amplitude
# and phase drift from cycle to cycle puts sidebands there
HARMONIC_GUARD_BINS = 2.5
LN2 = 0.6931471805599453
EXCESS_SIGNIFICANCE = 3.0


class NoiseSpectrum(NamedTuple):
    """Noise in a channel beyond its white level: excess[k] is the extra power (units^2 per
    periodogram bin, E|rfft(x)|^2/N) at frequency k*step_hz; zero above the band read."""

    step_hz: float
    excess: np.ndarray

    def draws(self, n_draws: int, length: int, sample_rate_hz: float, rng) -> np.ndarray:
        """(n_draws, length) Gaussian noise with this spectrum: X_k = sqrt(s(f_k) L/2)(g1 + i g2),
        x = irfft(X), so that E|X_k|^2/L = s(f_k)."""
        freq = np.fft.rfftfreq(length, 1.0 / sample_rate_hz)
        grid = np.arange(len(self.excess)) * self.step_hz
        power = np.interp(freq, grid, self.excess, right=0.0)
        scale = np.sqrt(power * length / 2.0)
        spectrum = scale * (rng.standard_normal((n_draws, len(freq))) + 1j * rng.standard_normal((n_draws, len(freq))))
        spectrum[:, 0] = 0.0
        return np.fft.irfft(spectrum, n=length, axis=-1)


def _readable_bins(n: int, period_samples: float, cutoff_hz: float, sample_rate_hz: float, band_gain):
    """What coloured_noise_excess reads of a record of n samples: (harmonics up to the cut-off,
    periodogram bins, the low-pass's power gain there, the bins read: in band, away from the
    harmonics and half-harmonics), or None when fewer than 4 bins are left (a record of 6 or
    fewer cycles, or too short for its harmonics' fit). It depends on the record's length and
    rates only."""
    frequency = sample_rate_hz / period_samples
    harmonics = int(np.floor(cutoff_hz / frequency + 1e-9))
    if n < 24 * (harmonics + 1):
        return None
    bins = np.arange(n // 2 + 1)
    gain = np.asarray(band_gain(bins * sample_rate_hz / n), dtype=float)
    cycles = n / period_samples
    harmonic_bins = np.arange(0, harmonics + 1) * cycles
    offset = np.min(np.abs(bins[:, None] - harmonic_bins[None, :]), axis=1)
    # half-harmonics too: a period that is close to a whole number of half samples samples
    # the steps of every other cycle alike, which puts aliased lines at (k + 1/2) f
    valid = (gain >= 0.5) & (offset > HARMONIC_GUARD_BINS) & (np.abs(offset - 0.5 * cycles) > 0.5)
    return None if valid.sum() < 4 else (harmonics, bins, gain, valid)


def coloured_noise_excess(x, period_samples: float, cutoff_hz: float, sample_rate_hz: float,
                          white_sd: float, band_gain, covariates=()) -> NoiseSpectrum | None:
    """The noise of a periodic record below cutoff_hz that its white level does not account
    for, or None when there is none to speak of.

    x is the record low-passed at cutoff_hz over whole steady cycles of period_samples, and
    band_gain(f) the low-pass's power gain. The motion is periodic in a steady window, so x less
    its harmonics, r = x - c0(t) - sum_k (c_k(t) cos k*phi + s_k(t) sin k*phi) (least squares,
    k*f <= fc, each c(t) a quadratic in time to take up a slow drift of the motion's amplitude
    and phase), is noise, but for what the motion itself does beyond its harmonics: the
    covariates (a sequence of arrays, or a function giving one, called only when some bin can
    be read; for the accelerometer, the low-passed force and displacement, the displacement's
    second derivative (the motion the displacement transducer records too), and the sampled
    sign(v), which aliases as its friction step does: sampled without an anti-alias filter, a
    step folds its harmonics above the Nyquist frequency back into the band, at frequencies
    that are not the test's harmonics) are columns of the fit too. Its periodogram I_k = |rfft(r)|^2/N divided
    by G(f_k), read away from the bins of the harmonics and half-harmonics, its running median
    over EXCESS_SMOOTHING_BINS read bins on each side divided by ln 2 (the median of an
    exponential variable; medians leave out the odd aliased line), less white_sd^2, is the
    excess. Why: an accelerometer drifts (1/f noise, thermal drift), and such noise sits at
    the slow tests' fundamental and harmonics, where the white level read mid-stroke from
    second differences does not see it. Left uncorrected, it biased one independently written
    simulator's sine tests' Me 20-40 % low (errors in variables), the fitted between-test
    spread of Me up to 18 %, and the shared-Me refit that followed put Me +3.9 % at 26 sds.
    None unless the median of I_k/(white_sd^2 G(f_k)) over the read bins exceeds ln 2 by
    EXCESS_SIGNIFICANCE of its own sampling sds (1/sqrt(bins)), so that white noise keeps the
    white treatment; a drift that stays below a fast test's fundamental is then not read, and
    it matters least there, where the motion's own acceleration is largest.
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    read = _readable_bins(n, period_samples, cutoff_hz, sample_rate_hz, band_gain)
    if read is None or white_sd <= 0.0:
        return None
    harmonics, bins, gain, valid = read
    if callable(covariates):  # built only now, when something can be read
        covariates = covariates()
    harmonic = fourier_columns(2.0 * np.pi * np.arange(n) / period_samples, harmonics)
    position = np.linspace(-1.0, 1.0, n)[:, None]
    design = np.column_stack([harmonic, harmonic * position, harmonic * (1.5 * position**2 - 0.5)]
                             + [np.asarray(c, dtype=float) for c in covariates])
    design = design / np.maximum(np.sqrt(np.mean(design**2, axis=0)), 1e-300)
    # normal equations (the columns are scaled and far from collinear; an SVD per test was 80 %
    # of the signal treatment's time on a 200-test series)
    gram = design.T @ design
    gram += 1e-10 * np.trace(gram) / gram.shape[0] * np.eye(gram.shape[0])
    residual = x - design @ np.linalg.solve(gram, design.T @ x)
    periodogram = np.abs(np.fft.rfft(residual)) ** 2 / n
    step = sample_rate_hz / n
    own = periodogram / np.maximum(gain, 1e-12)
    white = white_sd**2
    # medians, so that the odd aliased line the covariates miss does not count as noise: a
    # periodogram bin of white noise is white*Exp(1), whose median is white*ln 2, and the
    # median of m of them has an sd of about white/sqrt(m)
    if np.median(own[valid]) / white <= LN2 + EXCESS_SIGNIFICANCE / np.sqrt(valid.sum()):
        return None
    chosen = np.flatnonzero(valid)
    medians = [np.median(own[chosen[max(0, i - EXCESS_SMOOTHING_BINS): i + EXCESS_SMOOTHING_BINS + 1]])
               for i in range(chosen.size)]
    smoothed = np.interp(bins, chosen, np.asarray(medians) / LN2)
    excess = np.where(bins * step <= cutoff_hz, np.maximum(smoothed - white, 0.0), 0.0)
    return NoiseSpectrum(step, excess)
