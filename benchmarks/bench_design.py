"""`bayes-sst design` checked against reality on the virtual table.

1. Reality check (--reps, default 5): a 4-test (and a 6-test; --start-tests 20: the example's
   20-test plan) virtual-table series (sst-paper truth, 2 % test-to-test spread, the twin's
   coloured noise) is fitted; design recommends tests for
   targets Ke 2 %, Fmu 5 %; exactly the first 5 and the first 10 recommended tests are run on
   the virtual table (same table, new spread draws and noise), the series is refitted, and
   the realised half-width of every target is compared with the predicted 80 % band
   (q10-q90 over outcomes).
2. Poor plan: a series whose 6 tests are all 1 Hz sines; the number of added tests that
   meets the targets, recommended against repeating the plan.
3. Timing of design on the 20-test example run (data/sst-paper) when --timing is given.

    python benchmarks/bench_design.py [--reps 5] [--out benchmarks/results/design.json]
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from bayes_sst.design import design
from bayes_sst.inference import fit
from bayes_sst.inference._widening import model_draws
from bayes_sst.io import Series, write_json_atomic
from bayes_sst.twin import PlanItem, default_plan, simulate

TARGETS = {"Ke": 0.02, "Fmu": 0.05}
START_PLAN = [PlanItem("sine", 0.5, 0.03), PlanItem("sine", 1.0, 0.04), PlanItem("sine", 2.0, 0.03),
              PlanItem("triangle", 0.5, 0.05), PlanItem("sine", 0.75, 0.05), PlanItem("sine", 1.5, 0.02)]
POOR_PLAN = [PlanItem("sine", 1.0, a) for a in (0.01, 0.02, 0.03, 0.04, 0.06, 0.08)]
SPREAD = 0.02


def half_widths(tree) -> dict[str, float]:
    post = tree["posterior"]
    out = {}
    for name in ("Me", "Ke", "Ce", "alpha", "Fmu"):
        x = np.asarray(post[name].values).ravel()
        q05, q95 = np.quantile(x, [0.05, 0.95])
        out[name] = float((q95 - q05) / 2 / abs(x.mean()))
    return out


def extended(series: Series, added: Series, tag: str) -> Series:
    """series plus the tests of `added`, renamed so that ids and files stay unique."""
    renamed = []
    for k, record in enumerate(added.tests, 1):
        new_id = f"{tag}{k:02d}"
        spec = replace(record.spec, id=new_id, file=f"{new_id}.csv", order=len(series.tests) + k)
        renamed.append(replace(record, spec=spec))
    return Series(name=f"{series.name}+{tag}", tests=series.tests + tuple(renamed), table=series.table,
                  extra=series.extra)


def start_plan(n_start: int) -> list[PlanItem]:
    """The first n_start tests of START_PLAN, or beyond its length of the example's plan
    (default_plan, 20 tests), a series as large as a lab's first campaign."""
    return START_PLAN[:n_start] if n_start <= len(START_PLAN) else list(default_plan("sst-paper"))[:n_start]


def reality_check(rep: int, n_start: int, n_outcomes: int, say) -> dict:
    seed = 500 + rep
    series = simulate("sst-paper", plan=start_plan(n_start), seed=seed, spread=SPREAD, name=f"design-check-{rep}")
    start = fit(series, seed=rep)
    result = design(start.tree, targets=TARGETS, max_tests=10, series=series, n_outcomes=n_outcomes, seed=rep)
    data = result.to_json()
    spread = (start.tree["posterior"]["between_test_sd"].sel(coefficient="Ke")
              / model_draws(start.tree, "Ke"))  # the model's own Ke, the same draws as the spread
    row = {"rep": rep, "seed": seed, "current": data["current"], "n_needed": data["n_needed"],
           "Ke_relative_spread_posterior": {"q10": float(spread.quantile(0.1)), "q50": float(spread.quantile(0.5)),
                                            "q90": float(spread.quantile(0.9)), "truth": SPREAD},
           "recommended": data["recommended"], "design_seconds": data["diagnostics"]["seconds"], "checks": {}}
    for n_added in (5, 10):
        plan = [PlanItem(c["kind"], c["frequency_hz"], c["amplitude_m"]) for c in data["recommended"][:n_added]]
        new = simulate("sst-paper", plan=plan, seed=10_000 + 97 * seed + n_added, spread=SPREAD)
        refit = fit(extended(series, new, "D"), seed=rep)
        realised = half_widths(refit.tree)
        band = data["curve"][n_added]
        check = {}
        for name in TARGETS:
            inside = band[name]["q10"] <= realised[name] <= band[name]["q90"]
            check[name] = {"realised": realised[name], **band[name], "inside": bool(inside)}
        row["checks"][str(n_added)] = check
        say(f"{n_start} tests, rep {rep}, {n_added} added: " + ", ".join(
            f"{k} {v['realised']:.2%} in [{v['q10']:.2%}, {v['q90']:.2%}] {'yes' if v['inside'] else 'NO'}"
            for k, v in check.items()))
    return row


def poor_plan(n_outcomes: int, say) -> dict:
    series = simulate("sst-paper", plan=POOR_PLAN, seed=77, spread=SPREAD, name="one-frequency")
    start = fit(series, seed=0)
    result = design(start.tree, targets=TARGETS, max_tests=40, series=series, n_outcomes=n_outcomes, seed=0)
    data = result.to_json()
    say(f"poor plan (6 sines at 1 Hz): recommended tests meet the targets after {data['n_needed']}, "
        f"repeating the plan after {data['repeat_plan']['n_needed']} (of at most 40); {data['reason'] or ''}")
    return {"plan": [p.describe() for p in POOR_PLAN], "current": data["current"], "n_needed": data["n_needed"],
            "n_needed_repeat": data["repeat_plan"]["n_needed"], "reason": data["reason"],
            "recommended_first_10": data["recommended"][:10],
            "curve_at": {str(n): {"recommended": data["curve"][n], "repeat": data["repeat_plan"]["curve"][n]}
                         for n in (0, 5, 10, 20, 40)},
            "design_seconds": data["diagnostics"]["seconds"]}


def timing_20(say) -> dict:
    from bayes_sst.io import load_series, read_run_tree

    run = Path("runs/sst-paper")
    if not (run / "posterior.nc").is_file():
        return {"skipped": "runs/sst-paper not found (./dev.sh example writes it)"}
    tree = read_run_tree(run)
    started = time.perf_counter()
    result = design(tree, targets=TARGETS, max_tests=40, series=load_series("data/sst-paper"))
    seconds = time.perf_counter() - started
    say(f"design on the 20-test run: {seconds:.1f} s, n_needed {result.n_needed}")
    return {"seconds": seconds, "n_needed": result.n_needed, "current": result.current}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=5)
    parser.add_argument("--start-tests", type=int, nargs="+", default=[4, 6],
                        help="sizes of the starting series (first tests of START_PLAN; above its 6, of the "
                             "example's 20-test plan)")
    parser.add_argument("--outcomes", type=int, default=64)
    parser.add_argument("--skip-poor", action="store_true")
    parser.add_argument("--timing", action="store_true")
    parser.add_argument("--out", default="benchmarks/results/design.json")
    args = parser.parse_args()
    started = time.perf_counter()

    def say(message):
        print(f"[{time.perf_counter() - started:7.1f} s] {message}", flush=True)

    out = {"targets": TARGETS, "spread": SPREAD}
    if args.timing:
        out["timing_20_tests"] = timing_20(say)
    for n_start in args.start_tests:
        rows = [reality_check(rep, n_start, args.outcomes, say) for rep in range(args.reps)]
        summary = {}
        for n_added in ("5", "10"):
            for name in TARGETS:
                hits = sum(r["checks"][n_added][name]["inside"] for r in rows)
                summary[f"{name}@{n_added}"] = f"{hits}/{len(rows)}"
        out[f"reality_check_{n_start}_tests"] = {"start_plan": [p.describe() for p in start_plan(n_start)],
                                                 "summary": summary, "rows": rows}
        say(f"start from {n_start} tests, inside the predicted 80 % band: "
            + ", ".join(f"{k} {v}" for k, v in summary.items()))
    if not args.skip_poor:
        out["poor_plan"] = poor_plan(args.outcomes, say)
    write_json_atomic(args.out, out)
    say(f"wrote {args.out}")


if __name__ == "__main__":
    main()
