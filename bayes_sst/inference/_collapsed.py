"""Collapsed likelihood of the hierarchical AR(1) force model, in pure JAX.

Model, per test j (scaled units, see _statistics.py):

    y_j = X_j(alpha) theta_j + e_j,     e_jt = phi_j e_j(t-1) + w_jt,   w ~ N(0, sigma_j^2)
    theta_j ~ N(mu, T),  T = diag(rho^2)             (test-to-test variation)
    mu ~ N(m0, S0),      S0 = diag(s0^2)             (population values)

theta_j and mu enter linearly and with Gaussian priors, so both are integrated out exactly
(a Rao-Blackwellised, "collapsed" model): the sampler explores only alpha, rho, phi_j,
sigma_j, and theta_j, mu are drawn afterwards from their exact Gaussian conditionals.

Per test, with A = X'X/sigma^2, b = X'y/sigma^2 (AR-whitened moments), D = diag(rho) and
B = I + D A D (well conditioned for any rho >= 0):

    log p(y_j | mu) = c_j + h_j' mu - 1/2 mu' H_j mu
    c_j = -1/2 log|B| + 1/2 (Db)' B^-1 (Db) - n_j/2 log(2 pi sigma^2) - y'y/(2 sigma^2)
    H_j = A - A D B^-1 D A          (= (A^-1 + T)^-1)
    h_j = b - A D B^-1 D b          (= (I + A T)^-1 b)

and with Q = S0^-1 + sum H_j, r = S0^-1 m0 + sum h_j:

    log p(y | alpha, rho, phi, sigma) = sum c_j - 1/2 log|S0| - 1/2 log|Q|
                                        + 1/2 r' Q^-1 r - 1/2 m0' S0^-1 m0
    mu | rest ~ N(Q^-1 r, Q^-1),   theta_j | mu, rest ~ N(mu + P_j^-1 (b_j - A_j mu), P_j^-1),
    P_j^-1 = D B_j^-1 D.

test_terms evaluates H_j and h_j in forms without the subtractions above (see there), and the
noise sd entering A, b, c is sqrt(sigma^2 + floor^2) (RELATIVE_NOISE_FLOOR).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

import bayes_sst._jaxconfig  # noqa: F401  (float64 before any array)
from bayes_sst.inference import _smalllinalg as sl

LOG_2PI = 1.8378770664093453


DAMPING = 3  # index of the damping column in z = (y, a, u, |v|^alpha sign v, sign v)


class MomentTable(NamedTuple):
    """The lagged moments in the form the likelihood reads them, tests on the last axis.

    Whitening needs only the symmetric lag sums S = (M0, M1 + M1', M2), and only row and
    column DAMPING of them depend on alpha (see _statistics.py for the interpolation):

    constant : (3, 5, 5, J) S with row and column DAMPING zeroed;
    cross : (G-1, 3, 4, 4, J) S of the damping column's four Hermite basis columns with
        (y, a, u, sign), per grid interval;
    gram : (G-1, 3, 4, 4, J) S of the basis columns with each other.
    """

    constant: jax.Array
    cross: jax.Array
    gram: jax.Array
    n_pairs: jax.Array  # (J,)
    alpha_start: float
    alpha_step: float
    noise_floor: float = 0.0  # see RELATIVE_NOISE_FLOOR


# The likelihood's noise sd is sqrt(sigma^2 + floor^2), floor = this share of the RMS force.
# Why: the collapsed terms subtract moment sums of order (force/noise)^2 * n, so their
# precision falls with the square of the signal-to-noise ratio; measured on the virtual table
# with 10 N of white force noise (1.6 N after the low-pass, 3e-5 of the RMS force) the
# population draws came out 100-4700 % off while 30 N (8e-5) was still right. A floor of 1e-4
# of the RMS force keeps every fit on the right side of that and widens no realistic one:
# at the twin's default noise (about 3e-3 of the RMS force after the low-pass) it changes the
# noise variance by 0.1 %.
RELATIVE_NOISE_FLOOR = 1e-4


def compact_table(moments, damping_cross, damping_gram, n_pairs, alpha_grid, xp=jnp,
                  noise_floor: float = 0.0) -> MomentTable:
    """MomentTable from lagged moments (J, G, 3, 5, 5) and the damping cells (J, G-1, 3, 4, 4)
    of a LaggedMoments."""
    from bayes_sst.inference._statistics import symmetric_lag_sums

    alpha_grid = np.asarray(alpha_grid, dtype=float)
    constant = symmetric_lag_sums(np.asarray(moments, dtype=float)[:, 0])
    constant[..., DAMPING, :] = 0.0
    constant[..., :, DAMPING] = 0.0
    return MomentTable(
        constant=xp.asarray(np.moveaxis(constant, 0, -1)),
        cross=xp.asarray(np.moveaxis(np.asarray(damping_cross, dtype=float), 0, -1)),
        gram=xp.asarray(np.moveaxis(np.asarray(damping_gram, dtype=float), 0, -1)),
        n_pairs=xp.asarray(np.asarray(n_pairs, dtype=float)),
        alpha_start=float(alpha_grid[0]),
        alpha_step=float(alpha_grid[1] - alpha_grid[0]),
        noise_floor=float(noise_floor),
    )


def moment_table(lagged, xp=jnp) -> MomentTable:
    """MomentTable from a LaggedMoments (whose response is scaled by the RMS force, so that the
    noise floor is RELATIVE_NOISE_FLOOR in its units)."""
    return compact_table(lagged.moments, lagged.damping_cross, lagged.damping_gram, lagged.n_pairs,
                         lagged.alpha_grid, xp, noise_floor=RELATIVE_NOISE_FLOOR)


class TestTerms(NamedTuple):
    """Per-test Gaussian pieces of the collapsed likelihood (see module docstring); tests last."""

    __test__ = False  # not a pytest class

    c: jax.Array  # (J,)
    h: jax.Array  # (4, J)
    H: jax.Array  # (4, 4, J)
    A: jax.Array  # (4, 4, J)
    b: jax.Array  # (4, J)
    B_chol: jax.Array  # (4, 4, J)


def hermite_weights(table: MomentTable, alpha, xp=jnp):
    """Grid interval g and the cubic-Hermite weights at alpha: with s = (alpha - alpha_g)/step,
    M(alpha) = h00 M_g + h10 step M'_g + h01 M_(g+1) + h11 step M'_(g+1)."""
    n_cells = table.cross.shape[0]
    position = (alpha - table.alpha_start) / table.alpha_step
    g = xp.clip(xp.floor(position).astype(xp.int32), 0, n_cells - 1)
    s = position - g
    s2, s3 = s * s, s * s * s
    return g, xp.stack([2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2])


def whitened_moments(moments, phi, xp=jnp):
    """W_j = M0 - phi (M1 + M1') + phi^2 M2: moments of z_t - phi z_(t-1), (5, 5, J)."""
    m0, m1, m2 = moments[0], moments[1], moments[2]
    return m0 - phi * (m1 + xp.swapaxes(m1, 0, 1)) + phi * phi * m2


def whitened_at(table: MomentTable, alpha, phi, xp=jnp):
    """W_j(alpha, phi_j) = S0 - phi_j S1 + phi_j^2 S2 at alpha, (5, 5, J): the damping column
    interpolated as d = sum_k w_k K_k, so its row is sum_k w_k S(K_k, .) and its diagonal
    w' S(K, K) w (see MomentTable)."""
    g, weights = hermite_weights(table, alpha, xp)
    lag_weights = xp.stack([xp.ones_like(phi), -phi, phi * phi])  # (3, J)
    cross = xp.sum(table.cross[g] * lag_weights[:, None, None, :], axis=0)  # (4, 4, J)
    gram = xp.sum(table.gram[g] * lag_weights[:, None, None, :], axis=0)
    others = xp.einsum("k,koj->oj", weights, cross)  # (y, a, u, sign)
    diagonal = xp.einsum("k,l,klj->j", weights, weights, gram)
    row = xp.stack([others[0], others[1], others[2], diagonal, others[3]])
    base = xp.sum(table.constant * lag_weights[:, None, None, :], axis=0)
    unit = np.zeros(5)
    unit[DAMPING] = 1.0
    e_row, e_col = unit[:, None, None], unit[None, :, None]
    return base + e_row * row[None, :, :] + e_col * row[:, None, :] - e_row * e_col * row[DAMPING]


# spreads below this (scaled units, i.e. relative to the prior centre) are raised to it inside
# test_terms, so that D is invertible; a coefficient shared by all tests (spread 0) then varies
# by 1e-4 % between tests, far below any posterior sd
SPREAD_FLOOR = 1e-6


def test_terms(whitened, n_pairs, sigma, rho, xp=jnp) -> TestTerms:
    """c_j, h_j, H_j of the module docstring, for all tests at once (tests last).

    With L the Cholesky factor of B, Y = L^-1 (so B^-1 = Y'Y) and g = L^-1 D b:

        H = D^-1 (I - B^-1) D^-1,   h = D^-1 B^-1 D b,   (Db)' B^-1 (Db) = g'g.

    Algebraically H = A - A D B^-1 D A and h = b - A D B^-1 D b, but those differences cancel
    two numbers of order A ~ (force/noise)^2 n where the data pin a test's coefficients far
    beyond the between-test spread (D A D >> I), and a force recorded ~1e4 times above its
    noise gave population draws off by a factor of ten; in the forms used here B^-1 is small
    in those directions, and the cancellation moves to the directions the data hardly inform,
    where it costs nothing.
    """
    var = sigma * sigma
    yy = whitened[0, 0]
    A = whitened[1:, 1:] / var
    b = whitened[1:, 0] / var
    rho = xp.maximum(rho, SPREAD_FLOOR)
    DA = rho[:, None, None] * A
    B = xp.eye(4)[:, :, None] + DA * rho[None, :, None]
    B_chol = sl.cholesky(B, xp)
    Db = rho[:, None] * b
    identity = xp.broadcast_to(xp.eye(4)[:, :, None], B.shape)
    Yg = sl.solve_lower(B_chol, xp.concatenate([identity, Db[:, None, :]], axis=1), xp)
    Y, g = Yg[:, :4], Yg[:, 4]
    B_inverse = xp.sum(Y[:, :, None, :] * Y[:, None, :, :], axis=0)
    inverse_rho = 1.0 / rho
    H = (xp.eye(4)[:, :, None] - B_inverse) * (inverse_rho[:, None] * inverse_rho[None, :])[:, :, None]
    h = xp.sum(B_inverse * Db[None, :, :], axis=1) * inverse_rho[:, None]
    c = (
        -0.5 * sl.log_det_from_cholesky(B_chol, xp)
        + 0.5 * xp.sum(g * g, axis=0)
        - 0.5 * n_pairs * (LOG_2PI + 2.0 * xp.log(sigma))
        - 0.5 * yy / var
    )
    return TestTerms(c=c, h=h, H=H, A=A, b=b, B_chol=B_chol)


def population_posterior(terms: TestTerms, prior_mean, prior_sd, xp=jnp):
    """Q and r of the Gaussian conditional mu | rest ~ N(Q^-1 r, Q^-1)."""
    prior_precision = 1.0 / (prior_sd * prior_sd)
    Q = xp.diag(prior_precision) + xp.sum(terms.H, axis=-1)
    r = prior_precision * prior_mean + xp.sum(terms.h, axis=-1)
    return Q, r


def _terms(table, alpha, rho, phi, sigma, xp):
    noise = xp.sqrt(sigma * sigma + table.noise_floor * table.noise_floor)
    return test_terms(whitened_at(table, alpha, phi, xp), table.n_pairs, noise, rho, xp)


def collapsed_log_likelihood(table: MomentTable, alpha, rho, phi, sigma, prior_mean, prior_sd, xp=jnp):
    """log p(y | alpha, rho, phi, sigma) with every theta_j and mu integrated out (scaled units)."""
    terms = _terms(table, alpha, rho, phi, sigma, xp)
    Q, r = population_posterior(terms, prior_mean, prior_sd, xp)
    Q_chol = sl.cholesky_by_columns(Q, xp)
    # r' Q^-1 r = |L^-1 r|^2: one triangular solve instead of two
    whitened_r = sl.solve_lower(Q_chol, r, xp)
    prior_precision = 1.0 / (prior_sd * prior_sd)
    return (
        xp.sum(terms.c)
        - xp.sum(xp.log(prior_sd))
        - 0.5 * sl.log_det_from_cholesky(Q_chol, xp)
        + 0.5 * xp.sum(whitened_r * whitened_r)
        - 0.5 * xp.sum(prior_precision * prior_mean * prior_mean)
    )


def draw_coefficients(normal_mu, normal_theta, table: MomentTable, alpha, rho, phi, sigma,
                      prior_mean, prior_sd, xp=jnp):
    """An exact draw of mu (4,) and every theta_j (J, 4) given the sampled parameters, from
    standard normal deviates normal_mu (4,) and normal_theta (J, 4); also the per-test
    log-likelihood log p(y_j | mu, alpha, rho, phi_j, sigma_j), (J,) (scaled units)."""
    terms = _terms(table, alpha, rho, phi, sigma, xp)
    Q, r = population_posterior(terms, prior_mean, prior_sd, xp)
    Q_chol = sl.cholesky(Q, xp)
    # mu = Q^-1 r + L^-T z has covariance Q^-1
    mu = sl.cho_solve(Q_chol, r, xp) + sl.solve_upper_transposed(Q_chol, normal_mu, xp)
    residual = terms.b - xp.sum(terms.A * mu[None, :, None], axis=1)
    # theta_j = mu + D B^-1 D (b - A mu) + D L^-T z has covariance D B^-1 D
    D = rho[:, None]
    theta = (
        mu[:, None]
        + D * sl.cho_solve(terms.B_chol, D * residual, xp)
        + D * sl.solve_upper_transposed(terms.B_chol, normal_theta.T, xp)
    )
    quadratic = xp.sum(mu[:, None, None] * terms.H * mu[None, :, None], axis=(0, 1))
    per_test = terms.c + xp.sum(terms.h * mu[:, None], axis=0) - 0.5 * quadratic
    return mu, theta.T, per_test
