"""The candidate-effect library: what the base force model leaves out, one small object per effect.

    F = Me*a + Ke*u + (Ce*|v|^alpha + Fmu)*sign(v)  +  sum of the selected effects' terms

Force-term effects (stiction, nonlinear_stiffness, position_friction, specimen, drift,
strut_inertia, strut_damping) add regressor columns that are linear in their coefficients for
fixed grid parameters; channel_delay re-reads the force channel at a shifted time; oil_column is
a command-to-motion resonance seen in broadband tests. See docs/diagnosis.md.

    >>> from bayes_sst.effects import EFFECTS
    >>> [e.name for e in EFFECTS][:3]
    ['stiction', 'nonlinear_stiffness', 'position_friction']
"""

from bayes_sst.effects._data import EffectData
from bayes_sst.effects._library import (
    EFFECTS,
    AmplitudeFree,
    FORCE_EFFECTS,
    ChannelDelay,
    Drift,
    Effect,
    NonlinearStiffness,
    OilColumn,
    Parameter,
    PositionFriction,
    Specimen,
    Stiction,
    StrutDamping,
    StrutInertia,
    effect_by_name,
    sdof_base_shear,
    steady_amplitude,
)

__all__ = [
    "EFFECTS", "FORCE_EFFECTS", "AmplitudeFree", "ChannelDelay", "Drift", "Effect", "EffectData", "NonlinearStiffness",
    "OilColumn", "Parameter", "PositionFriction", "Specimen", "Stiction", "StrutDamping", "StrutInertia",
    "effect_by_name", "sdof_base_shear", "steady_amplitude",
]
