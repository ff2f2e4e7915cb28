"""Broadband displacement commands: band-limited random noise and earthquake-like records.

Both are built the same way, so that the recorded command is exactly what the servo loop was
given, with consistent velocity and acceleration:

1. an acceleration shape a0(t) is drawn at the internal rate (white noise shaped in the
   frequency domain; for an earthquake also multiplied by a time envelope);
2. it is integrated twice in the frequency domain, U(f) = -A0(f)*HP(f)/(2*pi*f)^2, with a
   causal 4th-order Butterworth high-pass HP (0.2 Hz) that removes the drift double
   integration would otherwise produce: this is the baseline correction. HP/s^2 is itself a
   causal, stable filter, so an earthquake's displacement starts with its shaking rather
   than seconds before it (as a zero-phase high-pass would make it), and settles after it;
3. the displacement u0 is faded in and out by the raised-cosine envelope e(t) of the periodic
   commands (rest, ramp, hold, ramp, rest), and the velocity and acceleration follow by the
   product rule from the spectral derivatives of u0,

       u = e*u0,  v = e'*u0 + e*u0',  a = e''*u0 + 2*e'*u0' + e*u0'',

   so the command starts and ends at rest and a_cmd is the second derivative of u_cmd, not
   the raw shape a0;
4. everything is scaled so that max|a| equals the requested peak acceleration.

Signals:

* 'noise': Gaussian noise whose acceleration spectrum is flat between band_hz[0] and
  band_hz[1] (a 4th-order Butterworth-shaped high-pass and low-pass in magnitude), so that
  the acceleration excites every frequency up to ~50 Hz evenly while the displacement stays
  small (its spectrum falls as f^-2). The default band is 1-50 Hz.
* 'earthquake': Kanai-Tajimi-filtered white noise (ground frequency 2.5 Hz, damping 0.6)
  with a Clough-Penzien high-pass (0.25 Hz) and the same 50 Hz low-pass, multiplied by a
  Jennings-type envelope over the record between the fade-in and fade-out: (t/t1)^2 rising
  over its first 10 %, flat up to 40 %, then exp(-c*(t - t2)) decaying to e^-5 at its end.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import butter, freqs

from bayes_sst.twin._command import Command, raised_cosine_envelope

BROADBAND_SIGNALS = ("noise", "earthquake")
DEFAULT_BROADBAND_DURATION_S = {"noise": 60.0, "earthquake": 30.0}
DEFAULT_PEAK_ACCELERATION = {"noise": 10.0, "earthquake": 1.0}
DEFAULT_BAND_HZ = (1.0, 50.0)
DEFAULT_TAPER_S = 1.0
# Kanai-Tajimi ground filter (Tajimi's firm-soil values) and Clough-Penzien high-pass.
KT_FREQUENCY_HZ = 2.5
KT_DAMPING = 0.6
CP_FREQUENCY_HZ = 0.25
CP_DAMPING = 0.6
# Baseline correction: high-pass applied to the displacement, as a Butterworth magnitude.
BASELINE_HIGHPASS_HZ = 0.2
BUTTERWORTH_ORDER = 4


def _highpass(f: np.ndarray, corner: float, order: int = BUTTERWORTH_ORDER) -> np.ndarray:
    """Butterworth high-pass magnitude |HP(f)| = r^n/sqrt(1 + r^2n), r = f/corner (zero phase)."""
    r = f / corner
    return r**order / np.sqrt(1.0 + r ** (2 * order))


def _causal_highpass(f: np.ndarray, corner: float, order: int = BUTTERWORTH_ORDER) -> np.ndarray:
    """Complex response of the analog Butterworth high-pass (causal), at frequencies f (Hz)."""
    b, a = butter(order, 2.0 * math.pi * corner, btype="highpass", analog=True)
    return freqs(b, a, 2.0 * math.pi * np.asarray(f, dtype=float))[1]


def _lowpass(f: np.ndarray, corner: float, order: int = BUTTERWORTH_ORDER) -> np.ndarray:
    """Butterworth low-pass magnitude 1/sqrt(1 + (f/corner)^2n) (zero phase)."""
    return 1.0 / np.sqrt(1.0 + (f / corner) ** (2 * order))


def kanai_tajimi(f: np.ndarray, f_g: float = KT_FREQUENCY_HZ, zeta_g: float = KT_DAMPING,
                 f_f: float = CP_FREQUENCY_HZ, zeta_f: float = CP_DAMPING) -> np.ndarray:
    """Kanai-Tajimi ground filter times the Clough-Penzien high-pass, complex, at frequencies f (Hz).

    H_KT = (wg^2 + 2j*zg*wg*w)/(wg^2 - w^2 + 2j*zg*wg*w),  H_CP = w^2/(wf^2 - w^2 + 2j*zf*wf*w).
    """
    w = 2.0 * math.pi * np.asarray(f, dtype=float)
    wg, wf = 2.0 * math.pi * f_g, 2.0 * math.pi * f_f
    kt = (wg**2 + 2j * zeta_g * wg * w) / (wg**2 - w**2 + 2j * zeta_g * wg * w)
    cp = w**2 / (wf**2 - w**2 + 2j * zeta_f * wf * w)
    return kt * cp


def jennings_envelope(t: np.ndarray, duration: float) -> np.ndarray:
    """Jennings-type envelope on [0, duration]: (t/t1)^2, then 1, then exp(-c*(t - t2)).

    t1 = 0.1*duration, t2 = 0.4*duration, c = 5/(duration - t2); zero outside [0, duration].
    """
    t1, t2 = 0.1 * duration, 0.4 * duration
    c = 5.0 / (duration - t2)
    env = np.where(t < t1, (np.clip(t, 0.0, None) / t1) ** 2, 1.0)
    env = np.where(t > t2, np.exp(-c * (t - t2)), env)
    return np.where((t < 0.0) | (t > duration), 0.0, env)


def broadband_duration(duration_s: float, *, rest_s: float) -> float:
    """Length of a broadband test's record: rest, the signal (tapers included), rest, s."""
    return 2.0 * rest_s + duration_s


def broadband_command(
    signal: str,
    t,
    *,
    rng: np.random.Generator,
    duration_s: float,
    peak_acceleration: float,
    rest_s: float,
    band_hz: tuple[float, float] = DEFAULT_BAND_HZ,
    taper_s: float = DEFAULT_TAPER_S,
) -> Command:
    """A broadband command at the uniform times t (s, from 0), as described in the module.

    The signal occupies [rest_s, rest_s + duration_s], faded in and out over taper_s; the
    table rests elsewhere. max|a| equals peak_acceleration (m/s^2).
    """
    if signal not in BROADBAND_SIGNALS:
        raise ValueError(f"unknown broadband signal {signal!r}; use one of {BROADBAND_SIGNALS}")
    t = np.asarray(t, dtype=float)
    n = t.shape[0]
    if n < 4:
        raise ValueError("a broadband command needs at least four samples")
    dt = float(t[1] - t[0])
    if not (duration_s > 2.0 * taper_s and peak_acceleration > 0.0):
        raise ValueError(f"need duration_s > 2*taper_s ({2 * taper_s} s) and peak_acceleration > 0, "
                         f"got {duration_s!r}, {peak_acceleration!r}")
    low, high = band_hz
    if not 0.0 < low < high < 0.5 / dt:
        raise ValueError(f"band_hz must satisfy 0 < low < high < Nyquist, got {band_hz!r}")
    # Pad to a length of whole record plus 50 % so that the circular integration wraps
    # into silence rather than into the start of the record.
    n_fft = int(2 ** math.ceil(math.log2(1.5 * n)))
    f = np.fft.rfftfreq(n_fft, dt)
    white = rng.standard_normal(n_fft)
    local = np.arange(n_fft) * dt - rest_s
    if signal == "noise":
        shape = _highpass(f, low) * _lowpass(f, high)
        a0 = np.fft.rfft(white) * shape
    else:
        shaped = np.fft.irfft(np.fft.rfft(white) * kanai_tajimi(f) * _lowpass(f, high), n_fft)
        # The shaking starts once the fade-in is over, so the fade-in meets a table at rest.
        strong = duration_s - 2.0 * taper_s
        a0 = np.fft.rfft(shaped * jennings_envelope(local - taper_s, strong))
    w = 2.0 * math.pi * f
    with np.errstate(divide="ignore", invalid="ignore"):
        u_spec = np.where(f > 0.0, -a0 * _causal_highpass(f, BASELINE_HIGHPASS_HZ) / w**2, 0.0)
    u0 = np.fft.irfft(u_spec, n_fft)[:n]
    v0 = np.fft.irfft(1j * w * u_spec, n_fft)[:n]
    acc0 = np.fft.irfft(-(w**2) * u_spec, n_fft)[:n]
    e, de, d2e = raised_cosine_envelope(t - rest_s, taper_s, duration_s - 2.0 * taper_s)
    u = e * u0
    v = de * u0 + e * v0
    a = d2e * u0 + 2.0 * de * v0 + e * acc0
    scale = peak_acceleration / float(np.max(np.abs(a)))
    return Command(t, u * scale, v * scale, a * scale)
