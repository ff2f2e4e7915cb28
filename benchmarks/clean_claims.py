"""Diagnose many series that carry no withheld effect and count what the diagnosis claims on them.

The issue asks for "never an effect claimed on a clean series"; this is the check at scale. Every
subfolder of --dir that holds a manifest (series.json) is diagnosed with the package defaults; per series the
selection, the rule that took each selected effect, and the three best-ranked effects are
printed, and at the end how many series had anything selected.

    PYTHONPATH=. .venv/bin/python benchmarks/clean_claims.py --dir /tmp/valve_clean \
        --out benchmarks/results/valve_clean_claims.json

The series are made beforehand, in their own processes (a generator that forks must not run
inside this script's JAX process), for instance the valve generator's clean seeds 100-139:
`for s in $(seq 100 139); do PYTHONPATH=. .venv/bin/python benchmarks/valve_generator.py --seed $s
--out /tmp/valve_clean/s$s; done` (benchmarks/README.md).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time


def _rules(diagnosis: dict) -> dict[str, str]:
    """{selected effect: the rule that took it}; the oil column has its own check."""
    from bayes_sst.diagnosis._output import selection_rules

    rules = selection_rules(diagnosis)
    if (diagnosis.get("oil_column") or {}).get("selected"):
        rules["oil_column"] = "oil_column_check"
    return {name: rules.get(name, "?") for name in diagnosis["selected"]}


def _first_round_amplitudes(diagnosis: dict) -> dict[str, dict[str, float]]:
    """{view: {effect: amplitude_z}} of each view's first screening (nothing given): how far each
    candidate's coefficient stood from zero on a series that has none, the figure a rule on the
    coefficient alone would have to stay above. A candidate at its bound (a coefficient of the
    wrong sign, which is the base model) is left out: no rule can select it, whatever its z."""
    out: dict[str, dict[str, float]] = {}
    for step in diagnosis.get("steps", []):
        view = step.get("view", "default")
        if step.get("given") or view in out:
            continue
        out[view] = {c["name"]: round(float(c["amplitude_z"]), 2) for c in step["candidates"]
                     if c.get("amplitude_z") is not None and math.isfinite(c["amplitude_z"])
                     and not c.get("at_bound")}
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", required=True, help="folder whose subfolders are series")
    parser.add_argument("--out", default=None, help="json file for the per-series rows")
    args = parser.parse_args()

    from bayes_sst.diagnosis import diagnose
    from bayes_sst.io import load_series
    from bayes_sst.io._manifest import MANIFEST_NAME

    folders = sorted(os.path.join(args.dir, name) for name in os.listdir(args.dir)
                     if os.path.exists(os.path.join(args.dir, name, MANIFEST_NAME)))
    if not folders:
        sys.exit(f"{args.dir}: no series (subfolders with a {MANIFEST_NAME})")
    rows = []
    for folder in folders:
        started = time.perf_counter()
        diagnosis = diagnose(load_series(folder)).to_json()
        row = {"series": os.path.basename(folder), "selected": diagnosis["selected"],
               "rules": _rules(diagnosis), "seconds": round(time.perf_counter() - started, 1),
               "top": [(r["name"], round(r["score"], 1), round(r["score_se"], 1)) for r in diagnosis["ranking"][:3]],
               "verdict": diagnosis["verdict"], "rms_before": diagnosis["rms_before"],
               "noise_floor": diagnosis["noise_floor"], "amplitude_z": _first_round_amplitudes(diagnosis)}
        rows.append(row)
        print(f"{row['series']:12s} {row['seconds']:5.1f} s  selected {row['selected'] or 'none'}"
              f"{'  ' + str(row['rules']) if row['selected'] else ''}  top {row['top']}", flush=True)
    claimed = [r["series"] for r in rows if r["selected"]]
    print(f"series with an effect claimed: {len(claimed)} of {len(rows)}" + (f" ({', '.join(claimed)})" if claimed else ""))
    if args.out:
        with open(args.out, "w") as handle:
            json.dump({"command": " ".join(sys.argv), "rows": rows, "claimed": claimed}, handle, indent=1)


if __name__ == "__main__":
    main()
