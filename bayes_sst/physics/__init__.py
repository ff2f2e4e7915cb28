"""Pure physics of the table: JAX force model and closed-form component relations.

Nothing here reads files, plots or samples.
"""

from bayes_sst.physics._components import (
    STANDARD_GRAVITY,
    coulomb_friction,
    hold_down_force,
    normal_force,
    oil_column_frequency,
    strut_cubic_stiffness,
    strut_stiffness,
)
from bayes_sst.physics._force import (
    PARAMETER_NAMES,
    ForceParams,
    damping_regressor,
    dissipative_force,
    force,
)

__all__ = [
    "PARAMETER_NAMES",
    "STANDARD_GRAVITY",
    "ForceParams",
    "coulomb_friction",
    "damping_regressor",
    "dissipative_force",
    "force",
    "hold_down_force",
    "normal_force",
    "oil_column_frequency",
    "strut_cubic_stiffness",
    "strut_stiffness",
]
