"""Fit and diagnose the blind generators' series: six clean series and, for each of six
effects, a clear and a weak case, from benchmarks/lugre_generator.py (LuGre friction, written
2026-11-26), benchmarks/valve_generator.py (servo-valve and two-chamber cylinder, DAQ
anti-alias filter, ADC and mains hum, written 2026-11-27), benchmarks/eighth_generator.py
(written 2026-12-02; a seventh effect, a low oil column, in a broadband test),
benchmarks/ninth_generator.py or benchmarks/tenth_generator.py (both 2026-12-02; benchmarks/README.md),
each by a helper session that saw the data format and the physics but not this package.

    PYTHONPATH=. .venv/bin/python benchmarks/blind_check.py --generator lugre --dir /tmp/lugre \
        --out benchmarks/results/lugre_check.json
    PYTHONPATH=. .venv/bin/python benchmarks/blind_check.py --generator valve --dir /tmp/valve \
        --out benchmarks/results/valve_check.json
    PYTHONPATH=. .venv/bin/python benchmarks/blind_check.py --generator eighth --dir /tmp/eighth \
        --out benchmarks/results/eighth_check.json

Series missing from --dir are generated first (10-40 s each). Per series: each population
value's error and z = (mean - truth)/sd, whether the 90 % interval covers it, the diagnosis's
selection and its three best-ranked effects. The LuGre generator scales a payload test's
friction by (1 + m_payload g/(Me g)), leaving out the struts' hold-down force that the package
(and the study) count in the normal load, so its series with payload tests carry that
disagreement (the fit's kappa takes it up).
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
NAMES = ("Me", "Ke", "Ce", "alpha", "Fmu")
EFFECT_CASES = ("stiction", "nonlinear_stiffness", "position_friction", "specimen", "channel_delay", "drift")
SHORT = {"nonlinear_stiffness": "cubic", "position_friction": "hinge", "channel_delay": "delay"}
# (case, seed, effect, size, record rate or None)
LUGRE_CASES = (
    ("clean_0", 0, None, None, 200), ("clean_1", 1, None, None, 256), ("clean_2", 2, None, None, 500),
    ("clean_3", 3, None, None, 1000), ("clean_4", 4, None, None, 256), ("clean_5", 5, None, None, 500),
) + tuple((f"{SHORT.get(e, e)}_{size}", 10 + 2 * i + k, e, size, None)
          for i, e in enumerate(EFFECT_CASES) for k, size in enumerate(("strong", "weak")))
# the tolerances on the population means: relative for Me, Ke, Ce, Fmu, absolute for alpha
TOLERANCE = {"Me": 0.03, "Ke": 0.03, "Ce": 0.10, "alpha": 0.05, "Fmu": 0.03}


def clean_cases(seeds):
    """Clean series of these seeds, the generator drawing its own record rate."""
    return tuple((f"clean_{s}", s, None, None, None) for s in seeds)


def seeded_cases(effects):
    """Six clean series (seeds 0-5), then each effect strong and weak on seeds 10, 11, 12, ..."""
    return clean_cases(range(6)) + tuple(
        (f"{SHORT.get(e, e)}_{size}", 10 + 2 * i + k, e, size, None)
        for i, e in enumerate(effects) for k, size in enumerate(("strong", "weak")))


# the valve generator draws its record rate from the seed
VALVE_CASES = seeded_cases(EFFECT_CASES)
# the eighth, ninth and tenth (2026-12-02) also withhold a low oil column, seen in a broadband
# test (ninth: model-following loop, Karnopp/Stribeck friction; tenth: force from chamber
# pressures with pump ripple, DAQ clock skew, binary record rates, a well-damped in-band column)
OIL_COLUMN_CASES = seeded_cases(EFFECT_CASES + ("oil_column",))
GENERATORS = {"lugre": ("lugre_generator", LUGRE_CASES), "valve": ("valve_generator", VALVE_CASES),
              "eighth": ("eighth_generator", OIL_COLUMN_CASES), "ninth": ("ninth_generator", OIL_COLUMN_CASES),
              "tenth": ("tenth_generator", OIL_COLUMN_CASES)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--generator", choices=sorted(GENERATORS), default="lugre")
    parser.add_argument("--dir", default=None, help="series folder (default /tmp/bayes_sst_GENERATOR)")
    parser.add_argument("--out", default=None)
    parser.add_argument("--only", nargs="*", default=None, help="case names to run")
    parser.add_argument("--clean-seeds", nargs=2, type=int, default=None, metavar=("FIRST", "STOP"),
                        help="instead of the cases: clean series of seeds FIRST to STOP-1")
    args = parser.parse_args()
    sys.path.insert(0, str(HERE))
    module, cases = GENERATORS[args.generator]
    if args.clean_seeds:
        cases = clean_cases(range(*args.clean_seeds))
    generate = __import__(module).generate
    base_dir = args.dir or f"/tmp/bayes_sst_{args.generator}"

    from bayes_sst.diagnosis import diagnose
    from bayes_sst.inference import fit
    from bayes_sst.inference._summary import summarize
    from bayes_sst.io import SeriesFormatError, load_series

    rows, refused = [], []
    for name, seed, effect, size, rate in cases:
        if args.only and name not in args.only:
            continue
        folder = os.path.join(base_dir, name)
        if not os.path.exists(os.path.join(folder, "truth.json")):
            options = dict(effect=effect, size=size) if effect else ({} if rate is None else dict(rate=rate))
            if "name" in inspect.signature(generate).parameters:
                options["name"] = name
            generate(seed, folder, verbose=False, **options)
        truth = json.load(open(os.path.join(folder, "truth.json")))
        started = time.perf_counter()
        try:
            series = load_series(folder)
            result = fit(series, seed=0)
        except SeriesFormatError as error:
            # a series the package refuses (a generator's own fault, as the eighth's first draft
            # ran a chamber dry) is reported and the other cases still run
            print(f"{name:16s} refused: {error}", flush=True)
            refused.append({"case": name, "refused": str(error)})
            continue
        parameters = summarize(result.tree)["parameters"]
        row = {"case": name, "effect": truth.get("effect"), "effect_params": truth.get("effect_params"),
               "fit_s": round(time.perf_counter() - started, 1), "mass_refit": bool(result.tree.attrs.get("mass_refit"))}
        for key in NAMES:
            p, value = parameters[key], truth[key]
            row[key] = {"truth": value, "mean": p["mean"], "sd": p["sd"],
                        "error": p["mean"] - value if key == "alpha" else (p["mean"] - value) / value,
                        "z": (p["mean"] - value) / p["sd"], "covered": bool(p["q05"] <= value <= p["q95"])}
        started = time.perf_counter()
        diagnosis = diagnose(series).to_json()
        row["diagnose_s"] = round(time.perf_counter() - started, 1)
        row["selected"] = diagnosis["selected"]
        row["broadband"] = any(t.spec.kind == "broadband" for t in series.tests)
        row["top"] = [(r["name"], round(r["score"], 1), round(r["score_se"], 1)) for r in diagnosis["ranking"][:3]]
        row["params"] = {r["name"]: r["params"] for r in diagnosis["ranking"] if r["name"] in diagnosis["selected"]}
        rows.append(row)
        cells = " ".join(f"{k} {row[k]['error'] * (1 if k == 'alpha' else 100):+.2f}{'' if k == 'alpha' else '%'}"
                         f"({row[k]['z']:+.1f}{'' if row[k]['covered'] else '!'})" for k in NAMES)
        print(f"{name:16s} {cells}  selected {row['selected']}", flush=True)
    if refused:
        print(f"refused by the package: {', '.join(r['case'] for r in refused)}")
    clean = [r for r in rows if r["effect"] is None]
    with_effect = [r for r in rows if r["effect"] is not None]
    for key in NAMES:
        print(f"{key:6s} covered in {sum(r[key]['covered'] for r in rows)} of {len(rows)}")
    print(f"clean series with nothing selected: {sum(not r['selected'] for r in clean)} of {len(clean)}; "
          f"with a force effect: {sum(any(n != 'oil_column' for n in r['selected']) for r in clean)}; "
          f"with the oil column: {sum('oil_column' in r['selected'] for r in clean)} "
          f"(of {sum(r['broadband'] for r in clean)} with a broadband test)")
    for key in NAMES:
        near = sum(abs(r[key]["error"]) <= TOLERANCE[key] for r in rows)
        print(f"{key:6s} within the issue's tolerance ({TOLERANCE[key]:g}) in {near} of {len(rows)}")
    print(f"effect series with the effect selected first: "
          f"{sum(bool(r['selected']) and r['selected'][0] == r['effect'] for r in with_effect)} of {len(with_effect)}")
    if args.out:
        with open(args.out, "w") as handle:
            json.dump({"command": " ".join(sys.argv), "rows": rows, "refused": refused}, handle, indent=1,
                      default=float)


if __name__ == "__main__":
    main()
