"""design(): which tests to add to a fitted series, and how many, to reach target precisions.

1. The run's posterior draws and its tests' regressors give, per draw, the exact Gaussian
   pieces of the collapsed model (see _engine.py).
2. Candidates (a grid inside the table's limits, or a file) get the regressors the fit would
   build from them (_signals.py).
3. A greedy search on the Fisher approximation orders them (_search.py).
4. A preposterior simulation (draw outcomes from the posterior predictive, reweight the
   draws, read the 90 % intervals) predicts each target's half-width against the number
   of added tests, for the recommended list and for repeating the series' own plan.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from bayes_sst.design._candidates import (
    Candidate,
    TableLimits,
    candidate_grid,
    limit_violations,
    table_limits,
)
from bayes_sst.design._engine import (
    PARAMETERS,
    Z90,
    NewTest,
    alpha_grid_for,
    design_posterior,
    existing_terms,
    fisher_information,
    half_widths_from_draws,
    ignored_outer,
    noise_sources,
    preposterior_curve,
    widening_factors,
    regressor_columns,
)
from bayes_sst.design._search import cycled, greedy_design
from bayes_sst.design._signals import candidate_test
from bayes_sst.inference._statistics import COEFFICIENTS

DEFAULT_MAX_TESTS = 40
DEFAULT_OUTCOMES = 64
DEFAULT_DRAWS = 1000
FISHER_DRAWS = 128
LOW_ESS = 20.0


def parse_target(text: str) -> tuple[str, float]:
    """'Ke=2%' or 'Ke=0.02' -> ('Ke', 0.02): a relative half-width of the 90 % interval."""
    name, sep, value = text.partition("=")
    name = name.strip()
    if not sep or name not in PARAMETERS:
        raise ValueError(f"--target {text!r}: expected NAME=VALUE with NAME one of {', '.join(PARAMETERS)} "
                         "(for example Ke=2%)")
    value = value.strip()
    try:
        number = float(value[:-1]) / 100.0 if value.endswith("%") else float(value)
    except ValueError:
        raise ValueError(f"--target {text!r}: {value!r} is not a number or a percentage") from None
    if not (math.isfinite(number) and 0.0 < number < 1.0):
        raise ValueError(f"--target {text!r}: the relative half-width must lie between 0 and 100 %")
    return name, number


@dataclass
class DesignResult:
    """Everything `bayes-sst design` reports; to_json() is design.json."""

    targets: dict[str, float]
    current: dict[str, float]
    recommended: list[Candidate]
    repeat_plan: list[Candidate]
    curve: list[dict[str, Any]]
    curve_repeat: list[dict[str, Any]]
    n_needed: int | None
    n_needed_repeat: int | None
    reason: str | None
    floor: dict[str, dict[str, float]]
    limits: TableLimits
    n_candidates: int
    rejected: list[dict[str, Any]]
    fisher_path: list[dict[str, float]]
    settings: dict[str, Any]
    diagnostics: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {
            "targets": self.targets,
            "current": self.current,
            "recommended": [c.to_json() for c in self.recommended],
            "curve": self.curve,
            "n_needed": self.n_needed,
            "reachable": self.n_needed is not None,
            "reason": self.reason,
            "repeat_plan": {
                "tests": [c.to_json() for c in self.repeat_plan],
                "curve": self.curve_repeat,
                "n_needed": self.n_needed_repeat,
            },
            "floor": self.floor,
            "limits": self.limits.to_json(),
            "candidates": {"considered": self.n_candidates, "rejected_for_limits": self.rejected},
            "fisher_search": self.fisher_path,
            "settings": self.settings,
            "diagnostics": self.diagnostics,
            "definitions": {
                "half_width": "(q95 - q05)/2 / posterior mean, relative (alpha too)",
                "curve": "predicted half-width after adding the first n_added tests: q10, q50, q90 over "
                         "possible outcomes (posterior predictive), from the preposterior reweighting",
                "n_needed": "smallest n_added whose median (q50) predicted half-width meets every target",
            },
        }


def _curve_rows(half: np.ndarray, names: Sequence[str]) -> list[dict[str, Any]]:
    """[{n_added, name: {q10, q50, q90}}] from half (R, N+1, 5)."""
    q = np.quantile(half, [0.1, 0.5, 0.9], axis=0)  # (3, N+1, 5)
    rows = []
    for n in range(half.shape[1]):
        row: dict[str, Any] = {"n_added": n}
        for name in names:
            k = PARAMETERS.index(name)
            row[name] = {"q10": float(q[0, n, k]), "q50": float(q[1, n, k]), "q90": float(q[2, n, k])}
        rows.append(row)
    return rows


def _n_needed(rows: list[dict[str, Any]], targets: Mapping[str, float]) -> int | None:
    for row in rows:
        if all(row[name]["q50"] <= target for name, target in targets.items()):
            return int(row["n_added"])
    return None


def spread_floor(post, n_total: int) -> dict[str, dict[str, float]]:
    """The between-test floor: with J tests, however informative each, the population value
    is known no better than rho/sqrt(J), so the half-width cannot fall below
    Z90 * rho_k / sqrt(J) / |mu_k| (posterior median of rho_k/mu_k)."""
    out = {}
    ignored = post.ignored_spread if post.ignored_spread is not None else np.zeros(len(COEFFICIENTS))
    for k, name in enumerate(COEFFICIENTS):
        # a shared coefficient's ignored spread is between-test variation all the same
        relative = float(np.median(np.hypot(post.rho[:, k] / np.abs(post.mu[:, k]), ignored[k])))
        out[name] = {
            "relative_spread": relative,
            "half_width_floor": Z90 * relative / math.sqrt(n_total),
            "n_tests_total": n_total,
        }
    return out


def _reason(targets, rows, floor, n_existing: int, max_tests: int) -> str:
    last = rows[-1]
    parts = []
    for name, target in targets.items():
        if last[name]["q50"] <= target:
            continue
        text = f"{name}: predicted {last[name]['q50']:.2%} after {max_tests} added tests, target {target:.2%}"
        if name in floor:
            rel = floor[name]["relative_spread"]
            low = floor[name]["half_width_floor"]
            needed_total = math.ceil((Z90 * rel * floor[name].get("widening", 1.0) / target) ** 2)
            if low >= target:
                text += (f"; its test-to-test variation ({rel:.2%} sd) alone sets a floor of {low:.2%} with "
                         f"{n_existing + max_tests} tests, which more samples per test cannot lower: "
                         f"{target:.2%} needs at least {needed_total} tests in all")
            elif low > 0.5 * target:
                text += (f"; most of what remains is test-to-test variation ({rel:.2%} sd; floor {low:.2%} with "
                         f"{n_existing + max_tests} tests), which only more tests, not longer ones, reduce: "
                         f"{target:.2%} needs at least {needed_total} tests in all, likely more")
            else:
                text += "; the candidates add too little information per test (longer tests or other candidates may help)"
        parts.append(text)
    return f"not reachable within {max_tests} tests: " + "; ".join(parts)


def design(
    tree,
    *,
    targets: Mapping[str, float],
    max_tests: int = DEFAULT_MAX_TESTS,
    candidates: Sequence[Candidate] | None = None,
    series=None,
    limit_overrides: Mapping[str, float | None] | None = None,
    n_outcomes: int = DEFAULT_OUTCOMES,
    n_draws: int = DEFAULT_DRAWS,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
) -> DesignResult:
    """Recommend the next tests for a fitted run (see the module docstring).

    tree: the run's DataTree (read_run_tree). targets: {parameter: relative half-width}.
    series: the run's Series (default: read from the folder the run records).
    """
    from bayes_sst.inference import run_prepared, run_signal_options
    from bayes_sst.inference._predictive import run_series

    say = progress or (lambda message: None)
    started = time.perf_counter()
    if not targets:
        raise ValueError("give at least one target, for example --target Ke=2%")
    if max_tests < 1:
        raise ValueError(f"--max-tests must be at least 1, got {max_tests}")
    if series is None:
        series = run_series(tree, "design")
    prepared = run_prepared(tree, series)
    options = run_signal_options(tree)
    full = design_posterior(tree, prepared)
    widening = widening_factors(tree)
    # the search reads the model's predicted intervals, which the widening then stretches
    model_targets = {name: target / widening[PARAMETERS.index(name)] for name, target in targets.items()}
    pick = np.unique(np.linspace(0, full.n_draws - 1, min(n_draws, full.n_draws)).round().astype(int))
    post = full.subset(pick)
    means = {name: float(np.mean(post.mu[:, k]) * post.scale[k]) for k, name in enumerate(COEFFICIENTS)}
    means["alpha"] = float(np.mean(post.alpha))
    limits = table_limits(series.table, **dict(limit_overrides or {}))

    if candidates is None:
        candidates = candidate_grid(limits, means)
    accepted, rejected = [], []
    for c in candidates:
        problems = limit_violations(c, limits, means)
        if problems:
            rejected.append({**c.to_json(), "why": "; ".join(problems)})
        else:
            accepted.append(c)
    if not accepted:
        raise ValueError(f"every one of the {len(candidates)} candidates exceeds the table's limits "
                         f"({limits.to_json()}); first: {rejected[0]['why']}")
    accepted = list(dict.fromkeys(accepted))
    n_cycles = int(np.median([t.window.n_cycles for t in prepared]))
    rate = float(np.median([t.sample_rate_hz for t in prepared]))
    grid = alpha_grid_for(post.alpha)
    say(f"{len(prepared)} recorded tests, {post.n_draws} posterior draws, {len(accepted)} candidates "
        f"({len(rejected)} outside the limits), alpha grid {grid[0]:.3f}-{grid[-1]:.3f}")

    noise_mass = float(np.mean(post.mu[:, 0]) * post.scale[0])

    def columns_of(test):
        return regressor_columns(test, grid, post.scale, post.force_scale, noise_mass)

    old_columns = [columns_of(t) for t in prepared]
    responses = [(t.F - t.payload_kg * t.a) / post.force_scale for t in prepared]
    old, old_ignored = existing_terms(post, old_columns, responses, with_ignored=True)
    repeat = cycled([Candidate(t.kind, t.frequency_hz, t.amplitude_m) for t in prepared], max_tests)
    unique = list(dict.fromkeys(list(accepted) + repeat))
    built = {}
    # candidates are recorded the way most of the series' tests were: with or without an accelerometer
    accelerometer = 2 * sum(t.acceleration_measured for t in prepared) >= len(prepared)
    for i, c in enumerate(unique):
        test = candidate_test(c, n_cycles=n_cycles, sample_rate_hz=rate, coefficients=means, options=options,
                              test_id=f"C{i + 1:03d}", accelerometer=accelerometer)
        built[c] = columns_of(test)
    twins = dict(zip(unique, noise_sources(prepared, [c.kind for c in unique], [c.frequency_hz for c in unique],
                                           [c.amplitude_m for c in unique])))
    say(f"candidate signals built ({time.perf_counter() - started:.1f} s)")

    fisher_pick = np.unique(np.linspace(0, post.n_draws - 1, min(FISHER_DRAWS, post.n_draws)).round().astype(int))
    fpost = post.subset(fisher_pick)
    # every draw's information is its own, so the search's draws take their rows of the whole set's
    old_info = [fisher_information(post, cols, j) for j, cols in enumerate(old_columns)]
    base_all = sum(old_info)
    base = base_all[fisher_pick]
    # the search's draws only: ignored_outer reads each draw's own mu
    base_ignored = (None if post.ignored_spread is None
                    else sum(ignored_outer(fpost, info[fisher_pick]) for info in old_info))
    cand_info = np.stack([fisher_information(fpost, built[c], twins[c]) for c in accepted])
    chosen, fisher_path = greedy_design(fpost, base, cand_info, model_targets, max_tests, base_ignored=base_ignored)
    recommended = [accepted[i] for i in chosen]
    say(f"greedy search done ({time.perf_counter() - started:.1f} s)")

    half_rec, ess_rec = preposterior_curve(post, old, [NewTest(built[c], twins[c]) for c in recommended],
                                           n_outcomes=n_outcomes, seed=seed, base_info=base_all,
                                           old_ignored=old_ignored)
    say(f"preposterior of the recommended tests done ({time.perf_counter() - started:.1f} s)")
    half_rep, ess_rep = preposterior_curve(post, old, [NewTest(built[c], twins[c]) for c in repeat],
                                           n_outcomes=n_outcomes, seed=seed + 1, base_info=base_all,
                                           old_ignored=old_ignored)
    say(f"preposterior of the repeated plan done ({time.perf_counter() - started:.1f} s)")

    curve = _curve_rows(half_rec * widening, PARAMETERS)
    curve_repeat = _curve_rows(half_rep * widening, PARAMETERS)
    n_needed = _n_needed(curve, targets)
    n_needed_repeat = _n_needed(curve_repeat, targets)
    floor = spread_floor(post, len(prepared) + max_tests)
    for name, entry in floor.items():
        entry["widening"] = float(widening[PARAMETERS.index(name)])
        entry["half_width_floor"] *= entry["widening"]
    reason = None if n_needed is not None else _reason(targets, curve, floor, len(prepared), max_tests)
    ess_median = np.median(ess_rec, axis=0)
    diagnostics = {
        "importance_ess_median": {"n_added": list(range(max_tests + 1)), "recommended": ess_median.tolist(),
                                  "repeat_plan": np.median(ess_rep, axis=0).tolist()},
        "seconds": time.perf_counter() - started,
    }
    low = [n for n, e in enumerate(ess_median) if e < LOW_ESS]
    if low:
        diagnostics["warning"] = (
            f"from {low[0]} added tests on, the reweighted posterior rests on fewer than {LOW_ESS:g} effective "
            "draws: alpha's predicted interval is coarse there and the others may be somewhat narrow; "
            "refit after the first tests and design again")
    return DesignResult(
        targets=dict(targets),
        current={name: value * widening[PARAMETERS.index(name)] for name, value in half_widths_from_draws(full).items()},
        recommended=recommended,
        repeat_plan=repeat,
        curve=curve,
        curve_repeat=curve_repeat,
        n_needed=n_needed,
        n_needed_repeat=n_needed_repeat,
        reason=reason,
        floor=floor,
        limits=limits,
        n_candidates=len(candidates),
        rejected=rejected,
        fisher_path=[{name: float(row[k] * widening[k]) for k, name in enumerate(PARAMETERS)} | {"n_added": n}
                     for n, row in enumerate(fisher_path)],
        settings={"max_tests": max_tests, "n_outcomes": n_outcomes, "n_draws": post.n_draws,
                  "fisher_draws": fpost.n_draws, "seed": seed, "n_cycles_per_test": n_cycles,
                  "sample_rate_hz": rate, "n_existing_tests": len(prepared)},
        diagnostics=diagnostics,
    )


def format_design(data: Mapping[str, Any]) -> str:
    """The text a lab engineer reads, from design.json's content."""
    lines = ["Design of the next tests", ""]
    lines.append("Current half-width of the 90 % interval (relative to the posterior mean):")
    for name, value in data["current"].items():
        mark = f"   target {data['targets'][name]:.2%}" if name in data["targets"] else ""
        lines.append(f"  {name:<6} {value:8.2%}{mark}")
    lines.append("")
    rows = data["curve"]
    rep = data["repeat_plan"]["curve"]
    if data["n_needed"] is not None:
        lines.append(f"Targets met (median outcome) after {data['n_needed']} recommended added tests; "
                     + (f"repeating the series' plan needs {data['repeat_plan']['n_needed']}."
                        if data["repeat_plan"]["n_needed"] is not None
                        else f"repeating the series' plan does not reach them within {len(rows) - 1}."))
    else:
        lines.append(data["reason"])
    lines.append("")
    n_show = len(rows) - 1 if data["n_needed"] is None else max(data["n_needed"], 1)
    n_show = min(len(data["recommended"]), max(n_show, 5))
    lines.append("Recommended tests, in order:")
    for i, c in enumerate(data["recommended"][:n_show], 1):
        lines.append(f"  {i:3d}. {c['kind']:<8} {c['frequency_hz']:6.3g} Hz  {c['amplitude_m'] * 1000:7.3g} mm")
    if n_show < len(data["recommended"]):
        lines.append(f"  ... {len(data['recommended']) - n_show} more in design.json")
    lines.append("")
    names = list(data["targets"])
    header = "  added " + "".join(f"{name + ' recommended q50 [q10-q90]':>36}{name + ' repeat q50':>16}" for name in names)
    lines.append("Predicted half-width against added tests:")
    lines.append(header)
    marks = sorted(set([0, 1, 2, 5, 10, 15, 20, 30, 40, len(rows) - 1] + ([data["n_needed"]] if data["n_needed"] else [])))
    for n in marks:
        if n >= len(rows):
            continue
        cells = ""
        for name in names:
            r = rows[n][name]
            cells += f"{r['q50']:14.2%} [{r['q10']:7.2%}-{r['q90']:7.2%}]".rjust(36) + f"{rep[n][name]['q50']:16.2%}"
        lines.append(f"  {n:5d} " + cells)
    warning = data.get("diagnostics", {}).get("warning")
    if warning:
        lines += ["", "Note: " + warning]
    return "\n".join(lines)
