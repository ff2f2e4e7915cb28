"""simulate(): a campaign of periodic tests on the twin table, as an in-memory Series.

For each planned test: the command (analytic, at the internal rate), the test's own
parameters (population truth times its spread factors, payload added to the mass and to
the bearings' normal force), one batched JAX integration of all tests, then the sensors.
Every random number comes from numpy Generators seeded by `seed` alone: one stream for the
spread draws and one per test for its sensor noise, so that switching the noise or the
spread does not move the other.
"""

from __future__ import annotations

import math
from dataclasses import asdict
from typing import Any, Iterable, Mapping

import numpy as np

from bayes_sst.io import Series, TestRecord, TestSpec
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
from bayes_sst.twin._noise import SensorNoise, add_sensor_noise, resolve_noise
from bayes_sst.twin._plan import PlanItem, as_plan, check_limits, default_plan
from bayes_sst.twin._spread import draw_factors, spread_sds
from bayes_sst.twin._truth import TableTruth, preset_truth

DEFAULT_INTERNAL_RATE_HZ = 4000.0


def _bucket(n: int) -> int:
    """n rounded up to a multiple of 2**(bit_length(n) - 4), at most 1/8 more than n, so
    that series of similar size share one compiled integrator."""
    if n <= 4:
        return n
    step = 2 ** max(0, n.bit_length() - 4)
    return -(-n // step) * step


def deck_of_test(truth: TableTruth, factors: Mapping[str, float], payload_kg: float) -> DeckParams:
    """The deck of one test: population truth times spread factors, payload on the deck."""
    fmu = truth.friction_with_payload(truth.Fmu * factors["Fmu"], payload_kg)
    return DeckParams(
        mass=truth.Me * factors["Me"] + payload_kg,
        Ke=truth.Ke * factors["Ke"],
        Ce=truth.Ce * factors["Ce"],
        alpha=truth.alpha,
        Fk=fmu,
        Fs=truth.static_ratio * fmu,
        stribeck_velocity=truth.stribeck_velocity,
    )


def _test_truth(truth: TableTruth, deck: DeckParams, factors: Mapping[str, float],
                payload_kg: float) -> dict[str, float]:
    """What the force model of this test should identify (payload included), plus the empty deck."""
    return {
        "Me": float(deck.mass),
        "Ke": float(deck.Ke),
        "Ce": float(deck.Ce),
        "alpha": float(deck.alpha),
        "Fmu": float(deck.Fk),
        "static_ratio": truth.static_ratio,
        "f_oil_hz": truth.f_oil_hz(float(deck.mass)),
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


def _item_ids(items: list[PlanItem]) -> list[str]:
    ids = [item.id or f"{'S' if item.kind == 'sine' else 'T'}{i + 1:02d}" for i, item in enumerate(items)]
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
) -> Series:
    """A simulated test series of a table with known truth.

    preset : a name in PRESETS, or a TableTruth.
    seed : the only source of randomness (spread draws and sensor noise).
    plan : tests to run, each a dict, PlanItem or TestSpec-like object with kind ('sine' or
        'triangle'), frequency_hz, amplitude_m and optionally payload_kg and id; None runs
        default_plan(preset). Commands beyond the stroke or velocity limit are refused.
    spread : relative sd of the test-to-test lognormal spread of Me, Ke, Ce, Fmu; one float
        for all four or a dict per parameter; None or 0 for none.
    noise : SensorNoise (or a dict of its fields); None for the realistic defaults; 'quiet'
        for none, so the recorded signals are exactly the simulated ones.
    n_cycles, ramp_cycles, rest_s, corner_rounding : shape of each command (see _command.py).
    sample_rate_hz : output rate; the integrator steps k = ceil(internal_rate_hz/sample_rate_hz)
        times per sample and records every k-th step.
    truth_overrides : TableTruth fields to change, e.g. {'static_ratio': 1.5}.
    record_velocity : add a 'v' column, the true (noise-free) deck velocity.

    Series.extra['truth'] holds the population truth; each TestSpec.extra['truth'] the
    test's own force-model parameters (payload included).
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
    if not (sample_rate_hz > 0.0 and internal_rate_hz > 0.0):
        raise ValueError("sample_rate_hz and internal_rate_hz must be positive")
    k = max(1, math.ceil(internal_rate_hz / sample_rate_hz - 1e-9))
    dt = 1.0 / (k * sample_rate_hz)

    seeds = np.random.SeedSequence(seed)
    spread_seed, noise_seed = seeds.spawn(2)
    factors = draw_factors(np.random.default_rng(spread_seed), len(items), sds)
    noise_rngs = [np.random.default_rng(s) for s in noise_seed.spawn(len(items))]

    timing = dict(n_cycles=int(n_cycles), ramp_cycles=ramp_cycles, rest_s=rest_s)
    decks, commands, n_out, test_factor_list = [], [], [], []
    for i, item in enumerate(items):
        n = math.ceil(command_duration(item.frequency_hz, **timing) * sample_rate_hz) + 1
        t_internal = np.arange(n * k) * dt
        command = periodic_command(item.kind, item.frequency_hz, item.amplitude_m, t_internal,
                                   corner_rounding=corner_rounding, **timing)
        check_limits(item, command, truth)
        commands.append(command)
        n_out.append(n)
        test_factors = {p: float(f[i]) for p, f in factors.items()}
        test_factor_list.append(test_factors)
        decks.append(deck_of_test(truth, test_factors, item.payload_kg))

    sim = _run(truth, decks, [c.u for c in commands], [c.v for c in commands], dt, k)

    tests = []
    for i, item in enumerate(items):
        t = np.arange(n_out[i]) / sample_rate_hz
        measured = add_sensor_noise({"u": sim["u"][i], "a": sim["a"][i], "F": sim["F"][i]},
                                    noise, noise_rngs[i], sample_rate_hz)
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
        spec = TestSpec(
            id=ids[i],
            file=f"{ids[i]}.csv",
            kind=item.kind,
            frequency_hz=item.frequency_hz,
            amplitude_m=item.amplitude_m,
            payload_kg=item.payload_kg,
            order=i + 1,
            extra={"truth": _test_truth(truth, decks[i], test_factor_list[i], item.payload_kg)},
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
        "internal_rate_hz": k * float(sample_rate_hz),
        "controller": truth.controller(),
        "stribeck_velocity": truth.stribeck_velocity,
    }
    return Series(
        name=name or f"{preset_name}-twin-seed{seed}",
        tests=tuple(tests),
        table=truth.table_description(),
        extra={"truth": truth.population(), "twin": twin},
    )
