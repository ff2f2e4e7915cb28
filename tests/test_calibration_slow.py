"""Coverage of the 90 % intervals over 50 randomised virtual tables (slow: about 15 minutes).

Run with ./dev.sh test -m slow. For p = 0.9 and 50 series the binomial 95 % range of the
observed coverage is about [0.80, 0.98]; a calibrated model lands inside it 95 % of the time.
"""

import numpy as np
import pytest

from bayes_sst.inference import fit
from bayes_sst.inference._summary import summarize
from bayes_sst.twin import random_series

NAMES = ("Me", "Ke", "Ce", "alpha", "Fmu")


@pytest.mark.slow
def test_ninety_percent_intervals_cover_the_truth_about_ninety_percent_of_the_time():
    covered = {name: [] for name in NAMES}
    for seed in range(50):
        series = random_series(seed)
        truth = series.extra["truth"]
        summary = summarize(fit(series, seed=seed).tree)
        for name in NAMES:
            p = summary["parameters"][name]
            covered[name].append(p["q05"] <= truth[name] <= p["q95"])
    coverage = {name: float(np.mean(flags)) for name, flags in covered.items()}
    print("coverage of 90 % intervals over 50 series:", coverage)
    for name, value in coverage.items():
        assert 0.80 <= value <= 0.98, (name, value)
