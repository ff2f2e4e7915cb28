"""JAX settings the package relies on; every module that uses JAX imports this first.

- float64: the force balance mixes 1e5 N forces with 1e-5 m displacements.
- Several CPU devices, so NUTS chains run in parallel on a multi-core machine. This only
  takes effect if JAX has not started its backend yet (XLA reads the flag once); the
  user's own XLA_FLAGS setting wins.
- A persistent compilation cache under ~/.cache/bayes_sst/jax (or $BAYES_SST_CACHE; `off`
  disables it), so that a
  second fit of a series of the same size skips XLA compilation.
- Closed-over arrays passed to the compiled program as arguments, not embedded in it
  (jax_use_simplified_jaxpr_constants; arrays above jax_embedded_constants_max_bytes are
  hoisted). NumPyro's parallel chains close over the model's data, its start values and its
  initial mass matrix; embedded, they made every series a different program, so the
  persistent cache only served refits of the same series (measured: a second randomised
  series of 20 tests compiled again, 9.3 s; with the flag it loads, 4.1 s). Set as the
  environment variable JAX_USE_SIMPLIFIED_JAXPR_CONSTANTS in bayes_sst/__init__.py, since JAX
  reads it at import (jax.config.update afterwards did not reach NumPyro's pmap); it takes
  effect only when JAX is first imported through bayes_sst. JAX calls the
  flag transitional; a release without it ignores the variable and only the cache hits are
  lost.
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
