"""A fifth, independent simulator of a servo-hydraulic shaking table.

Written from the data format and first principles only (no code of bayes_sst is used or read),
to test the package blind.  Physics, integrated with a fixed 0.1-0.2 ms step (semi-implicit
Euler), every test of a series at once (vectorised over tests):

* Servo-valve: second-order spool (40-80 Hz, damping 0.6-0.8), saturating at +-1, turbulent
  orifice flow Q = Qmax * xv * sqrt((Ps - sign(xv) * P_L) / Ps).
* Oil column: load pressure P_L of a double-ended actuator,
  dP_L/dt = 4*beta/V * (Q - Ap*v - C_leak*P_L), actuator force Ap*P_L (this is what the load
  cell reads, with noise).  beta, Ap, V are drawn so that the oil-column resonance with the
  deck mass is 20-35 Hz; cross-port leakage gives it a few per cent damping.
* Deck: mass Me (+ payload), gas-strut stiffness Ke (+ optional cubic K3*u^3), power-law
  damping Ce*|v|^alpha, Coulomb friction Fk = mu*(F_hd + (m_deck + payload)*g) with an explicit
  stick/slip state machine: a deck at rest stays at rest while |net other force| <= Fs
  (+ hinge friction), Fs = Fk ... 1.03 Fk on clean tables with a Stribeck drop
  Fk + (Fs - Fk) * exp(-(|v|/vs)^2) when sliding.  A velocity sign change inside a step either
  sticks (force below the static capacity) or goes on sliding.
* Controller: three-variable control, displacement PI + velocity feed-forward + acceleration
  feed-forward/feedback + load-pressure (delta-P) feedback damping the oil column.  The deck
  follows what the physics gives, not the command.
* Commands: sines and rounded triangles, raised-cosine ramp in/out of 1.5-3 cycles, 5-12
  steady cycles, capped at 0.5 m/s and 8 m/s^2.
* Sensors, sampled by taking every k-th step (no filtering): LVDT (white noise, quantisation,
  offset), accelerometer (noise, offset), load cell (AR(1) coloured noise, 50 Hz hum, offset),
  optional velocity transducer.
* Test-to-test variation of Me, Ke, Ce, Fk (1-3 % sd, independent); truth = population values.
* Effects (one at a time): stiction, channel_delay, specimen, nonlinear_stiffness,
  position_friction, drift.

make_series(seed, out_dir, effect=None, size=None, truth_path=None) writes the series folder
and returns the truth dictionary.
"""
from __future__ import annotations

import argparse
import json
import os

import numpy as np

G = 9.81


def _ramp_env(t, T, n_in, n_steady, n_out, t0):
    """Raised-cosine envelope: 0 before t0, rising over n_in periods, flat, falling over n_out."""
    tt = (t - t0) / T
    env = np.zeros_like(t)
    a = (tt >= 0) & (tt < n_in)
    env[a] = 0.5 * (1 - np.cos(np.pi * tt[a] / n_in))
    b = (tt >= n_in) & (tt < n_in + n_steady)
    env[b] = 1.0
    c = (tt >= n_in + n_steady) & (tt < n_in + n_steady + n_out)
    env[c] = 0.5 * (1 + np.cos(np.pi * (tt[c] - n_in - n_steady) / n_out))
    return env


def _command(kind, f, A, t, n_in, n_steady, n_out, t0, round_frac):
    T = 1.0 / f
    env = _ramp_env(t, T, n_in, n_steady, n_out, t0)
    ph = 2 * np.pi * f * (t - t0)
    if kind == "sine":
        base = np.sin(ph)
    else:
        # triangle (starting at 0 going up) with rounded corners: convolve with a Hann window
        x = ((t - t0) * f + 0.25) % 1.0
        tri = np.where(x < 0.5, 4 * x - 1, 3 - 4 * x)
        dt = t[1] - t[0]
        w = max(3, int(round(round_frac * T / dt)) | 1)
        win = np.hanning(w)
        win /= win.sum()
        pad = w
        # periodic extension for the convolution
        tri_p = np.concatenate([tri[-pad:], tri, tri[:pad]]) if len(tri) > 2 * pad else tri
        sm = np.convolve(tri_p, win, mode="same")
        base = sm[pad:-pad] if len(tri) > 2 * pad else sm
        base = base / np.max(np.abs(base))
    u = A * env * base
    dt = t[1] - t[0]
    v = np.gradient(u, dt)
    a = np.gradient(v, dt)
    return u, v, a


def _ar1(rng, n, sd, phi):
    e = rng.normal(0, sd * np.sqrt(1 - phi ** 2), n)
    out = np.empty(n)
    acc = rng.normal(0, sd)
    for i in range(n):  # n ~ 1e4-1e5, fine
        acc = phi * acc + e[i]
        out[i] = acc
    return out


def _draw_tests(rng, n_tests, n_payload):
    tests = []
    for i in range(n_tests):
        kind = "triangle" if (i % 7 == 3) else "sine"
        for _ in range(200):
            f = float(np.exp(rng.uniform(np.log(0.2), np.log(6.0))))
            A = float(np.exp(rng.uniform(np.log(0.005), np.log(0.12))))
            if kind == "sine":
                vmax, amax = 2 * np.pi * f * A, (2 * np.pi * f) ** 2 * A
            else:
                vmax, amax = 4 * A * f, 2 * 4 * A * f / (0.12 / f)
            if vmax <= 0.5 and amax <= 8.0 and vmax >= 0.02:
                break
        else:
            A = min(A, 0.5 / (2 * np.pi * f), 8.0 / (2 * np.pi * f) ** 2)
        n_steady = int(rng.integers(5, 13))
        if f < 0.5:
            n_steady = min(n_steady, 6)
        tests.append(dict(kind=kind, f=f, A=A, n_in=float(rng.uniform(1.5, 3.0)),
                          n_out=float(rng.uniform(1.5, 3.0)), n_steady=n_steady,
                          round_frac=float(rng.uniform(0.08, 0.14)), payload=0.0))
    for i in rng.choice(n_tests, size=n_payload, replace=False):
        tests[i]["payload"] = float(rng.uniform(1000, 4000))
    return tests


def make_series(seed, out_dir, effect=None, size=None, truth_path=None, name=None,
                n_tests=None, verbose=False, overrides=None, dry_run=False):
    """Simulate one series into out_dir (created); return the truth dictionary.

    effect: None, 'stiction' (size = Fs/Fk), 'channel_delay' (size = delay in s),
    'specimen' (size = mass in kg), 'nonlinear_stiffness' (size = K3 u^3 / Ke u at the largest
    amplitude), 'position_friction' (size = hinge share of Fk at the largest amplitude),
    'drift' (size = fall of friction and damping over the campaign).
    overrides: replace draws after they are made, so every other draw stays the same: 'spread'
    (relative sd of the test-to-test variation; 'spread_Me', 'spread_Ke', 'spread_Ce', 'spread_mu'
    for one parameter), 'spread_seed' (the per-test factors drawn from a stream of their own),
    'static_ratio' (Fs/Fk of a clean table), 'quiet' (true: ideal sensors), one sensor's noise
    ('u_noise', 'u_q', 'a_noise', 'F_noise', 'F_hum', 'v_noise'),
    and the loop's 'Kdp', 'Ka', 'Kp', 'f_valve', 'f_oil'.
    """
    rng = np.random.default_rng(seed + 1000 * (1 + ["None", "stiction", "channel_delay", "specimen",
                                                      "nonlinear_stiffness", "position_friction",
                                                      "drift"].index(str(effect))))
    # ---- table population values
    Me = rng.uniform(11e3, 15e3)
    m_deck = Me * rng.uniform(0.88, 0.97)
    Ke = rng.uniform(0.55e6, 0.9e6)
    alpha = rng.uniform(0.35, 0.7)
    Ce = rng.uniform(10e3, 25e3) / 0.3 ** alpha
    mu = rng.uniform(0.008, 0.016)
    F_hd = rng.uniform(0.5e6, 1.0e6)
    Fk0 = mu * (F_hd + m_deck * G)
    ratio_s = rng.uniform(1.0, 1.03)
    v_s = rng.uniform(1e-3, 5e-3)
    spread = rng.uniform(0.01, 0.03)
    p0 = rng.uniform(1.0e6, 3.0e6)
    area = F_hd / (4 * p0)
    h = F_hd / Ke
    l0 = h * rng.uniform(0.4, 0.8)
    gamma = rng.uniform(1.3, 1.42)
    # oil column
    f_oil = rng.uniform(20, 35)
    beta = rng.uniform(1.2e9, 1.6e9)
    Ap = rng.uniform(0.018, 0.026)
    k_h = Me * (2 * np.pi * f_oil) ** 2
    V = 4 * beta * Ap ** 2 / k_h
    zeta_leak = rng.uniform(0.03, 0.08)
    C_leak = zeta_leak * 2 * Ap / np.sqrt(beta * Me / V) / 2  # ~ zeta * Ap / sqrt(beta M / V)
    Ps = 21e6
    Qmax = Ap * rng.uniform(1.0, 1.4) / np.sqrt(0.5)  # >= 0.5 m/s at half the supply pressure
    f_valve = rng.uniform(40, 80)
    z_valve = rng.uniform(0.6, 0.8)
    fs = int(rng.choice([256, 500, 512, 1000, 1024]))
    k_sub = int(round(1.0 / (fs * 1.25e-4)))
    dt = 1.0 / (fs * k_sub)
    has_v = bool(rng.uniform() < 0.3)
    has_a = bool(rng.uniform() < 0.9)
    # sensors
    u_noise = rng.uniform(5e-6, 30e-6)
    u_q = rng.uniform(2e-6, 5e-6)
    u_off = rng.uniform(-1e-3, 1e-3)
    a_noise = rng.uniform(0.02, 0.08)
    a_off = rng.uniform(-0.03, 0.03)
    F_noise = rng.uniform(100, 400)
    F_phi = rng.uniform(0.5, 0.9)
    F_hum = rng.uniform(20, 100)
    F_off = rng.uniform(-2000, 2000)
    v_noise = rng.uniform(1e-3, 3e-3)

    n_tests = int(n_tests or rng.integers(16, 25))
    tests = _draw_tests(rng, n_tests, int(rng.integers(2, 4)))
    order = rng.permutation(n_tests) + 1

    # ---- effect
    eff = {"name": effect}
    K3 = 0.0
    Fp = 0.0
    spec_m = 0.0
    delay = 0.0
    drift = 0.0
    umax = max(t["A"] for t in tests)
    if effect == "stiction":
        ratio_s = float(size or 1.3)
        v_s = rng.uniform(1e-3, 5e-3)
        eff.update(static_ratio=ratio_s, stribeck_velocity=v_s)
    elif effect == "channel_delay":
        delay = float(size or rng.uniform(2e-3, 6e-3))
        delay = round(delay / dt) * dt
        eff.update(delay=delay)
    elif effect == "specimen":
        spec_m = float(size or rng.uniform(2000, 4000))
        spec_f = rng.uniform(6, 15)
        spec_z = rng.uniform(0.02, 0.05)
        eff.update(specimen_mass=spec_m, specimen_frequency=spec_f, specimen_damping=spec_z)
    elif effect == "nonlinear_stiffness":
        share = float(size or rng.uniform(0.05, 0.15))
        K3 = share * Ke / umax ** 2
        eff.update(share=share, K3=K3, cubic_stiffness=K3 * h ** 2, u_max=umax)
    elif effect == "position_friction":
        share = float(size or rng.uniform(0.10, 0.30))
        Fp = share * Fk0 / (umax / h) ** 2
        eff.update(share=share, position_friction=Fp, u_max=umax)
    elif effect == "drift":
        drift = float(size or rng.uniform(0.10, 0.20))
        eff.update(drift=drift)
    elif effect is not None:
        raise ValueError(effect)

    # ---- per-test parameters
    ov = dict(overrides or {})
    spread = ov.get("spread", spread)
    ratio_s = ov.get("static_ratio", ratio_s)
    if ov.get("quiet"):  # ideal sensors (the noise draws below still consume the same stream)
        u_noise = a_noise = F_noise = F_hum = v_noise = 0.0
        u_q = 1e-12
    u_noise, u_q, a_noise = ov.get("u_noise", u_noise), ov.get("u_q", u_q), ov.get("a_noise", a_noise)
    F_noise, F_hum, v_noise = ov.get("F_noise", F_noise), ov.get("F_hum", F_hum), ov.get("v_noise", v_noise)
    nT = n_tests
    # 'spread_seed': the per-test factors from a stream of their own (the main stream still
    # makes its draws, so the rest of the series stays the same)
    factor_rng = np.random.default_rng([int(ov["spread_seed"]), 4242]) if "spread_seed" in ov else None

    def rel(name):
        z = rng.normal(size=nT)
        if factor_rng is not None:
            z = factor_rng.normal(size=nT)
        return 1 + ov.get("spread_" + name, spread) * z

    Me_i = Me * rel("Me")
    Ke_i = Ke * rel("Ke")
    Ce_i = Ce * rel("Ce")
    mu_i = mu * rel("mu")
    pay = np.array([t["payload"] for t in tests])
    s_camp = (order - 1) / max(nT - 1, 1)
    fall = 1 - drift * s_camp
    M_i = Me_i + pay
    Fk_i = mu_i * (F_hd + (m_deck + pay + spec_m) * G) * fall
    Ce_i = Ce_i * fall
    Fs_i = ratio_s * Fk_i
    per_test = {"Me": Me_i.tolist(), "Ke": Ke_i.tolist(), "Ce": Ce_i.tolist(),
                "Fk": Fk_i.tolist(), "Fk_at_deck_load": (mu_i * (F_hd + m_deck * G) * fall).tolist(),
                "payload": pay.tolist(), "order": order.tolist()}
    if dry_run:  # the draws only (same random stream), for replaying a series' per-test truth
        return {"Me": Me, "Ke": Ke, "Ce": Ce, "alpha": alpha, "Fmu": Fk0, "per_test": per_test,
                "fs": fs, "has_a": has_a, "has_v": has_v, "effect": eff}

    # ---- commands on the fine grid (common length, padded with rest)
    t_pre = 0.5
    durs = []
    for tst in tests:
        T = 1 / tst["f"]
        durs.append(t_pre + (tst["n_in"] + tst["n_steady"] + tst["n_out"]) * T + 1.0)
    n_fine = [int(np.ceil(d / dt / k_sub)) * k_sub for d in durs]
    N = max(n_fine)
    tf = np.arange(N) * dt
    uc = np.zeros((nT, N))
    vc = np.zeros((nT, N))
    ac = np.zeros((nT, N))
    for i, tst in enumerate(tests):
        uc[i], vc[i], ac[i] = _command(tst["kind"], tst["f"], tst["A"], tf, tst["n_in"],
                                        tst["n_steady"], tst["n_out"], t_pre, tst["round_frac"])

    # ---- controller gains
    Kvel = Qmax / Ap * np.sqrt(0.7)  # nominal m/s per unit spool
    Kp = 2 * np.pi * rng.uniform(2.0, 3.0)  # displacement loop crossover, rad/s
    Ki = Kp * 0.5
    Ka = rng.uniform(0.001, 0.003)  # acceleration feedback (s); >= 0.008 limit-cycles at f_oil
    Kdp = rng.uniform(0.04, 0.08)  # delta-P feedback per Ps
    Kdp = ov.get("Kdp", Kdp)
    Ka = ov.get("Ka", Ka)
    Kp = ov.get("Kp", Kp)
    if "f_valve" in ov or "f_oil" in ov:
        f_valve = ov.get("f_valve", f_valve)
        f_oil = ov.get("f_oil", f_oil)
        V = 4 * beta * Ap ** 2 / (Me * (2 * np.pi * f_oil) ** 2)
        C_leak = zeta_leak * Ap / np.sqrt(beta * Me / V)
        c_p = 4 * beta / V
    wv = 2 * np.pi * f_valve

    # ---- state
    x = np.zeros(nT)
    v = np.zeros(nT)
    acc = np.zeros(nT)
    PL = np.zeros(nT)
    xv = np.zeros(nT)
    xvd = np.zeros(nT)
    integ = np.zeros(nT)
    stuck = np.ones(nT, dtype=bool)
    y = np.zeros(nT)
    yd = np.zeros(nT)
    PL_lp = np.zeros(nT)
    if spec_m:
        w_s = 2 * np.pi * spec_f
        k_s = spec_m * w_s ** 2
        c_s = 2 * spec_z * spec_m * w_s
    Fdrop = Fs_i - Fk_i
    nS = N // k_sub
    rec_u = np.zeros((nT, nS))
    rec_v = np.zeros((nT, nS))
    rec_a = np.zeros((nT, nS))
    F_fine = np.zeros((nT, N))
    if not ("f_valve" in ov or "f_oil" in ov):
        c_p = 4 * beta / V
    a_lp_alpha = dt / (dt + 1 / (2 * np.pi * 100))
    a_fb = np.zeros(nT)
    dp_hp_alpha = dt / (dt + 1 / (2 * np.pi * 10.0))
    for n in range(N):
        # controller (sensors at fine rate: true states, accel through a 100 Hz low-pass)
        e = uc[:, n] - x
        integ += e * dt
        a_fb += a_lp_alpha * (acc - a_fb)
        PL_lp += dp_hp_alpha * (PL - PL_lp)
        v_dem = vc[:, n] + Kp * e + Ki * integ + Ka * (ac[:, n] - a_fb)
        # flow linearisation: divide by the valve's gain at the measured load pressure
        gain = Qmax / Ap * np.sqrt(np.clip(Ps - np.sign(v_dem) * PL, 0.05 * Ps, None) / Ps)
        i_cmd = v_dem / gain - Kdp * (PL - PL_lp) / Ps
        # valve spool (2nd order), saturation
        xva = wv * wv * (i_cmd - xv) - 2 * z_valve * wv * xvd
        xvd += xva * dt
        xv += xvd * dt
        np.clip(xv, -1, 1, out=xv)
        # flow and pressure
        dpv = np.clip(Ps - np.sign(xv) * PL, 0, None)
        Q = Qmax * xv * np.sqrt(dpv / Ps)
        PL += c_p * (Q - Ap * v - C_leak * PL) * dt
        np.clip(PL, -Ps, Ps, out=PL)
        Fa = Ap * PL
        F_fine[:, n] = Fa
        # deck
        spring = Ke_i * x + K3 * x ** 3
        f_spec = (k_s * y + c_s * yd) if spec_m else 0.0
        F_other = Fa - spring + f_spec
        cap = Fs_i + Fp * (x / h) ** 2
        # stuck decks
        brk = stuck & (np.abs(F_other) > cap)
        stay = stuck & ~brk
        sv = np.sign(v)
        sv = np.where(brk, np.sign(F_other), sv)
        av = np.abs(v)
        fric = (Fk_i + Fdrop * np.exp(-(av / v_s) ** 2) + Fp * (x / h) ** 2) * sv
        damp = Ce_i * av ** alpha * sv
        a_new = (F_other - fric - damp) / M_i
        a_new = np.where(stay, 0.0, a_new)
        v_new = v + a_new * dt
        cross = (~stuck) & (np.sign(v_new) != sv)
        stick_now = cross & (np.abs(F_other) <= cap)
        v_new = np.where(stick_now | stay, 0.0, v_new)
        stuck = stay | stick_now
        a_new = np.where(stick_now, (v_new - v) / dt, a_new)
        if n % k_sub == 0:
            # sample at the start of the step: x_n, v_n with the force and acceleration of step n
            j = n // k_sub
            rec_u[:, j] = x
            rec_v[:, j] = v
            rec_a[:, j] = a_new
        acc = a_new
        v = v_new
        x = x + v * dt
        if spec_m:
            ydd = -2 * spec_z * w_s * yd - w_s ** 2 * y - acc
            yd += ydd * dt
            y += yd * dt
        if verbose and n % 50000 == 0:
            print(n, N, flush=True)

    # ---- write
    os.makedirs(out_dir, exist_ok=True)
    shift = int(round(delay / dt))
    man_tests = []
    track = []
    ring = []
    for i, tst in enumerate(tests):
        ns = n_fine[i] // k_sub
        idx = np.arange(ns) * k_sub
        Ff = F_fine[i]
        if shift:
            Ff = np.concatenate([np.full(shift, Ff[0]), Ff[:-shift]])
        t = idx * dt
        u = rec_u[i, :ns] + u_off + rng.normal(0, u_noise, ns)
        u = np.round(u / u_q) * u_q
        F = Ff[idx] + F_off + _ar1(rng, ns, F_noise, F_phi) \
            + F_hum * np.sin(2 * np.pi * 50 * t + rng.uniform(0, 2 * np.pi))
        cols = {"t": t, "u": u, "F": F}
        if has_a:
            cols["a"] = rec_a[i, :ns] + a_off + rng.normal(0, a_noise, ns)
        if has_v:
            cols["v"] = rec_v[i, :ns] + rng.normal(0, v_noise, ns)
        cols["u_cmd"] = uc[i, idx]
        tid = f"T{i + 1:02d}"
        fn = f"{tid}.csv"
        arr = np.column_stack(list(cols.values()))
        np.savetxt(os.path.join(out_dir, fn), arr, delimiter=",", header=",".join(cols),
                   comments="", fmt="%.9g")
        man_tests.append({"id": tid, "file": fn, "kind": tst["kind"], "frequency_hz": tst["f"],
                          "amplitude_m": tst["A"], "payload_kg": tst["payload"],
                          "order": int(order[i])})
        steady = (t > t_pre + (tst["n_in"]) / tst["f"]) & \
                 (t < t_pre + (tst["n_in"] + tst["n_steady"]) / tst["f"])
        track.append(float(np.max(np.abs(rec_u[i, :ns][steady])) / tst["A"]))
        # loop health: sample-to-sample change of the true acceleration over the steady cycles
        ring.append(float(np.std(np.diff(rec_a[i, :ns][steady]))))
    manifest = {
        "format": "sst-series/1",
        "name": name or f"g5-seed{seed}-{effect or 'clean'}",
        "table": {
            "deck_mass_kg": float(m_deck),
            "strut": {"p0_pa": float(p0), "area_m2": float(area), "h_m": float(h),
                      "l0_m": float(l0), "gamma": float(gamma)},
            "oil": {"bulk_modulus_pa": float(beta), "piston_area_m2": float(Ap),
                    "oil_volume_m3": float(V)},
        },
        "tests": man_tests,
    }
    with open(os.path.join(out_dir, "series.json"), "w") as fh:
        json.dump(manifest, fh, indent=1)
    truth = {"seed": seed, "Me": Me, "Ke": Ke, "Ce": Ce, "alpha": alpha, "Fmu": Fk0,
             "Fmu_with_specimen": mu * (F_hd + (m_deck + spec_m) * G),
             "mu": mu, "F_hd": F_hd, "m_deck": m_deck, "spread": spread,
             "static_ratio_clean": ratio_s if effect != "stiction" else None,
             "stribeck_velocity": v_s, "fs": fs, "dt": dt, "f_oil": f_oil, "f_valve": f_valve,
             "has_a": has_a, "has_v": has_v, "n_tests": nT, "h": h,
             "noise": {"u": u_noise, "u_q": u_q, "a": a_noise, "F": F_noise, "F_phi": F_phi,
                       "hum": F_hum, "v": v_noise},
             "tracking_ratio": track, "accel_step_rms": ring,
             "loop_unstable": bool(max(ring) > 2.0), "per_test": per_test, "effect": eff}
    if truth["loop_unstable"]:
        print("WARNING: servo loop limit-cycling (accel_step_rms", max(ring), ")", flush=True)
    if truth_path:
        os.makedirs(os.path.dirname(truth_path), exist_ok=True)
        with open(truth_path, "w") as fh:
            json.dump(truth, fh, indent=1, default=float)
    return truth


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--out", required=True)
    p.add_argument("--truth")
    p.add_argument("--effect", default=None)
    p.add_argument("--size", type=float, default=None)
    p.add_argument("--n-tests", type=int, default=None)
    p.add_argument("--verbose", action="store_true")
    a = p.parse_args()
    tr = make_series(a.seed, a.out, a.effect, a.size, a.truth, n_tests=a.n_tests,
                     verbose=a.verbose)
    print(json.dumps({k: tr[k] for k in ("Me", "Ke", "Ce", "alpha", "Fmu", "fs")}, default=float))


if __name__ == "__main__":
    main()
