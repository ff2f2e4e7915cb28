"""The public surface: the verbs of the command line are importable from the package."""

import subprocess
import sys

import bayes_sst


def test_top_level_verbs_resolve_to_the_implementations():
    from bayes_sst.inference import fit, summarize
    from bayes_sst.io import load_series
    from bayes_sst.twin import simulate

    assert bayes_sst.load_series is load_series
    assert bayes_sst.simulate is simulate
    assert bayes_sst.fit is fit
    assert bayes_sst.summarize is summarize


def test_importing_the_package_is_light():
    code = "import sys, bayes_sst; print(','.join(m for m in ('jax', 'numpyro', 'arviz', 'matplotlib') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
