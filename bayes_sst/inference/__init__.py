"""Inference: the NumPyro model, its priors, fitting, and summaries of the posterior."""

from bayes_sst.inference._fit import FitResult, SamplerSettings, fit
from bayes_sst.inference._priors import Priors, make_priors
from bayes_sst.inference._summary import format_summary, summarize

__all__ = ["FitResult", "Priors", "SamplerSettings", "fit", "format_summary", "make_priors", "summarize"]
