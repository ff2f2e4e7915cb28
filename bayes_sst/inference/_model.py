"""The NumPyro model (priors and the collapsed likelihood) and, in numpy, the sampler's start:
its sites in NumPyro's unconstrained space and their potential energy."""

from __future__ import annotations

import math
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist

from bayes_sst.inference._collapsed import MomentTable, collapsed_gradient, collapsed_log_likelihood

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
# 6.0 s). The start's gradient comes from numpy too (potential_gradient). It must be the true
# one: a state keeps its gradient until a transition moves it, so with a zero gradient every
# transition from the start opened with a wrong momentum half-step, was rejected, and left the
# chain where it was; the step size's dual averaging read those rejections as a step size far
# too large and fell from 1 to 1e-3 within four iterations, and the next dozen warm-up
# iterations ran at the maximum tree depth (measured at 200 tests: a quarter of the warm-up's
# leapfrog steps).


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


def constrained_sites(z: dict, priors: ScaledPriors) -> dict:
    """The sites' values at unconstrained z (numpy), the inverse of unconstrained_start."""
    return {
        "alpha": _interval(z["alpha"], priors.alpha_low, priors.alpha_high)[0],
        "spread": np.exp(np.asarray(z["spread"], dtype=float)),
        "phi": _interval(z["phi"], -PHI_BOUND, PHI_BOUND)[0],
        "sigma": np.exp(np.asarray(z["sigma"], dtype=float)),
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


def potential_gradient(z: dict, table: MomentTable, priors: ScaledPriors) -> dict:
    """dU/dz of potential_energy at unconstrained z, per site, in numpy.

    With x = low + (high - low) s(z), s the logistic function, dx/dz = (high - low) s (1 - s)
    and d log|dx/dz| / dz = 1 - 2 s; for x = exp(z), a log-normal prior (loc, scale) and its
    Jacobian together give d/dz = -(z - loc)/scale^2. The likelihood's derivatives with respect
    to alpha, the spreads, phi and sigma are collapsed_gradient's closed form.
    """
    def logistic(value):
        return 1.0 / (1.0 + np.exp(-np.asarray(value, dtype=float)))

    alpha_share, phi_share = logistic(z["alpha"]), logistic(z["phi"])
    alpha = priors.alpha_low + (priors.alpha_high - priors.alpha_low) * alpha_share
    phi = -PHI_BOUND + 2.0 * PHI_BOUND * phi_share
    z_spread, z_sigma = np.asarray(z["spread"], dtype=float), np.asarray(z["sigma"], dtype=float)
    spread, sigma = np.exp(z_spread), np.exp(z_sigma)
    varying = np.asarray(priors.varying, dtype=float)
    _, (d_alpha, d_rho, d_phi, d_sigma, _, _) = collapsed_gradient(
        table, float(alpha), spread * varying, phi, sigma,
        np.asarray(priors.mean, dtype=float), np.asarray(priors.sd, dtype=float), np,
    )
    spread_loc = np.log(np.asarray(priors.spread_median, dtype=float))
    spread_scale = np.asarray(priors.spread_log_sd, dtype=float)
    log_density = {
        "alpha": (float(d_alpha) - (alpha - priors.alpha_mean) / priors.alpha_sd ** 2)
        * (priors.alpha_high - priors.alpha_low) * alpha_share * (1.0 - alpha_share) + 1.0 - 2.0 * alpha_share,
        "spread": np.asarray(d_rho) * varying * spread - (z_spread - spread_loc) / spread_scale ** 2,
        "phi": np.asarray(d_phi) * 2.0 * PHI_BOUND * phi_share * (1.0 - phi_share) + 1.0 - 2.0 * phi_share,
        "sigma": np.asarray(d_sigma) * sigma - (z_sigma - priors.noise_loc) / priors.noise_log_sd ** 2,
    }
    return {name: -np.asarray(value, dtype=float).reshape(np.shape(z[name])) for name, value in log_density.items()}


def posterior_mode(z: dict, table: MomentTable, priors: ScaledPriors, scales: dict,
                   max_iterations: int = 300) -> dict:
    """The mode of the unconstrained posterior density exp(-U(z)) found from z by L-BFGS in
    numpy, with each site measured in units of its scale (a rough posterior sd, so that the
    search sees a well-conditioned problem); z itself if the search fails or ends higher.

    Why: the per-test least-squares start leaves the global sites far from where many tests put
    them (at 200 tests the start's gradient of U along alpha was ~900 times what a point one
    assumed sd away from the mode would have), and the first warm-up trajectories from there
    diverge whatever the step size, so the step-size adaptation falls by orders of magnitude and
    the next warm-up iterations run at the maximum tree depth.
    """
    from scipy.optimize import minimize

    names = list(z)
    shapes = [np.shape(z[name]) for name in names]
    sizes = [int(np.prod(shape)) for shape in shapes]
    origin = np.concatenate([np.ravel(np.asarray(z[name], dtype=float)) for name in names])
    scale = np.concatenate([np.broadcast_to(np.asarray(scales[name], dtype=float), shape).ravel()
                            for name, shape in zip(names, shapes)])

    def unpack(w):
        flat = origin + scale * w
        parts = np.split(flat, np.cumsum(sizes)[:-1])
        return {name: part.reshape(shape) for name, part, shape in zip(names, parts, shapes)}

    def objective(w):
        sites = unpack(w)
        with np.errstate(all="ignore"):
            value = potential_energy(sites, table, priors)
            gradient = potential_gradient(sites, table, priors)
        flat = np.concatenate([np.ravel(gradient[name]) for name in names]) * scale
        if not (np.isfinite(value) and np.all(np.isfinite(flat))):
            return np.inf, np.zeros_like(w)
        return value, flat

    start_value = objective(np.zeros_like(origin))[0]
    try:
        found = minimize(objective, np.zeros_like(origin), jac=True, method="L-BFGS-B",
                         options={"maxiter": max_iterations})
    except (ValueError, FloatingPointError, np.linalg.LinAlgError):
        return z
    if not (np.isfinite(found.fun) and found.fun <= start_value):
        return z
    return unpack(found.x)


GLOBAL_SITES = ("alpha", "spread")


def global_curvature(z: dict, table: MomentTable, priors: ScaledPriors, step: float = 1e-5) -> np.ndarray:
    """d2U/dz dz' over the global sites (alpha, then the four spreads) at z, the per-test sites
    held: central differences of potential_gradient, symmetrised, (5, 5).

    Its inverse is the conditional posterior covariance of the global sites at a mode, a
    slight underestimate of their marginal covariance (the per-test sites are nearly
    independent of them), which is the safe side for the sampler's mass matrix: too small a
    scale costs leapfrog steps, too large a one makes trajectories diverge.
    """
    coordinates = [(name, index) for name in GLOBAL_SITES for index in range(int(np.size(z[name])))]

    def global_gradient(name, index, shift):
        moved = {key: np.array(value, dtype=float, copy=True) for key, value in z.items()}
        moved[name].reshape(-1)[index] += shift
        gradient = potential_gradient(moved, table, priors)
        return np.concatenate([np.ravel(gradient[key]) for key in GLOBAL_SITES])

    columns = [(global_gradient(name, index, step) - global_gradient(name, index, -step)) / (2.0 * step)
               for name, index in coordinates]
    hessian = np.stack(columns, axis=1)
    return 0.5 * (hessian + hessian.T)
