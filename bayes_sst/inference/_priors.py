"""Priors of the force model, on physical scales.

Population values (Gaussian, so they can be integrated out exactly):

    Me ~ N(c_Me, (s*c_Me)^2), Ke ~ N(c_Ke, (s*c_Ke)^2), Ce ~ N(c_Ce, (s*c_Ce)^2),
    Fmu ~ N(c_Fmu, (s*c_Fmu)^2)

with centres c and relative width s. The generic centres describe a mid-size
servo-hydraulic table (10 t, 1 MN/m, 20 kN/(m/s)^alpha, 10 kN) with s = 1: a factor of a
few either way is a priori plausible and the data decide. With prior="physics" the centres
come from the series' `table` description through the study's component relations
(Me ~ deck mass, Ke = 4*p0*A/h, Fmu = mu_e*(F_hd + m*g)) and s = 0.5.

    alpha ~ N(0.75, 0.5^2) truncated to [0.05, 1.95]   (0.5 turbulent orifice flow, 1 laminar)
    rho_k ~ HalfNormal(0.1)    between-test sd of each coefficient, relative to its centre
    phi_j ~ U(-0.999, 0.999)   AR(1) coefficient of test j's residual
    sigma_j ~ LogNormal(log(0.05 F_rms), 2)   innovation sd of test j
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Mapping

import numpy as np

from bayes_sst.inference._statistics import ALPHA_MAX, ALPHA_MIN, COEFFICIENTS
from bayes_sst.physics import STANDARD_GRAVITY, hold_down_force, normal_force, strut_stiffness

GENERIC_CENTRES = {"Me": 10_000.0, "Ke": 1.0e6, "Ce": 20_000.0, "Fmu": 10_000.0}
DEFAULT_FRICTION_COEFFICIENT = 0.01


@dataclass(frozen=True)
class Priors:
    """Prior settings; see the module docstring for the distributions."""

    centres: Mapping[str, float] = field(default_factory=lambda: dict(GENERIC_CENTRES))
    relative_sd: float = 1.0
    alpha_mean: float = 0.75
    alpha_sd: float = 0.5
    alpha_low: float = ALPHA_MIN
    alpha_high: float = ALPHA_MAX
    spread_scale: float = 0.1
    noise_scale: float = 0.05
    noise_log_sd: float = 2.0
    source: str = "generic"

    def centre_vector(self) -> np.ndarray:
        return np.array([self.centres[name] for name in COEFFICIENTS], dtype=float)

    def describe(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "centres": dict(self.centres),
            "relative_sd": self.relative_sd,
            "alpha": {"mean": self.alpha_mean, "sd": self.alpha_sd, "low": self.alpha_low, "high": self.alpha_high},
            "between_test_spread_scale": self.spread_scale,
        }


def physics_centres(table: Mapping[str, Any]) -> dict[str, float]:
    """Prior centres from a `table` description; keys it lacks keep the generic centre."""
    centres = dict(GENERIC_CENTRES)
    deck = table.get("deck_mass_kg")
    if isinstance(deck, (int, float)) and deck > 0:
        centres["Me"] = float(deck)
    strut = table.get("strut") or {}
    p0, area, h = strut.get("p0_pa"), strut.get("area_m2"), strut.get("h_m")
    if all(isinstance(x, (int, float)) and x > 0 for x in (p0, area, h)):
        centres["Ke"] = strut_stiffness(p0, area, h)
        if isinstance(deck, (int, float)) and deck > 0:
            mu = table.get("mu_e", DEFAULT_FRICTION_COEFFICIENT)
            centres["Fmu"] = float(mu) * normal_force(hold_down_force(p0, area), deck, STANDARD_GRAVITY)
    return centres


def make_priors(kind: str = "generic", table: Mapping[str, Any] | None = None) -> Priors:
    """Priors of a named kind: 'generic' or 'physics' (centred by the table description)."""
    if kind == "generic":
        return Priors()
    if kind == "physics":
        return replace(Priors(), centres=physics_centres(table or {}), relative_sd=0.5, source="physics")
    raise ValueError(f"unknown prior kind {kind!r}; expected 'generic' or 'physics'")
