"""`bayes-sst design RUN --target Ke=2% [...]`: the next tests to run, and how many.

Only argparse at import time; the numerical stack is imported when the command runs.
"""

from __future__ import annotations

from bayes_sst._argtypes import non_negative_int

DESIGN_JSON = "design.json"
DESIGN_TEXT = "design.txt"
DESIGN_PLOT = "design.png"


def add_parser(subparsers):
    """Register the `design` sub-command on an argparse subparsers object; returns its parser."""
    p = subparsers.add_parser(
        "design",
        help="which tests to add, and how many, to reach target precisions",
        description="Bayesian design of the next tests of a fitted series: the current half-width of every "
        "parameter, an ordered list of recommended tests inside the table's limits, the predicted half-width "
        "of each target against the number of added tests (median and 80 % band over possible outcomes) for "
        "the recommended tests and for repeating the series' own plan, and the smallest number of added tests "
        "that meets every target. Writes design.json, design.txt and design.png.",
    )
    p.add_argument("run", help="run folder written by 'bayes-sst fit'")
    p.add_argument("--target", action="append", default=[], metavar="NAME=VALUE", required=True,
                   help="relative half-width of the 90 %% interval to reach, e.g. Ke=2%% or Fmu=0.05 "
                   "(repeatable; NAME one of Me, Ke, Ce, alpha, Fmu)")
    p.add_argument("--max-tests", type=int, default=40, help="most tests to add (default 40)")
    p.add_argument("--candidates", default=None, metavar="FILE",
                   help="JSON list of candidate tests {kind, frequency_hz, amplitude_m} (default: a grid of "
                   "sines and triangles, 0.25-4 Hz, 20-100 %% of the largest amplitude the limits allow)")
    p.add_argument("--out", default=None, help="output folder to create (default: RUN/design)")
    p.add_argument("--force", action="store_true", help="replace an existing output folder")
    p.add_argument("--series", default=None, help="series folder (default: the one the run records)")
    from bayes_sst.cli import add_exclude_argument
    add_exclude_argument(p)
    p.add_argument("--stroke", type=float, default=None, metavar="M", help="half stroke, m (overrides the series' table.limits)")
    p.add_argument("--max-velocity", type=float, default=None, metavar="M_S", help="velocity limit, m/s")
    p.add_argument("--max-acceleration", type=float, default=None, metavar="M_S2", help="acceleration limit, m/s^2")
    p.add_argument("--max-force", type=float, default=None, metavar="N", help="actuator force limit, N")
    p.add_argument("--outcomes", type=int, default=64, help="simulated outcomes per design (default 64)")
    p.add_argument("--seed", type=non_negative_int, default=0, help="seed of the simulated outcomes")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    """Handler of `design`: check the output early, design, print, write atomically."""
    import sys
    import time
    from pathlib import Path

    from bayes_sst.design._candidates import read_candidates
    from bayes_sst.design._design import design, format_design, parse_target
    from bayes_sst.inference._predictive import run_series
    from bayes_sst.io import atomic_output_dir, check_run_target, read_run_tree, write_json_atomic

    started = time.perf_counter()

    def say(message):
        print(f"[{time.perf_counter() - started:6.1f} s] {message}", file=sys.stderr, flush=True)

    targets = dict(parse_target(t) for t in args.target)
    if args.outcomes < 8:
        raise ValueError(f"--outcomes must be at least 8 for an 80 % band, got {args.outcomes}")
    out = Path(args.out) if args.out else Path(args.run) / "design"
    check_run_target(out, overwrite=args.force)
    candidates = read_candidates(args.candidates) if args.candidates else None
    tree = read_run_tree(args.run)
    series = (run_series(tree, "design", path=args.series, exclude=args.exclude_test)
              if args.series or args.exclude_test else None)
    result = design(
        tree,
        targets=targets,
        max_tests=args.max_tests,
        candidates=candidates,
        series=series,
        limit_overrides={"stroke_m": args.stroke, "velocity_m_s": args.max_velocity,
                         "acceleration_m_s2": args.max_acceleration, "force_n": args.max_force},
        n_outcomes=args.outcomes,
        seed=args.seed,
        progress=say,
    )
    data = result.to_json()
    data["command"] = " ".join(["bayes-sst"] + sys.argv[1:])
    text = format_design(data)
    with atomic_output_dir(out, overwrite=args.force) as tmp:
        write_json_atomic(tmp / DESIGN_JSON, data)
        (tmp / DESIGN_TEXT).write_text(text + "\n")
        from bayes_sst.design._plot import plot_design

        plot_design(data, tmp / DESIGN_PLOT)
    print(text)
    say(f"design written to {out}")
    return 0
