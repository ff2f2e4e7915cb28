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


def _table(per_test, alpha_grid):
    """MomentTable from per-test (y (n,), X (G, 4, n), dX (G, 4, n)), every pair valid, built
    with the fit's own moment functions."""
    from bayes_sst.inference._statistics import damping_cells, response_moments

    step = float(alpha_grid[1] - alpha_grid[0])
    moments, cross, gram, n_pairs = [], [], [], []
    for y, X, dX in per_test:
        valid = np.ones(len(y) - 1)
        moments.append(response_moments(y, X, dX, valid)[0])
        c, g = damping_cells(y, X, dX, valid, step)
        cross.append(c)
        gram.append(g)
        n_pairs.append(valid.sum())
    return compact_table(np.stack(moments), np.stack(cross), np.stack(gram), np.asarray(n_pairs), alpha_grid)


def _random_problem(rng, n_tests=3, n_samples=60):
    """Per-test data z = (y, x1..x4) with known lag moments on a 2-point alpha grid."""
    zs = [rng.standard_normal((5, n_samples)) for _ in range(n_tests)]
    # alpha-independent columns on a 2-point grid
    table = _table([(z[0], np.stack([z[1:]] * 2), np.zeros((2, 4, n_samples))) for z in zs], np.array([0.0, 1.0]))
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
    """z = (v, v^2, v^3, |v|^alpha sign v, sign v), the damping column's basis tabulated on a
    0.025 grid; the whitened moments read off between nodes against a direct computation at
    that alpha."""
    rng = np.random.default_rng(3)
    v = rng.uniform(-1.0, 1.0, 400)
    grid = np.arange(0.05, 1.96, 0.025)

    def z_of(alpha):
        return np.stack([v, v**2, v**3, np.abs(v) ** alpha * np.sign(v), np.sign(v)])

    def columns(alpha):
        c = np.abs(v) ** alpha * np.sign(v)
        return np.stack([v**2, v**3, c, np.sign(v)]), np.stack([0 * v, 0 * v, c * np.log(np.abs(v)), 0 * v])

    X, dX = (np.stack(parts) for parts in zip(*(columns(a) for a in grid)))
    table = _table([(v, X, dX)], grid)
    for alpha, phi in ((0.3137, 0.0), (0.5, 0.4), (0.777, -0.3), (1.4321, 0.9)):
        z = z_of(alpha)
        w = z[:, 1:] - phi * z[:, :-1]
        exact = w @ w.T
        interpolated = np.asarray(whitened_at(table, alpha, jnp.asarray([phi])))[..., 0]
        assert np.max(np.abs(interpolated - exact)) / np.max(np.abs(exact)) < 1e-7
        host = np.asarray(whitened_at(MomentTable(*(np.asarray(x) if hasattr(x, "shape") else x for x in table)),
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


def test_column_cholesky_of_one_matrix_matches_numpy_and_its_gradient_matches_jax():
    rng = np.random.default_rng(7)
    a = rng.standard_normal((4, 4))
    spd = a @ a.T + 0.5 * np.eye(4)
    assert np.allclose(sl.cholesky_by_columns(spd, np), np.linalg.cholesky(spd))
    assert np.allclose(sl.cholesky_by_columns(jnp.asarray(spd)), np.linalg.cholesky(spd))

    def log_det(m, factor):
        return 2.0 * jnp.sum(jnp.log(jnp.diag(factor(m @ m.T + 0.5 * jnp.eye(4)))))

    ours = jax.grad(log_det)(jnp.asarray(a), sl.cholesky_by_columns)
    reference = jax.grad(log_det)(jnp.asarray(a), jnp.linalg.cholesky)
    assert np.allclose(ours, reference, rtol=1e-10, atol=1e-12)


def _precise_problem(rng, noise, n_tests=6, n_samples=80):
    """Tests whose force is X_j theta_j plus white noise of sd `noise`, force of order 1, with a
    sine-like pair of nearly collinear columns (as a and u are), on a 2-point alpha grid."""
    t = np.arange(n_samples) * 0.05
    thetas = 1.0 + 0.1 * rng.standard_normal((n_tests, 4))
    per_test = []
    for j in range(n_tests):
        w = 1.0 + 0.3 * j
        x = np.stack([-w * w * np.sin(w * t) + 0.01 * np.sin(3 * w * t), np.sin(w * t),
                      np.abs(np.cos(w * t)) ** 0.5 * np.sign(np.cos(w * t)), np.sign(np.cos(w * t))])
        y = thetas[j] @ x + noise * rng.standard_normal(n_samples)
        per_test.append((y, np.stack([x, x]), np.zeros((2, 4, n_samples))))
    return thetas, _table(per_test, np.array([0.0, 1.0]))


def test_population_draws_stay_exact_when_the_force_is_far_above_its_noise():
    """Force 1e5 times its noise, well conditioned columns: each theta_j is pinned by its data,
    so mu | rest tends to N(mean_j theta_j, T/J) (flat prior) and theta_j to its own value."""
    rng = np.random.default_rng(7)
    noise = 1e-5
    thetas, table = _precise_problem(rng, noise)
    host = MomentTable(*(np.asarray(x) if hasattr(x, "shape") else x for x in table))
    J = len(thetas)
    rho = np.full(4, 0.1)
    phi, sigma = np.zeros(J), np.full(J, noise)
    m0, s0 = np.ones(4), np.full(4, 1e3)
    draws = [draw_coefficients(rng.standard_normal(4), rng.standard_normal((J, 4)), host, 0.5, rho, phi, sigma,
                               m0, s0, xp=np) for _ in range(4000)]
    mu = np.array([d[0] for d in draws])
    theta = np.array([d[1] for d in draws])
    se = 0.1 / np.sqrt(J) / np.sqrt(len(draws))
    assert np.all(np.abs(mu.mean(0) - thetas.mean(0)) < 5 * se)
    assert np.allclose(mu.std(0), 0.1 / np.sqrt(J), rtol=0.06)
    assert np.allclose(theta.mean(0), thetas, atol=1e-3)
    # and the sampler's (JAX) likelihood is finite with a finite gradient there
    value, grad = jax.value_and_grad(
        lambda r: collapsed_log_likelihood(table, 0.5, r, jnp.asarray(phi), jnp.asarray(sigma), jnp.asarray(m0), jnp.asarray(s0))
    )(jnp.asarray(rho))
    assert np.isfinite(float(value)) and np.all(np.isfinite(np.asarray(grad)))


def test_population_is_right_when_the_recorded_force_is_nearly_noise_free():
    """The virtual table with 10 N of white force noise and no motion-sensor noise (1.6 N after
    the low-pass, 3e-5 of the RMS force). When the moments themselves were interpolated in
    alpha, the triangle tests' whitened moment matrices (damping and friction columns collinear
    to 1e-9) came out indefinite here and the population draws were 40-5000 % off."""
    from bayes_sst.inference import fit
    from bayes_sst.inference._summary import summarize
    from bayes_sst.twin import SensorNoise, simulate

    series = simulate("sst-paper", seed=43, spread=0.03,
                      noise=SensorNoise(u_white=0.0, u_quantum=0.0, a_white=0.0, F_white=10.0, F_colored=0.0))
    truth = series.extra["truth"]
    summary = summarize(fit(series, seed=1, draws=300, warmup=300).tree)
    for name, tolerance in (("Me", 0.03), ("Ke", 0.03), ("Ce", 0.05), ("Fmu", 0.05)):
        assert abs(summary["parameters"][name]["mean"] / truth[name] - 1) < tolerance, name
    assert abs(summary["parameters"]["alpha"]["mean"] - truth["alpha"]) < 0.05


def _site_problem(seed, spread_prior=(0.03, 1.0), varying=(1.0, 0.0, 1.0, 1.0), noise_loc=0.2,
                  n_samples=50, phi=(0.3, -0.2, 0.8, 0.0), sigma=(0.9, 1.1, 1.3, 0.7), friction_load=None,
                  alpha_spread=False):
    """A small collapsed problem (one test per phi), its scaled priors and site values: the
    generator (for later draws), the table in JAX and in numpy, the priors and the values;
    with friction_load (one per test), the payload's friction gain is a site too; with
    alpha_spread, the exponent's between-test sd (on a table with a real damping column)."""
    from bayes_sst.inference._model import ALPHA_SPREAD_SITE, GAIN_SITE, ScaledPriors

    rng = np.random.default_rng(seed)
    if alpha_spread:
        table = _damping_problem(rng, n_tests=len(phi), n_samples=n_samples)
    else:
        _, table = _random_problem(rng, n_tests=len(phi), n_samples=n_samples)
    if friction_load is not None:
        table = table._replace(load_share=jnp.asarray(1.0 - 1.0 / np.asarray(friction_load)))
    numpy_table = MomentTable(*(np.asarray(field) if isinstance(field, jax.Array) else field for field in table))
    priors = ScaledPriors(
        mean=jnp.array([1.0, 0.8, 1.2, 0.9]), sd=jnp.array([0.5, 0.4, 0.7, 0.3]),
        alpha_mean=0.5, alpha_sd=0.2, alpha_low=0.1, alpha_high=1.2,
        spread_median=jnp.asarray(spread_prior[0]), spread_log_sd=jnp.asarray(spread_prior[1]),
        noise_loc=noise_loc, noise_log_sd=1.5, varying=jnp.array(varying),
        gain=None if friction_load is None else (1.0, 2.0, 0.0, 6.0),
        alpha_spread=(0.02, 1.0) if alpha_spread else None, deviation_scale=0.6,
    )
    values = {"alpha": 0.45, "spread": np.array([0.02, 0.05, 0.01, 0.1]), "phi": np.array(phi), "sigma": np.array(sigma)}
    if friction_load is not None:
        values[GAIN_SITE] = 1.6
    if alpha_spread:
        values[ALPHA_SPREAD_SITE] = 0.05
    return rng, table, numpy_table, priors, values


# spread priors and bearing loads of the start's tests: one spread prior for all, one per
# coefficient (fit's mass refit holds Me's), tests under payloads (the friction gain sampled),
# and the damping exponent's between-test sd sampled (with payloads too)
SITE_CASES = [((0.03, 1.0), None, False), (((0.02, 0.03, 0.03, 0.05), (0.35, 1.0, 1.0, 0.5)), None, False),
              ((0.03, 1.0), (1.0, 1.2, 1.0, 1.5), False), ((0.03, 1.0), None, True),
              ((0.03, 1.0), (1.0, 1.2, 1.0, 1.5), True)]


@pytest.mark.parametrize("spread_prior, friction_load, alpha_spread", SITE_CASES)
def test_numpy_potential_of_the_start_equals_numpyros_potential_energy(spread_prior, friction_load, alpha_spread):
    """The sampler's start carries a potential computed in numpy (inference._model); NumPyro's
    own potential_energy of the same model must give the same number, at the start and away
    from it, with every site's prior and Jacobian; with one spread prior for all coefficients,
    with a prior of their own (fit's mass refit holds Me's), and with the payload's friction
    gain among the sites."""
    from numpyro.infer.util import potential_energy as numpyro_potential, unconstrain_fn

    from bayes_sst.inference._model import potential_energy, table_force_model, unconstrained_start

    rng, table, numpy_table, priors, values = _site_problem(7, spread_prior, friction_load=friction_load,
                                                            alpha_spread=alpha_spread)
    z = unconstrained_start(values, priors)
    z_numpyro = unconstrain_fn(table_force_model, (table, priors), {}, {k: jnp.asarray(v) for k, v in values.items()})
    for name in values:
        np.testing.assert_allclose(z[name], np.asarray(z_numpyro[name]), atol=1e-12)
    for shift in (0.0, 0.7, -1.5):
        moved = {name: value + shift * rng.standard_normal(np.shape(value)) for name, value in z.items()}
        expected = float(numpyro_potential(table_force_model, (table, priors), {},
                                           {k: jnp.asarray(v) for k, v in moved.items()}))
        assert potential_energy(moved, numpy_table, priors) == pytest.approx(expected, rel=1e-10, abs=1e-8)



@pytest.mark.parametrize("spread_prior, friction_load, alpha_spread", SITE_CASES)
def test_numpy_gradient_of_the_start_equals_numpyros_gradient(spread_prior, friction_load, alpha_spread):
    """The start also carries the potential's gradient from numpy (inference._model.
    potential_gradient); reverse-mode differentiation of NumPyro's potential_energy of the same
    model must give the same vector for every site, with a coefficient shared (Ke), with
    per-coefficient spread priors, and with the payload's friction gain among the sites."""
    from numpyro.infer.util import potential_energy as numpyro_potential

    from bayes_sst.inference._model import potential_gradient, table_force_model, unconstrained_start

    rng, table, numpy_table, priors, values = _site_problem(11, spread_prior, friction_load=friction_load,
                                                            alpha_spread=alpha_spread)
    z = unconstrained_start(values, priors)

    def potential(sites):
        return numpyro_potential(table_force_model, (table, priors), {}, sites)

    for shift in (0.0, 0.4, -0.8):
        moved = {name: value + shift * rng.standard_normal(np.shape(value)) for name, value in z.items()}
        expected = jax.grad(potential)({k: jnp.asarray(v) for k, v in moved.items()})
        got = potential_gradient(moved, numpy_table, priors)
        for name in values:
            assert np.shape(got[name]) == np.shape(moved[name]), name
            np.testing.assert_allclose(got[name], np.asarray(expected[name]), rtol=1e-7, atol=1e-8, err_msg=name)
        assert got["spread"][1] != 0.0  # a shared coefficient's spread still has its prior's pull


@pytest.mark.parametrize("spread_prior, friction_load, alpha_spread", SITE_CASES)
def test_the_samplers_whitened_potential_is_numpyros_potential_of_the_model(spread_prior, friction_load,
                                                                          alpha_spread):
    """fit samples w with z_global = centre + root w (WhitenedFrame) through whitened_potential,
    in place of NumPyro's potential of table_force_model with a dense mass over z_global. The
    two must be one density: the same value at the same point, JAX's gradient over w equal to
    root' times NumPyro's gradient over z_global (and the per-test sites' as they are), and the
    frame's numpy maps (to_sampler, from_sampler, gradient_to_sampler) consistent with them."""
    from numpyro.infer.util import potential_energy as numpyro_potential

    from bayes_sst.inference._model import (WhitenedFrame, global_sites, potential_and_gradient,
                                            table_force_model, unconstrained_start, whitened_potential)

    rng, table, numpy_table, priors, values = _site_problem(13, spread_prior, friction_load=friction_load,
                                                            alpha_spread=alpha_spread)
    z = unconstrained_start(values, priors)
    size = sum(int(np.size(z[name])) for name in global_sites(z))
    loose = rng.standard_normal((size, size))
    frame = WhitenedFrame.around(z, loose @ loose.T + 0.5 * np.eye(size))
    for shift in (0.0, 0.5, -1.0):
        moved = {name: value + shift * rng.standard_normal(np.shape(value)) for name, value in z.items()}
        params = frame.to_sampler(moved)
        back = frame.from_sampler(params)
        for name in moved:
            np.testing.assert_allclose(back[name], moved[name], rtol=1e-12, atol=1e-12, err_msg=name)

        def model_potential(sites):
            return numpyro_potential(table_force_model, (table, priors), {}, sites)

        expected_value = float(model_potential({k: jnp.asarray(v) for k, v in moved.items()}))
        expected_gradient = frame.gradient_to_sampler(
            jax.grad(model_potential)({k: jnp.asarray(v) for k, v in moved.items()}))
        value, gradient = jax.value_and_grad(whitened_potential)(
            {k: jnp.asarray(v) for k, v in params.items()}, table, priors, frame)
        assert float(value) == pytest.approx(expected_value, rel=1e-10, abs=1e-8)
        numpy_value, numpy_gradient = potential_and_gradient(moved, numpy_table, priors)
        assert numpy_value == pytest.approx(expected_value, rel=1e-10, abs=1e-8)
        for name in params:
            np.testing.assert_allclose(np.asarray(gradient[name]), expected_gradient[name], rtol=1e-7, atol=1e-8,
                                       err_msg=name)
            np.testing.assert_allclose(frame.gradient_to_sampler(numpy_gradient)[name], expected_gradient[name],
                                       rtol=1e-7, atol=1e-8, err_msg=name)
        assert np.all(np.abs(expected_gradient["global"]) > 0)


def _start_problem():
    """A small collapsed problem, its priors and a start in the unconstrained space."""
    from bayes_sst.inference._model import unconstrained_start

    _, table, numpy_table, priors, values = _site_problem(
        5, varying=(1.0, 1.0, 1.0, 1.0), noise_loc=0.0, n_samples=80,
        phi=(0.3, -0.2, 0.5, 0.0, 0.1), sigma=(0.9, 1.1, 1.3, 0.7, 1.0))
    return table, numpy_table, priors, unconstrained_start(values, priors)


def test_the_posterior_mode_is_where_the_potential_is_flat_and_lowest_around():
    """posterior_mode must end where dU/dz is ~0 (a thousandth of the start's) and U is below the start,
    and no random nearby point may be lower; a search whose potential cannot be evaluated
    returns the start unchanged."""
    from bayes_sst.inference import _model
    from bayes_sst.inference._model import posterior_mode, potential_energy, potential_gradient

    _, numpy_table, priors, z = _start_problem()
    scales = {"alpha": 0.1, "spread": np.full(4, 0.3), "phi": np.full(5, 0.1), "sigma": np.full(5, 0.1)}
    mode = posterior_mode(z, numpy_table, priors, scales)
    lowest = potential_energy(mode, numpy_table, priors)
    assert lowest < potential_energy(z, numpy_table, priors) - 1.0
    def steepest(sites):
        return max(np.max(np.abs(g)) for g in potential_gradient(sites, numpy_table, priors).values())

    assert steepest(z) > 10.0
    assert steepest(mode) < 1e-3 * steepest(z)
    rng = np.random.default_rng(2)
    for _ in range(20):
        nearby = {name: value + 0.05 * rng.standard_normal(np.shape(value)) for name, value in mode.items()}
        assert potential_energy(nearby, numpy_table, priors) > lowest

    def broken(*args, **kwargs):
        return float("nan"), {}

    original = _model.potential_and_gradient
    _model.potential_and_gradient = broken
    try:
        kept = posterior_mode(z, numpy_table, priors, scales)
    finally:
        _model.potential_and_gradient = original
    for name in z:
        np.testing.assert_array_equal(kept[name], z[name])


def test_global_curvature_equals_the_hessian_of_numpyros_potential():
    """global_curvature's finite differences of the numpy gradient must match JAX's exact
    second derivatives of NumPyro's potential over alpha and the four spreads."""
    from numpyro.infer.util import potential_energy as numpyro_potential

    from bayes_sst.inference._model import global_curvature, table_force_model

    table, numpy_table, priors, z = _start_problem()

    def potential(global_sites):
        sites = {"alpha": global_sites[0], "spread": global_sites[1:],
                 "phi": jnp.asarray(z["phi"]), "sigma": jnp.asarray(z["sigma"])}
        return numpyro_potential(table_force_model, (table, priors), {}, sites)

    flat = jnp.concatenate([jnp.atleast_1d(jnp.asarray(z["alpha"])), jnp.asarray(z["spread"])])
    expected = np.asarray(jax.hessian(potential)(flat))
    got = global_curvature(z, numpy_table, priors)
    assert got.shape == (5, 5)
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-5 * np.abs(expected).max())

def _damping_problem(rng, n_tests=5, n_samples=120):
    """Tests with a real damping column |v|^alpha sign v tabulated on a 0.025 grid (alpha moves
    the likelihood), force = x . theta_j + AR(1)-ish noise."""
    grid = np.arange(0.05, 1.96, 0.025)
    per_test = []
    for j in range(n_tests):
        t = np.arange(n_samples) * 0.03
        w = 1.0 + 0.4 * j
        v = np.cos(w * t) + 0.05 * rng.standard_normal(n_samples)
        base = np.stack([-w * np.sin(w * t), np.sin(w * t) / w, np.zeros(n_samples), np.sign(v)])

        def columns(alpha):
            c = np.abs(v) ** alpha * np.sign(v)
            X = base.copy()
            X[2] = c
            dX = np.zeros_like(X)
            dX[2] = c * np.log(np.abs(v))
            return X, dX

        X, dX = (np.stack(parts) for parts in zip(*(columns(a) for a in grid)))
        theta = np.array([1.0, 1.0, 0.6, 0.3]) * (1 + 0.05 * rng.standard_normal(4))
        y = theta @ columns(0.7)[0] + 0.05 * np.convolve(rng.standard_normal(n_samples), [1.0, 0.5], "same")
        per_test.append((y, X, dX))
    return _table(per_test, grid)


@pytest.mark.parametrize("shared_friction", [False, True])
def test_closed_form_gradient_equals_reverse_mode_differentiation(shared_friction):
    """The sampler's likelihood carries a hand-derived gradient (Fisher's identity, see
    marginal_gradient); it must equal JAX's reverse-mode derivative of the same value, for
    every sampled site, with and without a coefficient shared by all tests (spread 0)."""
    from bayes_sst.inference._collapsed import _collapsed_value

    rng = np.random.default_rng(11)
    table = _damping_problem(rng)
    J = table.n_pairs.shape[0]
    for _ in range(3):
        rho = np.array([0.05, 0.08, 0.2, 0.1]) * np.exp(0.3 * rng.standard_normal(4))
        if shared_friction:
            rho[3] = 0.0
        args = (jnp.asarray(rng.uniform(0.4, 1.2)), jnp.asarray(rho), jnp.asarray(rng.uniform(-0.5, 0.8, J)),
                jnp.asarray(rng.uniform(0.03, 0.1, J)), jnp.asarray(1 + 0.1 * rng.standard_normal(4)),
                jnp.full(4, 0.7))
        ours = jax.value_and_grad(lambda *a: collapsed_log_likelihood(table, *a), argnums=tuple(range(6)))(*args)
        traced = jax.value_and_grad(lambda *a: _collapsed_value(table, *a, jnp), argnums=tuple(range(6)))(*args)
        assert float(ours[0]) == pytest.approx(float(traced[0]), rel=1e-12)
        for name, mine, reference in zip(("alpha", "rho", "phi", "sigma", "m0", "s0"), ours[1], traced[1]):
            mine, reference = np.asarray(mine), np.asarray(reference)
            assert np.all(np.isfinite(mine)), name
            assert np.allclose(mine, reference, rtol=1e-7, atol=1e-9 * np.max(np.abs(reference))), name
        if shared_friction:
            assert float(ours[1][1][3]) == 0.0


def test_the_payload_friction_gain_scales_the_coulomb_column_and_its_gradient_is_exact():
    """kappa rescales test j's Coulomb column from L_j filter(sign v) to (1 + kappa (L_j - 1))
    filter(sign v): the likelihood at kappa must equal that of moments whose SIGN row and column
    were multiplied by s_j = (1 + kappa (L_j - 1))/L_j by hand; kappa = 1 must leave the
    likelihood as it is without loads; and the closed-form derivative in kappa (with those in
    alpha and phi, which the scaling also enters) must equal reverse-mode differentiation."""
    from bayes_sst.inference._collapsed import SIGN, _collapsed_value

    rng = np.random.default_rng(21)
    plain = _damping_problem(rng)
    J = plain.n_pairs.shape[0]
    loads = 1.0 + rng.uniform(0.0, 0.6, J)
    loads[0] = 1.0
    loaded = plain._replace(load_share=jnp.asarray(1.0 - 1.0 / loads))
    args = (jnp.asarray(0.7), jnp.array([0.05, 0.08, 0.2, 0.1]), jnp.asarray(rng.uniform(-0.5, 0.8, J)),
            jnp.asarray(rng.uniform(0.03, 0.1, J)), jnp.ones(4), jnp.full(4, 0.7))
    assert float(collapsed_log_likelihood(loaded, *args, gain=1.0)) == pytest.approx(
        float(collapsed_log_likelihood(plain, *args)), rel=1e-13)
    for gain in (0.0, 0.4, 2.5):
        factors = (1.0 + gain * (loads - 1.0)) / loads
        column = np.ones((5, J))
        column[SIGN] = factors
        by_hand = plain._replace(constant=plain.constant * column[:, None] * column[None, :],
                                 cross=plain.cross.at[:, :, :, 3].multiply(factors))
        assert float(collapsed_log_likelihood(loaded, *args, gain=gain)) == pytest.approx(
            float(collapsed_log_likelihood(by_hand, *args)), rel=1e-11)
        ours = jax.grad(lambda a, p, k: collapsed_log_likelihood(loaded, a, args[1], p, *args[3:], gain=k),
                        argnums=(0, 1, 2))(args[0], args[2], jnp.asarray(gain))
        traced = jax.grad(lambda a, p, k: _collapsed_value(loaded, a, args[1], p, *args[3:], jnp, k),
                          argnums=(0, 1, 2))(args[0], args[2], jnp.asarray(gain))
        for name, mine, reference in zip(("alpha", "phi", "gain"), ours, traced):
            np.testing.assert_allclose(np.asarray(mine), np.asarray(reference), rtol=1e-8,
                                       atol=1e-10 * np.max(np.abs(np.asarray(reference))), err_msg=name)
        assert abs(float(ours[2])) > 0.0


def test_closed_form_gradient_holds_when_the_force_is_far_above_its_noise():
    """Force 1e4 times its noise, the likelihood's own floor (RELATIVE_NOISE_FLOOR; the regime
    where the algebraic forms cancel, see test_terms): the closed-form gradient against
    reverse-mode differentiation. (At 1e5 the reverse-mode derivative itself comes out in
    steps of 2^-7 or so, and the two differ by 0.1 %.)"""
    from bayes_sst.inference._collapsed import _collapsed_value

    rng = np.random.default_rng(12)
    _, table = _precise_problem(rng, 1e-5)
    J = table.n_pairs.shape[0]
    args = (jnp.asarray(0.5), jnp.full(4, 0.1), jnp.zeros(J), jnp.full(J, 1e-4), jnp.ones(4), jnp.full(4, 1e3))
    ours = jax.grad(lambda *a: collapsed_log_likelihood(table, *a), argnums=(1, 2, 3))(*args)
    traced = jax.grad(lambda *a: _collapsed_value(table, *a, jnp), argnums=(1, 2, 3))(*args)
    for mine, reference in zip(ours, traced):
        assert np.allclose(np.asarray(mine), np.asarray(reference), rtol=1e-4, atol=1e-6 * np.max(np.abs(reference)))


def test_coefficient_draws_for_many_draws_at_once_equal_draw_by_draw():
    """build_tree draws the coefficients for blocks of posterior draws in one call; each draw
    must be what the one-draw call gives."""
    rng = np.random.default_rng(13)
    table = _damping_problem(rng)
    host = MomentTable(*(np.asarray(x) if hasattr(x, "shape") else x for x in table))
    n_draws, J = 6, table.n_pairs.shape[0]
    alpha = rng.uniform(0.4, 1.2, n_draws)
    rho = np.array([0.05, 0.08, 0.2, 0.1])[:, None] * np.exp(0.3 * rng.standard_normal((4, n_draws)))
    rho[3, :2] = 0.0
    phi, sigma = rng.uniform(-0.5, 0.8, (n_draws, J)), rng.uniform(0.03, 0.1, (n_draws, J))
    normal_mu, normal_theta = rng.standard_normal((n_draws, 4)), rng.standard_normal((n_draws, J, 4))
    m0, s0 = np.ones(4), np.full(4, 0.7)
    together = draw_coefficients(normal_mu.T, normal_theta, host, alpha, rho, phi, sigma, m0, s0, xp=np)
    for i in range(n_draws):
        alone = draw_coefficients(normal_mu[i], normal_theta[i], host, alpha[i], rho[:, i], phi[i], sigma[i],
                                  m0, s0, xp=np)
        assert together.exponents is None and alone.exponents is None
        for part_together, part_alone in zip(together[:3], alone[:3]):
            assert np.allclose(part_together[i], part_alone, rtol=1e-12, atol=1e-12)


def test_a_shared_coefficients_ignored_spread_moves_the_population_as_refitted_data_do():
    """Priors.ignored_spread: with Me shared (rho_Me = 0), a standard normal z_j = 1 for test j
    alone must move mu exactly as refitting the data with test j's true Me raised by
    s*|mu_Me| does (the conditional mean is linear in the data), and z = 0 must change nothing."""
    rng = np.random.default_rng(21)
    t = np.arange(80) * 0.05
    per_test = []
    for j in range(4):
        w = 1.0 + 0.4 * j
        x = np.stack([-w * w * np.sin(w * t) + 0.05 * np.sin(3 * w * t), np.sin(w * t),
                      np.abs(np.cos(w * t)) ** 0.5 * np.sign(np.cos(w * t)), np.sign(np.cos(w * t))])
        y = (1.0 + 0.1 * rng.standard_normal(4)) @ x + 0.05 * rng.standard_normal(len(t))
        per_test.append((y, x))

    def host_table(data):
        table = _table([(y, np.stack([x, x]), np.zeros((2, 4, len(y)))) for y, x in data], np.array([0.0, 1.0]))
        return MomentTable(*(np.asarray(v) if hasattr(v, "shape") else v for v in table))

    J = len(per_test)
    rho = np.array([0.0, 0.1, 0.05, 0.1])
    phi, sigma = np.full(J, 0.3), np.full(J, 0.05)
    m0, s0 = np.ones(4), np.full(4, 10.0)
    spread = np.array([0.02, 0.0, 0.0, 0.0])
    zero_mu, zero_theta = np.zeros(4), np.zeros((J, 4))
    plain = draw_coefficients(zero_mu, zero_theta, host_table(per_test), 0.5, rho, phi, sigma, m0, s0, xp=np)[0]
    unmoved = draw_coefficients(zero_mu, zero_theta, host_table(per_test), 0.5, rho, phi, sigma, m0, s0, xp=np,
                                ignored_spread=spread, normal_ignored=np.zeros((4, J)))[0]
    assert np.allclose(unmoved, plain, rtol=0, atol=1e-14)
    for j in range(J):
        one_hot = np.zeros((4, J))
        one_hot[0, j] = 1.0
        moved = draw_coefficients(zero_mu, zero_theta, host_table(per_test), 0.5, rho, phi, sigma, m0, s0, xp=np,
                                  ignored_spread=spread, normal_ignored=one_hot)[0]
        shifted = [(y + (0.02 * abs(plain[0]) * x[0] if i == j else 0.0), x) for i, (y, x) in enumerate(per_test)]
        refitted = draw_coefficients(zero_mu, zero_theta, host_table(shifted), 0.5, rho, phi, sigma, m0, s0, xp=np)[0]
        # to 1e-5 of the shift: the table's relative noise floor follows the data's scale
        assert np.max(np.abs(moved - refitted)) < 1e-5 * np.max(np.abs(refitted - plain)), j
        assert abs(moved[0] - plain[0]) > 1e-4  # each test moves the shared mass


def test_a_per_test_exponent_deviation_integrates_out_as_one_more_gaussian_coefficient():
    """Each test's deviation coefficient c_j ~ N(0, rho_d^2) on the damping column's
    alpha-derivative (DEVIATION, absorb_deviation) must give the likelihood of a dense joint
    Gaussian in which every test has that fifth column with a zero-mean coefficient of sd rho_d,
    at alpha on a grid node (where the interpolated d' is the tabulated one); rho_d -> 0 must
    give back the plain likelihood, and a larger rho_d must fit data whose tests differ in their
    exponent better than rho_d -> 0 does."""
    rng = np.random.default_rng(31)
    grid = np.arange(0.05, 1.96, 0.025)
    node = 26  # alpha = 0.7
    alpha = float(grid[node])
    per_test, zs = [], []
    for j in range(4):
        t = np.arange(90) * 0.03
        w = 1.0 + 0.5 * j
        v = (0.3 + 0.2 * j) * np.cos(w * t) + 0.02 * rng.standard_normal(len(t))
        base = np.stack([-w * np.sin(w * t), np.sin(w * t) / w, np.zeros(len(t)), np.sign(v)])
        X = np.repeat(base[None], len(grid), axis=0)
        X[:, 2] = np.abs(v)[None] ** grid[:, None] * np.sign(v)[None]
        dX = np.zeros_like(X)
        dX[:, 2] = X[:, 2] * np.log(np.abs(v))[None]
        exponent = alpha + 0.15 * (j - 1.5)  # tests that read different exponents
        y = (base[0] + base[1] + 0.6 * np.abs(v) ** exponent * np.sign(v) + 0.3 * base[3]
             + 0.005 * rng.standard_normal(len(t)))
        per_test.append((y, X, dX))
        zs.append(np.vstack([y, X[node], dX[node, 2]]))
    table = _table(per_test, grid)
    J = len(per_test)
    phi, sigma = np.array([0.2, -0.1, 0.4, 0.0]), np.array([0.006, 0.005, 0.007, 0.005])
    rho, m0, s0 = np.array([0.1, 0.2, 0.3, 0.1]), np.array([1.0, 1.0, 0.5, 0.3]), np.array([1.0, 1.0, 0.5, 0.5])
    args = (jnp.asarray(alpha), jnp.asarray(rho), jnp.asarray(phi), jnp.asarray(sigma), jnp.asarray(m0), jnp.asarray(s0))

    def dense(spread):
        ys, Xs, Ds = [], [], []
        for z, p in zip(zs, phi):
            whitened = z[:, 1:] - p * z[:, :-1]
            ys.append(whitened[0])
            Xs.append(whitened[1:5].T)
            Ds.append(whitened[5])
        y, X_mu = np.concatenate(ys), np.concatenate(Xs)
        cov = X_mu @ np.diag(s0**2) @ X_mu.T
        offset = 0
        for X, D, s in zip(Xs, Ds, sigma):
            n = len(D)
            block = slice(offset, offset + n)
            cov[block, block] += X @ np.diag(rho**2) @ X.T + spread**2 * np.outer(D, D) + s**2 * np.eye(n)
            offset += n
        resid = y - X_mu @ m0
        return -0.5 * (len(y) * np.log(2 * np.pi) + np.linalg.slogdet(cov)[1] + resid @ np.linalg.solve(cov, resid))

    for spread in (0.02, 0.1, 0.5):
        ours = float(collapsed_log_likelihood(table, *args, deviation=jnp.asarray(spread)))
        assert ours == pytest.approx(dense(spread), rel=1e-9, abs=1e-7)
    plain = float(collapsed_log_likelihood(table, *args))
    assert float(collapsed_log_likelihood(table, *args, deviation=jnp.asarray(1e-7))) == pytest.approx(plain, abs=1e-4)
    # with Ce nearly shared, only the deviation can take up the tests' different exponents
    tight = (args[0], jnp.asarray([0.1, 0.2, 0.02, 0.1])) + args[2:]
    assert (float(collapsed_log_likelihood(table, *tight, deviation=jnp.asarray(0.15)))
            > float(collapsed_log_likelihood(table, *tight)) + 10.0)
    # the draws' per-test log-likelihood carries the same integral
    host = MomentTable(*(np.asarray(x) if hasattr(x, "shape") else x for x in table))
    value = collapsed_log_likelihood(host, *(np.asarray(a) for a in args), xp=np, deviation=0.1)
    assert value == pytest.approx(dense(0.1), rel=1e-9, abs=1e-7)
    # each test's exponent given its coefficients: the Gaussian conditional of c_j from the
    # whitened samples themselves, c = d'(y - X theta)/(d'd' + s^2/rho_d^2), delta = c / Ce_j
    from bayes_sst.inference._collapsed import draw_deviations

    theta = np.array([[1.0, 1.0, 0.6, 0.3]]) * (1.0 + 0.1 * rng.standard_normal((J, 4)))
    spread = 0.1
    for normal in (0.0, 1.0):
        got = draw_deviations(np.full((1, J), normal), host, np.array([alpha]), theta[None], phi[None], sigma[None],
                              np.array([spread]))[0]
        for j, (z, p, s, th) in enumerate(zip(zs, phi, sigma, theta)):
            whitened = z[:, 1:] - p * z[:, :-1]
            d = whitened[5]
            precision = d @ d / s**2 + 1.0 / spread**2
            c = (d @ (whitened[0] - th @ whitened[1:5]) / s**2) / precision + normal / np.sqrt(precision)
            assert got[j] == pytest.approx(alpha + c / th[2], rel=1e-9)


def test_the_deviation_spreads_closed_form_gradient_equals_reverse_mode_differentiation():
    """With each test's deviation coefficient integrated out, the closed-form gradient
    (absorb_deviation_gradient through marginal_gradient) against JAX's derivative of the
    traced value, for every sampled site and the spread rho_d, with the payload's gain on."""
    from bayes_sst.inference._collapsed import _collapsed_value

    rng = np.random.default_rng(32)
    table = _damping_problem(rng)
    J = table.n_pairs.shape[0]
    table = table._replace(load_share=jnp.asarray(1.0 - 1.0 / (1.0 + rng.uniform(0.0, 0.5, J))))
    for spread in (0.01, 0.08, 0.4):
        args = (jnp.asarray(rng.uniform(0.4, 1.2)), jnp.asarray(np.array([0.05, 0.08, 0.2, 0.1])),
                jnp.asarray(rng.uniform(-0.5, 0.8, J)), jnp.asarray(rng.uniform(0.03, 0.1, J)),
                jnp.asarray(1 + 0.1 * rng.standard_normal(4)), jnp.full(4, 0.7), jnp.asarray(1.3), jnp.asarray(spread))
        ours = jax.value_and_grad(lambda *a: collapsed_log_likelihood(table, *a[:6], gain=a[6], deviation=a[7]),
                                  argnums=tuple(range(8)))(*args)
        traced = jax.value_and_grad(lambda *a: _collapsed_value(table, *a[:6], jnp, a[6], a[7]),
                                    argnums=tuple(range(8)))(*args)
        assert float(ours[0]) == pytest.approx(float(traced[0]), rel=1e-12)
        for name, mine, reference in zip(("alpha", "rho", "phi", "sigma", "m0", "s0", "gain", "deviation"),
                                         ours[1], traced[1]):
            mine, reference = np.asarray(mine), np.asarray(reference)
            assert np.all(np.isfinite(mine)) and np.max(np.abs(reference)) > 0, name
            np.testing.assert_allclose(mine, reference, rtol=1e-6, atol=1e-8 * np.max(np.abs(reference)), err_msg=name)
