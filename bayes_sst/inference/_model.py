"""The NumPyro model (priors and the collapsed likelihood); its potential energy over NumPyro's
unconstrained sites, in numpy (the sampler's start, the mode, the jackknife) and under JAX in
the whitened coordinates the sampler moves in (WhitenedFrame, whitened_potential)."""

from __future__ import annotations

import math
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
import numpyro
import numpyro.distributions as dist

from bayes_sst.inference._collapsed import MomentTable, collapsed_gradient, collapsed_log_likelihood
from bayes_sst.inference._priors import ALPHA_SPREAD_SITE, GAIN_SITE

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
    # (mean, sd, low, high) of the truncated normal prior of the payload's friction gain kappa
    # (see bayes_sst.inference._collapsed.friction_factors); None: kappa = 1, not sampled
    gain: tuple[float, float, float, float] | None = None
    # (median, log sd) of the log-normal prior of tau, the between-test sd of the damping
    # exponent (see _collapsed.DEVIATION); None: every test has the population's alpha
    alpha_spread: tuple[float, float] | None = None
    # rho_d = tau * deviation_scale: |Ce| in scaled units, the factor between a test's deviation
    # coefficient c_j = Ce_j delta_j and its exponent's deviation delta_j
    deviation_scale: float = 1.0


def table_force_model(table: MomentTable, priors: ScaledPriors):
    """Hierarchical force model with AR(1) residuals, theta_j and mu integrated out.

    Sites: alpha (damping exponent), spread (4 between-test sds, relative), alpha_spread (tau,
    the between-test sd of the exponent, where priors.alpha_spread is set; each test's own
    deviation is integrated out, see _collapsed.DEVIATION), phi and sigma (per test AR(1)
    coefficient and innovation sd, scaled units), and where the series has tests under
    different payloads, payload_friction_gain (kappa, see _collapsed.friction_factors). See
    _collapsed.py.

    fit samples this density through whitened_potential, the same potential in whitened
    coordinates of the global sites (tests/test_collapsed.py checks value and gradient against
    NumPyro's potential of this model); the model itself is what NumPyro's other tools take.
    """
    n_tests = table.n_pairs.shape[0]
    alpha = numpyro.sample(
        "alpha",
        dist.TruncatedNormal(priors.alpha_mean, priors.alpha_sd, low=priors.alpha_low, high=priors.alpha_high),
    )
    gain = 1.0
    if priors.gain is not None:
        mean, sd, low, high = priors.gain
        gain = numpyro.sample(GAIN_SITE, dist.TruncatedNormal(mean, sd, low=low, high=high))
    spread_loc = jnp.broadcast_to(jnp.log(jnp.asarray(priors.spread_median)), (4,))
    spread_scale = jnp.broadcast_to(jnp.asarray(priors.spread_log_sd), (4,))
    spread = numpyro.sample("spread", dist.LogNormal(spread_loc, spread_scale).to_event(1))
    deviation = None
    if priors.alpha_spread is not None:
        median, log_sd = priors.alpha_spread
        deviation = numpyro.sample(ALPHA_SPREAD_SITE, dist.LogNormal(math.log(median), log_sd)) * priors.deviation_scale
    with numpyro.plate("test", n_tests):
        phi = numpyro.sample("phi", dist.Uniform(-PHI_BOUND, PHI_BOUND))
        sigma = numpyro.sample("sigma", dist.LogNormal(priors.noise_loc, priors.noise_log_sd))
    numpyro.factor(
        "force",
        collapsed_log_likelihood(table, alpha, spread * priors.varying, phi, sigma, priors.mean, priors.sd,
                                 gain=gain, deviation=deviation),
    )


# The sampler's starting state, in numpy. Left to NumPyro, the start's potential and gradient
# are evaluated inside the compiled sampler, a second inlined copy of the gradient beside the
# leapfrog's: handing NUTS a start whose potential is computed here lets XLA drop that copy
# (measured on the 20-test example: the sampler's compile 7.2-8.1 s -> 6.0 s). The start's
# gradient comes from numpy too (potential_gradient). It must be the true one: a state keeps
# its gradient until a transition moves it, so with a zero gradient every transition from the
# start opened with a wrong momentum half-step, was rejected, and left the chain where it was;
# the step size's dual averaging read those rejections as a step size far too large and fell
# from 1 to 1e-3 within four iterations, and the next dozen warm-up iterations ran at the
# maximum tree depth (measured at 200 tests: a quarter of the warm-up's leapfrog steps).


def _interval(z, low, high, xp=np):
    """x = low + (high - low) sigmoid(z) and log|dx/dz| (NumPyro's transform to an interval)."""
    z = xp.asarray(z, dtype=float)
    x = low + (high - low) / (1.0 + xp.exp(-z))
    return x, math.log(high - low) - xp.logaddexp(0.0, z) - xp.logaddexp(0.0, -z)


def _to_interval(x, low, high):
    share = (np.asarray(x, dtype=float) - low) / (high - low)
    return np.log(share) - np.log1p(-share)


def _log_normal_density(x, loc, scale, xp=np):
    log_x = xp.log(x)
    return -log_x - xp.log(scale) - 0.5 * math.log(2 * math.pi) - 0.5 * ((log_x - loc) / scale) ** 2


def unconstrained_start(values: dict, priors: ScaledPriors) -> dict:
    """The sites of table_force_model in NumPyro's unconstrained space (numpy): interval sites
    through logit((x - low)/(high - low)), positive sites through log."""
    z = {
        "alpha": _to_interval(values["alpha"], priors.alpha_low, priors.alpha_high),
        "spread": np.log(np.asarray(values["spread"], dtype=float)),
        "phi": _to_interval(values["phi"], -PHI_BOUND, PHI_BOUND),
        "sigma": np.log(np.asarray(values["sigma"], dtype=float)),
    }
    if priors.gain is not None:
        z[GAIN_SITE] = _to_interval(values[GAIN_SITE], *priors.gain[2:])
    if priors.alpha_spread is not None:
        z[ALPHA_SPREAD_SITE] = np.log(float(values[ALPHA_SPREAD_SITE]))
    return z


def constrained_sites(z: dict, priors: ScaledPriors) -> dict:
    """The sites' values at unconstrained z (numpy), the inverse of unconstrained_start."""
    sites = {
        "alpha": _interval(z["alpha"], priors.alpha_low, priors.alpha_high)[0],
        "spread": np.exp(np.asarray(z["spread"], dtype=float)),
        "phi": _interval(z["phi"], -PHI_BOUND, PHI_BOUND)[0],
        "sigma": np.exp(np.asarray(z["sigma"], dtype=float)),
    }
    if priors.gain is not None:
        sites[GAIN_SITE] = _interval(z[GAIN_SITE], *priors.gain[2:])[0]
    if priors.alpha_spread is not None:
        sites[ALPHA_SPREAD_SITE] = np.exp(np.asarray(z[ALPHA_SPREAD_SITE], dtype=float))
    return sites


def _truncated_normal_log_density(x, mean, sd, low, high):
    """log of N(mean, sd^2) truncated to [low, high] at x; the normaliser is
    Phi((high - m)/s) - Phi((low - m)/s)."""
    cdf = lambda t: 0.5 * math.erfc(-t / math.sqrt(2.0))  # noqa: E731
    return (-0.5 * ((x - mean) / sd) ** 2 - math.log(sd) - 0.5 * math.log(2 * math.pi)
            - math.log(cdf((high - mean) / sd) - cdf((low - mean) / sd)))


def _interval_site_gradient(z, d_log_density_dx, mean, sd, low, high):
    """d/dz [log p(x) + log|dx/dz| + l(x)] for x = low + (high - low) s(z) under a truncated
    normal prior, given d_log_density_dx = dl/dx: (dl/dx - (x - mean)/sd^2) dx/dz + 1 - 2 s."""
    share = 1.0 / (1.0 + np.exp(-float(z)))
    x = low + (high - low) * share
    return (d_log_density_dx - (x - mean) / sd ** 2) * (high - low) * share * (1.0 - share) + 1.0 - 2.0 * share


def _sites_and_log_prior(z: dict, priors: ScaledPriors, xp=np):
    """The sites' values at unconstrained z and sum_s log p_s(x_s(z)) + sum_s log|dx_s/dz_s|
    (the truncated normals' normaliser is Phi((high - m)/s) - Phi((low - m)/s)). In numpy the
    scalars come back as Python floats; under JAX (xp=jax.numpy) as traced arrays."""
    scalar = float if xp is np else (lambda x: x)
    alpha, log_jacobian = _interval(z["alpha"], priors.alpha_low, priors.alpha_high, xp)
    phi, phi_jacobian = _interval(z["phi"], -PHI_BOUND, PHI_BOUND, xp)
    spread, sigma = xp.exp(xp.asarray(z["spread"], dtype=float)), xp.exp(xp.asarray(z["sigma"], dtype=float))
    gain, gain_log_prior, gain_jacobian = 1.0, 0.0, 0.0
    if priors.gain is not None:
        gain, gain_jacobian = _interval(z[GAIN_SITE], *priors.gain[2:], xp)
        gain_log_prior = _truncated_normal_log_density(gain, *priors.gain)
    log_prior = (
        _truncated_normal_log_density(alpha, priors.alpha_mean, priors.alpha_sd, priors.alpha_low, priors.alpha_high)
        + gain_log_prior
        + xp.sum(_log_normal_density(spread, xp.log(xp.asarray(priors.spread_median, dtype=float)),
                                     xp.asarray(priors.spread_log_sd, dtype=float), xp))
        - phi.size * math.log(2 * PHI_BOUND)
        + xp.sum(_log_normal_density(sigma, priors.noise_loc, priors.noise_log_sd, xp))
    )
    jacobian = (scalar(log_jacobian) + scalar(gain_jacobian) + xp.sum(z["spread"]) + xp.sum(phi_jacobian)
                + xp.sum(z["sigma"]))
    sites = {"alpha": scalar(alpha), "phi": phi, "spread": spread, "sigma": sigma, "gain": scalar(gain),
             "deviation": None}
    if priors.alpha_spread is not None:
        log_tau = scalar(z[ALPHA_SPREAD_SITE])
        tau = xp.exp(log_tau)
        log_prior += scalar(_log_normal_density(tau, math.log(priors.alpha_spread[0]), priors.alpha_spread[1], xp))
        jacobian += log_tau
        sites["deviation"] = tau * priors.deviation_scale
    return sites, scalar(log_prior + jacobian)


def _likelihood_arguments(sites: dict, priors: ScaledPriors, xp=np) -> tuple:
    """collapsed_log_likelihood's (alpha, rho, phi, sigma, prior mean, prior sd)."""
    return (sites["alpha"], sites["spread"] * xp.asarray(priors.varying, dtype=float), sites["phi"], sites["sigma"],
            xp.asarray(priors.mean, dtype=float), xp.asarray(priors.sd, dtype=float))


def potential_energy(z: dict, table: MomentTable, priors: ScaledPriors, xp=np):
    """-log p(sites, y) + log-Jacobian terms of table_force_model at unconstrained z.

        U(z) = -[sum_s log p_s(x_s(z)) + sum_s log|dx_s/dz_s| + log p(y | alpha, rho, phi, sigma)],

    the same number NumPyro's potential_energy gives (tests/test_collapsed.py compares them).
    In numpy (a float; `table` holds numpy arrays, moment_table(lagged, np)) for the sampler's
    start and the jackknife; under JAX (xp=jax.numpy, a jax table) inside the sampler
    (whitened_potential). Where the gradient is needed in numpy too, potential_and_gradient
    evaluates the likelihood once for both.
    """
    sites, log_prior = _sites_and_log_prior(z, priors, xp)
    likelihood = collapsed_log_likelihood(table, *_likelihood_arguments(sites, priors, xp), xp, gain=sites["gain"],
                                          deviation=sites["deviation"])
    value = -(log_prior + likelihood)
    return float(value) if xp is np else value


def potential_and_gradient(z: dict, table: MomentTable, priors: ScaledPriors) -> tuple[float, dict]:
    """potential_energy at unconstrained z and its gradient dU/dz per site, in numpy, from one
    evaluation of the collapsed likelihood (collapsed_gradient returns its value beside its
    closed-form derivatives).

    With x = low + (high - low) s(z), s the logistic function, dx/dz = (high - low) s (1 - s)
    and d log|dx/dz| / dz = 1 - 2 s; for x = exp(z), a log-normal prior (loc, scale) and its
    Jacobian together give d/dz = -(z - loc)/scale^2.
    """
    sites, log_prior = _sites_and_log_prior(z, priors)
    likelihood, (d_alpha, d_rho, d_phi, d_sigma, _, _, d_gain, d_deviation) = collapsed_gradient(
        table, *_likelihood_arguments(sites, priors), np, gain=sites["gain"], deviation=sites["deviation"])
    phi_share = 1.0 / (1.0 + np.exp(-np.asarray(z["phi"], dtype=float)))  # s(z) of phi's transform
    z_spread, z_sigma = np.asarray(z["spread"], dtype=float), np.asarray(z["sigma"], dtype=float)
    spread_loc = np.log(np.asarray(priors.spread_median, dtype=float))
    spread_scale = np.asarray(priors.spread_log_sd, dtype=float)
    log_density = {
        "alpha": _interval_site_gradient(z["alpha"], float(d_alpha), priors.alpha_mean, priors.alpha_sd,
                                         priors.alpha_low, priors.alpha_high),
        "spread": (np.asarray(d_rho) * np.asarray(priors.varying, dtype=float) * sites["spread"]
                   - (z_spread - spread_loc) / spread_scale ** 2),
        "phi": np.asarray(d_phi) * 2.0 * PHI_BOUND * phi_share * (1.0 - phi_share) + 1.0 - 2.0 * phi_share,
        "sigma": np.asarray(d_sigma) * sites["sigma"] - (z_sigma - priors.noise_loc) / priors.noise_log_sd ** 2,
    }
    if priors.gain is not None:
        log_density[GAIN_SITE] = _interval_site_gradient(z[GAIN_SITE], float(d_gain), *priors.gain)
    if priors.alpha_spread is not None:
        median, log_sd = priors.alpha_spread
        log_density[ALPHA_SPREAD_SITE] = (float(d_deviation) * sites["deviation"]
                                          - (float(z[ALPHA_SPREAD_SITE]) - math.log(median)) / log_sd ** 2)
    gradient = {name: -np.asarray(value, dtype=float).reshape(np.shape(z[name])) for name, value in log_density.items()}
    return float(-(log_prior + likelihood)), gradient


def potential_gradient(z: dict, table: MomentTable, priors: ScaledPriors) -> dict:
    """dU/dz of potential_energy at unconstrained z, per site, in numpy (potential_and_gradient)."""
    return potential_and_gradient(z, table, priors)[1]


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
            value, gradient = potential_and_gradient(sites, table, priors)
        if not np.isfinite(value):
            return np.inf, np.zeros_like(w)
        flat = np.concatenate([np.ravel(gradient[name]) for name in names]) * scale
        if not np.all(np.isfinite(flat)):
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


def global_sites(sites) -> tuple[str, ...]:
    """The sites shared by all tests among `sites` (names, or a dict keyed by them), in the order
    of the sampler's whitened coordinates (WhitenedFrame): alpha, the four spreads, the exponent's between-test sd
    and the payload's friction gain where they are sampled."""
    return (("alpha", "spread") + ((ALPHA_SPREAD_SITE,) if ALPHA_SPREAD_SITE in sites else ())
            + ((GAIN_SITE,) if GAIN_SITE in sites else ()))


def split_global(vector, names) -> dict:
    """{site: part} of a vector over the global sites' coordinates (`names` in global_sites
    order; leading axes kept): four entries for the spreads, one for each other site."""
    parts, position = {}, 0
    for name in names:
        size = 4 if name == "spread" else 1
        part = vector[..., position:position + size]
        parts[name] = part if name == "spread" else part[..., 0]
        position += size
    return parts


def global_curvature(z: dict, table: MomentTable, priors: ScaledPriors, step: float = 1e-5) -> np.ndarray:
    """d2U/dz dz' over the global sites (global_sites: alpha, the four spreads, the exponent's
    spread, the gain) at z, the per-test sites held: central differences of potential_gradient,
    symmetrised, (5, 5) to (7, 7).

    Its inverse is the conditional posterior covariance of the global sites at a mode, a
    slight underestimate of their marginal covariance (the per-test sites are nearly
    independent of them), which is the safe side for the sampler's mass matrix: too small a
    scale costs leapfrog steps, too large a one makes trajectories diverge.
    """
    names = global_sites(z)
    coordinates = [(name, index) for name in names for index in range(int(np.size(z[name])))]

    def global_gradient(name, index, shift):
        moved = {key: np.array(value, dtype=float, copy=True) for key, value in z.items()}
        moved[name].reshape(-1)[index] += shift
        gradient = potential_gradient(moved, table, priors)
        return np.concatenate([np.ravel(gradient[key]) for key in names])

    columns = [(global_gradient(name, index, step) - global_gradient(name, index, -step)) / (2.0 * step)
               for name, index in coordinates]
    hessian = np.stack(columns, axis=1)
    return 0.5 * (hessian + hessian.T)


class WhitenedFrame(NamedTuple):
    """The sampler's coordinates: the global sites (global_sites) as w with

        z_g = centre + root w,   root root' = C,

    C the global block of the sampler's inverse mass matrix (the inverse curvature at the mode,
    fit._with_curvature), the per-test sites phi and sigma as they are.

    Why: the mass matrix stays fixed (SamplerSettings.adapt_mass_matrix), and NUTS over z_g
    with the dense inverse mass C takes the same trajectories as NUTS over w with a unit mass.
    Sampling w, with the potential handed to NUTS directly (whitened_potential), leaves NumPyro's
    dense-mass algebra and its tracing of the model out of the compiled sampler: measured on a
    stand-in model of the same sites, the dense block alone cost 1.0 s of a 4.7 s compilation.
    """

    names: tuple[str, ...]
    centre: np.ndarray  # (k,)
    root: np.ndarray  # (k, k), lower triangular

    @classmethod
    def around(cls, z: dict, covariance) -> "WhitenedFrame":
        """The frame centred on z's global sites with root the Cholesky factor of covariance."""
        names = global_sites(z)
        centre = np.concatenate([np.ravel(np.asarray(z[name], dtype=float)) for name in names])
        root = np.linalg.cholesky(np.asarray(covariance, dtype=float))
        return cls(names, centre, root)

    def to_sampler(self, z: dict) -> dict:
        """w, phi, sigma of one state z (numpy)."""
        centred = np.concatenate([np.ravel(np.asarray(z[name], dtype=float)) for name in self.names]) - self.centre
        from scipy.linalg import solve_triangular

        return {"global": solve_triangular(self.root, centred, lower=True),
                "phi": np.asarray(z["phi"], dtype=float), "sigma": np.asarray(z["sigma"], dtype=float)}

    def gradient_to_sampler(self, gradient: dict) -> dict:
        """dU/dw = root' dU/dz_g beside dU/dphi, dU/dsigma (numpy)."""
        global_gradient = np.concatenate([np.ravel(np.asarray(gradient[name], dtype=float)) for name in self.names])
        return {"global": self.root.T @ global_gradient, "phi": np.asarray(gradient["phi"], dtype=float),
                "sigma": np.asarray(gradient["sigma"], dtype=float)}

    def from_sampler(self, params: dict, xp=np) -> dict:
        """z from w, phi, sigma; w may carry leading axes (chains, draws)."""
        global_z = xp.asarray(self.centre) + xp.asarray(params["global"]) @ xp.asarray(self.root).T
        return {**split_global(global_z, self.names), "phi": params["phi"], "sigma": params["sigma"]}


def whitened_potential(params: dict, table: MomentTable, priors: ScaledPriors, frame: WhitenedFrame):
    """U(z(w, phi, sigma)) under JAX, the sampler's potential (WhitenedFrame; potential_energy).
    Its gradient is JAX's, through the transforms and priors, and collapsed_gradient's closed
    form for the likelihood."""
    return potential_energy(frame.from_sampler(params, jnp), table, priors, jnp)
