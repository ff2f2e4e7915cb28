"""The posterior-predictive report: numbers against independent computations, warnings of a
bad run at the top, the command line, and the page rendered by a real (headless) Chromium."""

import json
import re
import shutil
import subprocess
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from bayes_sst.cli import main
from bayes_sst.inference import fit, posterior_predictive, run_prepared
from bayes_sst.inference._summary import format_summary, summarize
from bayes_sst.io import read_run_tree, write_run, write_series
from bayes_sst.report import build_report, loop_energy, peak_force, rms_force, write_report
from bayes_sst.report._checks import thinned_posterior
from bayes_sst.twin import simulate

PLAN = [
    {"kind": "sine", "frequency_hz": 0.5, "amplitude_m": 0.03},
    {"kind": "sine", "frequency_hz": 1.0, "amplitude_m": 0.04},
    {"kind": "sine", "frequency_hz": 1.5, "amplitude_m": 0.02},
    {"kind": "sine", "frequency_hz": 2.0, "amplitude_m": 0.03},
    {"kind": "triangle", "frequency_hz": 1.0, "amplitude_m": 0.04},
]


def _write_fit(series, run_dir, **settings):
    result = fit(series, **settings)
    summary = summarize(result.tree)
    summary["command"] = "test fit"
    write_run(run_dir, result.tree, summary, format_summary(summary))
    return run_dir


@pytest.fixture(scope="module")
def runs():
    """A 5-test virtual-table series (2 % test-to-test spread, the twin's coloured sensor
    noise) fitted properly, and the same series fitted with far too few draws."""
    root = Path(tempfile.mkdtemp(prefix="bayes-sst-report-"))
    series = simulate("sst-paper", seed=11, spread=0.02, plan=PLAN, name="report-test")
    write_series(series, root / "series")
    from bayes_sst.io import load_series

    series = load_series(root / "series")
    good = _write_fit(series, root / "good", chains=2, draws=1000, warmup=400, seed=1)
    bad = _write_fit(series, root / "bad", chains=2, draws=15, warmup=15, seed=2, extensions=0)
    report = build_report(good, draws=300, seed=4)
    write_report(report, root / "report")
    yield {"root": root, "series": series, "good": good, "bad": bad, "report": report}
    shutil.rmtree(root, ignore_errors=True)


def test_loop_energy_of_an_ellipse_is_pi_f0_u0_sin_delta():
    """E = pi*F0*u0*sin(delta) for F = F0 sin(wt + delta), u = u0 sin(wt), with a
    non-whole number of samples per cycle (8.3, as the likelihood's decimation gives)."""
    f, u0, f0, delta = 1.5, 0.03, 40e3, 0.35
    t = np.arange(50) / (8.3 * f) + 0.123
    u = u0 * np.sin(2 * np.pi * f * t)
    force = f0 * np.sin(2 * np.pi * f * t + delta)
    assert loop_energy(t, force, u, f) == pytest.approx(np.pi * f0 * u0 * np.sin(delta), rel=1e-10)
    # leading draw axes are carried through
    both = loop_energy(t, np.stack([force, 2 * force]), u, f)
    assert both == pytest.approx([np.pi * f0 * u0 * np.sin(delta), 2 * np.pi * f0 * u0 * np.sin(delta)])
    assert rms_force(force[:-2]) == pytest.approx(f0 / np.sqrt(2), rel=0.05)
    assert peak_force(-force) == pytest.approx(np.max(np.abs(force)))


def test_loop_energy_with_harmonics_matches_a_dense_trapezoid():
    """A triangle-like displacement (3rd harmonic) and a force with a friction-like 3rd
    harmonic: the Fourier closed form against the trapezoid of F du over a densely sampled cycle."""
    f = 0.75
    def u_of(t):
        w = 2 * np.pi * f * t
        return 0.05 * (np.sin(w) - np.sin(3 * w) / 9)

    def force_of(t):
        w = 2 * np.pi * f * t
        return 30e3 * np.sin(w + 0.2) + 4e3 * np.cos(w) + 2e3 * np.cos(3 * w) + 1e3 * np.sin(3 * w)

    dense = np.linspace(0, 1 / f, 200001)
    u_dense = u_of(dense)
    force_dense = force_of(dense)
    reference = np.sum(0.5 * (force_dense[1:] + force_dense[:-1]) * np.diff(u_dense))
    t = np.arange(40) / (8.0 * f)
    assert loop_energy(t, force_of(t), u_of(t), f) == pytest.approx(reference, rel=1e-6)


def test_too_few_samples_for_the_harmonics_is_a_clear_error():
    with pytest.raises(ValueError, match="cannot resolve 3 harmonics"):
        loop_energy(np.arange(5.0), np.ones(5), np.ones(5), 1.0)


def test_band_coverage_in_report_json_matches_an_independent_recount(runs):
    """Bands rebuilt from the run with the same draws and seed: plain quantiles of the
    replicated force, and at fitted points with a kept predecessor the PSIS leave-one-point-out
    quantiles (one-step AR(1) log-density from scipy, LOO quantiles from ArviZ's
    loo_expectations). ArviZ's weighted-quantile convention differs slightly from the
    report's, so a test may differ by a point or two."""
    from arviz_stats import loo_expectations
    from scipy.stats import norm

    data = runs["report"].data
    tree = read_run_tree(runs["good"])
    prepared = run_prepared(tree)
    posterior = thinned_posterior(tree, 300)
    predictives = posterior_predictive(xr.DataTree.from_dict({"posterior": posterior}), prepared,
                                       n_draws=10**6, seed=4)
    phi = posterior["phi"].values.reshape(-1, len(prepared))
    sigma = posterior["sigma"].values.reshape(-1, len(prepared))
    chains, draws = posterior.sizes["chain"], posterior.sizes["draw"]
    log_lik, where = [], []
    for j, pred in enumerate(predictives):
        for i in np.flatnonzero(pred.keep[1:] & pred.keep[:-1]) + 1:
            centre = pred.mean[:, i] + phi[:, j] * (pred.observed[i - 1] - pred.mean[:, i - 1])
            log_lik.append(norm.logpdf(pred.observed[i], centre, sigma[:, j]))
            where.append((j, i))
    dims = ("chain", "draw", "point")
    paths = np.stack([predictives[j].replicated[:, i] for j, i in where], axis=-1)
    point_tree = xr.DataTree.from_dict({
        "posterior": xr.Dataset({"alpha": posterior["alpha"]}),
        "posterior_predictive": xr.Dataset({"F": (dims, paths.reshape(chains, draws, -1))}),
        "log_likelihood": xr.Dataset({"F": (dims, np.stack(log_lik, axis=-1).reshape(chains, draws, -1))}),
    })
    with warnings.catch_warnings():  # Pareto k > 0.7 on a few points is reported by the health checks
        warnings.simplefilter("ignore", UserWarning)
        quantiles, _ = loo_expectations(point_tree, var_name="F", kind="quantile", probs=[0.05, 0.25, 0.75, 0.95])
    axis = [d for d in quantiles.dims if d != "point"][0]
    loo_q = {q: quantiles.isel({axis: n}).values for n, q in enumerate((0.05, 0.25, 0.75, 0.95))}
    inside90, inside50 = [], []
    for j, (pred, row) in enumerate(zip(predictives, data["tests"])):
        bands = {q: np.quantile(pred.replicated, q, axis=0) for q in (0.05, 0.25, 0.75, 0.95)}
        for k, (jj, i) in enumerate(where):
            if jj == j:
                for q in bands:
                    bands[q][i] = loo_q[q][k]
        y, keep = pred.observed, pred.keep
        in90 = ((y >= bands[0.05]) & (y <= bands[0.95]))[keep]
        in50 = ((y >= bands[0.25]) & (y <= bands[0.75]))[keep]
        inside90.append(in90)
        inside50.append(in50)
        assert abs(row["coverage_90"] - in90.mean()) <= 2.01 / keep.sum(), row["id"]
        assert abs(row["coverage_50"] - in50.mean()) <= 2.01 / keep.sum(), row["id"]
        assert row["n_kept"] == int(keep.sum())
    # the overall figures are the point-weighted per-test ones, each checked above within two
    # points (PSIS-LOO quantiles at a band edge can tip a point either way)
    n_kept = np.array([row["n_kept"] for row in data["tests"]])
    for band in ("coverage_90", "coverage_50"):
        per_test = np.array([row[band] for row in data["tests"]])
        assert data["calibration"][band] == pytest.approx(np.sum(per_test * n_kept) / n_kept.sum(), abs=1e-9)
    assert data["calibration"]["coverage_90"] == pytest.approx(np.concatenate(inside90).mean(), abs=0.015)
    assert data["calibration"]["coverage_50"] == pytest.approx(np.concatenate(inside50).mean(), abs=0.02)
    # the twin's series is what the model describes: its bands must be about honest
    assert 0.85 <= data["calibration"]["coverage_90"] <= 0.97
    assert 0.4 <= data["calibration"]["coverage_50"] <= 0.65


def test_observed_energy_per_cycle_matches_the_recorded_rate_trapezoid(runs):
    """The report's loop area (8 samples a cycle, Fourier closed form) against the
    trapezoid of F du over the steady cycles at the full recorded rate, both of the signals
    the likelihood sees (force and displacement weighted by the reversal weight, then filtered)."""
    from bayes_sst.signals._filters import zero_phase_lowpass

    data = runs["report"].data
    tree = read_run_tree(runs["good"])
    prepared = {t.id: t for t in run_prepared(tree)}
    records = {r.spec.id: r for r in runs["series"].tests}
    for row in data["tests"]:
        test, record = prepared[row["id"]], records[row["id"]]
        fs = record.sample_rate_hz
        weight = test.weight_full
        assert weight is not None and 0.0 < weight.mean() < 1.0  # the default treatment weights reversals out
        force = zero_phase_lowpass(record.F * weight, test.cutoff_hz, fs)[test.window.start : test.window.stop]
        u = zero_phase_lowpass(record.u * weight, test.cutoff_hz, fs)[test.window.start : test.window.stop]
        trapezoid = np.sum(0.5 * (force[1:] + force[:-1]) * np.diff(u)) / test.window.n_cycles
        assert row["statistics"]["energy"]["observed"] == pytest.approx(trapezoid, rel=0.03), row["id"]
        assert row["statistics"]["energy"]["observed"] > 0


def test_report_json_sections_and_healthy_run(runs):
    data = runs["report"].data
    assert data["format"] == "bayes-sst-report/1"
    assert data["header"]["n_tests"] == len(PLAN)
    assert data["header"]["sampler"]["chains"] == 2 and data["header"]["seed"] == 1
    assert data["header"]["command"] == "test fit"
    names = {c["name"] for c in data["health"]["checks"]}
    for needed in ("R-hat (population values)", "bulk ESS (population values)", "tail ESS (population values)",
                   "divergent transitions", "E-BFMI (lowest chain)", "maximum tree depth reached",
                   "PSIS-LOO Pareto k > 0.7 (share of points)"):
        assert needed in names
    failed = [c for c in data["health"]["checks"] if not c["ok"]]
    assert not failed, failed
    truth = runs["series"].extra["truth"]
    run_tree = read_run_tree(runs["good"])
    for name in ("Me", "Ke", "Ce", "alpha", "Fmu"):
        p = data["parameters"][name]
        assert p["q05"] <= p["mean"] <= p["q95"]
        # the page's numbers are the run's posterior, recomputed here from the draws
        draws = run_tree["posterior"][name].values.ravel()
        assert p["mean"] == pytest.approx(draws.mean(), rel=1e-9), name
        # five tests leave Fmu trading off against Ce and alpha: no accuracy target, but
        # the truth must sit within the posterior's reach
        assert abs(p["mean"] - truth[name]) < 4 * draws.std(), name
    for row in data["tests"]:
        for name in ("rms_force", "peak_force", "energy", "phase_residual"):
            assert 0.0 <= row["statistics"][name]["p_value"] <= 1.0
    # five tests are too few to read the tests' scatter from: nothing widened, and the page says so
    assert set(data["widening"]) == {"Me", "Ke", "Ce", "alpha", "Fmu"}
    assert all(w["factor"] == 1.0 for w in data["widening"].values())
    assert "<th>widened</th>" in runs["report"].html and "<td>x1.00</td>" in runs["report"].html
    pit = np.asarray(data["calibration"]["loo_pit"]["values"])
    assert pit.min() >= 0 and pit.max() <= 1 and abs(pit.mean() - 0.5) < 0.1
    assert data["conclusion"]["sentences"]


def test_bad_run_shows_its_warnings_at_the_top(runs, tmp_path):
    report = build_report(runs["bad"], draws=30, seed=0, figures=False)
    warnings = report.data["health"]["warnings"]
    assert any("R-hat" in w for w in warnings), warnings
    assert any("effective sample size" in w for w in warnings), warnings
    html = report.html
    top = html.index("id='warnings'")
    assert top < html.index("id='health'") < html.index("id='parameters'")
    section = html[top : html.index("</section>", top)]
    assert "class='warnings'" in section and "R-hat" in section


def test_cli_writes_refuses_and_replaces(runs, tmp_path, capsys):
    out = tmp_path / "rep"
    assert main(["report", str(runs["good"]), "--out", str(out), "--draws", "100"]) == 0
    assert "90 % bands" in capsys.readouterr().out
    files = {p.name for p in (out / "figures").iterdir()}
    assert {"parameters.png", "pair.png", "loo_pit.png", "coverage.png"} <= files
    assert len([f for f in files if f.startswith("test_")]) == len(PLAN)
    data = json.loads((out / "report.json").read_text())
    assert set(data["figures"]) == files
    html = (out / "report.html").read_text()
    assert html.count("<img ") == len(files)
    assert not re.search(r"(src|href)=['\"]https?:", html)  # nothing fetched from a network
    assert main(["report", str(runs["good"]), "--out", str(out)]) == 2
    assert "already exists" in capsys.readouterr().err
    write_report(runs["report"], out, overwrite=True)  # what --force does, without a rebuild
    assert json.loads((out / "report.json").read_text())["header"]["report_draws"] == 300
    assert main(["report", str(tmp_path / "missing"), "--out", str(tmp_path / "x")]) == 2
    assert "not a run folder" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def _chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


@pytest.mark.skipif(_chromium() is None, reason="Chromium is not installed")
def test_page_renders_in_headless_chromium_with_every_figure(runs, tmp_path):
    """Chromium loads the page from disk (no network), runs its check script, and the DOM it
    dumps says every <img> decoded to a non-empty picture."""
    page = runs["root"] / "report" / "report.html"
    command = [
        _chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync",
        f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=15000", "--dump-dom", page.as_uri(),
    ]
    dom = subprocess.run(command, capture_output=True, text=True, timeout=120).stdout
    images = re.search(r'data-images="(\d+)"', dom)
    loaded = re.search(r'data-images-loaded="(\d+)"', dom)
    assert images and loaded, dom[:500]
    n_figures = len(runs["report"].figures)
    assert int(images.group(1)) == n_figures == 9 + len(PLAN)
    assert int(loaded.group(1)) == n_figures
    assert 'id="warnings"' in dom or "id='warnings'" in dom


@pytest.mark.slow
def test_series_with_an_effect_the_model_lacks_shows_warnings_at_the_top(tmp_path):
    """A hardening strut, k3*u^3 with k3 = 5e7 N/m^3 (50 kN at 0.1 m), added to the recorded
    force of large-stroke twin tests: the per-test coefficients absorb its fundamental, the
    residual model its third harmonic, and the report must say so at the top."""
    from bayes_sst.io import load_series

    plan = [
        {"kind": "sine", "frequency_hz": 0.5, "amplitude_m": 0.08},
        {"kind": "sine", "frequency_hz": 0.75, "amplitude_m": 0.1},
        {"kind": "sine", "frequency_hz": 1.0, "amplitude_m": 0.08},
        {"kind": "triangle", "frequency_hz": 0.5, "amplitude_m": 0.09},
        {"kind": "sine", "frequency_hz": 1.0, "amplitude_m": 0.04},
        {"kind": "sine", "frequency_hz": 2.0, "amplitude_m": 0.03},
    ]
    series = simulate("sst-paper", seed=5, spread=0.02, plan=plan)
    tests = []
    for record in series.tests:
        columns = dict(record.columns)
        columns["F"] = columns["F"] + 5e7 * columns["u"] ** 3
        tests.append(type(record)(spec=record.spec, columns=columns))
    from dataclasses import replace

    write_series(replace(series, tests=tuple(tests)), tmp_path / "series")
    run = _write_fit(load_series(tmp_path / "series"), tmp_path / "run", chains=2, draws=500, warmup=400, seed=1)
    report = build_report(run, figures=False)
    warnings_ = report.data["health"]["warnings"]
    assert any("fit poorly" in w for w in warnings_), warnings_
    assert len(report.data["conclusion"]["tests_fitting_poorly"]) >= 2
    html = report.html
    assert html.index("id='warnings'") < html.index("id='health'")
    assert "fit poorly" in html[html.index("id='warnings'") : html.index("id='health'")]


def test_sampler_checks_leave_out_a_coefficient_shared_by_all_tests():
    """With Me shared its between-test sd is 0 in every draw: the report's R-hat and ESS checks
    must skip it (not divide by its zero variance) and still judge the other spreads."""
    from dataclasses import replace

    from bayes_sst.inference._priors import make_priors
    from bayes_sst.report._health import sampler_checks

    plan = [{"kind": "sine", "frequency_hz": f, "amplitude_m": a} for f, a in ((0.5, 0.06), (1.0, 0.04), (2.0, 0.02))]
    series = simulate("sst-paper", seed=8, spread=0.02, plan=plan)
    result = fit(series, chains=2, draws=200, warmup=200, seed=2, prior=replace(make_priors("generic"), shared=("Me",)))
    assert float(result.tree["posterior"]["between_test_sd"].sel(coefficient="Me").max()) == 0.0
    checks = {c.name: c for c in sampler_checks(result.tree)}
    rhat_check = checks["R-hat (population values)"]
    assert np.isfinite(rhat_check.value) and rhat_check.value < 1.1
    assert np.isfinite(checks["bulk ESS (population values)"].value)
