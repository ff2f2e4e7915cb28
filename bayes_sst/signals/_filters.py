"""Zero-phase filtering and differentiation of sampled signals."""

from __future__ import annotations

import numpy as np
from scipy import signal as _sp_signal

BUTTERWORTH_ORDER = 4


def lowpass_sos(cutoff_hz: float, sample_rate_hz: float, order: int = BUTTERWORTH_ORDER):
    """Second-order sections of a Butterworth low-pass; the cut-off must lie below Nyquist."""
    nyquist = 0.5 * sample_rate_hz
    if not 0.0 < cutoff_hz < nyquist:
        raise ValueError(
            f"low-pass cut-off {cutoff_hz:.4g} Hz must lie between 0 and the Nyquist "
            f"frequency {nyquist:.4g} Hz"
        )
    return _sp_signal.butter(order, cutoff_hz / nyquist, btype="low", output="sos")


def zero_phase_lowpass(x, cutoff_hz: float, sample_rate_hz: float, *, axis: int = -1):
    """Forward-backward Butterworth low-pass: no phase lag, |H|^2 of the single pass.

    Zero phase matters here because the identification separates forces by their phase
    relative to the motion (dissipative forces lead the displacement by 90 degrees); a causal
    filter's lag would leak inertia into damping.
    """
    sos = lowpass_sos(cutoff_hz, sample_rate_hz)
    return _sp_signal.sosfiltfilt(sos, np.asarray(x, dtype=float), axis=axis)


def time_derivative(x, sample_rate_hz: float, *, axis: int = -1):
    """dx/dt by second-order central differences (one-sided at the ends)."""
    return np.gradient(np.asarray(x, dtype=float), 1.0 / sample_rate_hz, axis=axis)
