"""Tenth blind generator: a servo-hydraulic "virtual shaking table" with a pressure-derived force.

Writes one test series (format sst-series/1, /work/shared/DATA_FORMAT.md) plus truth.json for a
deck modelled on the Sharif University table, identified with

    F = Me a + Ke u + (Ce |v|^alpha + Fmu) sign(v)

Physics (fixed step 1/4096 s, written independently of the identification package):

* Force from differential pressure.  The recorded F is (p1 - p2) A_piston from two chamber
  transducers (0-35 MPa, 16-bit), each with its own white noise, offset and pump ripple (axial
  piston pump, 9 pistons, shaft 24-25 Hz: 9x shaft and its 2nd/3rd harmonics plus a 1x shaft
  line; amplitudes and phases differ per chamber, so the ripple does not cancel in p1 - p2).
  Chambers: p1,2 = Ps/2 +- pL/2 (matched symmetric valve).  Because the force is taken in the
  chambers it contains the piston/rod mass times a and the actuator's seal (Coulomb) friction.
  The truth is the balance the recorded force obeys: Me = deck + piston/rod, Fmu = deck friction
  mu_e (F_hd + deck weight) + seal Coulomb friction.  No viscous seal term is simulated.
* Deck: Ke u (nitrogen struts, Ke = 4 p0 A / h), power-law damping Ce |v|^alpha, friction with
  an implicit (Karnopp-type) stick law solved jointly with the oil column by backward Euler: the
  deck is held exactly at v = 0 while the force needed to hold it is below the static level;
  while slipping the friction is Fk + (Fs - Fk) exp(-(v/vs)^2), Fs/Fk 1.00-1.04 when clean.
  Power law and Stribeck are solved implicitly (scalar Newton), so F obeys the balance with the
  backward-difference acceleration to rounding.  A payload (kg in the manifest) adds mass and
  mu_e payload g to the deck friction; truth Me/Fmu exclude it.
* Test-to-test variation: Me (deck part), Ke, Ce, friction 1-3 % sd, normalised so that the
  campaign mean is the truth (a pooled least-squares fit weights tests unequally, so it lands a few
  % from the mean; with the variation off it recovers the truth to < 1 %).
* Oil column: dF/dt = k_h (q - v) - F/tau_leak, k_h = 2 beta A^2 / V (25-40 Hz with the deck mass).
* Servo-valve: spool 2nd order 60-150 Hz (exact discretisation), saturating at +-1, flow
  q = vmax x sqrt(1 - sign(x) F/Fmax).
* Controller (2048/4096 Hz digital loop, one sample of computational delay, ZOH): velocity +
  jerk (oil compressibility, dF_ff/dt / k_h) flow feed-forward taken from the command previewed by
  the valve lag + loop delay (the command file is known ahead), displacement P feedback
  and Delta-p (force) feedback on F - F_ff, F_ff the model force of the command (controller's own
  estimates, a few % off).  Flow linearisation divides by sqrt(1 - sign F/Fmax) with measured F.
  Gains are chosen on the linear model (with a Pade delay) so that the clean |u/u_cmd| stays
  within ~2 % of 1 and the loop is stable.
* DAQ: analog-like 4th-order Butterworth anti-alias at 0.3-0.45 fs, fs in {256,512,1024,2048} Hz
  nominal; the real sample clock is 30-200 ppm off but t is written as i/fs_nominal (so in the
  written time axis a commanded frequency_hz appears lower by the factor 1/(1 + skew)).  LVDT: 5-20 um
  white + 16-bit over +-150 mm; accelerometer 0.01-0.05 m/s^2 white + offset + linear drift; a
  velocity channel on ~1/4 of the seeds; u_cmd always, a_cmd on about half of the seeds.
* Tests: 12-20 periodic (sines 0.1-6 Hz, 2-4 rounded triangles), cosine ramps of 1-3 cycles,
  >= 5 steady cycles, rests; a contiguous payload block of 2-3 tests (1-6 t); 1-2 broadband tests
  (band-limited random up to 20-40 Hz, 20-40 s) on half of the seeds and always for oil_column.
  Campaign trimmed so that the folder stays under ~10 MB.

Effect force (what effect_rms_N measures, through the same anti-alias filter): stiction: friction
beyond the kinetic level (Stribeck excess while slipping, holding force beyond +-Fk while stuck);
nonlinear_stiffness K3 (u/h)^2 u; position_friction Fp (u/h)^2 sign v; specimen: its base shear;
channel_delay: delayed minus undelayed force; drift: the dissipative force minus its campaign-mean
value.  noise_rms_N: recorded F minus the noiseless filtered F (pressure noise, ripple,
quantisation), offset removed.

Withheld effects (--effect NAME --size strong|weak): stiction, nonlinear_stiffness,
position_friction, specimen, channel_delay, drift, oil_column.  Strong: effect-force RMS over
the periodic tests' steady cycles >= 1x force-noise RMS (parameters start in their strong
range, scaled up if needed); weak: rescaled by re-simulation to 0.3-0.5x.  The specimen's
weight is not added to the friction normal load (only its base shear acts).  oil_column: the
effective bulk modulus drops (entrained air) so the open column sits at 8-18 Hz, the Delta-p gain
leaves it 5-20 % damped: |u/u_cmd| has a clear peak; the force balance itself is unchanged.

CLI: python benchmarks/tenth_generator.py --seed N --out DIR [--effect NAME] [--size strong|weak]
"""
import argparse
import json
import math
import os
import time

import numpy as np
from scipy import signal

DT = 1.0 / 4096
G = 9.81
RATES = (256, 512, 1024, 2048)
EFFECTS = ("stiction", "nonlinear_stiffness", "position_friction", "specimen", "channel_delay", "drift",
           "oil_column")
P_FS = 35e6  # pressure transducer full scale


# ----------------------------------------------------------------------------------------- draws
def _draw_table(rng):
    p = {}
    p["m_deck"] = rng.uniform(9000, 13500)
    p["m_piston"] = rng.uniform(600, 1500)
    p["Me"] = p["m_deck"] + p["m_piston"]
    p["Ke"] = rng.uniform(0.4e6, 1.5e6)
    p["p0"] = rng.uniform(5e6, 8e6)
    p["strut_area"] = rng.uniform(0.025, 0.035)
    p["h"] = 4 * p["p0"] * p["strut_area"] / p["Ke"]
    p["l0"] = p["h"] * rng.uniform(0.6, 0.8)
    p["gamma"] = rng.uniform(1.3, 1.4)
    p["F_hd"] = 4 * p["p0"] * p["strut_area"]
    p["Ce"] = rng.uniform(15e3, 45e3)
    p["alpha"] = rng.uniform(0.3, 0.9)
    p["mu_e"] = rng.uniform(0.008, 0.02)
    p["F_deck"] = p["mu_e"] * (p["F_hd"] + p["m_deck"] * G)
    p["F_seal"] = rng.uniform(800, 2500)
    p["Fmu"] = p["F_deck"] + p["F_seal"]
    p["static_ratio"] = rng.uniform(1.0, 1.04)
    p["vs"] = rng.uniform(0.001, 0.004)
    p["A_p"] = rng.uniform(0.02, 0.03)
    p["Ps"] = rng.uniform(21e6, 28e6)
    p["Fmax"] = p["Ps"] * p["A_p"]
    p["beta"] = rng.uniform(1.2e9, 1.6e9)
    p["f_oil_nom"] = rng.uniform(25, 40)
    kh = p["Me"] * (2 * math.pi * p["f_oil_nom"]) ** 2
    p["kh"] = kh
    p["V"] = 2 * p["beta"] * p["A_p"] ** 2 / kh
    p["tau_leak"] = rng.uniform(0.5, 2.0)
    p["f_valve"] = rng.uniform(60, 150)
    p["z_valve"] = rng.uniform(0.6, 0.8)
    p["vmax"] = rng.uniform(0.7, 0.9)
    p["fc"] = int(rng.choice([2048, 4096]))
    p["sd"] = rng.uniform(0.01, 0.03)
    return p


def _plan(rng, rate, want_bb, row_bytes):
    """Test list; trimmed so that the CSVs stay under ~9.5 MB and the simulation under ~300 s."""
    tmax = min(300.0, 9.3e6 / (row_bytes * rate))
    hi = rate >= 2048
    n = int(rng.integers(12, 21))
    ntri = int(rng.integers(2, 5))
    nbb = int(rng.integers(1, 3)) if want_bb else 0
    fmin = {256: 0.1, 512: 0.1, 1024: 0.25, 2048: 0.6}[rate]
    for attempt in range(60):
        tests = []
        for i in range(n):
            tri = i < ntri
            if tri:
                f = rng.uniform(0.5, 1.0) if hi else rng.uniform(min(max(0.1, fmin * 0.6), 0.45), 0.5)
                vpk = math.exp(rng.uniform(math.log(0.01), math.log(0.15)))
                A = min(max(vpk / (4 * f), 0.002), 0.08)
            else:
                f = math.exp(rng.uniform(math.log(fmin), math.log(6)))
                vpk = math.exp(rng.uniform(math.log(0.01), math.log(0.5)))
                A = vpk / (2 * math.pi * f)
                A = min(A, 0.9 * G / (2 * math.pi * f) ** 2, 0.08, 0.5 / (2 * math.pi * f))
                A = max(A, 0.002, 0.0101 / (2 * math.pi * f))
            nr = int(rng.integers(1, 4)) if f > 0.4 else 1
            tests.append({"kind": "triangle" if tri else "sine", "f": f, "A": A, "nr": nr,
                          "ns": 5 if (f < 1 or hi) else int(rng.integers(5, 9)),
                          "rest": (0.5 if f < 2 else 0.3) if hi else (1.0 if f < 2 else 0.6)})
        for j in range(nbb):
            tests.append({"kind": "broadband", "dur": rng.uniform(20, 40) if rate <= 512 else 20.0,
                          "fhi": rng.uniform(20, 40), "rest": 1.0})
        dur = sum(_duration(t) for t in tests)
        if dur <= tmax:
            break
        n = max(12, n - 2)
        fmin = min(fmin * 1.3, 2.0)
        ntri = 2
    order = rng.permutation(len(tests))
    tests = [tests[i] for i in order]
    # payload block: 2-3 contiguous periodic tests
    per = [i for i, t in enumerate(tests) if t["kind"] != "broadband"]
    npay = int(rng.integers(2, 4))
    start = int(rng.integers(0, len(per) - npay + 1))
    mpay = rng.uniform(1000, 6000)
    for t in tests:
        t["payload"] = 0.0
    for i in per[start:start + npay]:
        tests[i]["payload"] = mpay
    cnt = {"sine": 0, "triangle": 0, "broadband": 0}
    for k, t in enumerate(tests):
        cnt[t["kind"]] += 1
        t["id"] = {"sine": "S", "triangle": "T", "broadband": "B"}[t["kind"]] + f"{cnt[t['kind']]:02d}"
        t["order"] = k + 1
    return tests


def _duration(t):
    if t["kind"] == "broadband":
        return t["dur"] + 2 * t["rest"]
    return (2 * t["nr"] + t["ns"]) / t["f"] + 2 * t["rest"]


def _command(t, rng):
    """Commanded displacement on the simulation grid plus derivatives and steady-cycle mask."""
    T = _duration(t)
    n = int(round(T / DT)) + 1
    tt = np.arange(n) * DT
    steady = np.zeros(n, bool)
    if t["kind"] == "broadband":
        x = rng.standard_normal(n)
        sos = signal.butter(4, [0.4, t["fhi"]], btype="band", fs=1 / DT, output="sos")
        x = signal.sosfiltfilt(sos, x)
        # displacement spectrum ~ 1/f^1.5 (between flat velocity and flat acceleration)
        X = np.fft.rfft(x)
        f = np.fft.rfftfreq(n, DT)
        w = 2 * math.pi * np.maximum(f, 0.4)
        X = X / w ** 1.5
        u = np.fft.irfft(X, n)
        env = np.clip((tt - t["rest"]) / 2.0, 0, 1) * np.clip((T - t["rest"] - tt) / 2.0, 0, 1)
        env = 0.5 - 0.5 * np.cos(math.pi * env)
        u = u * env
    else:
        f, A = t["f"], t["A"]
        t0 = t["rest"]
        tr = t["nr"] / f
        ts = t["ns"] / f
        s = tt - t0
        env = np.where(s < tr, 0.5 - 0.5 * np.cos(math.pi * np.clip(s / tr, 0, 1)), 1.0)
        env = np.where(s > tr + ts, 0.5 + 0.5 * np.cos(math.pi * np.clip((s - tr - ts) / tr, 0, 1)), env)
        env[(s < 0) | (s > 2 * tr + ts)] = 0
        ph = 2 * math.pi * f * s
        if t["kind"] == "sine":
            base = np.sin(ph)
        else:
            tri = (2 / math.pi) * np.arcsin(np.sin(ph))
            k = max(3, int(0.08 / f / DT))  # rounded corners: smoothing over 8 % of the period
            win = np.hanning(2 * k + 1)
            base = np.convolve(tri, win / win.sum(), mode="same")
        u = A * env * base
        steady = (s >= tr) & (s <= tr + ts)
    v = np.gradient(u, DT)
    a = np.gradient(v, DT)
    j = np.gradient(a, DT)
    if t["kind"] == "broadband":  # scale to table limits
        sc = min(0.06 / np.abs(u).max(), 0.8 * G / np.abs(a).max(), 0.45 / np.abs(v).max())
        u, v, a, j = u * sc, v * sc, a * sc, j * sc
    return tt, u, v, a, j, steady


# ------------------------------------------------------------------------------- linear model
def _pade2(T):
    # e^{-sT} ~ (1 - sT/2 + (sT)^2/12)/(1 + sT/2 + (sT)^2/12); coefficients high power first
    return np.array([T * T / 12, -T / 2, 1.0]), np.array([T * T / 12, T / 2, 1.0])


def _linear(M, Ke, Cl, kh, tau, wv, zv, Td, Kp, c, tl, Mh, Kh, Ch, khh, f):
    s = 2j * math.pi * f
    D = np.exp(-s * Td)
    Gv = wv ** 2 / (s * s + 2 * zv * wv * s + wv ** 2)
    Z = M * s * s + Cl * s + Ke
    Zh = Mh * s * s + Ch * s + Kh
    num = Gv * D * (np.exp(s * tl) * (s + s * Zh / khh) + Kp + c * Zh)
    den = Z * (s + 1 / tau) / kh + s + Gv * D * (Kp + c * Z)
    return num / den


def _poles(M, Ke, Cl, kh, tau, wv, zv, Td, Kp, c):
    P = np.polynomial.polynomial
    Nd, Dd = _pade2(Td)
    Nd, Dd = Nd[::-1], Dd[::-1]  # low power first
    Pv = np.array([wv ** 2, 2 * zv * wv, 1.0])
    Z = np.array([Ke, Cl, M])
    ch = P.polyadd(P.polymul(P.polymul(P.polymul(Z, [1 / tau, 1.0]), Pv), Dd),
                   kh * P.polymul(P.polymul([0, 1.0], Pv), Dd))
    ch = P.polyadd(ch, kh * wv ** 2 * P.polymul(Nd, P.polyadd([Kp], c * Z)))
    return P.polyroots(ch)


def _tune(p, M, Cl, est, kh_act, oil_zeta=None, fixed=None):
    """Choose Kp, Delta-p gain c and lead tl on the linear model."""
    wv = 2 * math.pi * p["f_valve"]
    Td = 1.5 / p["fc"] + DT
    f = np.concatenate([np.linspace(0.05, 60, 600), np.linspace(60, 300, 200)])
    args = (M, p["Ke"], Cl, kh_act, p["tau_leak"], wv, p["z_valve"], Td)
    best = None
    if fixed is None:
        wh = math.sqrt(p["kh"] / M)
        tl0 = 2 * p["z_valve"] / wv + Td
        for Kp in (2 * math.pi * 1.0, 2 * math.pi * 2.5, 2 * math.pi * 5.0):
            for zp in np.linspace(0.1, 2.5, 25):
                c = 2 * zp * wh / p["kh"]
                for lam in (0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3):
                    H = np.abs(_linear(*args, Kp, c, lam * tl0, est["M"], est["K"], est["C"], est["kh"], f))
                    if not np.all(np.isfinite(H)):
                        continue
                    lo = f <= 50
                    score = np.max(np.abs(H[lo] - 1)) + 5 * max(0.0, H.max() - 1.005)
                    if best is None or score < best[0]:
                        if np.max(_poles(*args, Kp, c).real) < -1.0:
                            best = (score, Kp, c, lam * tl0)
        return {"Kp": best[1], "c": best[2], "tl": best[3]}
    # oil_column: keep Kp and lead, pick c so that the oil-mode pole has damping oil_zeta
    Kp, tl = fixed["Kp"], fixed["tl"]
    wh = math.sqrt(kh_act / M)
    cands = []
    for zp in np.linspace(0.0, 1.5, 301):
        c = 2 * zp * wh / kh_act
        r = _poles(*args, Kp, c)
        if np.max(r.real) >= -0.5:
            continue
        osc = r[(np.abs(r.imag) > 0.4 * wh) & (np.abs(r.imag) < 2.5 * wh)]
        if len(osc) == 0:
            continue
        k = np.argmin(np.abs(np.abs(osc) - wh))
        z = -osc[k].real / abs(osc[k])
        cands.append((abs(z - oil_zeta), c, z))
    cands.sort()
    return {"Kp": Kp, "c": cands[0][1], "tl": tl, "oil_pole_zeta": cands[0][2]}


# ------------------------------------------------------------------------------------ simulator
def _simulate(p, t, cmd, par, ctrl, est, eff, rng_sim):
    tt, uc, vc, ac, jc, steady = cmd
    n = len(tt)
    M, Ke, Ce, al = par["M"], par["Ke"], par["Ce"], par["alpha"]
    Fk0, rs, vsb = par["Fk"], par["rs"], par["vs"]
    kh, tau = par["kh"], p["tau_leak"]
    vmax, Fmax = p["vmax"], p["Fmax"]
    wv, zv = 2 * math.pi * p["f_valve"], p["z_valve"]
    A = np.array([[0, 1], [-wv * wv, -2 * zv * wv]])
    Bm = np.array([[0], [wv * wv]])
    Ad, Bd, _, _, _ = signal.cont2discrete((A, Bm, np.eye(2), np.zeros((2, 1))), DT, method="zoh")
    a11, a12, a21, a22 = Ad[0, 0], Ad[0, 1], Ad[1, 0], Ad[1, 1]
    b1, b2 = Bd[0, 0], Bd[1, 0]
    sub = 4096 // p["fc"]
    Kp, c, tl = ctrl["Kp"], ctrl["c"], ctrl["tl"]
    Fff = est["M"] * ac + est["K"] * uc + est["C"] * np.abs(vc) ** est["alpha"] * np.sign(vc) \
        + est["Fk"] * np.tanh(vc / 0.003)
    dFff = np.gradient(est["M"] * ac + est["K"] * uc, DT)  # compressibility flow of the inertia/spring force
    ff = vc + dFff / est["kh"]  # open-loop flow demand, previewed by tl (the command is known ahead)
    ff = np.interp(tt + tl, tt, ff, right=0.0)
    base = (ff + c * Fff + Kp * uc).tolist()
    nu = (rng_sim.standard_normal(n) * p["lvdt_sd"]).tolist()
    nF = (rng_sim.standard_normal(n) * p["ctrl_F_sd"]).tolist()
    K3h = eff.get("K3h", 0.0)
    Fph = eff.get("Fph", 0.0)
    spec = eff.get("spec")
    if spec:
        ms, ks, cs = spec
    us = vsp = 0.0
    ie = 1.0 + DT / tau
    c2 = DT * kh / ie
    Kt = M / DT + c2 + Ke * DT
    U = np.empty(n); V = np.empty(n); Fa = np.empty(n); Ff = np.empty(n); E = np.empty(n)
    u = v = F = x = xd = 0.0
    w_app = w_pend = 0.0
    dFsr = (rs - 1.0) * Fk0
    for i in range(n):
        if i % sub == 0:
            w_app = w_pend
            um = u + nu[i]
            Fm = F + nF[i]
            wq = base[i] - Kp * um - c * Fm
            s = 1.0 - Fm / Fmax if wq >= 0 else 1.0 + Fm / Fmax
            wq = wq / math.sqrt(s if s > 0.1 else 0.1) / vmax
            w_pend = 1.0 if wq > 1.0 else (-1.0 if wq < -1.0 else wq)
        x, xd = a11 * x + a12 * xd + b1 * w_app, a21 * x + a22 * xd + b2 * w_app
        if x > 1.0:
            x, xd = 1.0, 0.0
        elif x < -1.0:
            x, xd = -1.0, 0.0
        s = 1.0 - F / Fmax if x >= 0 else 1.0 + F / Fmax
        q = vmax * x * math.sqrt(s if s > 0 else 0.0)
        c1 = (F + DT * kh * q) / ie
        Fnl = K3h * u * u * u
        if spec:
            Fnl += ks * (u - us) + cs * (v - vsp)
        Fk = Fk0 + Fph * u * u
        Fs = Fk + dFsr
        R = c1 - Ke * u - Fnl + M * v / DT
        if -Fs <= R <= Fs:
            vn = 0.0
            fr = R
        else:
            sg = 1.0 if R > 0 else -1.0
            Ra = R * sg
            w = abs(v)
            if w < 1e-9:
                w = max((Ra - Fs) / Kt, 1e-9)
            for _ in range(30):
                wa = w ** al
                ex = math.exp(-(w / vsb) ** 2)
                g = Kt * w + Ce * wa + Fk + dFsr * ex - Ra
                dg = Kt + al * Ce * wa / w - 2 * w / (vsb * vsb) * dFsr * ex
                wn = w - g / dg
                if wn <= 0:
                    wn = 0.5 * w
                if abs(wn - w) <= 1e-13 + 1e-11 * w:
                    w = wn
                    break
                w = wn
            vn = sg * w
            # friction from the solved balance (equals the Stribeck value to Newton accuracy) so that
            # the recorded force obeys the balance to rounding
            fr = sg * (Ra - Kt * w - Ce * w ** al)
        F = c1 - c2 * vn
        v = vn
        u = u + DT * vn
        if spec:
            asp = (ks * (u - us) + cs * (v - vsp)) / ms
            vsp += DT * asp
            us += DT * vsp
        U[i] = u; V[i] = v; Fa[i] = F; Ff[i] = fr; E[i] = Fnl
    a = np.diff(V, prepend=0.0) / DT
    return {"t": tt, "u": U, "v": V, "a": a, "F": Fa, "fric": Ff, "Fnl": E, "steady": steady,
            "uc": uc, "ac": ac}


def _effect_force(sim, effect, par, eff):
    v = sim["v"]
    sg = np.sign(v)
    if effect == "stiction":
        fk = par["Fk"]
        slip = sg != 0
        return np.where(slip, sim["fric"] - fk * sg, sim["fric"] - np.clip(sim["fric"], -fk, fk))
    if effect in ("nonlinear_stiffness", "specimen"):
        return sim["Fnl"]
    if effect == "position_friction":
        return eff["Fph"] * sim["u"] ** 2 * sg
    if effect == "drift":
        s = eff["scale"]
        return (1 - 1 / s) * (par["Ce"] * np.abs(v) ** par["alpha"] * sg + sim["fric"])
    return np.zeros_like(v)


# -------------------------------------------------------------------------------------- record
def _record(p, sens, sim, t, eff_force, delay, rng):
    fs = p["rate"]
    fs_true = fs * (1 + p["skew_ppm"] * 1e-6)
    T = sim["t"][-1]
    N = int(math.floor(T * fs_true)) + 1
    ts = np.arange(N) / fs_true
    sos = signal.butter(4, p["aa_frac"] * fs, fs=1 / DT, output="sos")

    def aa(x):
        return np.interp(ts, sim["t"], signal.sosfilt(sos, x))
    F = sim["F"]
    if delay:
        Fd = np.interp(sim["t"] - delay, sim["t"], F, left=0.0)
        eff_force = Fd - F
        F = Fd
    F_clean = aa(F)
    # pressures
    pL = F_clean / p["A_p"]
    _, hz = signal.sosfreqz(sos, worN=np.array(sens["rip_f"]), fs=1 / DT)
    out = {}
    pm = []
    for ch, sgn in ((0, 1), (1, -1)):
        pr = p["Ps"] / 2 + sgn * pL / 2
        for k, fr in enumerate(sens["rip_f"]):
            amp = sens["rip_a"][ch][k] * abs(hz[k])
            pr = pr + amp * np.cos(2 * math.pi * fr * ts + sens["rip_ph"][ch][k] + np.angle(hz[k]))
        pr = pr + sens["p_off"][ch] + rng.standard_normal(N) * sens["p_sd"]
        lsb = P_FS / 65536
        pm.append(np.clip(np.round(pr / lsb) * lsb, 0, P_FS))
    Frec = (pm[0] - pm[1]) * p["A_p"]
    out["t"] = np.arange(N) / fs
    lsb_u = 0.3 / 65536
    out["u"] = np.round((aa(sim["u"]) + rng.standard_normal(N) * sens["lvdt_sd"]) / lsb_u) * lsb_u
    out["F"] = Frec
    a = aa(sim["a"])
    out["a"] = a + sens["acc_off"] + sens["acc_drift"] * ts / ts[-1] + rng.standard_normal(N) * sens["acc_sd"]
    if sens["has_v"]:
        out["v"] = aa(sim["v"]) + rng.standard_normal(N) * 1e-3
    out["u_cmd"] = np.interp(ts, sim["t"], sim["uc"])
    if sens["has_acmd"]:
        out["a_cmd"] = np.interp(ts, sim["t"], sim["ac"])
    steady = np.interp(ts, sim["t"], sim["steady"].astype(float)) > 0.5
    noise = Frec - F_clean
    noise = noise - noise.mean()
    ef = aa(eff_force) if eff_force is not None else np.zeros(N)
    return out, noise, ef, steady


def _write_csv(path, rec):
    cols = [c for c in ("t", "u", "F", "a", "v", "u_cmd", "a_cmd") if c in rec]
    fmts = {"t": "%.10g", "u": "%.6f", "F": "%.0f", "a": "%.4f", "v": "%.5f", "u_cmd": "%.7f", "a_cmd": "%.4f"}
    data = np.column_stack([rec[c] for c in cols])
    np.savetxt(path, data, delimiter=",", header=",".join(cols), comments="", fmt=[fmts[c] for c in cols])


# ------------------------------------------------------------------------------------ generate
def _test_params(p, t, var, eff_scale=1.0):
    par = {"M": p["m_deck"] * var[0] + p["m_piston"] + t["payload"], "Ke": p["Ke"] * var[1],
           "Ce": p["Ce"] * var[2] * eff_scale, "alpha": p["alpha"],
           "Fk": (p["mu_e"] * (p["F_hd"] + (p["m_deck"] + t["payload"]) * G) + p["F_seal"]) * var[3] * eff_scale,
           "rs": p["static_ratio"], "vs": p["vs"], "kh": p["kh_act"]}
    return par


def _run_all(p, tests, cmds, vars_, est, ctrl, effect, ep, sens, seed, which):
    res = {}
    for k in which:
        t = tests[k]
        scale = 1.0
        eff = {}
        if effect == "drift":
            n = len(tests)
            scale = 1 + ep["drift"] / 2 - ep["drift"] * (t["order"] - 1) / (n - 1)
            eff["scale"] = scale
        par = _test_params(p, t, vars_[k], scale)
        if effect == "stiction":
            par["rs"], par["vs"] = ep["static_ratio"], ep["stribeck_velocity"]
        if effect == "nonlinear_stiffness":
            eff["K3h"] = ep["cubic_stiffness"] / ep["h"] ** 2
        if effect == "position_friction":
            eff["Fph"] = ep["position_friction"] / ep["h"] ** 2
        if effect == "specimen":
            ms = ep["specimen_mass"]
            w = 2 * math.pi * ep["specimen_frequency"]
            eff["spec"] = (ms, ms * w * w, 2 * ep["specimen_damping"] * ms * w)
        e_t = dict(est[k])
        sim = _simulate(p, t, cmds[k], par, ctrl[k], e_t, eff, np.random.default_rng([seed, k, 7]))
        ef = _effect_force(sim, effect, par, eff)
        rec, noise, efr, steady = _record(p, sens, sim, t, ef, ep.get("delay", 0.0) if effect == "channel_delay"
                                          else 0.0, np.random.default_rng([seed, k, 11]))
        res[k] = {"sim": sim, "par": par, "rec": rec, "noise": noise, "ef": efr, "steady": steady}
    return res


def _ratio(res, tests):
    nn = ee = 0.0
    cnt = 0
    for k, r in res.items():
        if tests[k]["kind"] == "broadband":
            continue
        m = r["steady"]
        nn += np.sum(r["noise"][m] ** 2)
        ee += np.sum(r["ef"][m] ** 2)
        cnt += m.sum()
    return math.sqrt(nn / cnt), math.sqrt(ee / cnt)


_FORCE_BB = False  # checks only: always add a broadband test
_VARIATION = True  # checks only: False switches the test-to-test variation off

SIZE_KEY = {"stiction": "static_ratio", "nonlinear_stiffness": "cubic_stiffness",
            "position_friction": "position_friction", "specimen": "specimen_mass", "channel_delay": "delay",
            "drift": "drift"}


FREE = ("nonlinear_stiffness", "position_friction", "specimen")  # no strong range given: capped at 3x noise


def _scale_param(ep, effect, factor):
    key = SIZE_KEY[effect]
    if key == "static_ratio":
        ep[key] = 1 + (ep[key] - 1) * factor
    else:
        ep[key] *= factor


def generate(seed: int, out: str, effect: str | None = None, size: str | None = None, verbose: bool = True,
             name: str | None = None) -> dict:
    """Write one test series (series.json, CSVs, truth.json) into `out`; return the truth dict."""
    started = time.perf_counter()
    if effect is not None and effect not in EFFECTS:
        raise ValueError(f"unknown effect {effect}")
    if effect is not None and size is None:
        size = "strong"
    rng = np.random.default_rng([seed, 10])
    p = _draw_table(rng)
    p["rate"] = int(rng.choice(RATES))
    p["skew_ppm"] = float(rng.uniform(30, 200) * rng.choice([-1, 1]))
    p["aa_frac"] = rng.uniform(0.3, 0.45)
    want_bb = effect == "oil_column" or rng.random() < 0.5 or _FORCE_BB
    has_v = bool(rng.random() < 0.25) and p["rate"] < 2048
    has_acmd = bool(rng.random() < 0.5) and p["rate"] < 2048
    tests = _plan(rng, p["rate"], want_bb, 50 + 8 * has_v + 8 * has_acmd)
    cmds = [_command(t, rng) for t in tests]
    vsteady = [np.abs(c[2][c[5]]).max() for c, t in zip(cmds, tests) if t["kind"] != "broadband"]
    p["v_median"] = float(np.median(vsteady))
    # sensors
    Fpk = []
    for c, t in zip(cmds, tests):
        Fpk.append(np.max(np.abs(p["Me"] * c[3] + p["Ke"] * c[1])) + p["Fmu"])
    sens = {"p_sd": rng.uniform(0.002, 0.006) * np.median(Fpk) / p["A_p"],
            "p_off": list(rng.uniform(-40e3, 40e3, 2)),
            "rip_f": [], "rip_a": [[], []], "rip_ph": [[], []],
            "lvdt_sd": rng.uniform(5e-6, 20e-6), "acc_sd": rng.uniform(0.01, 0.05),
            "acc_off": rng.uniform(-0.05, 0.05), "acc_drift": rng.uniform(-0.02, 0.02),
            "has_v": has_v, "has_acmd": has_acmd}
    shaft = rng.uniform(24, 25)
    amp0 = rng.uniform(0.5, 1.5) * sens["p_sd"]
    for fr, rel in ((shaft, 0.2), (9 * shaft, 1.0), (18 * shaft, 0.4), (27 * shaft, 0.2)):
        sens["rip_f"].append(fr)
        for ch in (0, 1):
            sens["rip_a"][ch].append(amp0 * rel * rng.uniform(0.5, 1.5))
            sens["rip_ph"][ch].append(rng.uniform(0, 2 * math.pi))
    p["lvdt_sd"] = sens["lvdt_sd"]
    p["ctrl_F_sd"] = math.sqrt(2) * sens["p_sd"] * p["A_p"]
    # test-to-test variation, normalised to campaign mean 1
    vars_ = 1 + p["sd"] * rng.standard_normal((len(tests), 4)) * (1.0 if _VARIATION else 0.0)
    vars_ /= vars_.mean(axis=0)
    # effect parameters (strong draws)
    ep = {}
    p["kh_act"] = p["kh"]
    if effect == "stiction":
        ep = {"static_ratio": rng.uniform(1.3, 1.6), "stribeck_velocity": rng.uniform(0.002, 0.015)}
    elif effect == "nonlinear_stiffness":
        ep = {"cubic_stiffness": rng.uniform(0.3, 0.8) * p["Ke"] * 100, "h": p["h"]}
    elif effect == "position_friction":
        ep = {"position_friction": rng.uniform(0.5, 1.0) * p["Fmu"] * 100, "h": p["h"]}
    elif effect == "specimen":
        ep = {"specimen_mass": rng.uniform(1000, 4000), "specimen_frequency": rng.uniform(2, 15),
              "specimen_damping": rng.uniform(0.02, 0.05)}
    elif effect == "channel_delay":
        ep = {"delay": rng.uniform(0.002, 0.015)}
    elif effect == "drift":
        ep = {"drift": rng.uniform(0.15, 0.30)}
    elif effect == "oil_column":
        ep = {"oil_frequency": rng.uniform(8, 18), "oil_damping": rng.uniform(0.05, 0.2)}
        p["kh_act"] = p["Me"] * (2 * math.pi * ep["oil_frequency"]) ** 2
    # controller estimates and tuning per test (payload known to the operator)
    erng = np.random.default_rng([seed, 13])
    e_err = 1 + 0.01 * erng.standard_normal(5)
    est, ctrl = [], []
    tune_cache = {}
    for k, t in enumerate(tests):
        M = p["Me"] + t["payload"]
        Cl = p["Ce"] * max(p["v_median"], 0.02) ** (p["alpha"] - 1)
        e = {"M": M * e_err[0], "K": p["Ke"] * e_err[1], "C": p["Ce"] * e_err[2], "alpha": p["alpha"],
             "Fk": p["Fmu"] * e_err[3], "kh": p["kh"] * (M / p["Me"]) ** 0 * e_err[4]}
        e["Clin"] = Cl * e_err[2]
        est.append(e)
        key = t["payload"]
        if key not in tune_cache:
            eh = {"M": e["M"], "K": e["K"], "C": e["Clin"], "kh": e["kh"]}
            cl = _tune(p, M, Cl, eh, p["kh"])
            if effect == "oil_column":
                cl = _tune(p, M, Cl, eh, p["kh_act"], oil_zeta=ep["oil_damping"], fixed=cl)
            f = np.linspace(0.05, 100, 4000)
            wv = 2 * math.pi * p["f_valve"]
            H = np.abs(_linear(M, p["Ke"], Cl, p["kh_act"], p["tau_leak"], wv, p["z_valve"], 1.5 / p["fc"] + DT,
                               cl["Kp"], cl["c"], cl["tl"], eh["M"], eh["K"], eh["C"], eh["kh"], f))
            cl["H_peak"] = float(H.max())
            cl["H_peak_hz"] = float(f[np.argmax(H)])
            tune_cache[key] = cl
        ctrl.append(tune_cache[key])
    per = [k for k, t in enumerate(tests) if t["kind"] != "broadband"]
    bb = [k for k, t in enumerate(tests) if t["kind"] == "broadband"]
    history = []
    if effect in SIZE_KEY:
        for it in range(4):
            res = _run_all(p, tests, cmds, vars_, est, ctrl, effect, ep, sens, seed, per)
            n_rms, e_rms = _ratio(res, tests)
            r = e_rms / n_rms
            history.append({SIZE_KEY[effect]: ep[SIZE_KEY[effect]], "ratio": r})
            if size == "strong" and (r >= 1.0 and (r <= 3.0 or effect not in FREE)):
                break
            if size == "weak" and 0.3 <= r <= 0.5:
                break
            target = (1.2 if r < 1 else 2.0) if size == "strong" else 0.4
            _scale_param(ep, effect, target / max(r, 1e-6))
        res.update(_run_all(p, tests, cmds, vars_, est, ctrl, effect, ep, sens, seed, bb))
    else:
        res = _run_all(p, tests, cmds, vars_, est, ctrl, effect, ep, sens, seed, per + bb)
    n_rms, e_rms = _ratio(res, tests)
    # empirical closed-loop FRF from the broadband tests
    emp = None
    if bb:
        sim = res[bb[0]]["sim"]
        f, Pxy = signal.csd(sim["uc"], sim["u"], fs=1 / DT, nperseg=4096)
        _, Pxx = signal.welch(sim["uc"], fs=1 / DT, nperseg=4096)
        _, Coh = signal.coherence(sim["uc"], sim["u"], fs=1 / DT, nperseg=4096)
        H = np.abs(Pxy / Pxx)
        m = (f >= 0.5) & (f <= min(40, tests[bb[0]]["fhi"])) & (Coh > 0.9)
        emp = {"max": float(H[m].max()), "peak_hz": float(f[m][np.argmax(H[m])])}
    # write
    os.makedirs(out, exist_ok=True)
    mt = []
    for k, t in enumerate(tests):
        _write_csv(os.path.join(out, f"{t['id']}.csv"), res[k]["rec"])
        entry = {"id": t["id"], "file": f"{t['id']}.csv", "kind": t["kind"]}
        if t["kind"] != "broadband":
            entry["frequency_hz"] = round(t["f"], 6)
            entry["amplitude_m"] = round(t["A"], 6)
        entry["payload_kg"] = round(t["payload"], 1)
        entry["order"] = t["order"]
        mt.append(entry)
    table = {"deck_mass_kg": round(p["m_deck"], 1),
             "strut": {"p0_pa": round(p["p0"], 1), "area_m2": round(p["strut_area"], 6), "h_m": round(p["h"], 5),
                       "l0_m": round(p["l0"], 5), "gamma": round(p["gamma"], 3)},
             "oil": {"bulk_modulus_pa": round(p["beta"], -5), "piston_area_m2": round(p["A_p"], 6),
                     "oil_volume_m3": round(p["V"], 8)}}
    manifest = {"format": "sst-series/1", "name": name or f"tenth-seed{seed}", "table": table, "tests": mt}
    with open(os.path.join(out, "series.json"), "w") as fh:
        json.dump(manifest, fh, indent=1)
    params = {}
    if effect == "oil_column":
        params = {"oil_frequency": ep["oil_frequency"], "oil_damping": ep["oil_damping"],
                  "oil_peak_hz": tune_cache.get(0.0, ctrl[0])["H_peak_hz"],
                  "oil_peak_hz_broadband": emp["peak_hz"] if emp else None}
    elif effect:
        params = dict(ep)
    c0 = tune_cache.get(0.0, ctrl[0])
    truth = {"Me": p["Me"], "Ke": p["Ke"], "Ce": p["Ce"], "alpha": p["alpha"], "Fmu": p["Fmu"],
             "effect": effect, "effect_params": params, "size": size, "seed": seed,
             "sample_rate_hz": p["rate"], "clock_skew_ppm": p["skew_ppm"], "noise_rms_N": n_rms,
             "effect_rms_N": e_rms, "effect_to_noise": e_rms / n_rms, "sizing_history": history,
             "deck_mass": p["m_deck"], "piston_mass": p["m_piston"], "mu_e": p["mu_e"], "F_hd": p["F_hd"],
             "deck_friction_N": p["F_deck"], "seal_friction_N": p["F_seal"],
             "static_ratio": ep.get("static_ratio", p["static_ratio"]),
             "stribeck_velocity": ep.get("stribeck_velocity", p["vs"]),
             "oil_frequency_nominal_hz": p["f_oil_nom"],
             "oil_frequency_hz": math.sqrt(p["kh_act"] / p["Me"]) / (2 * math.pi),
             "closed_loop": {"H_peak_linear": c0["H_peak"], "H_peak_hz_linear": c0["H_peak_hz"],
                             "H_broadband": emp, "Kp": c0["Kp"], "dp_gain": c0["c"], "lead_s": c0["tl"],
                             "controller_hz": p["fc"], "valve_hz": p["f_valve"], "valve_zeta": p["z_valve"],
                             "vmax": p["vmax"], "Fmax_N": p["Fmax"], "supply_pa": p["Ps"]},
             "variation_sd": p["sd"], "median_peak_speed": p["v_median"], "anti_alias_frac": p["aa_frac"],
             "sensors": {k: v for k, v in sens.items()},
             "generator": "tenth_generator", "seconds": round(time.perf_counter() - started, 1)}
    with open(os.path.join(out, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=1, default=float)
    if verbose:
        print(f"{out}: {len(tests)} tests, {p['rate']} Hz, effect {effect} {size}, "
              f"ratio {e_rms / n_rms:.3f}, H_lin {c0['H_peak']:.3f}@{c0['H_peak_hz']:.1f}Hz, "
              f"emp {emp}, {truth['seconds']} s", flush=True)
    return truth


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", required=True)
    parser.add_argument("--effect", default=None, choices=EFFECTS)
    parser.add_argument("--size", default=None, choices=("strong", "weak"))
    parser.add_argument("--name", default=None)
    args = parser.parse_args()
    generate(args.seed, args.out, effect=args.effect, size=args.size, verbose=True, name=args.name)


if __name__ == "__main__":
    main()
