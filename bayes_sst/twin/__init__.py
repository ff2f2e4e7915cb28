"""The digital twin: a simulated servo-hydraulic shaking table with known truth.

Realistic synthetic test series for tests, example data, experiment design and model
diagnosis. The table is simulated physically, not as "force model plus white noise":

* command (_command.py): sine or rounded-triangle displacement with raised-cosine ramps;
* servo loop and oil column (_hydraulics.py): velocity feed-forward, displacement and
  differential-pressure feedback, first-order valve, compressible oil (resonance f_oil);
* deck (_deck.py): Me*a = F_A - Ke*u - Ce*|v|^alpha*sign(v) - friction, with true sticking
  at reversals (static friction static_ratio*Fmu, optional Stribeck decay);
* integration (_integrate.py): fixed 4 kHz step in JAX, lax.scan in time, vmap over tests;
* sensors (_noise.py): white and quantised displacement, white acceleration, white plus
  AR(1) force noise;
* truth (_truth.py, _spread.py): presets, and an optional test-to-test lognormal spread.

    >>> from bayes_sst.twin import simulate
    >>> series = simulate("sst-paper", seed=1, spread=0.02)      # doctest: +SKIP
    >>> series.extra["truth"]["Me"], series.tests[0].spec.extra["truth"]["Me"]  # doctest: +SKIP
"""

from bayes_sst.twin._command import Command, periodic_command
from bayes_sst.twin._noise import SensorNoise
from bayes_sst.twin._plan import PlanItem, broadband_plan, default_plan
from bayes_sst.twin._scenarios import random_series
from bayes_sst.twin._simulate import simulate, simulate_response
from bayes_sst.twin._spread import SPREAD_PARAMETERS
from bayes_sst.twin._truth import PRESETS, TableTruth

QUIET = SensorNoise.off()

__all__ = [
    "PRESETS",
    "QUIET",
    "SPREAD_PARAMETERS",
    "Command",
    "PlanItem",
    "SensorNoise",
    "TableTruth",
    "broadband_plan",
    "default_plan",
    "periodic_command",
    "random_series",
    "simulate",
    "simulate_response",
]
