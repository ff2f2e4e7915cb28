"""The posterior-predictive check report of a run: health, parameters, bands, calibration.

`build_report(run)` computes every number and figure from a run folder; `write_report`
writes report.html (self-contained), report.json and figures/*.png atomically. The command
line is `bayes-sst report RUN [--out reports/NAME]`. Nothing here samples a posterior.
"""

from bayes_sst._lazy import lazy_attributes

_NAMES = {
    "Report": "bayes_sst.report._build",
    "build_report": "bayes_sst.report._build",
    "write_report": "bayes_sst.report._build",
    "loop_energy": "bayes_sst.report._loops",
    "peak_force": "bayes_sst.report._loops",
    "rms_force": "bayes_sst.report._loops",
}
__getattr__, __dir__ = lazy_attributes(__name__, _NAMES)
__all__ = sorted(_NAMES)
