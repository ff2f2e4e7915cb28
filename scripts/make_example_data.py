"""Write the example series data/sst-paper/: the sst-paper twin, seed 2024, 2 % test-to-test spread.

    python scripts/make_example_data.py [--out data/sst-paper]

Signals are rounded to well below their noise (u to 0.1 um, F to 0.1 N, a to 1e-4 m/s^2) so
the folder stays small (about 2.5 MB) without changing what any fit can see.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

from bayes_sst.io import Series, TestRecord, write_series
from bayes_sst.twin import simulate

ROOT = Path(__file__).resolve().parents[1]
DECIMALS = {"u": 7, "u_cmd": 7, "v": 6, "F": 1, "a": 4, "a_cmd": 4}


def rounded(series: Series) -> Series:
    tests = tuple(
        # + 0.0 turns the -0.0 of rounded tiny negatives into 0.
        TestRecord(r.spec, {name: np.round(x, DECIMALS[name]) + 0.0 if name in DECIMALS else x
                            for name, x in r.columns.items()})
        for r in series.tests
    )
    return dataclasses.replace(series, tests=tests)


def main(argv=None) -> Path:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "data" / "sst-paper")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    series = simulate("sst-paper", seed=2024, spread=0.02, name="sst-paper")
    path = write_series(rounded(series), args.out, overwrite=True)
    size = sum(f.stat().st_size for f in path.iterdir())
    print(f"wrote {path}: {len(series.tests)} tests, {series.n_samples} samples, "
          f"{size / 1e6:.2f} MB in {time.perf_counter() - start:.1f} s")
    return path


if __name__ == "__main__":
    main()
