"""EffectData: one periodic test as the effect library sees it (pure arrays, no I/O).

Two sample sets: the full-rate stretch [lo, hi) of the record around the steady window
(filtered at `cutoff_hz`), from which effect regressors are built and filtered exactly like
the force, and the kept samples `index` (absolute record indices, decimated) at which the
likelihood is evaluated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

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
        return self.F_full[self.kept]

    def filtered(self, values: np.ndarray) -> np.ndarray:
        """filter(g)[kept] for a full-rate regressor g (last axis time): treated like the force."""
        return zero_phase_lowpass(values, self.cutoff_hz, self.sample_rate_hz, axis=-1)[..., self.kept]

    def filtered_full(self, values: np.ndarray) -> np.ndarray:
        """filter(g) at every full-rate sample."""
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
        """The filtered force read shift_s later than the kept instants, F(t + shift), by linear interpolation."""
        position = self.kept + shift_s * self.sample_rate_hz
        return np.interp(position, np.arange(len(self.F_full)), self.F_full)
