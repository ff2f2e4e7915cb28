"""The closed loop's linear frequency response, and the twin's true resonance.

With the deck's damping and friction left out (Ce = Fmu = 0), the twin's equations
(_hydraulics.py, _deck.py) are linear:

    M*s^2*U = A_p*P - Ke*U                                 deck
    (tau_v*s + 1)*Q = A_p*(s + kp)*U_cmd - A_p*kp*U - kdp*P  controller and valve
    (s + leakage)*P = g*(Q - A_p*s*U),   g = 2*beta/V       oil column

so that, eliminating P = (M*s^2 + Ke)*U/A_p and Q,

    H(s) = U/U_cmd = A_p*(s + kp) / [(tau_v*s + 1)*((M*s^2 + Ke)*(s + leakage)/(A_p*g) + A_p*s)
                                     + A_p*kp + kdp*(M*s^2 + Ke)/A_p].

H is also the response a/a_cmd, since a = s^2*u. The pressure feedback kdp damps the oil
column and, with the valve lag, moves the peak of |H| away from the open-column f_oil:
for the sst-paper preset it sits at 28.61 Hz on the empty table (f_oil 28.60 Hz) but at
20.74 Hz with 10 t (f_oil 21.57 Hz) and 15.12 Hz with 25 t (f_oil 16.81 Hz), as the
heavier deck is more heavily damped by the same kdp.

The twin's "true resonance" of a test is the peak of this |H| for the test's own moving
mass and Ke. Ce*|v|^alpha (alpha < 1) has no linearisation at rest and friction none at all,
so both are left out; under broadband shaking they add some damping but move the peak by
far less than the 3 % a resonance estimate is held to.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize_scalar


def closed_loop_response(truth, moving_mass: float, frequency_hz, *, Ke: float | None = None) -> np.ndarray:
    """H(j*2*pi*f) = U/U_cmd (= a/a_cmd) of the linearised closed loop, complex, at frequencies f (Hz).

    truth: a TableTruth (servo loop and oil column); moving_mass (kg): the deck with its
    payload; Ke (N/m): the struts' stiffness, truth.Ke unless given.
    """
    s = 2j * math.pi * np.asarray(frequency_hz, dtype=float)
    area = truth.piston_area
    gain = 2.0 * truth.bulk_modulus / truth.oil_volume
    ke = truth.Ke if Ke is None else Ke
    spring_mass = moving_mass * s**2 + ke
    column = spring_mass * (s + truth.leakage) / (area * gain) + area * s
    denominator = (truth.valve_time_constant * s + 1.0) * column + area * truth.kp + truth.kdp * spring_mass / area
    return area * (s + truth.kp) / denominator


def closed_loop_resonance_hz(truth, moving_mass: float, *, Ke: float | None = None) -> float:
    """Frequency of the peak of |H| (Hz): a fine grid search refined by a bounded minimisation."""
    f_oil = truth.f_oil_hz(moving_mass)
    grid = np.linspace(0.2 * f_oil, 2.0 * f_oil, 2001)
    magnitude = np.abs(closed_loop_response(truth, moving_mass, grid, Ke=Ke))
    i = int(np.argmax(magnitude))
    if i in (0, len(grid) - 1):
        raise ValueError(f"|H| of the closed loop has no peak between {grid[0]:.3g} and {grid[-1]:.3g} Hz")
    result = minimize_scalar(
        lambda f: -abs(closed_loop_response(truth, moving_mass, f, Ke=Ke)),
        bounds=(grid[i - 1], grid[i + 1]),
        method="bounded",
        options={"xatol": 1e-7 * f_oil},
    )
    return float(result.x)
