"""Signals: filtering, derivatives, steady-state cycles and the likelihood's sample set."""

from bayes_sst.signals._checks import accelerometer_disagreement
from bayes_sst.signals._cycles import CycleWindow, fourier_columns, fundamental_phase, periodic_component, steady_cycles
from bayes_sst.signals._filters import acceleration_from_velocity, acceleration_of_recorded_velocity, derived_acceleration, lowpass_sos, second_derivative, time_derivative, zero_phase_lowpass
from bayes_sst.signals._prepare import (
    MIN_STEADY_CYCLES,
    PreparedTest,
    SignalOptions,
    complementary_velocity,
    friction_load,
    kept_indices,
    prepare_series,
    prepare_test,
    project_out,
    recorded_velocity_is_quieter,
    reversal_weight,
    without_steady_offsets,
)

__all__ = [
    "MIN_STEADY_CYCLES",
    "acceleration_from_velocity",
    "acceleration_of_recorded_velocity",
    "accelerometer_disagreement",
    "CycleWindow",
    "PreparedTest",
    "SignalOptions",
    "complementary_velocity",
    "derived_acceleration",
    "friction_load",
    "fourier_columns",
    "fundamental_phase",
    "kept_indices",
    "lowpass_sos",
    "periodic_component",
    "prepare_series",
    "prepare_test",
    "project_out",
    "recorded_velocity_is_quieter",
    "reversal_weight",
    "second_derivative",
    "steady_cycles",
    "time_derivative",
    "without_steady_offsets",
    "zero_phase_lowpass",
]
