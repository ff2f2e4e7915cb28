"""Fitting a series: signals -> lagged moments -> NUTS over the collapsed model -> DataTree."""

from __future__ import annotations

import json
import time
from functools import partial
from dataclasses import dataclass, field, replace
from typing import Any, Callable

import numpy as np

from bayes_sst.inference._priors import ALPHA_SPREAD_SITE, GAIN_SITE, Priors, make_priors, payload_gain_identifiable
from bayes_sst.inference._summary import (ESS_LIMIT, IMPLAUSIBLE_MASS_SPREAD, RHAT_LIMIT, largest_chain_spread,
                                         short_of_limits)
from bayes_sst.inference._statistics import LaggedMoments, lagged_moments, pooled_damping
from bayes_sst.io import Series
from bayes_sst.signals import PreparedTest, SignalOptions, prepare_series

# (median, log sd) of the moving mass's between-test spread prior in fit's mass refit: 90 % of
# its mass from 1.1 % to 3.6 %, what fixtures and mounting change between tests. Why not a
# shared Me (the refit until 2026-11-26): where the mass does vary by a few percent, a shared
# Me is over-confident; on clean series of the LuGre generator (Me varying 1-3 % per test)
# three slow-sine series of thirty came out at Me -3.1, +1.0, +5.0 % with sds of 0.1 %.
HELD_MASS_SPREAD = (0.02, 0.35)


@dataclass(frozen=True)
class SamplerSettings:
    """NUTS settings. Defaults reach R-hat <= 1.01 and bulk ESS >= 400 with margin."""

    chains: int = 4
    draws: int = 500
    # the warm-up starts from asymptotic posterior scales (_initial_inverse_mass), so 300
    # iterations adapt as well as 500 did: 100 virtual-table series covered and converged as
    # before (100 of 100, against 99 with 500), 24 independent ones too, bulk ESS at 200 tests
    # 1800-2000 either way; the 200-test fit samples about 2.5 s faster
    warmup: int = 300
    seed: int = 0
    target_accept: float = 0.85
    max_tree_depth: int = 8
    # the global sites (alpha and the between-test spreads, which are correlated) are sampled
    # in coordinates whitened by their curvature at the mode (_model.WhitenedFrame), the per-test
    # noise sites with their asymptotic scales: a fully dense mass in 2J+5 dimensions adapts
    # poorly for hundreds of tests (maximum tree depth on every draw)
    # when R-hat or the bulk ESS falls short of its limit (summary.short_of_limits), the chains
    # go on for `draws` more, up to this many times; the tree's sampler settings then give the
    # total draws. Why: 2 of 100 randomised virtual-table series ended at population R-hat
    # 1.010-1.011 after 500 draws
    extensions: int = 2
    # the mass matrix stays the one the sampler starts with (the inverse curvature at the mode
    # for alpha and the spreads, asymptotic scales for the per-test sites; _initial_inverse_mass)
    # and only the step size adapts. Why: re-estimated from 25-100 warm-up draws in 2J+5
    # dimensions the diagonal came out noisier than the scales it started from; measured at 200
    # tests, the adapted step size fell from 0.30 to 0.22 and draws took 27 leapfrog steps
    # instead of 15, with the same bulk ESS (1820 against 1867). True adapts a diagonal over the
    # sampler's coordinates (the whitened global sites w, phi, sigma; _model.WhitenedFrame)
    adapt_mass_matrix: bool = False


@dataclass
class FitResult:
    """A finished fit: labelled posterior, signals and moments it came from, timings."""

    tree: Any  # xarray.DataTree
    prepared: list[PreparedTest]
    moments: LaggedMoments
    priors: Priors
    settings: SamplerSettings
    timings: dict[str, float] = field(default_factory=dict)
    series_name: str = ""

    @property
    def posterior(self):
        return self.tree["posterior"].to_dataset()


def _say(progress: Callable[[str], None] | None, message: str):
    if progress is not None:
        progress(message)


def _initial_values(moments: LaggedMoments, alpha: float, with_gain: bool = False,
                    alpha_spread: float | None = None):
    """Per-test least-squares start for sigma and phi at a plausible alpha (scaled units); the
    payload's friction gain at 1 (the table description's physics) where it is sampled, the
    exponent's between-test sd at alpha_spread where it is."""
    grid = moments.alpha_grid
    g = int(np.argmin(np.abs(grid - alpha)))
    sigmas, phis = [], []
    for j in range(moments.n_tests):
        m0, m1, m2 = moments.moments[j, g]
        n = max(moments.n_pairs[j], 1.0)
        xx, xy, yy = m0[1:, 1:], m0[1:, 0], m0[0, 0]
        theta = np.linalg.lstsq(xx + 1e-9 * np.eye(4), xy, rcond=None)[0]
        rss = max(yy - 2 * theta @ xy + theta @ xx @ theta, 1e-12)
        vec = np.concatenate([[1.0], -theta])
        lag1 = vec @ m1 @ vec
        lag0 = vec @ m2 @ vec
        phi = float(np.clip(lag1 / max(lag0, 1e-12), -0.9, 0.95))
        sigmas.append(np.sqrt(rss / n * max(1 - phi * phi, 0.05)))
        phis.append(phi)
    values = {
        "alpha": np.asarray(alpha, dtype=float),
        "spread": np.full(4, 0.02),
        "phi": np.asarray(phis, dtype=float),
        "sigma": np.asarray(sigmas, dtype=float),
    }
    if alpha_spread is not None:
        values[ALPHA_SPREAD_SITE] = np.asarray(alpha_spread, dtype=float)
    if with_gain:
        values[GAIN_SITE] = np.asarray(1.0)
    return values


def _initial_inverse_mass(moments: LaggedMoments, start: dict, priors: Priors, alpha_sd: float = 0.03,
                          gain_sd: float = 0.3):
    """A first guess of the posterior variances in NumPyro's unconstrained space.

    An identity mass matrix makes the first 100 warm-up iterations of a 200-test fit take
    ~150 leapfrog steps each: the per-test AR(1) sites are known to a few percent while alpha
    is known to ~0.01. Asymptotic scales fix that:

        sd(log sigma_j) ~ 1/sqrt(2 n_j),   sd(phi_j) ~ sqrt(max(1 - phi_j^2, 2/n_j)/n_j),
        sd(log rho_k) ~ 1/sqrt(2 J) + 0.25 (capped at the prior's 1), and so sd(log tau),
        sd(kappa) ~ gain_sd (the payload's friction gain, where it is sampled),

    mapped through the interval transforms: for x = low + (high - low)*sigmoid(z),
    dz/dx = (high - low)/((x - low)(high - x)). These scales steer the search for the mode;
    at the mode fit evaluates them again and replaces the alpha and spread block by the
    inverse curvature there (_with_curvature), and the sampler keeps that mass matrix
    (SamplerSettings.adapt_mass_matrix).
    """
    from bayes_sst.inference._model import PHI_BOUND, global_sites

    n = np.maximum(np.asarray(moments.n_pairs, dtype=float), 4.0)
    phi = np.clip(np.asarray(start["phi"], dtype=float), -0.995, 0.995)
    sd_phi = np.sqrt(np.maximum(1.0 - phi * phi, 2.0 / n) / n) * 2 * PHI_BOUND / ((PHI_BOUND + phi) * (PHI_BOUND - phi))
    sd_log_sigma = 1.0 / np.sqrt(2.0 * n)
    alpha = float(np.clip(start["alpha"], priors.alpha_low + 0.05, priors.alpha_high - 0.05))
    sd_alpha = alpha_sd * (priors.alpha_high - priors.alpha_low) / ((alpha - priors.alpha_low) * (priors.alpha_high - alpha))
    sd_log_spread = np.minimum(priors.spread_prior()[1], 0.25 + 1.0 / np.sqrt(2.0 * moments.n_tests))
    global_variances = np.concatenate([[sd_alpha**2], sd_log_spread**2])
    if ALPHA_SPREAD_SITE in start:
        sd_log_tau = min(priors.alpha_spread[1], 0.25 + 1.0 / np.sqrt(2.0 * moments.n_tests))
        global_variances = np.append(global_variances, sd_log_tau**2)
    if GAIN_SITE in start:
        low, high = priors.payload_friction_gain[2:]
        gain = float(np.clip(start[GAIN_SITE], low + 0.05 * (high - low), high - 0.05 * (high - low)))
        sd_gain = gain_sd * (high - low) / ((gain - low) * (high - gain))
        global_variances = np.append(global_variances, sd_gain**2)
    return {
        global_sites(start): np.diag(global_variances),
        ("phi",): sd_phi**2,
        ("sigma",): sd_log_sigma**2,
    }


def _global_key(inverse_mass: dict) -> tuple[str, ...]:
    """The key of the dense global block in an inverse mass matrix dict (_model.global_sites of
    the sites it covers)."""
    from bayes_sst.inference._model import global_sites

    return global_sites(set().union(*inverse_mass))


# Each chain starts this many (conditional) posterior sds away from the mode, in a random
# direction drawn from the starting mass matrix's Gaussian: chains that begin apart and still
# agree are what R-hat can vouch for; chains begun at one point agree for free.
START_DISPERSION = 2.0


def _dispersed_starts(mode: dict, inverse_mass: dict, chains: int, seed: int, dispersion: float) -> list[dict]:
    """One start per chain: mode + dispersion * (draw from N(0, inverse_mass)), in NumPyro's
    unconstrained space (the global block dense, the per-test sites diagonal)."""
    from bayes_sst.inference._model import split_global

    rng = np.random.default_rng([seed, 20_251_126])
    block = _global_key(inverse_mass)
    global_root = np.linalg.cholesky(np.asarray(inverse_mass[block], dtype=float))
    starts = []
    for _ in range(chains):
        shift = split_global(global_root @ rng.standard_normal(global_root.shape[0]), block)
        start = {name: np.asarray(mode[name], dtype=float) + dispersion * shift[name] for name in shift}
        for name in ("phi", "sigma"):
            sd = np.sqrt(np.asarray(inverse_mass[(name,)], dtype=float))
            start[name] = np.asarray(mode[name], dtype=float) + dispersion * sd * rng.standard_normal(sd.shape)
        starts.append(start)
    return starts


def _site_scales(inverse_mass: dict) -> dict:
    """Each site's rough posterior sd in the unconstrained space, from _initial_inverse_mass."""
    from bayes_sst.inference._model import split_global

    block = _global_key(inverse_mass)
    return {
        **split_global(np.sqrt(np.diag(np.asarray(inverse_mass[block], dtype=float))), block),
        "phi": np.sqrt(np.asarray(inverse_mass[("phi",)])),
        "sigma": np.sqrt(np.asarray(inverse_mass[("sigma",)])),
    }


def _with_curvature(inverse_mass: dict, hessian: np.ndarray) -> dict:
    """inverse_mass with its global block replaced by the inverse of the curvature `hessian`
    (global_curvature) where that is positive definite and finite; as it was otherwise."""
    if not np.all(np.isfinite(hessian)):
        return inverse_mass
    try:
        root = np.linalg.cholesky(hessian)
    except np.linalg.LinAlgError:
        return inverse_mass
    inverse_root = np.linalg.solve(root, np.eye(len(hessian)))
    covariance = inverse_root.T @ inverse_root
    return {**inverse_mass, _global_key(inverse_mass): 0.5 * (covariance + covariance.T)}


def _sampler_start(starts: list[dict], mode: dict, frame, potential, table, priors):
    """The chains' start for NumPyro (ParamInfo: the whitened coordinates, their potential and
    gradient), one chain per entry of `starts` (unconstrained sites).

    The potential and gradient come from numpy (_model.potential_and_gradient). A start where
    they are not finite is replaced by the mode; where even the mode's numpy potential is not
    finite, the sampler's own JAX potential is evaluated instead (jitted here, once), and a start
    that it cannot evaluate either stops the fit with an error: NUTS started at an infinite
    potential rejects every move and returns the start as its draws, without an error of its own.
    """
    import jax
    import jax.numpy as jnp
    from numpyro.infer.util import ParamInfo

    from bayes_sst.inference._model import potential_and_gradient

    def finite(value, gradient):
        return bool(np.isfinite(value)) and all(np.all(np.isfinite(g)) for g in gradient.values())

    numpy_value = lambda start: potential_and_gradient(start, table, priors)  # noqa: E731
    evaluated = [numpy_value(start) for start in starts]
    if not all(finite(*e) for e in evaluated):
        at_mode = numpy_value(mode)
        starts = [start if finite(*e) else mode for start, e in zip(starts, evaluated)]
        evaluated = [e if finite(*e) else at_mode for e in evaluated]
    sampler_starts = [frame.to_sampler(start) for start in starts]
    if all(finite(*e) for e in evaluated):
        values = [e[0] for e in evaluated]
        gradients = [frame.gradient_to_sampler(e[1]) for e in evaluated]
    else:
        value_and_gradient = jax.jit(jax.value_and_grad(potential))
        pairs = [value_and_gradient({k: jnp.asarray(v) for k, v in start.items()}) for start in sampler_starts]
        values = [float(value) for value, _ in pairs]
        gradients = [jax.device_get(gradient) for _, gradient in pairs]
        if not all(finite(value, gradient) for value, gradient in zip(values, gradients)):
            raise RuntimeError(
                "the posterior's potential energy is not finite at the chains' start, the posterior mode "
                f"(alpha, spreads: {np.round(frame.centre, 4).tolist()} in the unconstrained space): the series' "
                "tests give no usable likelihood there. Check the records (fit --signal options, or leave out the "
                "test the signal notes name)")

    def per_chain(parts):
        stacked = np.stack([np.asarray(part, dtype=float) for part in parts])
        return jnp.asarray(stacked if len(parts) > 1 else stacked[0])

    names = list(sampler_starts[0])
    return ParamInfo(z={name: per_chain([start[name] for start in sampler_starts]) for name in names},
                     potential_energy=per_chain(values),
                     z_grad={name: per_chain([gradient[name] for gradient in gradients]) for name in names})


def _release_compiled_programs():
    """Free the compiled programs JAX keeps in memory (jax.clear_caches).

    Why: a fit's sampler is a new program each time, and JAX keeps every program it compiled
    or loaded for the life of the process. On CPU each one holds about 900 memory mappings (one
    per compiled kernel); measured here, a process that fitted ~70 series in a row reached the
    kernel's limit of 65,530 mappings and aborted inside LLVM ('Cannot allocate memory'). With
    the programs released the count stays flat (about 1,330 after each fit).
    """
    import gc

    import jax

    gc.collect()
    jax.clear_caches()


def fit(
    series: Series,
    *,
    chains: int = SamplerSettings.chains,
    draws: int = SamplerSettings.draws,
    warmup: int = SamplerSettings.warmup,
    seed: int = SamplerSettings.seed,
    extensions: int = SamplerSettings.extensions,
    prior: str | Priors = "generic",
    signals: SignalOptions = SignalOptions(),
    progress: Callable[[str], None] | None = None,
    auto_mass_refit: bool = True,
    release_compiled: bool = True,
    widen: bool = True,
) -> FitResult:
    """Posterior of the table's force model from every periodic test of `series`.

    The model (see bayes_sst.inference._collapsed) lets Me, Ke, Ce, Fmu vary between tests
    around population values (except the coefficients in prior.shared), shares alpha, and gives
    each test an AR(1) residual.

    auto_mass_refit: when the fitted between-test sd of Me exceeds IMPLAUSIBLE_MASS_SPREAD
    (10 %) in any chain (its mean over the chain's draws), refit with Me's between-test spread
    prior held to HELD_MASS_SPREAD (median 2 %); if the spread still exceeds it in any chain,
    refit once more with Me shared by all tests, its population value still allowing for the
    tests' masses differing by HELD_MASS_SPREAD's median (Priors.ignored_spread: a shared Me
    rests on the few tests that pin it, and a generator that varies Me by 2 % put it 0.8 % off
    at 0.05 % sd, 15 sds); record it in tree.attrs["mass_refit"]. A table's moving mass does not change that much between tests;
    such a spread means that the sine tests' per-test Me and Ke, which a sine tells apart only
    through its harmonics, slid along their ridge. Measured on the virtual table with white
    force noise only: population Me 43-57 % low with the spread at 73-96 %; held, within 1 %.
    On three clean series of the LuGre generator the slow sines' harmonics carry its Stribeck
    friction and their per-test Me came out 30-90 % low; held, the population values are within
    1.7 sds, where a shared Me was 33-49 sds off (that generator varies Me by 1-3 % per test).
    On its strong-cubic series one sine's Me is pinned at -11 t +- 1 t, the held spread stays
    at 42 % with Me -27 %, and the shared refit gives Me +0.1 %.

    extensions: when R-hat or the bulk ESS is short of its limit after `draws`, the chains go
    on for `draws` more, up to this many times (SamplerSettings.extensions; 0: never).

    widen: leave each test out in turn (at the posterior mode) and stretch the population draws
    where the estimates scatter more than the posterior allows (bayes_sst.inference._widening;
    the model's own draws are kept in the tree's model_posterior group, the jackknife's
    estimates in its jackknife group). False: the model's posterior as it is.

    release_compiled: after sampling, drop JAX's in-memory compiled programs
    (jax.clear_caches; see _release_compiled_programs). A later fit loads its sampler from the
    persistent compilation cache either way, since every fit builds a new one.
    """
    import bayes_sst._jaxconfig  # noqa: F401  (float64, CPU devices for chains)
    import jax
    import jax.numpy as jnp
    from numpyro.infer import MCMC, NUTS

    from bayes_sst.inference._collapsed import moment_table
    from bayes_sst.inference._model import (
        ScaledPriors,
        WhitenedFrame,
        constrained_sites,
        global_curvature,
        posterior_mode,
        unconstrained_start,
        whitened_potential,
    )
    from bayes_sst.inference._posterior import build_tree

    for name, value, least in (("chains", chains, 1), ("draws", draws, 4), ("warmup", warmup, 0),
                               ("extensions", extensions, 0)):
        if not isinstance(value, (int, np.integer)) or value < least:
            raise ValueError(f"{name} must be a whole number of at least {least}, got {value!r}")
    settings = SamplerSettings(chains=chains, draws=draws, warmup=warmup, seed=seed, extensions=extensions)
    timings: dict[str, float] = {}
    start = time.perf_counter()
    prepared = prepare_series(series, signals)
    priors = prior if isinstance(prior, Priors) else make_priors(prior, series.table)
    moments = lagged_moments(prepared, priors.centre_vector())
    timings["signals"] = time.perf_counter() - start
    _say(
        progress,
        f"{len(prepared)} periodic tests, {int(moments.n_pairs.sum())} likelihood samples "
        f"(from {sum(t.n_samples for t in series.periodic_tests)} recorded) prepared in {timings['signals']:.1f} s",
    )

    notes = [note for test in prepared for note in test.notes]
    for note in notes:
        _say(progress, f"!! {note}")
    table = moment_table(moments, jnp)
    # the same table in numpy, for the start's potential (computed outside the compiled sampler)
    start_table = moment_table(moments, np)

    def sample(priors: Priors):
        with_gain = priors.payload_friction_gain is not None and payload_gain_identifiable(moments.friction_load)
        table_now = table if with_gain else table._replace(load_share=None)
        start_now = start_table if with_gain else start_table._replace(load_share=None)
        spread_medians, spread_log_sds = priors.spread_prior()
        scaled = ScaledPriors(
            mean=jnp.asarray(priors.centre_vector() / moments.coefficient_scale),
            sd=jnp.full(4, priors.relative_sd) * jnp.asarray(priors.centre_vector() / moments.coefficient_scale),
            alpha_mean=priors.alpha_mean,
            alpha_sd=priors.alpha_sd,
            alpha_low=priors.alpha_low,
            alpha_high=priors.alpha_high,
            spread_median=jnp.asarray(spread_medians),
            spread_log_sd=jnp.asarray(spread_log_sds),
            noise_loc=float(np.log(priors.noise_scale)),
            noise_log_sd=priors.noise_log_sd,
            varying=jnp.asarray(priors.varying_mask()),
            gain=tuple(float(x) for x in priors.payload_friction_gain) if with_gain else None,
            alpha_spread=None if priors.alpha_spread is None else tuple(float(x) for x in priors.alpha_spread),
            deviation_scale=pooled_damping(moments)[1] if priors.alpha_spread is not None else 1.0,
        )
        start_values = _initial_values(moments, priors.alpha_mean, with_gain,
                                       None if priors.alpha_spread is None else float(priors.alpha_spread[0]))
        inverse_mass = _initial_inverse_mass(moments, start_values, priors)
        # the chains start around the posterior mode (_dispersed_starts), with potentials and
        # gradients computed outside the compiled sampler (see bayes_sst.inference._model), and
        # the global sites' mass matrix from the curvature at the mode
        z = unconstrained_start({name: np.asarray(value) for name, value in start_values.items()}, scaled)
        z = posterior_mode(z, start_now, scaled, _site_scales(inverse_mass))
        inverse_mass = _with_curvature(_initial_inverse_mass(moments, constrained_sites(z, scaled), priors),
                                       global_curvature(z, start_now, scaled))
        # the global sites' dense block becomes a change of coordinates (WhitenedFrame), so the
        # sampler itself works with a diagonal mass: unit for w, the asymptotic scales for the
        # per-test sites
        frame = WhitenedFrame.around(z, inverse_mass[_global_key(inverse_mass)])
        sampler_frame = frame._replace(centre=jnp.asarray(frame.centre), root=jnp.asarray(frame.root))
        potential = partial(whitened_potential, table=table_now, priors=scaled, frame=sampler_frame)
        kernel = NUTS(
            potential_fn=potential,
            inverse_mass_matrix=jnp.concatenate([jnp.ones(len(frame.centre)), inverse_mass[("phi",)],
                                                 inverse_mass[("sigma",)]]),
            target_accept_prob=settings.target_accept,
            max_tree_depth=settings.max_tree_depth,
            adapt_mass_matrix=settings.adapt_mass_matrix,
        )
        n_devices = jax.local_device_count()
        chain_method = "parallel" if n_devices >= chains and chains > 1 else "vectorized"
        mcmc = MCMC(
            kernel,
            num_warmup=warmup,
            num_samples=draws,
            num_chains=chains,
            chain_method=chain_method,
            progress_bar=False,
        )
        _say(progress, f"sampling {chains} chains x ({warmup} warm-up + {draws} draws), NUTS ({chain_method}) ...")
        start = time.perf_counter()
        starts = _dispersed_starts(z, inverse_mass, chains, seed, START_DISPERSION)
        init = _sampler_start(starts, z, frame, potential, start_now, scaled)

        def drawn_sites():
            # the chains' draws as the model's sites (from the sampler's whitened coordinates)
            return constrained_sites(frame.from_sampler(jax.device_get(mcmc.get_samples(group_by_chain=True))), scaled)

        fields = ("diverging", "num_steps", "accept_prob", "energy", "potential_energy", "adapt_state.step_size")
        mcmc.run(jax.random.PRNGKey(seed), init_params=init, extra_fields=fields)
        samples = drawn_sites()
        extra = jax.device_get(mcmc.get_extra_fields(group_by_chain=True))
        seconds = time.perf_counter() - start
        timings["sampling"] = timings.get("sampling", 0.0) + seconds
        _say(progress, f"sampled in {seconds:.1f} s (compilation included)")

        start = time.perf_counter()
        total = settings
        tree = build_tree(seed + 1, samples, extra, scaled, moments, prepared, priors, total, series, signals)
        timings["posterior"] = timings.get("posterior", 0.0) + time.perf_counter() - start
        for _ in range(settings.extensions):
            short = short_of_limits(tree)
            if short is None:
                break
            # the chains go on from where they stopped, with the adapted step size and mass matrix
            _say(progress, f"not yet converged ({short}; limits R-hat {RHAT_LIMIT}, bulk ESS {ESS_LIMIT}): "
                           f"drawing {draws} more per chain ...")
            start = time.perf_counter()
            mcmc.post_warmup_state = mcmc.last_state
            mcmc.run(mcmc.post_warmup_state.rng_key, extra_fields=fields)
            more = drawn_sites()
            more_extra = jax.device_get(mcmc.get_extra_fields(group_by_chain=True))
            samples = {k: np.concatenate([samples[k], more[k]], axis=1) for k in samples}
            extra = {k: np.concatenate([extra[k], more_extra[k]], axis=1) for k in extra}
            timings["sampling"] += time.perf_counter() - start
            start = time.perf_counter()
            total = replace(total, draws=total.draws + draws)
            tree = build_tree(seed + 1, samples, extra, scaled, moments, prepared, priors, total, series, signals)
            timings["posterior"] += time.perf_counter() - start
        # what the jackknife of the final fit starts from (widen, below)
        last_fit.update(samples=samples, potential=extra["potential_energy"], table=start_now, priors=scaled,
                        scales=_site_scales(inverse_mass))
        if release_compiled:
            del mcmc, kernel
            _release_compiled_programs()
        return tree

    last_fit: dict = {}

    def mass_spread(tree) -> float:
        return largest_chain_spread(tree["posterior"], "Me")

    tree = sample(priors)
    first_spread = mass_spread(tree)
    if (auto_mass_refit and "Me" not in priors.shared and "Me" not in priors.spread_by_coefficient
            and first_spread > IMPLAUSIBLE_MASS_SPREAD):
        _say(progress, f"the moving mass came out varying by {100 * first_spread:.0f} % between tests, which a "
                       f"table does not do; refitting with its between-test spread held near "
                       f"{100 * HELD_MASS_SPREAD[0]:.0f} % ...")
        refit = {"first_fit_mass_spread": first_spread, "threshold": IMPLAUSIBLE_MASS_SPREAD,
                 "spread_median": HELD_MASS_SPREAD[0], "spread_log_sd": HELD_MASS_SPREAD[1]}
        held = replace(priors, spread_by_coefficient={**priors.spread_by_coefficient, "Me": HELD_MASS_SPREAD})
        tree = sample(held)
        held_spread = mass_spread(tree)
        priors = held
        if held_spread > IMPLAUSIBLE_MASS_SPREAD:
            # the prior could not hold it: some tests' Me is pinned far off by what the model
            # lacks (a strong cubic's third harmonic); with Me shared, their misfit goes to
            # their noise instead of pulling the population
            _say(progress, f"still {100 * held_spread:.0f} %; refitting with Me shared by all tests ...")
            priors = replace(priors, shared=tuple(priors.shared) + ("Me",),
                             ignored_spread={**priors.ignored_spread, "Me": HELD_MASS_SPREAD[0]})
            tree = sample(priors)
            refit.update(held_fit_mass_spread=held_spread, shared=True, ignored_spread=HELD_MASS_SPREAD[0])
        tree.attrs["mass_refit"] = json.dumps(refit)
    if widen:
        from bayes_sst.inference._widening import jackknife_modes
        from bayes_sst.inference._widening import widen as widen_tree

        start = time.perf_counter()
        tree["jackknife"] = jackknife_modes(last_fit["samples"], last_fit["potential"], last_fit["table"],
                                            last_fit["priors"], last_fit["scales"], moments.coefficient_scale,
                                            moments.test_ids)
        timings["jackknife"] = time.perf_counter() - start
        _say(progress, f"tests left out one at a time in {timings['jackknife']:.1f} s (the intervals' check "
                       "against the tests' own scatter)")
        tree = widen_tree(tree)
    if notes:
        tree.attrs["signal_notes"] = json.dumps(notes)
    broadband = [r.spec.id for r in series.tests if not r.spec.is_periodic]
    if broadband:
        tree.attrs["broadband_tests"] = json.dumps(broadband)
    return FitResult(
        tree=tree,
        prepared=prepared,
        moments=moments,
        priors=priors,
        settings=settings,
        timings=timings,
        series_name=series.name,
    )
