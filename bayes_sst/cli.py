"""The bayes-sst command line: one sub-command per task; heavy imports only once a task runs."""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time
import traceback
from pathlib import Path

from bayes_sst._argtypes import non_negative_int, non_negative_number, positive_number, share_below_one

_START = time.perf_counter()


def _progress(message: str) -> None:
    print(f"[{time.perf_counter() - _START:6.1f} s] {message}", file=sys.stderr, flush=True)


def _cmd_simulate(args) -> int:
    from bayes_sst.io import check_run_target, write_series
    from bayes_sst.twin import simulate

    check_run_target(args.out, overwrite=args.force)
    _progress(f"simulating preset '{args.preset}' (seed {args.seed}) on the virtual table ...")
    series = simulate(args.preset, seed=args.seed, spread=args.spread, name=args.name)
    write_series(series, args.out, overwrite=args.force)
    _progress(f"wrote {len(series.tests)} tests, {series.n_samples} samples to {args.out}")
    return 0


def _comma_list(text: str) -> list[str]:
    """The non-empty items of a comma-separated option value, stripped."""
    return [x.strip() for x in text.split(",") if x.strip()]


def _test_ids(text: str) -> list[str]:
    ids = _comma_list(text)
    if not ids:
        raise argparse.ArgumentTypeError(f"no test id in {text!r}")
    return ids


SHAREABLE = ("Me", "Ke", "Ce", "Fmu")


def _shared_coefficients(text: str) -> list[str]:
    """--shared NAME[,NAME...]: one token per use (nargs='+' swallowed a SERIES written after it)."""
    names = _comma_list(text)
    unknown = [x for x in names if x not in SHAREABLE]
    if not names or unknown:
        raise argparse.ArgumentTypeError(f"{text!r}: give one or more of {', '.join(SHAREABLE)}, separated by commas")
    return names


def add_exclude_argument(parser) -> None:
    """--exclude-test ID[,ID...] (repeatable): tests of the series' manifest to leave out
    (load_series(..., exclude=)). One token per use, so that it cannot swallow SERIES."""
    parser.add_argument("--exclude-test", action="extend", type=_test_ids, default=[], metavar="ID[,ID...]",
                        help="leave these tests of the manifest out (their CSV files are not read), e.g. a test "
                             "the analysis refuses; ids separated by commas, or the option repeated. A fit "
                             "records them, and report, design and diagnose --run leave a run's own out by "
                             "themselves")


def fit_signal_options(args):
    """The SignalOptions of `bayes-sst fit`'s arguments."""
    from dataclasses import replace

    from bayes_sst.signals import SignalOptions

    options = SignalOptions(cutoff_multiple=args.cutoff_multiple)
    if args.reversal_band is not None:  # the user's band holds for every test, accelerometer or not
        options = replace(options, reversal_band=args.reversal_band, reversal_band_without_accelerometer=None)
    if args.reversal_speed is not None:
        options = replace(options, reversal_speed=args.reversal_speed)
    if args.presliding is not None:
        options = replace(options, presliding=args.presliding)
    if args.presliding_floor is not None:
        options = replace(options, presliding_floor=args.presliding_floor)
    return options


def _cmd_fit(args) -> int:
    from dataclasses import replace

    from bayes_sst.inference import fit
    from bayes_sst.inference._priors import make_priors
    from bayes_sst.inference._summary import format_summary, summarize
    from bayes_sst.io import check_run_target, load_series, write_run

    check_run_target(args.out, overwrite=args.force)
    started = time.perf_counter()
    _progress(f"reading {args.series} ...")
    series = load_series(args.series, exclude=args.exclude_test)
    options = fit_signal_options(args)
    priors = make_priors(args.prior, series.table, per_test_alpha=args.per_test_alpha)
    if args.shared:
        priors = replace(priors, shared=tuple(dict.fromkeys(args.shared)))
    result = fit(
        series,
        chains=args.chains,
        draws=args.draws,
        warmup=args.warmup,
        seed=args.seed,
        extensions=args.extensions,
        prior=priors,
        signals=options,
        progress=_progress,
        widen=not args.no_widening,
    )
    _progress("checking convergence and writing the run ...")
    summary = summarize(result.tree, seconds=time.perf_counter() - started)
    summary["command"] = " ".join(["bayes-sst"] + sys.argv[1:])
    summary["timings"] = result.timings
    summary["classical"] = _classical_beside(series)
    text = format_summary(summary)
    write_run(args.out, result.tree, summary, text, overwrite=args.force)
    print(text)
    for warning in summary["warnings"]:
        print(f"WARNING: {warning}", file=sys.stderr)
    _progress(f"run written to {args.out}")
    return 0


def _classical_beside(series):
    """The hand method's pooled estimates for the summary's middle column, or None with a note."""
    from bayes_sst.classical import classical_identification

    try:
        # the fit's signal preparation has checked these records against the manifest already
        return classical_identification(series, check_records=False).to_json()["pooled"]
    except (ValueError, ArithmeticError) as exc:
        _progress(f"classical estimates not available for this series: {exc}")
        return None


def _cmd_summary(args) -> int:
    from bayes_sst.inference._summary import format_summary
    from bayes_sst.io import read_run_summary

    print(format_summary(read_run_summary(args.run)))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="bayes-sst",
        description="Bayesian identification of a shaking table's force model "
        "F = Me*a + Ke*u + (Ce*|v|^alpha + Fmu)*sign(v) from periodic test series.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("simulate", help="write a synthetic test series from the virtual table")
    p.add_argument("--preset", default="sst-paper", help="table preset (default sst-paper)")
    p.add_argument("--out", required=True, help="series folder to create")
    p.add_argument("--seed", type=non_negative_int, default=0)
    p.add_argument("--spread", type=non_negative_number, default=None, help="test-to-test relative sd of Me, Ke, Ce, Fmu")
    p.add_argument("--name", default=None, help="series name (default from the preset)")
    p.add_argument("--force", action="store_true", help="replace an existing folder")
    p.set_defaults(handler=_cmd_simulate)

    p = sub.add_parser("fit", help="posterior of Me, Ke, Ce, alpha, Fmu from a series folder")
    p.add_argument("series", help="series folder (with series.json)")
    p.add_argument("--out", required=True, help="run folder to create")
    p.add_argument("--chains", type=int, default=4)
    p.add_argument("--draws", type=int, default=500, help="draws per chain after warm-up")
    p.add_argument("--warmup", type=int, default=300, help="warm-up iterations per chain")
    p.add_argument("--extensions", type=int, default=2,
                   help="times the chains go on for --draws more while R-hat or bulk ESS misses its limit (0: never)")
    p.add_argument("--seed", type=non_negative_int, default=0)
    p.add_argument("--prior", choices=("generic", "physics"), default="generic",
                   help="generic weak priors, or centred by the series' table description")
    p.add_argument("--shared", action="extend", type=_shared_coefficients, default=[], metavar="NAME[,NAME...]",
                   help="coefficients (Me, Ke, Ce, Fmu) the same in every test (no between-test variation), "
                        "e.g. --shared Me when the moving mass cannot change between tests; names separated "
                        "by commas, or the option repeated")
    p.add_argument("--per-test-alpha", action="store_true",
                   help="let the damping exponent vary between tests around the population's (its between-test "
                        "sd reported as alpha_between_test_sd): for a damping law that is a power law only "
                        "approximately, read by tests over different speed ranges")
    p.add_argument("--no-widening", action="store_true",
                   help="report the model's posterior as it is: do not widen the population intervals where the "
                        "tests, left out one at a time, scatter more than the model allows (README, Model)")
    p.add_argument("--cutoff-multiple", type=positive_number, default=4.0,
                   help="low-pass cut-off as a multiple of each test's frequency (default 4)")
    p.add_argument("--reversal-band", type=share_below_one, default=None,
                   help="leave out samples slower than this share of the peak speed (default 0.1, and "
                        "0.2 for tests without an accelerometer; a value given here applies to every test)")
    p.add_argument("--reversal-speed", type=non_negative_number, default=None, metavar="M_PER_S",
                   help="the band reaches at least this speed, up to half the peak speed (default 0.01 m/s: "
                        "friction exceeds its kinetic level below a few Stribeck velocities)")
    p.add_argument("--presliding", type=non_negative_number, default=None, metavar="M",
                   help="the friction's pre-sliding travel: the samples within 4 times it after each reversal "
                        "are left out (default: read from the series; 0 leaves nothing out for it)")
    p.add_argument("--presliding-floor", type=non_negative_number, default=None, metavar="M",
                   help="with --presliding read from the series, the travel left out where the series leans to "
                        "a turn too short to read (default 4e-05 m; 0: none)")
    add_exclude_argument(p)
    p.add_argument("--force", action="store_true", help="replace an existing run folder")
    p.set_defaults(handler=_cmd_fit)

    from bayes_sst.classical._command import add_parser as add_classical
    from bayes_sst.oil._command import add_parser as add_ocrf
    from bayes_sst.report._command import add_parser as add_report
    from bayes_sst.diagnosis._command import add_parser as add_diagnose
    from bayes_sst.design._command import add_parser as add_design

    add_classical(sub)
    add_ocrf(sub)
    add_report(sub)
    add_diagnose(sub)
    add_design(sub)

    p = sub.add_parser("summary", help="print the posterior summary of a run folder")
    p.add_argument("run", help="run folder written by 'bayes-sst fit'")
    p.set_defaults(handler=_cmd_summary)
    return parser


def _raised_elsewhere(exc: BaseException) -> str | None:
    """Where in bayes_sst an exception came from when a library below it (numpy, json) raised
    it, as 'path:line (function)'; None when bayes_sst raised it itself (a message for the user)."""
    frames = traceback.extract_tb(exc.__traceback__)
    package = os.path.dirname(os.path.abspath(__file__))
    ours = [f for f in frames if os.path.abspath(f.filename).startswith(package + os.sep)]
    if not frames or not ours or ours[-1] is frames[-1]:
        return None
    last = ours[-1]
    return f"{os.path.relpath(last.filename, os.path.dirname(package))}:{last.lineno} ({last.name})"


# the file that marks a folder as a series or a run, and the one command whose output it is:
# --force lets a command replace a folder of its own kind only
MARKED_OUTPUTS = {"series.json": "simulate", "posterior.nc": "fit"}


def _inside(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


def check_output_against_inputs(args) -> None:
    """Refuse an --out that would replace what the command reads or where it runs: the input
    series or run folder (or a folder holding it), the current folder or one above it, or,
    with --force, a folder of another kind (a series for any command but simulate, a run for
    any but fit). Why: --force replaces its target whole, and a mistyped --out once deleted
    the series it was fitting."""
    from bayes_sst.io import OutputTargetError

    out = getattr(args, "out", None)
    if out is None or str(out).strip() == "":
        return
    target = Path(out).resolve()
    for name in ("series", "run"):
        given = getattr(args, name, None)
        if given and _inside(Path(given).resolve(), target):
            raise OutputTargetError(f"--out {out} would replace the {name} folder {given} this command reads; "
                                    "choose another output folder")
    if _inside(Path.cwd().resolve(), target):
        raise OutputTargetError(f"--out {out} is the current folder or holds it; choose another output folder")
    if getattr(args, "force", False) and target.is_dir():
        for marker, owner in MARKED_OUTPUTS.items():
            if args.command != owner and (target / marker).is_file():
                kind = "a test series" if owner == "simulate" else "a run of bayes-sst fit"
                raise OutputTargetError(f"--out {out} holds {kind} ({marker}); --force replaces only an earlier "
                                        f"output of bayes-sst {args.command}: choose another output folder")


def _terminate(signum, frame):
    # SIGTERM (a scheduler's kill, a closed session) unwinds like Ctrl-C, so that the atomic
    # writers remove their hidden temporary folders and leave an existing output as it was
    raise KeyboardInterrupt


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    on_main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminate) if on_main_thread else None
    try:
        return _run(args)
    finally:
        if on_main_thread:
            signal.signal(signal.SIGTERM, previous)


def _run(args) -> int:
    from bayes_sst.io import OutputExistsError, SeriesFormatError

    try:
        check_output_against_inputs(args)
        return args.handler(args)
    except (SeriesFormatError, OutputExistsError, ValueError) as exc:
        where = None if isinstance(exc, (SeriesFormatError, OutputExistsError)) else _raised_elsewhere(exc)
        if where is None:
            print(f"bayes-sst {args.command}: error: {exc}", file=sys.stderr)
        else:
            # not one of the package's messages: a fault of the package on this input
            print(f"bayes-sst {args.command}: internal error at {where}: {exc}; nothing was written. Please "
                  "report it with the series (BAYES_SST_TRACEBACK=1 prints the traceback)", file=sys.stderr)
            if os.environ.get("BAYES_SST_TRACEBACK"):
                traceback.print_exception(exc)
        return 2
    except OSError as exc:
        # the file system refused (read-only, full, permissions) where no check could foresee it
        where = exc.filename or "a file"
        print(f"bayes-sst {args.command}: error: {where}: {exc.strerror or exc}; an existing output was left as it "
              "was (BAYES_SST_TRACEBACK=1 prints the traceback)", file=sys.stderr)
        if os.environ.get("BAYES_SST_TRACEBACK"):
            traceback.print_exception(exc)
        return 2
    except KeyboardInterrupt:
        print(f"bayes-sst {args.command}: interrupted; nothing was written", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
