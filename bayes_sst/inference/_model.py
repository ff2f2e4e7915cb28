"""The NumPyro model (priors and the collapsed likelihood) and, in numpy, the sampler's start:
its sites in NumPyro's unconstrained space and their potential energy."""

from __future__ import annotations

import math
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist

from bayes_sst.inference._collapsed import MomentTable, collapsed_log_likelihood

PHI_BOUND = 0.999


class ScaledPriors(NamedTuple):
    """Priors in the scaled units of the moment table (coefficients divided by their scale)."""

    mean: jnp.ndarray  # (4,)
    sd: jnp.ndarray  # (4,)
    alpha_mean: float
    alpha_sd: float
    alpha_low: float
    alpha_high: float
    spread_median: float | jnp.ndarray  # one for all four coefficients, or (4,)
    spread_log_sd: float | jnp.ndarray
    noise_loc: float
    noise_log_sd: float
    varying: jnp.ndarray  # (4,) 1.0 varies between tests, 0.0 shared


def table_force_model(table: MomentTable, priors: ScaledPriors):
    """Hierarchical force model with AR(1) residuals, theta_j and mu integrated out.

    Sites: alpha (damping exponent), spread (4 between-test sds, relative), phi and sigma
    (per test AR(1) coefficient and innovation sd, scaled units). See _collapsed.py.
    """
    n_tests = table.n_pairs.shape[0]
    alpha = numpyro.sample(
        "alpha",
        dist.TruncatedNormal(priors.alpha_mean, priors.alpha_sd, low=priors.alpha_low, high=priors.alpha_high),
    )
    spread_loc = jnp.broadcast_to(jnp.log(jnp.asarray(priors.spread_median)), (4,))
    spread_scale = jnp.broadcast_to(jnp.asarray(priors.spread_log_sd), (4,))
    spread = numpyro.sample("spread", dist.LogNormal(spread_loc, spread_scale).to_event(1))
    with numpyro.plate("test", n_tests):
        phi = numpyro.sample("phi", dist.Uniform(-PHI_BOUND, PHI_BOUND))
        sigma = numpyro.sample("sigma", dist.LogNormal(priors.noise_loc, priors.noise_log_sd))
    numpyro.factor(
        "force",
        collapsed_log_likelihood(table, alpha, spread * priors.varying, phi, sigma, priors.mean, priors.sd),
    )


# The sampler's starting state, in numpy. NumPyro's own initialisation (find_valid_initial_params)
# evaluates the potential's gradient inside the compiled sampler, a second inlined copy of the
# model's gradient beside the leapfrog's: handing NUTS a start whose potential is computed here
# lets XLA drop that copy (measured on the 20-test example: the sampler's compile 7.2-8.1 s ->
# 6.0 s). The start's gradient is left at zero: only the first warm-up transition's opening
# momentum half-step reads it, every later gradient comes from the compiled leapfrog, and
# warm-up draws are discarded.


def _interval(z, low, high):
    """x = low + (high - low) sigmoid(z) and log|dx/dz| (NumPyro's transform to an interval)."""
    z = np.asarray(z, dtype=float)
    x = low + (high - low) / (1.0 + np.exp(-z))
    return x, math.log(high - low) - np.logaddexp(0.0, z) - np.logaddexp(0.0, -z)


def _to_interval(x, low, high):
    share = (np.asarray(x, dtype=float) - low) / (high - low)
    return np.log(share) - np.log1p(-share)


def _log_normal_density(x, loc, scale):
    log_x = np.log(x)
    return -log_x - np.log(scale) - 0.5 * math.log(2 * math.pi) - 0.5 * ((log_x - loc) / scale) ** 2


def unconstrained_start(values: dict, priors: ScaledPriors) -> dict:
    """The sites of table_force_model in NumPyro's unconstrained space (numpy): interval sites
    through logit((x - low)/(high - low)), positive sites through log."""
    return {
        "alpha": _to_interval(values["alpha"], priors.alpha_low, priors.alpha_high),
        "spread": np.log(np.asarray(values["spread"], dtype=float)),
        "phi": _to_interval(values["phi"], -PHI_BOUND, PHI_BOUND),
        "sigma": np.log(np.asarray(values["sigma"], dtype=float)),
    }


def potential_energy(z: dict, table: MomentTable, priors: ScaledPriors) -> float:
    """-log p(sites, y) + log-Jacobian terms of table_force_model at unconstrained z, in numpy.

        U(z) = -[sum_s log p_s(x_s(z)) + sum_s log|dx_s/dz_s| + log p(y | alpha, rho, phi, sigma)],

    the same number NumPyro's potential_energy gives (tests/test_collapsed.py compares them);
    the truncated normal's normaliser is Phi((high - m)/s) - Phi((low - m)/s). `table` holds
    numpy arrays (moment_table(lagged, np)).
    """
    alpha, log_jacobian = _interval(z["alpha"], priors.alpha_low, priors.alpha_high)
    phi, phi_jacobian = _interval(z["phi"], -PHI_BOUND, PHI_BOUND)
    spread, sigma = np.exp(np.asarray(z["spread"], dtype=float)), np.exp(np.asarray(z["sigma"], dtype=float))
    m, s = priors.alpha_mean, priors.alpha_sd
    cdf = lambda t: 0.5 * math.erfc(-t / math.sqrt(2.0))  # noqa: E731
    log_prior = (
        -0.5 * ((float(alpha) - m) / s) ** 2 - math.log(s) - 0.5 * math.log(2 * math.pi)
        - math.log(cdf((priors.alpha_high - m) / s) - cdf((priors.alpha_low - m) / s))
        + np.sum(_log_normal_density(spread, np.log(np.asarray(priors.spread_median, dtype=float)),
                                     np.asarray(priors.spread_log_sd, dtype=float)))
        - phi.size * math.log(2 * PHI_BOUND)
        + np.sum(_log_normal_density(sigma, priors.noise_loc, priors.noise_log_sd))
    )
    jacobian = float(log_jacobian) + np.sum(z["spread"]) + np.sum(phi_jacobian) + np.sum(z["sigma"])
    likelihood = collapsed_log_likelihood(
        table, float(alpha), spread * np.asarray(priors.varying, dtype=float), phi, sigma,
        np.asarray(priors.mean, dtype=float), np.asarray(priors.sd, dtype=float), np,
    )
    return float(-(log_prior + jacobian + likelihood))
