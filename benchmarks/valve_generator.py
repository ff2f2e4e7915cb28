#!/usr/bin/env python
"""Physics-based generator of shaking-table test series (blind check data).

Written from first principles, independently of the identification package.
One horizontal deck DOF driven by an equivalent double-acting cylinder:

  servo-valve   spool 2nd order (40-80 Hz), sign-aware orifice flow
                Q = Kv*x*sqrt(dp) (supply 21 MPa, tank 0, small linear zone |dp|<0.5 MPa)
  cylinder      dp_i/dt = beta/V_i (Q_i -/+ Ap*v - leakage), V_1,2 = V0 +/- Ap*u
  load cell     between piston rod and deck: reads F = (p1-p2)*Ap - seal friction
  deck          Me*a = F - Ke*u - Ce|v|^alpha sgn v - friction (+ effects)
                friction: Coulomb + Stribeck with true sticking (time-stepping scheme:
                the deck stops exactly when the force it would need to keep moving
                is within the static limit); damping handled implicitly.
  controller    three-variable: displacement PID + velocity FF + force FF through a
                differential-pressure feedback that damps the oil column, with valve
                flow linearisation.
  DAQ           4-pole Butterworth anti-alias (analog-like, causal), decimation,
                white + AR(1) noise, offsets, 50 Hz hum on F, 16-bit ADC.

Usage: python valve_generator.py --seed N --out DIR [--effect NAME] [--size strong|weak]
"""
import argparse
import json
import math
import os
import time

import numpy as np
from scipy import signal

G = 9.81
PS = 21e6                      # supply pressure, Pa
P_MIN = 1e4                    # cavitation floor, Pa
DP_LIN = 5e5                   # orifice laminar zone, Pa
VR = 1.0                       # valve rated: Q = Ap*VR at full spool, zero load
RATES = (200, 256, 500, 512, 1000)
F_INT = 10000.0                # nominal internal rate, Hz
FULL = {"u": 0.25, "F": 300e3, "a": 20.0, "v": 1.0}
EFFECTS = ("stiction", "nonlinear_stiffness", "position_friction", "specimen",
           "channel_delay", "drift")
V_LIM, A_LIM, U_LIM = 0.5, 8.0, 0.12


def _lu(r, lo, hi):
    return float(np.exp(r.uniform(np.log(lo), np.log(hi))))


# ----------------------------------------------------------------------------- draws
def _draw_table(rb, effect):
    hlo, hhi = (0.4, 0.7) if effect == "nonlinear_stiffness" else (0.4, 1.5)
    for _ in range(100000):
        Me, Ke = _lu(rb, 7e3, 22e3), _lu(rb, 0.3e6, 1.8e6)
        deck = Me * rb.uniform(0.87, 1.0)
        Fmu, mu = _lu(rb, 5e3, 25e3), rb.uniform(0.006, 0.025)
        Nhd = Fmu / mu - deck * G               # hold-down force 4*p0*A
        h = Nhd / Ke
        if hlo <= h <= hhi:
            break
    alpha = rb.uniform(0.3, 1.0)
    Ce = _lu(rb, 3e3, 15e3) / 0.3 ** alpha
    p0 = rb.uniform(2e6, 8e6)
    T = dict(Me=Me, Ke=Ke, Ce=Ce, alpha=alpha, Fmu=Fmu, mu=mu, deck=deck, Nhd=Nhd,
             h=h, p0=p0, A=Nhd / (4 * p0))
    # oil column: 4*beta*Ap^2/Vt with Me at f_oil; Ap large enough for the force needed
    beta, f_oil, L0 = rb.uniform(1.2e9, 1.6e9), rb.uniform(15, 40), rb.uniform(0.45, 0.8)
    w2 = (2 * np.pi * f_oil) ** 2
    Fneed = (Me + 8000) * A_LIM + 1.3 * (Fmu + Ce * 0.5 ** alpha) + Ke * 0.04
    Ap = max(Me * w2 * L0 / (4 * beta), Fneed / (0.55 * PS))
    Vt = 4 * beta * Ap ** 2 / (Me * w2)
    T.update(beta=beta, f_oil=f_oil, Ap=Ap, Vt=Vt, Kv=Ap * VR / math.sqrt(PS / 2),
             Cl=0.003 * Ap * VR / PS, fv=rb.uniform(40, 80), zv=rb.uniform(0.6, 0.8),
             seal_c=rb.uniform(0.01, 0.03) * Fmu, seal_v=rb.uniform(0.002, 0.01) * Fmu / 0.5,
             rs=rb.uniform(1.0, 1.05), vs=rb.uniform(1e-3, 5e-3),
             sig=rb.uniform(0.005, 0.03, 4), sig_alpha=rb.uniform(0.003, 0.015))
    # controller, tuned on nominal (design) values known to the operator
    Mn = Me * (1 + 0.05 * rb.standard_normal())
    wh = math.sqrt(4 * beta * Ap ** 2 / (Vt * Mn))
    zh = min(0.7, 0.25 * T["fv"] / f_oil)
    Kce = 2 * zh * Ap ** 2 / (Mn * wh)             # equivalent flow-pressure coefficient
    Kvl = min(0.35 * 2 * zh * wh, 2 * np.pi * 5)   # position loop gain 1/s
    err = np.clip(rb.normal(0, [0.1, 0.1, 0.2]), -0.25, 0.25)  # operator model errors
    T["ctl"] = dict(Mn=Mn, Ken=Ke * (1 + err[0]), Fn=Fmu * (1 + err[1]), Cn=Ce * (1 + err[2]),
                    zh=zh, Kvl=Kvl,
                    kdp=Kce / (Ap * VR), wi=0.1 * Kvl, Td=0.15 / Kvl, wd=2 * np.pi * 100)
    return T


def _draw_daq(rb):
    rate = int(rb.choice(RATES))
    return dict(rate=rate, aa=rb.uniform(0.3, 0.4), nF=rb.uniform(0.003, 0.01),
                nu=rb.uniform(5e-6, 20e-6), na=rb.uniform(0.01, 0.05), nv=rb.uniform(5e-4, 2e-3),
                hum=rb.uniform(20, 150), white=rb.uniform(0.4, 0.8, 4),
                corner=rb.uniform(0.3, 3.0, 4))


def _draw_effect(re, effect, strong):
    if effect == "stiction":
        return {"static_ratio": re.uniform(1.2, 1.6) if strong else re.uniform(1.15, 1.25),
                "stribeck_velocity": re.uniform(5e-3, 20e-3)}
    if effect == "nonlinear_stiffness":
        return {"ratio": re.uniform(1, 3) if strong else re.uniform(0.5, 1)}
    if effect == "position_friction":
        return {"frac": re.uniform(0.05, 0.15) if strong else re.uniform(0.02, 0.04)}
    if effect == "specimen":
        return {"specimen_mass": re.uniform(1e3, 5e3) if strong else re.uniform(700, 1500),
                "specimen_frequency": re.uniform(3, 15), "damping_ratio": re.uniform(0.02, 0.05)}
    if effect == "channel_delay":
        return {"delay": re.uniform(1e-3, 5e-3) if strong else re.uniform(0.4e-3, 1e-3)}
    if effect == "drift":
        return {"drift": re.uniform(0.10, 0.25) if strong else re.uniform(0.04, 0.08)}
    return {}


def _amp_limit(kind, f, T, M, eff):
    w = 2 * np.pi * f
    if kind == "sine":
        lim = min(U_LIM, V_LIM / w, A_LIM / w ** 2)
    else:
        lim = min(U_LIM, V_LIM / (4 * f) * 0.95, 0.25 / f ** 2 * 0.9)
    dyn = M * w ** 2 + T["Ke"]                      # force limit, incl. specimen shear
    if "specimen_mass" in eff:
        r, z = f / eff["specimen_frequency"], eff["damping_ratio"]
        Tr = abs((1 + 2j * z * r) / (1 - r ** 2 + 2j * z * r))
        dyn += eff["specimen_mass"] * w ** 2 * Tr
    Fcap = min(0.55 * PS * T["Ap"], 0.8 * FULL["F"])           # actuator and load-cell range
    Fav = Fcap - 1.3 * (T["Fmu"] + T["Ce"] * (w * lim) ** T["alpha"])
    return min(lim, max(Fav, 0.3 * Fcap) / dyn)


# ----------------------------------------------------------------------------- commands
def _command(test, fs, rng):
    """Command displacement at the internal rate, plus steady window (s)."""
    pre, post = test["rest"]
    if test["kind"] == "broadband":
        Tb, Tr = test["duration"], 2.0
        n = int(round((pre + Tb + post) * fs))
        m = int(round(Tb * fs))
        acc = rng.standard_normal(m)
        spec = np.fft.rfft(acc)
        fr = np.fft.rfftfreq(m, 1 / fs)
        band = (fr >= 0.5) & (fr <= 30)
        spec = np.where(band, -spec / np.maximum((2 * np.pi * fr) ** 2, 1e-12), 0)
        tt = np.arange(m) / fs
        env = np.clip(np.minimum(tt, Tb - tt) / Tr, 0, 1)
        uc = np.zeros(n)
        i0 = int(round(pre * fs))
        uc[i0:i0 + m] = np.fft.irfft(spec, m) * 0.5 * (1 - np.cos(np.pi * env))
        win = (pre + Tr, pre + Tb - Tr)
        amp_cap = 0.06
    else:
        f, nr, ns = test["frequency_hz"], test["ramp_cycles"], test["steady_cycles"]
        T1 = (2 * nr + ns) / f
        n = int(round((pre + T1 + post) * fs))
        tau = np.arange(n) / fs - pre
        ph = 2 * np.pi * f * tau
        if test["kind"] == "sine":
            base = np.sin(ph)
        else:                  # triangle, corners box-averaged over wdt: finite acceleration
            wdt = min(max(V_LIM / A_LIM, 0.06 / f), 0.25 / f)
            k = max(int(round(wdt * fs)), 1)
            tri = 2 / np.pi * np.arcsin(np.sin(ph))
            base = np.convolve(np.pad(tri, k, mode="reflect"), np.ones(k) / k, "same")[k:-k]
            base /= np.max(np.abs(base[(tau > nr / f) & (tau < (nr + ns) / f)]))
        Tr = nr / f
        env = np.where(tau < Tr, 0.5 * (1 - np.cos(np.pi * np.clip(tau / Tr, 0, 1))), 1.0)
        tail = tau - (T1 - Tr)
        env = np.where(tail > 0, 0.5 * (1 + np.cos(np.pi * np.clip(tail / Tr, 0, 1))), env)
        env[(tau < 0) | (tau > T1)] = 0
        uc = env * base
        win = (pre + Tr, pre + T1 - Tr)
        amp_cap = test["amplitude_m"]
    vc = np.gradient(uc, 1 / fs)
    ac = np.gradient(vc, 1 / fs)
    s = min(amp_cap / np.max(np.abs(uc)), 0.98 * V_LIM / np.max(np.abs(vc)),
            0.98 * A_LIM / np.max(np.abs(ac)))
    if test["kind"] != "broadband":
        test["amplitude_m"] = float(s)            # after the velocity/acceleration check
    return uc * s, vc * s, ac * s, win


# ----------------------------------------------------------------------------- physics
def _simulate(job):
    """Integrate one test at the internal rate (fixed step, semi-implicit)."""
    uc, xff, c = job
    uc, xff = uc.tolist(), xff.tolist()
    n = len(uc)
    dt, fs = c["dt"], 1.0 / c["dt"]
    Ap, Kv, V0, beta, Cl = c["Ap"], c["Kv"], c["V0"], c["beta"], c["Cl"]
    wv2, zw2 = c["wv"] ** 2, 2 * c["zv"] * c["wv"]
    Fsc, csl, vsl = c["seal_c"], c["seal_v"], 1e-3
    M, Ke, Ce, al = c["M"], c["Ke"], c["Ce"], c["alpha"]
    ial = 1.0 / al
    Fmu, Fs, vs = c["Fmu"], c["Fs"], c["vs"]
    dFs = Fs - Fmu
    K3, h, Fp = c["K3"], c["h"], c["Fp"]
    ms, ks, cs = c["ms"], c["ks"], c["cs"]
    spec, cubic, hinge = ms > 0, K3 != 0, Fp != 0
    ge, gi, gd, kdp = c["ge"], c["gi"], c["gd"], c["kdp"]
    wd = c["wd"]
    Mdt = M / dt
    u = v = x = xd = ie = ef = z = zd = 0.0
    p1 = p2 = 0.5 * PS
    U, Vv, A, F = [0.0] * n, [0.0] * n, [0.0] * n, [0.0] * n
    sqrt, exp, tanh = math.sqrt, math.exp, math.tanh
    g_min = 0.2 * PS
    for k in range(n):
        e = uc[k] - u
        ie += e * dt
        ef += wd * dt * (e - ef)
        dP = p1 - p2
        xr = xff[k] + ge * e + gi * ie + gd * wd * (e - ef) - kdp * dP
        g = PS - dP if xr >= 0.0 else PS + dP     # valve flow linearisation
        xr *= sqrt(PS / (g if g > g_min else g_min))
        if xr > 1.0:
            xr = 1.0
        elif xr < -1.0:
            xr = -1.0
        xd += dt * (wv2 * (xr - x) - zw2 * xd)
        x += dt * xd
        if x >= 0.0:
            d1, d2 = PS - p1, p2
        else:
            d1, d2 = p1, PS - p2
        a1, a2 = abs(d1), abs(d2)
        q1 = Kv * x * d1 / sqrt(a1 if a1 > DP_LIN else DP_LIN)
        q2 = -Kv * x * d2 / sqrt(a2 if a2 > DP_LIN else DP_LIN)
        FA = Ap * dP - Fsc * tanh(v / vsl) - csl * v          # load-cell force on deck
        Fr = FA - Ke * u
        if cubic:
            Fr -= K3 * (u / h) ** 2 * u
        if spec:
            Fr += ks * z + cs * zd
        Fh = Fp * (u / h) ** 2 if hinge else 0.0
        P = Fr + Mdt * v
        aP = abs(P)
        if aP <= Fs + Fh:
            w = 0.0                                               # stick
        else:
            R = aP - Fh - Fmu - dFs * exp(-(v / vs) ** 2)
            y = (R / Mdt) ** al                                   # y = |w|^alpha
            for _ in range(3):
                yp = y ** (ial - 1.0)
                y -= (Mdt * yp * y + Ce * y - R) / (Mdt * ial * yp + Ce)
            w = y ** ial if P > 0 else -(y ** ial)
        acc = (w - v) * fs
        U[k], Vv[k], A[k], F[k] = u, w, acc, FA
        v = w
        u += dt * v
        if spec:
            zd += dt * (-(ks * z + cs * zd) / ms - acc)
            z += dt * zd
        QL = Cl * dP
        p1 += dt * beta / (V0 + Ap * u) * (q1 - Ap * v - QL)
        p2 += dt * beta / (V0 - Ap * u) * (q2 + Ap * v + QL)
        if p1 < P_MIN:
            p1 = P_MIN
        if p2 < P_MIN:
            p2 = P_MIN
    return np.array(U), np.array(Vv), np.array(A), np.array(F)


# ----------------------------------------------------------------------------- DAQ
def _daq(sim, uc, c, D, rng, delay):
    u, v, a, F = sim
    fs, N, rate = 1.0 / c["dt"], c["decim"], D["rate"]
    n = len(u)
    ti = np.arange(n) / fs
    if delay:                                     # fractional delay at internal rate
        F = np.interp(np.arange(n) - delay * fs, np.arange(n), F, left=0.0)
    F = F + D["hum"] * np.sin(2 * np.pi * 50 * ti + rng.uniform(0, 2 * np.pi))
    X = np.vstack([u, F, a, v])
    sos = signal.butter(4, D["aa"] * rate, fs=fs, output="sos")
    Y = signal.sosfilt(sos, X, axis=1)[:, ::N]
    Wn = signal.sosfilt(sos, rng.standard_normal((4, n)), axis=1)[:, ::N]
    m = Y.shape[1]
    lvl = np.array([D["nu"], D["nF"] * np.max(np.abs(sim[3])), D["na"], D["nv"]])
    off = np.array([5e-4, 500.0, 0.02, 1e-3]) * rng.uniform(-1, 1, 4)
    out = {}
    for i, key in enumerate("uFav"):
        wf = D["white"][i]
        rho = math.exp(-2 * np.pi * D["corner"][i] / rate)
        col = signal.lfilter([math.sqrt(1 - rho ** 2)], [1, -rho], rng.standard_normal(m),
                             zi=[rho * rng.standard_normal()])[0]
        y = Y[i] + lvl[i] * (math.sqrt(wf) * Wn[i] / np.std(Wn[i]) + math.sqrt(1 - wf) * col)
        lsb = 2 * FULL[key] / 2 ** 16
        out[key] = np.clip(np.round((y + off[i]) / lsb) * lsb, -FULL[key], FULL[key] - lsb)
    out["t"] = np.arange(m) / rate
    out["u_cmd"] = uc[::N][:m]
    return out


# ----------------------------------------------------------------------------- series
def _plan_tests(rb, T, eff):
    n = int(rb.integers(12, 26))
    n_bb = int(rb.integers(1, 3)) if rb.random() < 1 / 3 else 0
    has_pay = rb.random() < 1 / 3
    n_per = n - n_bb
    fr = 0.2 * 25 ** ((rb.permutation(n_per) + rb.uniform(0, 1, n_per)) / n_per)
    pay = np.zeros(n)
    if has_pay:
        pay[rb.choice(n, int(round(0.3 * n)), replace=False)] = rb.uniform(2000, 8000, int(round(0.3 * n)))
    tests = []
    for i in range(n):
        t = {"payload_kg": float(round(pay[i], 1)), "rest": rb.uniform(0.5, 1.5, 2).tolist()}
        if i < n_per:
            f = float(fr[i])
            t.update(kind="sine" if rb.random() < 0.6 else "triangle", frequency_hz=f,
                     ramp_cycles=2 if f < 0.5 else int(rb.integers(2, 5)),
                     steady_cycles=int(np.clip(round(f * rb.uniform(4, 8)), 5, 40)))
            lim = _amp_limit(t["kind"], f, T, T["Me"] + pay[i], eff)
            t["amplitude_m"] = float(max(lim * rb.uniform(0.35, 1.0), min(0.003, lim)))
        else:
            t.update(kind="broadband", duration=rb.uniform(15, 25))
        tests.append(t)
    order = rb.permutation(n) + 1
    rb.shuffle(tests)
    tests.sort(key=lambda t: (t["kind"], t.get("frequency_hz", 0)))
    for i, t in enumerate(tests):
        t["id"] = "%s%02d" % (t["kind"][0].upper(), i + 1)
        t["order"] = int(order[i])
    return tests


NOTES = (
    "Deck truth: F = Me*a + Ke*u + Ce*|v|^alpha*sgn(v) + Fmu*sgn(v), F the load-cell force "
    "(cell between piston rod and deck), so the actuator's own seal friction (table_internal."
    "seal_coulomb_N/seal_viscous_Ns_m) is NOT in Fmu or Ce and does not appear in F's balance. "
    "Fmu is the kinetic (high-velocity) Coulomb level; clean series carry a mild Stribeck rise "
    "to Fs = static_ratio*Fmu (table_internal.clean_static_ratio, 1.00-1.05) below the Stribeck "
    "velocity, and the deck sticks (v = 0 exactly) while the force it needs stays within Fs. "
    "Top-level Me/Ke/Ce/alpha/Fmu are population values for the empty deck (payload 0) and, "
    "for drift, at campaign order 1. per_test values are those the deck equation used in that "
    "test: Me includes the declared payload, Fmu is scaled by (Nhd+(deck+payload)g)/(Nhd+deck g) "
    "and by the drift factor, Ce by the drift factor; specimen, cubic and hinge terms are "
    "not folded into per_test. Oil-column and valve dynamics only act through the force the "
    "actuator delivers: they shape u and F (ringing at the oil-column frequency after friction "
    "reversals, tracking error) but add no term to the deck balance. All channels pass the same "
    "causal 4-pole Butterworth anti-alias filter (cut-off aa_ratio*record rate), so they share "
    "its group delay; u_cmd is the unfiltered digital command. Offsets, hum, noise, 16-bit ADC "
    "are applied per test. position_friction: extra Coulomb level Fp*(u/h)^2 (h = strut h_m), Fp "
    "set so that at the series' largest commanded amplitude it adds frac*Fmu. nonlinear_stiffness: "
    "extra spring force cubic_stiffness*(u/h)^2*u. specimen: SDOF on the deck, base shear acts on "
    "the deck (mass not in payload_kg nor in Me). channel_delay: F recorded delay s late. drift: "
    "Fmu and Ce of the test at order k are multiplied by 1 - drift*(k-1)/(n-1).")


_JOBS = []


def _worker(i):
    return _simulate(_JOBS[i])


def generate(seed, out, effect=None, size="strong", verbose=False):
    t_start = time.time()
    if effect in ("none", "None", ""):
        effect = None
    if effect is not None and effect not in EFFECTS:
        raise ValueError("unknown effect %r" % effect)
    strong = size != "weak"
    rb = np.random.default_rng(seed)
    re = np.random.default_rng([seed, 101])
    rn = np.random.default_rng([seed, 202])
    T = _draw_table(rb, effect)
    D = _draw_daq(rb)
    has_v = rb.random() < 1 / 3
    eff = _draw_effect(re, effect, strong)
    tests = _plan_tests(rb, T, eff)
    nt = len(tests)
    rate = D["rate"]
    decim = int(round(F_INT / rate))
    fs = rate * decim
    ctl = T["ctl"]
    # commands
    cmds = []
    for t in tests:
        cmds.append(_command(t, fs, rn))
    umax = max([t["amplitude_m"] for t in tests if t["kind"] != "broadband"] + [1e-3])
    K3 = eff["ratio"] * T["Ke"] if effect == "nonlinear_stiffness" else 0.0
    Fp = eff["frac"] * T["Fmu"] / (umax / T["h"]) ** 2 if effect == "position_friction" else 0.0
    rs, vs = (eff["static_ratio"], eff["stribeck_velocity"]) if effect == "stiction" else (T["rs"], T["vs"])
    sg = T["sig"]
    jobs, per_test = [], {}
    W = T["Nhd"] + T["deck"] * G
    for t, (uc, vc, ac, win) in zip(tests, cmds):
        z = rb.standard_normal(5)
        pay = t["payload_kg"]
        dr = 1 - eff["drift"] * (t["order"] - 1) / max(nt - 1, 1) if effect == "drift" else 1.0
        al = float(np.clip(T["alpha"] + T["sig_alpha"] * z[4], 0.2, 1.0))
        tr = dict(Me=T["Me"] * math.exp(sg[0] * z[0]) + pay, Ke=T["Ke"] * math.exp(sg[1] * z[1]),
                  Ce=T["Ce"] * math.exp(sg[2] * z[2]) * dr, alpha=al,
                  Fmu=T["Fmu"] * math.exp(sg[3] * z[3]) * (W + pay * G) / W * dr)
        per_test[t["id"]] = dict(tr, payload_kg=pay)
        Mn = ctl["Mn"] + pay
        Fn = ctl["Fn"] * (W + pay * G) / W
        Fff = Mn * ac + ctl["Ken"] * uc + (Fn * np.tanh(vc / 0.005)
                                           + ctl["Cn"] * np.abs(vc) ** T["alpha"] * np.sign(vc))
        # oil-compressibility (pressure-rate) feed-forward of the inertial + spring force
        k5 = max(int(0.005 * fs), 1)
        dFl = np.convolve(np.gradient(Mn * ac + ctl["Ken"] * uc, 1 / fs), np.ones(k5) / k5, "same")
        xff = (vc + T["Vt"] / (4 * T["beta"] * T["Ap"] ** 2) * dFl) / VR + ctl["kdp"] * Fff / T["Ap"]
        xff += T["zv"] / (2 * np.pi * T["fv"]) * np.gradient(xff, 1 / fs)   # valve-lag lead
        ge = ctl["Kvl"] / VR
        c = dict(dt=1.0 / fs, decim=decim, Ap=T["Ap"], Kv=T["Kv"], V0=T["Vt"] / 2, beta=T["beta"],
                 Cl=T["Cl"], wv=2 * np.pi * T["fv"], zv=T["zv"], seal_c=T["seal_c"],
                 seal_v=T["seal_v"], M=tr["Me"], Ke=tr["Ke"], Ce=tr["Ce"], alpha=al,
                 Fmu=tr["Fmu"], Fs=rs * tr["Fmu"], vs=vs, K3=K3, h=T["h"], Fp=Fp,
                 ms=0.0, ks=0.0, cs=0.0, ge=ge, gi=ge * ctl["wi"], gd=ge * ctl["Td"],
                 kdp=ctl["kdp"], wd=ctl["wd"])
        if effect == "specimen":
            ms, wsp = eff["specimen_mass"], 2 * np.pi * eff["specimen_frequency"]
            c.update(ms=ms, ks=ms * wsp ** 2, cs=2 * eff["damping_ratio"] * ms * wsp)
        t["steady_start_s"], t["steady_end_s"] = float(win[0]), float(win[1])
        jobs.append((uc, xff, c))
    # simulate, longest first, on all cores
    idx = sorted(range(nt), key=lambda i: -len(jobs[i][0]))
    sims = [None] * nt
    _JOBS[:] = jobs                                # read by forked workers
    try:
        import multiprocessing as mp
        ncpu = min(int(os.environ.get("VALVE_GEN_PROCS", os.cpu_count() or 1)), 8, nt)
        if ncpu < 2:
            raise RuntimeError("one core")
        with mp.get_context("fork").Pool(ncpu) as pool:
            for i, r in zip(idx, pool.imap(_worker, idx)):
                sims[i] = r
    except Exception:                              # no fork / not picklable: run serially
        for i in idx:
            if sims[i] is None:
                sims[i] = _simulate(jobs[i])
    _JOBS[:] = []
    t_sim = time.time() - t_start
    # record, write
    os.makedirs(out, exist_ok=True)
    delay = eff.get("delay", 0.0)
    man = []
    for t, sim, (uc, _, _, _), job in zip(tests, sims, cmds, jobs):
        rec = _daq(sim, uc, job[2], D, rn, delay)
        cols = ["t", "u", "F", "a", "u_cmd"] + (["v"] if has_v else [])
        fname = t["id"] + ".csv"
        np.savetxt(os.path.join(out, fname), np.column_stack([rec[k] for k in cols]),
                   delimiter=",", header=",".join(cols), comments="",
                   fmt=["%.6f", "%.7e", "%.6e", "%.6e", "%.7e"] + (["%.6e"] if has_v else []))
        e = {"id": t["id"], "file": fname, "kind": t["kind"]}
        if t["kind"] != "broadband":
            e.update(frequency_hz=round(t["frequency_hz"], 6), amplitude_m=round(t["amplitude_m"], 7))
        e.update(payload_kg=t["payload_kg"], order=t["order"],
                 steady_start_s=round(t["steady_start_s"], 4), steady_end_s=round(t["steady_end_s"], 4))
        man.append(e)
    man.sort(key=lambda e: e["id"])
    series = {"format": "sst-series/1", "name": "valve-gen-s%d-%s%s" % (seed, effect or "clean",
                                                                       "" if effect is None else "-" + size),
              "table": {"deck_mass_kg": round(T["deck"], 1),
                        "strut": {"p0_pa": round(T["p0"], 1), "area_m2": T["A"], "h_m": T["h"]},
                        "oil": {"bulk_modulus_pa": round(T["beta"], 1), "piston_area_m2": T["Ap"],
                                "oil_volume_m3": T["Vt"]}},
              "tests": man}
    with open(os.path.join(out, "series.json"), "w") as fh:
        json.dump(series, fh, indent=1)
    ep = {}
    if effect == "stiction":
        ep = dict(eff)
    elif effect == "nonlinear_stiffness":
        ep = {"cubic_stiffness": K3, "h_m": T["h"], "rel_at_max_amplitude": K3 * (umax / T["h"]) ** 2 / T["Ke"]}
    elif effect == "position_friction":
        ep = {"position_friction": Fp, "h_m": T["h"], "reference_amplitude_m": umax, "frac_of_Fmu": eff["frac"]}
    elif effect in ("specimen", "channel_delay", "drift"):
        ep = dict(eff)
    truth = {"Me": T["Me"], "Ke": T["Ke"], "Ce": T["Ce"], "alpha": T["alpha"], "Fmu": T["Fmu"],
             "effect": effect, "size": size if effect else None, "seed": seed,
             "record_rate_hz": rate, "effect_params": ep, "per_test": per_test,
             "table_internal": {
                 "mu_e": T["mu"], "holddown_N": T["Nhd"], "deck_mass_kg": T["deck"],
                 "clean_static_ratio": T["rs"], "clean_stribeck_velocity": T["vs"],
                 "spread_Me_Ke_Ce_Fmu": T["sig"].tolist(), "spread_alpha_abs": T["sig_alpha"],
                 "oil_column_hz_empty": T["f_oil"], "valve_bandwidth_hz": T["fv"], "valve_damping": T["zv"],
                 "seal_coulomb_N": T["seal_c"], "seal_viscous_Ns_m": T["seal_v"],
                 "internal_rate_hz": fs, "aa_cutoff_hz": D["aa"] * rate, "v_column": has_v,
                 "controller": {k: float(v) for k, v in ctl.items()}},
             "notes": NOTES}
    with open(os.path.join(out, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=1)
    if verbose:
        print("seed %d effect %s: %d tests, rate %d Hz, sim %.1f s, total %.1f s -> %s"
              % (seed, effect, nt, rate, t_sim, time.time() - t_start, out))
    return truth


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--effect", default="none", choices=["none"] + list(EFFECTS))
    ap.add_argument("--size", default="strong", choices=["strong", "weak"])
    a = ap.parse_args()
    generate(a.seed, a.out, a.effect, a.size, verbose=True)


if __name__ == "__main__":
    main()
