"""Seventh, independent shaking-table simulator (blind-test data for system identification).

Plant
-----
One rigid moving body: steel deck (plus the effective mass of the hold-down struts and
hinges, all on the deck side of the load cell) and an optional bolted payload, driven by a
double-rod, equal-area hydraulic actuator whose piston/rod mass ``m_p`` sits on the other
side of a stiff load cell.  The deck sees

    Me*a = F_lc - Ke*u [- K3*(u/h)^2*u] - Ce*|v|^alpha*sign(v) - F_fric [+ base shear]

Four vertical nitrogen struts (pre-charge p0, piston area A, height h) give the linear
geometric stiffness Ke = 4*p0*A/h and the hold-down force F_hd = 4*p0*A.  Friction is a
LuGre-type bristle model: a bristle deflection z with stiffness sigma0 (pre-sliding travel
of some tens of micrometres), micro-damping sigma1 that fades with speed, and a sliding
capacity g(v) = Fk*(1 + (r-1)*exp(-(v/vs)^2)), Fk = mu_e*(F_hd + (m_deck+payload)*g).  The
deck therefore genuinely sticks at reversals while the net force stays inside the static
capacity; the bristle state is advanced with its exact exponential solution (no chatter).
In clean series r <= 1.03.  Viscous damping is integrated implicitly (regularised below
1e-5 m/s).

Hydraulics: 4-way servo-valve with second-order spool (80-190 Hz, exact discretisation),
spool saturation at +-1, small underlap (null leakage), turbulent orifice law against supply
and return pressure (smoothly regularised at small pressure drop); two chambers of
compressible oil (bulk modulus beta, volumes V0 +- A_p*u), cross-piston leakage, cavitation
clamp; actuator seal friction (acts on the piston, so it is NOT in the measured force).
The oil column resonance f_oil = sqrt(2*beta*A_p^2/(V0*M))/2pi is 15-40 Hz (M = Me+m_p;
lower where the stroke volume forces a larger V0).

Controller: digital three-variable controller at 1-2.6 kHz with one-tick computation delay
and zero-order hold: displacement, velocity (complementary filter of LVDT and accelerometer)
and acceleration feedback, plus flow feed-forward of the reference velocity.  The gains are
"commissioned" per table by an eigenvalue search on a linearised model of the true plant.
References: sine or rounded (Lanczos-smoothed Fourier) triangle displacement with a
sin^2 envelope ramp-in/out of 1-3 cycles (half a cycle below 0.15 Hz), or one band-limited random record.

Force channel: load cell between rod and deck, so F = Me*a + deck forces; ``Me`` in the
truth is the mass that force accelerates (deck + strut share; payload adds per test).

Sensors: LVDT, accelerometer, load cell and (in some series) a velocity transducer.  Each
has white electronic noise through a 1st-order conditioning low-pass (0.5-1.5 kHz; the
controller samples these conditioned signals), a per-test offset, and the load cell in
addition AR(1)-coloured noise and 50/150 Hz mains hum.  The DAQ passes every channel
through the same Butterworth anti-alias filter (order 4-8, cut-off 0.28-0.4 fs), decimates
to fs (200, 500, 1000 or 2048 Hz) and quantises to 16 bit.  Internal step 1e-4 s (10 kHz;
10.24 kHz at fs = 2048 Hz).  Columns: t, u, F always; a in ~85 %, v in ~35 %, u_cmd in
~50 % (a_cmd in some of those) of the series.

Test-to-test scatter: Me, Ke, Ce, Fmu each times 1 + N(0, spread^2), spread in 0-3 %.

Withheld effects (one per series, ``size`` in [0,1] picks within range, else random):
  stiction            static_ratio 1.1-1.6 and stribeck_velocity 2-20 mm/s (both grow
                      with size) in the LuGre capacity g(v)
  channel_delay       delay 0.5-6 ms (log) of the whole force channel before anti-aliasing
  specimen            SDOF on the deck: mass 1-5 t (grows), 25-5 Hz and 5-2 % damping (fall
                      with size, jittered); its weight also loads the friction (truth
                      reports Fmu_with_specimen; "Fmu" stays the empty table's)
  nonlinear_stiffness K3 = 0.3-15 Ke (log), spring Ke*u + K3*(u/h)^2*u (l0_implied given)
  position_friction   Fp*(u/h)^2 added to the sliding capacity, 3-40 % (log) of Fmu at the
                      largest commanded amplitude of the plan
  drift               Fmu and Ce fall by 5-25 % from first to last test (concave warm-up
                      curve over campaign order); truth Ce and Fmu are the first test's
The same seed gives the same table, plan and noise with or without an effect.

The manifest's l0/gamma are nominal strut data; in clean series the truth spring is linear.
oil_volume_m3 is the volume of ONE chamber at mid-stroke (incl. hoses), as used in f_oil.
Known simplifications: rigid rod/load cell, one lumped strut stiffness, constant bulk
modulus and oil temperature (except drift), no servo-valve hysteresis or supply dynamics.

Usage: python benchmarks/seventh_generator.py --seed N --out DIR [--effect NAME] [--size X]
       python benchmarks/seventh_generator.py --selfcheck DIR
"""
from __future__ import annotations

import argparse
import json
import math
import os
import time

import numpy as np
from scipy import linalg, signal

G = 9.81
EFFECTS = ("stiction", "channel_delay", "specimen", "nonlinear_stiffness",
           "position_friction", "drift")
STROKE = 0.125
V_LIM = 0.6
A_LIM = 10.0
_DEBUG = None        # dict(chunks=(...)) keeps internal-rate buffers (development aid)


def _lerp(lo, hi, s, log=False):
    if log:
        return float(math.exp(math.log(lo) + s * (math.log(hi) - math.log(lo))))
    return float(lo + s * (hi - lo))


# ---------------------------------------------------------------- table and plan
def _draw_table(rng):
    T = {}
    T["Me"] = rng.uniform(10e3, 25e3)
    T["m_deck"] = T["Me"] * rng.uniform(0.82, 0.93)
    T["Ke"] = math.exp(rng.uniform(math.log(0.3e6), math.log(2.0e6)))
    T["h"] = rng.uniform(0.6, 1.2)
    T["F_hd"] = T["Ke"] * T["h"]
    T["p0"] = rng.uniform(3e6, 12e6)
    T["A_strut"] = T["F_hd"] / (4 * T["p0"])
    T["gamma"] = rng.uniform(1.1, 1.4)
    T["l0"] = T["h"] * rng.uniform(0.25, 0.6)
    T["mu_e"] = rng.uniform(0.005, 0.02)
    T["Fmu"] = T["mu_e"] * (T["F_hd"] + T["m_deck"] * G)
    T["alpha"] = rng.uniform(0.3, 1.0)
    T["Fd03"] = rng.uniform(5e3, 40e3)
    T["Ce"] = T["Fd03"] / 0.3 ** T["alpha"]
    T["spread"] = rng.uniform(0.0, 0.03)
    # friction microstructure
    T["z_pre"] = rng.uniform(30e-6, 150e-6)
    T["zeta_bristle"] = rng.uniform(0.3, 0.8)
    T["static_ratio_clean"] = 1.0 + rng.uniform(0.0, 0.03)
    T["stribeck_clean"] = rng.uniform(3e-3, 15e-3)
    return T


def _draw_hydraulics(rng, T, payload_max):
    H = {}
    H["Ps"] = rng.uniform(20e6, 28e6)
    H["Pr"] = rng.uniform(0.2e6, 0.5e6)
    H["m_p"] = rng.uniform(150.0, 600.0)
    H["beta"] = rng.uniform(0.8e9, 1.5e9)
    Fd = T["Ce"] * 0.4 ** T["alpha"]
    F_design = (T["Me"] + payload_max) * rng.uniform(6, 9) + T["Ke"] * 0.05 + Fd + T["Fmu"]
    H["Ap"] = float(np.clip(F_design * rng.uniform(1.2, 1.6) / (0.67 * H["Ps"]), 0.01, 0.09))
    M = T["Me"] + H["m_p"]
    f_t = rng.uniform(15.0, 40.0)
    V0 = 2 * H["beta"] * H["Ap"] ** 2 / (M * (2 * math.pi * f_t) ** 2)
    H["V0"] = max(V0, 1.15 * H["Ap"] * STROKE + 0.5e-3)
    H["f_oil"] = math.sqrt(2 * H["beta"] * H["Ap"] ** 2 / (H["V0"] * M)) / (2 * math.pi)
    H["v_cap"] = rng.uniform(0.7, 0.95)
    H["Kv"] = H["Ap"] * H["v_cap"] / math.sqrt(H["Ps"] / 3)     # m^3/s/sqrt(Pa) at x=1
    H["xu"] = rng.uniform(0.002, 0.01)
    H["dp_reg"] = 0.3e6
    H["f_valve"] = max(rng.uniform(80, 160), 3.5 * H["f_oil"]) * rng.uniform(1.0, 1.2)
    H["zeta_valve"] = rng.uniform(0.55, 0.8)
    H["C_leak"] = 10 ** rng.uniform(-13, -12)
    H["F_seal"] = rng.uniform(300.0, 1500.0)
    H["F_cap"] = 0.75 * H["Ap"] * H["Ps"]
    return H


def _triangle_harmonics(A, f, a_lim):
    """Odd harmonic numbers and Lanczos-smoothed coefficients of a rounded triangle."""
    w = 2 * math.pi * f
    for N in (15, 13, 11, 9, 7, 5, 3, 1):
        n = np.arange(1, N + 1, 2)
        sig = np.sinc(n / (N + 2))
        c = 8 / math.pi ** 2 * sig * (-1.0) ** ((n - 1) // 2) / n ** 2
        ph = np.linspace(0, 2 * math.pi, 2001)
        shape = (c[None, :] * np.sin(np.outer(ph, n))).sum(1)
        acc = (-(c * n ** 2)[None, :] * np.sin(np.outer(ph, n))).sum(1)
        scale = 1.0 / np.abs(shape).max()
        if A * scale * np.abs(acc).max() * w ** 2 <= a_lim or N == 1:
            return n, c * scale


def _peak_demand(kind, A, f, T, H, Mtot, Fmu_t):
    w = 2 * math.pi * f
    if kind == "sine":
        vp, ap = A * w, A * w * w
    else:
        n, c = _triangle_harmonics(A, f, A_LIM)
        vp = A * w * np.abs(c * n).sum()
        ap = A * w * w * np.abs(c * n * n).sum()
    F = Mtot * ap + T["Ke"] * A + T["Ce"] * vp ** T["alpha"] + Fmu_t + H["F_seal"]
    return vp, ap, F


def _draw_plan(rng, T, H, payload, fs):
    n_tests = int(rng.integers(8, 25))
    with_bb = rng.random() < 0.5
    bb_pos = int(rng.integers(0, n_tests)) if with_bb else -1
    pay = np.zeros(n_tests)
    if payload > 0:
        nb = max(2, int(round(n_tests * rng.uniform(0.2, 0.45))))
        s0 = int(rng.integers(0, n_tests - nb + 1))
        pay[s0:s0 + nb] = payload
    tests = []
    for k in range(n_tests):
        Mtot = T["Me"] + H["m_p"] + pay[k]
        Fmu_t = T["mu_e"] * (T["F_hd"] + (T["m_deck"] + pay[k]) * G)
        if k == bb_pos:
            a_allow = (0.8 * H["F_cap"] - T["Ke"] * 0.1 - T["Ce"] * 0.5 ** T["alpha"] - Fmu_t
                       - H["F_seal"]) / Mtot
            tests.append(dict(kind="broadband", payload=pay[k], f_hi=rng.uniform(4, 10),
                              a_allow=float(np.clip(a_allow, 0.5, 7.0)),
                              dur=rng.uniform(20, 30), seed=int(rng.integers(2**31))))
            continue
        kind = "sine" if rng.random() < 0.65 else "triangle"
        f = math.exp(rng.uniform(math.log(0.1), math.log(8.0)))
        f = round(f, 2) if f < 1 else round(f, 1)
        w = 2 * math.pi * f
        if kind == "sine":
            Amax = min(0.12, 0.95 * V_LIM / w, 0.9 * A_LIM / w ** 2)
        else:
            Amax = min(0.12, 0.9 * V_LIM / (4 * f), 0.8 * A_LIM * math.pi ** 2 / 8 / w ** 2)
        A = math.exp(rng.uniform(math.log(max(1e-3, Amax / 40)), math.log(max(Amax, 1.2e-3))))
        for _ in range(40):
            vp, ap, F = _peak_demand(kind, A, f, T, H, Mtot, Fmu_t)
            if F < 0.8 * H["F_cap"] and vp < min(V_LIM, 0.8 * H["v_cap"]) and ap < A_LIM:
                break
            A *= 0.85
        A = round(max(A, 1e-3), 4)
        n_r = 0.5 if f < 0.15 else (1 if f < 0.3 else (2 if f < 1.5 else 3))
        n_s = int(rng.integers(5, 16))
        n_s = max(5, min(n_s, int(30 * f)))
        tests.append(dict(kind=kind, f=f, A=A, payload=pay[k], n_r=n_r, n_s=n_s,
                          dur=0.4 + (2 * n_r + n_s) / f + 0.4))
    return tests


# ---------------------------------------------------------------- references
class _Reference:
    """Commanded displacement/velocity/acceleration of one test."""

    def __init__(self, test, dt_ctrl):
        self.t = test
        self.kind = test["kind"]
        if self.kind == "triangle":
            self.n, self.c = _triangle_harmonics(test["A"], test["f"], A_LIM)
        if self.kind == "broadband":
            self._make_broadband(test, dt_ctrl)

    def _make_broadband(self, test, dt):
        rng = np.random.default_rng(test["seed"])
        Tr = 1.5
        Tb = test["dur"] - 0.8
        N = int(Tb / dt) + 1
        fr = np.fft.rfftfreq(N, dt)
        band = 1 / (1 + (0.3 / np.maximum(fr, 1e-9)) ** 4) / (1 + (fr / test["f_hi"]) ** 6)
        X = band * (rng.standard_normal(fr.size) + 1j * rng.standard_normal(fr.size))
        X[0] = 0
        u = np.fft.irfft(X, N)
        tt = np.arange(N) * dt
        e = np.clip(np.minimum(tt, Tb - tt) / Tr, 0, 1)
        e = np.sin(0.5 * math.pi * e) ** 2
        # envelope applied in time; derivatives numerically (smooth, oversampled)
        uu = u * e
        vv = np.gradient(uu, dt)
        aa = np.gradient(vv, dt)
        s = min(0.1 / np.abs(uu).max(), 0.5 / np.abs(vv).max(), test["a_allow"] / np.abs(aa).max())
        self.bb_t0 = 0.4
        self.bb = (s * uu, s * vv, s * aa)
        self.bb_dt = dt
        test["A"] = float(s * np.abs(uu).max())

    def __call__(self, t):
        tt = self.t
        if self.kind == "broadband":
            idx = np.clip(np.round((t - self.bb_t0) / self.bb_dt).astype(int), 0,
                          len(self.bb[0]) - 1)
            inside = (t >= self.bb_t0) & (t <= self.bb_t0 + (len(self.bb[0]) - 1) * self.bb_dt)
            return tuple(np.where(inside, x[idx], 0.0) for x in self.bb)
        f, A, n_r, n_s = tt["f"], tt["A"], tt["n_r"], tt["n_s"]
        w = 2 * math.pi * f
        Tr = n_r / f
        Tm = (2 * n_r + n_s) / f
        tl = t - 0.4
        inside = (tl >= 0) & (tl <= Tm)
        # envelope sin^2 ramps
        tin = np.clip(tl / Tr, 0, 1)
        tout = np.clip((Tm - tl) / Tr, 0, 1)
        th_rate = math.pi / (2 * Tr)
        ein, eout = np.sin(0.5 * math.pi * tin) ** 2, np.sin(0.5 * math.pi * tout) ** 2
        din = np.where((tin > 0) & (tin < 1), np.sin(math.pi * tin) * th_rate, 0.0)
        dout = np.where((tout > 0) & (tout < 1), -np.sin(math.pi * tout) * th_rate, 0.0)
        ddin = np.where((tin > 0) & (tin < 1), 2 * np.cos(math.pi * tin) * th_rate ** 2, 0.0)
        ddout = np.where((tout > 0) & (tout < 1), 2 * np.cos(math.pi * tout) * th_rate ** 2, 0.0)
        e = ein * eout
        de = din * eout + ein * dout
        dde = ddin * eout + 2 * din * dout + ein * ddout
        ph = w * tl
        if self.kind == "sine":
            s, ds, dds = np.sin(ph), w * np.cos(ph), -w * w * np.sin(ph)
        else:
            arg = np.outer(ph, self.n)
            sn, cs = np.sin(arg), np.cos(arg)
            s = sn @ self.c
            ds = w * (cs @ (self.c * self.n))
            dds = -w * w * (sn @ (self.c * self.n ** 2))
        u = A * e * s
        v = A * (de * s + e * ds)
        a = A * (dde * s + 2 * de * ds + e * dds)
        return (np.where(inside, u, 0.0), np.where(inside, v, 0.0), np.where(inside, a, 0.0))


# ---------------------------------------------------------------- controller tuning
def _tune_controller(rng, T, H, Tc):
    M = T["Me"] + H["m_p"]
    Kq = H["Kv"] * math.sqrt(H["Ps"] / 2)
    Kc = 0.5 * H["Kv"] * H["xu"] / math.sqrt(H["Ps"] / 2)
    wv = 2 * math.pi * H["f_valve"]
    zv = H["zeta_valve"]
    wh = 2 * math.pi * H["f_oil"]
    Td = 1.5 * Tc
    C = 2 * H["beta"] / H["V0"]
    Ap = H["Ap"]
    g_v = rng.uniform(0.0, 0.3)

    def poles(Kp, Kvv, Ka):
        # states u, v, pL, xv, xvd, w (Pade delay)
        Aa = np.zeros((6, 6))
        Aa[0, 1] = 1
        Aa[1, 0], Aa[1, 2] = -T["Ke"] / M, Ap / M
        Aa[2, 1], Aa[2, 2], Aa[2, 3] = -C * Ap, -C * Kc, C * Kq
        xraw = -Kp * np.eye(6)[0] - Kvv * np.eye(6)[1] - Ka * Aa[1]
        Aa[3, 4] = 1
        y = -xraw.copy()
        y[5] += 2  # y = 2w - xraw
        Aa[4] = wv ** 2 * (y - np.eye(6)[3]) - 2 * zv * wv * np.eye(6)[4]
        Aa[5] = (2 / Td) * (xraw - np.eye(6)[5])
        return np.linalg.eigvals(Aa)

    best = None
    r0_max = rng.uniform(0.2, 0.4)
    for r0 in (0.4, 0.35, 0.3, 0.25, 0.2, 0.15, 0.1, 0.07, 0.05):
        if r0 > r0_max:
            continue
        for zt in (0.6, 0.45, 0.3, 0.15, 0.0):
            Kp = r0 * wh * Ap / Kq
            Ka = 2 * zt / wh * Ap / Kq
            Kvv = g_v * Ap / Kq
            lam = poles(Kp, Kvv, Ka)
            if np.any(lam.real >= 0):
                continue
            zeta = np.min(-lam.real / np.maximum(np.abs(lam), 1e-9))
            score = (zeta >= 0.2, r0 if zeta >= 0.2 else zeta)
            if best is None or score > best[0]:
                best = (score, Kp, Kvv, Ka, zeta, r0, zt)
    _, Kp, Kvv, Ka, zeta, r0, zt = best
    Kq_nom = Kq * (1 + 0.08 * rng.standard_normal())
    return dict(Kp=Kp, Kv=Kvv, Ka=Ka, Kff=rng.uniform(0.85, 1.0) * Ap / Kq_nom,
                min_pole_damping=float(zeta), r0=r0, zeta_target=zt,
                c_comp=math.exp(-2 * math.pi * 3.0 * Tc))


# ---------------------------------------------------------------- simulation
def _simulate(T, H, tests, refs, eff, S, ctrl, tp, rng):
    n = len(tests)
    fs, k_dec, n_sub = S["fs"], S["k_dec"], S["n_sub"]
    fi = float(fs * k_dec)
    h = 1.0 / fi
    Tc = h * n_sub
    n_samp = np.array([int(tt["dur"] * fs) + 1 for tt in tests])
    chunk = int(np.lcm(k_dec, n_sub)) * max(1, 4096 // int(np.lcm(k_dec, n_sub)))
    N = int(math.ceil(n_samp.max() * k_dec / chunk)) * chunk

    # per-test plant parameters
    Me_t, Ke_t, Ce_t, Fk_t = tp["Me"], tp["Ke"], tp["Ce"], tp["Fmu"]
    Mtot = Me_t + H["m_p"]
    alpha = T["alpha"]
    sig0 = T["Fmu"] / T["z_pre"]
    sig1 = 2 * T["zeta_bristle"] * np.sqrt(sig0 * Mtot)
    r_st = np.full(n, eff.get("static_ratio", T["static_ratio_clean"]))
    vs = eff.get("stribeck_velocity", T["stribeck_clean"])
    K3 = eff.get("cubic_stiffness", 0.0)
    Fp = eff.get("position_friction", 0.0)
    spec = "specimen_mass" in eff
    invh_s = 1.0 / T["h"]
    Ap, Ps, Pr, Kv, xu = H["Ap"], H["Ps"], H["Pr"], H["Kv"], H["xu"]
    dl2 = H["dp_reg"] ** 2
    bh = H["beta"] * h
    V0, Cl = H["V0"], H["C_leak"]
    Fsl, inv_vsl = H["F_seal"], 1.0 / 2e-3
    eps2 = 1e-10
    pw = 0.5 * (alpha - 1.0)
    hM = h / Mtot
    dr = r_st - 1.0
    inv_vs = 1.0 / vs
    # spool exact discretisation
    wv, zv = 2 * math.pi * H["f_valve"], H["zeta_valve"]
    Ac = np.array([[0, 1], [-wv ** 2, -2 * zv * wv]])
    Bc = np.array([[0], [wv ** 2]])
    Mx = linalg.expm(np.block([[Ac, Bc], [np.zeros((1, 3))]]) * h)
    p11, p12, p21, p22, g1, g2 = Mx[0, 0], Mx[0, 1], Mx[1, 0], Mx[1, 1], Mx[0, 2], Mx[1, 2]
    if spec:
        ms, ks, cs = eff["ms"], eff["ks"], eff["cs"]
    Kp, Kvc, Ka, Kff, cc = ctrl["Kp"], ctrl["Kv"], ctrl["Ka"], ctrl["Kff"], ctrl["c_comp"]

    # state (chamber pressures and spool as 2-row arrays to save numpy calls)
    u = np.zeros(n); v = np.zeros(n); z = np.zeros(n)
    P = np.full((2, n), 0.5 * (Ps + Pr))
    X = np.zeros((2, n)); xc = np.zeros(n); xc_next = np.zeros(n)
    xs = np.zeros(n); vsp = np.zeros(n)
    a = np.zeros(n); ve = np.zeros(n)
    sg2 = np.array([[1.0], [-1.0]])
    Phi = np.array([[p11, p12], [p21, p22]])
    Gam = np.array([[g1], [g2]])
    # numpy is markedly faster on array-array than on float-array operations, so every
    # constant used inside the step loop is broadcast to a full array once here
    fl = lambda x, rows=None: np.full((n,) if rows is None else (rows, n), 0.0) + x
    c_bhKv, c_bhsg = fl(bh * Kv, 2), sg2 * fl(bh, 2)
    c_sgAp, c_V0, c_xu = sg2 * fl(Ap, 2), fl(V0, 2), fl(xu, 2)
    c_Ps, c_Pr, c_dl2, c_pmin = fl(Ps, 2), fl(Pr, 2), fl(dl2, 2), fl(1e4, 2)
    c_zero2, c_wAp = fl(0.0, 2), np.array([Ap, -Ap])
    c_ClA, c_Ap = fl(Cl / Ap), fl(Ap)
    c_sig1h = sig1 / h
    c_dFk = Fk_t * dr
    c_Ceh = Ce_t * hM
    c_sig0, c_ivs, c_mh, c_fi, c_h = fl(sig0), fl(inv_vs), fl(-h), fl(fi), fl(h)
    c_one, c_tiny, c_eps2, c_pw = fl(1.0), fl(1e-12), fl(eps2), fl(pw)
    c_Fsl, c_ivsl, c_ih = fl(Fsl), fl(inv_vsl), fl(invh_s)
    c_Fp, c_K3 = fl(Fp), fl(K3)
    if spec:
        c_ks, c_cs, c_hms = fl(ks), fl(cs), fl(h / ms)

    # sensor set-up
    sos = signal.butter(S["aa_order"], S["aa_fc"], fs=fi, output="sos")
    chans = ["u", "a", "F", "v"]
    zi = {c: None for c in chans + ["vt"]}
    # transducer electronics: white noise through a 1st-order conditioning low-pass at
    # f_cond; sig_* are the RMS at the conditioner output (what the controller sees)
    p_c = math.exp(-2 * math.pi * S["f_cond"] / fi)
    wscale = math.sqrt((1 + p_c) / (1 - p_c))
    zc = {c: np.zeros((1, n)) for c in chans}

    def cond_noise(c):
        w = rng.standard_normal((chunk, n)) * (S["sig_" + c] * wscale * (1 - p_c))
        y, zc[c] = signal.lfilter([1.0], [1.0, -p_c], w, axis=0, zi=zc[c])
        return y
    phi_ar = math.exp(-2 * math.pi * S["F_corner"] / fi)
    ar_state = rng.standard_normal(n) * S["sig_Fc"]
    hum_ph = rng.uniform(0, 2 * math.pi, (2, n))
    off = {c: S["off_" + c] * rng.standard_normal(n) for c in chans}
    dsteps = eff.get("delay", 0.0) / h
    dlen = int(math.ceil(dsteps)) + 2
    F_hist = np.zeros((dlen, n))
    um_prev = off["u"].copy()
    out = {c: [] for c in chans + ["vt"]}
    clean = {c: [] for c in ("u", "v", "a", "F", "Ffr", "Fx")}
    buf = {c: np.zeros((chunk, n)) for c in ("u", "v", "a", "F", "Ffr", "Fx")}

    for c0 in range(0, N, chunk):
        tk = (c0 + np.arange(0, chunk, n_sub)) * h
        R = [np.empty((tk.size, n)) for _ in range(3)]
        for j, rf in enumerate(refs):
            ur, vr, ar = rf(tk)
            R[0][:, j], R[1][:, j], R[2][:, j] = ur, vr, ar
        m_u = cond_noise("u") + off["u"]
        m_a = cond_noise("a") + off["a"]
        bu, bv, ba, bF, bfr, bx = (buf[c] for c in ("u", "v", "a", "F", "Ffr", "Fx"))
        for i in range(chunk):
            if i % n_sub == 0:
                # controller tick: sample sensors, output applied next tick (ZOH)
                xc = xc_next
                q = i // n_sub
                um = u + m_u[i]
                am = a + m_a[i]
                ve = cc * (ve + am * Tc) + (1 - cc) * (um - um_prev) / Tc
                um_prev = um
                xr = (Kp * (R[0][q] - um) + Kvc * (R[1][q] - ve) + Ka * (R[2][q] - am)
                      + Kff * R[1][q])
                xc_next = np.clip(xr, -1.0, 1.0)
            # deck-side forces at the start of the step
            vv = v * c_ivs
            sx = np.exp(-(vv * vv))
            if Fp:
                uh = u * c_ih
                gcap = (Fk_t + c_Fp * uh * uh) * (c_one + dr * sx)
            else:
                gcap = Fk_t + c_dFk * sx
            k = np.abs(v) * c_sig0 / gcap + c_tiny
            E = np.exp(c_mh * k)
            zn = z * E + v * (c_one - E) / k          # exact bristle update, v frozen
            Ffr = c_sig0 * zn + c_sig1h * sx * (zn - z)
            z = zn
            Fsp = Ke_t * u
            if K3:
                uh = u * c_ih
                Fc = c_K3 * uh * uh * u
                Fsp = Fsp + Fc
            Fdeck = Fsp + Ffr
            Fext = c_wAp @ P - c_Fsl * np.tanh(v * c_ivsl) - Fdeck
            if spec:
                Fb = c_ks * (xs - u) + c_cs * (vsp - v)
                Fext = Fext + Fb
            ceff = (v * v + c_eps2) ** c_pw
            vn = (v + hM * Fext) / (c_one + c_Ceh * ceff)   # damping implicit
            a = (vn - v) * c_fi
            Fdeck = Fdeck + Ce_t * ceff * vn
            if spec:
                Fdeck = Fdeck - Fb
                vsp = vsp - c_hms * Fb
                xs = xs + c_h * vsp
                bx[i] = Fb
            elif K3:
                bx[i] = Fc
            bu[i] = u; bv[i] = vn; ba[i] = a; bF[i] = Me_t * a + Fdeck; bfr[i] = Ffr
            v = vn
            # hydraulics with the new velocity: rows = chamber 1 / chamber 2
            Xo = np.maximum(sg2 * X[0], c_zero2) + c_xu      # [xp, xn]
            Ds = c_Ps - P
            Dr = P - c_Pr
            Q = (Xo * (Ds / np.sqrt(np.sqrt(Ds * Ds + c_dl2)))
                 - Xo[::-1] * (Dr / np.sqrt(np.sqrt(Dr * Dr + c_dl2))))
            ql = c_ClA * (c_wAp @ P) + c_Ap * v
            P = np.maximum(P + (c_bhKv * Q - c_bhsg * ql) / (c_V0 + c_sgAp * u), c_pmin)
            u = u + c_h * v
            X = Phi @ X + Gam * xc
        # ---- sensors for this chunk
        tch = (c0 + np.arange(chunk)) * h
        Fsig = bF.copy()
        if dsteps > 0:
            ext = np.vstack([F_hist, Fsig])
            idx = np.arange(chunk) + dlen - dsteps
            i0 = np.floor(idx).astype(int)
            fr = (idx - i0)[:, None]
            F_hist = ext[-dlen:].copy()
            Fsig = ext[i0] * (1 - fr) + ext[i0 + 1] * fr
        wnF = rng.standard_normal((chunk, n)) * (S["sig_Fc"] * math.sqrt(1 - phi_ar ** 2))
        lc, _ = signal.lfilter([1.0], [1.0, -phi_ar], wnF, axis=0, zi=(phi_ar * ar_state)[None, :])
        ar_state = lc[-1]
        hum = (S["hum50"] * np.sin(2 * math.pi * S["f_mains"] * tch[:, None] + hum_ph[0])
               + S["hum150"] * np.sin(6 * math.pi * S["f_mains"] * tch[:, None] + hum_ph[1]))
        raw = {"u": bu + m_u, "a": ba + m_a,
               "F": Fsig + lc + hum + off["F"] + cond_noise("F"),
               "v": bv + off["v"] + cond_noise("v"), "vt": bv}
        for c in chans + ["vt"]:
            x = raw[c]
            if zi[c] is None:
                zi[c] = signal.sosfilt_zi(sos)[:, :, None] * x[0][None, None, :]
            y, zi[c] = signal.sosfilt(sos, x, axis=0, zi=zi[c])
            out[c].append(y[::k_dec])
        for c in clean:
            clean[c].append(buf[c][::k_dec].copy())
        if _DEBUG is not None and c0 // chunk in _DEBUG.get("chunks", ()):
            _DEBUG.setdefault("buf", []).append({c: buf[c].copy() for c in buf})
    out = {c: np.concatenate(out[c]) for c in out}
    clean = {c: np.concatenate(clean[c]) for c in clean}
    # per-test slices, quantisation
    res = []
    for j in range(n):
        m = n_samp[j]
        d = {"t": np.arange(m) / fs}
        for c in chans:
            lsb = S["range_" + c] * 2 / 65536
            d[c] = np.round(out[c][:m, j] / lsb) * lsb
        ucmd, _, acmd = refs[j](d["t"])
        d["u_cmd"], d["a_cmd"] = ucmd, acmd
        cl = {c: clean[c][:m, j] for c in clean}
        cl["v_aa"] = out["vt"][:m, j]          # noise-free v through the DAQ filter
        res.append((d, cl))
    return res


# ---------------------------------------------------------------- effect draws
def _draw_effect(name, size, rng, T, H, tests):
    s = float(rng.uniform()) if size is None else float(np.clip(size, 0, 1))
    e, sim = {"name": name, "size": s}, {}
    if name == "stiction":
        e["static_ratio"] = _lerp(1.1, 1.6, s)
        e["stribeck_velocity"] = _lerp(2e-3, 20e-3, s, log=True)
        sim = {"static_ratio": e["static_ratio"], "stribeck_velocity": e["stribeck_velocity"]}
    elif name == "channel_delay":
        e["delay"] = _lerp(0.5e-3, 6e-3, s, log=True)
        sim = {"delay": e["delay"]}
    elif name == "specimen":
        # small and stiff is the weak end, heavy and soft (close to the test band) strong
        e["specimen_mass"] = _lerp(1000.0, 5000.0, s)
        e["specimen_frequency"] = _lerp(25.0, 5.0, float(np.clip(s + rng.uniform(-0.15, 0.15),
                                                                 0, 1)), log=True)
        e["specimen_damping"] = _lerp(0.05, 0.02, float(np.clip(s + rng.uniform(-0.2, 0.2), 0, 1)))
        wn = 2 * math.pi * e["specimen_frequency"]
        sim = {"specimen_mass": e["specimen_mass"], "ms": e["specimen_mass"],
               "ks": e["specimen_mass"] * wn ** 2,
               "cs": 2 * e["specimen_damping"] * e["specimen_mass"] * wn}
        e["Fmu_with_specimen"] = T["mu_e"] * (T["F_hd"] + (T["m_deck"] + e["specimen_mass"]) * G)
    elif name == "nonlinear_stiffness":
        r = _lerp(0.3, 15.0, s, log=True)
        e["cubic_stiffness"] = r * T["Ke"]
        e["l0_implied"] = T["gamma"] * T["h"] / (1 + 2 * r)
        sim = {"cubic_stiffness": e["cubic_stiffness"]}
    elif name == "position_friction":
        umax = max(tt["A"] for tt in tests)
        r = _lerp(0.03, 0.40, s, log=True)
        e["position_friction"] = r * T["Fmu"] * (T["h"] / umax) ** 2
        e["fraction_of_Fmu_at_max_stroke"] = r
        sim = {"position_friction": e["position_friction"]}
    elif name == "drift":
        e["drift"] = _lerp(0.05, 0.25, s)
        e["warmup_exponent"] = float(rng.uniform(0.5, 1.0))
        sim = {"drift": e["drift"], "p": e["warmup_exponent"]}
    else:
        raise ValueError(f"unknown effect {name!r}; choose from {EFFECTS}")
    return e, sim


# ---------------------------------------------------------------- CSV writing
def _write_csv(path, cols, data):
    arr = np.column_stack([data[c] for c in cols])
    fmt = ",".join(["%.6f"] + ["%.7g"] * (len(cols) - 1)) + "\n"
    with open(path, "w") as fh:
        fh.write(",".join(cols) + "\n")
        step = 20000
        for i in range(0, arr.shape[0], step):
            blk = arr[i:i + step]
            fh.write((fmt * blk.shape[0]) % tuple(blk.ravel()))


# ---------------------------------------------------------------- public entry
def make_series(seed, out_dir, effect=None, size=None, truth_path=None, _return_clean=False):
    t_start = time.time()
    ss = np.random.SeedSequence([7077, int(seed)])
    r_tab, r_plan, r_sens, r_ctrl, r_sim, r_eff = (np.random.default_rng(x) for x in ss.spawn(6))
    T = _draw_table(r_tab)
    payload = float(r_plan.uniform(2e3, 10e3)) if r_plan.random() < 0.6 else 0.0
    H = _draw_hydraulics(r_tab, T, payload)
    fs = int(r_sens.choice([200, 500, 1000, 2048], p=[0.15, 0.3, 0.35, 0.2]))
    tests = _draw_plan(r_plan, T, H, payload, fs)
    n = len(tests)
    fi_mult = {200: 50, 500: 20, 1000: 10, 2048: 5}[fs]
    n_sub = int(r_ctrl.choice([4, 5, 10]))
    S = dict(fs=fs, k_dec=fi_mult, n_sub=n_sub)
    S["aa_order"] = int(r_sens.choice([4, 6, 8]))
    S["aa_fc"] = float(r_sens.uniform(0.28, 0.4) * fs)
    S["sig_u"] = r_sens.uniform(5e-6, 30e-6)
    S["sig_a"] = r_sens.uniform(0.005, 0.03)
    S["sig_v"] = r_sens.uniform(1e-3, 4e-3)
    S["sig_Fc"] = r_sens.uniform(80.0, 400.0)
    S["sig_F"] = r_sens.uniform(30.0, 120.0)       # white part (AR(1) part: sig_Fc)
    S["f_cond"] = r_sens.uniform(500.0, 1500.0)
    S["F_corner"] = r_sens.uniform(15.0, 150.0)
    S["hum50"] = r_sens.uniform(30.0, 300.0)
    S["hum150"] = S["hum50"] * r_sens.uniform(0.05, 0.3)
    S["f_mains"] = 50.0 + r_sens.uniform(-0.05, 0.05)
    S["off_u"], S["off_a"], S["off_F"], S["off_v"] = 1e-4, 0.01, 200.0, 1e-3
    S["range_u"], S["range_a"], S["range_v"] = 0.15, 20.0, 1.0
    S["range_F"] = 1.3 * H["F_cap"]
    cols = ["t", "u", "F"]
    rec_a = r_sens.random() < 0.85
    rec_v = r_sens.random() < 0.35
    rec_cmd = r_sens.random() < 0.5
    rec_acmd = rec_cmd and r_sens.random() < 0.4
    cols += ["a"] * rec_a + ["v"] * rec_v + ["u_cmd"] * rec_cmd + ["a_cmd"] * rec_acmd
    ctrl = _tune_controller(r_ctrl, T, H, n_sub / (fs * fi_mult))
    refs = [_Reference(tt, n_sub / (fs * fi_mult)) for tt in tests]

    eff_truth, eff_sim = (None, {})
    if effect is not None:
        eff_truth, eff_sim = _draw_effect(effect, size, r_eff, T, H, tests)

    # per-test truth with scatter (and drift)
    sc = 1 + T["spread"] * r_tab.standard_normal((4, n))
    pay = np.array([tt["payload"] for tt in tests])
    extra_m = eff_sim.get("ms", 0.0)
    tp = {"Me": T["Me"] * sc[0] + pay, "Ke": T["Ke"] * sc[1], "Ce": T["Ce"] * sc[2],
          "Fmu": T["mu_e"] * (T["F_hd"] + (T["m_deck"] + pay + extra_m) * G) * sc[3]}
    if "drift" in eff_sim:
        wk = (np.arange(n) / max(n - 1, 1)) ** eff_sim["p"]
        fall = 1 - eff_sim["drift"] * wk
        tp["Ce"] = tp["Ce"] * fall
        tp["Fmu"] = tp["Fmu"] * fall
    res = _simulate(T, H, tests, refs, eff_sim, S, ctrl, tp, r_sim)

    os.makedirs(out_dir, exist_ok=True)
    mtests = []
    for k, (tt, (d, _)) in enumerate(zip(tests, res)):
        tid = f"T{k + 1:02d}"
        e = {"id": tid, "file": f"{tid}.csv", "kind": tt["kind"]}
        if tt["kind"] != "broadband":
            e["frequency_hz"], e["amplitude_m"] = tt["f"], tt["A"]
        e["payload_kg"] = float(tt["payload"])
        e["order"] = k + 1
        mtests.append(e)
        _write_csv(os.path.join(out_dir, e["file"]), cols, d)
    manifest = {
        "format": "sst-series/1",
        "name": f"seventh-seed{seed}" + (f"-{effect}" if effect else ""),
        "table": {
            "deck_mass_kg": round(T["m_deck"], 1),
            "strut": {"n": 4, "p0_pa": T["p0"], "area_m2": T["A_strut"], "h_m": T["h"],
                      "l0_m": T["l0"], "gamma": T["gamma"]},
            "oil": {"bulk_modulus_pa": H["beta"], "piston_area_m2": H["Ap"],
                    "oil_volume_m3": H["V0"]},
            "supply_pressure_pa": H["Ps"],
        },
        "tests": mtests,
    }
    with open(os.path.join(out_dir, "series.json"), "w") as fh:
        json.dump(manifest, fh, indent=1)

    truth = {"seed": int(seed), "Me": T["Me"], "Ke": T["Ke"], "Ce": T["Ce"], "alpha": T["alpha"],
             "Fmu": T["Fmu"], "spread": T["spread"], "fs": fs, "n_tests": n,
             "effect": eff_truth,
             "mu_e": T["mu_e"], "m_deck": T["m_deck"], "F_hd": T["F_hd"],
             "per_test": {k: [float(x) for x in v] for k, v in tp.items()},
             "payload_kg": payload, "f_oil": H["f_oil"],
             "hydraulics": {k: float(v) for k, v in H.items()},
             "controller": {"rate_hz": fs * fi_mult / n_sub, **{k: float(v) for k, v in ctrl.items()}},
             "sensors": {k: (float(v) if not isinstance(v, str) else v) for k, v in S.items()},
             "friction_model": {"z_pre": T["z_pre"], "sigma0": T["Fmu"] / T["z_pre"],
                                "static_ratio": T["static_ratio_clean"],
                                "stribeck_velocity": T["stribeck_clean"]},
             "columns": cols, "internal_rate_hz": fs * fi_mult,
             "generation_s": time.time() - t_start}
    if truth_path:
        os.makedirs(os.path.dirname(os.path.abspath(truth_path)), exist_ok=True)
        with open(truth_path, "w") as fh:
            json.dump(truth, fh, indent=1)
    out = {"manifest": manifest, "truth": truth}
    if _return_clean:
        out["clean"] = [cl for _, cl in res]
        out["recorded"] = [d for d, _ in res]
    return out


# ---------------------------------------------------------------- self-checks
def _travel_since_reversal(u, v):
    sgn = np.sign(v)
    seg = np.concatenate([[0], np.cumsum(sgn[1:] != sgn[:-1])])
    cum = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(u)))])
    start = np.zeros(seg[-1] + 1)
    first = np.concatenate([[True], seg[1:] != seg[:-1]])
    start[seg[first]] = cum[first]
    return cum - start[seg]


def _base_residual_clean(r):
    """Residual of the base law with the true per-test parameters on the noise-free
    internal signals (decimated, not filtered).  Returns RMS/Fmu while moving
    (|v| > 1 mm/s) and away from reversals (|v| > 10 % of peak and more than 5 pre-sliding
    lengths of travel since the last velocity reversal), plus the fraction kept."""
    tr = r["truth"]
    mov, away, nk, nt = [], [], 0, 0
    zp = tr["friction_model"]["z_pre"]
    for j, cl in enumerate(r["clean"]):
        p = {k: tr["per_test"][k][j] for k in ("Me", "Ke", "Ce", "Fmu")}
        v = cl["v"]
        model = (p["Me"] * cl["a"] + p["Ke"] * cl["u"]
                 + (p["Ce"] * np.abs(v) ** tr["alpha"] + p["Fmu"]) * np.sign(v))
        res = cl["F"] - model
        m = (np.abs(v) > 0.1 * np.abs(v).max()) & (_travel_since_reversal(cl["u"], v) > 5 * zp)
        mov.append(res[np.abs(v) > 1e-3]); away.append(res[m])
        nk += m.sum(); nt += (np.abs(v) > 1e-3).sum()
    rms = lambda x: float(np.sqrt(np.mean(np.concatenate(x) ** 2)))
    return rms(mov) / tr["Fmu"], rms(away) / tr["Fmu"], nk / nt


def _base_fit_rms(r, per_test=False):
    """Least-squares fit of the base law to the RECORDED force (true v used, alpha on a
    grid); pooled: one parameter set, payload mass and its friction share as known
    regressors; per_test: Me, Ke, Ce, Fmu free in every test.  Returns the residual RMS
    in N on the samples away
    from reversals (|v| > 10 % of the test's peak, > 5 pre-sliding lengths travelled)."""
    rows, F, tid, keep = [], [], [], []
    zp = r["truth"]["friction_model"]["z_pre"]
    for j, (d, cl, m) in enumerate(zip(r["recorded"], r["clean"], r["manifest"]["tests"])):
        # all regressors through the same anti-alias filter as the force
        ac, vr = d["a"], cl["v_aa"]
        pay = m["payload_kg"]
        sg = np.sign(vr)
        rows.append((ac, d["u"], np.abs(vr), sg, pay * G * sg))
        F.append(d["F"] - pay * ac)
        tid.append(np.full(len(ac), j))
        keep.append((np.abs(cl["v"]) > 0.1 * np.abs(cl["v"]).max())
                    & (_travel_since_reversal(cl["u"], cl["v"]) > 5 * zp))
    keep = np.concatenate(keep)
    F, tid = np.concatenate(F)[keep], np.concatenate(tid)[keep]
    cols = [np.concatenate([x[i] for x in rows])[keep] for i in range(5)]
    best = None
    for al in np.linspace(0.3, 1.0, 15):
        X = np.column_stack([cols[0], cols[1], cols[2] ** al * cols[3], cols[3], cols[4]])
        if per_test:       # separate Me, Ke, Ce, Fmu for every test, common alpha
            res = np.empty_like(F)
            for j in range(tid.max() + 1):
                m = tid == j
                coef, *_ = np.linalg.lstsq(X[m, :4], F[m], rcond=None)
                res[m] = F[m] - X[m, :4] @ coef
        else:
            coef, *_ = np.linalg.lstsq(X, F, rcond=None)
            res = F - X @ coef
        rr = float(np.sqrt(np.mean(res ** 2)))
        if best is None or rr < best:
            best = rr
    return best


def _selfcheck(root, effects=EFFECTS, clean_seeds=(0, 1, 2)):
    os.makedirs(root, exist_ok=True)
    lines = []

    def say(x):
        lines.append(x)
        print(x, flush=True)

    for seed in clean_seeds:
        t0 = time.time()
        r = make_series(seed, os.path.join(root, f"clean_{seed}"), None, None,
                        os.path.join(root, f"clean_{seed}_truth.json"), _return_clean=True)
        dt = time.time() - t0
        a, b, frac = _base_residual_clean(r)
        tr = r["truth"]
        say(f"clean seed {seed}: {dt:.1f}s fs={tr['fs']} n={tr['n_tests']} "
            f"Me={tr['Me']:.0f} Ke={tr['Ke']:.3g} Ce={tr['Ce']:.3g} alpha={tr['alpha']:.2f} "
            f"Fmu={tr['Fmu']:.0f} f_oil={tr['f_oil']:.1f} | true-law resid/Fmu moving={a:.3f} "
            f"away={b:.4f} ({100 * frac:.0f} % of moving) | fit RMS pooled "
            f"{_base_fit_rms(r):.0f} N, per-test {_base_fit_rms(r, True):.0f} N")
    for i, eff in enumerate(effects):
        seed = 10 + EFFECTS.index(eff)
        base = make_series(seed, os.path.join(root, f"base_{seed}"), None, _return_clean=True)
        rb = (_base_fit_rms(base), _base_fit_rms(base, True))
        for sz in (0.0, 1.0):
            t0 = time.time()
            tag = f"{eff}_{'weak' if sz == 0 else 'strong'}"
            r = make_series(seed, os.path.join(root, tag), eff, sz,
                            os.path.join(root, tag + "_truth.json"), _return_clean=True)
            dt = time.time() - t0
            re = (_base_fit_rms(r), _base_fit_rms(r, True))
            e = {k: (round(v, 5) if isinstance(v, float) else v)
                 for k, v in r["truth"]["effect"].items() if k != "name"}
            say(f"{tag}: {dt:.1f}s fit RMS pooled {rb[0]:.0f}->{re[0]:.0f} N "
                f"(+{100 * (re[0] / rb[0] - 1):.1f} %), per-test {rb[1]:.0f}->{re[1]:.0f} N "
                f"(+{100 * (re[1] / rb[1] - 1):.1f} %) {e}")
    return lines


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None)
    ap.add_argument("--effect", default=None, choices=EFFECTS)
    ap.add_argument("--size", type=float, default=None)
    ap.add_argument("--truth", default=None)
    ap.add_argument("--selfcheck", default=None, metavar="DIR")
    ap.add_argument("--check-effects", default=",".join(EFFECTS))
    ap.add_argument("--check-clean", default="0,1,2")
    a = ap.parse_args()
    if a.selfcheck:
        _selfcheck(a.selfcheck, [e for e in a.check_effects.split(",") if e],
                   [int(x) for x in a.check_clean.split(",") if x])
        return
    if a.out is None:
        ap.error("--out is required")
    truth = a.truth or os.path.join(a.out, "..", os.path.basename(os.path.normpath(a.out)) + "_truth.json")
    r = make_series(a.seed, a.out, a.effect, a.size, truth)
    print(json.dumps({k: r["truth"][k] for k in ("seed", "Me", "Ke", "Ce", "alpha", "Fmu",
                                                  "spread", "fs", "n_tests", "effect",
                                                  "generation_s")}, indent=1))


if __name__ == "__main__":
    main()
