"""EffectData: one periodic test as the effect library sees it (pure arrays, no I/O).

Two sample sets: the full-rate stretch [lo, hi) of the record around the steady window
(filtered at `cutoff_hz`), from which effect regressors are built and filtered exactly like
the force, and the kept samples `index` (absolute record indices, decimated) at which the
likelihood is evaluated.

With a reversal weight w (bayes_sst.signals.reversal_weight), the force and every regressor
are multiplied by w before the low-pass, as in the fit: filter(w*F) = Me*filter(w*a) +
Ke*filter(w*u) + ... stays exact, and the table's rest at each reversal, where the Coulomb
step is not the physics, never reaches the kept samples. The unweighted filtered u, v, a stay
available as the inputs of nonlinear regressors (u^3, the specimen's response) and for
locating the residual.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage as _ndimage

from bayes_sst.signals import zero_phase_lowpass


@dataclass(frozen=True)
class EffectData:
    """A periodic test for the effect library, SI units.

    id, frequency_hz, amplitude_m, payload_kg; position: campaign position s in [0, 1]
    ((order - first)/(last - first)); strut_h: the strut height h (m) of the table;
    sample_rate_hz, cutoff_hz; lo: record index of the first full-rate sample held;
    index: record indices of the kept samples; u_full, v_full, a_full, F_full: filtered
    full-rate displacement, velocity, acceleration and force over [lo, lo + len);
    a_record: the recorded (unfiltered) acceleration from the record's start to lo + len, so
    that a dynamic effect can be run from rest (a_raw is its part over [lo, lo + len));
    period_samples: the test's period in samples; friction_load: N_test/N_empty, the factor of
    the Coulomb regressor (bayes_sst.signals.friction_load: a payload loads the bearings).
    With a reversal weight: weight_full, w over [lo, lo + len); F_full is then filter(w*F);
    u_model_full, a_model_full are filter(w*u), filter(w*a) (None: u_full, a_full); F_raw is
    the unfiltered force over [lo, lo + len), for re-reading it at a shifted time.
    """

    id: str
    frequency_hz: float
    amplitude_m: float
    payload_kg: float
    position: float
    strut_h: float
    sample_rate_hz: float
    cutoff_hz: float
    lo: int
    index: np.ndarray
    u_full: np.ndarray
    v_full: np.ndarray
    a_full: np.ndarray
    F_full: np.ndarray
    a_record: np.ndarray
    period_samples: float
    friction_load: float = 1.0
    notes: tuple[str, ...] = ()  # what the signal treatment set aside (PreparedTest.notes)
    weight_full: np.ndarray | None = None
    # (K, len(F_full)) draws of the accelerometer's white noise over [lo, lo + len), as recorded
    # (before the weight and the low-pass), for the errors-in-variables correction; None: none known
    a_noise_full: np.ndarray | None = None
    u_model_full: np.ndarray | None = None
    a_model_full: np.ndarray | None = None
    F_raw: np.ndarray | None = None
    # False: no usable accelerometer, a is derived from u (signals.acceleration_from_velocity)
    acceleration_measured: bool = True

    @property
    def a_raw(self) -> np.ndarray:
        return self.a_record[self.lo:]

    @property
    def kept(self) -> np.ndarray:
        """Positions of the kept samples in the full-rate arrays."""
        return self.index - self.lo

    @property
    def u(self) -> np.ndarray:
        return self.u_full[self.kept]

    @property
    def v(self) -> np.ndarray:
        return self.v_full[self.kept]

    @property
    def a(self) -> np.ndarray:
        return self.a_full[self.kept]

    @property
    def F(self) -> np.ndarray:
        """The modelled force, filter(w*F), at the kept samples."""
        return self.F_full[self.kept]

    @property
    def model_u_full(self) -> np.ndarray:
        """filter(w*u), the displacement regressor, at every full-rate sample."""
        return self.u_full if self.u_model_full is None else self.u_model_full

    @property
    def model_a_full(self) -> np.ndarray:
        """filter(w*a), the acceleration regressor, at every full-rate sample."""
        return self.a_full if self.a_model_full is None else self.a_model_full

    @property
    def model_u(self) -> np.ndarray:
        return self.model_u_full[self.kept]

    @property
    def model_a(self) -> np.ndarray:
        return self.model_a_full[self.kept]

    def filtered(self, values: np.ndarray) -> np.ndarray:
        """filter(w*g)[kept] for a full-rate regressor g (last axis time): treated like the force."""
        return self.filtered_full(values)[..., self.kept]

    def filtered_full(self, values: np.ndarray) -> np.ndarray:
        """filter(w*g) at every full-rate sample."""
        if self.weight_full is not None:
            values = values * self.weight_full
        return zero_phase_lowpass(values, self.cutoff_hz, self.sample_rate_hz, axis=-1)

    def damping_full(self, alpha: float) -> np.ndarray:
        """filter(|v|^alpha sign v) at every full-rate sample."""
        return self.filtered_full(np.abs(self.v_full) ** alpha * np.sign(self.v_full))

    def sign_full(self) -> np.ndarray:
        """friction_load*filter(sign v) at every full-rate sample: the Coulomb regressor of the
        empty table's Fmu."""
        return self.friction_load * self.filtered_full(np.sign(self.v_full))

    def damping(self, alpha: float) -> np.ndarray:
        """damping_full(alpha) at the kept samples."""
        return self.damping_full(alpha)[self.kept]

    def sign(self) -> np.ndarray:
        """sign_full() at the kept samples."""
        return self.sign_full()[self.kept]

    def force_at(self, shift_s: float) -> np.ndarray:
        """The modelled force read shift_s later, filter(w(t)*F(t + shift)) at the kept instants
        (F(t + shift) by cubic spline through the raw force; without a weight, the filtered force
        interpolated linearly)."""
        grid = np.arange(len(self.F_full))
        if self.weight_full is None or self.F_raw is None:
            return np.interp(self.kept + shift_s * self.sample_rate_hz, grid, self.F_full)
        # a cubic spline, not linear interpolation: the raw force carries content up to the
        # Nyquist frequency, which linear interpolation damps by a fraction that varies with
        # the shift (it acts as a low-pass that moves with d)
        shifted = _ndimage.shift(self.F_raw, -shift_s * self.sample_rate_hz, order=3, mode="nearest")
        return self.filtered(shifted)
