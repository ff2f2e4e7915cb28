"""The oil column: its analytic frequency and its resonance measured by broadband tests.

* _analytic.py: f_oil = (1/2pi)*sqrt(chambers*beta*A^2/(V*M)) from a series' table
  description, as a function of payload (chambers=2, V per chamber, by default);
* _frf.py: the H1 frequency response of broadband tests (Welch, Hann, 50 % overlap), its
  coherence and random error;
* _resonance.py: the peak of |H1| (second-order fit) with an interval, per payload;
* _command.py: `bayes-sst ocrf SERIES --out DIR`, writing ocrf.json.

    >>> from bayes_sst.oil import oil_column_resonance           # doctest: +SKIP
    >>> result = oil_column_resonance(series)                     # doctest: +SKIP
    >>> result.to_json()["per_payload"][0]["f_oil_hz"]            # doctest: +SKIP

numpy and scipy, plus bayes_sst.physics for the one formula (which loads jax).
"""

from __future__ import annotations

from bayes_sst._lazy import lazy_attributes

# lazy, so that the command line registers `ocrf` without loading scipy or jax
_LAZY = {
    "analytic_oil_frequency": "bayes_sst.oil._analytic",
    "oil_frequency_vs_payload": "bayes_sst.oil._analytic",
    "FrequencyResponse": "bayes_sst.oil._frf",
    "frequency_response": "bayes_sst.oil._frf",
    "OilColumnResult": "bayes_sst.oil._resonance",
    "PayloadResonance": "bayes_sst.oil._resonance",
    "Resonance": "bayes_sst.oil._resonance",
    "format_oil_column": "bayes_sst.oil._resonance",
    "locate_resonance": "bayes_sst.oil._resonance",
    "oil_column_resonance": "bayes_sst.oil._resonance",
}


__getattr__, __dir__ = lazy_attributes('bayes_sst.oil', _LAZY)
__all__ = sorted(_LAZY)
