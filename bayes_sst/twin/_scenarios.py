"""Randomised tables around a preset, for calibration studies and design checks."""

from __future__ import annotations

import numpy as np

from bayes_sst.twin._noise import SensorNoise
from bayes_sst.twin._simulate import simulate
from bayes_sst.twin._truth import PRESETS


def random_series(seed: int, preset: str = "sst-paper", *, plan=None):
    """A series whose truth is drawn around `preset`, as an independent lab's table might be.

    Me, Ke, Ce, Fmu each within +-25 % of the preset, alpha in [0.35, 0.9], a static-to-kinetic
    friction ratio in [1.0, 1.15] (so the table sticks and breaks away at reversals), a
    test-to-test spread of 2-4 %, and the twin's coloured force noise scaled by 0.5-2. The
    draw depends on `seed` only; the population truth is in series.extra["truth"].
    """
    rng = np.random.default_rng(np.random.SeedSequence([seed, 2718]))
    base = PRESETS[preset]
    overrides = {
        "Me": base.Me * rng.uniform(0.75, 1.25),
        "Ke": base.Ke * rng.uniform(0.75, 1.25),
        "Ce": base.Ce * rng.uniform(0.75, 1.25),
        "alpha": rng.uniform(0.35, 0.9),
        "Fmu": base.Fmu * rng.uniform(0.75, 1.25),
        "static_ratio": rng.uniform(1.0, 1.15),
    }
    default = SensorNoise()
    k = rng.uniform(0.5, 2.0)
    noise = SensorNoise(
        u_white=default.u_white,
        u_quantum=default.u_quantum,
        a_white=default.a_white,
        F_white=default.F_white * k,
        F_colored=default.F_colored * k,
        F_correlation_s=default.F_correlation_s,
    )
    spread = float(rng.uniform(0.02, 0.04))
    return simulate(preset, seed=seed, spread=spread, noise=noise, truth_overrides=overrides, plan=plan,
                    name=f"{preset}-random-{seed}")
