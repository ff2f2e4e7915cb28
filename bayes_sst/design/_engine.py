"""The numbers behind the design: the fitted model's Gaussian pieces, per posterior draw.

Same model and priors as `fit` (see bayes_sst.inference._collapsed). Per test j, with the
AR(1)-whitened moments A_j = X_j'X_j/sigma_j^2, b_j = X_j'y_j/sigma_j^2 (scaled units,
coefficients relative to `scale`), D = diag(rho), B_j = I + D A_j D:

    H_j = A_j - A_j D B_j^-1 D A_j = (A_j^-1 + T)^-1,     h_j = b_j - A_j D B_j^-1 D b_j
    c_j = -1/2 log|B_j| + 1/2 (D b_j)' B_j^-1 (D b_j) - n_j/2 log(2 pi sigma_j^2) - y_j'y_j/(2 sigma_j^2)
    Q = S0^-1 + sum_j H_j,   r = S0^-1 m0 + sum_j h_j,   mu | hyper, y ~ N(Q^-1 r, Q^-1)
    log p(y | hyper) = sum_j c_j - sum log s0 - 1/2 log|Q| + 1/2 r'Q^-1 r - 1/2 m0'S0^-1 m0

Two uses:

* Preposterior (`Preposterior`): a future outcome y' of added tests is drawn from the
  posterior predictive (a posterior draw as truth, new theta_j ~ N(mu, T), AR(1) noise);
  the updated posterior is the current draws reweighted by p(y' | hyper_s, y) =
  p(y, y' | hyper_s)/p(y | hyper_s), each draw carrying its exact Gaussian
  N(Q'^-1 r', Q'^-1) for mu. Its 90 % interval is that of the weighted Gaussian mixture.
* Fisher information (`fisher_information`), for the fast search: with alpha linearised
  around each draw (a fifth parameter delta = alpha - alpha_s whose regressor is
  d = Ce dX3/dalpha), the information a test gives on (mu, delta) after its own theta_j
  is integrated out is I_j = M - Mx' D B^-1 D Mx, M the whitened 5x5 moments of
  (x1..x4, d) over sigma^2 and Mx its first four rows.

Where the fit sampled the payload's friction gain kappa, a recorded payload test's Coulomb
column is the fit's, s_j L_j filter(sign v) with s_j = 1 + (kappa_s - 1)(L_j - 1)/L_j
(inference._collapsed.friction_factors), so each draw's Gaussian for mu is the one the fit
drew from. Why: with the description's ratio (kappa = 1) in place of the draws' kappa, the
design's starting point was not the run's posterior: on a LuGre-generator series with seven
payload tests (kappa 1.87) the Fmu half-width before any added test came out 2.59 % against
the posterior's 3.20 %. Added tests carry no payload, so kappa changes only the recorded
tests' terms; its uncertainty enters through the draws, as the spreads' does.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np
from scipy.special import erfinv, ndtr

from bayes_sst.inference import _smalllinalg as sl
from bayes_sst.inference._collapsed import load_share, payload_friction_factor
from bayes_sst.inference._priors import ALPHA_SPREAD_VARIABLE, GAIN_SITE
from bayes_sst.inference._widening import flat_model_draws, widening_of
from bayes_sst.inference._statistics import (
    ALPHA_MAX,
    ALPHA_MIN,
    COEFFICIENTS,
    acceleration_noise_correction,
    pair_moments,
    response_moments,
    scaled_regressors,
)
from bayes_sst.signals import PreparedTest

LOG_2PI = math.log(2 * math.pi)
PARAMETERS = ("Me", "Ke", "Ce", "alpha", "Fmu")
Z90 = 1.6448536269514722  # standard normal 95 % point: the 90 % interval is mean +- Z90 sd


@dataclass(frozen=True)
class DesignPosterior:
    """Posterior draws of a run in the engine's scaled units.

    mu (S, 4) = (Me, Ke, Ce, Fmu)/scale; alpha (S,); rho (S, 4) between-test sds / scale;
    phi, sigma (S, J) per existing test (sigma / force_scale); prior_mean, prior_sd (4,)
    of the population values / scale (the fit's priors); alpha_prior_sd; gain (S,) the
    payload's friction gain kappa per draw, None where the fit did not sample it (kappa = 1);
    ignored_spread (4,) the relative between-test sd a shared coefficient is still taken to
    have (the fit's Priors.ignored_spread), None where none is.
    """

    mu: np.ndarray
    alpha: np.ndarray
    rho: np.ndarray
    phi: np.ndarray
    sigma: np.ndarray
    scale: np.ndarray
    force_scale: float
    prior_mean: np.ndarray
    prior_sd: np.ndarray
    alpha_prior_sd: float
    gain: np.ndarray | None = None
    ignored_spread: np.ndarray | None = None

    @property
    def n_draws(self) -> int:
        return len(self.alpha)

    def subset(self, index) -> "DesignPosterior":
        return DesignPosterior(self.mu[index], self.alpha[index], self.rho[index], self.phi[index],
                               self.sigma[index], self.scale, self.force_scale, self.prior_mean,
                               self.prior_sd, self.alpha_prior_sd,
                               None if self.gain is None else self.gain[index], self.ignored_spread)


def widening_factors(tree) -> np.ndarray:
    """The run's widening of the population intervals (bayes_sst.inference._widening), in
    PARAMETERS order; ones for a run fitted without it. The design predicts the model's own
    intervals and stretches them by these, as the fit did: the tests' scatter beyond the model
    is taken to stay in proportion as tests are added, since both shrink as 1/sqrt(J)."""
    widening = widening_of(tree)
    return np.array([float(widening.get(name, {}).get("factor", 1.0)) for name in PARAMETERS])


def design_posterior(tree, prepared: Sequence[PreparedTest]) -> DesignPosterior:
    """DesignPosterior of a run tree; `prepared` are the run's tests in its order (run_prepared)."""
    # the model's own draws: the design predicts the model's posterior and applies the run's
    # widening to what it predicts (widening_factors)
    mu_si = np.stack([flat_model_draws(tree, name) for name in COEFFICIENTS], axis=-1)
    scale = np.abs(mu_si.mean(axis=0))
    force_scale = float(np.sqrt(np.mean(np.concatenate([((t.F - t.payload_kg * t.a)[t.keep]) ** 2 for t in prepared]))))
    priors = json.loads(tree.attrs.get("priors", "{}") or "{}")
    if "centres" not in priors:
        raise ValueError("the run does not record its priors (posterior.nc attrs 'priors'); refit it with this version")
    if ALPHA_SPREAD_VARIABLE in tree["posterior"]:
        # the engine's Gaussian pieces share the exponent between tests; with each test's own
        # deviation integrated out the run's intervals are wider, and the design would start
        # from (and predict) intervals narrower than the run's
        raise ValueError("the run was fitted with the damping exponent varying between tests (fit --per-test-alpha), "
                         "which the design does not model yet: fit the series again without --per-test-alpha "
                         "for the design")
    centres = np.array([priors["centres"][name] for name in COEFFICIENTS], dtype=float)
    relative_sd = float(priors.get("relative_sd", 1.0))
    ignored = priors.get("between_test_spread", {}).get("ignored_by_sharing") or {}
    return DesignPosterior(
        mu=mu_si / scale,
        alpha=flat_model_draws(tree, "alpha"),
        rho=flat_model_draws(tree, "between_test_sd") / scale,
        phi=flat_model_draws(tree, "phi"),
        sigma=flat_model_draws(tree, "sigma") / force_scale,
        scale=scale,
        force_scale=force_scale,
        prior_mean=centres / scale,
        prior_sd=relative_sd * np.abs(centres) / scale,
        alpha_prior_sd=float(priors.get("alpha", {}).get("sd", 0.5)),
        gain=flat_model_draws(tree, GAIN_SITE) if GAIN_SITE in tree["posterior"] else None,
        ignored_spread=(np.array([float(ignored.get(name, 0.0)) for name in COEFFICIENTS]) if ignored else None),
    )


# The engine interpolates the lagged MOMENTS in alpha (cubic Hermite, slopes by finite
# differences), which, unlike the fit's interpolation of the damping column, does not keep a
# moment matrix positive semidefinite; it needs a finer grid than the fit's. On the fit's 0.025
# grid a slow-marked test's Fisher information of a triangle test came out indefinite
# (negative variances); on 0.0125 it did not. Only the draws' alpha range is tabulated.
DESIGN_ALPHA_STEP = 0.0125


def alpha_grid_for(alpha: np.ndarray, margin: float = 0.05) -> np.ndarray:
    """An alpha grid of step DESIGN_ALPHA_STEP over the draws' range plus a margin."""
    step = DESIGN_ALPHA_STEP
    full = np.arange(ALPHA_MIN, ALPHA_MAX + 0.5 * step, step)
    lo, hi = float(alpha.min()) - margin, float(alpha.max()) + margin
    keep = (full >= lo - step) & (full <= hi + step)
    grid = full[keep]
    if len(grid) < 2:
        grid = full[max(0, np.searchsorted(full, lo) - 1):][:2]
    return grid


class TestColumns(NamedTuple):
    """Scaled regressors of one test on an alpha grid.

    X (G, 4, n): (a, u, filter(|v|^alpha sign v), filter(sign v)) * scale / force_scale at
    the kept samples; dX (G, 4, n) their alpha-derivative (only the damping column moves);
    valid (n-1,) 1 for consecutive pairs that both enter the likelihood. source, scale,
    force_scale, noise_mass_kg: the prepared test and units they came from and the plug-in
    mass, so that `lagged` can take the accelerometer's noise out of a recorded test's moments
    as the fit does (inference._statistics.acceleration_noise_correction).
    """

    __test__ = False

    X: np.ndarray
    dX: np.ndarray
    valid: np.ndarray
    grid: np.ndarray
    source: PreparedTest | None = None
    scale: np.ndarray | None = None
    force_scale: float = 1.0
    noise_mass_kg: float = float("nan")

    @property
    def n_pairs(self) -> float:
        return float(self.valid.sum())


def regressor_columns(test: PreparedTest, grid: np.ndarray, scale: np.ndarray, force_scale: float,
                      noise_mass_kg: float | None = None) -> TestColumns:
    """TestColumns of a prepared (recorded or candidate) test: the fit's scaled regressors.
    noise_mass_kg: Me for the accelerometer-noise correction (None: the scale of Me)."""
    scale = np.asarray(scale, dtype=float)
    mass = float(scale[0] if noise_mass_kg is None else noise_mass_kg)
    return TestColumns(*scaled_regressors(test, grid, scale, force_scale), grid, test, scale, float(force_scale), mass)


def lagged(columns: TestColumns, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lagged moments (G, 3, 5, 5) of z = (y, x) and their alpha-slopes, for a scaled response y (n,)
    (y a function of the test only, not of alpha); for a recorded test with a known
    accelerometer noise, less that noise's share (inference._statistics.acceleration_noise_correction)."""
    moments, slopes = response_moments(y, columns.X, columns.dX, columns.valid)
    source = columns.source
    if source is not None and source.acceleration_noise_known:
        moments = moments - acceleration_noise_correction(
            source, moments, columns.valid, columns.grid, columns.scale, columns.force_scale, columns.noise_mass_kg
        )[None]
    return moments, slopes


def hermite(values: np.ndarray, slopes: np.ndarray, grid: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Cubic Hermite interpolation of tabulated values (G, ...) with alpha-slopes at alpha (S,),
    (S, ...): f = h00 f_g + h10 step f'_g + h01 f_(g+1) + h11 step f'_(g+1), s = (alpha - a_g)/step."""
    step = grid[1] - grid[0]
    position = (np.asarray(alpha, dtype=float) - grid[0]) / step
    g = np.clip(np.floor(position).astype(int), 0, len(grid) - 2)
    s = (position - g).reshape((-1,) + (1,) * (values.ndim - 1))
    s2, s3 = s * s, s * s * s
    return ((2 * s3 - 3 * s2 + 1) * values[g] + (s3 - 2 * s2 + s) * step * slopes[g]
            + (-2 * s3 + 3 * s2) * values[g + 1] + (s3 - s2) * step * slopes[g + 1])


def whiten(moments: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """W = M0 - phi (M1 + M1') + phi^2 M2 for moments (..., 3, 5, 5) and phi (...)."""
    p = phi[..., None, None]
    m0, m1, m2 = moments[..., 0, :, :], moments[..., 1, :, :], moments[..., 2, :, :]
    return m0 - p * (m1 + np.swapaxes(m1, -1, -2)) + p * p * m2


def _logdet_spd(M: np.ndarray) -> np.ndarray:
    """log|M| of symmetric positive definite matrices (..., k, k), from their Cholesky factors."""
    return 2.0 * np.sum(np.log(np.diagonal(np.linalg.cholesky(M), axis1=-2, axis2=-1)), axis=-1)


class Terms(NamedTuple):
    """c (...), h (..., 4), H (..., 4, 4) of the module docstring."""

    c: np.ndarray
    h: np.ndarray
    H: np.ndarray


def ignored_outer(post: DesignPosterior, H: np.ndarray) -> np.ndarray | None:
    """sum_k (s_k mu_k)^2 (H e_k)(H e_k)' per draw, H (S, ..., n, n) with mu's four coefficients
    first (a test's H_j, or its Fisher information on (mu, delta alpha)); None without an ignored
    spread. Summed over tests it is V, and Q^-1 V Q^-1 is what a shared coefficient's ignored
    between-test spread adds to mu's covariance (inference._collapsed.draw_coefficients)."""
    if post.ignored_spread is None:
        return None
    out = np.zeros(H.shape)
    for k, relative_sd in enumerate(post.ignored_spread):
        if relative_sd > 0.0:
            scale = (relative_sd * post.mu[:, k]).reshape((-1,) + (1,) * (H.ndim - 2))
            column = H[..., :, k] * scale
            out += column[..., :, None] * column[..., None, :]
    return out


def ignored_variance(V: np.ndarray, H_sum: np.ndarray, prior_sd: np.ndarray) -> np.ndarray:
    """diag(Q^-1 V Q^-1) (..., 4) with Q = S0^-1 + H_sum (..., 4, 4)."""
    Q_inv = np.linalg.inv(H_sum + np.diag(1.0 / prior_sd**2))
    return np.einsum("...ki,...ij,...kj->...k", Q_inv, V, Q_inv)


def _last(x: np.ndarray, k: int) -> np.ndarray:
    """Move the k trailing matrix/vector axes to the front (the batch-last layout of
    bayes_sst.inference._smalllinalg, whose unrolled factorisations vectorise over the batch)."""
    return np.moveaxis(x, tuple(range(-k, 0)), tuple(range(k)))


def _first(x: np.ndarray, k: int) -> np.ndarray:
    """Inverse of _last: the k leading axes go back to the end."""
    return np.moveaxis(x, tuple(range(k)), tuple(range(-k, 0)))


def collapsed_terms(W: np.ndarray, n_pairs, sigma: np.ndarray, rho: np.ndarray) -> Terms:
    """Per-test Gaussian pieces from whitened moments W (..., 5, 5), sigma (...), rho (..., 4),
    all broadcast to W's batch shape. With L L' = B and [G | g] = L^-1 [D A | D b]:
    H = A - G'G, h = b - G'g, (D b)' B^-1 (D b) = g'g."""
    batch = W.shape[:-2]
    Wt = _last(W, 2)
    var = np.broadcast_to(sigma * sigma, batch)
    rho_t = _last(np.broadcast_to(rho, batch + (4,)), 1)
    yy = Wt[0, 0]
    A = Wt[1:, 1:] / var
    b = Wt[1:, 0] / var
    DA = rho_t[:, None] * A
    B = np.eye(4).reshape((4, 4) + (1,) * len(batch)) + DA * rho_t[None, :]
    L = sl.cholesky(B, np)
    Gg = sl.solve_lower(L, np.concatenate([DA, (rho_t * b)[:, None]], axis=1), np)
    G, g = Gg[:, :4], Gg[:, 4]
    H = A - np.sum(G[:, :, None] * G[:, None, :], axis=0)
    h = b - np.sum(G * g[:, None], axis=0)
    c = (-0.5 * sl.log_det_from_cholesky(L, np) + 0.5 * np.sum(g * g, axis=0)
         - 0.5 * n_pairs * (LOG_2PI + np.log(var)) - 0.5 * yy / var)
    return Terms(c, _first(h, 1), _first(H, 2))


def population(c_sum, h_sum, H_sum, prior_mean, prior_sd):
    """Conditional mean Q^-1 r (..., 4), variances diag(Q^-1) (..., 4) and log p(y | hyper)
    (module docstring) from summed test terms (batched)."""
    precision = 1.0 / prior_sd**2
    batch = H_sum.shape[:-2]
    Q = _last(H_sum, 2) + np.diag(precision).reshape((4, 4) + (1,) * len(batch))
    r = _last(h_sum, 1) + (precision * prior_mean).reshape((4,) + (1,) * len(batch))
    L = sl.cholesky(Q, np)
    mean = sl.cho_solve(L, r, np)
    # diag(Q^-1)_k = sum_i ((L^-1)_ik)^2, from the columns of L^-1
    eye = np.broadcast_to(np.eye(4).reshape((4, 4) + (1,) * len(batch)), (4, 4) + batch)
    L_inv = sl.solve_lower(L, eye, np)
    variance = np.sum(L_inv * L_inv, axis=0)
    log_lik = (c_sum - np.sum(np.log(prior_sd)) - 0.5 * sl.log_det_from_cholesky(L, np)
               + 0.5 * np.sum(r * mean, axis=0) - 0.5 * np.sum(precision * prior_mean**2))
    return _first(mean, 1), _first(variance, 1), log_lik


def friction_scaling(post: DesignPosterior, columns: TestColumns) -> np.ndarray | None:
    """s_j (S,) = 1 + (kappa_s - 1)(L_j - 1)/L_j of a recorded test, L_j its bearing-load ratio
    (the factor its Coulomb column already carries); None where nothing scales (no gain sampled,
    or a test without payload, L_j = 1)."""
    load = 1.0 if columns.source is None else float(columns.source.friction_load)
    if post.gain is None or load == 1.0:
        return None
    return payload_friction_factor(post.gain, load_share(load))


def _scale_row_and_column(M: np.ndarray, index: int, factors: np.ndarray | None) -> np.ndarray:
    """M (S, k, k) with row and column `index` multiplied by factors (S,): E M E."""
    if factors is None:
        return M
    M = M.copy()
    M[:, index, :] *= factors[:, None]
    M[:, :, index] *= factors[:, None]
    return M


def existing_terms(post: DesignPosterior, columns: Sequence[TestColumns], responses: Sequence[np.ndarray],
                   with_ignored: bool = False):
    """Summed terms of the recorded tests for every draw, (S,), (S, 4), (S, 4, 4); a payload
    test's Coulomb column scaled by its draw's friction gain (friction_scaling). with_ignored:
    return (terms, V) with V the recorded tests' sum of ignored_outer (None without one)."""
    c = np.zeros(post.n_draws)
    h = np.zeros((post.n_draws, 4))
    H = np.zeros((post.n_draws, 4, 4))
    V = None if post.ignored_spread is None else np.zeros((post.n_draws, 4, 4))
    for j, (cols, y) in enumerate(zip(columns, responses)):
        moments, slopes = lagged(cols, y)
        W = whiten(hermite(moments, slopes, cols.grid, post.alpha), post.phi[:, j])
        W = _scale_row_and_column(W, 4, friction_scaling(post, cols))  # z = (y, a, u, damping, sign)
        t = collapsed_terms(W, cols.n_pairs, post.sigma[:, j], post.rho)
        c += t.c
        h += t.h
        H += t.H
        if V is not None:
            V += ignored_outer(post, t.H)
    return (Terms(c, h, H), V) if with_ignored else Terms(c, h, H)


class NoiseSource(NamedTuple):
    """Where an added test's AR(1) residual comes from: recorded test `twin` (its per-draw
    phi_j, sigma_j), with sigma_j multiplied by `inflation` >= 1."""

    twin: int
    inflation: float


def noise_sources(prepared: Sequence[PreparedTest], kinds, frequencies, amplitudes) -> list[NoiseSource]:
    """The residual each new test is given (the model has no law for a test it has not seen).

    Twin: the recorded test nearest in frequency first (the low-pass band, the servo and oil
    column dynamics scale with it), then amplitude and kind:
    d = (dlog f)^2 + 0.1 (dlog A)^2 + 0.1 [kind differs].
    Inflation: outside the recorded envelope the residual is assumed to grow in proportion to
    how far the test goes, max(1, f/f_max, f_min/f) * max(1, a_peak/a_peak_max) *
    max(1, v_peak_min/v_peak), with the peak commanded acceleration and velocity. On the
    virtual table a 3 Hz triangle at the acceleration limit left a residual 2.6 times that of
    the nearest recorded 2 Hz sine, and slow tests (peak speed a few cm/s, where friction and
    |v|^alpha damping look alike) left alpha and Fmu on a ridge the refit could not sample;
    without the inflation the design trusted such tests far too much.
    """
    from bayes_sst.design._candidates import peak_motion

    f0 = np.array([t.frequency_hz for t in prepared])
    a0 = np.array([t.amplitude_m for t in prepared])
    k0 = np.array([t.kind for t in prepared])
    peaks0 = np.array([peak_motion(t.kind, t.frequency_hz, t.amplitude_m) for t in prepared])
    out = []
    for kind, f, a in zip(kinds, frequencies, amplitudes):
        distance = (np.log(f0 / f)) ** 2 + 0.1 * (np.log(a0 / a)) ** 2 + 0.1 * (k0 != kind)
        _, speed, acc = peak_motion(kind, f, a)
        inflation = (max(1.0, f / f0.max(), f0.min() / f) * max(1.0, acc / peaks0[:, 2].max())
                     * max(1.0, peaks0[:, 1].min() / speed))
        out.append(NoiseSource(int(np.argmin(distance)), float(inflation)))
    return out


def ar1_path(rng: np.random.Generator, phi: float, sigma: float, n: int) -> np.ndarray:
    """A stationary AR(1) path e_t = phi e_(t-1) + w_t, w ~ N(0, sigma^2)."""
    w = rng.standard_normal(n) * sigma
    e = np.empty(n)
    e[0] = w[0] / math.sqrt(max(1.0 - phi * phi, 1e-6))
    for t in range(1, n):
        e[t] = phi * e[t - 1] + w[t]
    return e


def mixture_quantiles(weights: np.ndarray, means: np.ndarray, sds: np.ndarray, levels=(0.05, 0.95),
                      iterations: int = 20, tolerance: float = 1e-10) -> np.ndarray:
    """Quantiles of sum_s w_s N(m_s, sd_s^2); weights (..., S) summing to 1, means/sds (..., S);
    returns (len(levels), ...). Newton's method on the mixture CDF from the moment-matched
    Gaussian's quantile, each step kept inside a bisection bracket so it cannot diverge. A
    quantile whose CDF is within `tolerance` of its level is final.

    Why final: at convergence the bracket closes onto x, and a Newton step that rounds to x
    itself fails the strict bracket test; the bisection fallback then threw the converged x
    to the middle of its bracket. In a batch every element went on iterating until the last
    did, so some ended far off: on the example's design, 296 of 576 calls returned a CDF
    0.2-1.7 % away from its level (the 5 % quantile read at 3.3-6.7 %)."""
    centre = np.sum(weights * means, axis=-1)
    spread = np.sqrt(np.maximum(np.sum(weights * (sds**2 + means**2), axis=-1) - centre**2, 0.0))
    out = []
    for level in levels:
        lo = np.min(means - 10 * sds, axis=-1)
        hi = np.max(means + 10 * sds, axis=-1)
        x = np.clip(centre + np.sqrt(2) * erfinv(2 * level - 1) * spread, lo, hi)
        for _ in range(iterations):
            z = (x[..., None] - means) / sds
            error = np.sum(weights * ndtr(z), axis=-1) - level
            open_ = np.abs(error) >= tolerance
            if not np.any(open_):
                break
            density = np.sum(weights * np.exp(-0.5 * z * z) / (sds * np.sqrt(2 * np.pi)), axis=-1)
            lo = np.where(open_ & (error < 0), x, lo)
            hi = np.where(open_ & (error > 0), x, hi)
            step = x - error / np.maximum(density, 1e-300)
            x = np.where(open_, np.where((step > lo) & (step < hi), step, 0.5 * (lo + hi)), x)
        out.append(x)
    return np.stack(out)


def half_widths_from_draws(post: DesignPosterior) -> dict[str, float]:
    """Current relative half-widths (q95 - q05)/2/mean of the posterior draws."""
    out = {}
    for name in PARAMETERS:
        x = post.alpha if name == "alpha" else post.mu[:, COEFFICIENTS.index(name)]
        q05, q95 = np.quantile(x, [0.05, 0.95])
        out[name] = float((q95 - q05) / 2 / abs(x.mean()))
    return out


class NewTest(NamedTuple):
    """An added test as the engine sees it: its columns and where its residual comes from."""

    columns: TestColumns
    noise: NoiseSource


def simulate_response(rng, columns: TestColumns, alpha: float, theta: np.ndarray, phi: float, sigma: float):
    """Scaled y = X(alpha) theta + e, e a stationary AR(1) path over the test's kept samples."""
    X = hermite(columns.X, columns.dX, columns.grid, np.array([alpha]))[0]
    return theta @ X + ar1_path(rng, phi, sigma, X.shape[-1])


def alpha_laplace(post: DesignPosterior, base_info: np.ndarray, tests: Sequence[NewTest]):
    """Per draw and number of added tests n, the Fisher (linearised) variance of alpha given the
    other hyperparameters, v (N+1, S), and the regression of mu on alpha, g (N+1, S, 4):
    v = C[4, 4], g = C[:4, 4]/C[4, 4], C = (prior + base_info + sum_(j<=n) I_j)^-1."""
    prior = np.diag(np.concatenate([1.0 / post.prior_sd**2, [1.0 / post.alpha_prior_sd**2]]))
    info = base_info + prior
    totals = [info]
    for test in tests:
        info = info + fisher_information(post, test.columns, test.noise)
        totals.append(info)
    cov = np.linalg.inv(np.stack(totals))
    v = cov[..., 4, 4]
    return v, cov[..., :4, 4] / v[..., None]


def preposterior_curve(post: DesignPosterior, old: Terms, tests: Sequence[NewTest], *, n_outcomes: int,
                       seed: int, base_info: np.ndarray | None = None, min_components: int = 128,
                       weight_coverage: float = 0.999, truths: np.ndarray | None = None,
                       old_ignored: np.ndarray | None = None):
    """Predicted relative half-widths after adding tests[:n], n = 0..len(tests), over outcomes.

    Returns (half (R, N+1, 5) in PARAMETERS order, ess (R, N+1)): for each outcome r a
    posterior draw plays the truth; the added tests get theta_j ~ N(mu_r, diag(rho_r^2)) and
    AR(1) noise with the (phi, sigma) of their nearest recorded test in that draw; the
    updated posterior reweights all draws (module docstring). `truths` (indices of draws)
    fixes which draws play the truth, for diagnosis.

    With an ignored spread (post.ignored_spread; old_ignored the recorded tests' V from
    existing_terms) each component's covariance gains Q'^-1 V' Q'^-1, V' summed over the
    recorded and the added tests, and an added test's true coefficients vary by that spread.

    With many added tests the reweighting rests on few draws and their spread in alpha
    understates alpha's remaining uncertainty (and that of Ce, Fmu, which move with it).
    When base_info (S, 5, 5), the Fisher information of the recorded tests, is given, each
    component's alpha-variance is topped up to the Laplace value: with v_s, g_s from
    alpha_laplace and V_w the weighted variance of the draws' alpha, component s gets
    e_s = max(v_s - V_w, 0) more variance in alpha and e_s g_s g_s' more in mu.

    The mixture's quantiles are taken over the heaviest draws that together hold
    `weight_coverage` of the weight, per row with a test added (at least min_components, rounded
    up to min_components times a power of two so that rows of like size go together).
    Why not a fixed number: on a 20-test series one added test leaves the weights nearly flat
    (importance ESS about 600 of 1000 draws), and the 128 heaviest of them are a cluster, not
    the posterior: the predicted Fmu half-width after one added test on the example series came
    out 2.36 % against 3.35 % from every draw (alpha 2.01 % against 3.00 %), so the curve fell
    at the first test by what the truncation cut off and the design promised too much.
    """
    rng = np.random.default_rng(seed)
    S, N = post.n_draws, len(tests)
    if truths is None:
        truths = rng.choice(S, size=n_outcomes, replace=n_outcomes > S)
    # draws in random order, so that where weights tie the heaviest components kept for the
    # quantiles are a random subset, not the first chain's start
    order = rng.permutation(S)
    truths = np.argsort(order)[np.asarray(truths)]
    post = post.subset(order)
    old = Terms(old.c[order], old.h[order], old.H[order])
    ignored = post.ignored_spread is not None and old_ignored is not None
    if ignored:
        old_ignored = old_ignored[order]
    if base_info is not None:
        base_info = base_info[order]
    _, _, old_loglik = population(old.c, old.h, old.H, post.prior_mean, post.prior_sd)
    half = np.empty((len(truths), N + 1, len(PARAMETERS)))
    ess = np.empty((len(truths), N + 1))
    alpha_index = PARAMETERS.index("alpha")
    coefficient_slots = [PARAMETERS.index(name) for name in COEFFICIENTS]
    if base_info is not None:
        v_alpha, gain = alpha_laplace(post, base_info, tests)
    else:
        v_alpha, gain = np.zeros((N + 1, S)), np.zeros((N + 1, S, 4))
    n_pairs = np.array([test.columns.n_pairs for test in tests])
    grid = tests[0].columns.grid if tests else np.array([0.0, 1.0])
    if any(not np.array_equal(test.columns.grid, grid) for test in tests):
        raise ValueError("all added tests must share one alpha grid")
    for r, s_true in enumerate(truths):
        moments = np.empty((N, len(grid), 3, 5, 5))
        slopes = np.empty_like(moments)
        phis, sigmas = np.empty(N), np.empty(N)
        for k, test in enumerate(tests):
            phis[k] = post.phi[s_true, test.noise.twin]
            sigmas[k] = post.sigma[s_true, test.noise.twin] * test.noise.inflation
            theta = post.mu[s_true] + post.rho[s_true] * rng.standard_normal(4)
            if ignored:
                theta = theta + post.ignored_spread * np.abs(post.mu[s_true]) * rng.standard_normal(4)
            y = simulate_response(rng, test.columns, float(post.alpha[s_true]), theta, phis[k], sigmas[k])
            moments[k], slopes[k] = lagged(test.columns, y)
        # all added tests at once: (G, N, 3, 5, 5) interpolated at every draw's alpha; the new
        # tests' own noise parameters are taken as known (each test pins its own phi and
        # sigma from its samples), so only alpha and the spreads are updated by reweighting
        interpolated = hermite(np.swapaxes(moments, 0, 1), np.swapaxes(slopes, 0, 1), grid, post.alpha)
        W = whiten(interpolated, np.broadcast_to(phis, (S, N)))
        t = collapsed_terms(W, n_pairs[None, :], np.broadcast_to(sigmas, (S, N)), post.rho[:, None, :])
        zero = Terms(np.zeros((1, S)), np.zeros((1, S, 4)), np.zeros((1, S, 4, 4)))
        cum = [np.concatenate([z, np.cumsum(np.swapaxes(x, 0, 1), axis=0)]) for z, x in zip(zero, t)]
        mean, cov, loglik = population(old.c + cum[0], old.h + cum[1], old.H + cum[2],
                                       post.prior_mean, post.prior_sd)  # (N+1, S, ...)
        log_w = loglik - old_loglik
        log_w -= log_w.max(axis=-1, keepdims=True)
        w = np.exp(log_w)
        w /= w.sum(axis=-1, keepdims=True)
        ess[r] = 1.0 / np.sum(w * w, axis=-1)
        alpha_mean = w @ post.alpha  # (N+1,)
        alpha_var = w @ post.alpha**2 - alpha_mean**2
        extra = np.maximum(v_alpha - alpha_var[:, None], 0.0)  # (N+1, S)
        variances = cov + extra[..., None] * gain**2  # (N+1, S, 4)
        if ignored:
            added = np.concatenate([np.zeros((1, S, 4, 4)),
                                    np.cumsum(np.swapaxes(ignored_outer(post, t.H), 0, 1), axis=0)])
            variances = variances + ignored_variance(old_ignored + added, old.H + cum[2], post.prior_sd)
        # the quantiles of the mixture from its heaviest components: once the added tests
        # speak, a few dozen draws carry nearly all the weight; rows are taken in groups of
        # like size, for speed. Row 0 (nothing added) has equal weights and so takes every
        # draw, the same mixture for every outcome and both curves (a fixed number of the
        # heaviest draws, tied there, was a random subset: on a 20-test series the two
        # curves' starting points differed by 12 %, Fmu 2.82 % and 2.50 % for a posterior
        # half-width of 2.80 %)
        ranked = np.argsort(-w, axis=-1)
        covered = np.cumsum(np.take_along_axis(w, ranked, axis=-1), axis=-1)
        needed = np.sum(covered < weight_coverage, axis=-1) + 1
        sizes = np.minimum(S, min_components * 2 ** np.ceil(np.log2(np.maximum(needed / min_components, 1.0))))
        sizes[0] = S
        for size in np.unique(sizes):
            rows = np.flatnonzero(sizes == size)
            top = ranked[rows, :int(size)]  # (n, K)
            wk = np.take_along_axis(w[rows], top, axis=-1)
            wk /= wk.sum(axis=-1, keepdims=True)
            mk = np.swapaxes(np.take_along_axis(mean[rows], top[..., None], axis=1), -1, -2)  # (n, 4, K)
            vk = np.swapaxes(np.take_along_axis(variances[rows], top[..., None], axis=1), -1, -2)
            q = mixture_quantiles(wk[:, None, :], mk, np.sqrt(vk))
            centre = np.sum(wk[:, None, :] * mk, axis=-1)
            half[r][np.ix_(rows, coefficient_slots)] = (q[1] - q[0]) / 2 / np.abs(centre)
            ek = np.take_along_axis(extra[rows], top, axis=-1)
            alpha_sd = np.sqrt(ek + 1e-12 * alpha_mean[rows, None] ** 2)
            qa = mixture_quantiles(wk, post.alpha[top], alpha_sd)
            half[r][rows, alpha_index] = (qa[1] - qa[0]) / 2 / np.abs(alpha_mean[rows])
    return half, ess


def fisher_information(post: DesignPosterior, columns: TestColumns, noise: "NoiseSource | int") -> np.ndarray:
    """I_j (S, 5, 5) on (mu, delta alpha) of one test after integrating its theta_j out
    (module docstring); residual from `noise` (a NoiseSource, or a recorded test's index)."""
    if not isinstance(noise, NoiseSource):
        noise = NoiseSource(int(noise), 1.0)
    twin = noise.twin
    g = len(columns.grid)
    z = np.concatenate([columns.X, columns.dX[:, 2:3]], axis=1)  # (G, 5, n): x1..x4, dx3/dalpha
    # d/dalpha of the table, by finite differences of the grid (the info is smooth in alpha)
    moments = pair_moments(z, z, columns.valid)
    slopes = np.gradient(moments, columns.grid, axis=0) if g > 2 else np.zeros_like(moments)
    M = whiten(hermite(moments, slopes, columns.grid, post.alpha), post.phi[:, twin])
    M = _scale_row_and_column(M, 3, friction_scaling(post, columns))  # z = (a, u, damping, sign, d)
    M = M / ((post.sigma[:, twin] * noise.inflation) ** 2)[:, None, None]
    ce = post.mu[:, 2]
    M[:, 4, :] *= ce[:, None]
    M[:, :, 4] *= ce[:, None]
    A = M[:, :4, :4]
    Mx = M[:, :4, :]
    D = post.rho
    B = np.eye(4) + D[:, :, None] * A * D[:, None, :]
    DMx = D[:, :, None] * Mx
    return M - np.swapaxes(DMx, -1, -2) @ np.linalg.solve(B, DMx)


def fisher_half_widths(post: DesignPosterior, info: np.ndarray, ignored: np.ndarray | None = None) -> np.ndarray:
    """Relative half-widths (..., 5) in PARAMETERS order from total information (..., S, 5, 5):
    Z90 * sqrt(mean_s cov_s) / |mean|, prior precision added. ignored (..., S, 5, 5): the
    tests' summed ignored_outer of their information, whose C V C joins the covariance C (a
    shared coefficient's ignored between-test spread, as in preposterior_curve)."""
    # in the prior's units: cov = P (P I P + 1)^-1 P with P the prior sds, I the information.
    # Why not inv(I + P^-2): its entries span 1e-12 to 1e12 in SI units, and for a run of one
    # test the plain inverse gave negative variances (NaN in design.json); here every
    # eigenvalue of (P I P + 1) is at least 1, and a direction the tests leave undetermined
    # keeps its prior variance
    prior_sd = np.concatenate([post.prior_sd, [post.alpha_prior_sd]])
    whitened = info * prior_sd[:, None] * prior_sd[None, :]
    whitened = 0.5 * (whitened + np.swapaxes(whitened, -1, -2))
    eigenvalues, vectors = np.linalg.eigh(whitened)
    gain = 1.0 / (1.0 + np.maximum(eigenvalues, 0.0))
    cov_diag = np.einsum("...ij,...j,...ij->...i", vectors, gain, vectors) * prior_sd**2
    if ignored is not None:
        scaled_vectors = vectors * prior_sd[:, None]
        cov = np.einsum("...ij,...j,...kj->...ik", scaled_vectors, gain, scaled_vectors)
        cov_diag = cov_diag + np.einsum("...ij,...jk,...ik->...i", cov, ignored, cov)
    sd = np.sqrt(np.mean(cov_diag, axis=-2))  # (..., 5): mu1..mu4, alpha
    centre = np.concatenate([np.abs(post.mu.mean(axis=0)), [abs(post.alpha.mean())]])
    rel = Z90 * sd / centre
    # reorder (Me, Ke, Ce, Fmu, alpha) -> PARAMETERS
    order = [0, 1, 2, 4, 3]
    return rel[..., order]
