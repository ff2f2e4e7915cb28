"""simulate(): a campaign of periodic and broadband tests on the twin table, as an in-memory Series.

For each planned test: the command (analytic for periodic tests, a seeded random signal for
broadband ones, at the internal rate), the test's own parameters (population truth times its
spread factors, payload added to the mass and to the bearings' normal force), one batched
JAX integration per output rate, then the sensors. Every random number comes from numpy
Generators seeded by `seed` alone: one stream for the spread draws, one per test for its
sensor noise and one per test for its broadband command, so that switching the noise or the
spread, or adding broadband tests, does not move the others.
"""

from __future__ import annotations

import math
from dataclasses import asdict
from typing import Any, Iterable, Mapping

import numpy as np

from bayes_sst.io import Series, TestRecord, TestSpec
from bayes_sst.twin._broadband import broadband_command, broadband_duration
from bayes_sst.twin._command import (
    DEFAULT_CORNER_ROUNDING,
    DEFAULT_RAMP_CYCLES,
    DEFAULT_REST_S,
    command_duration,
    periodic_command,
)
from bayes_sst.twin._deck import DeckParams
from bayes_sst.twin._hydraulics import servo_params
from bayes_sst.twin._integrate import integrate
from bayes_sst.twin._linear import closed_loop_resonance_hz
from bayes_sst.twin._noise import SensorNoise, add_sensor_noise, resolve_noise
from bayes_sst.twin._plan import PlanItem, as_plan, check_limits, default_plan
from bayes_sst.twin._spread import draw_factors, spread_sds
from bayes_sst.twin._truth import TableTruth, preset_truth

DEFAULT_INTERNAL_RATE_HZ = 4000.0
DEFAULT_BROADBAND_RATE_HZ = 1000.0
_ID_PREFIX = {"sine": "S", "triangle": "T", "broadband": "B"}


def _bucket(n: int) -> int:
    """n rounded up to a multiple of 2**(bit_length(n) - 4), at most 1/8 more than n, so
    that series of similar size share one compiled integrator."""
    if n <= 4:
        return n
    step = 2 ** max(0, n.bit_length() - 4)
    return -(-n // step) * step


def deck_of_test(truth: TableTruth, factors: Mapping[str, float], payload_kg: float,
                 alpha_shift: float = 0.0) -> DeckParams:
    """The deck of one test: population truth times spread factors, payload on the deck, the
    damping exponent moved by alpha_shift.

    Effects (off unless switched on in the truth): cubic spring k3 = K'e/h^2, hinge friction
    kh = Fp/h^2, a specimen with k_s = m_s*(2*pi*f_s)^2 and c_s = 2*zeta_s*m_s*2*pi*f_s.
    """
    fmu = truth.friction_with_payload(truth.Fmu * factors["Fmu"], payload_kg)
    h2 = truth.strut_h**2
    omega_s = 2.0 * math.pi * truth.specimen_frequency
    return DeckParams(
        mass=truth.Me * factors["Me"] + payload_kg,
        Ke=truth.Ke * factors["Ke"],
        Ce=truth.Ce * factors["Ce"],
        alpha=truth.alpha + alpha_shift,
        Fk=fmu,
        Fs=truth.static_ratio * fmu,
        stribeck_velocity=truth.stribeck_velocity,
        cubic=truth.cubic_stiffness / h2,
        hinge=truth.position_friction / h2,
        specimen_mass=truth.specimen_mass,
        specimen_k=truth.specimen_mass * omega_s**2,
        specimen_c=2.0 * truth.specimen_damping * truth.specimen_mass * omega_s,
    )


def _drifted(truth: TableTruth, factors: dict[str, float], position: float) -> dict[str, float]:
    """Spread factors with the campaign drift: Fmu and Ce times (1 - drift*s), s in [0, 1]."""
    out = dict(factors)
    out["Fmu"] *= 1.0 - truth.friction_drift * position
    out["Ce"] *= 1.0 - truth.damping_drift * position
    return out


def _delayed(t: np.ndarray, values: np.ndarray, delay: float) -> np.ndarray:
    """values(t - delay) by linear interpolation (the first value held before the record starts)."""
    if delay == 0.0:
        return values
    return np.interp(t - delay, t, values)


def _resonance_or_none(truth: TableTruth, moving_mass: float, *, Ke: float | None = None) -> float | None:
    """The closed loop's resonance (Hz), or None where |H| has no peak between 0.2 and 2 f_oil
    (a column ten times stiffer than the preset's): such a table is still simulated."""
    try:
        return closed_loop_resonance_hz(truth, moving_mass, Ke=Ke)
    except ValueError:
        return None


def _test_truth(truth: TableTruth, deck: DeckParams, factors: Mapping[str, float],
                payload_kg: float) -> dict[str, float]:
    """What the force model of this test should identify (payload included), plus the empty deck.

    f_oil_hz is the open oil column's frequency with the test's moving mass; resonance_hz
    the peak of the closed loop's linear |H(a_cmd -> a)| (see _linear.py), which is what a
    frequency response measured on the table shows.
    """
    return {
        "Me": float(deck.mass),
        "Ke": float(deck.Ke),
        "Ce": float(deck.Ce),
        "alpha": float(deck.alpha),
        "Fmu": float(deck.Fk),
        "static_ratio": truth.static_ratio,
        "f_oil_hz": truth.f_oil_hz(float(deck.mass)),
        "resonance_hz": _resonance_or_none(truth, float(deck.mass), Ke=float(deck.Ke)),
        "Me_empty": float(truth.Me * factors["Me"]),
        "Fmu_empty": float(truth.Fmu * factors["Fmu"]),
    }


def _run(truth: TableTruth, decks: list[DeckParams], u_cmd: list[np.ndarray], v_cmd: list[np.ndarray],
         dt: float, k: int) -> dict[str, list[np.ndarray]]:
    """Integrate tests of different lengths in one padded batch; commands at the internal rate."""
    lengths = [-(-len(c) // k) for c in u_cmd]
    n_tests, n_samples = _bucket(len(decks)), _bucket(max(lengths))
    cu = np.zeros((n_tests, n_samples * k))
    cv = np.zeros((n_tests, n_samples * k))
    for i, (u, v) in enumerate(zip(u_cmd, v_cmd)):
        cu[i, : len(u)] = u
        cv[i, : len(v)] = v
    # Padding lanes repeat the first test's deck with a zero command: the table rests.
    lanes = decks + [decks[0]] * (n_tests - len(decks))
    deck = DeckParams(*(np.array(values, dtype=np.float64) for values in zip(*lanes)))
    records = integrate(deck, servo_params(truth), dt,
                        cu.reshape(n_tests, n_samples, k), cv.reshape(n_tests, n_samples, k))
    names = ("u", "v", "a", "F")
    return {name: [np.asarray(rec[i, :n]) for i, n in enumerate(lengths)] for name, rec in zip(names, records)}


def simulate_response(
    truth: TableTruth,
    u_cmd,
    v_cmd,
    *,
    dt: float = 1.0 / DEFAULT_INTERNAL_RATE_HZ,
    payload_kg: float = 0.0,
) -> dict[str, np.ndarray]:
    """True (noise-free) u, v, a, F of one test driven by an arbitrary command from rest.

    u_cmd, v_cmd: displacement and velocity command at every internal step of length dt.
    No spread, no sensors, no limits checked: the low-level door for step responses,
    broadband commands and checks of the hydraulics.
    """
    u_cmd = np.asarray(u_cmd, dtype=np.float64)
    v_cmd = np.asarray(v_cmd, dtype=np.float64)
    if u_cmd.shape != v_cmd.shape or u_cmd.ndim != 1:
        raise ValueError("u_cmd and v_cmd must be one-dimensional and of equal length")
    deck = deck_of_test(truth, dict.fromkeys(("Me", "Ke", "Ce", "Fmu"), 1.0), payload_kg)
    out = _run(truth, [deck], [u_cmd], [v_cmd], dt, 1)
    return {name: values[0] for name, values in out.items()}


# the command stays inside the stroke (check_limits); a motion this far beyond it means the
# simulated servo loop itself ran away
DIVERGED_STROKE_MULTIPLE = 2.0


def _check_servo_loop(test_id: str, u: np.ndarray, truth: TableTruth) -> None:
    """Refuse a simulation whose deck motion left all bounds: an unstable servo loop.

    Why: the loop's gains (kp, kdp) are set for the preset's oil column; with a much softer
    column (a smaller bulk modulus or piston area, a larger oil volume) the same gains
    destabilise it, and the integration grew to 1e33 m without complaint (a table with the
    data-format document's example oil, f_oil 8.5 Hz, under the sst-paper gains).
    """
    peak = float(np.max(np.abs(u))) if np.all(np.isfinite(u)) else math.inf
    if peak > DIVERGED_STROKE_MULTIPLE * truth.stroke:
        try:
            resonance = f"{closed_loop_resonance_hz(truth, truth.Me):.3g} Hz"
        except ValueError:
            resonance = "not found"
        raise ValueError(
            f"test {test_id!r}: the simulated servo loop is unstable (the deck reached {peak:.3g} m "
            f"against a stroke of +/-{truth.stroke:g} m). Its gains kp = {truth.kp:g} 1/s and "
            f"kdp = {truth.kdp:g} m^3/(s*Pa) do not suit this oil column "
            f"(closed-loop resonance {resonance}): a valve-driven "
            "actuator needs kp < 2*zeta_h*omega_h; lower kp or raise kdp")


def _item_ids(items: list[PlanItem]) -> list[str]:
    ids = [item.id or f"{_ID_PREFIX[item.kind]}{i + 1:02d}" for i, item in enumerate(items)]
    if len(set(ids)) != len(ids):
        raise ValueError(f"test ids must be unique, got {ids}")
    return ids


def simulate(
    preset: str | TableTruth = "sst-paper",
    *,
    seed: int = 0,
    plan: Iterable[Any] | None = None,
    spread: float | Mapping[str, float] | None = None,
    noise: SensorNoise | Mapping[str, float] | str | None = None,
    n_cycles: int = 6,
    sample_rate_hz: float = 200.0,
    name: str | None = None,
    truth_overrides: Mapping[str, float] | None = None,
    ramp_cycles: float = DEFAULT_RAMP_CYCLES,
    rest_s: float = DEFAULT_REST_S,
    corner_rounding: float = DEFAULT_CORNER_ROUNDING,
    internal_rate_hz: float = DEFAULT_INTERNAL_RATE_HZ,
    record_velocity: bool = False,
    broadband_sample_rate_hz: float = DEFAULT_BROADBAND_RATE_HZ,
    alpha_spread: float = 0.0,
) -> Series:
    """A simulated test series of a table with known truth.

    preset : a name in PRESETS, or a TableTruth.
    seed : the only source of randomness (spread draws and sensor noise).
    plan : tests to run, each a dict, PlanItem or TestSpec-like object with kind ('sine' or
        'triangle'), frequency_hz, amplitude_m and optionally payload_kg, id and
        sample_rate_hz; or kind 'broadband' with signal ('noise' or 'earthquake') and
        optionally duration_s, peak_acceleration_m_s2, payload_kg, id, sample_rate_hz (see
        PlanItem and _broadband.py). None runs default_plan(preset). Commands beyond the
        stroke or velocity limit (for broadband tests also the acceleration limit) are refused.
    spread : relative sd of the test-to-test lognormal spread of Me, Ke, Ce, Fmu; one float
        for all four or a dict per parameter; None or 0 for none.
    alpha_spread : sd of the damping exponent's test-to-test spread, absolute: test i's
        exponent is alpha + alpha_spread*z_i, z_i ~ N(0, 1) (a damping law that is a power
        law only approximately, read over different speed ranges); 0 for none.
    noise : SensorNoise (or a dict of its fields); None for the realistic defaults; 'quiet'
        for none, so the recorded signals are exactly the simulated ones.
    n_cycles, ramp_cycles, rest_s, corner_rounding : shape of each command (see _command.py).
    sample_rate_hz : output rate of periodic tests; the integrator steps
        k = ceil(internal_rate_hz/sample_rate_hz) times per sample and records every k-th step.
    broadband_sample_rate_hz : output rate of broadband tests (default 1000 Hz, so the oil
        column's resonance near 30 Hz is well resolved). A plan item's own sample_rate_hz
        overrides either.
    truth_overrides : TableTruth fields to change, e.g. {'static_ratio': 1.5}.
    record_velocity : add a 'v' column, the true (noise-free) deck velocity.

    Series.extra['truth'] holds the population truth; each TestSpec.extra['truth'] the
    test's own force-model parameters (payload included), its open oil-column frequency
    f_oil_hz and its closed-loop resonance resonance_hz (None where the loop has no peak). A
    broadband test's TestSpec has no frequency_hz or amplitude_m; its extra holds signal,
    duration_s, peak_acceleration_m_s2, peak_displacement_m and sample_rate_hz.
    """
    truth = preset_truth(preset).replace(truth_overrides)
    if plan is None:
        if isinstance(preset, TableTruth):
            raise ValueError("a plan is needed when the preset is given as a TableTruth")
        plan = default_plan(preset)
    items = as_plan(plan)
    ids = _item_ids(items)
    noise = resolve_noise(noise)
    sds = spread_sds(spread)
    if int(n_cycles) != n_cycles or n_cycles < 1:
        raise ValueError(f"n_cycles must be a positive integer, got {n_cycles!r}")
    if not (sample_rate_hz > 0.0 and internal_rate_hz > 0.0 and broadband_sample_rate_hz > 0.0):
        raise ValueError("sample_rate_hz, broadband_sample_rate_hz and internal_rate_hz must be positive")
    rates = [item.sample_rate_hz or (broadband_sample_rate_hz if item.is_broadband else sample_rate_hz)
             for item in items]
    steps = [max(1, math.ceil(internal_rate_hz / rate - 1e-9)) for rate in rates]

    seeds = np.random.SeedSequence(seed)
    spread_seed, noise_seed = seeds.spawn(2)
    # Spawned after the first two, so periodic tests keep the streams they always had.
    (command_seed,) = seeds.spawn(1)
    factors = draw_factors(np.random.default_rng(spread_seed), len(items), sds)
    if not (math.isfinite(alpha_spread) and alpha_spread >= 0.0):
        raise ValueError(f"alpha_spread must be a non-negative sd, got {alpha_spread!r}")
    # a stream of its own, spawned last, so that every other draw stays what it was
    (exponent_seed,) = seeds.spawn(1)
    exponent_shift = alpha_spread * np.random.default_rng(exponent_seed).standard_normal(len(items))
    noise_rngs = [np.random.default_rng(s) for s in noise_seed.spawn(len(items))]
    command_rngs = [np.random.default_rng(s) for s in command_seed.spawn(len(items))]

    timing = dict(n_cycles=int(n_cycles), ramp_cycles=ramp_cycles, rest_s=rest_s)
    decks, commands, n_out, test_factor_list = [], [], [], []
    for i, item in enumerate(items):
        rate, k = rates[i], steps[i]
        dt = 1.0 / (k * rate)
        if item.is_broadband:
            n = math.ceil(broadband_duration(item.duration_s, rest_s=rest_s) * rate) + 1
            command = broadband_command(item.signal, np.arange(n * k) * dt, rng=command_rngs[i],
                                        duration_s=item.duration_s,
                                        peak_acceleration=item.peak_acceleration_m_s2, rest_s=rest_s)
        else:
            n = math.ceil(command_duration(item.frequency_hz, **timing) * rate) + 1
            command = periodic_command(item.kind, item.frequency_hz, item.amplitude_m, np.arange(n * k) * dt,
                                       corner_rounding=corner_rounding, **timing)
        check_limits(item, command, truth)
        commands.append(command)
        n_out.append(n)
        test_factors = {p: float(f[i]) for p, f in factors.items()}
        test_factors = _drifted(truth, test_factors, i / max(1, len(items) - 1))
        test_factor_list.append(test_factors)
        decks.append(deck_of_test(truth, test_factors, item.payload_kg, float(exponent_shift[i])))

    # One batched integration per output rate (tests of one batch share the step and k).
    sim: dict[str, list] = {name: [None] * len(items) for name in ("u", "v", "a", "F")}
    for rate, k in sorted(set(zip(rates, steps))):
        lanes = [i for i in range(len(items)) if rates[i] == rate and steps[i] == k]
        out = _run(truth, [decks[i] for i in lanes], [commands[i].u for i in lanes],
                   [commands[i].v for i in lanes], 1.0 / (k * rate), k)
        for column, values in out.items():
            for i, value in zip(lanes, values):
                sim[column][i] = value
    for i in range(len(items)):
        _check_servo_loop(ids[i], sim["u"][i], truth)

    tests = []
    for i, item in enumerate(items):
        rate, k = rates[i], steps[i]
        t = np.arange(n_out[i]) / rate
        force = _delayed(t, sim["F"][i], truth.force_delay)
        measured = add_sensor_noise({"u": sim["u"][i], "a": sim["a"][i], "F": force},
                                    noise, noise_rngs[i], rate)
        columns = {
            "t": t,
            "u": measured["u"],
            "F": measured["F"],
            "a": measured["a"],
            "u_cmd": commands[i].u[::k].copy(),
            "a_cmd": commands[i].a[::k].copy(),
        }
        if record_velocity:
            columns["v"] = sim["v"][i]
        extra: dict[str, Any] = {}
        if item.is_broadband:
            extra = {
                "signal": item.signal,
                "duration_s": item.duration_s,
                "peak_acceleration_m_s2": item.peak_acceleration_m_s2,
                "peak_displacement_m": float(np.max(np.abs(commands[i].u))),
                "sample_rate_hz": float(rate),
            }
        elif item.sample_rate_hz is not None:
            extra = {"sample_rate_hz": float(rate)}
        extra["truth"] = _test_truth(truth, decks[i], test_factor_list[i], item.payload_kg)
        spec = TestSpec(
            id=ids[i],
            file=f"{ids[i]}.csv",
            kind=item.kind,
            frequency_hz=item.frequency_hz,
            amplitude_m=item.amplitude_m,
            payload_kg=item.payload_kg,
            order=i + 1,
            extra=extra,
        )
        tests.append(TestRecord(spec, columns))

    preset_name = preset if isinstance(preset, str) else "custom"
    twin = {
        "preset": preset_name,
        "seed": int(seed),
        "spread": sds,
        "noise": asdict(noise),
        "n_cycles": int(n_cycles),
        "ramp_cycles": float(ramp_cycles),
        "rest_s": float(rest_s),
        "corner_rounding": float(corner_rounding),
        "sample_rate_hz": float(sample_rate_hz),
        "internal_rate_hz": max(1, math.ceil(internal_rate_hz / sample_rate_hz - 1e-9)) * float(sample_rate_hz),
        "controller": truth.controller(),
        "stribeck_velocity": truth.stribeck_velocity,
    }
    if any(item.is_broadband for item in items):
        twin["broadband_sample_rate_hz"] = float(broadband_sample_rate_hz)
    population = dict(truth.population(), resonance_hz=_resonance_or_none(truth, truth.Me))
    return Series(
        name=name or f"{preset_name}-twin-seed{seed}",
        tests=tuple(tests),
        table=truth.table_description(),
        extra={"truth": population, "twin": twin},
    )
