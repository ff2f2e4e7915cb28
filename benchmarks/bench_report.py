"""Report time and honesty of the predictive bands.

1. The report of a 20-test run (the shipped example, runs/sst-paper, fitted first when it is
   missing): wall and CPU time of `build_report` + `write_report`, with figures.
2. Band coverage on virtual-table series (bayes_sst.twin.random_series: randomised truth
   around sst-paper, 2-4 % test-to-test spread, coloured force noise, stiction): the share of
   measured points inside the 90 % and 50 % bands, overall and per test.
3. A series with an effect the model lacks (a cubic hardening of the strut, k3 u^3, added to
   the recorded force of a twin series): which warnings the report raises.

    python benchmarks/bench_report.py --series 3 --k3 5e7 [--out figures.json]
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from bayes_sst.inference import fit
from bayes_sst.inference._summary import format_summary, summarize
from bayes_sst.io import TestRecord, load_series, write_run, write_series
from bayes_sst.report import build_report, write_report
from bayes_sst.twin import random_series, simulate

ROOT = Path(__file__).resolve().parent.parent


def _fit_to(series, folder: Path, seed: int) -> Path:
    """Fit with the package defaults and write the run folder (the series is written first
    so that the run records where it lies)."""
    write_series(series, folder / "series")
    series = load_series(folder / "series")
    result = fit(series, seed=seed)
    summary = summarize(result.tree)
    summary["command"] = f"benchmarks/bench_report.py (seed {seed})"
    write_run(folder / "run", result.tree, summary, format_summary(summary))
    return folder / "run"


def example_report(work: Path) -> dict:
    run = ROOT / "runs" / "sst-paper"
    if not (run / "posterior.nc").is_file():
        print("runs/sst-paper missing: fitting data/sst-paper first", flush=True)
        run = _fit_to(load_series(ROOT / "data" / "sst-paper"), work / "example", seed=0)
    wall, cpu = time.perf_counter(), time.process_time()
    report = build_report(run)
    write_report(report, work / "example-report", overwrite=True)
    row = {
        "tests": report.data["header"]["n_tests"],
        "wall_s": time.perf_counter() - wall,
        "cpu_s": time.process_time() - cpu,
        "coverage_90": report.data["calibration"]["coverage_90"],
        "coverage_50": report.data["calibration"]["coverage_50"],
        "warnings": report.data["health"]["warnings"],
        "timings": report.data["timings"],
        "html_bytes": len(report.html.encode()),
    }
    print(f"example report: {row['tests']} tests, {row['wall_s']:.1f} s wall, {row['cpu_s']:.1f} s CPU, "
          f"{row['html_bytes'] / 1e6:.1f} MB page; in 90 % bands {100 * row['coverage_90']:.1f} %, "
          f"in 50 % bands {100 * row['coverage_50']:.1f} %; warnings: {row['warnings'] or 'none'}", flush=True)
    return row


def coverage_rows(work: Path, seeds) -> list[dict]:
    rows = []
    for seed in seeds:
        started = time.perf_counter()
        run = _fit_to(random_series(seed), work / f"random-{seed}", seed=seed)
        report = build_report(run, figures=False)
        per_test = [t["coverage_90"] for t in report.data["tests"]]
        row = {
            "seed": seed,
            "coverage_90": report.data["calibration"]["coverage_90"],
            "coverage_50": report.data["calibration"]["coverage_50"],
            "tests": len(per_test),
            "tests_in_85_95": int(sum(0.85 <= c <= 0.95 for c in per_test)),
            "tests_in_80_100": int(sum(c >= 0.80 for c in per_test)),
            "per_test_coverage_90": per_test,
            "n_points": int(sum(t["n_kept"] for t in report.data["tests"])),
            "tests_fitting_poorly": report.data["conclusion"]["tests_fitting_poorly"],
            "warnings": report.data["health"]["warnings"],
            "seconds": time.perf_counter() - started,
        }
        rows.append(row)
        print(f"random series {seed}: in 90 % bands {100 * row['coverage_90']:.1f} % "
              f"(tests within 85-95 %: {row['tests_in_85_95']}/{row['tests']}, at least 80 %: "
              f"{row['tests_in_80_100']}/{row['tests']}), in 50 % bands {100 * row['coverage_50']:.1f} %; "
              f"{len(row['tests_fitting_poorly'])} tests fit poorly; {len(row['warnings'])} warnings; "
              f"{row['seconds']:.0f} s", flush=True)
        for w in row["warnings"]:
            print(f"  - {w}", flush=True)
    return rows


def with_cubic_strut(series, k3: float):
    """The series with k3*u^3 (N, u in m) added to every recorded force: a hardening gas strut."""
    tests = []
    for record in series.tests:
        columns = dict(record.columns)
        columns["F"] = columns["F"] + k3 * columns["u"] ** 3
        tests.append(TestRecord(spec=record.spec, columns=columns))
    return replace(series, tests=tuple(tests), name=f"{series.name}-cubic-strut")


def misspecified(work: Path, k3: float) -> dict:
    series = with_cubic_strut(simulate("sst-paper", seed=5, spread=0.02), k3)
    run = _fit_to(series, work / f"cubic-{k3:g}", seed=5)
    report = build_report(run, figures=False)
    row = {
        "k3_N_per_m3": k3,
        "coverage_90": report.data["calibration"]["coverage_90"],
        "tests_fitting_poorly": report.data["conclusion"]["tests_fitting_poorly"],
        "warnings": report.data["health"]["warnings"],
    }
    print(f"cubic strut k3 = {k3:.3g} N/m^3: in 90 % bands {100 * row['coverage_90']:.1f} %, "
          f"{len(row['tests_fitting_poorly'])} tests fit poorly; warnings:", flush=True)
    for w in row["warnings"]:
        print(f"  - {w}")
    return row


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--series", type=int, default=3, help="virtual-table series for the coverage")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--k3", type=float, nargs="*", default=[2e7, 5e7],
                        help="cubic strut coefficients of the misspecified series (N/m^3)")
    parser.add_argument("--skip-example", action="store_true")
    parser.add_argument("--out", default=None, help="write the figures as JSON here")
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench-report-"))
    try:
        result = {}
        if not args.skip_example:
            result["example"] = example_report(work)
        rows = coverage_rows(work, range(args.first_seed, args.first_seed + args.series))
        if rows:
            weights = np.array([r["n_points"] for r in rows], dtype=float)
            overall = float(np.average([r["coverage_90"] for r in rows], weights=weights))
            share = sum(r["tests_in_85_95"] for r in rows) / sum(r["tests"] for r in rows)
            print(f"virtual tables ({len(rows)} series): in 90 % bands {100 * overall:.1f} % of all points; "
                  f"{100 * share:.0f} % of the tests within 85-95 %", flush=True)
            result["virtual_tables"] = {"rows": rows, "coverage_90": overall, "share_tests_in_85_95": share}
        result["misspecified"] = [misspecified(work, k3) for k3 in args.k3]
        if args.out:
            Path(args.out).write_text(json.dumps(result, indent=2) + "\n")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
