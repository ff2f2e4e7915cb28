"""argparse value types that refuse a bad option value with a message naming the rule, instead
of letting it reach numpy (an 'internal error') or pass unnoticed (a negative band)."""

from __future__ import annotations

import argparse
import math


def non_negative_int(text: str) -> int:
    """A seed: an integer >= 0 (numpy's generators refuse negative seeds)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"{value} is negative; a seed is an integer >= 0")
    return value


def _finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def share_below_one(text: str) -> float:
    """A share of the peak speed: 0 <= x < 1."""
    value = _finite(text)
    if not 0.0 <= value < 1.0:
        raise argparse.ArgumentTypeError(f"{value:g} is not a share of the peak speed: give a number from 0 to below 1")
    return value


def non_negative_number(text: str) -> float:
    """A speed or a similar physical amount: finite and >= 0."""
    value = _finite(text)
    if value < 0.0:
        raise argparse.ArgumentTypeError(f"{value:g} is negative")
    return value


def positive_number(text: str) -> float:
    """A multiple or a scale: finite and > 0."""
    value = _finite(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f"{value:g} is not above zero")
    return value


def damping_exponent(text: str) -> float:
    """alpha of the power-law damping |v|^alpha: finite, above 0 and at most 2."""
    value = _finite(text)
    if not 0.0 < value <= 2.0:
        raise argparse.ArgumentTypeError(f"{value:g} is not a damping exponent: give a number above 0 and at most 2")
    return value
