"""Sixth independent simulator of a servo-hydraulic shaking table.

Written from first principles and the series file format only (sst-series/1).
It produces synthetic test campaigns for blind checks of a system-identification
package. One call of ``make_series`` draws a table, a test plan, a controller and a
set of sensors, integrates every test of the campaign on a fine fixed time grid, and
writes ``series.json`` plus one CSV per test.

Plant (per test, all tests integrated side by side as a vector):

* deck: M*a = F_act - Ke*u [- k3*(u/h)^2*u] - Ce*|v|^alpha*sgn(v) - friction
  [+ specimen base shear]. The friction is a set-valued Coulomb law with a Stribeck
  bump, resolved with an implicit (Moreau-type) time-stepping rule: the deck is held
  exactly at rest while the net other force stays inside the static capacity, so
  there is no chatter at reversals and no smoothing of the sign function.
* actuator: equal-area double-rod piston, two chambers, each with its own pressure
  ODE (bulk modulus, chamber volume that changes with stroke), four-land critically
  lapped servo-valve with square-root orifice law from supply / to tank, a small
  null leakage of the valve and a small cross-piston leakage.
* valve spool: second-order lag (40-100 Hz) with stroke limits.
* controller (digital, ZOH at the integration step): displacement PID on a noisy
  LVDT, velocity feed-forward (a slightly mis-calibrated inverse valve gain), and a
  high-passed differential-pressure feedback that damps the oil column.
* measured force: piston area times differential pressure (a load cell between the
  rod end and the deck); everything that moves beyond it belongs to Me.

Command line:
    python benchmarks/sixth_generator.py --seed N --out DIR [--effect NAME] [--size X]
"""

import argparse
import json
import os
import time

import numpy as np
from scipy import signal

GRAV = 9.81
EFFECTS = ("stiction", "channel_delay", "specimen", "nonlinear_stiffness",
           "position_friction", "drift")

# round numbers a lab would type into its test plan
FREQ_SET = [0.1, 0.2, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0]
FREQ_WEIGHT = [0.4, 0.7, 0.6, 1.2, 0.8, 1.5, 1.0, 1.3, 0.8, 0.9, 0.7, 0.6]
AMP_SET_MM = [2, 5, 10, 15, 20, 25, 30, 40, 50, 75, 100]

# performance envelope of the table
V_LIM = 0.5
A_LIM = 8.0
STROKE = 0.12


# ----------------------------------------------------------------------------
# draws
# ----------------------------------------------------------------------------
def _draw_table(rng):
    """All table, hydraulic, controller and sensor draws (fixed number of draws)."""
    p = {}
    fs_choice = [200, 500, 1000, 1024]
    p["fs"] = int(fs_choice[rng.integers(0, 4)])

    # structure
    p["m_deck"] = float(rng.uniform(8700.0, 16400.0))
    p["m_rod"] = float(rng.uniform(150.0, 500.0))        # piston, rod end, couplings
    p["Ke"] = float(rng.uniform(0.40e6, 1.0e6))
    F_hd = float(rng.uniform(0.40e6, 1.10e6))
    h_lo = max(0.8, 0.40e6 / p["Ke"])
    h_hi = min(1.6, 1.10e6 / p["Ke"])
    h_u = rng.uniform()
    p["strut_h"] = float(h_lo + (h_hi - h_lo) * h_u) if h_hi > h_lo else float(F_hd / p["Ke"])
    p["F_hd"] = p["Ke"] * p["strut_h"]                   # 4*p0*A = Ke*h
    p["strut_p0"] = float(rng.uniform(6e6, 16e6))
    p["strut_A"] = p["F_hd"] / (4.0 * p["strut_p0"])
    p["strut_l0"] = float(rng.uniform(0.35, 1.0))
    p["strut_gamma"] = float(rng.uniform(1.25, 1.40))
    p["alpha"] = float(rng.uniform(0.3, 0.8))
    Fd03 = float(rng.uniform(8e3, 30e3))                 # damping force at 0.3 m/s
    p["Ce"] = Fd03 / 0.3 ** p["alpha"]
    p["mu"] = float(rng.uniform(0.007, 0.018))
    p["static_ratio_clean"] = float(1.0 + rng.uniform(0.0, 0.03))
    p["stribeck_clean"] = float(rng.uniform(0.001, 0.006))
    p["spread"] = float(rng.uniform(0.01, 0.03))

    # hydraulics
    p["Ps"] = float(rng.uniform(14e6, 28e6))
    p["Pt"] = float(rng.uniform(0.2e6, 0.5e6))
    p["Ap"] = float(rng.uniform(0.018, 0.040))
    p["beta"] = float(rng.uniform(0.9e9, 1.5e9))
    p["f_oil_target"] = float(rng.uniform(22.0, 36.0))
    p["v_valve"] = float(rng.uniform(0.70, 0.95))        # no-load velocity at full spool
    p["f_valve"] = float(rng.uniform(40.0, 100.0))
    p["z_valve"] = float(rng.uniform(0.55, 0.9))
    p["leak_piston_rel"] = float(rng.uniform(0.01, 0.04))  # fraction of rated flow at Ps
    p["leak_null_rel"] = float(rng.uniform(0.002, 0.01))

    # controller
    p["f_cross"] = float(rng.uniform(1.5, 3.5))          # displacement loop crossover
    p["f_int"] = float(rng.uniform(0.1, 0.4))
    p["tau_d"] = float(rng.uniform(0.0, 0.003))
    p["ff_gain"] = float(rng.uniform(0.85, 1.0))
    p["zeta_dp"] = float(rng.uniform(0.05, 0.25))        # oil-column damping aimed at
    p["f_dp_hp"] = float(rng.uniform(0.5, 2.0))

    # sensors
    p["quiet"] = False
    p["u_noise"] = float(rng.uniform(5e-6, 30e-6))
    p["u_offset"] = float(rng.uniform(-5e-4, 5e-4))
    p["u_range"] = float([0.15, 0.15, 0.2, 0.125][rng.integers(0, 4)])
    p["a_noise"] = float(rng.uniform(0.01, 0.08))
    p["a_offset"] = float(rng.uniform(-0.04, 0.04))
    p["F_noise"] = float(rng.uniform(50.0, 300.0))
    p["F_ar"] = float(rng.uniform(0.3, 0.9))             # AR(1) pole at the sample rate
    p["F_hum"] = float(rng.uniform(20.0, 150.0))
    p["F_hum3"] = float(rng.uniform(0.0, 0.3))           # 150 Hz part of the hum
    p["F_offset"] = float(rng.uniform(-1000.0, 1000.0))
    p["has_v"] = bool(rng.uniform() < 0.4)
    p["v_noise"] = float(rng.uniform(0.5e-3, 3e-3))
    p["v_offset"] = float(rng.uniform(-1e-3, 1e-3))

    # what the lab writes in the manifest (a few % off the truth)
    p["desc_err"] = [float(x) for x in rng.normal(0.0, 0.03, 9)]
    return p


def _finish_table(p):
    """Derived quantities (recomputed after overrides)."""
    p["Me"] = p["m_deck"] + p["m_rod"]
    p["Fmu"] = p["mu"] * (p["F_hd"] + p["m_deck"] * GRAV)
    w_oil = 2 * np.pi * p["f_oil_target"]
    Vt = 4 * p["beta"] * p["Ap"] ** 2 / (p["Me"] * w_oil ** 2)
    Vt_min = 2.6 * p["Ap"] * STROKE                      # both chambers at mid stroke
    p["Vt"] = float(max(Vt, Vt_min))
    p["k_oil"] = 4 * p["beta"] * p["Ap"] ** 2 / p["Vt"]
    p["f_oil"] = float(np.sqrt(p["k_oil"] / p["Me"]) / (2 * np.pi))
    # valve flow coefficient: Q = Kv * x * sqrt(dp_land); no-load drop per land = (Ps-Pt)/2
    p["Kv"] = p["Ap"] * p["v_valve"] / np.sqrt((p["Ps"] - p["Pt"]) / 2)
    Qr = p["Ap"] * p["v_valve"]
    p["C_leak"] = p["leak_piston_rel"] * Qr / p["Ps"]
    p["C_null"] = p["leak_null_rel"] * Qr / p["Ps"]
    # controller gains
    Kq = p["v_valve"]                                    # m/s per unit spool
    p["Kp"] = 2 * np.pi * p["f_cross"] / Kq
    p["Ki"] = p["Kp"] * 2 * np.pi * p["f_int"]
    p["Kd"] = p["Kp"] * p["tau_d"]
    p["Kff"] = p["ff_gain"] / Kq
    # pressure feedback sized for a target hydraulic damping ratio
    Kce = p["zeta_dp"] * p["Ap"] / np.sqrt(p["beta"] * p["Me"] / p["Vt"])
    p["Kdp"] = Kce / (Kq * p["Ap"])                      # spool per Pa
    return p


def _legal(f, A, kind, corner_frac):
    """Is a (frequency, amplitude) pair inside the table's performance envelope?"""
    if A > 0.100 + 1e-9 or A < 0.002 - 1e-9:
        return False
    if kind == "sine":
        vmax, amax = 2 * np.pi * f * A, (2 * np.pi * f) ** 2 * A
    else:
        vmax = 4 * f * A
        # a Hann-smoothed corner reverses 2*vmax within corner_frac/f, peak twice the mean
        amax = 2 * (2 * vmax) / (corner_frac / f) / 0.85
    return vmax <= V_LIM and amax <= A_LIM


def _pick_amp(rng, f, kind, corner_frac):
    ok = [a_mm * 1e-3 for a_mm in AMP_SET_MM if _legal(f, a_mm * 1e-3, kind, corner_frac)]
    if not ok:
        return None
    # labs like the larger amplitudes a frequency allows, but not only those
    idx = rng.integers(max(0, len(ok) - 5), len(ok))
    return ok[int(idx)]


def _draw_plan(rng, fs):
    n_tests = int(rng.integers(14, 27))
    ramp_shape = "raised_cosine" if rng.uniform() < 0.5 else "linear"
    pre = float(np.round(rng.uniform(0.5, 1.5), 1))
    post = float(np.round(rng.uniform(0.5, 1.0), 1))
    corner_frac = float(rng.uniform(0.06, 0.15))
    has_bb = bool(rng.uniform() < 0.3)
    has_payload = bool(rng.uniform() < 0.5)
    payload = float(rng.choice([1000, 1500, 2000, 2500, 3000, 4000, 5000]))
    n_pay = int(rng.integers(2, 5)) if has_payload else 0
    w = np.array(FREQ_WEIGHT) / np.sum(FREQ_WEIGHT)

    tests = []
    seen = set()
    n_base = n_tests - n_pay - (1 if has_bb else 0)
    tries = 0
    while len(tests) < n_base and tries < 500:
        tries += 1
        kind = "triangle" if rng.uniform() < 0.2 else "sine"
        f = float(FREQ_SET[rng.choice(len(FREQ_SET), p=w)])
        A = _pick_amp(rng, f, kind, corner_frac)
        if A is None or (kind, f, A) in seen:
            continue
        seen.add((kind, f, A))
        tests.append(dict(kind=kind, frequency_hz=f, amplitude_m=A, payload_kg=0.0,
                          ramp_cycles=int(rng.integers(1, 4)),
                          steady_cycles=int(rng.integers(4, 13))))
    # payload repeats of a few sine tests (the mass is bolted on once)
    sines = [t for t in tests if t["kind"] == "sine"]
    if n_pay:
        pick = rng.choice(len(sines), size=min(n_pay, len(sines)), replace=False)
        for i in pick:
            t = dict(sines[int(i)])
            t["payload_kg"] = payload
            tests.append(t)
    if has_bb:
        tests.append(dict(kind="broadband", frequency_hz=None, amplitude_m=None,
                          payload_kg=0.0, f_hi=float(rng.uniform(3.0, 8.0)),
                          bb_dur=float(np.round(rng.uniform(20.0, 40.0))),
                          bb_seed=int(rng.integers(0, 2 ** 31))))

    # keep the data volume (and run time) bounded: at high sample rates the lab
    # runs fewer and shorter low-frequency tests
    def dur(t):
        if t["kind"] == "broadband":
            return pre + post + t["bb_dur"]
        return pre + post + (2 * t["ramp_cycles"] + t["steady_cycles"]) / t["frequency_hz"]

    row_budget = 180_000
    t_cap = 70.0
    for _ in range(2000):
        durs = np.array([dur(t) for t in tests])
        if durs.sum() * fs <= row_budget and durs.max() <= t_cap:
            break
        j = int(np.argmax(durs))
        t = tests[j]
        if t["kind"] == "broadband":
            if t["bb_dur"] > 15:
                t["bb_dur"] -= 5
                continue
        elif t["steady_cycles"] > 4:
            t["steady_cycles"] -= 1
            continue
        elif t["ramp_cycles"] > 1:
            t["ramp_cycles"] -= 1
            continue
        elif t["frequency_hz"] < 0.5 and t["payload_kg"] == 0:
            # move the slowest test up the frequency list (if it stays new and legal)
            k = FREQ_SET.index(t["frequency_hz"])
            moved = False
            for f2 in FREQ_SET[k + 1:]:
                key2 = (t["kind"], f2, t["amplitude_m"])
                if key2 not in seen and _legal(f2, t["amplitude_m"], t["kind"], corner_frac):
                    seen.discard((t["kind"], t["frequency_hz"], t["amplitude_m"]))
                    seen.add(key2)
                    t["frequency_hz"] = f2
                    moved = True
                    break
            if moved:
                continue
        if len(tests) > 14:
            tests.pop(j)
        else:
            break

    # file order: grouped by kind, then payload, frequency and amplitude
    def key(t):
        kk = {"sine": 0, "triangle": 1, "broadband": 2}[t["kind"]]
        return (kk, t["payload_kg"], t["frequency_hz"] or 0, t["amplitude_m"] or 0)
    tests.sort(key=key)
    n = len(tests)
    # campaign order: random, payload tests in one block, broadband near the end
    normal = [i for i, t in enumerate(tests) if t["payload_kg"] == 0 and t["kind"] != "broadband"]
    pay = [i for i, t in enumerate(tests) if t["payload_kg"] > 0]
    bb = [i for i, t in enumerate(tests) if t["kind"] == "broadband"]
    normal = [normal[i] for i in rng.permutation(len(normal))]
    pay = [pay[i] for i in rng.permutation(len(pay))]
    cut = int(rng.integers(0, len(normal) + 1))
    seq = normal[:cut] + pay + normal[cut:]
    if bb:
        seq.insert(max(0, len(seq) - int(rng.integers(0, 3))), bb[0])
    for pos, i in enumerate(seq):
        tests[i]["order"] = pos + 1
    prefix = {"sine": "S", "triangle": "T", "broadband": "B"}
    cnt = {}
    for t in tests:
        c = prefix[t["kind"]] + ("P" if t["payload_kg"] > 0 else "")
        cnt[c] = cnt.get(c, 0) + 1
        t["id"] = f"{c}{cnt[c]:02d}"
        t["file"] = t["id"] + ".csv"
    plan = dict(ramp_shape=ramp_shape, pre=pre, post=post, corner_frac=corner_frac,
                payload=payload if n_pay else 0.0)
    return tests, plan, n


def _draw_effect(rng, name, size, A_max, p):
    """Effect parameters; rng draws are fixed in number whatever the effect."""
    u = rng.uniform(size=6)
    s = float(u[0] ** 1.5) if size is None else float(size)
    eff = {"name": name, "size": s}
    if name is None:
        return None
    # size: 0 = weakest, 1 = strongest end of the effect's range; values outside
    # [0, 1] extrapolate linearly (floors keep the parameters physical)
    if name == "stiction":
        eff["static_ratio"] = max(1.0, 1.1 + 0.5 * s)
        eff["stribeck_velocity"] = float(np.exp(np.log(0.003) + u[1] * np.log(20 / 3)))
    elif name == "channel_delay":
        eff["delay"] = max(0.0, 0.001 + 0.005 * s)
    elif name == "specimen":
        eff["specimen_mass"] = float(max(50.0, np.round((1000.0 + 4000.0 * s) / 50.0) * 50.0))
        eff["specimen_frequency"] = float(4.0 + 16.0 * u[2])
        eff["specimen_damping"] = float(0.02 + 0.04 * u[3])
    elif name == "nonlinear_stiffness":
        frac = max(0.0, 0.03 + 0.12 * s)
        eff["fraction_at_max"] = frac
        eff["cubic_stiffness"] = frac * p["Ke"] * (p["h_desc"] / A_max) ** 2
    elif name == "position_friction":
        frac = max(0.0, 0.05 + 0.25 * s)
        eff["fraction_at_max"] = frac
        eff["position_friction"] = frac * p["Fmu"] * (p["h_desc"] / A_max) ** 2
    elif name == "drift":
        eff["drift"] = max(0.0, 0.05 + 0.20 * s)
    else:
        raise ValueError(f"unknown effect {name!r}; choose from {EFFECTS}")
    return eff


# ----------------------------------------------------------------------------
# commands
# ----------------------------------------------------------------------------
def _envelope(tr, T_ramp, T_total, shape):
    e = np.zeros_like(tr)
    up = np.clip(tr / T_ramp, 0.0, 1.0)
    down = np.clip((T_total - tr) / T_ramp, 0.0, 1.0)
    r = np.minimum(up, down)
    if shape == "raised_cosine":
        r = 0.5 * (1 - np.cos(np.pi * r))
    e[:] = r
    e[(tr < 0) | (tr > T_total)] = 0.0
    return e


def _command(t, dt, test, plan):
    pre = plan["pre"]
    tr = t - pre
    if test["kind"] == "broadband":
        r = np.random.default_rng(test["bb_seed"])
        T = test["bb_dur"]
        n = len(t)
        X = np.fft.rfft(r.standard_normal(n))
        fr = np.fft.rfftfreq(n, dt)
        mask = (fr >= 0.2) & (fr <= test["f_hi"])
        soft = np.exp(-0.5 * ((fr - test["f_hi"]) / 0.5) ** 2) * (fr > test["f_hi"])
        # flat velocity spectrum in the band (displacement falls as 1/f)
        X = X * (mask + soft) / np.maximum(fr, 0.2)
        x = np.fft.irfft(X, n)
        env = _envelope(tr, 2.0, T, "raised_cosine")
        x = x * env
        x -= x[0]
        x *= env > 0
        v = np.gradient(x, dt)
        a = np.gradient(v, dt)
        sc = min(0.04 / np.abs(x).max(), 0.3 / np.abs(v).max(), 5.0 / np.abs(a).max())
        return x * sc
    f, A = test["frequency_hz"], test["amplitude_m"]
    nr, ns = test["ramp_cycles"], test["steady_cycles"]
    T_total = (2 * nr + ns) / f
    env = _envelope(tr, nr / f, T_total, plan["ramp_shape"])
    ph = 2 * np.pi * f * tr
    if test["kind"] == "sine":
        shape = np.sin(ph)
    else:
        # triangle with rounded corners: sharp triangle smoothed by a Hann window
        cyc = (f * tr) % 1.0
        tri = np.where(cyc < 0.25, 4 * cyc, np.where(cyc < 0.75, 2 - 4 * cyc, 4 * cyc - 4))
        nk = max(3, int(round(plan["corner_frac"] / f / dt)))
        ker = np.hanning(nk + 2)[1:-1]
        ker /= ker.sum()
        shape = signal.fftconvolve(tri, ker, mode="same")
        shape /= np.abs(shape[(tr > 0) & (tr < T_total)]).max()
    x = A * env * shape
    x[(tr < 0) | (tr > T_total)] = 0.0
    return x


# ----------------------------------------------------------------------------
# time integration
# ----------------------------------------------------------------------------
def _simulate(p, tests, tv, eff, dt, K, n_samp, ucmd_list, noise_ctrl_seed):
    """Integrate all tests together. Returns noise-free sampled channels per test.

    One step, in this order: digital controller (zero-order hold), spool, deck
    (implicit friction and damping, symplectic in the oil-column coupling),
    specimen, then the two chamber pressures with the new deck velocity.
    """
    N = len(tests)
    n_steps = max(n_samp) * K
    uc = np.zeros((n_steps, N))
    for j in range(N):
        uc[: len(ucmd_list[j]), j] = ucmd_list[j]
    ffv = np.gradient(uc, dt, axis=0) * p["Kff"]          # velocity feed-forward
    if not p["quiet"]:
        # the loop closes on the LVDT, so its noise enters the motion
        rngc = np.random.default_rng(noise_ctrl_seed)
        for k0 in range(0, n_steps, 50000):
            k1 = min(n_steps, k0 + 50000)
            uc[k0:k1] -= p["u_noise"] * rngc.standard_normal((k1 - k0, N))

    name = eff["name"] if eff else None
    M = tv["Me"] + tv["payload"]
    Ke, Ce, Fk = tv["Ke"], tv["Ce"], tv["Fk"]
    alpha = p["alpha"]
    ia = 1.0 / alpha
    ia1 = ia - 1.0
    mdt = M / dt
    mdt_ia = mdt * ia
    dFs = Fk * (tv["rs"] - 1.0)
    cap0 = Fk * tv["rs"]
    ivs = 1.0 / tv["vs"]

    Ap, Ps, Pt, beta = p["Ap"], p["Ps"], p["Pt"], p["beta"]
    Kv, Cl, Cn = p["Kv"], p["C_leak"], p["C_null"]
    V0 = p["Vt"] / 2
    pl = 0.3e6                       # regularisation of the orifice law near zero drop
    sg = np.array([[1.0], [-1.0]])   # chamber 1 / chamber 2
    sgAp = sg * Ap
    bdt = beta * dt
    wv = 2 * np.pi * p["f_valve"]
    wv2dt, c2dt = wv * wv * dt, 2 * p["z_valve"] * wv * dt
    Kp, kI, Kdp = p["Kp"], p["Ki"] * dt, p["Kdp"]
    tau_f = 1.0 / (2 * np.pi * 150.0)                    # derivative filter
    cf = dt / tau_f
    KdT = p["Kd"] / tau_f
    ch = dt * 2 * np.pi * p["f_dp_hp"]

    has_k3 = name == "nonlinear_stiffness"
    has_pf = name == "position_friction"
    has_sp = name == "specimen"
    h = p["h_desc"]
    if has_k3:
        k3h = eff["cubic_stiffness"] / h ** 2
    if has_pf:
        pfh = eff["position_friction"] / h ** 2
    if has_sp:
        ms = eff["specimen_mass"]
        ws = 2 * np.pi * eff["specimen_frequency"]
        ks, cs = ms * ws ** 2, 2 * eff["specimen_damping"] * ms * ws
        zs = np.zeros(N)
        zv = np.zeros(N)
    nd = int(round(eff["delay"] / dt)) if name == "channel_delay" else 0
    L = nd + 1
    fbuf = np.zeros((L, N))

    u = np.zeros(N)
    v = np.zeros(N)
    pc = np.full((2, N), 0.5 * (Ps + Pt))
    xv = np.zeros(N)
    xvd = np.zeros(N)
    integ = np.zeros(N)
    ef = np.zeros(N)
    dPl = np.zeros(N)
    shear = np.zeros(N)
    n_out = max(n_samp)
    keys = ("u", "v", "a", "F", "Fd", "spool", "stick", "shear")
    out = {k: np.zeros((n_out, N)) for k in keys}
    o_u, o_v, o_a, o_F, o_Fd, o_sp, o_st, o_sh = (out[k] for k in keys)
    idt = 1.0 / dt
    for k in range(n_steps):
        # --- controller: PID on displacement + velocity FF - high-passed dP feedback
        e = uc[k] - u
        integ += kI * e
        ef += cf * (e - ef)
        dP = pc[0] - pc[1]
        dPl += ch * (dP - dPl)
        icmd = Kp * e + integ + KdT * (e - ef) + ffv[k] - Kdp * (dP - dPl)
        # --- spool: second-order lag with end stops
        xvd += wv2dt * (icmd - xv) - c2dt * xvd
        xv += dt * xvd
        xv = np.minimum(np.maximum(xv, -1.0), 1.0)
        # --- deck
        F = Ap * dP
        G = F - Ke * u
        if has_k3:
            G -= k3h * u * u * u
        if has_sp:
            shear = ks * (zs - u) + cs * (zv - v)
            G += shear
        Ff = Fk + dFs * np.exp(-np.square(v * ivs))
        cap = cap0
        if has_pf:
            fp = pfh * u * u
            Ff = Ff + fp
            cap = cap + fp
        P = mdt * v + G
        aP = np.abs(P)
        slide = aP > cap
        R = (aP - Ff) * slide
        # |v_new| = w solves  mdt*w + Ce*w^alpha = R; Newton in y = w^alpha (convex)
        y = np.minimum(R / Ce, (R / mdt) ** alpha)
        for _ in range(3):
            yp = y ** ia1
            y = y - (mdt * yp * y + Ce * y - R) / (mdt_ia * yp + Ce)
        v_new = np.sign(P) * (y ** ia) * slide
        a = (v_new - v) * idt
        u_old = u
        u = u + dt * v_new
        # --- specimen (semi-implicit)
        if has_sp:
            zv = zv - (dt / ms) * shear
            zs = zs + dt * zv
        # --- chamber pressures (row 0: chamber 1, row 1: chamber 2)
        xs = sg * xv
        ds = Ps - pc
        dtk = pc - Pt
        q = Kv * (np.maximum(xs, 0.0) * ds / np.sqrt(np.abs(ds) + pl)
                  + np.minimum(xs, 0.0) * dtk / np.sqrt(np.abs(dtk) + pl))
        q -= sg * (Ap * v_new + Cl * dP)
        q += Cn * (ds - dtk)
        pc = np.maximum(pc + bdt * q / (V0 + sgAp * u), 2e4)
        v = v_new
        if nd:
            fbuf[k % L] = F
        if k % K == 0:
            m = k // K
            o_u[m] = u_old
            o_v[m] = v_new
            o_a[m] = a
            o_F[m] = F
            o_Fd[m] = (fbuf[(k - nd) % L] if k >= nd else 0.0) if nd else F
            o_sp[m] = xv
            o_st[m] = ~slide
            o_sh[m] = shear
    res = []
    for j in range(N):
        n = n_samp[j]
        res.append({k: out[k][:n, j].copy() for k in out})
    return res


# ----------------------------------------------------------------------------
# sensors
# ----------------------------------------------------------------------------
def _sensors(rng, p, x, fs):
    n = len(x["u"])
    t = np.arange(n) / fs
    z = rng.standard_normal((5, n))
    ph = rng.uniform(0, 2 * np.pi, 2)
    hum_f = 50.0 * (1 + rng.normal(0, 0.0005))          # mains is never exactly 50 Hz
    if p["quiet"]:
        return dict(u=x["u"].copy(), a=x["a"].copy(), F=x["Fd"].copy(), v=x["v"].copy())
    q_u = 2 * p["u_range"] / 65536
    u = np.round((x["u"] + p["u_offset"] + p["u_noise"] * z[0]) / q_u) * q_u
    q_a = 2 * 40.0 / 65536
    a = np.round((x["a"] + p["a_offset"] + p["a_noise"] * z[1]) / q_a) * q_a
    phi = p["F_ar"]
    col = signal.lfilter([np.sqrt(1 - phi ** 2)], [1.0, -phi], z[2])
    hum = p["F_hum"] * (np.sin(2 * np.pi * hum_f * t + ph[0])
                        + p["F_hum3"] * np.sin(2 * np.pi * 3 * hum_f * t + ph[1]))
    q_F = 2 * 500e3 / 65536
    F = np.round((x["Fd"] + p["F_offset"] + p["F_noise"] * col + hum) / q_F) * q_F
    v = x["v"] + p["v_offset"] + p["v_noise"] * z[3]
    return dict(u=u, a=a, F=F, v=v)


# ----------------------------------------------------------------------------
# main entry
# ----------------------------------------------------------------------------
def make_series(seed, out_dir, effect=None, size=None, truth_path=None, overrides=None):
    """Simulate one test series, write it to out_dir and return the truth dictionary.

    effect: None (clean) or one of EFFECTS. size: 0 (weak end) .. 1 (strong end) of
    the effect's range; drawn (skewed towards weak) when None. overrides: a dict that
    replaces drawn quantities after all draws are made, so every other draw stays
    the same; keys are the table/sensor draws (e.g. "spread", "quiet", "a_noise",
    "F_noise", "u_noise", "F_hum", "fs", "alpha", "mu", ...) or an effect
    parameter ("static_ratio", "delay", "drift", ...).
    """
    t_start = time.time()
    if effect is not None and effect not in EFFECTS:
        raise ValueError(f"unknown effect {effect!r}; choose from {EFFECTS}")
    ss = np.random.SeedSequence(int(seed))
    s_tab, s_plan, s_fac, s_eff, s_noise, s_ctrl, s_desc = ss.spawn(7)
    overrides = dict(overrides or {})

    p = _draw_table(np.random.default_rng(s_tab))
    eff_keys = {"static_ratio", "stribeck_velocity", "delay", "specimen_mass",
                "specimen_frequency", "specimen_damping", "cubic_stiffness",
                "position_friction", "drift"}
    for k, val in overrides.items():
        if k in eff_keys:
            continue
        if k not in p:
            raise KeyError(f"override {k!r} is not a drawn quantity")
        p[k] = val
    p = _finish_table(p)
    de = p["desc_err"]
    p["h_desc"] = float(np.round(p["strut_h"] * (1 + de[3]), 3))

    fs = int(p["fs"])
    K = {200: 20, 500: 8, 1000: 4, 1024: 4}.get(fs, max(1, int(round(1 / (fs * 2.5e-4)))))
    dt = 1.0 / (fs * K)

    tests, plan, n = _draw_plan(np.random.default_rng(s_plan), fs)

    # commands on the fine grid
    ucmd, n_samp = [], []
    for t in tests:
        if t["kind"] == "broadband":
            T = plan["pre"] + t["bb_dur"] + plan["post"]
        else:
            T = plan["pre"] + plan["post"] + (2 * t["ramp_cycles"] + t["steady_cycles"]) / t["frequency_hz"]
        ns_ = int(np.ceil(T * fs))
        n_samp.append(ns_)
        tt = np.arange(ns_ * K) * dt
        ucmd.append(_command(tt, dt, t, plan))
    A_max = max(float(np.abs(c).max()) for c in ucmd)

    eff = _draw_effect(np.random.default_rng(s_eff), effect, size, A_max, p)
    if eff is not None:
        for k, val in overrides.items():
            if k in eff_keys and k in eff:
                eff[k] = float(val)
                eff["size"] = None          # the value no longer comes from a size
    if eff and eff["name"] == "specimen":
        for t in tests:
            t["payload_kg"] = eff["specimen_mass"]

    # per-test values of the base model
    z = np.random.default_rng(s_fac).standard_normal((4, n))
    sp = p["spread"]
    order = np.array([t["order"] for t in tests], float)
    s_pos = (order - 1) / max(1, n - 1)
    d = eff["drift"] if (eff and eff["name"] == "drift") else 0.0
    payload = np.array([t["payload_kg"] for t in tests], float)
    rigid = payload if not (eff and eff["name"] == "specimen") else np.zeros(n)
    tv = {}
    tv["Me"] = p["Me"] * (1 + sp * z[0])
    tv["Ke"] = p["Ke"] * (1 + sp * z[1])
    tv["Ce"] = p["Ce"] * (1 + sp * z[2]) * (1 - d * s_pos)
    tv["Fk"] = p["mu"] * (p["F_hd"] + (p["m_deck"] + payload) * GRAV) * (1 + sp * z[3]) * (1 - d * s_pos)
    tv["payload"] = rigid
    if eff and eff["name"] == "stiction":
        tv["rs"], tv["vs"] = eff["static_ratio"], eff["stribeck_velocity"]
    else:
        tv["rs"], tv["vs"] = p["static_ratio_clean"], p["stribeck_clean"]
    if eff and eff["name"] == "channel_delay":
        eff["delay"] = float(round(eff["delay"] / dt) * dt)   # realised on the grid

    sims = _simulate(p, tests, tv, eff, dt, K, n_samp, ucmd, s_ctrl)

    # sensors and files
    os.makedirs(out_dir, exist_ok=True)
    rn = np.random.default_rng(s_noise)
    tfmt = "%.8f" if fs == 1024 else "%.3f"
    manifest_tests = []
    for j, t in enumerate(tests):
        x = sims[j]
        meas = _sensors(rn, p, x, fs)
        nn = n_samp[j]
        tt = np.arange(nn) / fs
        cols = [tt, meas["u"], meas["F"], meas["a"], ucmd[j][::K][:nn]]
        names = ["t", "u", "F", "a", "u_cmd"]
        fmts = [tfmt, "%.7f", "%.1f", "%.4f", "%.7f"]
        if p["has_v"]:
            cols.append(meas["v"])
            names.append("v")
            fmts.append("%.5f")
        np.savetxt(os.path.join(out_dir, t["file"]), np.column_stack(cols), fmt=fmts,
                   delimiter=",", header=",".join(names), comments="")
        mt = {"id": t["id"], "file": t["file"], "kind": t["kind"]}
        if t["kind"] != "broadband":
            mt["frequency_hz"] = t["frequency_hz"]
            mt["amplitude_m"] = t["amplitude_m"]
        mt["payload_kg"] = float(t["payload_kg"])
        mt["order"] = int(t["order"])
        manifest_tests.append(mt)

    table = {
        "deck_mass_kg": float(np.round(p["m_deck"] * (1 + de[0]), -1)),
        "strut": {"p0_pa": float(np.round(p["strut_p0"] * (1 + de[1]), -4)),
                  "area_m2": float(np.round(p["strut_A"] * (1 + de[2]), 5)),
                  "h_m": float(np.round(p["h_desc"], 3)),
                  "l0_m": float(np.round(p["strut_l0"] * (1 + de[4]), 3)),
                  "gamma": float(np.round(p["strut_gamma"], 2))},
        "oil": {"bulk_modulus_pa": float(np.round(p["beta"] * (1 + de[5]), -7)),
                "piston_area_m2": float(np.round(p["Ap"] * (1 + 0.3 * de[6]), 4)),
                "oil_volume_m3": float(np.round(p["Vt"] * (1 + de[7]), 5))},
    }
    h_m = table["strut"]["h_m"]
    manifest = {"format": "sst-series/1", "name": f"sixth-sim-{seed}", "table": table,
                "tests": manifest_tests}
    with open(os.path.join(out_dir, "series.json"), "w") as fh:
        json.dump(manifest, fh, indent=1)

    truth = {
        "seed": int(seed), "Me": p["Me"], "Ke": p["Ke"], "Ce": p["Ce"], "alpha": p["alpha"],
        "Fmu": p["Fmu"], "spread": p["spread"], "fs": fs, "n_tests": n,
        "effect": None,
        "mu": p["mu"], "F_hd": p["F_hd"], "m_deck": p["m_deck"], "m_rod": p["m_rod"],
        "static_ratio_clean": p["static_ratio_clean"],
        "stribeck_velocity_clean": p["stribeck_clean"],
        "f_oil_hz": p["f_oil"], "k_oil": p["k_oil"], "oil_volume_m3": p["Vt"],
        "Ap": p["Ap"], "beta": p["beta"], "Ps": p["Ps"], "f_valve": p["f_valve"],
        "z_valve": p["z_valve"], "dt": dt,
        "controller": {k: float(p[k]) for k in ("Kp", "Ki", "Kd", "Kff", "Kdp", "f_dp_hp",
                                                "f_cross", "zeta_dp")},
        "noise": {k: (float(p[k]) if not p["quiet"] else 0.0)
                  for k in ("u_noise", "u_offset", "a_noise", "a_offset", "F_noise", "F_ar",
                            "F_hum", "F_offset", "v_noise")},
        "quiet": bool(p["quiet"]), "has_v": bool(p["has_v"]),
        "ramp_shape": plan["ramp_shape"], "strut_h_desc": p["h_desc"], "h_m_manifest": h_m,
        "A_max": A_max,
        "tests": [{"id": t["id"], "order": int(t["order"]), "Me": float(tv["Me"][j]),
                   "mass": float(tv["Me"][j] + tv["payload"][j]),
                   "Ke": float(tv["Ke"][j]), "Ce": float(tv["Ce"][j]),
                   "Fmu": float(tv["Fk"][j]),
                   "stick_fraction": float(sims[j]["stick"].mean()),
                   "peak_spool": float(np.abs(sims[j]["spool"]).max())}
                  for j, t in enumerate(tests)],
    }
    if eff is not None:
        keep = {"stiction": ("static_ratio", "stribeck_velocity"),
                "channel_delay": ("delay",),
                "specimen": ("specimen_mass", "specimen_frequency", "specimen_damping"),
                "nonlinear_stiffness": ("cubic_stiffness",),
                "position_friction": ("position_friction",),
                "drift": ("drift",)}[eff["name"]]
        e_out = {"name": eff["name"]}
        for k in keep:
            e_out[k] = float(eff[k])
        e_out["size"] = eff["size"]
        if "fraction_at_max" in eff:
            e_out["fraction_at_max"] = eff["fraction_at_max"]
        truth["effect"] = e_out
    truth["gen_seconds"] = time.time() - t_start
    truth = json.loads(json.dumps(truth, default=float))
    if truth_path:
        with open(truth_path, "w") as fh:
            json.dump(truth, fh, indent=1)
    # keep the raw noise-free states for self checks (not written to disk)
    make_series.last_sims = sims
    make_series.last_tv = tv
    make_series.last_p = p
    return truth


def main():
    ap = argparse.ArgumentParser(description="sixth independent shaking-table simulator")
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--effect", default=None, choices=EFFECTS)
    ap.add_argument("--size", type=float, default=None,
                    help="effect size as a fraction 0..1 of the effect's range")
    a = ap.parse_args()
    truth = make_series(a.seed, a.out, effect=a.effect, size=a.size,
                        truth_path=os.path.join(a.out, "truth.json"))
    print(json.dumps({k: truth[k] for k in ("seed", "Me", "Ke", "Ce", "alpha", "Fmu",
                                            "spread", "fs", "n_tests", "effect")}, indent=1))


if __name__ == "__main__":
    main()
