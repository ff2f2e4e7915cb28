"""The twin's table: the true parameters of one simulated shaking table, and named presets.

A TableTruth holds three kinds of numbers, all SI:

* the force model the identification is after, F_A = Me*a + Ke*u + (Ce*|v|^alpha + Fmu)*sign(v),
  with static friction Fs = static_ratio*Fmu that holds a stopped deck;
* the table's make-up (deck mass, nitrogen struts, oil column), which the component relations
  of bayes_sst.physics turn into Ke, Fmu and f_oil, and which Series.table reports;
* the servo loop (valve lag, displacement and pressure feedback gains) and the table's limits.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from typing import Any, Mapping

from bayes_sst.physics import (
    STANDARD_GRAVITY,
    coulomb_friction,
    friction_load_ratio,
    hold_down_force,
    normal_force,
    oil_column_frequency,
    strut_stiffness,
)


@dataclass(frozen=True, kw_only=True)
class TableTruth:
    """True parameters of a simulated table, SI units.

    Force model: Me (kg), Ke (N/m), Ce (N/(m/s)^alpha), alpha (-), Fmu kinetic friction of
    the empty deck (N), static_ratio = Fs/Fmu >= 1, stribeck_velocity v_s (m/s) over which
    friction falls from Fs to Fmu as exp(-(|v|/v_s)^2).

    Make-up: deck_mass (kg); strut_p0 (Pa), strut_area (m^2), strut_h (m), strut_l0 (m),
    strut_gamma (-) of the four nitrogen struts; bulk_modulus (Pa), piston_area (m^2) and
    oil_volume (m^3, each of the two chambers) of the actuator.

    Servo loop: valve_time_constant (s) of the first-order valve; kp (1/s), the displacement
    feedback gain; kdp (m^3/(s*Pa)), the differential-pressure feedback gain; leakage (1/s),
    the cross-piston leakage rate of the load pressure.

    Limits: stroke (m, half stroke), max_velocity (m/s), max_acceleration (m/s^2),
    max_force (N).

    Effects the base force model leaves out (all off by default; see EFFECT_FIELDS and
    docs/diagnosis.md). static_ratio > 1 is the stiction switch; a smaller bulk_modulus the
    oil column's. The others:

    * cubic_stiffness K'e (N/m): strut spring Ke*u + K'e*(u/h)^2*u, h = strut_h
      (physics.strut_cubic_stiffness gives the gas strut's value; negative, softening, for a
      gas column longer than gamma*h, as long as the spring stays stiffening within the stroke);
    * position_friction Fp (N): hinge friction Fp*(u/h)^2 added to the friction level, so the
      force Fp*(u/h)^2*sign(v);
    * specimen_mass m_s (kg), specimen_frequency f_s (Hz), specimen_damping zeta_s (-): a flexible
      single-degree-of-freedom specimen whose base shear m_s*(a + x'') loads the deck, with
      x'' + 2*zeta_s*w_s*x' + w_s^2*x = -a (x the specimen's drift relative to the deck);
    * force_delay d (s): the force channel records F(t - d);
    * friction_drift, damping_drift (-): Fmu and Ce of the test at campaign position
      s = (order - 1)/(n - 1) are multiplied by (1 - drift*s) (oil warming over the campaign).
    """

    Me: float
    Ke: float
    Ce: float
    alpha: float
    Fmu: float
    static_ratio: float = 1.0
    stribeck_velocity: float = 0.005

    deck_mass: float
    strut_p0: float
    strut_area: float
    strut_h: float
    strut_l0: float
    strut_gamma: float = 1.4
    bulk_modulus: float
    piston_area: float
    oil_volume: float

    valve_time_constant: float
    kp: float
    kdp: float
    leakage: float = 1.0

    stroke: float
    max_velocity: float
    max_acceleration: float
    max_force: float

    cubic_stiffness: float = 0.0
    position_friction: float = 0.0
    specimen_mass: float = 0.0
    specimen_frequency: float = 10.0
    specimen_damping: float = 0.03
    force_delay: float = 0.0
    friction_drift: float = 0.0
    damping_drift: float = 0.0

    def __post_init__(self):
        for name, value in asdict(self).items():
            if not math.isfinite(value):
                raise ValueError(f"TableTruth.{name} must be finite, got {value!r}")
            # a gas column longer than gamma*h softens the struts: K'e < 0 (class docstring)
            if value < 0.0 and name != "cubic_stiffness":
                raise ValueError(f"TableTruth.{name} must not be negative, got {value!r}")
        if self.Ke + 3.0 * self.cubic_stiffness * (self.stroke / self.strut_h) ** 2 <= 0.0:
            raise ValueError(f"TableTruth.cubic_stiffness {self.cubic_stiffness!r} N/m softens the struts to a "
                             f"negative stiffness within the stroke (Ke + 3*K'e*(stroke/h)^2 <= 0)")
        for name in ("Me", "deck_mass", "bulk_modulus", "piston_area", "oil_volume",
                     "valve_time_constant", "stribeck_velocity", "stroke", "specimen_frequency"):
            if getattr(self, name) <= 0.0:
                raise ValueError(f"TableTruth.{name} must be positive, got {getattr(self, name)!r}")
        if not 0.0 < self.alpha <= 1.0:
            # The implicit friction step (see _deck.py) relies on |v|^alpha being concave.
            raise ValueError(f"TableTruth.alpha must lie in (0, 1], got {self.alpha!r}")
        if self.static_ratio < 1.0:
            raise ValueError(f"TableTruth.static_ratio must be >= 1, got {self.static_ratio!r}")
        for name in ("friction_drift", "damping_drift"):
            if getattr(self, name) >= 1.0:
                raise ValueError(f"TableTruth.{name} is a relative fall over the campaign and must be < 1, "
                                 f"got {getattr(self, name)!r}")

    @property
    def active_effects(self) -> dict[str, float]:
        """The effect fields switched on (non-default), by field name."""
        defaults = {"specimen_frequency": 10.0, "specimen_damping": 0.03}
        out = {}
        for name in EFFECT_FIELDS:
            value = getattr(self, name)
            if name in defaults:
                if self.specimen_mass > 0.0:
                    out[name] = value
            elif value != 0.0:
                out[name] = value
        return out

    @property
    def hold_down_force(self) -> float:
        """F_hd = 4*p0*A, N."""
        return hold_down_force(self.strut_p0, self.strut_area)

    @property
    def mu_e(self) -> float:
        """Equivalent friction coefficient mu_e = Fmu/(F_hd + deck_mass*g)."""
        return self.Fmu / normal_force(self.hold_down_force, self.deck_mass)

    def friction_with_payload(self, fmu: float, payload_kg: float) -> float:
        """Fmu_test = Fmu*(F_hd + (m_deck + payload)*g)/(F_hd + m_deck*g): the bearings carry the payload too."""
        return fmu * friction_load_ratio(self.hold_down_force, self.deck_mass, payload_kg)

    def f_oil_hz(self, moving_mass: float | None = None) -> float:
        """Oil-column resonance (1/2pi)*sqrt(2*beta*A_p^2/(V*M)) with M = Me unless given, Hz."""
        mass = self.Me if moving_mass is None else moving_mass
        return oil_column_frequency(self.bulk_modulus, self.piston_area, self.oil_volume, mass, chambers=2)

    def population(self) -> dict[str, float]:
        """The force-model truth of the empty table, as recorded in Series.extra['truth']."""
        return {
            "Me": self.Me,
            "Ke": self.Ke,
            "Ce": self.Ce,
            "alpha": self.alpha,
            "Fmu": self.Fmu,
            "static_ratio": self.static_ratio,
            "f_oil_hz": self.f_oil_hz(),
            **self.active_effects,
        }

    def table_description(self) -> dict[str, Any]:
        """The nominal table in the data format's `table` layout, plus mu_e and limits."""
        return {
            "deck_mass_kg": self.deck_mass,
            "strut": {
                "p0_pa": self.strut_p0,
                "area_m2": self.strut_area,
                "h_m": self.strut_h,
                "l0_m": self.strut_l0,
                "gamma": self.strut_gamma,
            },
            "oil": {
                "bulk_modulus_pa": self.bulk_modulus,
                "piston_area_m2": self.piston_area,
                "oil_volume_m3": self.oil_volume,
            },
            "mu_e": round(self.mu_e, 6),
            "limits": {
                "stroke_m": self.stroke,
                "velocity_m_s": self.max_velocity,
                "acceleration_m_s2": self.max_acceleration,
                "force_n": self.max_force,
            },
        }

    def controller(self) -> dict[str, float]:
        """The servo loop's settings, for the record."""
        return {
            "valve_time_constant_s": self.valve_time_constant,
            "kp_per_s": self.kp,
            "kdp_m3_per_s_pa": self.kdp,
            "leakage_per_s": self.leakage,
        }

    def replace(self, overrides: Mapping[str, float] | None = None) -> "TableTruth":
        """A copy with some fields changed; unknown names raise TypeError."""
        if not overrides:
            return self
        names = set(asdict(self))
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise TypeError(f"unknown TableTruth field(s) {unknown}; known: {sorted(names)}")
        return replace(self, **{k: float(v) for k, v in overrides.items()})


def _sst_paper() -> TableTruth:
    """The Sharif University of Technology table of the reference study.

    Struts: with A = 0.0314 m^2 and mu_e = 1.27 %, Fmu = mu_e*(4*p0*A + m_deck*g) = 12.5 kN
    needs 4*p0*A = 866.6 kN, so p0 = 6.9 MPa; Ke = 4*p0*A/h = 0.72 MN/m then gives
    h = 1.2037 m. Oil: beta = 1.4 GPa and A_p = 0.02 m^2 (420 kN at 21 MPa); the chamber
    volume V = 2*beta*A_p^2/((2*pi*28.6)^2*Me) = 2.6276 L puts f_oil at 28.6 Hz, and is
    what an A_p piston with about 0.13 m of oil on each side holds.

    Servo loop: kp = 20 1/s alone would destabilise the lightly damped oil column (a valve-
    driven actuator needs kp < 2*zeta_h*omega_h); the pressure feedback kdp = 7e-11
    m^3/(s*Pa) gives it a damping ratio of about 0.16, and with the 1.5 ms valve moves the
    closed-loop ringing to about 29.0 Hz, 1.6 % above the open-column f_oil.
    """
    deck_mass = 12000.0
    mu_e = 0.0127
    area = 0.0314
    p0 = 6.9e6
    ke = 0.72e6
    f_hd = hold_down_force(p0, area)
    h = round(f_hd / ke, 5)
    assert abs(strut_stiffness(p0, area, h) / ke - 1.0) < 1e-5
    fmu = coulomb_friction(mu_e, normal_force(f_hd, deck_mass, STANDARD_GRAVITY))
    return TableTruth(
        Me=13200.0,
        Ke=ke,
        Ce=29.6e3,
        alpha=0.5,
        Fmu=round(fmu, 2),
        static_ratio=1.0,
        stribeck_velocity=0.005,
        deck_mass=deck_mass,
        strut_p0=p0,
        strut_area=area,
        strut_h=h,
        strut_l0=0.8,
        strut_gamma=1.4,
        bulk_modulus=1.4e9,
        piston_area=0.02,
        oil_volume=2.6276e-3,
        valve_time_constant=1.5e-3,
        kp=20.0,
        kdp=7e-11,
        leakage=1.0,
        stroke=0.1,
        max_velocity=0.6,
        max_acceleration=12.0,
        max_force=0.02 * 21e6,
    )


# Fields that switch on an effect the base force model leaves out (static_ratio is stiction).
EFFECT_FIELDS = ("cubic_stiffness", "position_friction", "specimen_mass", "specimen_frequency",
                 "specimen_damping", "force_delay", "friction_drift", "damping_drift")

PRESETS: dict[str, TableTruth] = {"sst-paper": _sst_paper()}


def preset_truth(preset: str | TableTruth) -> TableTruth:
    """The TableTruth of a preset name (or the TableTruth itself)."""
    if isinstance(preset, TableTruth):
        return preset
    try:
        return PRESETS[preset]
    except KeyError:
        raise ValueError(f"unknown preset {preset!r}; known: {sorted(PRESETS)}") from None
