"""Reading numbers from a series' optional `table` description (every key may be absent)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any


def positive_or_none(value: Any) -> float | None:
    """value as a float when it is a finite number > 0 (not a bool or a string), else None."""
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value > 0:
        return float(value)
    return None


def table_number(table: Any, *path: str) -> float | None:
    """The positive number at table[path[0]][path[1]]..., or None when a level is missing,
    not a mapping, or the value is not a finite positive number."""
    node = table
    for key in path:
        if not isinstance(node, Mapping):
            return None
        node = node.get(key)
    return positive_or_none(node)
