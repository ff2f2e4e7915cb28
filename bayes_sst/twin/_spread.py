"""Test-to-test spread: each test of a campaign draws its own Me, Ke, Ce and Fmu.

Real tables drift between tests (oil temperature, bearing condition, strut pressure), so a
twin that repeats one parameter set exactly would make pooled identification look too
good. Test i's parameter is theta_i = theta*exp(sigma*z_i), z_i ~ N(0, 1), with
sigma = sqrt(log(1 + s^2)) so that theta_i/theta has relative standard deviation exactly s
(its median is 1, its mean sqrt(1 + s^2)).
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

SPREAD_PARAMETERS = ("Me", "Ke", "Ce", "Fmu")


def spread_sds(spread: float | Mapping[str, float] | None) -> dict[str, float]:
    """Relative sd per spread parameter, from None (off), one float for all, or a dict."""
    if spread is None:
        return dict.fromkeys(SPREAD_PARAMETERS, 0.0)
    if isinstance(spread, Mapping):
        unknown = sorted(set(spread) - set(SPREAD_PARAMETERS))
        if unknown:
            raise ValueError(f"spread given for {unknown}; only {SPREAD_PARAMETERS} spread")
        sds = {name: float(spread.get(name, 0.0)) for name in SPREAD_PARAMETERS}
    else:
        sds = dict.fromkeys(SPREAD_PARAMETERS, float(spread))
    for name, sd in sds.items():
        if not (math.isfinite(sd) and sd >= 0.0):
            raise ValueError(f"spread of {name} must be a non-negative relative sd, got {sd!r}")
    return sds


def draw_factors(rng: np.random.Generator, n_tests: int, sds: Mapping[str, float]) -> dict[str, np.ndarray]:
    """Multiplicative lognormal factors per parameter, shape (n_tests,).

    The standard normals are drawn for every parameter whatever its sd, so that switching
    one parameter's spread on or off leaves the other parameters' draws unchanged.
    """
    z = rng.standard_normal((n_tests, len(SPREAD_PARAMETERS)))
    factors = {}
    for j, name in enumerate(SPREAD_PARAMETERS):
        sigma = math.sqrt(math.log1p(sds[name] ** 2))
        factors[name] = np.exp(sigma * z[:, j])
    return factors
