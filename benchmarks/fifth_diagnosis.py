"""`bayes-sst diagnose` on the fifth simulator's withheld-effect series (benchmarks/fifth_generator.py):
is the withheld effect selected first, how far are its parameters from the truth, how much of the
excess does it remove. The cases are the eighteen series that the diagnosis was measured on since
2026-11-28 (seed, effect, size as the generator takes them; an empty size lets the generator draw
it). Its clean series are checked by benchmarks/clean_claims.py (fifth_clean_claims.json).

    PYTHONPATH=. .venv/bin/python benchmarks/fifth_diagnosis.py --dir /tmp/fifth_effects \
        [--cases stic115 y7] [--out benchmarks/results/fifth_diagnosis.json]
    PYTHONPATH=. .venv/bin/python benchmarks/fifth_diagnosis.py --fresh 12 --first-seed 200 --dir DIR

--fresh N draws N series of seeds not looked at before, the six effects in turn (stiction,
channel_delay, specimen, nonlinear_stiffness, position_friction, drift), each at a size the
generator draws.

Series missing from --dir are generated first (10-40 s each, numpy only); each diagnosis takes
10-90 s on this 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

# label, seed, generator effect, size (None: the generator draws it)
CASES = [
    ("stic130", 21, "stiction", 1.3),
    ("stic115", 22, "stiction", 1.15),
    ("delay3", 23, "channel_delay", 0.003),
    ("spec", 24, "specimen", None),
    ("cubic", 25, "nonlinear_stiffness", None),
    ("hinge", 26, "position_friction", None),
    ("drift", 27, "drift", None),
    ("xspec31", 31, "specimen", None),
    ("xspec33", 33, "specimen", None),
    ("xstic115", 31, "stiction", 1.15),
    ("xdelay30", 30, "channel_delay", 0.003),
    ("y1", 41, "stiction", 1.3),
    ("y2", 42, "channel_delay", None),
    ("y3", 43, "specimen", None),
    ("y4", 44, "nonlinear_stiffness", None),
    ("y5", 45, "position_friction", None),
    ("y6", 46, "drift", None),
    ("y7", 47, "stiction", 1.15),
]

# the withheld effect's reported parameters, checked against the generator's truth (same names)
PARAMETERS = {
    "stiction": ("static_ratio",),
    "channel_delay": ("delay",),
    "specimen": ("specimen_mass", "specimen_frequency"),
    "nonlinear_stiffness": ("cubic_stiffness",),
    "position_friction": ("position_friction",),
    "drift": ("drift",),
}


def _reported(ranking: list[dict], effect: str) -> dict[str, float]:
    for entry in ranking:
        if entry["name"] == effect:
            return {name: value.get("posterior_mean", value["mean"]) for name, value in entry["params"].items()
                    if isinstance(value, dict) and value.get("mean") is not None}
    return {}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", default="/tmp/bayes_sst_fifth_effects")
    parser.add_argument("--cases", nargs="*", default=None, help="labels to run (default: all)")
    parser.add_argument("--out", default=None)
    parser.add_argument("--fresh", type=int, default=0, metavar="N",
                        help="instead of the eighteen cases, N series of seeds not looked at before (from "
                             "--first-seed), the six effects in turn, each at the size the generator draws")
    parser.add_argument("--first-seed", type=int, default=200)
    args = parser.parse_args()
    sys.path.insert(0, str(HERE))
    from fifth_generator import make_series

    from bayes_sst.diagnosis import diagnose
    from bayes_sst.io import load_series

    cases = CASES
    if args.fresh:
        effects = list(PARAMETERS)
        cases = [(f"f{seed}", seed, effects[(seed - args.first_seed) % len(effects)], None)
                 for seed in range(args.first_seed, args.first_seed + args.fresh)]
    rows = []
    for label, seed, effect, size in cases:
        if args.cases and label not in args.cases:
            continue
        folder = os.path.join(args.dir, label)
        truth_path = os.path.join(folder, "truth.json")
        if not os.path.exists(truth_path):
            make_series(seed, folder, effect=effect, size=size, truth_path=truth_path)
        truth = json.loads(Path(truth_path).read_text())["effect"]
        started = time.perf_counter()
        result = diagnose(load_series(folder)).to_json()
        seconds = time.perf_counter() - started
        selected = result["selected"]
        reported = _reported(result["ranking"], effect)
        errors = {name: round(reported[name] / truth[name] - 1, 3) for name in PARAMETERS[effect]
                  if name in reported and truth.get(name)}
        first = bool(selected) and selected[0] == effect
        within = first and all(abs(e) <= 0.2 for e in errors.values()) and len(errors) == len(PARAMETERS[effect])
        row = {"case": label, "seed": seed, "effect": effect,
               "truth": {k: v for k, v in truth.items() if k != "name"}, "selected": selected,
               "first": first, "reported": reported, "errors": errors, "within_20_percent": within,
               "shrink": result["shrink"], "shrink_basis": result["shrink_basis"],
               "rms_before": result["rms_before"], "rms_after": result["rms_after"],
               "noise_floor": result["noise_floor"], "top": result["ranking"][0]["name"] if result["ranking"] else None,
               "seconds": round(seconds, 1)}
        rows.append(row)
        print(f"{label:9s} {effect:20s} selected={str(selected):34s} first={'yes' if first else 'NO ':3s} "
              f"errors={errors} shrink={result['shrink']:.2f} ({result['shrink_basis']}) "
              f"rms {result['rms_before']:.0f}->{result['rms_after']:.0f} floor {result['noise_floor']:.0f} "
              f"{seconds:.0f} s", flush=True)
    print(f"withheld effect selected first: {sum(r['first'] for r in rows)} of {len(rows)}; "
          f"its parameters within 20 %: {sum(r['within_20_percent'] for r in rows)}; "
          f"shrink >= 0.7: {sum(r['first'] and r['shrink'] >= 0.7 for r in rows)}")
    if args.out:
        Path(args.out).write_text(json.dumps({"command": " ".join(sys.argv), "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
