"""One series of the first independent generator, many times over: how often the 90 % intervals
hold the truth when only the chance parts of that series are drawn again.

Two modes, both on one generator seed (its test plan, population truth, friction and noise
levels kept):

--mode redraw (default): the series regenerated with fresh test-to-test factors (spread_seed)
    and fresh sensor noise (noise_seed), every other draw as the seed made it; then fitted with
    the package defaults.
--mode own-world: the force drawn from the package's own model on the seed's motion. The
    series is regenerated once with ideal sensors; for each draw every test gets coefficients
    theta_j = population*(1 + spread*N(0, 1)) and the record's force becomes

        F = Me_j*a + Ke_j*u + (Ce_j*|v|^alpha + Fmu_j)*sign(v) + noise,   v = du/dt,

    the noise being the seed's own force noise (AR(1) plus white) or, with --white-sd, white
    noise of that sd at the recorded rate. This is the model the package fits, so its intervals
    should cover the truth 90 % of the time here whatever the plan; what the redraw mode adds
    on top is the generator's own physics (closed loop, sticking at reversals, sensor noise).

    PYTHONPATH=. .venv/bin/python benchmarks/redraw_coverage.py --seed 40 --draws 48 \
        --dir /tmp/redraw40 --out benchmarks/results/redraw_first_40.json
    PYTHONPATH=. .venv/bin/python benchmarks/redraw_coverage.py --seed 40 --draws 40 --mode own-world \
        --dir /tmp/own40 --out benchmarks/results/own_world_first_40.json
    PYTHONPATH=. .venv/bin/python benchmarks/redraw_coverage.py --seed 40 --draws 40 --mode own-world \
        --spread-on Ce,Fmu [--pinned-spread] --dir /tmp/own40cf --out ...

--spread-on lets only some coefficients vary between tests; --pinned-spread fits with their
between-test spread prior held at the truth, which shows what reading the spread from the data
costs the intervals. --spread-from-prior draws, for each draw, every varying coefficient's
between-test sd from the fit's own spread prior (log-normal, relative to the prior's centres),
so that the coverage averaged over the draws is what an exact posterior must give whatever the
spread (the population values stay the seed's, which the data pin down far more tightly than
the prior does); each row records the sds drawn.

Each draw prints z = (mean - truth)/sd per parameter; the end prints z's mean and sd and the
coverage over the draws. About 15 s a draw (generation 5-10 s in redraw mode, fit 4-8 s).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import NamedTuple

import numpy as np

from _options import PARAMETERS as NAMES, coverage_summary, interval_check
from independent_generator import ar1, make_series

from bayes_sst.inference._statistics import COEFFICIENTS


class QuietSeries(NamedTuple):
    """The ideal-sensor series own-world mode writes its forces onto, read once."""

    folder: str
    truth: dict
    motion: dict  # test file -> (its columns t, u, F, a; |v|^alpha; sign(v) where the table moves, else 0)


def read_quiet(folder: str) -> QuietSeries:
    """The ideal-sensor series in `folder`: its truth and, per test, the recorded columns with the
    speed term |v|^alpha and the moving sign sign(v)*(|v| > 1e-6) of the model's force, v = du/dt."""
    truth = json.loads(Path(folder, "truth.json").read_text())
    motion = {}
    for test in json.loads(Path(folder, "series.json").read_text())["tests"]:
        data = np.loadtxt(Path(folder, test["file"]), delimiter=",", skiprows=1)
        v = np.gradient(data[:, 1], data[:, 0])
        moving = np.sign(v) * (np.abs(v) > 1e-6)  # the generator's table rests with v exactly 0
        motion[test["file"]] = (data, np.abs(v) ** truth["population"]["alpha"], moving)
    return QuietSeries(folder, truth, motion)


def own_world_series(quiet: QuietSeries, folder: str, draw: int, spread: float, white_sd: float | None,
                     spread_on=COEFFICIENTS, theta_stream: bool = False, prior_spread=None) -> dict:
    """Copy the ideal-sensor series `quiet` to `folder` with every test's force replaced by the
    model's (module docstring), only the coefficients in spread_on varying between tests;
    returns the truth's population values. theta_stream: the tests' coefficients come from a
    random stream of their own instead of the one the noise is drawn from, so that two runs that
    differ only in the noise (--white-sd) fit the same coefficients. prior_spread: (median, log
    sd, centres) of the fit's spread prior; each coefficient in spread_on then varies by an sd
    drawn from it (centre times a log-normal draw, from a stream of its own), returned as
    population["between_test_sd"]."""
    population, rate, noise = quiet.truth["population"], quiet.truth["fs"], quiet.truth["noise_of_seed"]
    rng = np.random.default_rng([draw, 11])
    coefficient_rng = np.random.default_rng([draw, 12]) if theta_stream else rng
    absolute_sd = None
    if prior_spread is not None:
        median, log_sd, centres = prior_spread
        coefficient_rng = np.random.default_rng([draw, 13])
        drawn = {k: float(np.exp(np.log(m) + s * coefficient_rng.normal()))
                 for k, m, s in zip(COEFFICIENTS, median, log_sd)}
        absolute_sd = {k: drawn[k] * centres[k] if k in spread_on else 0.0 for k in COEFFICIENTS}
    shutil.rmtree(folder, ignore_errors=True)
    shutil.copytree(quiet.folder, folder)
    for file, (recorded, speed_term, moving) in quiet.motion.items():
        data = recorded.copy()
        u, a = data[:, 1], data[:, 3]
        # every coefficient takes its deviate, so the noise's stream is the same whatever varies
        if prior_spread is None:
            theta = {k: population[k] * (1.0 + (spread if k in spread_on else 0.0) * coefficient_rng.normal())
                     for k in COEFFICIENTS}
        else:
            theta = {k: population[k] + absolute_sd[k] * coefficient_rng.normal() for k in COEFFICIENTS}
        force = theta["Me"] * a + theta["Ke"] * u + (theta["Ce"] * speed_term + theta["Fmu"]) * moving
        n = len(data)
        if white_sd is None:
            force += ar1(rng, n, rate, noise["F_tc"], noise["F_ar_sd"]) + rng.normal(0.0, noise["F_white"], n)
        else:
            force += rng.normal(0.0, white_sd, n)
        data[:, 2] = force
        np.savetxt(Path(folder, file), data, fmt=("%.6f", "%.9e", "%.9e", "%.9e"), delimiter=",",
                   header="t,u,F,a", comments="")
    return population if absolute_sd is None else {**population, "between_test_sd": absolute_sd}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, required=True, help="the first generator's series seed")
    parser.add_argument("--draws", type=int, default=24)
    parser.add_argument("--first-draw", type=int, default=0)
    parser.add_argument("--mode", choices=("redraw", "own-world"), default="redraw")
    parser.add_argument("--spread", type=float, default=0.02,
                        help="own-world: relative test-to-test sd of Me, Ke, Ce, Fmu (the generator's is 0.02)")
    parser.add_argument("--spread-on", default=",".join(COEFFICIENTS),
                        help="own-world: the coefficients that vary between tests, e.g. Ce,Fmu")
    parser.add_argument("--pinned-spread", action="store_true",
                        help="own-world: fit with the between-test spread prior of the --spread-on "
                             "coefficients pinned at the truth (log sd 0.05), to see what reading the spread costs")
    parser.add_argument("--theta-stream", action="store_true",
                        help="own-world: draw the tests' coefficients from a random stream of their own "
                             "(paired runs: the same coefficients under different noise)")
    parser.add_argument("--spread-from-prior", action="store_true",
                        help="own-world: each draw's between-test sds drawn from the fit's spread prior "
                             "instead of --spread (module docstring)")
    parser.add_argument("--white-sd", type=float, default=None,
                        help="own-world: white force noise of this sd (N) in place of the seed's own")
    parser.add_argument("--dir", default="/tmp/bayes_sst_redraw")
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    from bayes_sst.inference import fit
    from bayes_sst.inference._priors import make_priors
    from bayes_sst.inference._summary import summarize
    from bayes_sst.io import load_series

    spread_on = tuple(name for name in args.spread_on.split(",") if name)
    unknown = set(spread_on) - set(COEFFICIENTS)
    if unknown:
        raise SystemExit(f"--spread-on: {sorted(unknown)} are not among {COEFFICIENTS}")
    if args.spread_from_prior and (args.mode != "own-world" or args.pinned_spread):
        raise SystemExit("--spread-from-prior needs --mode own-world and no --pinned-spread")
    quiet = os.path.join(args.dir, f"s{args.seed:02d}_ideal_sensors")
    if args.mode == "own-world" and not os.path.exists(os.path.join(quiet, "truth.json")):
        noisy = os.path.join(args.dir, f"s{args.seed:02d}")
        make_series(args.seed, noisy)
        make_series(args.seed, quiet, noise_scale=0.0)
        truth = json.loads(Path(quiet, "truth.json").read_text())
        truth["noise_of_seed"] = json.loads(Path(noisy, "truth.json").read_text())["noise"]
        Path(quiet, "truth.json").write_text(json.dumps(truth, indent=1))

    rows = []
    quiet_series = read_quiet(quiet) if args.mode == "own-world" else None
    prior_spread = None
    if args.spread_from_prior:
        generic = make_priors("generic", load_series(quiet).table)
        prior_spread = (*generic.spread_prior(), dict(generic.centres))
    for draw in range(args.first_draw, args.first_draw + args.draws):
        folder = os.path.join(args.dir, f"s{args.seed:02d}_draw{draw:03d}")
        if args.mode == "redraw":
            if not os.path.exists(os.path.join(folder, "truth.json")):
                make_series(args.seed, folder, spread_seed=500 + draw, noise_seed=900 + draw)
            population = json.loads(Path(folder, "truth.json").read_text())["population"]
        else:
            population = own_world_series(quiet_series, folder, draw, args.spread, args.white_sd, spread_on,
                                          args.theta_stream, prior_spread)
        started = time.perf_counter()
        series = load_series(folder)
        prior = make_priors("generic", series.table)
        if args.pinned_spread:
            pinned = {k: (args.spread * population[k] / prior.centres[k], 0.05) for k in spread_on}
            prior = replace(prior, spread_by_coefficient={**prior.spread_by_coefficient, **pinned})
        result = fit(series, seed=draw, prior=prior)
        summary = summarize(result.tree)
        row = {"draw": draw, "seconds": time.perf_counter() - started, "converged": summary["converged"],
               **interval_check(summary["parameters"], population)}
        if "between_test_sd" in population:
            row["between_test_sd"] = population["between_test_sd"]
        rows.append(row)
        print(f"draw {draw:3d}  " + "  ".join(f"{n} {row[n]['z']:+5.2f}{'' if row[n]['covered'] else '*'}" for n in NAMES)
              + ("" if row["converged"] else "  NOT CONVERGED"), flush=True)
    summary = coverage_summary(rows)
    if args.out:
        Path(args.out).write_text(json.dumps({"command": " ".join(sys.argv), "seed": args.seed, "mode": args.mode,
                                              "spread": args.spread, "white_sd": args.white_sd,
                                              "spread_on": list(spread_on), "pinned_spread": args.pinned_spread,
                                              "theta_stream": args.theta_stream,
                                              "spread_from_prior": args.spread_from_prior,
                                              "summary": summary, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
