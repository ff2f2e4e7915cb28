"""Wall time, compilation, ESS per second and peak memory of bayes_sst.inference.fit.

Two virtual-table series (sst-paper preset, spread 0.02, default sensor noise):

* 20 tests: the default plan (about 42,700 recorded samples);
* 200 tests: the default plan ten times, the first copy as is, the other nine with
  frequencies jittered by up to +-5 % and amplitudes by -15..0 % (about 400,000 samples).

Every configuration runs in its own subprocess, so that the peak resident memory
(VmHWM of /proc/self/status, the per-process high-water mark; ru_maxrss would inherit the
parent's across exec) belongs to that run alone. In the bayes_sst worker the JAX persistent compilation
cache points at a fresh, empty folder, and fit() runs twice with the same settings: the first
("cold") compiles, the second ("warm") loads the compiled code from the persistent cache,
as a second fit of a same-sized series does in practice. Compilation = cold - warm sampling
time; JAX's own compile-time events are reported next to it as a check.

With --peer the same model, priors and prepared data are sampled by PyMC + nutpie
(benchmarks/peer_pymc.py) in another subprocess, and the posterior means are compared.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_fit.py --tests 20 200 --peer

Writes benchmarks/results/fit_benchmark.json (or --out).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pickle
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
POPULATION = ("Me", "Ke", "Ce", "alpha", "Fmu")
SPREAD = 0.02
DISPLAY = {"Me": (1e-3, "t"), "Ke": (1e-3, "kN/m"), "Ce": (1e-3, "kN/(m/s)^a"), "alpha": (1.0, "-"),
           "Fmu": (1e-3, "kN")}


# --------------------------------------------------------------------------- series


def large_plan(copies: int = 10, seed: int = 0):
    """The default sst-paper plan `copies` times; copies after the first jittered slightly."""
    from bayes_sst.twin import default_plan

    base = default_plan("sst-paper")
    rng = np.random.default_rng(20_240 + seed)
    stroke, max_velocity = 0.1, 0.6  # sst-paper limits (TableTruth.stroke, .max_velocity)
    plan = []
    for copy in range(copies):
        for item in base:
            f, amp = item.frequency_hz, item.amplitude_m
            if copy:
                f = f * rng.uniform(0.95, 1.05)
                amp = amp * rng.uniform(0.85, 1.0)
                if item.kind == "sine":
                    amp = min(amp, stroke, 0.97 * max_velocity / (2 * math.pi * f))
            plan.append({"kind": item.kind, "frequency_hz": float(f), "amplitude_m": float(amp)})
    return plan


def make_series(n_tests: int, seed: int = 1):
    """The benchmark series of 20 (default plan) or 200 tests (10 jittered copies)."""
    from bayes_sst.twin import simulate

    if n_tests == 20:
        return simulate("sst-paper", seed=seed, spread=SPREAD, name=f"bench-20-seed{seed}")
    if n_tests % 20:
        raise ValueError("n_tests must be a multiple of 20")
    return simulate("sst-paper", seed=seed, spread=SPREAD, plan=large_plan(n_tests // 20, seed),
                    name=f"bench-{n_tests}-seed{seed}")


# --------------------------------------------------------------------------- workers


def _peak_rss_mib() -> float:
    """High-water resident set of this process's own address space (VmHWM), MiB.

    Not ru_maxrss: Linux carries the high-water mark of the address space an exec replaces
    into ru_maxrss, so a worker started by a big parent (here, the one that simulated the
    series) would report the parent's peak. VmHWM belongs to the worker's address space alone.
    """
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0  # kB
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # KiB on Linux


def worker_ours(series_file: str, result_file: str, per_test_alpha: bool = False):
    """Two fits (cold, warm) of one series in this process; JSON to result_file."""
    import jax.monitoring

    events: dict[str, float] = {}

    def listener(event, duration, **kwargs):
        if event.startswith(("/jax/core/compile", "/jax/compilation_cache")):
            events[event] = events.get(event, 0.0) + float(duration)

    jax.monitoring.register_event_duration_secs_listener(listener)
    import xarray as xr
    from arviz_stats import mcse

    from bayes_sst.inference import fit
    from bayes_sst.inference._summary import summarize
    from bayes_sst.inference._widening import model_draws

    with open(series_file, "rb") as fh:
        series = pickle.load(fh)
    from bayes_sst.inference._priors import make_priors

    prior = make_priors("generic", series.table, per_test_alpha=per_test_alpha)
    rss_before = _peak_rss_mib()
    out = {"implementation": "bayes_sst", "cache_dir": os.environ.get("BAYES_SST_CACHE"), "runs": {}}
    for label in ("cold", "warm"):
        events.clear()
        start = time.perf_counter()
        result = fit(series, prior=prior)
        wall = time.perf_counter() - start
        summary = summarize(result.tree)
        # the model's own draws, as the peer samples the model: the widening stretches the
        # reported ones (bayes_sst.inference._widening), which the peer does not do
        model = xr.DataTree.from_dict({"posterior": xr.Dataset(
            {n: model_draws(result.tree, n) for n in POPULATION})})
        m = mcse(model, var_names=list(POPULATION))
        model_values = {n: {"mean": float(model["posterior"][n].mean()),
                            "sd": float(model["posterior"][n].std(ddof=1))} for n in POPULATION}
        out["runs"][label] = {
            "wall_s": wall,
            "timings": dict(result.timings),
            "jax_events_s": dict(events),
            "min_ess_bulk": min(summary["parameters"][n]["ess_bulk"] for n in POPULATION),
            "max_r_hat_population": max(summary["parameters"][n]["r_hat"] for n in POPULATION),
            "max_r_hat_all": summary["max_r_hat"],
            "divergences": summary["divergences"],
            "mean_leapfrog_steps": float(result.tree["sample_stats"]["n_steps"].values.mean()),
            "parameters": {n: {**summary["parameters"][n], **model_values[n], "mcse_mean": float(m[n]),
                               "reported_sd": summary["parameters"][n]["sd"]} for n in POPULATION},
            "between_test_sd_mean": {
                n: float(result.tree["posterior"]["between_test_sd"].sel(coefficient=n).mean())
                for n in ("Me", "Ke", "Ce", "Fmu")
            },
        }
        out["n_tests"] = summary["n_tests"]
        out["n_recorded_samples"] = summary["n_samples"]
        out["n_likelihood_pairs"] = int(result.moments.n_pairs.sum())
        out["n_decimated_samples"] = int(sum(len(t.index) for t in result.prepared))
        del result
    out["peak_rss_before_fit_mib"] = rss_before
    out["peak_rss_mib"] = _peak_rss_mib()
    Path(result_file).write_text(json.dumps(out, indent=1))


def worker_peer(series_file: str, result_file: str, runs, budget_s: float):
    """Compile and sample the PyMC + nutpie peer; writes JSON after every run (partial on timeout)."""
    sys.path.insert(0, str(HERE))
    from peer_pymc import run_peer

    with open(series_file, "rb") as fh:
        series = pickle.load(fh)
    rss_before = _peak_rss_mib()

    def checkpoint(partial):
        partial = dict(partial, peak_rss_before_fit_mib=rss_before, peak_rss_mib=_peak_rss_mib(),
                       implementation="pymc+nutpie")
        Path(result_file).write_text(json.dumps(partial, indent=1))

    out = run_peer(series, runs=runs, budget_s=budget_s, checkpoint=checkpoint, progress=_log)
    checkpoint(out)


def _log(message: str):
    print(message, file=sys.stderr, flush=True)


def _spawn(args: list[str], env: dict, result_file: Path, timeout: float | None):
    start = time.perf_counter()
    cmd = [sys.executable, str(Path(__file__).resolve())] + args + ["--result-file", str(result_file)]
    timed_out = False
    try:
        subprocess.run(cmd, env=env, check=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        timed_out = True
    except subprocess.CalledProcessError as error:
        _log(f"worker failed ({error.returncode}): {' '.join(args)}")
    wall = time.perf_counter() - start
    data = json.loads(result_file.read_text()) if result_file.exists() else {}
    data["process_wall_s"] = wall
    data["timed_out"] = timed_out
    return data


# --------------------------------------------------------------------------- report


def _row(cols, widths):
    return "".join(f"{c:>{w}}" if i else f"{c:<{w}}" for i, (c, w) in enumerate(zip(cols, widths)))


def _f(x, fmt=".1f"):
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)


def format_tables(results: list[dict]) -> str:
    widths = (28, 8, 9, 9, 8, 9, 9, 9, 8, 8, 5, 7, 7, 9)
    head = ("configuration", "prep s", "compile", "sample", "post s", "cold s", "warm s", "min ESS",
            "ESS/s", "R-hat", "div", "steps", "draws", "peak MiB")
    lines = ["timings (s) and sampler efficiency; ESS = bulk ESS, minimum over Me, Ke, Ce, alpha, Fmu;",
             "ESS/s = min ESS / sampling time (compilation excluded); R-hat = max over the same five;",
             "steps = mean leapfrog steps per draw; peak MiB = VmHWM (peak resident memory) of the worker process",
             _row(head, widths), "-" * sum(widths)]
    for res in results:
        config = res["config"]
        ours = res.get("ours") or {}
        if ours.get("runs"):
            cold, warm = ours["runs"]["cold"], ours["runs"]["warm"]
            compile_s = cold["timings"]["sampling"] - warm["timings"]["sampling"]
            lines.append(_row((
                f"{config}: bayes_sst", _f(warm["timings"]["signals"], ".2f"), _f(compile_s), _f(warm["timings"]["sampling"]),
                _f(warm["timings"]["posterior"]), _f(cold["wall_s"]), _f(warm["wall_s"]), _f(cold["min_ess_bulk"], ".0f"),
                _f(cold["min_ess_bulk"] / warm["timings"]["sampling"], ".0f"), _f(cold["max_r_hat_population"], ".3f"),
                str(cold["divergences"]), _f(cold["mean_leapfrog_steps"], ".0f"), "4x500", _f(ours["peak_rss_mib"], ".0f"),
            ), widths))
        elif ours:
            lines.append(f"{config}: bayes_sst worker failed or timed out")
        peer = res.get("peer") or {}
        for k, run in enumerate(peer.get("runs", [])):
            label = f"{config}: pymc+nutpie"
            draws = f"{peer['chains']}x{run['draws']}"
            if run.get("skipped"):
                lines.append(_row((label, "", "", "", "", "", "", "", "", "", "", "", draws, ""), widths)
                             + f"   skipped: {run['skipped']}")
                continue
            wall = peer["signals_s"] + peer["model_build_s"] + peer["compile_s"] + run["sampling_s"]
            lines.append(_row((
                label, _f(peer["signals_s"], ".2f"), _f(peer["model_build_s"] + peer["compile_s"]),
                _f(run["sampling_s"]), "-", _f(wall), "-", _f(run["min_ess_bulk"], ".0f"),
                _f(run["ess_per_s"], ".0f"), _f(run["max_r_hat"], ".3f"), str(run["divergences"]),
                _f(run["mean_leapfrog_steps"], ".0f"), f"{draws}", _f(peer.get("peak_rss_mib"), ".0f"),
            ), widths))
        if peer.get("timed_out"):
            lines.append(f"{config}: pymc+nutpie stopped at the time limit; runs above are those that finished")
        if res.get("peer_note"):
            lines.append(f"{config}: pymc+nutpie: {res['peer_note']}")
    lines.append("")
    lines.append("compile (bayes_sst) = cold - warm sampling time, the warm fit loading XLA code from the persistent cache;")
    lines.append("compile (pymc+nutpie) = PyMC model build + nutpie numba compilation; cold s = first fit end to end")
    for res in results:
        ours = (res.get("ours") or {}).get("runs")
        if ours:
            ev = ours["cold"]["jax_events_s"]
            backend = ev.get("/jax/core/compile/backend_compile_duration", 0.0)
            trace = ev.get("/jax/core/compile/jaxpr_trace_duration", 0.0)
            lower = ev.get("/jax/core/compile/jaxpr_to_mlir_module_duration", 0.0)
            wev = ours["warm"]["jax_events_s"]
            lines.append(f"  {res['config']}: JAX events, cold fit: trace {trace:.1f} s, lowering {lower:.1f} s, "
                         f"XLA compile {backend:.1f} s; warm fit: XLA compile or cache load "
                         f"{wev.get('/jax/core/compile/backend_compile_duration', 0.0):.1f} s")
    lines.append("")
    lines.append("posterior of the population values, bayes_sst (4x500) vs pymc+nutpie (largest finished run):")
    lines.append("  d/sd = (peer - ours) / posterior sd (ours); z = (peer - ours) / sqrt(mcse_ours^2 + mcse_peer^2)")
    widths2 = (28, 12, 11, 12, 11, 8, 7)
    lines.append(_row(("parameter", "ours mean", "ours sd", "peer mean", "peer sd", "d/sd", "z"), widths2))
    for res in results:
        ours = (res.get("ours") or {}).get("runs", {}).get("cold")
        peer_runs = [r for r in (res.get("peer") or {}).get("runs", []) if not r.get("skipped")]
        if not ours or not peer_runs:
            continue
        peer = max(peer_runs, key=lambda r: r["n_draws"])
        for name in POPULATION:
            scale, unit = DISPLAY[name]
            o, p = ours["parameters"][name], peer["parameters"][name]
            d = (p["mean"] - o["mean"]) / o["sd"]
            z = (p["mean"] - o["mean"]) / math.hypot(o["mcse_mean"], p["mcse_mean"])
            lines.append(_row((f"{res['config']}: {name} [{unit}]", f"{o['mean'] * scale:.5g}", f"{o['sd'] * scale:.3g}",
                               f"{p['mean'] * scale:.5g}", f"{p['sd'] * scale:.3g}", f"{d:+.2f}", f"{z:+.1f}"), widths2))
        for name in ("Me", "Ke", "Ce", "Fmu"):
            scale, unit = DISPLAY[name]
            o, p = ours["between_test_sd_mean"][name], peer["between_test_sd_mean"][name]
            lines.append(_row((f"{res['config']}: sd_{name} [{unit}]", f"{o * scale:.4g}", "", f"{p * scale:.4g}",
                               "", "", ""), widths2))
    return "\n".join(lines)


# --------------------------------------------------------------------------- main


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tests", type=int, nargs="+", default=[20, 200])
    parser.add_argument("--seed", type=int, default=1, help="simulation seed of the series")
    parser.add_argument("--peer", action="store_true", help="also sample the PyMC + nutpie peer")
    parser.add_argument("--peer-runs", default="500:500,1000:1000",
                        help="tune:draws per chain for the peer, comma separated (4 chains)")
    parser.add_argument("--peer-budget", type=float, default=900.0,
                        help="seconds of peer sampling per configuration; a run predicted to exceed "
                             "it is skipped, and the worker is stopped at 1.3x this")
    parser.add_argument("--out", default=str(HERE / "results" / "fit_benchmark.json"))
    parser.add_argument("--per-test-alpha", action="store_true",
                        help="fit with the damping exponent varying between tests (fit --per-test-alpha)")
    parser.add_argument("--worker", choices=("ours", "peer"), help=argparse.SUPPRESS)
    parser.add_argument("--series-file", help=argparse.SUPPRESS)
    parser.add_argument("--result-file", help=argparse.SUPPRESS)
    args = parser.parse_args()
    runs = [tuple(int(x) for x in item.split(":")) for item in args.peer_runs.split(",")]

    if args.worker == "ours":
        return worker_ours(args.series_file, args.result_file, args.per_test_alpha)
    if args.worker == "peer":
        return worker_peer(args.series_file, args.result_file, runs, args.peer_budget)

    results = []
    with tempfile.TemporaryDirectory(prefix="bench_fit_") as scratch:
        scratch = Path(scratch)
        for n_tests in args.tests:
            config = f"{n_tests} tests"
            start = time.perf_counter()
            series = make_series(n_tests, args.seed)
            simulated = time.perf_counter() - start
            series_file = scratch / f"series{n_tests}.pkl"
            with open(series_file, "wb") as fh:
                pickle.dump(series, fh)
            n_samples = sum(t.n_samples for t in series.periodic_tests)
            _log(f"== {config}: {n_samples} recorded samples, simulated in {simulated:.1f} s")
            del series
            env = dict(os.environ)
            env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
            env["BAYES_SST_CACHE"] = str(scratch / f"jax-cache-{n_tests}")  # empty: the first fit is cold
            res = {"config": config, "n_tests": n_tests, "n_recorded_samples": n_samples, "simulation_s": simulated}
            _log(f"== {config}: bayes_sst fit, cold then warm ...")
            res["ours"] = _spawn(["--worker", "ours", "--series-file", str(series_file)]
                                 + (["--per-test-alpha"] if args.per_test_alpha else []), env,
                                 scratch / f"ours{n_tests}.json", None)
            if args.peer:
                _log(f"== {config}: pymc + nutpie peer ...")
                env_peer = dict(env)
                env_peer["PYTENSOR_FLAGS"] = f"compiledir={scratch / f'pytensor-{n_tests}'}"  # cold compile
                res["peer"] = _spawn(
                    ["--worker", "peer", "--series-file", str(series_file), "--peer-runs", args.peer_runs,
                     "--peer-budget", str(args.peer_budget)],
                    env_peer, scratch / f"peer{n_tests}.json", 1.3 * args.peer_budget + 300,
                )
            results.append(res)
            _log(format_tables([res]))

    table = format_tables(results)
    print(table)
    out = {
        "command": " ".join([Path(sys.executable).name] + sys.argv),
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform(), "python": platform.python_version()},
        "settings": {"spread": SPREAD, "seed": args.seed, "fit": "defaults (4 chains, 300 warm-up + 500 draws)",
                     "peer_runs": runs, "peer_budget_s": args.peer_budget},
        "results": results,
        "table": table,
    }
    try:
        import jax, numpyro  # noqa: E401

        out["versions"] = {"jax": jax.__version__, "numpyro": numpyro.__version__}
        import nutpie, pymc  # noqa: E401

        out["versions"].update({"pymc": pymc.__version__, "nutpie": nutpie.__version__})
    except ImportError:
        pass
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=1, default=float))
    _log(f"wrote {args.out}")


if __name__ == "__main__":
    main()
