"""Fit and diagnose series of the independent generator (benchmarks/independent_generator.py)
in parameter regimes away from its default draw: linear (alpha 1) and nearly Coulomb-like
(alpha 0.25) damping, light and heavy friction, heavy damping, a heavy deck on stiff struts,
soft struts, 8 % test-to-test spread, 8 tests; each clean, and some with a withheld effect.

    PYTHONPATH=. .venv/bin/python benchmarks/independent_regimes.py --seeds 5 6 --dir /tmp/regimes \
        --out benchmarks/results/independent_regimes.json

Per clean series: the fit's error and 90 % interval per parameter (Y: covers the truth) and the
diagnosis's verdict (should be none); per effect series: the diagnosis's verdict (should be the
withheld effect). Series missing from --dir are generated first (about 20 s each).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
NAMES = ("Me", "Ke", "Ce", "alpha", "Fmu")

REGIMES = {
    "alpha1": dict(population=dict(alpha=1.0)),
    "alpha025": dict(population=dict(alpha=0.25)),
    "lowfric": dict(population=dict(Fmu=4000.0)),
    "highfric": dict(population=dict(Fmu=30000.0)),
    "heavystiff": dict(population=dict(Me=25000.0, Ke=2.0e6)),
    "heavydamp": dict(population=dict(Ce=80000.0)),
    "spread8": dict(spread=0.08),
    "tests8": dict(n_tests=8),
    "softstrut": dict(population=dict(Ke=2.0e5)),
}
# regime, withheld effects (the generator's keys), the effect the diagnosis should name
EFFECT_CASES = {
    "alpha1-delay2ms": ("alpha1", dict(force_delay=0.002), "channel_delay"),
    "alpha1-delay0.7ms": ("alpha1", dict(force_delay=0.0007), "channel_delay"),
    "alpha025-spec2t14": ("alpha025", dict(specimen_mass=2000.0, specimen_frequency=14.0), "specimen"),
    "heavystiff-hinge2e5": ("heavystiff", dict(hinge_friction=2e5), "position_friction"),
    "softstrut-cubic1e6": ("softstrut", dict(cubic_stiffness=1e6), "nonlinear_stiffness"),
    "highfric-drift20": ("highfric", dict(drift=0.2), "drift"),
    "lowfric-spec3t9": ("lowfric", dict(specimen_mass=3000.0, specimen_frequency=9.0), "specimen"),
    "spread8-delay2ms": ("spread8", dict(force_delay=0.002), "channel_delay"),
    "heavydamp-hinge2e5": ("heavydamp", dict(hinge_friction=2e5), "position_friction"),
}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[5, 6])
    parser.add_argument("--dir", default="/tmp/bayes_sst_regimes")
    parser.add_argument("--out", default=None)
    parser.add_argument("--effects-seed", type=int, default=None,
                        help="seed of the effect series (default: the first of --seeds)")
    args = parser.parse_args()
    sys.path.insert(0, str(HERE))
    from independent_generator import make_series

    from bayes_sst.diagnosis import diagnose
    from bayes_sst.inference import fit
    from bayes_sst.inference._summary import summarize
    from bayes_sst.io import load_series

    def series_at(name, seed, **kwargs):
        folder = os.path.join(args.dir, f"{name}-s{seed}")
        made_with = os.path.join(folder, "regime.json")
        wanted = json.dumps(kwargs, sort_keys=True)
        # a folder made with other settings (or before this marker existed) is made afresh
        if not (os.path.exists(made_with) and Path(made_with).read_text() == wanted):
            make_series(seed, folder, **kwargs)
            Path(made_with).write_text(wanted)
        return folder

    rows = []
    for seed in args.seeds:
        for name, kwargs in REGIMES.items():
            folder = series_at(name, seed, **kwargs)
            truth = json.load(open(os.path.join(folder, "truth.json")))["population"]
            series = load_series(folder)
            started = time.perf_counter()
            summary = summarize(fit(series, seed=seed).tree)
            fitted = time.perf_counter()
            d = diagnose(series)
            row = {"case": name, "seed": seed, "fit_seconds": fitted - started,
                   "diagnosis_seconds": time.perf_counter() - fitted, "converged": summary["converged"],
                   "selected": d.selected, "top": d.ranking[0]["name"], "top_score": d.ranking[0]["score"]}
            for p in NAMES:
                s = summary["parameters"][p]
                row[p] = {"truth": truth[p], "mean": s["mean"], "sd": s["sd"],
                          "covered": bool(s["q05"] <= truth[p] <= s["q95"])}
            rows.append(row)
            cells = "  ".join(
                (f"{p} {row[p]['mean'] - row[p]['truth']:+.3f}" if p == "alpha"
                 else f"{p} {100 * (row[p]['mean'] / row[p]['truth'] - 1):+5.1f}%")
                + (" Y" if row[p]["covered"] else " N") for p in NAMES)
            print(f"{name:11s} s{seed}  {cells}  converged={row['converged']}  diagnosis: {d.selected or 'none'}",
                  flush=True)
    seed = args.effects_seed if args.effects_seed is not None else args.seeds[0]
    for name, (regime, effects, expected) in EFFECT_CASES.items():
        folder = series_at(name, seed, effects=effects, **REGIMES[regime])
        started = time.perf_counter()
        d = diagnose(load_series(folder))
        top = d.ranking[0]
        row = {"case": name, "seed": seed, "expected": expected, "selected": d.selected, "top": top["name"],
               "top_score": top["score"], "top_score_se": top["score_se"], "shrink": d.shrink,
               "params": {k: v["mean"] for k, v in top["params"].items()},
               "ok": d.selected == [expected], "diagnosis_seconds": time.perf_counter() - started}
        rows.append(row)
        print(f"{name:20s} s{seed}  selected={d.selected}  top {top['name']} {top['score']:.1f} +- "
              f"{top['score_se']:.1f}  {row['params']}  shrink {d.shrink:.2f}  {'OK' if row['ok'] else 'MISS'}",
              flush=True)
    clean = [r for r in rows if "expected" not in r]
    for p in NAMES:
        print(f"{p:6s} covered in {sum(r[p]['covered'] for r in clean)} of {len(clean)} regime series")
    print(f"clean regime series with an effect claimed: {sum(bool(r['selected']) for r in clean)} of {len(clean)}; "
          f"effect series as expected: {sum(r['ok'] for r in rows if 'expected' in r)} of "
          f"{sum('expected' in r for r in rows)}")
    if args.out:
        Path(args.out).write_text(json.dumps({"command": " ".join(sys.argv), "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
