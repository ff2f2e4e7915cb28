"""JAX settings the package relies on; every module that uses JAX imports this first.

- float64: the force balance mixes 1e5 N forces with 1e-5 m displacements.
- Several CPU devices, so NUTS chains run in parallel on a multi-core machine. This only
  takes effect if JAX has not started its backend yet (XLA reads the flag once); the
  user's own XLA_FLAGS setting wins.
- A persistent compilation cache under ~/.cache/bayes_sst (or $BAYES_SST_CACHE), so that a
  second fit of a series of the same size skips XLA compilation.
"""

import os

_CHAIN_DEVICES = 4

if "xla_force_host_platform_device_count" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (
        os.environ.get("XLA_FLAGS", "") + f" --xla_force_host_platform_device_count={_CHAIN_DEVICES}"
    ).strip()

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

_cache = os.environ.get("BAYES_SST_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "bayes_sst", "jax"))
if _cache and _cache.lower() != "off":
    jax.config.update("jax_compilation_cache_dir", _cache)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
