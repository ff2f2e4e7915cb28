"""Which recorded channel's noise takes a specimen's slow sines their mass: one series made twice.

The fifth simulator's seed 226 (a 3.71 t specimen at 11.49 Hz, 4.1 % damping, 21 tests at
256 Hz) is generated as drawn and again with the accelerometer's noise set to zero. The
generator draws every noise from one stream whether its level is zero or not, so the two series
differ in the accelerometer channel's noise alone. Per test, the force less the specimen's
shear at its true setting and mass is fitted by least squares on the base columns (a, u, the
damping column, the Coulomb column), with the acceleration column and the specimen's column
taken from either series; and the diagnosis engine scores the specimen at its true setting
and at a rival (1.8 t at 18.7 Hz) on each series, printing the per-test Me it reads.

    PYTHONPATH=. .venv/bin/python benchmarks/specimen_noise_attribution.py --dir /tmp/specimen226

Measured 2026-11-29 (docs/diagnosis.md, Known gaps): least squares puts the own Me of six slow
sines (0.23-0.73 Hz) at -1.8 to 3.9 t with the noisy acceleration column and at 15.4-20.6 t with
the quiet one, whichever series the specimen's column comes from (truth 16.2 t for deck and
specimen together; two sines at 0.28-0.29 Hz tell no mass either way); the faster tests read
15-16.4 t from both.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fifth_generator import make_series  # noqa: E402  (numpy only, as fifth_diagnosis.py runs it)

SEED = 226
RIVAL = {"specimen_frequency": 18.7, "specimen_damping": 0.05}


def _make(folder: Path, overrides: dict | None) -> dict:
    """The series in `folder` (generated where missing) and its truth."""
    if not (folder / "truth.json").exists():
        make_series(SEED, str(folder), effect="specimen", truth_path=str(folder / "truth.json"), overrides=overrides)
    return json.loads((folder / "truth.json").read_text())


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--dir", default="/tmp/bayes_sst_specimen_noise")
    args = parser.parse_args()
    root = Path(args.dir)
    truth = _make(root / "as_drawn", None)
    _make(root / "quiet_accelerometer", {"a_noise": 0.0})

    import numpy as np

    from bayes_sst.diagnosis._data import DIAGNOSIS_SIGNALS, effect_data
    from bayes_sst.diagnosis._diagnose import _scale
    from bayes_sst.diagnosis._engine import Scorer
    from bayes_sst.diagnosis._screen import fit_base
    from bayes_sst.effects import effect_by_name
    from bayes_sst.io import load_series

    effect = truth["effect"]
    f_s, zeta, m_s = effect["specimen_frequency"], effect["specimen_damping"], effect["specimen_mass"]
    print(f"seed {SEED}: deck {truth['Me'] / 1e3:.2f} t, specimen {m_s / 1e3:.2f} t at {f_s:.2f} Hz, "
          f"{100 * zeta:.1f} %; accelerometer noise {truth['noise']['a']:.3f} m/s^2")
    series = {name: load_series(root / name) for name in ("as_drawn", "quiet_accelerometer")}
    tests = {name: effect_data(s, DIAGNOSIS_SIGNALS) for name, s in series.items()}

    specimen = effect_by_name("specimen")
    exact = {"specimen_frequency": f_s, "specimen_damping": zeta}

    def dynamic_column(t):
        """The specimen's shear column per unit mass less its rigid part, the acceleration
        treated the same way."""
        return specimen.columns(t, exact, 0.5)[0] - t.filtered(t.a_record[t.lo:])

    print("\nper-test least-squares Me (t), force less the specimen's dynamic shear at the truth:")
    print(f"{'test':5} {'Hz':>5}  {'a noisy, x noisy':>16} {'a noisy, x quiet':>16} "
          f"{'a quiet, x noisy':>16} {'a quiet, x quiet':>16}")
    for noisy, quiet in zip(tests["as_drawn"], tests["quiet_accelerometer"]):
        row = []
        for a_from in (noisy, quiet):
            for x_from in (noisy, quiet):
                # the force is the same in both series; a and the specimen's column come from one each
                y = noisy.F - noisy.payload_kg * a_from.model_a - m_s * dynamic_column(x_from)
                X = np.vstack([a_from.model_a, noisy.model_u, noisy.damping(0.5), noisy.sign()]).T
                coef, *_ = np.linalg.lstsq(X, y, rcond=None)
                row.append(coef[0] / 1e3)
        print(f"{noisy.id:5} {noisy.frequency_hz:5.2f}  " + " ".join(f"{v:16.1f}" for v in row))

    true_setting = {"specimen_frequency": round(f_s, 2), "specimen_damping": round(zeta, 3)}
    for name, ts in tests.items():
        scorer = Scorer(ts, _scale(series[name], ts))
        base = fit_base(scorer)
        grid = np.linspace(base.alpha - 0.1, base.alpha + 0.1, 9)
        print(f"\n{name}: base model Me {base.coefficient('Me') / 1e3:.2f} t")
        for label, setting in (("truth", true_setting), ("rival", RIVAL)):
            fit = scorer.profile_alpha([(specimen, setting)], grid)
            me = fit.theta[:, 0] / 1e3
            print(f"  {label} {setting['specimen_frequency']:5.2f} Hz: log marginal "
                  f"{fit.log_marginal - base.log_marginal:+8.1f} nats over the base, Me "
                  f"{fit.coefficient('Me') / 1e3:.2f} t (per test {me.min():.1f}-{me.max():.1f}), "
                  f"m_s {fit.coefficient('specimen.specimen_mass') / 1e3:.2f} t")


if __name__ == "__main__":
    os.environ.setdefault("JAX_PLATFORMS", "cpu")
    main()
