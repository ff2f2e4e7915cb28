"""Fit series of an independent generator with the package defaults and compare with their
population truth: relative error, 90 % interval coverage and z = (mean - truth)/sd per parameter.

    PYTHONPATH=. .venv/bin/python benchmarks/independent_coverage.py --series 24 --dir /tmp/independent \
        --out benchmarks/results/independent_coverage.json
    PYTHONPATH=. .venv/bin/python benchmarks/independent_coverage.py --generator lugre --series 30 \
        --first-seed 100 --dir /tmp/lugre_clean --out benchmarks/results/lugre_coverage.json

--generator first (default): benchmarks/independent_generator.py, Coulomb friction with an
instant breakaway; lugre: benchmarks/lugre_generator.py, clean series (LuGre friction with
pre-sliding, a small Stribeck peak and real sticking, an orifice-law servo loop); valve:
benchmarks/valve_generator.py, clean series (servo-valve and oil-column hydraulics under a
three-variable controller, Coulomb friction with a Stribeck peak of up to 5 % and exact
sticking, an anti-alias filter, hum and a 16-bit converter); fifth: benchmarks/fifth_generator.py,
clean series (servo-valve, oil column and three-variable loop integrated at 0.1-0.2 ms, Coulomb
friction with a Stribeck peak of up to 3 % and exact sticking, AR(1) force noise, hum,
quantised u, 256-1024 Hz, no recorder filter). Series
missing from --dir are generated first (20-40 s each). --without-acceleration removes the
`a` and `v` columns first (a lab without an accelerometer). The LuGre generator scales a
payload test's friction by (1 + m_payload g/(Me g)), without the struts' hold-down force that
the package counts in the normal load; each row says how many payload tests its series has.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from _options import PARAMETERS as NAMES

HERE = Path(__file__).resolve().parent


def gain_truth(series, truth):
    """The payload's friction gain the generator's friction rule implies in the package's terms,
    where truth.json names the rule's normal load (the LuGre generator: Fmu_test =
    Fmu*(1 + m_p g/N0), so kappa = N_described/N0 with N_described = F_hd + m_deck g from the
    series' description); None otherwise."""
    from bayes_sst.signals import friction_load

    normal_load = truth.get("friction_normal_load_n")
    if not normal_load:
        return None
    probe = 1000.0
    described = friction_load(series.table, probe) - 1.0
    return float(probe * 9.81 / normal_load / described) if described > 0 else None


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--series", type=int, default=12)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--dir", default="/tmp/bayes_sst_independent")
    parser.add_argument("--out", default=None)
    parser.add_argument("--generator", choices=("first", "lugre", "valve", "fifth"), default="first")
    parser.add_argument("--signal", action="append", default=[], metavar="NAME=VALUE",
                        help="override a SignalOptions field, e.g. reversal_band=0.1")
    parser.add_argument("--without-acceleration", action="store_true",
                        help="remove the a (and v) columns before fitting")
    parser.add_argument("--per-test-alpha", action="store_true",
                        help="let the damping exponent vary between tests (fit --per-test-alpha)")
    parser.add_argument("--fifth-override", action="append", default=[], metavar="NAME=VALUE",
                        help="fifth generator only: replace one of its draws after it is made, e.g. spread=0 "
                             "(no test-to-test variation), quiet=1 (ideal sensors), static_ratio=1; see "
                             "fifth_generator.make_series")
    args = parser.parse_args()
    from _options import coverage_summary, interval_check, name_values, without_motion_sensors

    overrides = name_values(args.signal)
    sys.path.insert(0, str(HERE))
    if args.generator == "lugre":
        from lugre_generator import generate

        def make_series(seed, folder):
            generate(seed, folder, name=os.path.basename(folder), verbose=False)
    elif args.generator == "valve":
        from valve_generator import generate as generate_valve

        def make_series(seed, folder):
            generate_valve(seed, folder)
    elif args.generator == "fifth":
        from fifth_generator import make_series as make_fifth

        physics = name_values(args.fifth_override, "--fifth-override", "spread=0")

        def make_series(seed, folder):
            make_fifth(seed, folder, truth_path=os.path.join(folder, "truth.json"), overrides=physics)
    else:
        from independent_generator import make_series

    from bayes_sst.inference import fit
    from bayes_sst.inference._priors import make_priors
    from bayes_sst.inference._summary import summarize
    from bayes_sst.io import load_series
    from bayes_sst.signals import SignalOptions

    rows = []
    for seed in range(args.first_seed, args.first_seed + args.series):
        folder = os.path.join(args.dir, f"s{seed:02d}")
        if not os.path.exists(os.path.join(folder, "truth.json")):
            make_series(seed, folder)
        truth = json.load(open(os.path.join(folder, "truth.json")))
        truth = truth["population"] if args.generator == "first" else truth
        started = time.perf_counter()
        series = load_series(folder)
        if args.without_acceleration:
            series = without_motion_sensors(series)
        prior = make_priors("generic", series.table, per_test_alpha=args.per_test_alpha)
        result = fit(series, seed=seed, signals=SignalOptions(**overrides), prior=prior)
        summary = summarize(result.tree)
        row = {"seed": seed, "seconds": time.perf_counter() - started, "converged": summary["converged"],
               "divergences": summary["divergences"], "max_r_hat": summary["max_r_hat"],
               "mass_refit": bool(result.tree.attrs.get("mass_refit")),
               "payload_tests": sum(bool(t.spec.payload_kg) for t in series.tests)}
        row.update(interval_check(summary["parameters"], truth))
        if "payload_friction_gain" in summary:
            g = summary["payload_friction_gain"]
            # the valve and fifth generators scale friction by the package's own normal load: kappa = 1
            gain = 1.0 if args.generator in ("valve", "fifth") else gain_truth(series, truth)
            row["payload_friction_gain"] = {"mean": g["mean"], "sd": g["sd"], "q05": g["q05"], "q95": g["q95"],
                                            "truth": gain}
        if "alpha_between_test_sd" in summary:
            tau = summary["alpha_between_test_sd"]
            row["alpha_between_test_sd"] = {"mean": tau["mean"], "q05": tau["q05"], "q95": tau["q95"]}
        rows.append(row)
        cells = "  ".join(
            (f"{row[n]['mean'] - row[n]['truth']:+.3f}" if n == "alpha" else f"{100 * (row[n]['mean'] / row[n]['truth'] - 1):+5.1f}%")
            + (" Y" if row[n]["covered"] else " N") for n in NAMES)
        gain = row.get("payload_friction_gain")
        print(f"seed {seed:3d}  {cells}  R-hat {row['max_r_hat']:.3f}{'  mass refit' if row['mass_refit'] else ''}"
              + (f"  kappa {gain['mean']:.2f} [{gain['q05']:.2f}, {gain['q95']:.2f}]"
                 + (f" truth {gain['truth']:.2f}" if gain["truth"] is not None else "") if gain else ""),
              flush=True)
    summary = coverage_summary(rows)
    if args.out:
        Path(args.out).write_text(json.dumps({"generator": args.generator, "signals": overrides, "without_acceleration": args.without_acceleration,
                                              "per_test_alpha": args.per_test_alpha,
                                              "fifth_overrides": args.fifth_override, "summary": summary, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
