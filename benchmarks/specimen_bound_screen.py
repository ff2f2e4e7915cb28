"""Which clean series does the specimen's damping bound decide? A screen of the default view.

For each series (made first where missing) the base model is fitted and the specimen scored
against it (bayes_sst.diagnosis._screen.score_effect), and the script prints where its best
setting lies, whether that setting is at the top of the damping range (Specimen.at_setting_bound,
the bound as it was until 2026-11-30 evening, which always made such a fit the base model) and
whether the bound binds under the rule since then (a fit at 1.5 times the top damping better
by more than PAST_BOUND_NATS). A series marked FLIP is one whose specimen the new rule lets off its
bound; run `bayes-sst diagnose` on those to see whether anything is then claimed.

    PYTHONPATH=. .venv/bin/python benchmarks/specimen_bound_screen.py --out FILE sixth:300 fifth:3 valve:0 ...

KIND:SEED with KIND one of sixth, fifth, valve, lugre, first (the independent generator) or
twin (bayes_sst.twin.random_series); series go to --dir/KIND/KINDSEED (sixth: a folder that
sixth_check.py made, if present under --sixth-dir, is used as is). About 5-40 s a series.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


# simulators with a command line (--seed, --out; clean by default), run in a process of their
# own: the valve generator forks workers, which must not happen inside this JAX process
COMMAND_LINE = {"sixth": "sixth_generator.py", "fifth": "fifth_generator.py", "valve": "valve_generator.py",
                "lugre": "lugre_generator.py"}


def make(kind: str, seed: int, folder: str) -> None:
    """The clean series KIND:SEED in folder, unless it is there already."""
    if os.path.exists(os.path.join(folder, "series.json")):
        return
    if kind in COMMAND_LINE:
        subprocess.run([sys.executable, str(HERE / COMMAND_LINE[kind]), "--seed", str(seed), "--out", folder],
                       check=True, stdout=subprocess.DEVNULL)
    elif kind == "first":
        import independent_generator
        independent_generator.make_series(seed, folder)
    elif kind == "twin":
        from bayes_sst.io import write_series
        from bayes_sst.twin import random_series
        write_series(random_series(seed), folder)
    else:
        raise SystemExit(f"unknown series kind {kind!r}: {', '.join(COMMAND_LINE)}, first or twin")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("items", nargs="+", metavar="KIND:SEED")
    parser.add_argument("--dir", default="/tmp/bayes_sst_clean")
    parser.add_argument("--sixth-dir", default="/tmp/bayes_sst_sixth", help="sixth_check.py's folder (cNNN)")
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    sys.path.insert(0, str(HERE))

    from bayes_sst.diagnosis._diagnose import DIAGNOSIS_SIGNALS, Scorer, _scale, effect_data, fit_base
    from bayes_sst.diagnosis._screen import score_effect
    from bayes_sst.effects import effect_by_name
    from bayes_sst.io import load_series

    specimen = effect_by_name("specimen")
    rows = []
    for item in args.items:
        kind, _, seed_text = item.partition(":")
        seed = int(seed_text)
        started = time.perf_counter()
        folder = os.path.join(args.sixth_dir, f"c{seed:03d}") if kind == "sixth" else ""
        if not os.path.exists(os.path.join(folder, "series.json")):
            folder = os.path.join(args.dir, kind, f"{kind}{seed:03d}")
            make(kind, seed, folder)
        series = load_series(folder)
        tests = effect_data(series, DIAGNOSIS_SIGNALS)
        scorer = Scorer(tests, _scale(series, tests))
        score = score_effect(scorer, specimen, fit_base(scorer))
        at_top = bool(specimen.at_setting_bound(score.setting))
        row = {"item": item, "folder": folder, "setting": dict(score.setting), "at_setting_bound": at_top,
               "at_bound_new": bool(score.at_bound), "score": score.score, "score_se": score.score_se,
               "amplitude_z": score.amplitude_z, "s": round(time.perf_counter() - started, 1)}
        rows.append(row)
        flag = "FLIP" if at_top and not score.at_bound else "    "
        print(f"{item:10s} {flag} {score.setting['specimen_frequency']:7.3f} Hz "
              f"{100 * score.setting['specimen_damping']:5.1f} %  score {score.score:7.1f} +- {score.score_se:6.1f}"
              f"  amplitude z {score.amplitude_z:6.2f}  ({row['s']} s)", flush=True)
    at_top = [r for r in rows if r["at_setting_bound"]]
    flips = [r["item"] for r in at_top if not r["at_bound_new"]]
    print(f"{len(rows)} series: specimen at the damping top on {len(at_top)}, let off its bound on "
          f"{len(flips)}: {' '.join(flips) or '-'}")
    if args.out:
        Path(args.out).write_text(json.dumps({"command": " ".join(sys.argv), "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
