"""Command-line helpers shared by the benchmark scripts."""

from __future__ import annotations


def signal_overrides(items: list[str]) -> dict:
    """SignalOptions overrides from NAME=VALUE strings: VALUE a number, true/false, or none."""
    overrides = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise SystemExit(f"--signal {item!r}: expected NAME=VALUE, e.g. reversal_band=0.1")
        words = {"true": True, "false": False, "none": None}
        word = value.strip().lower()
        overrides[name] = words[word] if word in words else float(value)
    return overrides


def without_motion_sensors(series):
    """The series with its `a` and `v` columns removed, as a lab without an accelerometer records it."""
    from dataclasses import replace

    from bayes_sst.io import TestRecord

    return replace(series, tests=tuple(
        TestRecord(r.spec, {k: v for k, v in r.columns.items() if k not in ("a", "v")}) for r in series.tests))
