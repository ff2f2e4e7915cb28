"""build_report(run) -> Report: every number and figure of the posterior-predictive report.

The report never computes a posterior: it reads the run folder (posterior.nc, summary.json),
re-prepares the run's series exactly as the fit did (bayes_sst.inference.run_prepared) and
draws posterior-predictive replications from the stored draws.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bayes_sst.io import read_run_tree
from bayes_sst.inference._summary import POPULATION
from bayes_sst.reference import PUBLISHED_SST
from bayes_sst.report import _checks, _figures, _health

REPORT_FORMAT = "bayes-sst-report/1"
DEFAULT_DRAWS = 400
# overall share of kept measured points inside the 90 % bands outside this range fails
COVERAGE_RANGE = (0.85, 0.97)
# a test whose 90 % band holds fewer of its points than this fits poorly (about 40 kept
# points per test: 3 binomial sd below 90 %)
TEST_COVERAGE_MIN = 0.75
# more tests than this share fitting poorly is a warning at the top; fewer are named in the
# conclusion only (a healthy 20-test run flags about one test by chance: 4 statistics at 1 %
# two-sided and the 75 % coverage floor)
POOR_TESTS_SHARE = 0.10
# relative posterior sd (sd / |mean|) below which a parameter counts as well identified
WELL_IDENTIFIED = 0.03
POORLY_IDENTIFIED = 0.15


@dataclass
class Report:
    """What `write_report` writes: report.json's content, PNG figures by file name, the page."""

    data: dict
    figures: dict[str, bytes] = field(default_factory=dict)
    html: str = ""


def _versions() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for name in ("bayes_sst", "numpy", "scipy", "jax", "numpyro", "arviz", "arviz-stats", "arviz-plots",
                 "xarray", "matplotlib"):
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = None
    return out


def _run_summary(run: Path) -> dict:
    from bayes_sst.io import read_run_summary

    try:
        return read_run_summary(run)
    except ValueError:
        return {}


def _parameters(posterior, classical) -> dict:
    out = {}
    for name in POPULATION:
        x = posterior[name].values.ravel()
        q05, q25, q50, q75, q95 = np.quantile(x, [0.05, 0.25, 0.5, 0.75, 0.95])
        mean, sd = float(x.mean()), float(x.std(ddof=1))
        out[name] = {
            "mean": mean, "sd": sd, "q05": float(q05), "q25": float(q25), "q50": float(q50),
            "q75": float(q75), "q95": float(q95), "relative_sd": sd / abs(mean) if mean else None,
            "published": PUBLISHED_SST.get(name),
            "classical": (classical or {}).get(name),
            "unit": {"Me": "kg", "Ke": "N/m", "Ce": "N/(m/s)^alpha", "alpha": "1", "Fmu": "N"}[name],
        }
    return out


def _correlations(posterior) -> dict:
    matrix = np.corrcoef(np.stack([posterior[name].values.ravel() for name in POPULATION]))
    return {"names": list(POPULATION), "matrix": matrix.tolist()}


def _test_issues(check: _checks.TestCheck) -> list[str]:
    """Plain words for what is wrong with one test's fit (empty when nothing is)."""
    issues = []
    if check.coverage[0.9] < TEST_COVERAGE_MIN:
        issues.append(f"only {100 * check.coverage[0.9]:.0f} % of its kept points lie in the 90 % band")
    for name, (label, unit, scale) in _checks.STATISTICS.items():
        s = check.statistics[name]
        p = s["p_value"]
        # a phase-locked residual smaller than replicated only says the fit is close: one-sided
        one_sided = name == "phase_residual"
        if p < _checks.P_EXTREME or (not one_sided and p > 1 - _checks.P_EXTREME):
            side = "larger" if p < 0.5 else "smaller"
            issues.append(
                f"measured {label} {s['observed'] * scale:.3g} {unit} is {side} than "
                f"{100 * max(1 - p, p):.1f} % of the replications (p = {p:.3f})"
            )
    return issues


def _percent(x) -> str:
    return "undefined" if x is None else f"{100 * x:.0f} %"


def _conclusion(parameters: dict, correlations: dict, tests: list[dict]) -> dict:
    well, moderate, poor = [], [], []
    for name, p in parameters.items():
        r = p["relative_sd"] if p["relative_sd"] is not None else float("inf")
        (well if r < WELL_IDENTIFIED else poor if r > POORLY_IDENTIFIED else moderate).append(name)
    names = correlations["names"]
    matrix = np.asarray(correlations["matrix"])
    strong = [
        (names[i], names[j], float(matrix[i, j]))
        for i in range(len(names)) for j in range(i + 1, len(names)) if abs(matrix[i, j]) >= 0.5
    ]
    sentences = []
    if well:
        sentences.append(
            "Well identified (posterior sd under 3 % of the value): "
            + ", ".join(f"{n} ({100 * parameters[n]['relative_sd']:.1f} %)" for n in well) + "."
        )
    if moderate:
        sentences.append(
            "Moderately identified (sd 3-15 %): "
            + ", ".join(f"{n} ({100 * parameters[n]['relative_sd']:.1f} %)" for n in moderate) + "."
        )
    if poor:
        sentences.append(
            "Poorly identified (sd over 15 %): "
            + ", ".join(f"{n} ({_percent(parameters[n]['relative_sd'])})" for n in poor)
            + "; these tests do not pin them down."
        )
    for a, b, r in strong:
        sentences.append(
            f"{a} and {b} are correlated (r = {r:+.2f}): the data constrain a combination of them better than "
            "either alone, so quote them together."
        )
    bad = [t for t in tests if t["issues"]]
    if bad:
        for t in bad:
            sentences.append(f"Test {t['id']} fits poorly: " + "; ".join(t["issues"]) + ".")
    else:
        sentences.append("Every test is reproduced by the model within its predictive bands.")
    return {"well_identified": well, "moderately_identified": moderate, "poorly_identified": poor,
            "strong_correlations": [{"a": a, "b": b, "r": r} for a, b, r in strong],
            "tests_fitting_poorly": [t["id"] for t in bad], "sentences": sentences}


def build_report(run, *, draws: int = DEFAULT_DRAWS, seed: int = 0, series=None, figures: bool = True) -> Report:
    """All numbers (report.json) and figures of the report of run folder `run`.

    draws : posterior draws (thinned evenly over each chain) used for bands, statistics and LOO.
    series : the run's Series, when the folder it recorded has moved; else it is read again.
    figures : False skips the figures (numbers and a page without pictures, for tests and benchmarks).
    """
    import xarray as xr

    from bayes_sst.inference import posterior_predictive, run_prepared
    started = time.perf_counter()
    cpu_started = time.process_time()
    timings: dict[str, float] = {}
    run = Path(run)
    tree = read_run_tree(run)
    summary = _run_summary(run)
    prepared = run_prepared(tree, series)
    timings["read and prepare"] = time.perf_counter() - started
    posterior_all = tree["posterior"].to_dataset()
    posterior = _checks.thinned_posterior(tree, draws)
    predictives = posterior_predictive(xr.DataTree.from_dict({"posterior": posterior}), prepared,
                                       n_draws=posterior.sizes["chain"] * posterior.sizes["draw"], seed=seed)
    loo = _checks.point_loo(predictives, posterior, seed=seed)
    checks = []
    for j, (p, t) in enumerate(zip(predictives, prepared)):
        mine = loo.test_index == j
        overrides = (loo.sample_index[mine], {q: v[mine] for q, v in loo.band_quantiles.items()})
        checks.append(_checks.check_test(p, t, overrides))
    timings["posterior predictive and LOO"] = time.perf_counter() - started - timings["read and prepare"]

    labels = [f"{checks[j].test_id} t={checks[j].t[i]:.2f} s" for j, i in zip(loo.test_index, loo.sample_index)]
    health = _health.sampler_checks(tree) + [_health.loo_check(loo.pareto_k, labels)]

    kept_inside = {prob: [] for prob in _checks.BAND_PROBS}
    for c in checks:
        low_high = {prob: c.bands[prob] for prob in _checks.BAND_PROBS}
        for prob, (low, high) in low_high.items():
            kept_inside[prob].append(((c.observed >= low) & (c.observed <= high))[c.keep])
    overall = {prob: float(np.concatenate(v).mean()) for prob, v in kept_inside.items()}
    tests = []
    for j, (c, t) in enumerate(zip(checks, prepared)):
        mine = loo.test_index == j
        tests.append({
            "id": c.test_id, "kind": c.kind, "frequency_hz": c.frequency_hz, "amplitude_m": c.amplitude_m,
            "payload_kg": t.payload_kg, "n_points": int(len(c.t)), "n_kept": int(c.keep.sum()),
            "coverage_50": c.coverage[0.5], "coverage_90": c.coverage[0.9],
            "coverage_50_all_samples": c.coverage_all[0.5], "coverage_90_all_samples": c.coverage_all[0.9],
            "statistics": {
                name: {"observed": s["observed"], "p_value": s["p_value"],
                       "replicated_mean": float(np.mean(s["replicated"])),
                       "replicated_q05": float(np.quantile(s["replicated"], 0.05)),
                       "replicated_q95": float(np.quantile(s["replicated"], 0.95))}
                for name, s in c.statistics.items()
            },
            "loo_pit_mean": float(loo.pit[mine].mean()) if mine.any() else None,
            "max_pareto_k": float(loo.pareto_k[mine].max()) if mine.any() else None,
            "issues": _test_issues(c),
        })
    in90 = [t["coverage_90"] for t in tests]
    calibration_checks = [
        _health.Check("share of kept points in the 90 % bands", overall[0.9], COVERAGE_RANGE[0],
                      COVERAGE_RANGE[0] <= overall[0.9] <= COVERAGE_RANGE[1],
                      f"{100 * overall[0.9]:.1f} % of the measured points lie inside the 90 % predictive bands "
                      f"(expected {100 * COVERAGE_RANGE[0]:.0f}-{100 * COVERAGE_RANGE[1]:.0f} %): the model "
                      + ("misses part of the force; the intervals are too narrow to be believed."
                         if overall[0.9] < COVERAGE_RANGE[0] else
                         "over-states the noise, so the bands are too wide; usually the residual model has "
                         "absorbed a systematic force (an effect the model lacks) or outliers as noise.")),
    ]
    poor = [t["id"] for t in tests if t["issues"]]
    share_poor = len(poor) / max(len(tests), 1)
    # a healthy run flags about one test in twenty by chance, so one flagged test alone is
    # never a warning, whatever the number of tests (it is named in the conclusion)
    allowed_poor = max(1, int(POOR_TESTS_SHARE * len(tests)))
    calibration_checks.append(_health.Check(
        "share of tests that fit poorly", share_poor, allowed_poor / max(len(tests), 1), len(poor) <= allowed_poor,
        f"{len(poor)} of {len(tests)} tests fit poorly ({', '.join(poor[:8])}{' ...' if len(poor) > 8 else ''}): "
        "the model misses an effect present in these tests; see the conclusion and their panels."))
    all_checks = health + calibration_checks
    warnings = [c.message for c in all_checks if not c.ok]

    parameters = _parameters(posterior_all, summary.get("classical"))
    correlations = _correlations(posterior_all)
    from bayes_sst.inference._summary import summarize

    run_numbers = summarize(tree)
    sampler = json.loads(tree.attrs.get("sampler", "{}") or "{}")
    test_loo = None
    try:
        import warnings as _warnings

        from arviz_stats import loo as _loo

        with _warnings.catch_warnings():
            _warnings.simplefilter("ignore", UserWarning)
            test_loo = [float(k) for k in _loo(tree, pointwise=True, var_name="F").pareto_k.values]
    except (ValueError, KeyError, TypeError):
        test_loo = None
    data = {
        "format": REPORT_FORMAT,
        "run": str(run),
        "header": {
            "series": tree.attrs.get("series", ""),
            "series_path": tree.attrs.get("series_path", ""),
            "n_tests": len(prepared),
            "n_recorded_samples": run_numbers["n_samples"],
            "n_steady_samples": run_numbers["n_steady_samples"],
            "n_likelihood_samples": run_numbers["n_likelihood_samples"],
            "sampler": sampler,
            "seed": sampler.get("seed"),
            "signal_options": json.loads(tree.attrs.get("signal_options", "{}") or "{}"),
            "priors": json.loads(tree.attrs.get("priors", "{}") or "{}"),
            "command": summary.get("command"),
            "run_seconds": summary.get("seconds"),
            "versions": _versions(),
            "run_bayes_sst_version": tree.attrs.get("bayes_sst_version"),
            "report_draws": int(posterior.sizes["chain"] * posterior.sizes["draw"]),
            "report_seed": seed,
        },
        "health": {
            "checks": [c.to_json() for c in all_checks],
            "warnings": warnings,
            "loo": {
                "kind": "leave-one-point-out, one-step-ahead predictive of each kept point given its kept predecessor",
                "elpd": loo.elpd, "se": loo.elpd_se, "n_points": int(len(loo.pit)), "good_k": loo.good_k,
                "share_k_above_0_7": float(np.mean(loo.pareto_k > _health.PARETO_K_LIMIT)),
                "max_k": float(loo.pareto_k.max()),
                "leave_one_test_out_pareto_k": test_loo,
            },
        },
        "parameters": parameters,
        "correlations": correlations,
        "between_test_spread": run_numbers["between_test_spread"],
        # each population interval's stretch by the tests' jackknife ({} for runs fitted without it)
        "widening": run_numbers.get("widening", {}),
        "calibration": {
            "coverage_50": overall[0.5],
            "coverage_90": overall[0.9],
            "tests_with_coverage_90_in_85_95": int(sum(0.85 <= x <= 0.95 for x in in90)),
            "loo_pit": {"values": loo.pit.tolist(), "test_index": loo.test_index.tolist(),
                        "mean": float(loo.pit.mean()), "sd": float(loo.pit.std()),
                        "uniform_sd": float(np.sqrt(1 / 12))},
        },
        "tests": tests,
        "conclusion": _conclusion(parameters, correlations, tests),
        "timings": timings,
    }
    report = Report(data=data)
    timings["numbers"] = time.perf_counter() - started
    if figures:
        report.figures = _draw(tree, posterior_all, parameters, checks, loo, summary, timings)
    data["figures"] = sorted(report.figures)
    from bayes_sst.report._page import render_page

    data["build_seconds"] = time.perf_counter() - started
    data["build_cpu_seconds"] = time.process_time() - cpu_started
    report.html = render_page(data, report.figures)
    return report


def _draw(tree, posterior, parameters, checks, loo, summary, timings) -> dict[str, bytes]:
    display = _figures.display_posterior(posterior)
    classical = summary.get("classical")
    jobs = {
        "parameters.png": lambda: _figures.parameter_densities(display, PUBLISHED_SST, classical),
        "pair.png": lambda: _figures.pair_plot(display),
        "spread.png": lambda: _figures.spread_figure(posterior, [c.test_id for c in checks]),
        "energy.png": lambda: _figures.energy_plot(tree),
        "pareto_k.png": lambda: _figures.khat_plot(loo.elpd_data),
        "loo_pit.png": lambda: _figures.loo_pit_plot(loo.pit),
        "coverage.png": lambda: _figures.coverage_figure(checks),
        "p_values.png": lambda: _figures.p_value_figure(checks, _checks.STATISTICS),
        "statistics.png": lambda: _figures.statistics_figure(checks, _checks.STATISTICS),
    }
    figures = {}
    for name, job in jobs.items():
        start = time.perf_counter()
        figures[name] = job()
        timings[f"figure {name}"] = time.perf_counter() - start
    start = time.perf_counter()
    painter = _figures.TestFigures()
    try:
        for c in checks:
            figures[test_figure_name(c.test_id)] = painter.draw(c)
    finally:
        painter.close()
    timings["figures of the tests"] = time.perf_counter() - start
    return figures


def _safe(name: str) -> str:
    """A test id as a file-name part: letters, digits, '-' and '_' kept, the rest '_'."""
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in name)


FIGURE_ID_CHARS = 60


def test_figure_name(test_id: str) -> str:
    """figures/test_<id>.png; an id that had to be changed or shortened to be a file name gets
    a digest of itself too, so that ids such as 'S 13' and 'S_13' (or two long ids with one
    beginning) never share a figure, and the name stays within the file system's limit."""
    safe = _safe(test_id)
    if safe == test_id and len(safe) <= FIGURE_ID_CHARS:
        return f"test_{safe}.png"
    digest = hashlib.sha1(test_id.encode("utf-8")).hexdigest()[:10]
    return f"test_{safe[:FIGURE_ID_CHARS]}-{digest}.png"


def write_report(report: Report, out, *, overwrite: bool = False) -> Path:
    """report.html, report.json and figures/*.png into `out`, atomically (all or nothing)."""
    from bayes_sst.io import atomic_output_dir, write_json_atomic

    with atomic_output_dir(out, overwrite=overwrite) as tmp:
        (tmp / "figures").mkdir()
        for name, content in report.figures.items():
            (tmp / "figures" / name).write_bytes(content)
        write_json_atomic(tmp / "report.json", report.data)
        (tmp / "report.html").write_text(report.html, encoding="utf-8")
    return Path(out)
