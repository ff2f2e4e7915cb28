"""Zero-phase filtering and differentiation of sampled signals."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import signal as _sp_signal

BUTTERWORTH_ORDER = 4


@lru_cache(maxsize=256)
def _butterworth(order: int, relative_cutoff: float) -> np.ndarray:
    return _sp_signal.butter(order, relative_cutoff, btype="low", output="sos")


def _relative_cutoff(cutoff_hz: float, sample_rate_hz: float) -> float:
    """cutoff/Nyquist; the cut-off must lie between 0 and the Nyquist frequency."""
    nyquist = 0.5 * sample_rate_hz
    if not 0.0 < cutoff_hz < nyquist:
        raise ValueError(
            f"low-pass cut-off {cutoff_hz:.4g} Hz must lie between 0 and the Nyquist "
            f"frequency {nyquist:.4g} Hz"
        )
    return float(cutoff_hz / nyquist)


def lowpass_sos(cutoff_hz: float, sample_rate_hz: float, order: int = BUTTERWORTH_ORDER):
    """Second-order sections of a Butterworth low-pass; the cut-off must lie below Nyquist.
    (Designs are cached: a series filters each test's regressors hundreds of times.)"""
    return _butterworth(int(order), _relative_cutoff(cutoff_hz, sample_rate_hz)).copy()  # the cached one stays intact


@lru_cache(maxsize=256)
def _steady_state(order: int, relative_cutoff: float) -> np.ndarray:
    """The sections' state (n_sections, 2) of a unit step held forever (scipy's sosfilt_zi)."""
    return _sp_signal.sosfilt_zi(_butterworth(order, relative_cutoff))


def zero_phase_lowpass(x, cutoff_hz: float, sample_rate_hz: float, *, axis: int = -1):
    """Forward-backward Butterworth low-pass: no phase lag, |H|^2 of the single pass.

    Zero phase matters here because the identification separates forces by their phase
    relative to the motion (dissipative forces lead the displacement by 90 degrees); a causal
    filter's lag would leak inertia into damping.

    The ends: the signal is extended by its odd reflection about each end sample over
    3*(2*n_sections + 1) samples, and each pass starts from the state a constant input at
    the extension's first value would have reached, as scipy.signal.sosfiltfilt does by
    default (same result to rounding). The steady state is computed once per design: the
    diagnosis filters tens of thousands of regressors and the solve was 40 % of the cost.
    """
    x = np.asarray(x, dtype=float)
    key = (BUTTERWORTH_ORDER, _relative_cutoff(cutoff_hz, sample_rate_hz))
    sos = _butterworth(*key)  # the cached design, only read here
    edge = 3 * (2 * len(sos) + 1)
    moved = np.moveaxis(x, axis, -1)
    if moved.shape[-1] <= edge:
        return _sp_signal.sosfiltfilt(sos, x, axis=axis)  # too short: scipy's own message
    ext = np.concatenate([2.0 * moved[..., :1] - moved[..., edge:0:-1], moved,
                          2.0 * moved[..., -1:] - moved[..., -2:-edge - 2:-1]], axis=-1)
    zi = _steady_state(*key).reshape((len(sos),) + (1,) * (ext.ndim - 1) + (2,))
    forward = _sp_signal.sosfilt(sos, ext, axis=-1, zi=zi * ext[..., :1])[0]
    backward = _sp_signal.sosfilt(sos, forward[..., ::-1], axis=-1, zi=zi * forward[..., -1:])[0]
    return np.moveaxis(backward[..., ::-1][..., edge:-edge], -1, axis)


def raised_cosine_step(x) -> np.ndarray:
    """(1 - cos(pi*x))/2 with x clipped to [0, 1]: 0 up to x = 0, 1 from x = 1, a smooth rise
    between (the ramp of the reversal and pre-sliding weights)."""
    return 0.5 - 0.5 * np.cos(np.pi * np.clip(x, 0.0, 1.0))


def time_derivative(x, sample_rate_hz: float, *, axis: int = -1):
    """dx/dt by second-order central differences (one-sided at the ends)."""
    return np.gradient(np.asarray(x, dtype=float), 1.0 / sample_rate_hz, axis=axis)


def running_integral(x, sample_rate_hz: float) -> np.ndarray:
    """The trapezoidal running integral of a 1-D record from its first sample:
    I_0 = 0, I_k = I_(k-1) + (x_(k-1) + x_k)/(2 fs)."""
    x = np.asarray(x, dtype=float)
    return np.concatenate([[0.0], np.cumsum(0.5 * (x[1:] + x[:-1]))]) / sample_rate_hz


def velocity_with_acceleration_above(low_v: np.ndarray, a, sample_rate_hz: float, lowpass) -> np.ndarray:
    """v = low_v + (I - L)(integral of a): a velocity that holds the motion below the low-pass L
    (low_v, already L applied to the velocity) and takes the band above it from the recorded
    acceleration's running integral, which keeps corners L rounds. L must pass a straight line,
    the integral of an accelerometer offset, so that the offset drops out."""
    integral = running_integral(a, sample_rate_hz)
    return low_v + integral - lowpass(integral)


@lru_cache(maxsize=64)
def smoothed_variance(sigma_samples: float) -> float:
    """Variance, in samples^2, of scipy's gaussian_filter1d kernel of sd sigma_samples (sampled
    and truncated at 4 sd, so below sigma_samples^2 when the kernel is a few samples wide)."""
    if sigma_samples <= 0:
        return 0.0
    from scipy.ndimage import gaussian_filter1d

    half = int(4 * sigma_samples + 2)
    impulse = np.zeros(2 * half + 1)
    impulse[half] = 1.0
    weights = gaussian_filter1d(impulse, sigma_samples)
    k = np.arange(-half, half + 1)
    return float(np.sum(weights * k * k) / np.sum(weights))


def acceleration_from_velocity(v, sample_rate_hz: float, smoothing_s: float, differences: int = 2):
    """The acceleration without an accelerometer, from v = D(u smoothed by a Gaussian of sd s):

        a0 = D(v),   a = a0 - k*D(D(a0)),   k = s^2/2 + differences*h^2/6,

    differences: the central differences from the smoothed signal to a0, 2 here (h^2/3); 1
    where v is a recorded velocity smoothed by the kernel (acceleration_of_recorded_velocity),
    each difference adding h^2/6*a''.

    D the central difference (time_derivative), s^2 the variance of the smoothing kernel as
    sampled (smoothed_variance), h = 1/fs.
    Why: smoothing and central differences are symmetric, so the estimate has no lag, but each
    adds a second-derivative term. A Gaussian of sd s turns x into x + s^2/2*x''; v = D(smoothed
    u) followed by D is a second difference over 2h, which reads x'' + (2h)^2/12*x''''. So
    a0 = a + k*a'' to leading order: about 6 % low at 12 Hz sampled at 200 Hz, and most wrong at
    the reversals, where friction steps the acceleration. Subtracting k*a0'' leaves an
    O(s^4, h^4) error. Without the correction the diagnosis claimed a stiff specimen on clean
    series with `a` removed, because a specimen below its resonance adds m_s*(a - a''/w_s^2),
    exactly that term (1.8 t at 22 Hz on the virtual table; 0.85 t at 16 Hz and 3.1 t at 24 Hz
    on an independent generator's series).
    """
    h = 1.0 / sample_rate_hz
    # the sampled, truncated kernel's own variance (0.86 s^2 at s = half a sample), not s^2
    k = smoothed_variance(smoothing_s * sample_rate_hz) * h * h / 2.0 + differences * h * h / 6.0
    a0 = time_derivative(v, sample_rate_hz)
    return a0 - k * time_derivative(time_derivative(a0, sample_rate_hz), sample_rate_hz)


def derived_acceleration(u, sample_rate_hz: float, smoothing_s: float):
    """The acceleration without an accelerometer, along the last axis of u:

        a = acceleration_from_velocity(D(G_s * u)),

    u smoothed by a Gaussian of sd smoothing_s (the fit's velocity kernel), differentiated at
    the recorded rate, differentiated again with the second-order error of both steps taken out.
    Why not the second derivative of the 4f-low-passed u: it smears each reversal over 1/fc; on
    the clean twin without `a` it left 453 N of residual against a 317 N floor and a spurious
    channel delay was selected; on an independent generator's series 1425 N against 239 N.
    """
    from scipy.ndimage import gaussian_filter1d

    smoothed = gaussian_filter1d(np.asarray(u, dtype=float), smoothing_s * sample_rate_hz, axis=-1)
    return acceleration_from_velocity(time_derivative(smoothed, sample_rate_hz), sample_rate_hz, smoothing_s)


def acceleration_of_recorded_velocity(v, sample_rate_hz: float, smoothing_s: float):
    """The acceleration without an accelerometer from a recorded velocity, along v's last axis:

        a = acceleration_from_velocity(G_s * v, differences=1),

    v smoothed by the fit's velocity kernel and differentiated once, the smoothing's and the
    difference's second-order terms, (s^2/2 + h^2/6)*a'', taken out."""
    from scipy.ndimage import gaussian_filter1d

    smoothed = gaussian_filter1d(np.asarray(v, dtype=float), smoothing_s * sample_rate_hz, axis=-1)
    return acceleration_from_velocity(smoothed, sample_rate_hz, smoothing_s, differences=1)


def second_derivative(x, sample_rate_hz: float):
    """d2x/dt2 by the fourth-order five-point stencil,

        x''(t) = [-x(t - 2h) + 16 x(t - h) - 30 x(t) + 16 x(t + h) - x(t + 2h)] / (12 h^2),

    (edges: the second-order three-point stencil; the first and last samples copy their
    neighbour). A sine of frequency f gains (32 cos w - 2 cos 2w - 30)/(-12 w^2), w = 2 pi f h:
    -0.008 % at 6 Hz sampled at 200 Hz, where two second-order first derivatives lose 1.2 %.
    """
    x = np.asarray(x, dtype=float)
    if x.shape[-1] < 5:
        return np.gradient(np.gradient(x, 1.0 / sample_rate_hz), 1.0 / sample_rate_hz)
    h2 = (1.0 / sample_rate_hz) ** 2
    out = np.empty_like(x)
    out[2:-2] = (-x[:-4] + 16.0 * x[1:-3] - 30.0 * x[2:-2] + 16.0 * x[3:-1] - x[4:]) / (12.0 * h2)
    out[1] = (x[0] - 2.0 * x[1] + x[2]) / h2
    out[-2] = (x[-3] - 2.0 * x[-2] + x[-1]) / h2
    out[0], out[-1] = out[1], out[-2]
    return out


def lowpass_power_gain(frequency_hz, cutoff_hz: float, sample_rate_hz: float) -> np.ndarray:
    """|H(f)|^4: the power gain of zero_phase_lowpass at these frequencies (a single pass's
    |H|^2, twice)."""
    sos = _butterworth(BUTTERWORTH_ORDER, _relative_cutoff(cutoff_hz, sample_rate_hz))
    _, response = _sp_signal.sosfreqz(sos, worN=np.asarray(frequency_hz, dtype=float), fs=sample_rate_hz)
    return np.abs(response) ** 4
