"""design.png: predicted half-width of each target against the number of added tests."""

from __future__ import annotations

from typing import Any, Mapping


def plot_design(data: Mapping[str, Any], path) -> None:
    """One panel per target: median and 80 % band for the recommended tests and for repeating
    the series' plan, the target as a dashed line and n_needed marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter, MaxNLocator

    names = list(data["targets"])
    fig, axes = plt.subplots(1, len(names), figsize=(5.0 * len(names), 3.8), squeeze=False)
    for ax, name in zip(axes[0], names):
        for rows, label, colour in ((data["curve"], "recommended", "C0"),
                                    (data["repeat_plan"]["curve"], "repeat the series' plan", "C1")):
            n = [row["n_added"] for row in rows]
            q10 = [100 * row[name]["q10"] for row in rows]
            q50 = [100 * row[name]["q50"] for row in rows]
            q90 = [100 * row[name]["q90"] for row in rows]
            ax.fill_between(n, q10, q90, color=colour, alpha=0.2, linewidth=0)
            ax.plot(n, q50, color=colour, label=f"{label} (median, 80 % band)")
        ax.axhline(100 * data["targets"][name], color="k", linestyle="--", linewidth=1, label="target")
        if data.get("n_needed") is not None:
            ax.axvline(data["n_needed"], color="C0", linestyle=":", linewidth=1)
        ax.set_yscale("log")
        # plain numbers on the log axis (1, 2, 5 %), not powers of ten
        ax.yaxis.set_major_formatter(FuncFormatter(lambda y, _: f"{y:g}"))
        ax.yaxis.set_minor_formatter(FuncFormatter(lambda y, _: f"{y:g}" if f"{y:g}"[0] in "25" else ""))
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_xlabel("added tests")
        ax.set_ylabel(f"{name}: half-width of the 90 % interval, %")
        ax.set_title(name)
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
