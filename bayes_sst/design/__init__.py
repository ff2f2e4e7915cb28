"""Bayesian design of the next tests: which tests to add to a fitted series, and how many,
so that chosen parameters reach a target precision (docs/design.md).

* _candidates.py: candidate tests, the table's limits, peak motion and force;
* _signals.py: the signals the fit would see from a candidate, built without running it;
* _engine.py: the collapsed model's Gaussian pieces per draw, preposterior and Fisher;
* _search.py: greedy ordering of the candidates on the Fisher approximation;
* _design.py: design(), DesignResult (design.json) and its text; _plot.py: design.png;
* _command.py: `bayes-sst design RUN --target Ke=2% ...`.

    >>> from bayes_sst.design import design                                  # doctest: +SKIP
    >>> result = design(tree, targets={"Ke": 0.02, "Fmu": 0.05})             # doctest: +SKIP
    >>> result.n_needed, result.recommended[:3]                              # doctest: +SKIP
"""

from __future__ import annotations

from bayes_sst._lazy import lazy_attributes

# lazy, so that the command line registers `design` without loading numpy, scipy or jax
_LAZY = {
    "Candidate": "bayes_sst.design._candidates",
    "TableLimits": "bayes_sst.design._candidates",
    "candidate_grid": "bayes_sst.design._candidates",
    "read_candidates": "bayes_sst.design._candidates",
    "table_limits": "bayes_sst.design._candidates",
    "DesignResult": "bayes_sst.design._design",
    "design": "bayes_sst.design._design",
    "format_design": "bayes_sst.design._design",
    "parse_target": "bayes_sst.design._design",
}

__getattr__, __dir__ = lazy_attributes("bayes_sst.design", _LAZY)
__all__ = sorted(_LAZY)
