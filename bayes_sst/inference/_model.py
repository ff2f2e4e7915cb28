"""The NumPyro model: priors, the collapsed likelihood, nothing else."""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
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
    spread_median: float
    spread_log_sd: float
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
    spread = numpyro.sample("spread", dist.LogNormal(jnp.log(priors.spread_median), priors.spread_log_sd).expand([4]).to_event(1))
    with numpyro.plate("test", n_tests):
        phi = numpyro.sample("phi", dist.Uniform(-PHI_BOUND, PHI_BOUND))
        sigma = numpyro.sample("sigma", dist.LogNormal(priors.noise_loc, priors.noise_log_sd))
    numpyro.factor(
        "force",
        collapsed_log_likelihood(table, alpha, spread * priors.varying, phi, sigma, priors.mean, priors.sd),
    )
