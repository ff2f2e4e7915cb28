"""Priors of the force model, on physical scales.

Population values (Gaussian, so they can be integrated out exactly):

    Me ~ N(c_Me, (s*c_Me)^2), Ke ~ N(c_Ke, (s*c_Ke)^2), Ce ~ N(c_Ce, (s*c_Ce)^2),
    Fmu ~ N(c_Fmu, (s*c_Fmu)^2)

with centres c and relative width s. The generic centres describe a mid-size
servo-hydraulic table (10 t, 1 MN/m, 20 kN/(m/s)^alpha, 10 kN) with s = 1: a factor of a
few either way is a priori plausible and the data decide. With prior="physics" the centres
come from the series' `table` description through the study's component relations
(Me ~ deck mass plus the actuator's moving mass, Ke = 4*p0*A/h, Fmu = mu_e*(F_hd + m*g))
and s = 0.5; physics_prior_report lists each centre with the relation and inputs used.

`table` keys read (all optional, SI):

    deck_mass_kg                          mass of the deck on its bearings
    actuator_mass_kg                      actuator's moving mass (piston, rod, swivel)
      or actuator.moving_mass_kg
    moving_parts_kg                       further moving mass: a number or {name: kg}
    moving_mass_kg                        the total moving mass, overriding the three above
    strut.p0_pa, strut.area_m2, strut.h_m pre-charge, area and height of the four struts
    strut.gamma, strut.l0_m               polytropic exponent (1.4 if absent), gas column
    mu_e or bearing_friction              bearing friction coefficient (a number, or
                                          {"mu": ...}); 0.01 if absent

    alpha ~ N(0.75, 0.5^2) truncated to [0.05, 1.95]   (0.5 turbulent orifice flow, 1 laminar)
    rho_k ~ LogNormal(log 0.03, 1)   between-test sd of each coefficient, relative to its
                               centre (90 % prior mass from 0.6 % to 15 %); a coefficient
                               in spread_by_coefficient has its own (median, log sd)
    kappa ~ N(1, 4^2) truncated to [0, 15]   the payload's friction gain: how much of the
                               friction increase the table description predicts for a test
                               under payload (signals.friction_load) is real; sampled only
                               where the series has tests under different bearing loads
    tau ~ LogNormal(log 0.02, 1)   between-test sd of the damping exponent, where asked for
                               (alpha_spread, fit --per-test-alpha): test j's damping is
                               Ce_j |v|^(alpha + delta_j) sign v, delta_j ~ N(0, tau^2), to first
                               order in delta_j (90 % prior mass from 0.004 to 0.1)
    phi_j ~ U(-0.999, 0.999)   AR(1) coefficient of test j's residual
    sigma_j ~ LogNormal(log(0.05 F_rms), 2)   innovation sd of test j

Why kappa, and why so wide: Fmu = mu_e*N, and the study's N includes the hold-down force
(N = F_hd + m g), so a 5 t payload raises the SST's friction by 5 %; a table (or a simulator)
whose bearings do not carry the struts' hold-down force raises it by 38 %, one whose friction
does not depend on the load not at all. With the description's ratio taken as exact, the
payload tests' extra friction went into the population Fmu: on 30 series of the LuGre
generator (friction proportional to the weight alone, kappa 1.34-1.91 in the description's
terms) Fmu came out 0-6 % high and its 90 % interval covered the truth in 73 % of them.
The range 0-15 spans all three cases for hold-down forces up to 14 times the deck's weight.

Why tau, and why not by default: a real table's damping is a power law only approximately, so
tests that sweep different speed ranges may read different exponents, and with one exponent
shared by all tests the population alpha is as sure as if they agreed; tau widens alpha by what
the tests' disagreement shows. Measured (docs/measurements.md, Known limitations): on 40 series of an
independently written simulator whose alpha and Fmu intervals came out some 20 % too narrow (over
80 series, 6-7 %), tau came out near 0.007 and moved alpha's z sd only from 1.2 to 1.15, so its
tests agree; on the virtual table it leaves the calibration in 85-95 %, but it costs a 200-test
fit 11 -> 15 s cold.

Why a log-normal and not a half-normal for rho: no real table repeats a test exactly (oil
temperature, seal wear, mounting), so a spread of exactly zero is not a plausible value, and
a prior that piles up at zero gives the sampler a funnel in log(rho) wherever the data
cannot tell 0.1 % from 1 %. With HalfNormal(0.1) about one fit in twelve on the virtual
table ended with divergences or R-hat above 1.01 (a chain stuck at rho_Ce near 0.1 %).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Mapping

import numpy as np

from bayes_sst.inference._statistics import ALPHA_MAX, ALPHA_MIN, COEFFICIENTS
from bayes_sst.io import positive_or_none
from bayes_sst.physics import (
    STANDARD_GRAVITY,
    coulomb_friction,
    hold_down_force,
    normal_force,
    strut_cubic_stiffness,
    strut_stiffness,
)

GENERIC_CENTRES = {"Me": 10_000.0, "Ke": 1.0e6, "Ce": 20_000.0, "Fmu": 10_000.0}
DEFAULT_FRICTION_COEFFICIENT = 0.01
DEFAULT_GAS_EXPONENT = 1.4
GAIN_SITE = "payload_friction_gain"
ALPHA_SPREAD_SITE = "alpha_spread"
# its name in the posterior and the summary
ALPHA_SPREAD_VARIABLE = "alpha_between_test_sd"
# (median, log sd) of tau's log-normal prior where the exponent varies between tests
PER_TEST_ALPHA_PRIOR = (0.02, 1.0)


def payload_gain_identifiable(friction_load) -> bool:
    """Whether the series' tests carry at least two different bearing loads (friction_load), so
    that the payload's friction gain kappa can be read from them."""
    loads = np.asarray(friction_load if friction_load is not None else [], dtype=float)
    return loads.size > 1 and bool(np.ptp(loads) > 1e-9)


@dataclass(frozen=True)
class Priors:
    """Prior settings; see the module docstring for the distributions."""

    centres: Mapping[str, float] = field(default_factory=lambda: dict(GENERIC_CENTRES))
    relative_sd: float = 1.0
    alpha_mean: float = 0.75
    alpha_sd: float = 0.5
    alpha_low: float = ALPHA_MIN
    alpha_high: float = ALPHA_MAX
    spread_median: float = 0.03
    spread_log_sd: float = 1.0
    shared: tuple[str, ...] = ()
    # {coefficient: (median, log sd)} of a between-test spread prior other than the common one
    spread_by_coefficient: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    # {shared coefficient: relative between-test sd it is still taken to have}: the automatic
    # mass refit shares Me only because its spread could not be fitted, not because the table's
    # tests have one mass, so the population value carries what such a spread adds to it
    # (_collapsed.draw_coefficients)
    ignored_spread: Mapping[str, float] = field(default_factory=dict)
    noise_scale: float = 0.05
    noise_log_sd: float = 2.0
    # (mean, sd, low, high) of kappa's truncated normal; None keeps kappa at 1 (the description's ratio)
    payload_friction_gain: tuple[float, float, float, float] | None = (1.0, 4.0, 0.0, 15.0)
    # (median, log sd) of the log-normal prior of tau, the damping exponent's between-test sd
    # (PER_TEST_ALPHA_PRIOR; fit --per-test-alpha); None: every test has the population's exponent
    alpha_spread: tuple[float, float] | None = None
    source: str = "generic"
    relations: Mapping[str, Any] = field(default_factory=dict)

    def centre_vector(self) -> np.ndarray:
        return np.array([self.centres[name] for name in COEFFICIENTS], dtype=float)

    def varying_mask(self) -> np.ndarray:
        """1.0 for the coefficients that vary between tests, 0.0 for the shared ones."""
        unknown = set(self.shared) - set(COEFFICIENTS)
        if unknown:
            raise ValueError(f"shared coefficients must be among {COEFFICIENTS}, got {sorted(unknown)}")
        return np.array([0.0 if name in self.shared else 1.0 for name in COEFFICIENTS])

    def spread_prior(self) -> tuple[np.ndarray, np.ndarray]:
        """Median and log sd of each coefficient's between-test spread prior, (4,) each."""
        unknown = set(self.spread_by_coefficient) - set(COEFFICIENTS)
        if unknown:
            raise ValueError(f"spread priors must be for coefficients among {COEFFICIENTS}, got {sorted(unknown)}")
        pairs = [self.spread_by_coefficient.get(name, (self.spread_median, self.spread_log_sd)) for name in COEFFICIENTS]
        return np.array([float(m) for m, _ in pairs]), np.array([float(s) for _, s in pairs])

    def ignored_spread_vector(self) -> np.ndarray | None:
        """(4,) relative sd of each coefficient's between-test spread that sharing it ignores
        (zeros where none), or None when no coefficient has one."""
        if not self.ignored_spread:
            return None
        unknown = set(self.ignored_spread) - set(self.shared)
        if unknown:
            raise ValueError(f"an ignored spread is only for shared coefficients, got {sorted(unknown)}")
        return np.array([float(self.ignored_spread.get(name, 0.0)) for name in COEFFICIENTS])

    def describe(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "centres": dict(self.centres),
            "relative_sd": self.relative_sd,
            "alpha": {"mean": self.alpha_mean, "sd": self.alpha_sd, "low": self.alpha_low, "high": self.alpha_high},
            "between_test_spread": {"median": self.spread_median, "log_sd": self.spread_log_sd,
                                    "shared": list(self.shared),
                                    **({"by_coefficient": {k: {"median": m, "log_sd": s} for k, (m, s)
                                                           in self.spread_by_coefficient.items()}}
                                       if self.spread_by_coefficient else {}),
                                    **({"ignored_by_sharing": dict(self.ignored_spread)} if self.ignored_spread else {})},
            "payload_friction_gain": (None if self.payload_friction_gain is None else dict(
                zip(("mean", "sd", "low", "high"), self.payload_friction_gain))),
            ALPHA_SPREAD_VARIABLE: (None if self.alpha_spread is None else dict(
                zip(("median", "log_sd"), self.alpha_spread))),
            **({"relations": dict(self.relations)} if self.relations else {}),
        }


def _positive(x) -> bool:
    return positive_or_none(x) is not None


def _moving_mass(table: Mapping[str, Any]) -> tuple[float | None, str, dict[str, float]]:
    """Me centre, the relation in words, and its inputs."""
    total = table.get("moving_mass_kg")
    if _positive(total):
        return float(total), "Me = moving_mass_kg (given)", {"moving_mass_kg": float(total)}
    deck = table.get("deck_mass_kg")
    if not _positive(deck):
        return None, "Me = deck + actuator moving mass: deck_mass_kg missing", {}
    inputs = {"deck_mass_kg": float(deck)}
    actuator = table.get("actuator_mass_kg")
    if not _positive(actuator) and isinstance(table.get("actuator"), Mapping):
        actuator = table["actuator"].get("moving_mass_kg")
    if _positive(actuator):
        inputs["actuator_mass_kg"] = float(actuator)
    parts = table.get("moving_parts_kg")
    if isinstance(parts, Mapping):
        for name, mass in parts.items():
            if _positive(mass):
                inputs[f"moving_parts_kg.{name}"] = float(mass)
    elif _positive(parts):
        inputs["moving_parts_kg"] = float(parts)
    relation = "Me = " + " + ".join(inputs)
    if len(inputs) == 1:
        relation += " (no actuator or other moving mass given)"
    return float(sum(inputs.values())), relation, inputs


def _friction_coefficient(table: Mapping[str, Any]) -> tuple[float, str]:
    """mu_e and where it came from."""
    for key in ("mu_e", "bearing_friction"):
        value = table.get(key)
        if isinstance(value, Mapping):
            for inner in ("mu", "mu_e", "coefficient"):
                if _positive(value.get(inner)):
                    return float(value[inner]), f"{key}.{inner}"
        elif _positive(value):
            return float(value), key
    return DEFAULT_FRICTION_COEFFICIENT, f"default {DEFAULT_FRICTION_COEFFICIENT} (no mu_e or bearing_friction)"


def physics_prior_report(table: Mapping[str, Any] | None) -> dict[str, dict[str, Any]]:
    """Component-relation values of the table description, each with its relation and inputs.

    Returns {"Me", "Ke", "Kpe", "F_hd", "Fmu"}: each {"value" (SI, or None when an input is
    missing), "unit", "relation", "inputs"}. Me, Ke and Fmu serve as prior centres (Ce has
    no component relation and keeps the generic centre); F_hd enters Fmu; K'e (the cubic
    strut coefficient of K'e*(u/h)^2*u) is not in the base force model and is listed for
    checks of it.
    """
    table = table or {}
    report: dict[str, dict[str, Any]] = {}
    me, relation, inputs = _moving_mass(table)
    report["Me"] = {"value": me, "unit": "kg", "relation": relation, "inputs": inputs}

    strut = table.get("strut") if isinstance(table.get("strut"), Mapping) else {}
    p0, area, h = (strut.get(k) for k in ("p0_pa", "area_m2", "h_m"))
    have_strut = all(_positive(x) for x in (p0, area, h))
    strut_inputs = {k: float(strut[k]) for k in ("p0_pa", "area_m2", "h_m") if _positive(strut.get(k))}
    missing = [f"strut.{k}" for k in ("p0_pa", "area_m2", "h_m") if not _positive(strut.get(k))]
    lacking = f": {', '.join(missing)} missing" if missing else ""
    ke = strut_stiffness(p0, area, h) if have_strut else None
    report["Ke"] = {"value": ke, "unit": "N/m", "relation": "Ke = 4*p0*A/h" + lacking, "inputs": strut_inputs}

    gamma = strut.get("gamma")
    gamma_given = _positive(gamma)
    gamma = float(gamma) if gamma_given else DEFAULT_GAS_EXPONENT
    l0 = strut.get("l0_m")
    kpe = strut_cubic_stiffness(ke, gamma, float(h), float(l0)) if ke is not None and _positive(l0) else None
    report["Kpe"] = {
        "value": kpe,
        "unit": "N/m",
        "relation": "K'e = 0.5*(gamma*h/l0 - 1)*Ke"
        + ("" if gamma_given else f", gamma = {DEFAULT_GAS_EXPONENT} assumed")
        + ("" if _positive(l0) else "; strut.l0_m missing")
        + ("" if ke is not None else "; needs Ke"),
        "inputs": {
            "gamma": gamma,
            **({"l0_m": float(l0)} if _positive(l0) else {}),
            **({"h_m": float(h)} if _positive(h) else {}),
        },
    }

    f_hd = hold_down_force(p0, area) if _positive(p0) and _positive(area) else None
    report["F_hd"] = {
        "value": f_hd,
        "unit": "N",
        "relation": "F_hd = 4*p0*A" + ("" if f_hd is not None else ": strut.p0_pa or strut.area_m2 missing"),
        "inputs": {k: v for k, v in strut_inputs.items() if k != "h_m"},
    }

    mu, mu_source = _friction_coefficient(table)
    deck = table.get("deck_mass_kg")
    fmu = None
    if f_hd is not None and _positive(deck):
        fmu = coulomb_friction(mu, normal_force(f_hd, float(deck), STANDARD_GRAVITY))
    report["Fmu"] = {
        "value": fmu,
        "unit": "N",
        "relation": "Fmu = mu_e*(F_hd + m_deck*g)"
        + ("" if fmu is not None else ": needs F_hd and deck_mass_kg")
        + f"; mu_e from {mu_source}",
        "inputs": {"mu_e": mu, **({"deck_mass_kg": float(deck)} if _positive(deck) else {}),
                   **({"F_hd": f_hd} if f_hd is not None else {}), "g": STANDARD_GRAVITY},
    }
    return report


def physics_centres(table: Mapping[str, Any]) -> dict[str, float]:
    """Prior centres from a `table` description; keys it lacks keep the generic centre."""
    centres = dict(GENERIC_CENTRES)
    report = physics_prior_report(table)
    for name in ("Me", "Ke", "Fmu"):
        if report[name]["value"] is not None:
            centres[name] = float(report[name]["value"])
    return centres


def make_priors(kind: str = "generic", table: Mapping[str, Any] | None = None, *,
                per_test_alpha: bool = False) -> Priors:
    """Priors of a named kind: 'generic' or 'physics' (centred by the table description);
    per_test_alpha: the damping exponent varies between tests (PER_TEST_ALPHA_PRIOR)."""
    exponent = {"alpha_spread": PER_TEST_ALPHA_PRIOR} if per_test_alpha else {}
    if kind == "generic":
        return Priors(**exponent)
    if kind == "physics":
        report = physics_prior_report(table or {})
        relations = {name: entry["relation"] for name, entry in report.items() if name in COEFFICIENTS}
        return replace(
            Priors(**exponent), centres=physics_centres(table or {}), relative_sd=0.5, source="physics",
            relations=relations
        )
    raise ValueError(f"unknown prior kind {kind!r}; expected 'generic' or 'physics'")
