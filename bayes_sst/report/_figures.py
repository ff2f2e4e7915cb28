"""The report's figures, each returned as PNG bytes.

ArviZ draws what it already knows (marginal densities, the pair plot, the energy plot,
Pareto k, LOO-PIT); the shaking-table figures (hysteresis loops with predictive bands,
residuals against time, cycle phase and velocity, per-test statistics) are drawn here with
matplotlib. Display units: t, kN, kN/m, kJ; the numbers in report.json stay SI.
"""

from __future__ import annotations

import io

import numpy as np

from bayes_sst.reference import DISPLAY_UNITS

DPI = 80
# zlib level 1: files about 5 % larger than the default level, encoded in half the time
PNG_COMPRESSION = 1
COLOURS = {"band90": "#c6dbef", "band50": "#6baed6", "mean": "#08519c", "inside": "#252525",
           "outside": "#d62728", "published": "#2ca02c", "classical": "#ff7f0e"}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=False)  # files only; no display is needed or wanted
    import matplotlib.pyplot as plt

    return plt


def png(fig, dpi: int = DPI) -> bytes:
    """The figure as PNG bytes; the figure is closed (many figures are drawn in one process)."""
    plt = _pyplot()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi, pil_kwargs={"compress_level": PNG_COMPRESSION})
    plt.close(fig)
    return buffer.getvalue()


def display_posterior(posterior, names=("Me", "Ke", "Ce", "alpha", "Fmu")):
    """Population parameters scaled to display units (t, kN/m, ...), one variable each."""
    import xarray as xr

    return xr.Dataset({name: posterior[name] * DISPLAY_UNITS[name][0] for name in names})


def parameter_densities(display, published: dict, classical: dict | None) -> bytes:
    """ArviZ marginal densities with 90 % intervals; published and classical values marked."""
    import arviz_plots as azp
    import xarray as xr

    names = list(display.data_vars)
    pc = azp.plot_dist(xr.DataTree.from_dict({"posterior": display}), var_names=names, backend="matplotlib",
                       ci_prob=0.9, col_wrap=3)
    fig = pc.get_viz("figure")
    fig.set_size_inches(11.0, 6.0)
    fig.subplots_adjust(hspace=0.55, wspace=0.25)
    for name in names:
        ax = pc.get_target(name, {})
        scale, unit = DISPLAY_UNITS[name]
        if published.get(name) is not None:
            ax.axvline(published[name] * scale, color=COLOURS["published"], ls="--", lw=1.5, label="published")
        if classical and classical.get(name) is not None:
            ax.axvline(classical[name] * scale, color=COLOURS["classical"], ls=":", lw=1.5, label="classical")
        ax.set_xlabel(f"{name} [{unit}]")
    first = pc.get_target(names[0], {})
    if first.get_legend_handles_labels()[1]:
        first.legend(loc="upper left", fontsize=8, frameon=False)
    return png(fig)


def pair_plot(display, max_points: int = 400) -> bytes:
    """ArviZ pair plot of the population parameters (Ce with alpha shows their trade-off)."""
    import arviz_plots as azp
    import xarray as xr

    draws = display.sizes["draw"]
    per_chain = max(1, max_points // max(display.sizes["chain"], 1))
    thin = display.isel(draw=np.unique(np.linspace(0, draws - 1, min(draws, per_chain)).round().astype(int)))
    pm = azp.plot_pair(xr.DataTree.from_dict({"posterior": thin}), var_names=list(display.data_vars),
                       backend="matplotlib", visuals={"scatter": {"alpha": 0.3}})
    fig = pm.get_viz("figure")
    fig.set_size_inches(9.0, 8.0)
    fig.suptitle("population values in t, kN/m, kN/(m/s)^alpha, -, kN", fontsize=10)
    return png(fig)


def spread_figure(posterior, test_ids, coefficients=("Me", "Ke", "Ce", "Fmu")) -> bytes:
    """Per-test coefficients (mean, 90 % interval) around the population mean +- between-test sd."""
    plt = _pyplot()
    fig, axes = plt.subplots(len(coefficients), 1, figsize=(max(6.0, 0.35 * len(test_ids) + 2), 2.0 * len(coefficients)),
                             sharex=True)
    x = np.arange(len(test_ids))
    for k, (ax, name) in enumerate(zip(np.atleast_1d(axes), coefficients)):
        scale, unit = DISPLAY_UNITS[name]
        per_test = posterior[f"{name}_test"].values.reshape(-1, len(test_ids)) * scale
        mu = float(posterior[name].values.mean()) * scale
        tau = float(posterior["between_test_sd"].isel(coefficient=k).values.mean()) * scale
        low, high = np.quantile(per_test, [0.05, 0.95], axis=0)
        ax.axhspan(mu - tau, mu + tau, color=COLOURS["band90"], label="population mean +- between-test sd")
        ax.axhline(mu, color=COLOURS["mean"], lw=1)
        ax.errorbar(x, per_test.mean(axis=0), yerr=[per_test.mean(axis=0) - low, high - per_test.mean(axis=0)],
                    fmt="o", ms=3, color="k", lw=1, label="test (mean, 90 %)")
        ax.set_ylabel(f"{name} [{unit}]")
    np.atleast_1d(axes)[0].legend(fontsize=7, loc="upper right", frameon=False, ncol=2)
    ax.set_xticks(x, test_ids, rotation=90, fontsize=7)
    fig.tight_layout()
    return png(fig)


def energy_plot(tree) -> bytes:
    """ArviZ energy plot (marginal and transition energy) with E-BFMI per chain."""
    import arviz_plots as azp

    pc = azp.plot_energy(tree, backend="matplotlib")
    return png(pc.get_viz("figure"))


def khat_plot(elpd) -> bytes:
    """ArviZ Pareto k of the point-wise PSIS-LOO."""
    import arviz_plots as azp

    pc = azp.plot_khat(elpd, backend="matplotlib")
    return png(pc.get_viz("figure"))


def loo_pit_plot(pit) -> bytes:
    """ArviZ Delta-ECDF of the LOO-PIT values with its uniformity test (PIT given, not recomputed)."""
    import arviz_plots as azp
    import xarray as xr

    dt = xr.DataTree.from_dict({"loo_pit": xr.Dataset({"LOO_PIT": (("point",), np.asarray(pit))})})
    pc = azp.plot_ecdf_pit(dt, group="loo_pit", sample_dims=["point"], backend="matplotlib")
    return png(pc.get_viz("figure"))


def coverage_figure(checks) -> bytes:
    """Share of kept measured points inside the 50 % and 90 % bands, per test."""
    plt = _pyplot()
    ids = [c.test_id for c in checks]
    x = np.arange(len(ids))
    fig, ax = plt.subplots(figsize=(max(6.0, 0.35 * len(ids) + 2), 3.0))
    ax.bar(x - 0.2, [100 * c.coverage[0.5] for c in checks], 0.4, color=COLOURS["band50"], label="in 50 % band")
    ax.bar(x + 0.2, [100 * c.coverage[0.9] for c in checks], 0.4, color=COLOURS["band90"], label="in 90 % band",
           edgecolor=COLOURS["mean"])
    for target in (50, 90):
        ax.axhline(target, color="k", ls="--", lw=0.8)
    ax.set_xticks(x, ids, rotation=90, fontsize=7)
    ax.set_ylabel("measured points inside [%]")
    ax.set_ylim(0, 105)
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    return png(fig)


def p_value_figure(checks, statistics: dict) -> bytes:
    """Posterior-predictive p-values of the per-test statistics, per test."""
    plt = _pyplot()
    ids = [c.test_id for c in checks]
    x = np.arange(len(ids))
    fig, ax = plt.subplots(figsize=(max(6.0, 0.35 * len(ids) + 2), 3.0))
    for k, (name, (label, _, _)) in enumerate(statistics.items()):
        ax.plot(x + (k - 1.5) * 0.18, [c.statistics[name]["p_value"] for c in checks], "o", ms=4, label=label)
    ax.axhspan(0, 0.005, color="#fdd0a2")
    ax.axhspan(0.995, 1, color="#fdd0a2")
    ax.set_ylim(-0.02, 1.02)
    ax.set_xticks(x, ids, rotation=90, fontsize=7)
    ax.set_ylabel("P(T_rep >= T_obs)")
    ax.legend(fontsize=7, ncol=4, loc="upper center", bbox_to_anchor=(0.5, 1.18), frameon=False)
    fig.tight_layout()
    return png(fig)


def statistics_figure(checks, statistics: dict) -> bytes:
    """Per test and statistic: the replicated 50 % and 90 % intervals with the measured value
    marked, all relative to the replicated median (per cent), so tests of any size share an axis."""
    plt = _pyplot()
    ids = [c.test_id for c in checks]
    x = np.arange(len(ids))
    fig, axes = plt.subplots(len(statistics), 1, figsize=(max(6.0, 0.35 * len(ids) + 2), 2.2 * len(statistics)),
                             sharex=True)
    for ax, (name, (label, _, _)) in zip(np.atleast_1d(axes), statistics.items()):
        rel = []
        for c in checks:
            s = c.statistics[name]
            median = np.median(s["replicated"])
            scale = 100.0 / abs(median) if median else 0.0
            q = (np.quantile(s["replicated"], [0.05, 0.25, 0.75, 0.95]) - median) * scale
            rel.append((q, (s["observed"] - median) * scale, s["p_value"]))
        ax.vlines(x, [r[0][0] for r in rel], [r[0][3] for r in rel], color=COLOURS["band90"], lw=6)
        ax.vlines(x, [r[0][1] for r in rel], [r[0][2] for r in rel], color=COLOURS["band50"], lw=6)
        extreme = np.array([min(r[2], 1 - r[2]) < 0.005 for r in rel])
        obs = np.array([r[1] for r in rel])
        ax.plot(x[~extreme], obs[~extreme], "D", color=COLOURS["inside"], ms=4)
        ax.plot(x[extreme], obs[extreme], "D", color=COLOURS["outside"], ms=6)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylabel(f"{label}\nvs replicated median [%]", fontsize=8)
    ax.set_xticks(x, ids, rotation=90, fontsize=7)
    fig.subplots_adjust(left=0.1, right=0.98, top=0.97, bottom=0.12, hspace=0.1)
    return png(fig)


class TestFigures:
    """Draws the 2x3 panel figure of each test on one reused figure.

    Panels: loops F-u and F-v and F(t) with 50/90 % bands; residuals against time, cycle
    phase and velocity with the 90 % predictive half-width. Creating a matplotlib figure
    with six axes costs more than drawing into it, so the axes are made once and only their
    data artists are replaced from test to test.
    """

    __test__ = False

    def __init__(self):
        plt = _pyplot()
        self.fig, self.axes = plt.subplots(2, 3, figsize=(12.0, 6.6))
        labels = (("displacement u [mm]", "force F [kN]", "loop F-u"),
                  ("velocity v [mm/s]", "", "loop F-v"),
                  ("time t [s]", "", "force against time (bands 50 %, 90 %)"),
                  ("time t [s]", "residual F - model [kN]", "residuals (bars: 90 % predictive)"),
                  ("cycle phase [cycles]", "", ""),
                  ("velocity v [mm/s]", "", ""))
        from matplotlib.ticker import MaxNLocator

        for ax, (xlabel, ylabel, title) in zip(self.axes.ravel(), labels):
            # fewer tick labels: text layout is most of the drawing time of 20-odd figures
            ax.xaxis.set_major_locator(MaxNLocator(5))
            ax.yaxis.set_major_locator(MaxNLocator(5))
            ax.set_xlabel(xlabel)
            ax.set_ylabel(ylabel)
            ax.set_title(title, fontsize=10)
        self.suptitle = self.fig.suptitle("", fontsize=9)
        self.fig.subplots_adjust(left=0.06, right=0.99, top=0.91, bottom=0.08, wspace=0.22, hspace=0.32)

    def close(self):
        _pyplot().close(self.fig)

    def draw(self, check) -> bytes:
        kN = 1e-3
        axes = self.axes
        for ax in axes.ravel():
            for artist in list(ax.lines) + list(ax.collections):
                artist.remove()
        # only the fitted samples: inside the reversal band the force and the regressors are
        # weighted out before filtering (signals.reversal_weight), so there is nothing to show
        kept = check.keep
        bands = {prob: tuple(b[kept] for b in check.bands[prob]) for prob in check.bands}
        t, phase, observed, mean = check.t[kept], check.phase[kept], check.observed[kept], check.mean[kept]
        u_mm, v_mm = check.u[kept] * 1e3, check.v[kept] * 1e3
        low90, high90 = bands[0.9]
        outside = (observed < low90) | (observed > high90)
        for ax, x, loop in ((axes[0, 0], u_mm, True), (axes[0, 1], v_mm, True), (axes[0, 2], t, False)):
            for prob, colour, width in ((0.9, COLOURS["band90"], 4), (0.5, COLOURS["band50"], 2)):
                ax.vlines(x, bands[prob][0] * kN, bands[prob][1] * kN, color=colour, lw=width, zorder=1)
            if loop:
                ax.plot(x, mean * kN, ".", color=COLOURS["mean"], ms=1.5, zorder=2)
            ax.plot(x[~outside], observed[~outside] * kN, ".", color=COLOURS["inside"], ms=4, zorder=3)
            ax.plot(x[outside], observed[outside] * kN, "x", color=COLOURS["outside"], ms=5, zorder=3)

        residual = (observed - mean) * kN
        half = (high90 - low90) / 2 * kN
        for ax, x in ((axes[1, 0], t), (axes[1, 1], phase), (axes[1, 2], v_mm)):
            ax.vlines(x, -half, half, color=COLOURS["band90"], lw=3, zorder=1)
            ax.axhline(0, color="k", lw=0.6)
            ax.plot(x, residual, ".", color=COLOURS["inside"], ms=4, zorder=3)
        phase_p = check.statistics.get("phase_residual", {}).get("p_value")
        axes[1, 1].set_title("" if phase_p is None else f"phase-locked residual: p = {phase_p:.3f}", fontsize=10)
        for ax in axes.ravel():
            ax.relim()
            ax.autoscale_view()
        self.suptitle.set_text(
            f"{check.test_id}: {check.kind} {check.frequency_hz:g} Hz x {1e3 * check.amplitude_m:g} mm;"
            f" {100 * check.coverage[0.9]:.0f} % in 90 % band, {100 * check.coverage[0.5]:.0f} % in 50 % band"
            " (fitted points only; red x: outside the 90 % band)")
        buffer = io.BytesIO()
        self.fig.savefig(buffer, format="png", dpi=DPI, pil_kwargs={"compress_level": PNG_COMPRESSION})
        return buffer.getvalue()
