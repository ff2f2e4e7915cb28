"""`bayes-sst ocrf SERIES [--out DIR]`: the oil-column resonance of a series' broadband tests.

Only argparse at import time: the command line registers this sub-command without loading
the numerical stack, which `run` imports when the command actually runs.
"""

from __future__ import annotations

OCRF_JSON = "ocrf.json"
OCRF_TEXT = "ocrf.txt"


def add_parser(subparsers):
    """Register the `ocrf` sub-command on an argparse subparsers object; returns its parser."""
    p = subparsers.add_parser(
        "ocrf",
        help="oil-column resonance from the broadband tests' frequency response",
        description="Estimate the frequency response H1 = S_xy/S_xx from command (a_cmd, else u_cmd) to "
        "measured motion (a, else u) of the series' broadband tests, pooled per payload, and locate its "
        "peak (the oil-column resonance) with an interval; the analytic f_oil of the table description "
        "is shown beside it. Prints a table; with --out writes ocrf.json (SI) and ocrf.txt.",
    )
    p.add_argument("series", help="series folder (with series.json)")
    from bayes_sst.cli import add_exclude_argument
    add_exclude_argument(p)
    p.add_argument("--out", default=None, help="output folder to create (default: print only)")
    p.add_argument("--force", action="store_true", help="replace an existing output folder")
    p.add_argument("--chambers", type=int, choices=(2, 4), default=2,
                   help="analytic form: 2 (V is each chamber's volume, the study's 2*beta, default) "
                   "or 4 (V is the total oil volume)")
    p.add_argument("--moving-mass", type=float, default=None, metavar="KG",
                   help="the empty table's moving mass for the analytic f_oil (default: the table "
                   "description's moving_mass_kg, else deck_mass_kg)")
    p.add_argument("--band", type=float, nargs=2, default=(5.0, 80.0), metavar=("LOW", "HIGH"),
                   help="search band, Hz (default 5 80)")
    p.add_argument("--min-coherence", type=float, default=0.5,
                   help="bins of lower coherence are not searched or fitted (default 0.5)")
    p.add_argument("--segment", type=float, default=2.0, metavar="S",
                   help="Welch segment length, s (resolution 1/S Hz, default 2)")
    p.add_argument("--interval", choices=("wider", "random", "half-power"), default="wider",
                   help="interval reported as low-high: the wider of the random-error bootstrap interval "
                   "and the half-power band (default), or either one")
    p.add_argument("--seed", type=int, default=0, help="seed of the bootstrap")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    """Handler of `ocrf`: refuse a taken --out early, estimate, print, write atomically."""
    from bayes_sst.io import atomic_output_dir, check_run_target, load_series, write_json_atomic
    from bayes_sst.oil._resonance import format_oil_column, oil_column_resonance

    out = getattr(args, "out", None)
    force = bool(getattr(args, "force", False))
    if out is not None:
        check_run_target(out, overwrite=force)
    series = load_series(args.series, exclude=args.exclude_test)
    result = oil_column_resonance(
        series,
        chambers=getattr(args, "chambers", 2),
        moving_mass_kg=getattr(args, "moving_mass", None),
        band_hz=tuple(getattr(args, "band", (5.0, 80.0))),
        min_coherence=getattr(args, "min_coherence", 0.5),
        segment_s=getattr(args, "segment", 2.0),
        interval=getattr(args, "interval", "wider"),
        seed=getattr(args, "seed", 0),
    )
    data = result.to_json()
    text = format_oil_column(data)
    if out is not None:
        with atomic_output_dir(out, overwrite=force) as tmp:
            write_json_atomic(tmp / OCRF_JSON, data)
            (tmp / OCRF_TEXT).write_text(text + "\n")
    print(text)
    return 0
