"""Servo loop and actuator: controller, servo-valve and the compressible oil column.

    Q_cmd  = A_p*(v_cmd + kp*(u_cmd - u)) - kdp*P_L       controller (flow demand)
    dQ/dt  = (Q_cmd - Q)/tau_v                            servo-valve, first-order lag
    dP_L/dt = (2*beta/V)*(Q - A_p*v) - leakage*P_L        oil column, two chambers of volume V
    F_A    = A_p*P_L                                      actuator force on the deck

The oil column is a spring k_oil = 2*beta*A_p^2/V against the moving mass, the resonance of
physics.oil_column_frequency(..., chambers=2). Velocity feed-forward makes the loop track
without waiting for a position error; the differential-pressure feedback (kdp) bleeds flow
in proportion to load pressure, which damps the oil column the way table controllers do,
at the price of a small tracking error under load.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

import bayes_sst._jaxconfig  # noqa: F401  (float64 before any array)


class ServoParams(NamedTuple):
    """piston_area A_p (m^2), oil_gain 2*beta/V (Pa/m^3), leakage (1/s),
    valve_time_constant tau_v (s), kp (1/s), kdp (m^3/(s*Pa))."""

    piston_area: float
    oil_gain: float
    leakage: float
    valve_time_constant: float
    kp: float
    kdp: float


def servo_params(truth) -> ServoParams:
    """ServoParams of a TableTruth."""
    return ServoParams(
        piston_area=truth.piston_area,
        oil_gain=2.0 * truth.bulk_modulus / truth.oil_volume,
        leakage=truth.leakage,
        valve_time_constant=truth.valve_time_constant,
        kp=truth.kp,
        kdp=truth.kdp,
    )


def flow_demand(servo: ServoParams, u_cmd, v_cmd, u, p_load):
    """Q_cmd = A_p*(v_cmd + kp*(u_cmd - u)) - kdp*P_L, m^3/s."""
    return servo.piston_area * (v_cmd + servo.kp * (u_cmd - u)) - servo.kdp * p_load


def valve_step(servo: ServoParams, q, q_demand, dt):
    """Valve flow after dt with the demand held: exact solution of the first-order lag."""
    return q_demand + (q - q_demand) * jnp.exp(-dt / servo.valve_time_constant)


def pressure_step(servo: ServoParams, p_load, q, v, dt):
    """P_L + dt*((2*beta/V)*(Q - A_p*v) - leakage*P_L), with v the deck's end-of-step velocity."""
    return p_load + dt * (servo.oil_gain * (q - servo.piston_area * v) - servo.leakage * p_load)


def actuator_force(servo: ServoParams, p_load):
    """F_A = A_p*P_L, N."""
    return servo.piston_area * p_load
