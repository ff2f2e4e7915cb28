"""`bayes-sst diagnose SERIES [--run RUN] --out DIR`: the sim-to-real gap of the base force model.

Only argparse at import time; the numerical stack is imported when the command runs.
"""

from __future__ import annotations


def add_parser(subparsers):
    """Register the `diagnose` sub-command; returns its parser."""
    p = subparsers.add_parser(
        "diagnose",
        help="where the base force model misses a series, which unmodelled effect is responsible",
        description="Locate the base model's residuals beyond the noise floor, score every candidate effect "
        "(stiction, nonlinear_stiffness, position_friction, specimen, channel_delay, drift, strut_inertia, "
        "strut_damping) by leave-one-test-out predictive density, and the oil column on broadband tests; select "
        "those that improve the fit beyond the noise, and report how far they shrink the residual. Prints a verdict; writes diagnosis.json "
        "(SI), diagnosis.txt and diagnosis.html into --out.",
    )
    p.add_argument("series", help="series folder (with series.json)")
    from bayes_sst.cli import add_exclude_argument
    add_exclude_argument(p)
    p.add_argument("--run", default=None, help="a run folder of 'bayes-sst fit' on this series (its alpha "
                   "starts the base model's profile)")
    p.add_argument("--out", required=True, help="output folder to create")
    p.add_argument("--force", action="store_true", help="replace an existing output folder")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    import sys
    import time

    from bayes_sst.diagnosis._diagnose import diagnose
    from bayes_sst.diagnosis._output import write_diagnosis
    from bayes_sst.io import check_run_target, load_series, read_run_tree

    started = time.perf_counter()

    def progress(message):
        print(f"[{time.perf_counter() - started:6.1f} s] {message}", file=sys.stderr, flush=True)

    check_run_target(args.out, overwrite=args.force)
    tree = read_run_tree(args.run) if args.run else None
    if tree is not None:
        from bayes_sst.inference._predictive import run_series

        series = run_series(tree, "diagnose", path=args.series, exclude=args.exclude_test)
    else:
        series = load_series(args.series, exclude=args.exclude_test)
    result = diagnose(series, run_tree=tree, progress=progress)
    write_diagnosis(args.out, result, overwrite=args.force)
    print(result.verdict)
    progress(f"diagnosis written to {args.out}")
    return 0
