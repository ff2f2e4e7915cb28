"""The published method beside the posterior: hysteresis-loop (symmetric-instant) identification.

    >>> from bayes_sst.classical import classical_identification
    >>> result = classical_identification(series)            # doctest: +SKIP
    >>> result.pooled["Me"], result.spread["Fmu"]["relative_sd"]  # doctest: +SKIP

_loops.py splits one steady cycle of each periodic test at symmetric instants into a
dissipative force against velocity and an inertial-plus-elastic force against displacement
and acceleration; _identify.py turns those into Me, Ke, Ce, alpha, Fmu, pooled and per
test; _command.py is the `bayes-sst classical` sub-command.

Imports are lazy so that the command line can register the sub-command without loading
numpy's heavier neighbours (scipy, jax).
"""

from __future__ import annotations

from bayes_sst._lazy import lazy_attributes

_LAZY = {
    "ClassicalResult": "bayes_sst.classical._identify",
    "classical_identification": "bayes_sst.classical._identify",
    "fit_dissipative": "bayes_sst.classical._identify",
    "fit_dissipative_loops": "bayes_sst.classical._identify",
    "format_classical": "bayes_sst.classical._identify",
    "table_stiffness": "bayes_sst.classical._identify",
    "Loop": "bayes_sst.classical._loops",
    "decompose_test": "bayes_sst.classical._loops",
    "quadruple_times": "bayes_sst.classical._loops",
    "split_force": "bayes_sst.classical._loops",
    "symmetric_instants": "bayes_sst.classical._loops",
}


__getattr__, __dir__ = lazy_attributes('bayes_sst.classical', _LAZY)
__all__ = sorted(_LAZY)
