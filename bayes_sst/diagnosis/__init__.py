"""Sim-to-real gap diagnosis: where the base force model misses, which effect is responsible,
how far adding it shrinks the residual (docs/diagnosis.md).

    >>> from bayes_sst.diagnosis import diagnose                 # doctest: +SKIP
    >>> result = diagnose(series); result.selected, result.shrink  # doctest: +SKIP
"""

from bayes_sst._lazy import lazy_attributes

_LAZY = {
    "Diagnosis": "bayes_sst.diagnosis._diagnose",
    "diagnose": "bayes_sst.diagnosis._diagnose",
    "noise_floor": "bayes_sst.diagnosis._diagnose",
    "effect_data": "bayes_sst.diagnosis._data",
    "Scorer": "bayes_sst.diagnosis._engine",
    "format_diagnosis": "bayes_sst.diagnosis._output",
    "write_diagnosis": "bayes_sst.diagnosis._output",
}

__getattr__, __dir__ = lazy_attributes("bayes_sst.diagnosis", _LAZY)
__all__ = sorted(_LAZY)
