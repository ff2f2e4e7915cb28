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
import zlib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from bayes_sst.signals import PreparedTest
from bayes_sst.signals._noise import NOISE_DRAWS, NOISE_KEEP

ALPHA_MIN = 0.05
ALPHA_MAX = 1.95
# The damping column is interpolated between nodes by cubic Hermite polynomials with exact
# alpha-derivatives, so the grid can be coarse; every node costs the low-pass filtering of two
# columns per test, most of the signal preparation. Measured on the 200-test benchmark series
# against a 0.0125 grid: the collapsed log-likelihood moves by at most 5e-4 nats for alpha in
# 0.3-1.8 (0.016 nats at alpha = 0.13, far out in the tails), and the moments take 1.25 s
# instead of 2.0 s. (A 0.05 grid moved it by 0.46 nats at 0.13.)
ALPHA_STEP = 0.025
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
    noise_mass_kg : the plug-in Me of the accelerometer-noise correction (pooled_mass).
    friction_load : (n_tests,) each test's bearing-load ratio L_j (signals.friction_load), the
        factor its Coulomb column already carries; None for a LaggedMoments built without it.
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
    noise_mass_kg: float = float("nan")
    friction_load: np.ndarray | None = None

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


# NOISE_DRAWS, NOISE_KEEP: bayes_sst.signals._noise; the correction also leaves at least
# RESIDUAL_KEEP of the residual energy
RESIDUAL_KEEP = 0.5
_CHECK_PHI = (-0.9, -0.5, 0.0, 0.5, 0.9)
_CHECK_ALPHA = (0.3, 0.5, 0.8, 1.2)


def _schur_first(W: np.ndarray) -> np.ndarray:
    """W_00 - W_0r W_rr^+ W_r0 for symmetric W (..., k, k): the part of column 0's energy the
    other columns do not explain (pseudo-inverse: a triangle test's damping and friction
    columns can be collinear)."""
    rest = np.linalg.pinv(W[..., 1:, 1:], rcond=1e-12, hermitian=True)
    return W[..., 0, 0] - np.einsum("...i,...ij,...j->...", W[..., 0, 1:], rest, W[..., 1:, 0])


def acceleration_noise_correction(test: PreparedTest, moments: np.ndarray, valid: np.ndarray, alpha_grid,
                                  coefficient_scale, force_scale: float, mass_kg: float) -> np.ndarray:
    """C (3, 5, 5), in the units of `moments`: what the accelerometer's noise adds to the lagged
    moments of z = (y, a, u, d, s), to be subtracted from every grid node.

    Errors in variables. The recorded a = a_true + n carries noise that the force does not, and
    a noisy regressor's coefficient is biased toward zero by the share of its energy that is
    noise. Within one sine test a is -omega^2 u up to small harmonics, so Me is told from Ke by
    those harmonics alone and the noise dominates them: single-test least squares on an
    independently written generator's series (0.05 m/s^2 of white accelerometer noise at 200 and
    500 Hz, random frequencies so that the cycle average rarely applied) put Me 2.9 % and Ke
    1.2 % low (median), and the hierarchical population inherited about 0.5 %. With n entering
    z as n*g, g = (-m_payload, Me_scale, 0, 0, 0)/force_scale, E[M_l] gains g g' N_l, where
    N_l are the noise's own lag sums after the signal treatment (Monte Carlo through
    PreparedTest.acceleration_noise). Subtracting them is the corrected least-squares moment
    estimator; the residual's noise, (m_payload + Me)^2 N_l, is added back to the (y, y) cell
    at Me = mass_kg (a plug-in value: lagged_moments' pooled least squares), so that the
    fitted noise sd stays that of the real residual. The whole correction is scaled down (by a
    factor <= 1) where it would leave less than NOISE_KEEP of the noise's energy unexplained in
    a, or less than RESIDUAL_KEEP of the residual energy, at any of a few AR coefficients and
    damping exponents: an estimate of the noise off by its own sampling error must not make a
    moment matrix indefinite.
    """
    draws = test.acceleration_noise(NOISE_DRAWS, seed=zlib.crc32(test.id.encode()))
    lag_sums = pair_moments(draws[:, None, :], draws[:, None, :], valid)[:, :, 0, 0].mean(axis=0)  # (3,)
    mass_scale = float(coefficient_scale[0]) / force_scale
    payload = test.payload_kg / force_scale
    g = np.array([-payload, mass_scale, 0.0, 0.0, 0.0])
    unit = np.zeros((5, 5))
    unit[0, 0] = (payload + mass_kg / force_scale) ** 2
    correction = lag_sums[:, None, None] * (np.outer(g, g) - unit)[None]

    nodes = np.unique([int(np.argmin(np.abs(alpha_grid - a))) for a in _CHECK_ALPHA])
    phi = np.asarray(_CHECK_PHI)[:, None, None, None]

    def whitened(m):
        return m[:, 0] - phi * (m[:, 1] + np.swapaxes(m[:, 1], -1, -2)) + phi * phi * m[:, 2]

    observed = whitened(moments[nodes])  # (phi, node, 5, 5)
    noise_energy = mass_scale**2 * (lag_sums[0] - 2 * np.asarray(_CHECK_PHI) * lag_sums[1]
                                    + np.asarray(_CHECK_PHI) ** 2 * lag_sums[2])[:, None]
    unexplained = _schur_first(observed[..., 1:, 1:])
    residual = _schur_first(observed)
    if np.any(noise_energy <= 0):
        return np.zeros_like(correction)
    factor = float(np.clip(np.min((unexplained - NOISE_KEEP * noise_energy) / noise_energy), 0.0, 1.0))
    while factor > 1e-3:
        corrected = whitened(moments[nodes] - factor * correction[None])
        if np.all(_schur_first(corrected) >= RESIDUAL_KEEP * residual):
            return factor * correction
        factor *= 0.5
    return np.zeros_like(correction)


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
        return moments, slopes, cross, gram, valid

    # the filtering of the damping regressors dominates and runs in scipy and numpy with the
    # GIL released: threads over tests halve the preparation of a 200-test series on 2 cores
    with ThreadPoolExecutor(max_workers=max(1, min(len(os.sched_getaffinity(0)), len(tests)))) as pool:
        per_test = list(pool.map(one_test, tests))
        all_moments, all_slopes, all_cross, all_gram, valids = (list(column) for column in zip(*per_test))
        mass = pooled_mass(all_moments, alpha_grid, coefficient_scale)

        def corrected(j):
            test = tests[j]
            if not test.acceleration_noise_known:
                return all_moments[j]
            return all_moments[j] - acceleration_noise_correction(
                test, all_moments[j], valids[j], alpha_grid, coefficient_scale, force_scale, mass
            )[None]

        all_moments = list(pool.map(corrected, range(len(tests))))
    n_pairs = [valid.sum() for valid in valids]
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
        noise_mass_kg=mass,
        friction_load=np.array([t.friction_load for t in tests], dtype=float),
    )


def _pooled_least_squares(m: np.ndarray) -> tuple[np.ndarray, float]:
    """The coefficients minimising the residual of the lag-0 moments m (5, 5) of z = (y, x), and
    that residual energy y'y - y'X theta."""
    theta = np.linalg.lstsq(m[1:, 1:], m[1:, 0], rcond=1e-12)[0]
    return theta, float(m[0, 0] - m[1:, 0] @ theta)


def pooled_mass(moments, alpha_grid, coefficient_scale) -> float:
    """Me (kg) by least squares on all tests' lag-0 moments together at alpha = 0.5, one
    coefficient set for the whole series: a rough value, good to a few %, for the
    accelerometer-noise correction's residual (across tests of different frequencies the
    mass is well apart from the stiffness, unlike within one). The scale of Me when the
    tests cannot give one."""
    node = int(np.argmin(np.abs(np.asarray(alpha_grid) - 0.5)))
    theta, _ = _pooled_least_squares(sum(m[node, 0] for m in moments))  # moments: per test (G, 3, 5, 5)
    mass = float(theta[0] * coefficient_scale[0])
    return mass if np.isfinite(mass) and mass > 0.0 else float(coefficient_scale[0])


def pooled_damping(lagged: LaggedMoments) -> tuple[float, float]:
    """(alpha, |Ce| in scaled units) by least squares on all tests' lag-0 moments together, one
    coefficient set for the series, at the grid node whose residual is least: rough values, the
    scale that turns a test's deviation coefficient into its exponent's deviation
    (_collapsed.DEVIATION). |Ce| falls back to 1 (the prior centre) where the fit gives none."""
    total = np.sum(np.asarray(lagged.moments)[:, :, 0], axis=0)  # (G, 5, 5)
    best, found = np.inf, (float("nan"), 1.0)
    for g, m in enumerate(total):
        theta, residual = _pooled_least_squares(m)
        if np.isfinite(residual) and residual < best:
            best, found = residual, (float(lagged.alpha_grid[g]), float(abs(theta[DAMPING_COLUMN])))
    alpha, scale = found
    return alpha, scale if np.isfinite(scale) and scale > 0.0 else 1.0
