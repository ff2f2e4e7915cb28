"""The oil_column check: the command-to-motion response of broadband tests against a rigid table.

Per payload, the H1 frequency response H(f) of the broadband tests (bayes_sst.oil) over the
usable bins (band, coherence >= min_coherence). Base: a rigid table, H = g (one real gain).
With the effect: H = g*f_o^2/(f_o^2 - f^2 + 2j*zeta_o*f_o*f), (f_o, zeta_o) profiled on the
effect's grid, g by weighted least squares. Each bin's complex error has sd sigma_k =
eps_k*|H_k| per component (eps the random error of |H1|), so

    log L = -1/2 sum_k |H_k - model_k|^2/sigma_k^2,   score = log L(effect) - log L(base),

and score_se = sqrt(n*var(d_k)*c) with d_k the per-bin differences and c = 1 + 2*sum_j rho_j
the Hann/50 % overlap correlation of neighbouring bins (bayes_sst.oil._frf.bin_error_correlation).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bayes_sst.effects import OilColumn
from bayes_sst.io import Series

BAND_HZ = (2.0, 80.0)
MIN_COHERENCE = 0.5


def _gain(h, m, w):
    """Weighted least-squares real gain g of h ~ g*m."""
    return float(np.sum(w * np.real(np.conj(m) * h)) / np.sum(w * np.abs(m) ** 2))


def oil_column_check(series: Series, effect: OilColumn = OilColumn()) -> dict[str, Any] | None:
    """Score the oil_column effect on the series' broadband tests; None when it has none."""
    from bayes_sst.oil._frf import bin_error_correlation, frequency_response

    broadband = [r for r in series.tests if r.spec.kind == "broadband"]
    if not broadband:
        return None
    groups: dict[float, list] = {}
    for record in broadband:
        groups.setdefault(float(record.spec.payload_kg or 0.0), []).append(record)
    diffs, per_payload = [], []
    misfit_before, misfit_after, floor_sq = [], [], []
    correlation = None
    for payload, records in sorted(groups.items()):
        frf = frequency_response(records)
        f = frf.frequency_hz
        eps = frf.random_error()
        usable = ((f >= BAND_HZ[0]) & (f <= BAND_HZ[1]) & (frf.coherence >= MIN_COHERENCE)
                  & np.isfinite(eps) & (np.abs(frf.h) > 0))
        if usable.sum() < 8:
            continue
        h, f, sigma = frf.h[usable], f[usable], (eps * np.abs(frf.h))[usable]
        w = 1.0 / sigma**2
        g0 = _gain(h, np.ones_like(h), w)
        r0 = np.abs(h - g0) ** 2 * w
        best = None
        profile = []
        for setting in effect.settings():
            m = effect.frf(f, setting["oil_frequency"], setting["oil_damping"])
            g = _gain(h, m, w)
            chi2 = float(np.sum(np.abs(h - g * m) ** 2 * w))
            profile.append((setting, chi2))
            if best is None or chi2 < best[1]:
                best = (setting, chi2, g, m)
        setting, chi2, g, m = best
        r1 = np.abs(h - g * m) ** 2 * w
        diffs.append(0.5 * (r0 - r1))
        chis = np.array([c for _, c in profile])
        weights = np.exp(-0.5 * (chis - chis.min()))
        weights /= weights.sum()
        fo = np.array([s["oil_frequency"] for s, _ in profile])
        mean = float(weights @ fo)
        per_payload.append({
            "payload_kg": payload, "tests": [r.spec.id for r in records], "bins": int(usable.sum()),
            "oil_frequency": {"mean": float(setting["oil_frequency"]),
                              "sd": float(math.sqrt(max(weights @ (fo - mean) ** 2, 0.0)))},
            "oil_damping": {"mean": float(setting["oil_damping"]), "sd": 0.0},
            "gain": g, "base_gain": g0,
        })
        misfit_before.append(np.abs(h - g0) ** 2)
        misfit_after.append(np.abs(h - g * m) ** 2)
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
        "params": {"oil_frequency": head["oil_frequency"], "oil_damping": head["oil_damping"]},
        "per_payload": per_payload, "equation": effect.equation, "physics": effect.physics,
        "domain": "command-to-motion frequency response of the broadband tests",
        "rms_before": before, "rms_after": after, "noise_floor": floor, "at_bound": False,
    }
