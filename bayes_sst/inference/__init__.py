"""Inference: the NumPyro model, its priors, fitting, and summaries of the posterior."""

from bayes_sst.inference._fit import FitResult, SamplerSettings, fit
from bayes_sst.inference._priors import Priors, make_priors

__all__ = ["FitResult", "Priors", "SamplerSettings", "fit", "make_priors"]
