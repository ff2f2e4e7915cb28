"""The breakaway check's readings on stiction that drops to its kinetic level at once (and on the
same tables without it): over all reversals, at the reversals where the table rests, and the
resting reading's lead over the reversals it sweeps through (docs/diagnosis.md, the breakaway
check). Series: the first independent generator (benchmarks/independent_generator.py) with
Fs/Fk = 1.4 and 1.2 at 200 Hz, 500 Hz and 1 kHz, and the twin with a 0.5 mm/s Stribeck velocity
(close to the Karnopp model) at 200 Hz and 1 kHz, each beside its clean counterpart.

    PYTHONPATH=. .venv/bin/python benchmarks/breakaway_readings.py --dir /tmp/breakaway \
        [--out breakaway.json]

Missing series are generated first, each in a subprocess (about 3 min in all); the readings take
about 2 s a series (the base fit and the check, not the whole diagnosis).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent

# (label, generator, seed, sample rate in Hz or None for the generator's own draw, static ratio or None)
CASES = ([("first-1.4", "first", s, None, 1.4) for s in range(5)]
         + [("first-1.4", "first", s, 200.0, 1.4) for s in range(5, 10)]
         + [("first-1.4", "first", s, fs, 1.4) for fs in (500.0, 1000.0) for s in range(3)]
         + [("first-1.2", "first", s, fs, 1.2) for fs in (200.0, 1000.0) for s in range(5)]
         + [("first-clean", "first", s, 200.0, None) for s in range(5, 10)]
         + [("first-clean", "first", s, fs, None) for fs in (500.0, 1000.0) for s in range(3)]
         + [(f"twin-{label}", "twin", s, fs, ratio) for label, ratio in (("1.4", 1.4), ("1.2", 1.2), ("clean", None))
            for fs in (200.0, 1000.0) for s in (21, 31, 32)])


def _folder(root: Path, label, generator, seed, fs, ratio) -> Path:
    return root / f"{label}-{'drawn' if fs is None else int(fs)}-s{seed}"


def _make(path: Path, generator, seed, fs, ratio):
    """Generate one series in its own process (keeps the generators out of this JAX process)."""
    if generator == "first":
        effects = {"static_ratio": ratio} if ratio else None
        code = (f"import sys; sys.path.insert(0, {str(HERE)!r}); from independent_generator import make_series; "
                f"make_series({seed}, {str(path)!r}, effects={effects!r}, sample_rate_hz={fs!r})")
    else:
        over = {"static_ratio": ratio, "stribeck_velocity": 0.0005} if ratio else {}
        code = ("from bayes_sst.twin import simulate; from bayes_sst.io import write_series; "
                f"write_series(simulate('sst-paper', seed={seed}, spread=0.02, sample_rate_hz={fs!r}, "
                f"truth_overrides={over!r}), {str(path)!r})")
    subprocess.run([sys.executable, "-c", code], check=True, env=dict(os.environ, PYTHONPATH=str(HERE.parent)))


def _reading(path: Path) -> dict:
    from bayes_sst.diagnosis._diagnose import breakaway_reading
    from bayes_sst.io import load_series

    check = breakaway_reading(load_series(path))
    if check is None:
        return {}
    reading = check["resting"]
    resting, sweeping = reading["resting"], reading["sweeping"]
    return {"excess": check["excess"], "z": check["z"],
            "resting": None if resting is None else resting["excess"],
            "resting_z": None if resting is None else resting["z"],
            "resting_tests": None if resting is None else resting["tests"],
            "lead": reading["lead"], "lead_z": None if reading["lead"] is None else reading["lead"] / reading["lead_se"],
            "sweeping_reversals": None if sweeping is None else sweeping["reversals"],
            "selected_by": check["selected_by"], "static_ratio": None if check["static_excess"] is None
            else 1.0 + check["static_excess"]}


def _number(x, form):
    return "-" if x is None else format(x, form)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", required=True, help="folder for the series (made where missing)")
    parser.add_argument("--out", default=None, help="json file for the per-series rows")
    args = parser.parse_args()
    root = Path(args.dir)
    rows = []
    for label, generator, seed, fs, ratio in CASES:
        path = _folder(root, label, generator, seed, fs, ratio)
        if not (path / "series.json").exists():
            _make(path, generator, seed, fs, ratio)
        row = {"case": label, "seed": seed, "sample_rate_hz": fs, "static_ratio_truth": ratio, **_reading(path)}
        rows.append(row)
        print(f"{path.name:28s} all {_number(row.get('excess'), '+.3f')} (z {_number(row.get('z'), '.1f')})  "
              f"resting {_number(row.get('resting'), '+.3f')} (z {_number(row.get('resting_z'), '.1f')}, "
              f"{_number(row.get('resting_tests'), 'd')} tests)  lead {_number(row.get('lead'), '+.3f')} "
              f"(z {_number(row.get('lead_z'), '.1f')})  selects: {row.get('selected_by') or 'no'}"
              + (f" at {row['static_ratio']:.2f}" if row.get("static_ratio") else ""), flush=True)
    for label in dict.fromkeys(r["case"] for r in rows):
        group = [r for r in rows if r["case"] == label]
        print(f"{label}: stiction selected on {sum(bool(r.get('selected_by')) for r in group)} of {len(group)}")
    if args.out:
        with open(args.out, "w") as fh:
            json.dump({"command": " ".join(sys.argv), "rows": rows}, fh, indent=1)


if __name__ == "__main__":
    main()
