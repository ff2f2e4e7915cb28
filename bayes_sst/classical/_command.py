"""`bayes-sst classical SERIES --out DIR`: the hysteresis-loop identification of a series.

Only argparse at import time: the command line registers this sub-command without loading
the numerical stack, which `run` imports when the command actually runs.
"""

from __future__ import annotations

from bayes_sst._argtypes import damping_exponent, positive_number

CLASSICAL_JSON = "classical.json"
CLASSICAL_TEXT = "classical.txt"


def add_parser(subparsers):
    """Register the `classical` sub-command on an argparse subparsers object; returns its parser."""
    p = subparsers.add_parser(
        "classical",
        help="the published hysteresis-loop identification of a series (no sampling)",
        description="Identify Me, Ke, Ce, alpha, Fmu by the reference study's hand method: one steady "
        "cycle per periodic test split at symmetric instants into dissipative and inertial-plus-elastic "
        "forces, Ke from triangle flanks (or 4*p0*A/h from the table description), Me from the sines, "
        "Fmu, Ce, alpha from the dissipative force. Writes classical.json (SI) and classical.txt.",
    )
    p.add_argument("series", help="series folder (with series.json)")
    from bayes_sst.cli import add_exclude_argument
    add_exclude_argument(p)
    p.add_argument("--out", required=True, help="output folder to create")
    p.add_argument("--cycle", type=int, default=-2,
                   help="which steady cycle of each test, Python index (default -2: the second-to-last)")
    p.add_argument("--cutoff-multiple", type=positive_number, default=4.0,
                   help="zero-phase low-pass cut-off as a multiple of each test's frequency (default 4)")
    p.add_argument("--alpha", type=damping_exponent, default=None,
                   help="fix the damping exponent (e.g. 0.5) instead of fitting it")
    p.add_argument("--force", action="store_true", help="replace an existing output folder")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    """Handler of `classical`: refuse a taken --out early, identify, write atomically, print a table."""
    from bayes_sst.classical._identify import classical_identification, format_classical
    from bayes_sst.io import atomic_output_dir, check_run_target, load_series, write_json_atomic

    force = bool(getattr(args, "force", False))
    check_run_target(args.out, overwrite=force)
    series = load_series(args.series, exclude=args.exclude_test)
    result = classical_identification(
        series,
        cycle=getattr(args, "cycle", -2),
        cutoff_multiple=getattr(args, "cutoff_multiple", 4.0),
        alpha=getattr(args, "alpha", None),
    )
    data = result.to_json()
    text = format_classical(data)
    with atomic_output_dir(args.out, overwrite=force) as tmp:
        write_json_atomic(tmp / CLASSICAL_JSON, data)
        (tmp / CLASSICAL_TEXT).write_text(text + "\n")
    print(text)
    return 0
