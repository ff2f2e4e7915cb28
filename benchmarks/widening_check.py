"""90 % coverage of the population values before and after the jackknife widening
(bayes_sst.inference._widening), from one fit per series.

    PYTHONPATH=. .venv/bin/python benchmarks/widening_check.py --folders /tmp/six2/c0* --out F.json
    PYTHONPATH=. .venv/bin/python benchmarks/widening_check.py --twin-seeds 0 60 --out F.json
    PYTHONPATH=. .venv/bin/python benchmarks/widening_check.py --summarize F.json [G.json ...]

--folders: series folders holding a truth.json with the population values (the independent
generators write one); --twin-seeds A B: bayes_sst.twin.random_series(seed) for seed in
[A, B), the series of benchmarks/calibration.py. Each fit runs with the package defaults; the
row keeps the model's own 5 %, 95 % quantiles, mean and sd (model_posterior) and the widened
ones (posterior), the jackknife's ratio per value and its time. An existing --out is resumed.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

NAMES = ("Me", "Ke", "Ce", "alpha", "Fmu")


def _row(label: str, tree, truth: dict, seconds: float, jackknife_s: float) -> dict:
    from bayes_sst.inference._widening import model_draws, widening_of

    row = {"case": label, "seconds": round(seconds, 1), "jackknife_s": round(jackknife_s, 2),
           "n_tests": int(tree["posterior"].sizes["test"])}
    widening = widening_of(tree)
    for name in NAMES:
        entry = {"truth": float(truth[name]), "ratio": widening[name]["ratio"], "factor": widening[name]["factor"]}
        for kind, draws in (("model", model_draws(tree, name)), ("widened", tree["posterior"][name])):
            x = np.asarray(draws.values).ravel()
            q05, q95 = np.quantile(x, [0.05, 0.95])
            entry[kind] = {"mean": float(x.mean()), "sd": float(x.std(ddof=1)), "q05": float(q05),
                           "q95": float(q95), "covered": bool(q05 <= truth[name] <= q95)}
        row[name] = entry
    return row


def summarize_rows(rows: list[dict]) -> dict:
    out = {"n": len(rows)}
    for kind in ("model", "widened"):
        out[kind] = {}
        for name in NAMES:
            z = np.array([(r[name][kind]["mean"] - r[name]["truth"]) / r[name][kind]["sd"] for r in rows])
            out[kind][name] = {"coverage": float(np.mean([r[name][kind]["covered"] for r in rows])),
                               "z_sd": float(z.std()), "z_mean": float(z.mean())}
    out["mean_factor"] = {name: float(np.mean([r[name]["factor"] for r in rows])) for name in NAMES}
    out["median_ratio"] = {name: float(np.median([r[name]["ratio"] for r in rows])) for name in NAMES}
    return out


def _print(label: str, summary: dict) -> None:
    print(f"{label}: {summary['n']} series")
    for kind in ("model", "widened"):
        cells = "  ".join(f"{n} {100 * summary[kind][n]['coverage']:5.1f}% (z sd {summary[kind][n]['z_sd']:.2f})"
                          for n in NAMES)
        print(f"  {kind:8s} {cells}")
    print("  mean factor  " + "  ".join(f"{n} {summary['mean_factor'][n]:.2f}" for n in NAMES))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--folders", nargs="+")
    group.add_argument("--twin-seeds", nargs=2, type=int, metavar=("FIRST", "STOP"))
    group.add_argument("--summarize", nargs="+", metavar="RESULT")
    parser.add_argument("--out")
    args = parser.parse_args()
    if args.summarize:
        for path in args.summarize:
            _print(path, json.loads(Path(path).read_text())["summary"])
        return
    from bayes_sst.inference import fit
    from bayes_sst.io import load_series
    from bayes_sst.twin import random_series

    rows = json.loads(Path(args.out).read_text())["rows"] if args.out and os.path.exists(args.out) else []
    done = {r["case"] for r in rows}
    if args.folders:
        cases = [(str(Path(f)), None) for f in args.folders]
    else:
        cases = [(f"twin{seed}", seed) for seed in range(*args.twin_seeds)]
    for label, seed in cases:
        if label in done:
            continue
        if seed is None:
            truth = json.loads(Path(label, "truth.json").read_text())
            truth = truth.get("population", truth)  # the first generator nests its population values
            series, fit_seed = load_series(label), int(truth.get("seed", seed or 0))
        else:
            series = random_series(seed)
            truth, fit_seed = dict(series.extra["truth"]), seed
        started = time.perf_counter()
        result = fit(series, seed=fit_seed)
        row = _row(label, result.tree, truth, time.perf_counter() - started, result.timings.get("jackknife", 0.0))
        rows.append(row)
        print(f"{Path(label).name}: " + "  ".join(
            f"{n} {'Y' if row[n]['model']['covered'] else 'N'}{'Y' if row[n]['widened']['covered'] else 'N'} "
            f"x{row[n]['factor']:.2f}" for n in NAMES) + f"  ({row['seconds']:.0f} s)", flush=True)
        if args.out:
            Path(args.out).write_text(json.dumps({"rows": rows, "summary": summarize_rows(rows)}, indent=1))
    _print("all", summarize_rows(rows))


if __name__ == "__main__":
    main()
