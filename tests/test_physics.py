"""The force model and the component relations against hand calculations and finite differences.

Reference values come from the closed forms written out in each test (pen-and-paper
arithmetic, quoted in the comments), from central finite differences of the function itself
for the gradients, and from plain Python loops for jit/vmap.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from bayes_sst import physics
from bayes_sst.physics import ForceParams, dissipative_force, force

# Round numbers so that the hand calculations below are exact: |v|^0.5 at v = 0.25 is 0.5,
# at v = 0.04 is 0.2.
P = ForceParams(Me=1000.0, Ke=2.0e5, Ce=4000.0, alpha=0.5, Fmu=500.0)


# --------------------------------------------------------------------------- force values


@pytest.mark.parametrize(
    "u, v, a, expected",
    [
        # 1000*(-2) + 2e5*0.01 + 4000*0.25^0.5 + 500 = -2000 + 2000 + 2000 + 500
        (0.01, 0.25, -2.0, 2500.0),
        # 1000*3 + 2e5*(-0.02) - 4000*0.04^0.5 - 500 = 3000 - 4000 - 800 - 500
        (-0.02, -0.04, 3.0, -2300.0),
        # v = 0: sign(0) = 0, so neither damping nor friction acts: 1000*1.5 + 2e5*0.005
        (0.005, 0.0, 1.5, 2500.0),
        # v = 0 and u = a = 0: nothing at all
        (0.0, 0.0, 0.0, 0.0),
    ],
)
def test_force_matches_hand_calculation(u, v, a, expected):
    value = force(P, u, v, a)
    assert value.dtype == jnp.float64
    assert float(value) == pytest.approx(expected, rel=1e-12, abs=1e-9)


def test_force_broadcasts_and_is_float64():
    u = np.array([0.01, -0.02, 0.005])
    v = np.array([0.25, -0.04, 0.0])
    a = np.array([-2.0, 3.0, 1.5])
    out = force(P, u, v, a)
    assert out.shape == (3,)
    assert out.dtype == jnp.float64
    np.testing.assert_allclose(np.asarray(out), [2500.0, -2300.0, 2500.0], rtol=1e-12)
    # scalar a broadcast against arrays u, v
    out2 = force(P, u, v, 0.0)
    np.testing.assert_allclose(np.asarray(out2), [4500.0, -5300.0, 1000.0], rtol=1e-12)


def test_force_keeps_float64_precision():
    # 1e5 N forces and 1e-9 m displacements: a float32 result would lose Ke*u entirely.
    p = ForceParams(Me=0.0, Ke=1.0e6, Ce=0.0, alpha=0.5, Fmu=1.0e5)
    out = force(p, 1.0e-9, 1.0, 0.0)
    assert out.dtype == jnp.float64
    # 1e5 + 1e6*1e-9 = 100000.001
    assert float(out) - 1.0e5 == pytest.approx(1.0e-3, rel=1e-6)


# --------------------------------------------------------------------------- gradients


def _central_difference(fun, x, rel_step=1e-6):
    h = rel_step * max(abs(x), 1e-3)
    return (fun(x + h) - fun(x - h)) / (2.0 * h)


@pytest.mark.parametrize("v", [0.3, -0.07])
@pytest.mark.parametrize("name", physics.PARAMETER_NAMES)
def test_parameter_gradient_matches_finite_difference(name, v):
    u, a = 0.012, -1.7
    params = ForceParams(Me=13200.0, Ke=7.2e5, Ce=2.0e4, alpha=0.6, Fmu=1.25e4)
    grad = jax.grad(lambda p: force(p, u, v, a))(params)
    analytic = float(getattr(grad, name))

    def f_of(x):
        return float(force(params._replace(**{name: x}), u, v, a))

    numeric = _central_difference(f_of, getattr(params, name))
    assert analytic == pytest.approx(numeric, rel=1e-6, abs=1e-9)
    # closed forms, as a second, independent reference
    s, speed = math.copysign(1.0, v), abs(v)
    closed = {
        "Me": a,
        "Ke": u,
        "Ce": speed**params.alpha * s,
        "alpha": params.Ce * speed**params.alpha * math.log(speed) * s,
        "Fmu": s,
    }[name]
    assert analytic == pytest.approx(closed, rel=1e-12)


@pytest.mark.parametrize("v", [0.3, -0.07])
def test_signal_gradients_match_finite_difference(v):
    u, a = 0.012, -1.7
    params = ForceParams(Me=13200.0, Ke=7.2e5, Ce=2.0e4, alpha=0.6, Fmu=1.25e4)
    gu, gv, ga = jax.grad(lambda u_, v_, a_: force(params, u_, v_, a_), argnums=(0, 1, 2))(u, v, a)
    fd_u = _central_difference(lambda x: float(force(params, x, v, a)), u)
    fd_v = _central_difference(lambda x: float(force(params, u, x, a)), v)
    fd_a = _central_difference(lambda x: float(force(params, u, v, x)), a)
    assert float(gu) == pytest.approx(fd_u, rel=1e-6)
    assert float(gv) == pytest.approx(fd_v, rel=1e-6)
    assert float(ga) == pytest.approx(fd_a, rel=1e-6)
    # closed forms: dF/du = Ke, dF/da = Me, dF/dv = Ce*alpha*|v|^(alpha-1) (the step has 0 slope)
    assert float(gu) == pytest.approx(params.Ke, rel=1e-12)
    assert float(ga) == pytest.approx(params.Me, rel=1e-12)
    assert float(gv) == pytest.approx(params.Ce * params.alpha * abs(v) ** (params.alpha - 1.0), rel=1e-12)


def test_gradients_finite_at_zero_velocity():
    params = ForceParams(Me=13200.0, Ke=7.2e5, Ce=2.0e4, alpha=0.6, Fmu=1.25e4)
    grad = jax.grad(lambda p: force(p, 0.01, 0.0, 2.0))(params)
    values = np.array([float(g) for g in grad])
    assert np.all(np.isfinite(values))
    # At v = 0 the damping and friction terms are identically 0, so their parameter
    # derivatives are 0; Me and Ke still see a and u.
    assert float(grad.alpha) == 0.0
    assert float(grad.Ce) == 0.0
    assert float(grad.Fmu) == 0.0
    assert float(grad.Me) == pytest.approx(2.0)
    assert float(grad.Ke) == pytest.approx(0.01)
    # the same holds for a batch that mixes zero and non-zero velocities
    v = jnp.array([0.0, 0.2, -0.2, 0.0])
    g_alpha = jax.grad(lambda al: jnp.sum(force(params._replace(alpha=al), 0.0, v, 0.0)))(0.6)
    assert np.isfinite(float(g_alpha))
    # d/dalpha of Ce*|v|^alpha*sign(v) cancels between +0.2 and -0.2
    assert float(g_alpha) == pytest.approx(0.0, abs=1e-9)


# --------------------------------------------------------------------------- jit / vmap


def test_jit_and_vmap_match_python_loop():
    rng = np.random.default_rng(7)
    n_sets, n_samples = 5, 40
    batch = ForceParams(
        Me=rng.uniform(5e3, 2e4, n_sets),
        Ke=rng.uniform(1e5, 1e6, n_sets),
        Ce=rng.uniform(1e3, 3e4, n_sets),
        alpha=rng.uniform(0.2, 1.0, n_sets),
        Fmu=rng.uniform(1e3, 2e4, n_sets),
    )
    u = rng.normal(0.0, 0.03, n_samples)
    v = rng.normal(0.0, 0.2, n_samples)
    v[::7] = 0.0  # some exact zeros
    a = rng.normal(0.0, 2.0, n_samples)

    looped = np.stack(
        [np.asarray(force(ForceParams(*(float(x[i]) for x in batch)), u, v, a)) for i in range(n_sets)]
    )
    # independent numpy evaluation of the same formula
    by_hand = np.stack(
        [
            batch.Me[i] * a
            + batch.Ke[i] * u
            + (batch.Ce[i] * np.abs(v) ** batch.alpha[i] + batch.Fmu[i]) * np.sign(v)
            for i in range(n_sets)
        ]
    )
    np.testing.assert_allclose(looped, by_hand, rtol=1e-12, atol=1e-8)

    batched = jax.vmap(force, in_axes=(0, None, None, None))(batch, u, v, a)
    jitted = jax.jit(jax.vmap(force, in_axes=(0, None, None, None)))(batch, u, v, a)
    single_jit = jax.jit(force)
    jit_loop = np.stack(
        [np.asarray(single_jit(ForceParams(*(x[i] for x in batch)), u, v, a)) for i in range(n_sets)]
    )
    assert batched.shape == (n_sets, n_samples)
    assert jitted.dtype == jnp.float64
    np.testing.assert_allclose(np.asarray(batched), looped, rtol=1e-13, atol=1e-9)
    np.testing.assert_allclose(np.asarray(jitted), looped, rtol=1e-13, atol=1e-9)
    np.testing.assert_allclose(jit_loop, looped, rtol=1e-13, atol=1e-9)


# --------------------------------------------------------------------------- dissipative part


def test_dissipative_force_is_odd_and_power_law():
    v = np.array([1e-6, 0.01, 0.04, 0.25, 0.7, 1.3])
    pos = np.asarray(dissipative_force(P, v))
    neg = np.asarray(dissipative_force(P, -v))
    np.testing.assert_array_equal(neg, -pos)
    # Fmu + Ce*v^alpha for v > 0; v = 0.04 -> 500 + 4000*0.2 = 1300, v = 0.25 -> 2500
    np.testing.assert_allclose(pos, P.Fmu + P.Ce * v**P.alpha, rtol=1e-12)
    assert pos[2] == pytest.approx(1300.0, rel=1e-12)
    assert pos[3] == pytest.approx(2500.0, rel=1e-12)
    assert float(dissipative_force(P, 0.0)) == 0.0
    # it is exactly the velocity part of force()
    u, a = 0.02, -0.5
    np.testing.assert_allclose(
        np.asarray(force(P, u, v, a)) - (P.Me * a + P.Ke * u), pos, rtol=1e-12
    )


# --------------------------------------------------------------------------- components


def test_hold_down_force_and_strut_stiffness():
    # 4 * 6.9e6 Pa * 0.0314 m^2 = 866 640 N
    assert physics.hold_down_force(6.9e6, 0.0314) == pytest.approx(866_640.0, rel=1e-12)
    ke = physics.strut_stiffness(6.9e6, 0.0314, 1.20367)
    # 866 640 N / 1.20367 m = 720 000 N/m (to 5 digits: 866640/1.20367 = 719997.9)
    assert ke == pytest.approx(866_640.0 / 1.20367, rel=1e-12)
    assert ke == pytest.approx(0.72e6, rel=1e-4)
    # stiffness falls as 1/h
    assert physics.strut_stiffness(6.9e6, 0.0314, 2 * 1.20367) == pytest.approx(ke / 2, rel=1e-12)


def test_strut_cubic_stiffness_formula():
    ke, gamma, h, l0 = 7.2e5, 1.4, 1.2, 0.3
    # 0.5*(1.4*1.2/0.3 - 1)*7.2e5 = 0.5*(5.6 - 1)*7.2e5 = 1.656e6
    assert physics.strut_cubic_stiffness(ke, gamma, h, l0) == pytest.approx(1.656e6, rel=1e-12)
    # zero when gamma*h = l0
    assert physics.strut_cubic_stiffness(ke, 1.0, 0.5, 0.5) == pytest.approx(0.0, abs=1e-9)
    # negative when gamma*h < l0
    assert physics.strut_cubic_stiffness(ke, 1.0, 0.25, 0.5) == pytest.approx(-0.25 * ke, rel=1e-12)


def test_normal_force_and_coulomb_friction():
    hold = physics.hold_down_force(6.9e6, 0.0314)
    n = physics.normal_force(hold, 12000.0)
    # 866 640 + 12 000 * 9.80665 = 866 640 + 117 679.8 = 984 319.8 N
    assert n == pytest.approx(984_319.8, rel=1e-12)
    assert physics.STANDARD_GRAVITY == 9.80665
    assert physics.normal_force(hold, 12000.0, g=10.0) == pytest.approx(986_640.0, rel=1e-12)
    fmu = physics.coulomb_friction(0.0127, n)
    # 0.0127 * 984 319.8 = 12 500.86 N
    assert fmu == pytest.approx(12_500.86, rel=1e-6)
    assert fmu == pytest.approx(12.5e3, rel=1e-3)


def test_oil_column_frequency():
    beta, area, volume, mass = 1.4e9, 0.02, 0.0026276, 13200.0
    f2 = physics.oil_column_frequency(beta, area, volume, mass)
    # (1/2pi)*sqrt(2*1.4e9*0.02^2/(0.0026276*13200)) = sqrt(32291.2)/2pi = 179.70/2pi = 28.60 Hz
    assert f2 == pytest.approx(28.60, abs=0.05)
    assert f2 == pytest.approx(math.sqrt(2 * beta * area**2 / (volume * mass)) / (2 * math.pi), rel=1e-12)
    assert physics.oil_column_frequency(beta, area, volume, mass, chambers=2) == f2
    f4 = physics.oil_column_frequency(beta, area, volume, mass, chambers=4)
    assert f4 == pytest.approx(math.sqrt(2.0) * f2, rel=1e-12)
    # payload: f ~ 1/sqrt(M); adding 3*13200 kg halves the frequency
    for payload in (0.0, 3000.0, 10_000.0, 3 * 13200.0):
        fp = physics.oil_column_frequency(beta, area, volume, mass + payload)
        assert fp == pytest.approx(f2 * math.sqrt(mass / (mass + payload)), rel=1e-12)
    assert physics.oil_column_frequency(beta, area, volume, 4 * mass) == pytest.approx(f2 / 2, rel=1e-12)
