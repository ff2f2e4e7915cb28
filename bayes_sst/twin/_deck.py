"""The deck: a rigid mass on nitrogen struts, with power-law damping and stick-slip friction.

    M*dv/dt = F_A - Ke*u - D(v),   D(v) = (Ce*|v|^alpha + Ff(|v|))*sign(v),
    Ff(s) = Fk + (Fs - Fk)*exp(-(s/v_s)^2),

(plus the optional effects of DeckParams: cubic spring, hinge friction, flexible specimen)
and at v = 0 the friction takes whatever value in [-Fs, Fs] holds the deck still. M is Me
plus any rigid payload.

One step of length dt is semi-implicit: the actuator and spring forces are taken at the
start of the step, the dissipative force D at its end (backward Euler),

    M*(v1 - v0)/dt = R - D(v1),   R = F_A - Ke*u0,   u1 = u0 + dt*v1.

Rearranged, M*v1/dt + D(v1) = p with p = M*v0/dt + R. D is set-valued at 0, so:

* |p| <= Fs: the deck is (or comes to) rest, v1 = 0 exactly. A moving deck whose momentum
  and force cannot carry it through the step sticks at its reversal; a stuck deck stays
  stuck until |F_A - Ke*u| exceeds Fs.
* |p| > Fs: v1 = sign(p)*w with w > 0 solving M*w/dt + Ce*w^alpha + Ff(w) = |p|.

The velocity can therefore only change sign through a step of exact rest or a step whose
net force exceeds static friction in the new direction: no sign flipping from one step to
the next (chatter), and no explicit friction step can overshoot zero. The recorded
acceleration (v1 - v0)/dt satisfies the force balance with v1 exactly.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

import bayes_sst._jaxconfig  # noqa: F401  (float64 before any array)

NEWTON_ITERATIONS = 5


class DeckParams(NamedTuple):
    """mass M (kg), Ke (N/m), Ce (N/(m/s)^alpha), alpha, Fk kinetic and Fs static friction (N),
    stribeck_velocity v_s (m/s).

    Effects beyond the base model (zero: off): cubic k3 (N/m^3), the spring being
    Ke*u + k3*u^3; hinge kh (N/m^2), friction levels raised by kh*u^2; a flexible specimen of
    mass specimen_mass (kg), stiffness specimen_k (N/m) and damping specimen_c (N*s/m).
    """

    mass: float
    Ke: float
    Ce: float
    alpha: float
    Fk: float
    Fs: float
    stribeck_velocity: float
    cubic: float = 0.0
    hinge: float = 0.0
    specimen_mass: float = 0.0
    specimen_k: float = 0.0
    specimen_c: float = 0.0


def friction_level(deck: DeckParams, speed):
    """Ff(s) = Fk + (Fs - Fk)*exp(-(s/v_s)^2) and its derivative dFf/ds."""
    x = speed / deck.stribeck_velocity
    bump = (deck.Fs - deck.Fk) * jnp.exp(-x * x)
    return deck.Fk + bump, -2.0 * x / deck.stribeck_velocity * bump


def sliding_speed(deck: DeckParams, drive, dt):
    """w > 0 with M*w/dt + Ce*w^alpha + Ff(w) = drive, for drive > Fs.

    Newton's method in z = w^alpha, where the left side is convex in z for alpha <= 1 (so the
    iteration started to the right of the root descends onto it without overshoot) and has no
    infinite slope at rest. The start w0 = (drive - Fk)*dt/M lies right of the root because
    Ce*w0^alpha + Ff(w0) >= Fk.
    """
    c = deck.mass / dt
    tiny = 1e-300
    w = jnp.maximum((drive - deck.Fk) / c, tiny)
    z = w**deck.alpha
    inv_alpha = 1.0 / deck.alpha
    for _ in range(NEWTON_ITERATIONS):
        w = z**inv_alpha
        ff, dff = friction_level(deck, w)
        g = c * w + deck.Ce * z + ff - drive
        slope = (c + dff) * inv_alpha * w / z + deck.Ce
        z = jnp.maximum(z - g / slope, tiny)
    return z**inv_alpha


def deck_step(deck: DeckParams, u, v, actuator_force, dt):
    """Advance (u, v) by dt under the actuator force; returns u1, v1 and a = (v1 - v)/dt.

    The spring is Ke*u + k3*u^3 and the hinge friction kh*u^2 raises both friction levels,
    all taken at the step's start (u is known there, so the implicit solve is unchanged).
    """
    hinge = deck.hinge * u * u
    deck = deck._replace(Fk=deck.Fk + hinge, Fs=deck.Fs + hinge)
    drive = deck.mass * v / dt + actuator_force - deck.Ke * u - deck.cubic * u * u * u
    magnitude = jnp.abs(drive)
    sticks = magnitude <= deck.Fs
    # Stuck lanes get a harmless drive so the solver sees no 0/0; their result is discarded.
    w = sliding_speed(deck, jnp.where(sticks, deck.Fs + deck.mass / dt, magnitude), dt)
    v1 = jnp.where(sticks, 0.0, jnp.sign(drive) * w)
    return u + dt * v1, v1, (v1 - v) / dt


def specimen_step(deck: DeckParams, x, xd, a_deck, dt):
    """Advance a specimen's drift x relative to the deck (semi-implicit Euler):

        m_s*(a + x'') = -k_s*x - c_s*x'',   i.e.  x'' = -(k_s*x + c_s*x')/m_s - a,

    returns x1, xd1; a lane without a specimen (m_s = 0) stays at rest.
    """
    has = deck.specimen_mass > 0.0
    mass = jnp.where(has, deck.specimen_mass, 1.0)
    xdd = jnp.where(has, -(deck.specimen_k * x + deck.specimen_c * xd) / mass - a_deck, 0.0)
    xd1 = xd + dt * xdd
    return x + dt * xd1, xd1


def specimen_shear(deck: DeckParams, x, xd):
    """Force of the specimen on the deck, k_s*x + c_s*x' (= -m_s*(a + x''), the base shear reversed)."""
    return deck.specimen_k * x + deck.specimen_c * xd
