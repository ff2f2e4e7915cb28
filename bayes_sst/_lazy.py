"""Lazy attribute access for package __init__ files: names resolve to their module on first use,
so that importing a package (and starting the command line) does not load JAX or SciPy."""

from __future__ import annotations

import importlib
from typing import Mapping


def lazy_attributes(package: str, names: Mapping[str, str]):
    """(__getattr__, __dir__) for a package whose public `names` live in the given modules."""

    def __getattr__(name):
        if name in names:
            return getattr(importlib.import_module(names[name]), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__():
        return sorted(names)

    return __getattr__, __dir__
