"""Component relations of the reference study, turning a table's make-up into model parameters.

All inputs and outputs are SI. Each function is a closed form so it can serve as a prior
centre, a check on an identified value, or a hand calculation in a test.
"""

from __future__ import annotations

import math

STANDARD_GRAVITY = 9.80665


def hold_down_force(p0: float, area: float) -> float:
    """F_hd = 4*p0*A: the four nitrogen struts' pre-charge pushing the deck onto its bearings, N."""
    return 4.0 * p0 * area


def strut_stiffness(p0: float, area: float, h: float) -> float:
    """Ke = 4*p0*A/h: horizontal stiffness of four pre-charged struts of height h, N/m."""
    return 4.0 * p0 * area / h


def strut_cubic_stiffness(ke: float, gamma: float, h: float, l0: float) -> float:
    """K'e = 0.5*(gamma*h/l0 - 1)*Ke: coefficient of the cubic term K'e*(u/h)^2*u, N/m.

    gamma is the gas's polytropic exponent, l0 the gas column length at rest.
    """
    return 0.5 * (gamma * h / l0 - 1.0) * ke


def normal_force(hold_down: float, moving_mass: float, g: float = STANDARD_GRAVITY) -> float:
    """N = F_hd + m*g: the vertical load the sliding bearings carry, N."""
    return hold_down + moving_mass * g


def friction_load_ratio(hold_down: float, deck_mass: float, payload: float, g: float = STANDARD_GRAVITY) -> float:
    """N_test/N_empty = (F_hd + (m_deck + m_payload)*g)/(F_hd + m_deck*g).

    Fmu = mu_e*N: a payload's weight loads the bearings too, so a test with a specimen on the
    deck has this much more Coulomb friction than the empty table (mu_e unchanged).
    """
    return normal_force(hold_down, deck_mass + payload, g) / normal_force(hold_down, deck_mass, g)


def coulomb_friction(mu: float, normal: float) -> float:
    """Fmu = mu_e*N, N."""
    return mu * normal


def oil_column_frequency(
    bulk_modulus: float,
    piston_area: float,
    oil_volume: float,
    moving_mass: float,
    chambers: int = 2,
) -> float:
    """Oil-column resonance f_oil = (1/2pi)*sqrt(chambers*beta*A^2/(V*M)), Hz.

    chambers=2 is the study's form (2*beta): a double-acting actuator whose two chambers,
    each of volume V, both stiffen the piston (k_oil = 2*beta*A^2/V). chambers=4 is the form
    for a symmetric actuator whose total oil volume V is split between the two chambers
    (each V/2, so k_oil = 4*beta*A^2/V).
    """
    stiffness = chambers * bulk_modulus * piston_area**2 / oil_volume
    return math.sqrt(stiffness / moving_mass) / (2.0 * math.pi)
