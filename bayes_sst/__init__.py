"""bayes_sst: Bayesian identification of a servo-hydraulic shaking table's force model.

The pipeline reads as the package's folders: io (test series) -> signals (filtering,
derivatives, steady cycles) -> physics (force model) -> inference (posterior) -> report.
Heavy modules are imported on first use so that ``import bayes_sst`` and the command line
start fast.
"""

from __future__ import annotations

import os

# Read by JAX when it is first imported, which a submodule may do before bayes_sst._jaxconfig
# runs; see _jaxconfig for why (the user's own setting wins).
os.environ.setdefault("JAX_USE_SIMPLIFIED_JAXPR_CONSTANTS", "true")

from bayes_sst._lazy import lazy_attributes  # noqa: E402

__version__ = "0.1.0"

_LAZY = {
    "load_series": "bayes_sst.io",
    "write_series": "bayes_sst.io",
    "SeriesFormatError": "bayes_sst.io",
    "simulate": "bayes_sst.twin",
    "fit": "bayes_sst.inference",
    "summarize": "bayes_sst.inference",
    "format_summary": "bayes_sst.inference",
}


__getattr__, __dir__ = lazy_attributes('bayes_sst', _LAZY)
__all__ = sorted(_LAZY)
