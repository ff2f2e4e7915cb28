"""The oil_column check: the command-to-motion response of broadband tests against a table
whose loop only lags.

Per payload, the H1 frequency response H(f) of the broadband tests (bayes_sst.oil) over the
usable bins (band, coherence >= min_coherence). Base: a rigid table in a servo loop,

    H0 = g*exp(-2j*pi*f*tau)/(1 + j*f/f_c),

a loop delay tau and a first-order roll-off f_c (f_c = inf: none), profiled on grids, g by
weighted least squares. A flat H = g was the base until 2026-11-27: every closed loop lags, and
on an independent generator's clean series (valve_generator.py, seed 5: 5 ms of phase lag per
10 Hz, no resonance in the 0.5-30 Hz band) the resonance model took that lag as an oil column
at 43 Hz with damping 0.8, its grid's top, 644,000 +- 78,000 nats. With the effect:

    H = g*exp(-2j*pi*f*tau)*f_o^2/(f_o^2 - f^2 + 2j*zeta_o*f_o*f),

(f_o, zeta_o, tau) profiled (resonance_fit). The twin's closed loop (tests/test_diagnosis.py)
is described well by it: its |H| peaks at f_o*sqrt(1 - 2 zeta_o^2) within 1 % of the true
closed-loop resonance (with the roll-off in the effect's model as well, 15 % off at 25 t).
Each bin's complex error has sd sigma_k = eps_k*|H_k| per component (eps the random error of
|H1|), so

    log L = -1/2 sum_k |H_k - model_k|^2/sigma_k^2,   score = log L(effect) - log L(base),

and score_se = sqrt(n*var(d_k)*c) with d_k the per-bin differences and c = 1 + 2*sum_j rho_j
the Hann/50 % overlap correlation of neighbouring bins (bayes_sst.oil._frf.bin_error_correlation).
A resonance is only claimed where it was measured and where it is one: a best f_o outside the
usable bins, or a resonance whose |H| rises less than MIN_PEAK_RISE above its low-frequency
gain (zeta_o above 0.54; above 0.71 there is no peak at all, only a roll-off), is `at_bound`
and not selectable.

Beside each payload's fitted resonance stands the analytic f_oil of the series' table
description (bayes_sst.oil._analytic, the study's 2*beta form with V each chamber's volume,
M the described deck mass plus the payload) and the ratio f_o/f_oil, None where the
description lacks a field. It is a reading aid, not part of the rule: the study's table rang
at 28.3 Hz against 28.6 Hz analytic, a column well below its described frequency points to
entrained air or more oil than described, and descriptions differ on whether V is each
chamber's volume or both chambers' (a factor sqrt(2) in f_oil; `bayes-sst ocrf --chambers`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bayes_sst.effects import OilColumn
from bayes_sst.io import Series

BAND_HZ = (2.0, 80.0)
MIN_COHERENCE = 0.5
# A resonance is a peak: the fitted |H| must rise at least this factor over its low-frequency
# gain, 1/(2*zeta*sqrt(1 - zeta^2)) >= 1.1, i.e. zeta <= 0.54. Why: a servo loop that tracks as
# the textbook second-order response, zeta 0.7 at 20 Hz (|H| at most 1.0002 times its gain),
# was fitted at zeta 0.686, the damping grid's step below its top, and claimed as an oil
# column at 451,000 nats (2026-12-02); the oil columns of the twin and the eighth simulator
# read zeta 0.20-0.43 (|H| up 28-150 %).
MIN_PEAK_RISE = 1.10


def peak_rise(damping: float) -> float:
    """How far the resonance f_o^2/(f_o^2 - f^2 + 2j*zeta*f_o*f) lifts |H| above its value at
    f = 0: 1/(2*zeta*sqrt(1 - zeta^2)) where zeta^2 < 1/2, else 1 (no peak)."""
    if damping**2 >= 0.5:
        return 1.0
    return 1.0 / (2.0 * damping * math.sqrt(1.0 - damping**2))


DELAYS_S = np.arange(0.0, 0.0301, 0.00025)
ROLL_OFFS_HZ = np.concatenate([[np.inf], np.geomspace(2.0, 300.0, 48)])


def _gain(h, m, w):
    """Weighted least-squares real gain g of h ~ g*m (m (..., n): one gain per leading index)."""
    return np.sum(w * np.real(np.conj(m) * h), axis=-1) / np.sum(w * np.abs(m) ** 2, axis=-1)


def _best(h, w, shapes) -> tuple[int, float, float]:
    """The shape (K, n) whose real-gain fit to h has the least chi^2: (index, chi^2, gain)."""
    g = _gain(h, shapes, w)
    chi2 = np.sum(np.abs(h - g[:, None] * shapes) ** 2 * w, axis=-1)
    k = int(np.argmin(chi2))
    return k, float(chi2[k]), float(g[k])


def _delays(f):
    """exp(-2j*pi*f*tau) for every tau of DELAYS_S, (T, n)."""
    return np.exp(-2j * np.pi * DELAYS_S[:, None] * f[None, :])


def _roll_off(f, f_c):
    """1/(1 + j f/f_c), 1 for f_c = inf."""
    return 1.0 / (1.0 + 1j * f / f_c)


def loop_base(h, f, w) -> tuple[dict[str, float], float, np.ndarray]:
    """The base's best (tau, f_c) of g*exp(-2j*pi*f*tau)/(1 + j*f/f_c): settings, chi^2 and
    model values."""
    lags = _roll_off(f[None, :], ROLL_OFFS_HZ[:, None])  # (R, n)
    shapes = (_delays(f)[:, None, :] * lags[None, :, :]).reshape(-1, len(f))
    k, chi2, g = _best(h, w, shapes)
    t, r = divmod(k, len(ROLL_OFFS_HZ))
    roll_off = float(ROLL_OFFS_HZ[r])
    # None: no roll-off (the flat loop); JSON has no infinity
    return ({"delay_s": float(DELAYS_S[t]), "roll_off_hz": roll_off if np.isfinite(roll_off) else None},
            chi2, g * shapes[k])


def resonance_fit(h, f, w, effect: OilColumn):
    """The effect's model g*exp(-2j*pi*f*tau)*resonance(f_o, zeta_o), (f_o, zeta_o, tau) profiled.
    Returns (setting, tau, chi^2, model values, the (f_o, zeta_o) profile [(setting, chi^2)])."""
    delays = _delays(f)
    best, profile = None, []
    for setting in effect.settings():
        shapes = delays * effect.frf(f, setting["oil_frequency"], setting["oil_damping"])[None, :]
        k, chi2, g = _best(h, w, shapes)
        profile.append((setting, chi2))
        if best is None or chi2 < best[2]:
            best = (setting, float(DELAYS_S[k]), chi2, g * shapes[k])
    return (*best, profile)


def _analytic_beside(series: Series, payload: float, fitted_hz: float) -> dict[str, float | None]:
    """The described table's analytic f_oil at this payload and the fitted f_o's ratio to it."""
    from bayes_sst.oil._analytic import analytic_oil_frequency, missing_for_analytic

    if missing_for_analytic(series.table):
        return {"analytic_frequency_hz": None, "analytic_ratio": None}
    analytic = analytic_oil_frequency(series.table, payload)
    return {"analytic_frequency_hz": analytic, "analytic_ratio": fitted_hz / analytic}


def oil_column_check(series: Series, effect: OilColumn = OilColumn(),
                     skipped: list[str] | None = None) -> dict[str, Any] | None:
    """Score the oil_column effect on the series' broadband tests that record a command; None
    when it has none, or none that gives a frequency response. skipped, where given, receives
    why a payload's tests gave none (a test shorter than one Welch segment, rates whose bins
    do not line up); the diagnosis notes it rather than stopping there."""
    from bayes_sst.oil._frf import bin_error_correlation, frequency_response, has_command

    broadband = [r for r in series.tests if r.spec.kind == "broadband" and has_command(r)]
    if not broadband:
        return None
    groups: dict[float, list] = {}
    for record in broadband:
        groups.setdefault(float(record.spec.payload_kg or 0.0), []).append(record)
    diffs, per_payload = [], []
    misfit_before, misfit_after, floor_sq = [], [], []
    correlation = None
    for payload, records in sorted(groups.items()):
        try:
            frf = frequency_response(records)
        except ValueError as exc:
            if skipped is not None:
                skipped.append(f"broadband tests {[r.spec.id for r in records]} at {payload:g} kg payload give no "
                               f"frequency response ({exc}); the oil column is not checked on them")
            continue
        f = frf.frequency_hz
        eps = frf.random_error()
        usable = ((f >= BAND_HZ[0]) & (f <= BAND_HZ[1]) & (frf.coherence >= MIN_COHERENCE)
                  & np.isfinite(eps) & (np.abs(frf.h) > 0))
        if usable.sum() < 8:
            continue
        h, f, sigma = frf.h[usable], f[usable], (eps * np.abs(frf.h))[usable]
        w = 1.0 / sigma**2
        base_setting, _, base_model = loop_base(h, f, w)
        r0 = np.abs(h - base_model) ** 2 * w
        setting, delay, _, model, profile = resonance_fit(h, f, w, effect)
        r1 = np.abs(h - model) ** 2 * w
        diffs.append(0.5 * (r0 - r1))
        chis = np.array([c for _, c in profile])
        weights = np.exp(-0.5 * (chis - chis.min()))
        weights /= weights.sum()
        fo = np.array([s["oil_frequency"] for s, _ in profile])
        mean = float(weights @ fo)
        outside = not (f.min() <= setting["oil_frequency"] <= f.max())
        rise = peak_rise(setting["oil_damping"])
        flat = rise < MIN_PEAK_RISE
        per_payload.append({
            "payload_kg": payload, "tests": [r.spec.id for r in records], "bins": int(usable.sum()),
            "band_hz": [float(f.min()), float(f.max())],
            "oil_frequency": {"mean": float(setting["oil_frequency"]),
                              "sd": float(math.sqrt(max(weights @ (fo - mean) ** 2, 0.0)))},
            "oil_damping": {"mean": float(setting["oil_damping"]), "sd": 0.0},
            # where |H| peaks, f_o*sqrt(1 - 2 zeta^2): what a measured frequency response shows
            "peak_frequency_hz": (float(setting["oil_frequency"] * math.sqrt(1.0 - 2.0 * setting["oil_damping"] ** 2))
                                  if setting["oil_damping"] ** 2 < 0.5 else None),
            **_analytic_beside(series, payload, float(setting["oil_frequency"])),
            "delay_s": delay, "base": base_setting,
            "peak_rise": rise,
            "at_bound": bool(outside or flat),
            "bound": "frequency outside the measured band" if outside else (
                f"no resonance peak: |H| rises {100 * (rise - 1):.1f} % (under {100 * (MIN_PEAK_RISE - 1):.0f} %)"
                if flat else None),
        })
        misfit_before.append(np.abs(h - base_model) ** 2)
        misfit_after.append(np.abs(h - model) ** 2)
        floor_sq.append(sigma**2 * 2.0)
        if correlation is None:
            rho = bin_error_correlation(frf.segment_samples)
            correlation = float(1.0 + 2.0 * np.sum(rho[1:]))
    if not diffs:
        return None
    d = np.concatenate(diffs)
    score = float(d.sum())
    se = float(math.sqrt(len(d) * np.var(d, ddof=1) * correlation))
    before = float(np.sqrt(np.mean(np.concatenate(misfit_before))))
    after = float(np.sqrt(np.mean(np.concatenate(misfit_after))))
    floor = float(np.sqrt(np.mean(np.concatenate(floor_sq))))
    head = per_payload[0]
    return {
        "name": effect.name, "score": score, "score_se": se, "z": score / se if se > 0 else None,
        # the first payload's: the resonance as fitted, and where |H| peaks (what a measured
        # frequency response, such as the study's 28.3 Hz, shows), None without a peak
        "params": {"oil_frequency": head["oil_frequency"], "oil_damping": head["oil_damping"],
                   **({"peak_frequency": {"mean": head["peak_frequency_hz"], "sd": head["oil_frequency"]["sd"]}}
                      if head["peak_frequency_hz"] is not None else {})},
        "per_payload": per_payload, "equation": effect.equation, "physics": effect.physics,
        "domain": "command-to-motion frequency response of the broadband tests",
        "rms_before": before, "rms_after": after, "noise_floor": floor,
        "at_bound": any(p["at_bound"] for p in per_payload),
    }
