"""The collapsed likelihood and its exact conditionals against independent dense computations."""

import numpy as np
import pytest

import bayes_sst._jaxconfig  # noqa: F401
import jax
import jax.numpy as jnp

from bayes_sst.inference import _smalllinalg as sl
from bayes_sst.inference._collapsed import (
    MomentTable,
    collapsed_log_likelihood,
    compact_table,
    draw_coefficients,
    whitened_at,
    whitened_moments,
)


def _random_problem(rng, n_tests=3, n_samples=60):
    """Per-test data z = (y, x1..x4) with known lag moments on a 2-point alpha grid."""
    zs = [rng.standard_normal((5, n_samples)) for _ in range(n_tests)]
    moments = []
    for z in zs:
        now, before = z[:, 1:], z[:, :-1]
        moments.append(np.stack([now @ now.T, now @ before.T, before @ before.T]))
    grid = np.stack([np.stack(moments)] * 2, axis=1)  # (J, 2, 3, 5, 5): alpha-independent here
    table = compact_table(grid, np.zeros_like(grid), np.full(n_tests, float(n_samples - 1)), np.array([0.0, 1.0]))
    return zs, table


def _dense_log_marginal(zs, phi, sigma, rho, m0, s0):
    """log of the integral over mu and theta_j of prod_j N(whitened y_j; X_j theta_j, sigma_j^2 I)
    N(theta_j; mu, diag rho^2) N(mu; m0, diag s0^2), as one joint Gaussian over all whitened
    observations: y ~ N(X m0, X (S0 (x) 11') X' + blockdiag(X_j T X_j') + diag(sigma^2))."""
    ys, Xs = [], []
    for z, p in zip(zs, phi):
        w = z[:, 1:] - p * z[:, :-1]
        ys.append(w[0])
        Xs.append(w[1:].T)
    y = np.concatenate(ys)
    X_mu = np.concatenate(Xs)
    cov = X_mu @ np.diag(s0**2) @ X_mu.T
    offset = 0
    noise = []
    for X, s in zip(Xs, sigma):
        n = X.shape[0]
        cov[offset:offset + n, offset:offset + n] += X @ np.diag(rho**2) @ X.T
        noise.append(np.full(n, s**2))
        offset += n
    cov += np.diag(np.concatenate(noise))
    resid = y - X_mu @ m0
    sign, logdet = np.linalg.slogdet(cov)
    assert sign > 0
    return -0.5 * (len(y) * np.log(2 * np.pi) + logdet + resid @ np.linalg.solve(cov, resid))


def test_collapsed_likelihood_equals_dense_joint_gaussian():
    rng = np.random.default_rng(1)
    zs, table = _random_problem(rng)
    phi = np.array([0.3, -0.2, 0.6])
    sigma = np.array([0.7, 1.1, 0.9])
    rho = np.array([0.5, 0.2, 1.3, 0.05])
    m0 = np.array([0.2, -0.1, 0.4, 1.0])
    s0 = np.array([1.0, 2.0, 0.5, 1.5])
    ours = collapsed_log_likelihood(table, 0.5, jnp.asarray(rho), jnp.asarray(phi), jnp.asarray(sigma),
                                    jnp.asarray(m0), jnp.asarray(s0))
    dense = _dense_log_marginal(zs, phi, sigma, rho, m0, s0)
    assert float(ours) == pytest.approx(dense, rel=1e-10, abs=1e-8)


def test_collapsed_likelihood_numpy_and_jax_agree_and_gradient_matches_differences():
    rng = np.random.default_rng(2)
    _, table = _random_problem(rng)
    args = (np.array([0.4, 0.1, 0.9, 0.3]), np.array([0.2, 0.5, -0.3]), np.array([1.0, 0.8, 1.2]))
    m0, s0 = np.ones(4), np.ones(4)
    host = MomentTable(*(np.asarray(x) if hasattr(x, "shape") else x for x in table))
    value_np = collapsed_log_likelihood(host, 0.5, *args, m0, s0, xp=np)
    value_jax = collapsed_log_likelihood(table, 0.5, *map(jnp.asarray, args), jnp.asarray(m0), jnp.asarray(s0))
    assert value_np == pytest.approx(float(value_jax), rel=1e-12)

    def f(rho):
        return collapsed_log_likelihood(table, 0.5, rho, *map(jnp.asarray, args[1:]), jnp.asarray(m0), jnp.asarray(s0))

    grad = np.asarray(jax.grad(f)(jnp.asarray(args[0])))
    eps = 1e-6
    for k in range(4):
        step = np.zeros(4)
        step[k] = eps
        fd = (float(f(jnp.asarray(args[0] + step))) - float(f(jnp.asarray(args[0] - step)))) / (2 * eps)
        assert grad[k] == pytest.approx(fd, rel=1e-5, abs=1e-6)


def test_hermite_interpolation_of_whitened_moments_matches_direct_computation():
    """z = (v, v^2, v^3, |v|^alpha sign v, sign v), moments tabulated on a 0.025 grid; the
    whitened moments read off between nodes against a direct computation at that alpha."""
    rng = np.random.default_rng(3)
    v = rng.uniform(-1.0, 1.0, 400)
    grid = np.arange(0.05, 1.96, 0.025)

    def z_of(alpha):
        return np.stack([v, v**2, v**3, np.abs(v) ** alpha * np.sign(v), np.sign(v)])

    def lag_moments(z, dz=None):
        now, before = z[:, 1:], z[:, :-1]
        if dz is None:
            return np.stack([now @ now.T, now @ before.T, before @ before.T])
        dnow, dbefore = dz[:, 1:], dz[:, :-1]
        return np.stack([dnow @ now.T + now @ dnow.T, dnow @ before.T + now @ dbefore.T,
                         dbefore @ before.T + before @ dbefore.T])

    moments = np.stack([lag_moments(z_of(a)) for a in grid])[None]
    slopes = []
    for a in grid:
        dz = np.zeros((5, len(v)))
        dz[3] = np.abs(v) ** a * np.log(np.abs(v)) * np.sign(v)
        slopes.append(lag_moments(z_of(a), dz))
    table = compact_table(moments, np.stack(slopes)[None], np.ones(1), grid)
    for alpha, phi in ((0.3137, 0.0), (0.5, 0.4), (0.777, -0.3), (1.4321, 0.9)):
        z = z_of(alpha)
        w = z[:, 1:] - phi * z[:, :-1]
        exact = w @ w.T
        interpolated = np.asarray(whitened_at(table, alpha, jnp.asarray([phi])))[..., 0]
        assert np.max(np.abs(interpolated - exact)) / np.max(np.abs(exact)) < 1e-7
        host = np.asarray(whitened_at(table._replace(constant=np.asarray(table.constant), cells=np.asarray(table.cells)),
                                      alpha, np.asarray([phi]), xp=np))[..., 0]
        assert np.allclose(host, interpolated, rtol=1e-12, atol=1e-12)


def test_whitening_is_the_moment_matrix_of_the_ar1_innovations():
    rng = np.random.default_rng(4)
    z = rng.standard_normal((5, 50))
    now, before = z[:, 1:], z[:, :-1]
    m = np.stack([now @ now.T, now @ before.T, before @ before.T])[..., None]
    phi = 0.37
    w = now - phi * before
    assert np.allclose(np.asarray(whitened_moments(jnp.asarray(m), jnp.asarray([phi])))[..., 0], w @ w.T)


def test_coefficient_draws_have_the_exact_conditional_moments():
    """Mean and covariance of mu draws against the dense Gaussian posterior of mu."""
    rng = np.random.default_rng(5)
    zs, table = _random_problem(rng, n_tests=2, n_samples=80)
    host = MomentTable(*(np.asarray(x) if hasattr(x, "shape") else x for x in table))
    phi, sigma = np.array([0.2, 0.4]), np.array([0.9, 1.1])
    rho, m0, s0 = np.array([0.3, 0.3, 0.3, 0.3]), np.zeros(4), np.full(4, 2.0)
    draws = np.array([
        draw_coefficients(rng.standard_normal(4), rng.standard_normal((2, 4)), host, 0.5, rho, phi, sigma, m0, s0, xp=np)[0]
        for _ in range(20000)
    ])
    # dense: mu | y is Gaussian with precision S0^-1 + sum_j X_j' (X_j T X_j' + s^2 I)^-1 X_j
    precision = np.diag(1 / s0**2)
    shift = m0 / s0**2
    for z, p, s in zip(zs, phi, sigma):
        w = z[:, 1:] - p * z[:, :-1]
        X, y = w[1:].T, w[0]
        cov_j = X @ np.diag(rho**2) @ X.T + s**2 * np.eye(len(y))
        precision += X.T @ np.linalg.solve(cov_j, X)
        shift += X.T @ np.linalg.solve(cov_j, y)
    cov = np.linalg.inv(precision)
    mean = cov @ shift
    se = np.sqrt(np.diag(cov) / len(draws))
    assert np.all(np.abs(draws.mean(0) - mean) < 5 * se)
    assert np.allclose(np.cov(draws.T), cov, rtol=0.05, atol=0.05 * np.max(np.diag(cov)))


def test_unrolled_cholesky_matches_numpy():
    rng = np.random.default_rng(6)
    a = rng.standard_normal((7, 4, 4))
    spd = a @ np.swapaxes(a, -1, -2) + 4 * np.eye(4)
    L = sl.cholesky(np.moveaxis(spd, 0, -1), np)  # batch last
    assert np.allclose(np.moveaxis(L, -1, 0), np.linalg.cholesky(spd))
    b = rng.standard_normal((7, 4))
    assert np.allclose(sl.cho_solve(L, b.T, np).T, np.linalg.solve(spd, b[..., None])[..., 0])
