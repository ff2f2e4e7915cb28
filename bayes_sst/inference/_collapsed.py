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

    Whitening needs only the symmetric combinations S = (M0, M1 + M1', M2), and only row and
    column DAMPING of them depend on alpha; the rest is stored once:

    constant : (3, 5, 5, J) S with row and column DAMPING zeroed;
    cells : (G-1, 4, 3, 5, J) per grid interval g, row DAMPING of S as the four cubic-Hermite
        pieces [S_g, step S'_g, S_(g+1), step S'_(g+1)], so that one dynamic slice and two small
        contractions give the whitened moments at any alpha (about a third of the cost of
        interpolating and whitening the full matrices, gradient included).
    """

    constant: jax.Array
    cells: jax.Array
    n_pairs: jax.Array  # (J,)
    alpha_start: float
    alpha_step: float


def compact_table(moments, slopes, n_pairs, alpha_grid, xp=jnp) -> MomentTable:
    """MomentTable from lagged moments and their alpha-slopes laid out (J, G, 3, 5, 5)."""
    moments, slopes = np.asarray(moments, dtype=float), np.asarray(slopes, dtype=float)

    def symmetric(m):
        return np.stack([m[..., 0, :, :], m[..., 1, :, :] + np.swapaxes(m[..., 1, :, :], -1, -2), m[..., 2, :, :]], axis=-3)

    alpha_grid = np.asarray(alpha_grid, dtype=float)
    step = float(alpha_grid[1] - alpha_grid[0])
    values, derivatives = symmetric(moments), symmetric(slopes)
    constant = values[:, 0].copy()
    constant[..., DAMPING, :] = 0.0
    constant[..., :, DAMPING] = 0.0
    row, row_slope = values[..., DAMPING, :], step * derivatives[..., DAMPING, :]  # (J, G, 3, 5)
    cells = np.stack([row[:, :-1], row_slope[:, :-1], row[:, 1:], row_slope[:, 1:]], axis=2)
    return MomentTable(
        constant=xp.asarray(np.moveaxis(constant, 0, -1)),
        cells=xp.asarray(np.moveaxis(cells, 0, -1)),
        n_pairs=xp.asarray(np.asarray(n_pairs, dtype=float)),
        alpha_start=float(alpha_grid[0]),
        alpha_step=step,
    )


def moment_table(lagged, xp=jnp) -> MomentTable:
    """MomentTable from a LaggedMoments."""
    return compact_table(lagged.moments, lagged.slopes, lagged.n_pairs, lagged.alpha_grid, xp)


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
    n_cells = table.cells.shape[0]
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
    """W_j(alpha, phi_j) = M0 - phi_j (M1 + M1') + phi_j^2 M2 at alpha, (5, 5, J), the
    damping row and column interpolated (see MomentTable)."""
    g, weights = hermite_weights(table, alpha, xp)
    lag_weights = xp.stack([xp.ones_like(phi), -phi, phi * phi])  # (3, J)
    row = xp.einsum("k,klmj->lmj", weights, table.cells[g])
    row = xp.sum(row * lag_weights[:, None, :], axis=0)  # (5, J)
    base = xp.sum(table.constant * lag_weights[:, None, None, :], axis=0)
    unit = np.zeros(5)
    unit[DAMPING] = 1.0
    e_row, e_col = unit[:, None, None], unit[None, :, None]
    return base + e_row * row[None, :, :] + e_col * row[:, None, :] - e_row * e_col * row[DAMPING]


def test_terms(whitened, n_pairs, sigma, rho, xp=jnp) -> TestTerms:
    """c_j, h_j, H_j of the module docstring, for all tests at once (tests last).

    With L the Cholesky factor of B and [G | g] = L^-1 [D A | D b], the pieces are
    H = A - G'G, h = b - G'g, (Db)' B^-1 (Db) = g'g: one triangular solve with five columns.
    """
    var = sigma * sigma
    yy = whitened[0, 0]
    A = whitened[1:, 1:] / var
    b = whitened[1:, 0] / var
    DA = rho[:, None, None] * A
    B = xp.eye(4)[:, :, None] + DA * rho[None, :, None]
    B_chol = sl.cholesky(B, xp)
    Gg = sl.solve_lower(B_chol, xp.concatenate([DA, (rho[:, None] * b)[:, None, :]], axis=1), xp)
    G, g = Gg[:, :4], Gg[:, 4]
    H = A - xp.sum(G[:, :, None, :] * G[:, None, :, :], axis=0)
    h = b - xp.sum(G * g[:, None, :], axis=0)
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
    return test_terms(whitened_at(table, alpha, phi, xp), table.n_pairs, sigma, rho, xp)


def collapsed_log_likelihood(table: MomentTable, alpha, rho, phi, sigma, prior_mean, prior_sd, xp=jnp):
    """log p(y | alpha, rho, phi, sigma) with every theta_j and mu integrated out (scaled units)."""
    terms = _terms(table, alpha, rho, phi, sigma, xp)
    Q, r = population_posterior(terms, prior_mean, prior_sd, xp)
    Q_chol = sl.cholesky(Q, xp)
    Qinv_r = sl.cho_solve(Q_chol, r, xp)
    prior_precision = 1.0 / (prior_sd * prior_sd)
    return (
        xp.sum(terms.c)
        - xp.sum(xp.log(prior_sd))
        - 0.5 * sl.log_det_from_cholesky(Q_chol, xp)
        + 0.5 * xp.sum(r * Qinv_r)
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
