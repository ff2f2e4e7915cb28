"""The table's force balance, as a pure JAX function of parameters and signals."""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

import bayes_sst._jaxconfig  # noqa: F401  (float64 before any array)

PARAMETER_NAMES = ("Me", "Ke", "Ce", "alpha", "Fmu")


class ForceParams(NamedTuple):
    """Parameters of the base force model, SI units.

    Me : effective moving mass, kg
    Ke : strut stiffness, N/m
    Ce : power-law damping coefficient, N/(m/s)^alpha
    alpha : damping exponent, dimensionless
    Fmu : Coulomb (kinetic) friction force, N
    """

    Me: float
    Ke: float
    Ce: float
    alpha: float
    Fmu: float


def damping_regressor(v, alpha):
    """|v|^alpha * sign(v), with a derivative in alpha that stays finite at v = 0.

    The power is written as exp(alpha*log|v|) on the non-zero entries only, so that
    gradients with respect to alpha and v are defined everywhere (0^alpha is 0 for alpha > 0).
    """
    speed = jnp.abs(v)
    moving = speed > 0.0
    safe = jnp.where(moving, speed, 1.0)
    return jnp.where(moving, jnp.exp(alpha * jnp.log(safe)), 0.0) * jnp.sign(v)


def force(params: ForceParams, u, v, a):
    """Actuator force of the base model.

    F_A = Me*a + Ke*u + (Ce*|v|^alpha + Fmu)*sign(v)

    Arrays u, v, a broadcast together; the result has their shape. Pure, so it can be
    jit-compiled, differentiated in params or signals, and vmapped over tests or draws.
    """
    return (
        params.Me * a
        + params.Ke * u
        + params.Ce * damping_regressor(v, params.alpha)
        + params.Fmu * jnp.sign(v)
    )


def dissipative_force(params: ForceParams, v):
    """F_D(v) = (Ce*|v|^alpha + Fmu)*sign(v): the part of F_A that is odd in velocity."""
    return params.Ce * damping_regressor(v, params.alpha) + params.Fmu * jnp.sign(v)
