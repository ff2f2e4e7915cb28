"""Command-line helpers shared by the benchmark scripts."""

from __future__ import annotations

# the population values a fit summary reports
from bayes_sst.inference._summary import POPULATION as PARAMETERS


def name_values(items: list[str], flag: str = "--signal", example: str = "reversal_band=0.1") -> dict:
    """{NAME: VALUE} from NAME=VALUE strings given to `flag`: VALUE a number, true/false, or none."""
    overrides = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise SystemExit(f"{flag} {item!r}: expected NAME=VALUE, e.g. {example}")
        words = {"true": True, "false": False, "none": None}
        word = value.strip().lower()
        try:
            overrides[name] = words[word] if word in words else float(value)
        except ValueError:
            raise SystemExit(f"{flag} {item!r}: VALUE must be a number, true, false or none") from None
    return overrides




def interval_check(parameters: dict, truth: dict) -> dict:
    """{name: truth, mean, sd, q05, q95, covered, z} for each of PARAMETERS, from a fit summary's
    "parameters" and the truth's values: z = (mean - truth)/sd, covered = truth in [q05, q95]."""
    rows = {}
    for name in PARAMETERS:
        p = parameters[name]
        rows[name] = {"truth": truth[name], "mean": p["mean"], "sd": p["sd"], "q05": p["q05"], "q95": p["q95"],
                      "covered": bool(p["q05"] <= truth[name] <= p["q95"]), "z": (p["mean"] - truth[name]) / p["sd"]}
    return rows


def coverage_summary(rows: list[dict]) -> dict:
    """{name: coverage, z_mean, z_sd} over rows holding interval_check's entries; printed too."""
    import numpy as np

    summary = {}
    for name in PARAMETERS:
        z = np.array([r[name]["z"] for r in rows])
        z_sd = float(z.std(ddof=1)) if len(z) > 1 else None
        summary[name] = {"coverage": float(np.mean([r[name]["covered"] for r in rows])),
                         "z_mean": float(z.mean()), "z_sd": z_sd}
        print(f"{name:6} coverage {100 * summary[name]['coverage']:5.1f} %  z mean {z.mean():+.2f}"
              + (f" sd {z_sd:.2f}" if z_sd is not None else ""))
    return summary


def without_motion_sensors(series):
    """The series with its `a` and `v` columns removed, as a lab without an accelerometer records it."""
    from dataclasses import replace

    from bayes_sst.io import TestRecord

    return replace(series, tests=tuple(
        TestRecord(r.spec, {k: v for k, v in r.columns.items() if k not in ("a", "v")}) for r in series.tests))
