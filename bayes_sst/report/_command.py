"""`bayes-sst report RUN [--out reports/NAME]`: the posterior-predictive check report of a run.

Only argparse at import time: the command line registers this sub-command without loading
the numerical stack, which `run` imports when the command actually runs.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from bayes_sst._argtypes import non_negative_int


def add_parser(subparsers):
    """Register the `report` sub-command on an argparse subparsers object; returns its parser."""
    p = subparsers.add_parser(
        "report",
        help="posterior-predictive check report of a run (HTML, PNG figures, report.json)",
        description="Write the report a reviewer reads before trusting a fitted model: sampler health "
        "(R-hat, ESS, divergences, E-BFMI, tree depth, PSIS-LOO Pareto k) with plain warnings at the top, "
        "the parameters, per-test hysteresis loops and force with 50 % and 90 % predictive bands, "
        "residuals, band coverage, LOO-PIT and posterior-predictive p-values. Writes OUT/report.html "
        "(self-contained), OUT/report.json (the numbers, SI) and OUT/figures/*.png.",
    )
    p.add_argument("run", help="run folder written by 'bayes-sst fit'")
    p.add_argument("--out", default=None, help="report folder to create (default reports/<run folder name>)")
    p.add_argument("--force", action="store_true", help="replace an existing report folder")
    p.add_argument("--draws", type=int, default=400,
                   help="posterior draws used for the bands and checks, thinned evenly (default 400)")
    p.add_argument("--seed", type=non_negative_int, default=0, help="seed of the predictive residual draws")
    p.add_argument("--series", default=None,
                   help="the run's series folder, when it has moved since the fit (default: the recorded one)")
    from bayes_sst.cli import add_exclude_argument
    add_exclude_argument(p)
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    """Handler of `report`: refuse a taken --out early, build, write atomically, print warnings."""
    from bayes_sst.io import check_run_target

    run_dir = Path(args.run)
    out = Path(args.out) if args.out else Path("reports") / run_dir.resolve().name
    force = bool(getattr(args, "force", False))
    check_run_target(out, overwrite=force)
    if getattr(args, "draws", 400) < 10:
        raise ValueError(f"--draws must be at least 10, got {args.draws}")
    from bayes_sst.report._build import build_report, write_report

    started = time.perf_counter()
    series = None
    if getattr(args, "series", None) or args.exclude_test:
        from bayes_sst.inference._predictive import run_series
        from bayes_sst.io import read_run_tree

        series = run_series(read_run_tree(run_dir), "report", path=args.series, exclude=args.exclude_test)
    report = build_report(run_dir, draws=args.draws, seed=args.seed, series=series)
    write_report(report, out, overwrite=force)
    data = report.data
    calibration = data["calibration"]
    print(f"report of {data['header']['series']!r} ({data['header']['n_tests']} tests) written to {out} "
          f"in {time.perf_counter() - started:.1f} s: {100 * calibration['coverage_90']:.1f} % of the measured "
          f"points in the 90 % bands, {100 * calibration['coverage_50']:.1f} % in the 50 % bands")
    for warning in data["health"]["warnings"]:
        print(f"WARNING: {warning}", file=sys.stderr)
    print(f"open {out / 'report.html'}")
    return 0
