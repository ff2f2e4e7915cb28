"""Inference: the NumPyro model, its priors, fitting, posterior predictive and summaries."""

from bayes_sst.inference._fit import FitResult, SamplerSettings, fit
from bayes_sst.inference._predictive import (
    TestPredictive,
    design_matrix,
    posterior_predictive,
    response,
    run_prepared,
    run_signal_options,
)
from bayes_sst.inference._priors import Priors, make_priors
from bayes_sst.inference._summary import format_summary, summarize

__all__ = [
    "FitResult", "Priors", "SamplerSettings", "TestPredictive", "design_matrix", "fit", "format_summary",
    "make_priors", "posterior_predictive", "response", "run_prepared", "run_signal_options", "summarize",
]
