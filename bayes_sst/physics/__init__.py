"""Pure physics of the table: JAX force model and closed-form component relations.

Nothing here reads files, plots or samples.
"""

from bayes_sst.physics._components import (
    STANDARD_GRAVITY,
    coulomb_friction,
    friction_load_ratio,
    hold_down_force,
    normal_force,
    oil_column_frequency,
    strut_cubic_stiffness,
    strut_stiffness,
)

# The JAX force model is imported on first use, so that the closed-form relations above serve
# the signal preparation (and `bayes-sst --help`) without starting JAX.
_FORCE_NAMES = ("PARAMETER_NAMES", "ForceParams", "damping_regressor", "dissipative_force", "force")


def __getattr__(name):
    if name in _FORCE_NAMES:
        from bayes_sst.physics import _force

        return getattr(_force, name)
    raise AttributeError(f"module 'bayes_sst.physics' has no attribute {name!r}")


__all__ = [
    "PARAMETER_NAMES",
    "STANDARD_GRAVITY",
    "ForceParams",
    "coulomb_friction",
    "damping_regressor",
    "dissipative_force",
    "force",
    "friction_load_ratio",
    "hold_down_force",
    "normal_force",
    "oil_column_frequency",
    "strut_cubic_stiffness",
    "strut_stiffness",
]
