"""Eighth independent generator: a closed-loop servo-hydraulic shaking-table simulator.

Writes a test series in the ``sst-series/1`` format (``series.json`` + one CSV per test)
plus ``truth.json`` (not referenced by the manifest) for blind system-identification tests.

Physics
-------
Mechanics (rigid load cell between rod and deck, so deck + rod + piston move together)::

    (Md + m_pay + Mp) a = Ap (p1 - p2) - F_seal(v) - F_deck
    F_deck = Ke u + K3 (u/h)^2 u + Ce |v|^alpha sign(v) + F_fr - F_spec
    F (load cell) = (Md + m_pay) a + F_deck          # piston/rod mass and seal friction excluded

* struts: Ke = 4 p0 A / h, hold-down F_hd = 4 p0 A = Ke h.
* deck friction F_fr: LuGre bristle model, F_fr = s0 z + s1 dz/dt,
  dz/dt = v - |v| z s0 / g(v, u), g = Fc + (Fs - Fc) exp(-(v/vs)^2) + Fp (u/h)^2,
  Fc = mu_e (F_hd + (Md + m_pay) g0); pre-sliding displacement z_ss = Fc / s0 (5-60 um).
  Clean series: Fs/Fc in [1.00, 1.03] (vs = 5 mm/s), Fp = 0.
* viscous term regularised linearly below |v| = 1 mm/s (alpha < 1 has infinite slope at 0).
* optional specimen: SDOF on the deck, base shear F_spec = k_s (x_s - u) + c_s (v_s - v).
* seal friction on the piston: F_seal = Fsl tanh(v / 1 mm/s) + c_sl v (not in F).

Hydraulics: 4-way critically-lapped servo-valve, spool as a 2nd-order system (60-200 Hz,
zeta 0.6-0.8, stroke saturated at +-1), orifice law Q = Kv x_v sqrt(dp) (sqrt regularised
linearly below 0.1 MPa, reverse flow allowed), two chambers
dp_i/dt = beta / V_i(u) (+-Q_i -+ Ap v - Q_leak), V_1,2 = V0 +- Ap u.  Oil-column frequency
at mid stroke f_oil = sqrt(4 beta Ap^2 / (V_tot (Md + Mp))) / 2 pi (the table description
gives ``oil_volume_m3`` = V_tot = both chambers incl. hoses).

Control: digital controller at f_c in {1000, 2000, 2500, 4000} Hz, one tick of delay, zero-order
hold on the valve command; law (three-variable style)::

    i = Kp e + Ki int(e) + Kff v_cmd - Kdp (p_L - p_L,ff) / Ps,   e = u_cmd - u
    p_L,ff = ((Md + m_pay + Mp) a_cmd + Ke u_cmd) / Ap    (nominal model feed-forward)

Kp is set for a loop crossover of 0.12-0.2 x the (true) oil-column frequency (capped at 9 Hz),
Kdp for ~0.3 hydraulic damping, Kff = the nominal velocity gain inverse.

Numerics
--------
Fixed internal step dt = 1/(f_c * nsub) (2-4 kHz), per step: exact ZOH discretisation of the
spool (matrix exponential), explicit Euler for the chamber pressures, semi-implicit
(symplectic) Euler for deck and specimen, exact exponential update of the LuGre bristle
state for the velocity held over the step (unconditionally stable, no chatter).  A scalar
Python loop (no numba available); runs at ~5-10 us per step.

Recording: the internal signals (and sensor noise: white + 1/f drift + 50 Hz hum on the
load cell + constant offsets) pass a 4th-order Butterworth anti-alias filter at 0.3-0.4 fs
(analog prototype discretised by a pre-warped bilinear transform at the internal rate, the
same on all channels), are resampled at fs in {200, 250, 500, 1000, 2048} Hz by cubic
interpolation, and quantised to 16 bits over the sensor range.  The ``channel_delay`` effect
records F at t - delay.

Effects (one at a time): stiction, nonlinear_stiffness, position_friction, specimen,
channel_delay, drift, oil_column.  See ``_effect_params``.  The oil_column effect is entrained
air: the true bulk modulus lowered so that f_oil falls to 8-12 Hz (strong) or 15-20 Hz (weak,
at most 0.8 x nominal) while the table description keeps the nominal oil.

Commissioning rules (added after 4 of 20 first-draft series ran a chamber dry and diverged):
the cylinder holds at least DEAD_FRAC of its mid-stroke volume in each chamber at the largest
programmed stroke (the oil volume grows, and the nominal f_oil with it, where the draw gave
less), and periodic tests stay below F_OIL_TEST_MAX x the oil-column frequency.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import time

import numpy as np
from scipy import signal
from scipy.interpolate import CubicSpline
from scipy.linalg import expm

G0 = 9.81
DEAD_FRAC = 0.05       # min. chamber volume at full programmed stroke / mid-stroke volume
F_OIL_TEST_MAX = 0.4   # periodic test frequencies kept below this x the oil-column frequency
EFFECTS = ("stiction", "nonlinear_stiffness", "position_friction", "specimen",
           "channel_delay", "drift", "oil_column")


# ----------------------------------------------------------------------------- commands
def _envelope(t, t0, n_ramp, n_steady, period):
    """Raised-cosine ramp-in of n_ramp cycles, n_steady steady cycles, ramp-out."""
    tr = n_ramp * period
    ts = n_steady * period
    tau = t - t0
    env = np.zeros_like(t)
    m = (tau >= 0) & (tau < tr)
    env[m] = 0.5 * (1 - np.cos(np.pi * tau[m] / tr))
    m = (tau >= tr) & (tau <= tr + ts)
    env[m] = 1.0
    m = (tau > tr + ts) & (tau < 2 * tr + ts)
    env[m] = 0.5 * (1 + np.cos(np.pi * (tau[m] - tr - ts) / tr))
    return env


def _periodic_command(test, t):
    w = 2 * np.pi * test["frequency_hz"]
    th = w * (t - test["t0"])
    if test["kind"] == "sine":
        shape = np.sin(th)
    else:  # rounded triangle, slope-normalised arcsin form
        rho = test["rho"]
        shape = np.arcsin(rho * np.sin(th)) / np.arcsin(rho)
    return test["amplitude_m"] * shape * _envelope(t, test["t0"], test["n_ramp"],
                                                   test["n_steady"], 1 / test["frequency_hz"])


def _broadband_command(rng, duration, fc, t0, vmax, umax, amax):
    """Velocity-flat band-limited noise 0.5-40 Hz, cosine tapers, on the controller grid."""
    n = int(round((duration + 2 * t0) * fc))
    n_core = int(round(duration * fc))
    f = np.fft.rfftfreq(n_core, 1 / fc)
    band = np.zeros_like(f)
    m = (f > 0.3) & (f < 45)
    band[m] = 1 / f[m]                                          # |U| ~ 1/f: velocity flat
    band *= 1 / (1 + (0.5 / np.maximum(f, 1e-9)) ** 8) / (1 + (f / 40) ** 8)
    spec = band * (rng.normal(size=f.size) + 1j * rng.normal(size=f.size))
    u = np.fft.irfft(spec, n_core)
    tap = int(1.5 * fc)
    win = np.ones(n_core)
    win[:tap] = 0.5 * (1 - np.cos(np.pi * np.arange(tap) / tap))
    win[-tap:] = win[:tap][::-1]
    u *= win
    u = np.concatenate([np.zeros(int(round(t0 * fc))), u, np.zeros(n - n_core - int(round(t0 * fc)))])
    v = np.gradient(u, 1 / fc)
    a = np.gradient(v, 1 / fc)
    s = min(umax / np.abs(u).max(), vmax / np.abs(v).max(), amax / np.abs(a).max())
    return u * s


# ----------------------------------------------------------------------------- program
def _draw_program(rng, effect, fc, fmax=np.inf):
    n_total = int(rng.integers(8, 25))
    has_bb = effect == "oil_column" or rng.random() < 0.5
    n_pay = int(rng.integers(1, 3)) if rng.random() < 0.5 else 0
    n_per = n_total - int(has_bb)
    tests = []
    big = effect in ("nonlinear_stiffness", "position_friction")
    for k in range(n_per):
        kind = "triangle" if rng.random() < 0.25 else "sine"
        if k < 2 or (big and k < 4):      # a few large-stroke, low-frequency tests
            f = float(np.exp(rng.uniform(np.log(0.2), np.log(1.2))))
        else:
            f = float(np.exp(rng.uniform(np.log(0.2), np.log(6.0))))
        f = min(f, fmax)     # no periodic test near the oil-column resonance
        rho = float(rng.uniform(0.9, 0.98))
        slope = 1.0 if kind == "sine" else rho / np.arcsin(rho)      # v_pk = A w slope
        curv = 1.0 if kind == "sine" else rho / np.sqrt(1 - rho ** 2) / np.arcsin(rho)
        w = 2 * np.pi * f
        if k < 2 or (big and k < 4):
            amp = rng.uniform(0.035, 0.06)
        else:
            vt = np.exp(rng.uniform(np.log(0.03), np.log(0.45)))
            amp = vt / (w * slope)
        amp = min(amp, 0.06, 0.48 / (w * slope), 9.0 / (w * w * curv))
        amp = float(round(max(amp, 0.001), 4))
        if f < 0.5:
            n_ramp, n_steady = 1, 4
        else:
            n_ramp, n_steady = int(rng.integers(1, 4)), int(rng.integers(4, 9))
        tests.append(dict(kind=kind, frequency_hz=round(f, 3), amplitude_m=amp, rho=rho,
                          n_ramp=n_ramp, n_steady=n_steady, payload_kg=0.0))
    for k in rng.choice(n_per, size=n_pay, replace=False):
        tests[k]["payload_kg"] = float(round(rng.uniform(500, 4000), -1))
    if has_bb:
        tests.append(dict(kind="broadband", duration_s=float(round(rng.uniform(20, 40), 1)),
                          payload_kg=0.0, band_hz=[0.5, 40.0]))
    order = rng.permutation(len(tests))
    tests = [tests[i] for i in order]
    n_s = 0
    for i, tst in enumerate(tests):
        tst["order"] = i + 1
        tst["t0"] = float(round(rng.uniform(0.5, 1.0), 3))
        if tst["kind"] == "broadband":
            tst["id"] = "B%02d" % (i + 1)
            tst["duration"] = tst["duration_s"] + 2 * tst["t0"]
        else:
            n_s += 1
            tst["id"] = ("S" if tst["kind"] == "sine" else "T") + "%02d" % (i + 1)
            tst["duration"] = (2 * tst["n_ramp"] + tst["n_steady"]) / tst["frequency_hz"] + 2 * tst["t0"]
        tst["file"] = tst["id"] + ".csv"
    return tests


def _effect_params(rng, effect, size, base):
    s = size == "strong"
    if effect is None:
        return None
    if effect == "stiction":
        return dict(static_ratio=rng.uniform(1.3, 1.5) if s else rng.uniform(1.15, 1.2),
                    stribeck_velocity=rng.uniform(0.008, 0.02) if s else rng.uniform(0.002, 0.004))
    if effect == "nonlinear_stiffness":
        r = rng.uniform(1.5, 3.0) if s else rng.uniform(0.3, 0.6)
        return dict(cubic_stiffness=r * base["Ke"], cubic_ratio=r, h=base["h"])
    if effect == "position_friction":
        frac = rng.uniform(0.25, 0.4) if s else rng.uniform(0.05, 0.1)
        return dict(position_friction_fraction=frac)   # Fp filled once the program is known
    if effect == "specimen":
        return dict(specimen_mass=rng.uniform(2000, 4000) if s else rng.uniform(500, 900),
                    specimen_frequency=rng.uniform(3, 10) if s else rng.uniform(14, 20),
                    specimen_damping=rng.uniform(0.01, 0.05) if s else rng.uniform(0.03, 0.05))
    if effect == "channel_delay":
        return dict(delay=rng.uniform(0.008, 0.015) if s else rng.uniform(0.002, 0.003))
    if effect == "drift":
        return dict(drift=rng.uniform(0.2, 0.3) if s else rng.uniform(0.05, 0.08))
    if effect == "oil_column":
        return dict(oil_frequency=rng.uniform(8, 12) if s else rng.uniform(15, 20))
    raise ValueError("unknown effect %r" % (effect,))


# ----------------------------------------------------------------------------- simulation
def _simulate(P, T, cmd_u, cmd_v, cmd_a):
    """Integrate one test. Returns internal-rate arrays x, v, a, F, friction, z-force."""
    nsub = P["nsub"]
    dt = P["dt"]
    ntick = cmd_u.size
    N = ntick * nsub
    Phi, Gam = P["Phi"], P["Gam"]
    f00, f01, f10, f11 = Phi[0, 0], Phi[0, 1], Phi[1, 0], Phi[1, 1]
    g0_, g1_ = Gam[0], Gam[1]
    Ap, beta, V10, V20 = P["Ap"], P["beta"], P["V10"], P["V20"]
    Ps, Pr, Kv, Cl = P["Ps"], P["Pr"], P["Kv"], P["Cl"]
    dpl = 1e5
    sdl = math.sqrt(dpl)
    Mdk = T["Mdeck"]
    Mt = Mdk + P["Mp"]
    Ke, K3h2 = T["Ke"], T["K3"] / P["h"] ** 2
    Ce, al, vreg = T["Ce"], T["alpha"], 1e-3
    cslope = Ce * vreg ** (al - 1)
    Fc, Fsx, vs2 = T["Fc"], T["Fs"] - T["Fc"], T["vs"] ** 2
    Fph2 = T["Fp"] / P["h"] ** 2
    s0, s1 = T["sigma0"], T["sigma1"]
    Fsl, csl = P["Fseal"], P["cseal"]
    ms, ks, cs = T["ms"], T["ks"], T["cs"]
    spec = ms > 0
    Kp, Ki, Kff, Kdp = P["Kp"], P["Ki"], P["Kff"], P["Kdp"]
    Tc = dt * nsub
    pff = ((Mt * cmd_a + Ke * cmd_u) / Ap).tolist()
    cu, cv = cmd_u.tolist(), cmd_v.tolist()
    x = v = z = zd = xv = xvd = r = rd = integ = 0.0
    p1 = p2 = 0.5 * (Ps + Pr)
    # start on the equilibrium pressure difference = 0 -> balanced
    pending = applied = 0.0
    X = [0.0] * N
    Vv = [0.0] * N
    A = [0.0] * N
    F = [0.0] * N
    exp, sqrt, tanh = math.exp, math.sqrt, math.tanh
    i = 0
    for k in range(ntick):
        applied = pending
        e = cu[k] - x
        integ += e * Tc
        c = Kp * e + Ki * integ + Kff * cv[k] - Kdp * ((p1 - p2) - pff[k]) / Ps
        pending = 1.0 if c > 1.0 else (-1.0 if c < -1.0 else c)
        for _ in range(nsub):
            xv, xvd = f00 * xv + f01 * xvd + g0_ * applied, f10 * xv + f11 * xvd + g1_ * applied
            if xv > 1.0:
                xv, xvd = 1.0, 0.0
            elif xv < -1.0:
                xv, xvd = -1.0, 0.0
            if xv >= 0.0:
                d1 = Ps - p1
                d2 = p2 - Pr
            else:
                d1 = p1 - Pr
                d2 = Ps - p2
            s1q = sqrt(d1) if d1 > dpl else (d1 / sdl if d1 > -dpl else -sqrt(-d1))
            s2q = sqrt(d2) if d2 > dpl else (d2 / sdl if d2 > -dpl else -sqrt(-d2))
            Q1 = Kv * xv * s1q
            Q2 = Kv * xv * s2q
            QL = Cl * (p1 - p2)
            Apv = Ap * v
            p1 += dt * beta / (V10 + Ap * x) * (Q1 - QL - Apv)
            p2 += dt * beta / (V20 - Ap * x) * (-Q2 + QL + Apv)
            if p1 < 1e4:
                p1 = 1e4
            if p2 < 1e4:
                p2 = 1e4
            # deck forces
            av = v if v >= 0 else -v
            if av > vreg:
                fv = Ce * av ** al
                fv = fv if v > 0 else -fv
            else:
                fv = cslope * v
            fd = Ke * x + K3h2 * x * x * x + fv + s0 * z + s1 * zd
            if spec:
                fsp = ks * r + cs * rd
                fd -= fsp
            a = (Ap * (p1 - p2) - Fsl * tanh(v * 1000.0) - csl * v - fd) / Mt
            X[i] = x
            Vv[i] = v
            A[i] = a
            F[i] = Mdk * a + fd
            i += 1
            v += dt * a
            x += dt * v
            if spec:
                rd += dt * (-(ks * r + cs * rd) / ms - a)
                r += dt * rd
            # exact bristle update for v held over the step
            g = Fc + Fsx * exp(-v * v / vs2) + Fph2 * x * x
            if v != 0.0:
                av = v if v >= 0 else -v
                zs = g / s0 if v > 0 else -g / s0
                zn = zs + (z - zs) * exp(-av * s0 / g * dt)
            else:
                zn = z
            zd = (zn - z) / dt
            z = zn
    return np.array(X), np.array(Vv), np.array(A), np.array(F)


def _pink(rng, n, fs, fmin):
    f = np.fft.rfftfreq(n, 1 / fs)
    amp = np.zeros_like(f)
    m = f >= fmin
    amp[m] = 1 / np.sqrt(f[m])
    x = np.fft.irfft(amp * (rng.normal(size=f.size) + 1j * rng.normal(size=f.size)), n)
    return x / (x.std() + 1e-300)


def _q(x, full):
    lsb = 2 * full / 65536
    return np.clip(np.round(x / lsb), -32768, 32767) * lsb


# ----------------------------------------------------------------------------- main entry
def generate(seed, out, effect=None, size="strong", verbose=False, name=None):
    """Simulate one test series and write it (plus truth.json) to folder ``out``."""
    if effect is not None and effect not in EFFECTS:
        raise ValueError("effect must be None or one of %s" % (EFFECTS,))
    if size not in ("strong", "weak"):
        raise ValueError("size must be 'strong' or 'weak'")
    t_start = time.time()
    rng = np.random.default_rng([8, int(seed)])
    name = name or "eighth-%d%s" % (seed, "" if effect is None else "-%s-%s" % (effect, size))

    # --- table
    Md = rng.uniform(8000, 16000)
    Ke = rng.uniform(0.4e6, 1.5e6)
    h = rng.uniform(0.25, 0.6)
    if effect == "nonlinear_stiffness" and size == "strong":
        h = rng.uniform(0.25, 0.35)       # short struts: the cubic term clearly visible
    p0 = rng.uniform(2e6, 8e6)
    A_s = Ke * h / (4 * p0)
    Fhd = 4 * p0 * A_s
    mu = rng.uniform(0.005, 0.02)
    Fmu = mu * (Fhd + Md * G0)
    alpha = rng.uniform(0.3, 1.0)
    zss = rng.uniform(5e-6, 60e-6)
    Mp = rng.uniform(300, 1000)
    fc = int(rng.choice([1000, 2000, 2500, 4000]))
    nsub = max(1, int(round(2000 / fc)))
    fs = int(rng.choice([200, 250, 500, 1000, 2048]))
    eff = _effect_params(rng, effect, size, dict(Ke=Ke, h=h))

    # The lab keeps its periodic tests below F_OIL_TEST_MAX x the oil-column frequency (only
    # binds for a strong oil_column effect; the broadband test still excites the resonance).
    fmax = F_OIL_TEST_MAX * eff["oil_frequency"] if effect == "oil_column" else np.inf
    tests = _draw_program(rng, effect, fc, fmax)
    per = [t for t in tests if t["kind"] != "broadband"]
    vpk = np.array([t["amplitude_m"] * 2 * np.pi * t["frequency_hz"]
                    * (1.0 if t["kind"] == "sine" else t["rho"] / np.arcsin(t["rho"])) for t in per])
    vref = float(np.median(vpk))
    visc_frac = rng.uniform(0.25, 0.5)
    Ce = visc_frac / (1 - visc_frac) * Fmu / vref ** alpha

    # --- hydraulics sizing
    Ps = rng.uniform(18e6, 28e6)
    Pr = 0.3e6
    umax = max(t["amplitude_m"] for t in per)
    amax = max(t["amplitude_m"] * (2 * np.pi * t["frequency_hz"]) ** 2 for t in per)
    mmax = Md + Mp + max(t["payload_kg"] for t in tests) + (eff or {}).get("specimen_mass", 0.0)
    Fneed = mmax * min(amax, 12.0) + 1.5 * Ke * umax + 2.5 * Fmu
    Ap = float("%.3g" % (Fneed / (0.5 * Ps)))
    f_oil_nom = rng.uniform(18, 45) if effect != "oil_column" else rng.uniform(22, 40)
    beta_nom = rng.uniform(1.0e9, 1.6e9)
    Vt = 4 * beta_nom * Ap ** 2 / ((2 * np.pi * f_oil_nom) ** 2 * (Md + Mp))
    # The cylinder must hold the programmed stroke: each chamber V0 -+ Ap u keeps at least
    # DEAD_FRAC of its mid-stroke volume (ports, manifold, hoses) at the largest programmed
    # displacement.  Without this a high drawn f_oil_nom gave V0 < Ap umax: the chamber volume
    # went through zero (oil lock -> MN forces, explicit-Euler blow-up of the pressures).
    # Where the volume is enlarged, the nominal oil-column frequency follows from it.
    stroke = max(umax, 0.04)                        # broadband commands reach 0.04 m
    Vt_min = 2 * Ap * stroke / (1 - DEAD_FRAC)
    if Vt < Vt_min:
        Vt = Vt_min
        f_oil_nom = math.sqrt(4 * beta_nom * Ap ** 2 / (Vt * (Md + Mp))) / (2 * np.pi)
        if effect == "oil_column" and eff["oil_frequency"] > 0.8 * f_oil_nom:
            eff["oil_frequency"] = 0.8 * f_oil_nom  # entrained air must lower f_oil
    f_oil = f_oil_nom if effect != "oil_column" else eff["oil_frequency"]
    beta = beta_nom * (f_oil / f_oil_nom) ** 2        # entrained air lowers the bulk modulus
    Kv = 1.6 * Ap * 0.5 / math.sqrt(0.5 * (Ps - Pr))
    Cl = rng.uniform(0.5e-12, 2e-12)
    wv = 2 * np.pi * rng.uniform(60, 200)
    zv = rng.uniform(0.6, 0.8)
    dt = 1.0 / (fc * nsub)
    Ac = np.array([[0.0, 1.0], [-wv * wv, -2 * zv * wv]])
    Bc = np.array([0.0, wv * wv])
    Mx = expm(np.block([[Ac, Bc[:, None]], [np.zeros((1, 3))]]) * dt)
    kvel = Kv * math.sqrt(0.5 * (Ps - Pr)) / Ap              # m/s per unit spool
    wh = 2 * np.pi * f_oil
    fbw = min(rng.uniform(0.12, 0.2) * f_oil, 9.0)
    Kp = 2 * np.pi * fbw / kvel
    Ki = Kp * 2 * np.pi * 0.3
    Kff = 1.0 / kvel
    # dp feedback: adds flow-pressure coefficient Kce = Kdp*Kv*sqrt(dP0)/Ps -> zeta ~ 0.3
    zeta_t = 0.3
    Kce = zeta_t * Ap / math.sqrt(beta * (Md + Mp) / Vt)
    Kdp = Kce * Ps / (Kv * math.sqrt(0.5 * (Ps - Pr)))
    P = dict(nsub=nsub, dt=dt, Phi=Mx[:2, :2], Gam=Mx[:2, 2], Ap=Ap, beta=beta, V10=Vt / 2,
             V20=Vt / 2, Ps=Ps, Pr=Pr, Kv=Kv, Cl=Cl, Mp=Mp, h=h,
             Fseal=rng.uniform(500, 2000), cseal=rng.uniform(500, 3000),
             Kp=Kp, Ki=Ki, Kff=Kff, Kdp=Kdp)

    # --- test-to-test scatter
    sc = rng.uniform(0.01, 0.04)
    sc_small = rng.uniform(0.002, 0.006)
    n_t = len(tests)
    if effect == "position_friction":
        eff["position_friction"] = eff["position_friction_fraction"] * Fmu / (umax / h) ** 2
    ratio_clean = rng.uniform(1.0, 1.03)
    per_test_truth = []
    sims = []
    for tst in tests:
        o = tst["order"]
        drift = 1.0
        if effect == "drift":
            drift = 1 - eff["drift"] * (o - 1) / max(n_t - 1, 1)
        pay = tst["payload_kg"]
        Fc = mu * (Fhd + (Md + pay) * G0) * (1 + sc * rng.normal()) * drift
        T = dict(Mdeck=Md * (1 + sc_small * rng.normal()) + pay,
                 Ke=Ke * (1 + sc_small * rng.normal()),
                 Ce=Ce * (1 + sc * rng.normal()) * drift, alpha=alpha, Fc=Fc,
                 K3=eff["cubic_stiffness"] if effect == "nonlinear_stiffness" else 0.0,
                 Fp=eff["position_friction"] if effect == "position_friction" else 0.0,
                 ms=0.0, ks=0.0, cs=0.0)
        if effect == "stiction":
            T["Fs"], T["vs"] = Fc * eff["static_ratio"], eff["stribeck_velocity"]
        else:
            T["Fs"], T["vs"] = Fc * ratio_clean, 0.005
        T["sigma0"] = Fc / zss
        T["sigma1"] = 2 * 0.4 * math.sqrt(T["sigma0"] * (T["Mdeck"] + Mp))
        if effect == "specimen":
            ms = eff["specimen_mass"]
            wsp = 2 * np.pi * eff["specimen_frequency"]
            T.update(ms=ms, ks=ms * wsp ** 2, cs=2 * eff["specimen_damping"] * ms * wsp)
        # command on the controller grid
        ntick = int(math.ceil(tst["duration"] * fc))
        tk = np.arange(ntick) / fc
        if tst["kind"] == "broadband":
            uc = _broadband_command(rng, tst["duration_s"], fc, tst["t0"], rng.uniform(0.25, 0.4),
                                    0.04, 10.0)[:ntick]
            uc = np.pad(uc, (0, ntick - uc.size))
        else:
            uc = _periodic_command(tst, tk)
        vc = np.gradient(uc, 1 / fc)
        ac = np.gradient(vc, 1 / fc)
        X, V, A, F = _simulate(P, T, uc, vc, ac)
        sims.append((tk, uc, X, V, A, F))
        tt = {k: T[k] for k in ("Mdeck", "Ke", "Ce", "alpha", "Fc", "Fs", "vs", "K3", "Fp")}
        tt.update(id=tst["id"], Me=tt.pop("Mdeck"), Fmu=tt.pop("Fc"), Fs=T["Fs"],
                  presliding_m=zss, peak_u_m=float(np.abs(X).max()),
                  peak_v_mps=float(np.abs(V).max()), peak_F_N=float(np.abs(F).max()))
        if tst["kind"] != "broadband":
            ss = (tk >= tst["t0"] + tst["n_ramp"] / tst["frequency_hz"]) & \
                 (tk <= tst["t0"] + (tst["n_ramp"] + tst["n_steady"]) / tst["frequency_hz"])
            xs = X[::nsub][:ntick]
            tt["steady_amplitude_ratio"] = float(np.ptp(xs[ss]) / np.ptp(uc[ss]))
        per_test_truth.append(tt)
        if verbose:
            print("  %s %-9s f=%s A=%s pay=%g  ampl.ratio=%s  (%.1fs)" % (
                tst["id"], tst["kind"], tst.get("frequency_hz"), tst.get("amplitude_m"), pay,
                "%.3f" % tt["steady_amplitude_ratio"] if "steady_amplitude_ratio" in tt else "-",
                time.time() - t_start))

    # --- recording
    t_sim = time.time() - t_start
    have_a = rng.random() < 2 / 3
    have_v = rng.random() < 1 / 3
    fpk = max(tt["peak_F_N"] for tt in per_test_truth)
    Frange = float(min(r for r in (2.5e5, 5e5, 1e6, 2e6, 4e6, 8e6) if r >= 1.05 * Ap * Ps)
                   if 1.05 * Ap * Ps < 8e6 else 8e6)
    rng_u, rng_a, rng_v = 0.1, 4 * G0, 1.0
    sig = dict(u=rng.uniform(2e-6, 20e-6), F=rng.uniform(0.001, 0.01) * fpk,
               a=rng.uniform(0.005, 0.05), v=rng.uniform(2e-4, 2e-3))
    off = dict(u=rng.uniform(-5e-4, 5e-4), F=rng.uniform(-0.002, 0.002) * Frange,
               a=rng.uniform(-0.03, 0.03), v=rng.uniform(-2e-3, 2e-3))
    fint = fc * nsub
    fcut = rng.uniform(0.3, 0.4) * fs
    wc = 2 * fint * np.tan(np.pi * fcut / fint)
    b_an, a_an = signal.butter(4, wc, analog=True)
    sos = signal.zpk2sos(*signal.bilinear_zpk(*signal.tf2zpk(b_an, a_an), fint))
    enbw = fcut * (np.pi / 8) / np.sin(np.pi / 8)
    white_gain = math.sqrt(2 * enbw / fint)
    hum_amp = rng.uniform(0.3, 1.0) * sig["F"]
    delay = eff["delay"] if effect == "channel_delay" else 0.0
    os.makedirs(out, exist_ok=True)
    entries = []
    for tst, (tk, uc, X, V, A, F) in zip(tests, sims):
        n = X.size
        ti = np.arange(n) / fint
        nrec = int(math.floor((ti[-1] - 0.05) * fs)) + 1
        tr = np.arange(nrec) / fs
        cols = [("t", tr)]
        chans = [("u", X, rng_u), ("F", F, Frange)]
        if have_a:
            chans.append(("a", A, rng_a))
        if have_v:
            chans.append(("v", V, rng_v))
        for key, xsig, full in chans:
            s = sig[key]
            nz = rng.normal(size=n) * (s * 0.85 / white_gain) + _pink(rng, n, fint, 0.02) * (s * 0.5)
            if key == "F":
                nz += hum_amp * np.sin(2 * np.pi * 50.0 * ti + rng.uniform(0, 2 * np.pi))
            raw = xsig + nz + off[key]
            y, _ = signal.sosfilt(sos, raw, zi=signal.sosfilt_zi(sos) * raw[0])
            tq = tr - delay if key == "F" else tr
            yr = CubicSpline(ti, y)(np.clip(tq, 0, None))
            cols.append((key, _q(yr, full)))
        cols.append(("u_cmd", CubicSpline(tk, uc)(tr)))
        hdr = ",".join(c[0] for c in cols)
        data = np.column_stack([c[1] for c in cols])
        np.savetxt(os.path.join(out, tst["file"]), data, delimiter=",", header=hdr, comments="",
                   fmt=["%.15g"] + ["%.8g"] * (len(cols) - 1))
        e = dict(id=tst["id"], file=tst["file"], kind=tst["kind"])
        if tst["kind"] != "broadband":
            e.update(frequency_hz=tst["frequency_hz"], amplitude_m=tst["amplitude_m"])
        else:
            e.update(band_hz=tst["band_hz"], duration_s=tst["duration_s"])
        e.update(payload_kg=tst["payload_kg"], order=tst["order"])
        entries.append(e)

    table = dict(
        deck_mass_kg=float(round(Md * (1 + 0.02 * rng.normal()), -1)),
        strut=dict(p0_pa=float("%.4g" % (p0 * (1 + 0.02 * rng.normal()))),
                   area_m2=float("%.4g" % A_s), h_m=float(round(h, 4)),
                   l0_m=float(round(rng.uniform(0.3, 0.6), 3)), gamma=1.4),
        oil=dict(bulk_modulus_pa=float("%.3g" % beta_nom), piston_area_m2=Ap,
                 oil_volume_m3=float("%.4g" % Vt)),
        actuator=dict(supply_pressure_pa=float("%.3g" % Ps), piston_rod_mass_kg=float(round(Mp, -1)),
                      controller_rate_hz=fc),
    )
    manifest = {"format": "sst-series/1", "name": name, "table": table, "tests": entries}
    with open(os.path.join(out, "series.json"), "w") as fh:
        json.dump(manifest, fh, indent=2)
    ep = None
    if eff is not None:
        ep = {k: float(v) for k, v in eff.items()}
    truth = dict(
        Me=Md, Ke=Ke, Ce=Ce, alpha=alpha, Fmu=Fmu, effect=effect, effect_params=ep, size=size,
        seed=int(seed), generator="eighth_generator",
        notes=("Population values: Me = deck mass without payload/specimen/piston; "
               "Fmu = mu_e (F_hd + Me g). Drift: Ce, Fmu at order 1, falling linearly by "
               "'drift' (fraction) to the last test. Per-test Fmu includes payload weight."),
        mu_e=mu, F_hd=Fhd, hold_down_N=Fhd, presliding_m=zss, static_ratio_clean=ratio_clean,
        viscous_fraction_at_median_peak_speed=visc_frac, median_peak_speed=vref,
        oil_frequency_true_hz=f_oil, oil_frequency_nominal_hz=f_oil_nom, beta_true=beta,
        piston_rod_mass=Mp, piston_area=Ap, oil_volume=Vt, supply_pressure=Ps,
        valve_frequency_hz=wv / 2 / np.pi, controller_rate_hz=fc, internal_rate_hz=fint,
        sample_rate_hz=fs, antialias_cutoff_hz=fcut, scatter=sc, scatter_small=sc_small,
        noise_rms=sig, offsets=off, hum_amplitude_N=hum_amp, channels=[c[0] for c in cols],
        loop_bandwidth_hz=fbw, tests=per_test_truth,
        sim_seconds=t_sim, total_seconds=time.time() - t_start)
    with open(os.path.join(out, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=2, default=float)
    if verbose:
        print("wrote %s: %d tests, fs=%d Hz, sim %.1fs, total %.1fs" % (
            out, len(tests), fs, t_sim, time.time() - t_start))
    return truth


def _main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--effect", default=None, choices=EFFECTS)
    ap.add_argument("--size", default="strong", choices=("strong", "weak"))
    ap.add_argument("--name", default=None)
    ap.add_argument("--verbose", action="store_true")
    a = ap.parse_args()
    generate(a.seed, a.out, effect=a.effect, size=a.size, verbose=a.verbose, name=a.name)


if __name__ == "__main__":
    _main()
