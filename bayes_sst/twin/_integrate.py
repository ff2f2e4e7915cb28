"""Fixed-step integration of the closed-loop table, in JAX: lax.scan in time, vmap over tests.

One internal step (length dt) of the state (u, v, P_L, Q, x, x') (x: a flexible specimen's
drift relative to the deck, zero without one):

1. F_A = A_p*P_L and the controller's flow demand from the state at the step's start;
2. the deck moves under F_A (semi-implicit, stick-slip friction: see _deck.py);
3. the valve flow relaxes towards the demand (exact lag), and the oil column's pressure
   follows the new flow and the new deck velocity (symplectic Euler for the oil-spring/mass
   pair, which keeps its resonance undamped by the integrator: omega_oil*dt ~ 0.05).

Signals are recorded every k-th step, which is how a data logger samples a table: no
anti-aliasing, so oil-column ringing above the output Nyquist frequency would alias, as it
does on real records. Per recorded sample: u, F_A at the step's start, the step's
acceleration (v1 - v0)/dt and its end velocity v1, which satisfy the force balance
M*a = F_A - Ke*u - D(v1) exactly.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
from jax import lax

import bayes_sst._jaxconfig  # noqa: F401  (float64 before any array)
from bayes_sst.twin._deck import DeckParams, deck_step, specimen_shear, specimen_step
from bayes_sst.twin._hydraulics import (
    ServoParams,
    actuator_force,
    flow_demand,
    pressure_step,
    valve_step,
)


def _step(deck: DeckParams, servo: ServoParams, dt, state, command):
    u, v, p_load, q, x, xd = state
    u_cmd, v_cmd = command
    force = actuator_force(servo, p_load)
    q_demand = flow_demand(servo, u_cmd, v_cmd, u, p_load)
    # A flexible specimen (if any) pulls on the deck with its spring and damper.
    u1, v1, a = deck_step(deck, u, v, force + specimen_shear(deck, x, xd), dt)
    x1, xd1 = specimen_step(deck, x, xd, a, dt)
    q1 = valve_step(servo, q, q_demand, dt)
    p1 = pressure_step(servo, p_load, q1, v1, dt)
    return (u1, v1, p1, q1, x1, xd1), (u, v1, a, force)


def _one_test(deck: DeckParams, servo: ServoParams, dt, u_cmd, v_cmd):
    """u_cmd, v_cmd of shape (n_samples, k): k internal steps per recorded sample."""
    step = partial(_step, deck, servo, dt)

    def sample(state, commands):
        cu, cv = commands
        state, record = step(state, (cu[0], cv[0]))
        state, _ = lax.scan(lambda s, c: (step(s, c)[0], None), state, (cu[1:], cv[1:]))
        return state, record

    zero = jnp.zeros((), dtype=jnp.float64)
    _, records = lax.scan(sample, (zero,) * 6, (u_cmd, v_cmd))
    return records


@jax.jit
def integrate(deck: DeckParams, servo: ServoParams, dt, u_cmd, v_cmd):
    """Simulate a batch of tests from rest.

    deck: DeckParams of arrays, shape (n_tests,); servo: ServoParams of scalars; dt: the
    internal step, s; u_cmd, v_cmd: commands at the internal rate, shape (n_tests, n_samples, k).
    Returns u, v, a, F of shape (n_tests, n_samples), recorded every k-th step.
    """
    run = jax.vmap(_one_test, in_axes=(0, None, None, 0, 0))
    return run(deck, servo, dt, u_cmd, v_cmd)
