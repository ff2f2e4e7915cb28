"""Per-test statistics of a hysteresis loop: RMS force, peak force, energy dissipated per cycle.

These are what a shaking-table engineer looks at in a loop, and they are computed the same way
for the measured force and for every posterior-predictive replication, so that comparing
them (posterior-predictive p-values) is fair whatever the sampling of the loop.
"""

from __future__ import annotations

import numpy as np

from bayes_sst.signals import fourier_columns

LOOP_HARMONICS = 3


def rms_force(force: np.ndarray) -> np.ndarray:
    """sqrt(mean(F^2)) over the last axis, N."""
    force = np.asarray(force, dtype=float)
    return np.sqrt(np.mean(force**2, axis=-1))


def peak_force(force: np.ndarray) -> np.ndarray:
    """max |F| over the last axis, N."""
    return np.max(np.abs(np.asarray(force, dtype=float)), axis=-1)


def loop_energy(t, force, displacement, frequency_hz: float, *, harmonics: int = LOOP_HARMONICS) -> np.ndarray:
    """Energy dissipated per cycle, the area of the F-u loop: E = closed integral of F du, J.

    Both signals are fitted by least squares with a Fourier series of the test frequency f,

        x(t) = c0 + sum_{k=1..K} [a_k cos(k w t) + b_k sin(k w t)],   w = 2 pi f,

    and the integral over one period then has the closed form

        E = integral_0^T F du/dt dt = pi * sum_k k (a_k^F b_k^u - b_k^F a_k^u).

    For an ellipse F = F0 sin(w t + d), u = u0 sin(w t) this is pi F0 u0 sin(d). The fit
    averages over all steady cycles and needs no whole number of samples per cycle (the
    likelihood's samples are decimated to about 8 per cycle, and a polygon through 8 points
    of a loop would miss about a tenth of its area). K = 3 by default: the force is low-passed
    at 4f, so the 4th harmonic and above are mostly gone.

    force may carry leading axes (draws); t and displacement are 1-D over the same samples.
    Positive E means the loop is run clockwise in the F-u plane: the table's force does work
    on the deck, which dissipates it.
    """
    t = np.asarray(t, dtype=float)
    design = fourier_columns(2.0 * np.pi * frequency_hz * np.asarray(t, dtype=float), harmonics)
    if design.shape[0] < design.shape[1]:
        raise ValueError(
            f"{design.shape[0]} samples cannot resolve {harmonics} harmonics of {frequency_hz:g} Hz; "
            f"at least {design.shape[1]} are needed"
        )
    solve = np.linalg.pinv(design)  # (2K+1, n)
    cu = solve @ np.asarray(displacement, dtype=float)
    cf = np.asarray(force, dtype=float) @ solve.T  # (..., 2K+1)
    k = np.arange(1, harmonics + 1)
    a_u, b_u = cu[1::2], cu[2::2]
    a_f, b_f = cf[..., 1::2], cf[..., 2::2]
    return np.pi * np.sum(k * (a_f * b_u - b_f * a_u), axis=-1)
