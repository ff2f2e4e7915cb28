"""Lagged sufficient statistics of the linear-in-coefficients force model.

For fixed alpha the base model is linear in theta = (Me, Ke, Ce, Fmu):

    y_t = x_t(alpha) . theta + e_t,   y = F - m_payload*a,   x = (a, u, |v|^alpha sign v, sign v)

With AR(1) residuals e_t = phi*e_(t-1) + w_t, w ~ N(0, sigma^2), the conditional likelihood
needs only the 5x5 moments of z_t = (y_t, x_t) at lags 0 and 1 over consecutive kept pairs:

    M0 = sum z_t z_t',  M1 = sum z_t z_(t-1)',  M2 = sum z_(t-1) z_(t-1)'
    sum_t (z_t - phi z_(t-1))(z_t - phi z_(t-1))' = M0 - phi (M1 + M1') + phi^2 M2

The moments depend on alpha only through the damping column d(alpha). The likelihood
interpolates that COLUMN between grid nodes by cubic Hermite polynomials,
d(alpha) = sum_k w_k(alpha) K_k with K = (d_g, step d'_g, d_(g+1), step d'_(g+1)), and reads its
moments from the tabulated moments of the four basis columns with each other and with the
other columns (damping_cells). The interpolated moment matrix is then exactly the moment
matrix of a set of columns, positive semidefinite at every alpha. (Interpolating the moments
themselves is not: a triangle test's damping and friction columns are collinear to 1e-9, and
the interpolation error made its whitened moment matrix indefinite, which at low force noise
sent the population draws to many times the truth.) One likelihood evaluation costs a few 5x5
operations per test, whatever the number of samples.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from bayes_sst.signals import PreparedTest

ALPHA_MIN = 0.05
ALPHA_MAX = 1.95
ALPHA_STEP = 0.0125
COEFFICIENTS = ("Me", "Ke", "Ce", "Fmu")


@dataclass(frozen=True)
class LaggedMoments:
    """Per-test lagged moments on an alpha grid, in scaled units.

    moments, slopes : (n_tests, n_grid, 3, 5, 5): M0, M1, M2 and their d/dalpha.
    damping_cross, damping_gram : (n_tests, n_grid - 1, 3, 4, 4): per grid interval, the lag
        sums (see damping_cells) of the damping column's four Hermite basis columns with the
        other columns (y, a, u, sign) and with each other.
    n_pairs : (n_tests,) consecutive kept sample pairs entering the likelihood.
    alpha_grid : (n_grid,) uniformly spaced.
    coefficient_scale : (4,) theta = coefficient_scale * theta_scaled (kg, N/m, N/(m/s)^a, N).
    force_scale : N; the response is y / force_scale.
    """

    moments: np.ndarray
    slopes: np.ndarray
    damping_cross: np.ndarray
    damping_gram: np.ndarray
    n_pairs: np.ndarray
    alpha_grid: np.ndarray
    coefficient_scale: np.ndarray
    force_scale: float
    test_ids: tuple[str, ...]

    @property
    def n_tests(self) -> int:
        return len(self.test_ids)


def damping_columns(alpha_grid: np.ndarray):
    """v -> [|v|^alpha sign v ; |v|^alpha log|v| sign v] for every alpha of the grid, (2G, n):
    the damping regressor and its exact alpha-derivative (0 where v = 0)."""

    def of_velocity(v):
        speed = np.abs(v)
        moving = speed > 0
        log_speed = np.where(moving, np.log(np.where(moving, speed, 1.0)), 0.0)
        power = np.where(moving, np.exp(alpha_grid[:, None] * log_speed[None, :]), 0.0) * np.sign(v)
        return np.concatenate([power, power * log_speed[None, :]])

    return of_velocity


def scaled_regressors(test: PreparedTest, alpha_grid: np.ndarray, coefficient_scale: np.ndarray, force_scale: float):
    """The test's regressors on an alpha grid, in scaled units, at its kept samples.

    X (G, 4, n) = (a, u, filter(|v|^alpha sign v), filter(sign v)) * coefficient_scale /
    force_scale; dX (G, 4, n) its alpha-derivative (only the damping column moves);
    valid (n-1,) 1.0 for consecutive pairs that both enter the likelihood.
    """
    both = test.regressor(damping_columns(alpha_grid))
    g, n = len(alpha_grid), len(test.index)
    X = np.empty((g, 4, n))
    X[:, 0] = test.a
    X[:, 1] = test.u
    X[:, 2] = both[:g]
    X[:, 3] = test.friction_sign
    dX = np.zeros_like(X)
    dX[:, 2] = both[g:]
    factor = (np.asarray(coefficient_scale, dtype=float) / force_scale)[None, :, None]
    valid = (test.keep[1:] & test.keep[:-1]).astype(float)
    return X * factor, dX * factor, valid


def pair_moments(p: np.ndarray, q: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """[sum p_t q_t', sum p_t q_(t-1)', sum p_(t-1) q_(t-1)'] over valid pairs; p, q (..., k, n),
    result (..., 3, k, k)."""
    p_now, p_before = p[..., 1:] * valid, p[..., :-1] * valid
    q_now, q_before = q[..., 1:], q[..., :-1]
    m0 = np.einsum("...it,...jt->...ij", p_now, q_now)
    m1 = np.einsum("...it,...jt->...ij", p_now, q_before)
    m2 = np.einsum("...it,...jt->...ij", p_before, q_before)
    return np.stack([m0, m1, m2], axis=-3)


def response_moments(y: np.ndarray, X: np.ndarray, dX: np.ndarray, valid: np.ndarray):
    """Lagged moments (G, 3, 5, 5) of z = (y, x) and their exact alpha-slopes, for a scaled
    response y (n,) that does not depend on alpha; d/dalpha of sum p q' is sum (dp q' + p dq')."""
    g, n = X.shape[0], X.shape[-1]
    z = np.concatenate([np.broadcast_to(y, (g, 1, n)), X], axis=1)
    dz = np.concatenate([np.zeros((g, 1, n)), dX], axis=1)
    moments = pair_moments(z, z, valid)
    slopes = pair_moments(dz, z, valid) + pair_moments(z, dz, valid)
    return moments, slopes


DAMPING_COLUMN = 2  # of X = (a, u, damping, sign)
OTHER_COLUMNS = (0, 1, 3)


def symmetric_lag_sums(m: np.ndarray, m_transposed_lag1: np.ndarray | None = None) -> np.ndarray:
    """(S0, S1, S2) = (M0, M1 + M1', M2) from pair moments (..., 3, k, l); the whitened moments
    are S0 - phi S1 + phi^2 S2. For cross moments of two different column sets pass the lag-1
    moment of the reverse pair (sum q_t p_(t-1)'), whose transpose completes S1."""
    lag1 = m[..., 1, :, :]
    other = np.swapaxes(lag1 if m_transposed_lag1 is None else m_transposed_lag1, -1, -2)
    return np.stack([m[..., 0, :, :], lag1 + other, m[..., 2, :, :]], axis=-3)


def damping_cells(y: np.ndarray, X: np.ndarray, dX: np.ndarray, valid: np.ndarray, step: float):
    """Lag sums of the damping column's Hermite basis per grid interval, for the interpolation
    d(alpha) = sum_k w_k K_k, K = (d_g, step d'_g, d_(g+1), step d'_(g+1)):

    cross (G-1, 3, 4, 4): S_l(K_k, o) for o = (y, a, u, sign);  gram (G-1, 3, 4, 4): S_l(K_k, K_m);
    S = (M0, M1 + M1', M2) as in symmetric_lag_sums.
    """
    d, dd = X[:, DAMPING_COLUMN], step * dX[:, DAMPING_COLUMN]
    basis = np.stack([d[:-1], dd[:-1], d[1:], dd[1:]], axis=1)  # (G-1, 4, n)
    others = np.concatenate([y[None], X[0, list(OTHER_COLUMNS)]], axis=0)  # (4, n)
    cross = symmetric_lag_sums(pair_moments(basis, others, valid), pair_moments(others, basis, valid)[..., 1, :, :])
    gram = symmetric_lag_sums(pair_moments(basis, basis, valid))
    return cross, gram


def lagged_moments(
    tests: list[PreparedTest],
    coefficient_scale,
    *,
    alpha_grid: np.ndarray | None = None,
) -> LaggedMoments:
    """Tabulate the lagged moments of every test (see the module docstring)."""
    if alpha_grid is None:
        alpha_grid = np.arange(ALPHA_MIN, ALPHA_MAX + 0.5 * ALPHA_STEP, ALPHA_STEP)
    coefficient_scale = np.asarray(coefficient_scale, dtype=float)
    force_scale = float(
        np.sqrt(np.mean(np.concatenate([(t.F - t.payload_kg * t.a)[t.keep] ** 2 for t in tests])))
    )

    step = float(alpha_grid[1] - alpha_grid[0])

    def one_test(test):
        X, dX, valid = scaled_regressors(test, alpha_grid, coefficient_scale, force_scale)
        y = (test.F - test.payload_kg * test.a) / force_scale
        moments, slopes = response_moments(y, X, dX, valid)
        cross, gram = damping_cells(y, X, dX, valid, step)
        return moments, slopes, cross, gram, valid.sum()

    # the filtering of the damping regressors dominates and runs in scipy and numpy with the
    # GIL released: threads over tests halve the preparation of a 200-test series on 2 cores
    with ThreadPoolExecutor(max_workers=max(1, min(len(os.sched_getaffinity(0)), len(tests)))) as pool:
        per_test = list(pool.map(one_test, tests))
    all_moments, all_slopes, all_cross, all_gram, n_pairs = zip(*per_test)
    return LaggedMoments(
        moments=np.stack(all_moments),
        slopes=np.stack(all_slopes),
        damping_cross=np.stack(all_cross),
        damping_gram=np.stack(all_gram),
        n_pairs=np.asarray(n_pairs),
        alpha_grid=np.asarray(alpha_grid, dtype=float),
        coefficient_scale=coefficient_scale,
        force_scale=force_scale,
        test_ids=tuple(t.id for t in tests),
    )
