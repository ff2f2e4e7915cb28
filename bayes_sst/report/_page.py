"""The report as one self-contained HTML page: figures embedded as PNG data URIs, no scripts
or styles fetched from anywhere, so that it opens offline in any browser.

The page carries one small inline script for automated checks: after loading it records on
<html> how many images there are (data-images) and how many decoded to a non-empty picture
(data-images-loaded). It changes nothing a reader sees.
"""

from __future__ import annotations

import base64
from html import escape

from bayes_sst.reference import DISPLAY_UNITS

_STYLE = """
body { font-family: system-ui, sans-serif; margin: 0 auto; max-width: 1100px; padding: 0 1em 3em; color: #222; }
h1 { margin-bottom: 0.2em; } h2 { border-bottom: 2px solid #ccc; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.5em 0; font-size: 0.92em; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.6em; text-align: right; }
th { background: #f2f2f2; } td.l, th.l { text-align: left; }
.warnings { background: #fde0dd; border: 2px solid #c51b8a; padding: 0.6em 1em; }
.warnings h2 { border: none; margin-top: 0.2em; color: #a50f15; }
.healthy { background: #e5f5e0; border: 2px solid #31a354; padding: 0.6em 1em; }
.healthy h2 { border: none; margin-top: 0.2em; color: #006d2c; }
.fail { color: #a50f15; font-weight: bold; } .pass { color: #006d2c; }
img { max-width: 100%; height: auto; display: block; margin: 0.5em 0; }
nav.tests a { display: inline-block; margin: 0.1em 0.3em; }
.meta td { text-align: left; }
.test { border-top: 1px solid #ddd; padding-top: 0.5em; }
"""

_CHECK_SCRIPT = """
window.addEventListener("load", function () {
  var images = Array.prototype.slice.call(document.images);
  var loaded = images.filter(function (im) { return im.complete && im.naturalWidth > 0; });
  document.documentElement.setAttribute("data-images", String(images.length));
  document.documentElement.setAttribute("data-images-loaded", String(loaded.length));
});
"""


def _img(figures: dict, name: str, alt: str) -> str:
    if name not in figures:  # a report built without figures (numbers only)
        return ""
    data = base64.b64encode(figures[name]).decode("ascii")
    return f'<img src="data:image/png;base64,{data}" alt="{escape(alt)}" data-file="figures/{escape(name)}">'


def _fmt(x, scale=1.0, digits=4) -> str:
    if x is None:
        return "-"
    return f"{x * scale:.{digits}g}"


def _header(data: dict) -> str:
    h = data["header"]
    s = h["sampler"]
    versions = ", ".join(f"{k} {v}" for k, v in h["versions"].items() if v)
    rows = [
        ("series", f"{escape(h['series'])} ({escape(h['series_path'])})"),
        ("tests", str(h["n_tests"])),
        ("samples", f"{h['n_recorded_samples']} recorded, {h['n_steady_samples']} in steady cycles, "
                    f"{h['n_likelihood_samples']} in the likelihood"),
        ("sampler", f"NUTS, {s.get('chains')} chains x ({s.get('warmup')} warm-up + {s.get('draws')} draws), "
                    f"target acceptance {s.get('target_accept')}, maximum tree depth {s.get('max_tree_depth')}"),
        ("seed", str(h["seed"])),
        ("reproduce the run", f"<code>{escape(h['command'] or 'not recorded')}</code>"),
        ("run time", f"{h['run_seconds']:.1f} s" if h["run_seconds"] else "not recorded"),
        ("report", f"{h['report_draws']} posterior draws, seed {h['report_seed']}, built in "
                   f"{data.get('build_seconds', 0):.1f} s"),
        ("versions", escape(versions)),
    ]
    body = "".join(f"<tr><th class='l'>{k}</th><td>{v}</td></tr>" for k, v in rows)
    return (f"<h1>Posterior-predictive check: {escape(h['series'])}</h1>"
            f"<p>Force model F = Me a + Ke u + (Ce |v|<sup>alpha</sup> + Fmu) sign(v), "
            f"run folder <code>{escape(data['run'])}</code>.</p><table class='meta'>{body}</table>")


def _warnings(data: dict) -> str:
    warnings = data["health"]["warnings"]
    if warnings:
        items = "".join(f"<li>{escape(w)}</li>" for w in warnings)
        return (f"<section id='warnings' class='warnings' data-count='{len(warnings)}'>"
                f"<h2>Warnings: do not trust this model before reading these</h2><ul>{items}</ul></section>")
    return ("<section id='warnings' class='healthy' data-count='0'><h2>No warnings</h2>"
            "<p>The sampler passed every check and the model reproduces the measured force within its "
            "predictive bands.</p></section>")


def _health(data: dict, figures: dict) -> str:
    rows = "".join(
        f"<tr><td class='l'>{escape(c['name'])}</td><td>{_fmt(c['value'])}</td><td>{_fmt(c['limit'])}</td>"
        f"<td class='{'pass' if c['ok'] else 'fail'}'>{'pass' if c['ok'] else 'FAIL'}</td></tr>"
        for c in data["health"]["checks"]
    )
    loo = data["health"]["loo"]
    return (
        "<h2 id='health'>Health</h2>"
        "<table><tr><th class='l'>check</th><th>worst value</th><th>limit</th><th>verdict</th></tr>"
        f"{rows}</table>"
        f"<p>PSIS-LOO ({escape(loo['kind'])}): elpd {loo['elpd']:.1f} &plusmn; {loo['se']:.1f} over "
        f"{loo['n_points']} points; {100 * loo['share_k_above_0_7']:.1f} % of points with Pareto k above 0.7 "
        f"(largest {loo['max_k']:.2f}).</p>"
        + _img(figures, "energy.png", "energy plot and E-BFMI")
        + _img(figures, "pareto_k.png", "Pareto k of every measured point")
    )


def _parameters(data: dict, figures: dict) -> str:
    rows = []
    widening = data.get("widening") or {}
    for name, p in data["parameters"].items():
        scale, unit = DISPLAY_UNITS[name]
        factor = widening.get(name, {}).get("factor")
        rows.append(
            f"<tr><td class='l'>{name}</td><td class='l'>{escape(unit)}</td><td>{_fmt(p['mean'], scale)}</td>"
            f"<td>{_fmt(p['sd'], scale, 3)}</td><td>{_fmt(p['q05'], scale)}</td><td>{_fmt(p['q95'], scale)}</td>"
            f"<td>{'-' if factor is None else f'x{factor:.2f}'}</td>"
            f"<td>{_fmt(p['published'], scale)}</td><td>{_fmt(p['classical'], scale)}</td></tr>"
        )
    spread = "".join(
        f"<tr><td class='l'>{name}</td><td>{100 * s['relative_sd_mean']:.2f} %</td>"
        f"<td>{100 * s['relative_sd_q05']:.2f} - {100 * s['relative_sd_q95']:.2f} %</td></tr>"
        for name, s in data["between_test_spread"].items()
    )
    corr = data["correlations"]
    names = corr["names"]
    corr_rows = "".join(
        f"<tr><th>{a}</th>" + "".join(f"<td>{corr['matrix'][i][j]:+.2f}</td>" for j in range(len(names))) + "</tr>"
        for i, a in enumerate(names)
    )
    return (
        "<h2 id='parameters'>Parameters</h2>"
        "<table><tr><th class='l'>parameter</th><th class='l'>unit</th><th>mean</th><th>sd</th><th>5 %</th>"
        "<th>95 %</th><th>widened</th><th>published</th><th>classical</th></tr>" + "".join(rows) + "</table>"
        "<p>Widened: how far the interval was stretched beyond the model's own because the tests, left out "
        "one at a time, scatter more than the model allows (x1.00: not at all; -: a run fitted without "
        "the check). Published: the reference study's point estimates; classical: this series' "
        "hysteresis-loop (symmetric-instant) estimate, when the run recorded one.</p>"
        + _img(figures, "parameters.png", "marginal posterior densities")
        + "<h3>Correlations</h3><table><tr><th></th>" + "".join(f"<th>{n}</th>" for n in names) + "</tr>"
        + corr_rows + "</table>"
        + _img(figures, "pair.png", "pair plot of the population parameters")
        + "<h3>Between-test spread</h3><table><tr><th class='l'>coefficient</th><th>sd / value</th>"
        "<th>90 % interval</th></tr>" + spread + "</table>"
        + _img(figures, "spread.png", "per-test coefficients around the population")
    )


def _tests(data: dict, figures: dict) -> str:
    from bayes_sst.report._build import test_figure_name

    nav = "".join(f"<a href='#test-{escape(t['id'])}'>{escape(t['id'])}</a>" for t in data["tests"])
    parts = [
        "<h2 id='predictive'>Posterior predictive, per test</h2>"
        "<p>Bands: central 50 % and 90 % of the replicated force (model with a posterior draw of the "
        "test's coefficients plus an AR(1) residual draw) at the samples the likelihood sees, after the "
        "low-pass. Dots are measured points that enter the likelihood, crosses those outside the 90 % band. "
        "The velocity-reversal band is not shown: there the force and the regressors are weighted to zero "
        "before the low-pass (the table rests and breaks away, and the force model does not hold), so the "
        "filtered signals near it are the model's view of the test, not the raw recording.</p>"
        f"<nav class='tests'>Tests: {nav}</nav>"
    ]
    for t in data["tests"]:
        issues = "".join(f"<li>{escape(i)}</li>" for i in t["issues"])
        parts.append(
            f"<section class='test' id='test-{escape(t['id'])}'><h3>{escape(t['id'])}: {t['kind']} "
            f"{t['frequency_hz']:g} Hz x {1e3 * t['amplitude_m']:g} mm, payload {t['payload_kg'] / 1e3:g} t</h3>"
            f"<p>{t['n_kept']} of {t['n_points']} points in the likelihood; in the 50 % band "
            f"{100 * t['coverage_50']:.0f} %, in the 90 % band {100 * t['coverage_90']:.0f} %. "
            f"<a href='#predictive'>back to the index</a></p>"
            + (f"<ul class='fail'>{issues}</ul>" if issues else "")
            + _img(figures, test_figure_name(t["id"]), f"test {t['id']}: loops, force, residuals, statistics")
            + "</section>"
        )
    return "".join(parts)


def _calibration(data: dict, figures: dict) -> str:
    from bayes_sst.report._checks import STATISTICS

    c = data["calibration"]
    rows = "".join(
        f"<tr><td class='l'><a href='#test-{escape(t['id'])}'>{escape(t['id'])}</a></td>"
        f"<td>{100 * t['coverage_50']:.0f} %</td><td>{100 * t['coverage_90']:.0f} %</td>"
        + "".join(
            f"<td>{_fmt(t['statistics'][n]['observed'], s, 4)}</td><td>{t['statistics'][n]['p_value']:.3f}</td>"
            for n, (_, _, s) in STATISTICS.items()
        )
        + "</tr>"
        for t in data["tests"]
    )
    head = "".join(f"<th>{label} [{unit}]</th><th>p</th>" for label, unit, _ in STATISTICS.values())
    return (
        "<h2 id='calibration'>Calibration</h2>"
        f"<p>Over all tests, {100 * c['coverage_50']:.1f} % of the measured points lie in the 50 % bands and "
        f"{100 * c['coverage_90']:.1f} % in the 90 % bands; {c['tests_with_coverage_90_in_85_95']} of "
        f"{len(data['tests'])} tests have 85-95 % of their points in the 90 % band.</p>"
        + _img(figures, "coverage.png", "band coverage per test")
        + "<h3>LOO-PIT</h3><p>Leave-one-point-out probability integral transform of each measured point under "
        "the one-step-ahead predictive (the factors of the fit's own AR(1) likelihood). A calibrated model gives "
        "uniform values: the ECDF difference stays inside the envelope. An S shape means the predictive is too "
        "wide (inverse S: too narrow); a shift means a bias.</p>"
        + _img(figures, "loo_pit.png", "LOO-PIT ECDF difference")
        + "<h3>Per-test statistics</h3><p>Posterior-predictive p = P(T(replicated) &ge; T(measured)) for the RMS "
        "force, the peak force, the energy dissipated per cycle (area of the F-u loop) and the phase-locked "
        "residual (largest mean residual over an eighth of the cycle: a force that repeats every cycle and "
        "that the model lacks). Values below 0.005 or above 0.995 (shaded) mark a statistic the model does not "
        "reproduce. Below: per test, the replicated 50 % (dark) and 90 % (light) intervals relative to their "
        "median, with the measured value marked (red when extreme).</p>"
        + _img(figures, "p_values.png", "posterior-predictive p-values per test")
        + _img(figures, "statistics.png", "replicated statistics per test with the measured value marked")
        + "<table><tr><th class='l'>test</th><th>in 50 %</th><th>in 90 %</th>" + head + "</tr>" + rows + "</table>"
    )


def _conclusion(data: dict) -> str:
    items = "".join(f"<li>{escape(s)}</li>" for s in data["conclusion"]["sentences"])
    return f"<h2 id='conclusion'>Conclusion</h2><ul>{items}</ul>"


def render_page(data: dict, figures: dict) -> str:
    """The whole HTML page of a report (report.json's data and the PNG figures by name)."""
    title = escape(f"bayes-sst report: {data['header']['series']}")
    toc = ("<p><a href='#warnings'>warnings</a> | <a href='#health'>health</a> | "
           "<a href='#parameters'>parameters</a> | <a href='#predictive'>posterior predictive</a> | "
           "<a href='#calibration'>calibration</a> | <a href='#conclusion'>conclusion</a></p>")
    body = (_header(data) + toc + _warnings(data) + _health(data, figures) + _parameters(data, figures)
            + _tests(data, figures) + _calibration(data, figures) + _conclusion(data))
    return (f"<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'><title>{title}</title>"
            f"<style>{_STYLE}</style><script>{_CHECK_SCRIPT}</script></head><body>{body}</body></html>\n")
