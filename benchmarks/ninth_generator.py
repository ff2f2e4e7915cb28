"""Ninth blind generator: a "virtual shaking table" written from the physics alone.

It writes one test series (format sst-series/1, see /work/shared/DATA_FORMAT.md) plus a
truth.json, for a deck modelled on the Sharif University of Technology table:

    F_A = M a + Ke u + (Ce |v|^alpha + Ff) sign(v)      (F_A: total horizontal actuator force)

Physics, as simulated at 2 kHz (= the controller rate):

* Controller (2 kHz, one sample of computational delay, zero-order hold): model following.  The
  command passes a reference model, the textbook second-order tracking response (damping
  0.6-0.8, natural frequency 10-25 Hz); the valve gets the reference's velocity, with a lead
  (reference acceleration x valve lag + delay) as feed-forward, plus a P correction
  Kv (xr - u_meas) behind a first-order filter (corner wf).  Kv and wf are tuned on a linear
  model (valve, oil, deck, Pade delay) so that the feedback loop alone has the same dominant
  pole pair.  In the clean table u/u_cmd is the reference model to within ~1 %.
  The controller reads its own LVDT sample (white noise + 16-bit quantisation).
* Servo-valve: the spool is an exact (ZOH-discretised) second-order lag at 60-150 Hz, damping
  0.6-0.8, saturating at full opening; the flow is q = vmax x sqrt(1 - sign(x) F_A/Fmax)
  (load-pressure drop over the metering edge), expressed as a piston velocity.
* Oil: the actuator force follows dF_A/dt = k_h (q - v) - F_A/tau (k_h = 2 beta A^2 / V, tau from
  the valve's flow-pressure coefficient / leakage).  In the clean table the oil column is put at
  150-250 Hz (well above the measured band: "effectively incompressible"); the `table` block
  still describes the nominal oil, whose analytic frequency is 22-35 Hz.
* Deck: mass M (deck + rigid payload), strut stiffness Ke = 4 p0 A / h, power-law damping
  Ce |v|^alpha, Coulomb friction mu_e (F_hd + M g) with a Karnopp-type stick law solved
  implicitly (backward Euler on deck and oil together): the deck stays exactly at rest while the
  net non-friction force (including the inertia needed to stop it this step) is below the static
  level; slipping friction follows a Stribeck curve Fk + (Fs - Fk) exp(-(v/vs)^2).  Clean tables
  have Fs/Fk in 1.00-1.05.  The power-law damping is implicit too (scalar Newton), so the
  recorded force obeys the balance to rounding.
* Test-to-test variation: Me, Ke, Ce, alpha and the friction vary 1-3 % (sd) from test to test,
  Ce and friction sharing part of it (temperature).  The truth is the population value.
* Sensors: a causal 4th-order Butterworth anti-alias filter at 0.4 fs on every channel, then
  sampling at fs in {200, 250, 500, 1000} Hz.  LVDT: white noise 5-20 um + 16-bit quantisation
  over +-125 mm.  Load cell: AR(1) noise (phi 0.9-0.98) + white noise, 0.3-2 % of the median
  test's peak force, an offset, 50 Hz hum on some seeds, 16-bit quantisation over +-Fmax.
  Accelerometer: white 0.02-0.05 m/s^2 + offset.  Velocity (some seeds): white 0.5-2 mm/s.
* Tests: 12-20 periodic tests (sines, 2-4 slow rounded triangles at 0.2-0.6 Hz taking speeds
  from the lower half of the campaign's), 0.2-5 Hz, 3-80 mm, peak speed
  0.02-0.4 m/s, cosine ramp-in/out of 1-3 cycles, >= 5 steady cycles, 1-2 s rest each side; a
  contiguous block of 2-4 tests carries a 2-8 t payload.  About half the seeds (always on
  oil_column) add 1-2 broadband tests (random with a flat acceleration spectrum, or a
  Kanai-Tajimi synthetic quake; up to 40 Hz, 20-40 s).  The folder is kept under ~9 MB by
  trimming the campaign (fewer cycles, shorter broadband, fewer sines, higher frequencies).

Withheld effects (one per series), each "strong" or "weak"; weak ones are sized by iteration so
that the effect force's RMS over the periodic tests' steady cycles is 0.30 x the force-noise RMS
(accepting 0.27-0.33), which can put a weak parameter outside its strong range (a sub-ms delay,
a specimen of tens of kg); strong ones start in their ranges and are scaled up until the ratio
is >= 1 (residual RMS up by >= 41 %).  The effect force is the effect's term along the simulated
trajectory (friction: the part beyond the kinetic/base level, sticking included; drift: the
dissipative force minus its undrifted value; delay: delayed minus undelayed recorded force),
through the same anti-alias filter; truth.json gives effect_rms_N and noise_rms_N (the force
noise without its offset).  The effects:
  stiction (Stribeck, static_ratio, stribeck_velocity), nonlinear_stiffness (K3 (u/h)^2 u),
  position_friction (Fp (u/h)^2 sign v, acting on static and kinetic levels), specimen (SDOF on
  the deck; its base shear only: its weight is not added to the friction normal load),
  channel_delay (force channel late by `delay`, linear interpolation on the 2 kHz grid),
  drift (Ce and friction scaled by 1 + d/2 at the first test down to 1 - d/2 at the last, so
  the truth is the campaign mean), oil_column (compressible oil: open column at 8-14 Hz with
  damping 5-10 % strong; 16-25 Hz, 15-25 % weak; the feedback gain is lowered only as far as
  needed to keep every closed-loop pole damped >= 0.7 x the column's; the feed-forward drives the
  column directly, so u/u_cmd shows its resonance; the periodic tests stay where |u/u_cmd| is
  within 7 % of 1).

    .venv/bin/python benchmarks/ninth_generator.py --seed 0 --out /tmp/ninth/clean_0
    .venv/bin/python benchmarks/ninth_generator.py --seed 10 --out /tmp/ninth/s --effect stiction
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time

import numpy as np
from scipy import linalg, optimize, signal

G = 9.81
FS_SIM = 2000.0  # controller and simulation rate, Hz
DT = 1.0 / FS_SIM
RATES = (200, 250, 500, 1000)
EFFECTS = ("stiction", "nonlinear_stiffness", "position_friction", "specimen", "channel_delay", "drift",
           "oil_column")
STROKE = 0.1
LVDT_RANGE = 0.125
BYTES_BUDGET = 8.6e6
WEAK_TARGET = 0.30


def _u(rng, lo, hi):
    return float(rng.uniform(lo, hi))


def _logu(rng, lo, hi):
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


# ----------------------------------------------------------------------------------- the table
def _draw_table(rng, rate):
    p = {}
    p["Me"] = _u(rng, 9000, 17000)
    p["Ke"] = _u(rng, 0.45e6, 1.1e6)
    p["alpha"] = _u(rng, 0.35, 0.9)
    p["mu_e"] = _u(rng, 0.008, 0.02)
    p["h"] = _u(rng, 1.0, 1.4)
    p["strut_area"] = _u(rng, 0.012, 0.03)
    p["p0"] = p["Ke"] * p["h"] / (4 * p["strut_area"])
    p["F_hd"] = 4 * p["p0"] * p["strut_area"]
    p["l0"] = _u(rng, 0.5, 0.9)
    p["gamma"] = _u(rng, 1.3, 1.42)
    p["Fmu"] = p["mu_e"] * (p["F_hd"] + p["Me"] * G)
    p["beta"] = _u(rng, 1.2e9, 1.6e9)
    p["A_p"] = _u(rng, 0.015, 0.03)
    p["f_oil_nominal"] = _u(rng, 22, 35)
    p["V"] = 2 * p["beta"] * p["A_p"] ** 2 / (p["Me"] * (2 * math.pi * p["f_oil_nominal"]) ** 2)
    p["Ps"] = 21e6
    p["Fmax"] = p["Ps"] * p["A_p"]
    p["vmax"] = _u(rng, 0.5, 0.8)
    p["f_valve"] = _u(rng, 60, 150)
    p["z_valve"] = _u(rng, 0.6, 0.8)
    p["loop_zeta_target"] = _u(rng, 0.6, 0.8)
    p["loop_fn_target"] = _u(rng, 10, min(25.0, p["f_valve"] / 4))
    p["f_h_clean"] = _u(rng, 150, 250)
    p["z_h_clean"] = _u(rng, 0.2, 0.35)
    p["static_ratio_clean"] = _u(rng, 1.0, 1.05)
    p["stribeck_v_clean"] = _u(rng, 0.002, 0.01)
    p["r_visc"] = _u(rng, 0.25, 0.6)
    p["sd"] = {k: _u(rng, 0.01, 0.03) for k in ("Me", "Ke", "Ce", "alpha", "Fmu")}
    p["sd"]["Me"] *= 0.5  # a mass varies less than a temperature-dependent coefficient
    p["common_share"] = _u(rng, 0.3, 0.7)
    p["rate"] = int(rate) if rate else int(rng.choice(RATES))
    return p


def _rounded_triangle(width):
    """Unit-amplitude rounded triangle on one period (phase grid), and its peak slope per cycle."""
    n = 8192
    ph = (np.arange(n) + 0.5) / n
    vel = np.where((ph < 0.25) | (ph >= 0.75), 1.0, -1.0)
    for c, s in ((0.25, -1.0), (0.75, 1.0)):  # raised-cosine transitions centred on the corners
        d = ph - c
        m = np.abs(d) < width / 2
        vel[m] = s * np.sin(np.pi * d[m] / width)
    x = np.concatenate([[0.0], np.cumsum(vel) / n])
    x -= 0.5 * (x.max() + x.min())
    peak = np.abs(x).max()
    x /= peak
    return x, 1.0 / peak  # per-cycle phase grid (n+1 points), peak |dx/dphase|


def _draw_tests(rng, p, effect, f_loop):
    n_per = int(rng.integers(12, 21))
    n_tri = int(rng.integers(2, 5))
    kinds = ["triangle"] * n_tri + ["sine"] * (n_per - n_tri)
    rng.shuffle(kinds)
    speeds = np.exp(np.log(0.02) + (np.arange(n_per) + rng.uniform(size=n_per)) / n_per * np.log(20))
    slow = list(rng.permutation(speeds[:n_per // 2]))  # the triangles are the slow friction runs
    tri = slow[:n_tri]
    rest = list(rng.permutation(slow[n_tri:] + list(speeds[n_per // 2:])))
    speeds = [tri.pop() if kind == "triangle" else rest.pop() for kind in kinds]
    fmax_test = min(5.0, f_loop / 2.5)  # keep the periodic tests well inside the loop's bandwidth
    tests = []
    for k, (kind, vp) in enumerate(zip(kinds, speeds)):
        vp = float(vp)
        width = _u(rng, 0.06, 0.16)
        shape_gain = _rounded_triangle(width)[1] if kind == "triangle" else 2 * math.pi
        for attempt in range(200):
            f = _logu(rng, 0.2, min(0.6, fmax_test) if kind == "triangle" else fmax_test)
            amp = vp / (shape_gain * f)
            force = p["Me"] * 1.5 * (2 * math.pi * f) ** 2 * amp + p["Ke"] * amp + 1.6 * p["Fmu"] * 1.5
            if 0.003 <= amp <= 0.08 and force < 0.5 * p["Fmax"]:
                break
            if attempt % 20 == 19:
                vp = max(0.02, vp * 0.85) if amp > 0.08 or force >= 0.5 * p["Fmax"] else min(0.4, vp * 1.15)
        n_r = int(rng.integers(1, 4)) if f > 0.5 else 1
        n_s = max(5, int(math.ceil(6 * f)))
        tests.append(dict(kind=kind, frequency_hz=round(f, 4), amplitude_m=round(amp, 5), peak_speed=vp,
                          width=width, n_ramp=n_r, n_steady=n_s, rest0=_u(rng, 1, 2), rest1=_u(rng, 1, 2),
                          payload_kg=0.0))
    # broadband tests
    n_bb = 0
    if effect == "oil_column" or rng.uniform() < 0.5:
        n_bb = int(rng.integers(1, 3))
    for k in range(n_bb):
        style = str(rng.choice(["noise", "quake"]))
        speed = _u(rng, 0.12, 0.3)
        if effect == "oil_column" and k == 0:  # the identification run: random, at full speed
            style, speed = "noise", 0.4
        tests.append(dict(kind="broadband", style=style, duration=_u(rng, 20, 40),
                          rate=int(rng.choice([1000, p["rate"]])), rest0=_u(rng, 1, 2), rest1=_u(rng, 1, 2),
                          payload_kg=0.0, peak_speed=speed, bb_seed=int(rng.integers(1 << 30))))
    # trim to the size budget
    def n_bytes():
        total = 0.0
        for t in tests:
            rate = t.get("rate", p["rate"])
            total += _duration(t) * rate * 55
        return total
    while n_bytes() > BYTES_BUDGET:
        per = [t for t in tests if t["kind"] != "broadband"]
        long = max(per, key=_duration)
        if long["n_ramp"] > 1 or long["n_steady"] > 5:
            long["n_ramp"], long["n_steady"] = 1, 5
            long["rest0"] = long["rest1"] = 1.0
            continue
        bbs = [t for t in tests if t["kind"] == "broadband" and t["duration"] > 20.5]
        if bbs:
            bbs[0]["duration"] = 20.0
            continue
        sines = [t for t in per if t["kind"] == "sine"]
        if len(per) > 12 and sines:  # drop the longest sine; the triangles stay
            tests.remove(max(sines, key=_duration))
            continue
        raise_ = [t for t in per if t["frequency_hz"] * 1.3 <= fmax_test and t["amplitude_m"] / 1.3 >= 0.003]
        if not raise_:
            break
        long = max(raise_, key=_duration)
        long["frequency_hz"] = round(long["frequency_hz"] * 1.3, 4)  # same speed, shorter test
        long["amplitude_m"] = round(long["amplitude_m"] / 1.3, 5)
    # campaign order, and a contiguous block of payload tests
    order = rng.permutation(len(tests)) + 1
    for t, o in zip(tests, order):
        t["order"] = int(o)
    tests.sort(key=lambda t: t["order"])
    per_idx = [i for i, t in enumerate(tests) if t["kind"] != "broadband"]
    n_pay = int(rng.integers(2, 5))
    start = int(rng.integers(0, len(per_idx) - n_pay + 1))
    mass = round(_u(rng, 2000, 8000), -1)
    for i in per_idx[start:start + n_pay]:
        tests[i]["payload_kg"] = mass
    counts = {"sine": 0, "triangle": 0, "broadband": 0}
    for t in tests:
        counts[t["kind"]] += 1
        t["id"] = f"{t['kind'][0].upper()}{counts[t['kind']]:02d}"
    return tests


def _duration(t):
    if t["kind"] == "broadband":
        return t["rest0"] + t["duration"] + t["rest1"]
    return t["rest0"] + (2 * t["n_ramp"] + t["n_steady"]) / t["frequency_hz"] + t["rest1"]


def _command(t, p):
    """Commanded displacement on the 2 kHz grid, and the steady window (start, stop) in s."""
    n = int(round(_duration(t) * FS_SIM)) + 1
    time_ = np.arange(n) * DT
    if t["kind"] == "broadband":
        return time_, _broadband(t, p, n), None
    f, amp = t["frequency_hz"], t["amplitude_m"]
    period = 1.0 / f
    tau = time_ - t["rest0"]
    ramp = t["n_ramp"] * period
    body = (2 * t["n_ramp"] + t["n_steady"]) * period
    env = np.ones(n)
    env[tau <= 0] = 0.0
    env[tau >= body] = 0.0
    m = (tau > 0) & (tau < ramp)
    env[m] = 0.5 * (1 - np.cos(np.pi * tau[m] / ramp))
    m = (tau > body - ramp) & (tau < body)
    env[m] = 0.5 * (1 - np.cos(np.pi * (body - tau[m]) / ramp))
    phase = np.mod(f * tau, 1.0)
    if t["kind"] == "sine":
        wave = np.sin(2 * np.pi * phase)
    else:
        grid, _ = _rounded_triangle(t["width"])
        wave = np.interp(phase, np.linspace(0, 1, len(grid)), grid)
    cmd = amp * wave * env
    return time_, cmd, (t["rest0"] + ramp, t["rest0"] + ramp + t["n_steady"] * period)


def _broadband(t, p, n):
    rng = np.random.default_rng(t["bb_seed"])
    n0, n1 = int(t["rest0"] * FS_SIM), int(t["rest1"] * FS_SIM)
    m = n - n0 - n1
    freq = np.fft.rfftfreq(m, DT)
    spec = rng.normal(size=len(freq)) + 1j * rng.normal(size=len(freq))
    w = 2 * np.pi * np.maximum(freq, 1e-3)
    if t["style"] == "quake":  # Kanai-Tajimi ground acceleration
        wg, zg = 2 * np.pi * _u(rng, 1.5, 5.0), _u(rng, 0.4, 0.7)
        r = w / wg
        acc = np.sqrt((1 + 4 * zg ** 2 * r ** 2) / ((1 - r ** 2) ** 2 + 4 * zg ** 2 * r ** 2))
    else:  # band-limited random, flat acceleration
        acc = np.ones_like(w)
    acc = acc / np.sqrt(1 + (freq / 40.0) ** 12)  # 6th-order roll-off at 40 Hz
    hp = (freq / 0.4) ** 4 / (1 + (freq / 0.4) ** 4)  # keep the displacement bounded
    disp = np.fft.irfft(spec * acc * hp / w ** 2, m)
    k = np.arange(m) * DT
    taper = min(3.0, 0.15 * t["duration"])
    env = np.clip(np.minimum(k, t["duration"] - k) / taper, 0, 1)
    disp = disp * (0.5 - 0.5 * np.cos(np.pi * env))
    disp -= np.linspace(disp[0], disp[-1], m)
    vel = np.gradient(disp, DT)
    acc_t = np.gradient(vel, DT)
    scale = min(t["peak_speed"] / np.abs(vel).max(), 0.08 / np.abs(disp).max(),
                0.3 * p["Fmax"] / (p["Me"] * np.abs(acc_t).max()))
    out = np.zeros(n)
    out[n0:n0 + m] = disp * scale
    return out


# ------------------------------------------------------------------------------ the loop design
def _char_poly(Kv, wf, p, M, kh, tau, w0=100.0):
    """Closed-loop characteristic polynomial (in s/w0) of the linearised loop."""
    s = np.poly1d([w0, 0.0])
    T = 1.5 * DT
    wv, zv = 2 * np.pi * p["f_valve"], p["z_valve"]
    c_den = s + wf
    d_num, d_den = 1 - s * (T / 2), 1 + s * (T / 2)
    v_den = s * s + 2 * zv * wv * s + wv ** 2
    p_den = (M * s * s + p["Ke"]) * (s + 1 / tau) + kh * s
    char = c_den * d_den * v_den * p_den + (Kv * wf * wv ** 2 * kh) * d_num
    return char, w0


def _poles(Kv, wf, p, M, kh, tau):
    char, w0 = _char_poly(Kv, wf, p, M, kh, tau)
    return np.roots(char.coeffs / char.coeffs[0]) * w0


def _dominant(roots):
    r = sorted(roots, key=abs)[:2]
    wn = math.sqrt(abs(r[0] * r[1]))
    zeta = float(-(r[0] + r[1]).real / (2 * wn))
    return zeta, wn


def _closed_loop_response(f, Kv, wf, p, M, kh, tau):
    """u / u_cmd of the linearised loop: reference model, velocity feed-forward, P feedback."""
    s = 2j * np.pi * np.asarray(f, float)
    wv, zv = 2 * np.pi * p["f_valve"], p["z_valve"]
    wr, zr = 2 * np.pi * p["loop_fn_target"], p["loop_zeta_target"]
    Gq = (np.exp(-1.5 * DT * s) * wv ** 2 / (s * s + 2 * zv * wv * s + wv ** 2)
          * kh / ((M * s * s + p["Ke"]) * (s + 1 / tau) + kh * s))
    L = Kv * wf / (s + wf) * Gq
    ff = s * (1 + s * _ff_lead(p))  # feed-forward: the reference's velocity and acceleration
    return wr ** 2 / (s * s + 2 * zr * wr * s + wr ** 2) * (ff * Gq + L) / (1 + L)


def _ff_lead(p):
    """Time lead of the feed-forward: computational delay + ZOH + the spool's lag."""
    return 1.5 * DT + 2 * p["z_valve"] / (2 * math.pi * p["f_valve"])


def _design_loop(p):
    kh = p["Me"] * (2 * math.pi * p["f_h_clean"]) ** 2
    tau = 1 / (2 * p["z_h_clean"] * 2 * math.pi * p["f_h_clean"])
    zt, wt = p["loop_zeta_target"], 2 * math.pi * p["loop_fn_target"]

    def resid(x):
        z, wn = _dominant(_poles(math.exp(x[0]), math.exp(x[1]), p, p["Me"], kh, tau))
        return [z - zt, math.log(wn / wt)]

    x0 = [math.log(wt / (2 * zt)), math.log(2 * zt * wt)]
    sol = optimize.least_squares(resid, x0, xtol=1e-10)
    Kv, wf = math.exp(sol.x[0]), math.exp(sol.x[1])
    z, wn = _dominant(_poles(Kv, wf, p, p["Me"], kh, tau))
    return dict(Kv=Kv, wf=wf, kh=kh, tau=tau, zeta=z, fn=wn / (2 * math.pi), gain_scale=1.0)


def _detune(loop, p, kh, tau, zmin):
    """Lower the loop gain until every closed-loop pole is damped at least zmin."""
    def worst(g):
        r = _poles(loop["Kv"] * g, loop["wf"], p, p["Me"], kh, tau)
        r = r[np.abs(r) > 1e-6]
        return float(np.min(-r.real / np.abs(r)))
    g = 1.0
    if worst(1.0) < zmin:
        lo, hi = 1e-3, 1.0
        for _ in range(40):
            mid = math.sqrt(lo * hi)
            lo, hi = (mid, hi) if worst(mid) >= zmin else (lo, mid)
        g = lo
    out = dict(loop, Kv=loop["Kv"] * g, kh=kh, tau=tau, gain_scale=g)
    z, wn = _dominant(_poles(out["Kv"], out["wf"], p, p["Me"], kh, tau))
    out.update(zeta=z, fn=wn / (2 * math.pi), worst_pole_damping=worst(g))
    return out


# ------------------------------------------------------------------------------- the simulation
def _spool_matrices(p, f=None, z=None):
    """Exact ZOH discretisation of a unit-gain second-order lag (the spool; the reference model)."""
    wv, zv = 2 * math.pi * (f or p["f_valve"]), (z or p["z_valve"])
    a = np.array([[0, 1, 0], [-wv ** 2, -2 * zv * wv, wv ** 2], [0, 0, 0]]) * DT
    e = linalg.expm(a)
    return [float(x) for x in (e[0, 0], e[0, 1], e[0, 2], e[1, 0], e[1, 1], e[1, 2])]


def _simulate(cmd, c, p, loop, spool, ctrl_noise, ref):
    """One test on the 2 kHz grid. c: this test's coefficients. Returns arrays."""
    n = len(cmd)
    exp, sqrt = math.exp, math.sqrt
    M, Ke, Ce, al, Fk, Fs, vs = c["M"], c["Ke"], c["Ce"], c["alpha"], c["Fk"], c["Fs"], c["vs"]
    K3c, Fpc = c.get("K3c", 0.0), c.get("Fpc", 0.0)
    ms = c.get("ms", 0.0)
    ks = ms * c.get("ws", 0.0) ** 2
    cs = 2 * c.get("zs", 0.0) * ms * c.get("ws", 0.0)
    kh, tau = c["kh"], c["tau"]
    Kv, af = loop["Kv"], 1 - math.exp(-loop["wf"] * DT)
    vmax, Fmax = p["vmax"], p["Fmax"]
    s00, s01, s0u, s10, s11, s1u = spool
    r00, r01, r0u, r10, r11, r1u = ref
    xr = vr = 0.0
    wr, zr, lead = 2 * math.pi * p["loop_fn_target"], p["loop_zeta_target"], _ff_lead(p)
    c1 = 1 / (1 + DT / tau)
    kdt = c1 * DT * kh
    Mdt = M / DT
    ia = 1 / al
    lsb = 2 * LVDT_RANGE / 65536
    U = [0.0] * n; V = [0.0] * n; A = [0.0] * n; F = [0.0] * n; FF = [0.0] * n; FD = [0.0] * n; FS = [0.0] * n
    u = v = Fa = 0.0
    xs = xsd = qd = 0.0
    x_next = 0.0
    z = zd = 0.0
    dFs = Fs - Fk
    for i in range(1, n):
        xc = x_next
        xs, xsd = s00 * xs + s01 * xsd + s0u * xc, s10 * xs + s11 * xsd + s1u * xc
        xo = 1.0 if xs > 1.0 else (-1.0 if xs < -1.0 else xs)
        # flow through the metering edge, linearised in the new force (implicit: the
        # flow-pressure coefficient is stiff against the oil column)
        sr = sqrt(max(1.0 - Fa / Fmax if xo > 0 else 1.0 + Fa / Fmax, 0.0025))
        q = vmax * xo * sr
        gq = -vmax * (xo if xo > 0 else -xo) / (2 * Fmax * sr)  # dq/dF_A <= 0
        c2 = 1.0 / (1.0 - kdt * gq)
        Fpart = c2 * (c1 * Fa + kdt * (q - gq * Fa))  # F_A' = Fpart - kk v'
        kk = c2 * kdt
        fsp = ks * z + cs * zd if ms else 0.0
        u2 = u * u
        D = Mdt + kk + DT * (Ke + 3 * K3c * u2)
        S = Mdt * v + Fpart - Ke * u - K3c * u2 * u + fsp
        av = v if v >= 0 else -v
        flim = Fk + (dFs * exp(-(av / vs) ** 2) if dFs else 0.0) + Fpc * u2
        if -flim <= S <= flim:
            vn, ff, fd = 0.0, S, 0.0
        else:
            sg = 1.0 if S > 0 else -1.0
            R = sg * S - flim
            y = min(R / Ce, (R / D) ** al)
            for _ in range(40):
                yi = y ** ia
                g = D * yi + Ce * y - R
                if g <= 1e-9 * R:
                    break
                y -= g / (D * ia * yi / y + Ce)
                if y <= 0:
                    y = 1e-300
                    break
            x = y ** ia
            vn, ff, fd = sg * x, sg * flim, sg * Ce * y
        Fa = Fpart - kk * vn
        acc = (vn - v) * FS_SIM
        u += DT * vn
        v = vn
        if ms:
            zd += DT * (-acc - fsp / ms)
            z += DT * zd
        U[i] = u; V[i] = v; A[i] = acc; F[i] = Fa; FF[i] = ff; FD[i] = fd; FS[i] = fsp
        um = round((u + ctrl_noise[i]) / lsb) * lsb
        xr, vr = r00 * xr + r01 * vr + r0u * cmd[i], r10 * xr + r11 * vr + r1u * cmd[i]
        qd += af * (Kv * (xr - um) - qd)
        ar = wr * wr * (cmd[i] - xr) - 2 * zr * wr * vr
        x_next = (vr + lead * ar + qd) / vmax  # feed-forward from the reference model + P feedback
    out = {k: np.asarray(x) for k, x in (("u", U), ("v", V), ("a", A), ("F", F), ("Ff", FF), ("Fd", FD),
                                          ("Fsp", FS))}
    return out


def _test_coefficients(rng, p, t, eff, n_tests):
    sd = p["sd"]
    common = rng.normal()
    share = p["common_share"]
    kCe = 1 + sd["Ce"] * (math.sqrt(share) * common + math.sqrt(1 - share) * rng.normal())
    kF = 1 + sd["Fmu"] * (math.sqrt(share) * common + math.sqrt(1 - share) * rng.normal())
    c = dict(Me=p["Me"] * (1 + sd["Me"] * rng.normal()), Ke=p["Ke"] * (1 + sd["Ke"] * rng.normal()),
             Ce=p["Ce"] * kCe, alpha=p["alpha"] * (1 + sd["alpha"] * rng.normal()),
             mu=p["mu_e"] * kF)
    c["M"] = c["Me"] + t["payload_kg"]
    c["Fk"] = c["mu"] * (p["F_hd"] + c["M"] * G)
    name = eff["name"]
    drift = 1.0
    if name == "drift":
        drift = 1 + eff["drift"] * (0.5 - (t["order"] - 1) / max(n_tests - 1, 1))
        c["Ce"] *= drift
        c["Fk"] *= drift
    c["drift_factor"] = drift
    ratio, vs = p["static_ratio_clean"], p["stribeck_v_clean"]
    if name == "stiction":
        ratio, vs = eff["static_ratio"], eff["stribeck_velocity"]
    c["Fs"], c["vs"] = ratio * c["Fk"], vs
    if name == "nonlinear_stiffness":
        c["K3c"] = eff["cubic_stiffness"] / p["h"] ** 2
    if name == "position_friction":
        c["Fpc"] = eff["position_friction"] / p["h"] ** 2
    if name == "specimen":
        c["ms"], c["ws"], c["zs"] = eff["specimen_mass"], 2 * math.pi * eff["specimen_frequency"], eff["specimen_damping"]
    c["kh"], c["tau"] = eff["kh"], eff["tau"]  # oil: the column's stiffness is fixed, a payload lowers its frequency
    return c


def _effect_force(sim, c, eff):
    """The effect's contribution to the actuator force on the 2 kHz grid (before the delay)."""
    name = eff["name"]
    if name == "stiction":
        ff = sim["Ff"]
        return ff - np.sign(ff) * np.minimum(np.abs(ff), c["Fk"])
    if name == "position_friction":
        ff = sim["Ff"]
        vold = np.abs(np.concatenate([[0.0], sim["v"][:-1]]))
        base = c["Fk"] + (c["Fs"] - c["Fk"]) * np.exp(-(vold / c["vs"]) ** 2)
        return ff - np.sign(ff) * np.minimum(np.abs(ff), base)
    if name == "nonlinear_stiffness":
        u = sim["u"]
        uo = np.concatenate([[0.0], u[:-1]])
        return c["K3c"] * (uo ** 3 + 3 * uo ** 2 * (u - uo))
    if name == "specimen":
        return -sim["Fsp"]
    if name == "drift":
        return (1 - 1 / c["drift_factor"]) * (sim["Ff"] + sim["Fd"])
    return np.zeros_like(sim["u"])


def _longest_run(mask):
    if not mask.any():
        return 0
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return int(np.max(edges[1::2] - edges[::2]))


def _delayed(x, d):
    if d <= 0:
        return x
    tt = np.arange(len(x)) * DT
    return np.interp(tt - d, tt, x, left=x[0])


# ----------------------------------------------------------------------------------- the sensors
def _draw_sensors(rng, p):
    return dict(sig_u=_u(rng, 5e-6, 20e-6), frac_F=_u(rng, 0.003, 0.02), phi=_u(rng, 0.9, 0.98),
                white_share=_u(rng, 0.25, 0.5), offset_F=_u(rng, -1, 1), hum=bool(rng.uniform() < 0.5),
                hum_share=_u(rng, 0.2, 0.5), sig_a=_u(rng, 0.02, 0.05), offset_a=_u(rng, -0.02, 0.02),
                with_v=bool(rng.uniform() < 0.4), sig_v=_u(rng, 0.5e-3, 2e-3), offset_u=_u(rng, -50e-6, 50e-6))


def _aa(x, rate):
    sos = signal.butter(4, 0.4 * rate / (FS_SIM / 2), output="sos")
    return signal.sosfilt(sos, x)


def _record(sim, cmd, eff_force, t, p, sens, seed, k, sdF):
    """Sampled channels; also the recorded effect force and the force noise."""
    rate = t.get("rate", p["rate"])
    step = int(round(FS_SIM / rate))
    idx = np.arange(0, len(cmd), step)
    rng = np.random.default_rng([seed, 77, k])
    n = len(idx)
    delay = eff_force.get("delay", 0.0)
    Fd = _delayed(sim["F"], delay)
    rec = {"t": idx * DT, "u_cmd": cmd[idx]}
    lsb_u = 2 * LVDT_RANGE / 65536
    u = _aa(sim["u"], rate)[idx] + sens["offset_u"] + sens["sig_u"] * rng.normal(size=n)
    rec["u"] = np.round(u / lsb_u) * lsb_u
    sd_col = sdF / math.sqrt(1 + sens["white_share"] ** 2 + (sens["hum_share"] ** 2 if sens["hum"] else 0))
    phi = sens["phi"]
    e = rng.normal(size=n) * sd_col * math.sqrt(1 - phi ** 2)
    ar = signal.lfilter([1.0], [1.0, -phi], e, zi=[rng.normal() * sd_col * phi])[0]
    noise = ar + sens["white_share"] * sd_col * rng.normal(size=n)
    if sens["hum"]:
        noise += sens["hum_share"] * sd_col * math.sqrt(2) * np.sin(2 * np.pi * 50 * rec["t"] + rng.uniform(0, 6.3))
    lsb_F = 2 * p["Fmax"] / 65536
    Fclean = _aa(Fd, rate)[idx]
    rec["F"] = np.round((Fclean + noise + sens["offset_F"] * 0.002 * p["Fmax"]) / lsb_F) * lsb_F
    rec["a"] = _aa(sim["a"], rate)[idx] + sens["offset_a"] + sens["sig_a"] * rng.normal(size=n)
    if sens["with_v"]:
        rec["v"] = _aa(sim["v"], rate)[idx] + sens["sig_v"] * rng.normal(size=n)
    eff = _aa(eff_force["force"], rate)[idx]
    if delay > 0:
        eff = eff + Fclean - _aa(sim["F"], rate)[idx]
    truth = {"u": _aa(sim["u"], rate)[idx], "v": _aa(sim["v"], rate)[idx], "a": _aa(sim["a"], rate)[idx],
             "F": _aa(sim["F"], rate)[idx]}
    return rec, noise, eff, truth


# --------------------------------------------------------------------------------- the effects
def _draw_effect(rng, effect, size, p, tests):
    eff = {"name": effect, "size": size}
    kh = p["Me"] * (2 * math.pi * p["f_h_clean"]) ** 2
    tau = 1 / (2 * p["z_h_clean"] * 2 * math.pi * p["f_h_clean"])
    umax = max(t["amplitude_m"] for t in tests if t["kind"] != "broadband")
    strong = size == "strong"
    if effect == "stiction":
        eff["static_ratio"] = _u(rng, 1.3, 1.6) if strong else 1.1
        eff["stribeck_velocity"] = _u(rng, 0.003, 0.02)
    elif effect == "nonlinear_stiffness":
        frac = _u(rng, 0.2, 0.5) if strong else 0.03
        eff["cubic_stiffness"] = frac * p["Ke"] * (p["h"] / umax) ** 2
        eff["h"] = p["h"]
    elif effect == "position_friction":
        frac = _u(rng, 0.3, 0.8) if strong else 0.05
        eff["position_friction"] = frac * p["Fmu"] * (p["h"] / umax) ** 2
        eff["h"] = p["h"]
    elif effect == "specimen":
        eff["specimen_mass"] = _u(rng, 1500, 4000) if strong else 500.0
        eff["specimen_frequency"] = _u(rng, 3, 20)
        eff["specimen_damping"] = _u(rng, 0.02, 0.05)
    elif effect == "channel_delay":
        eff["delay"] = _u(rng, 0.004, 0.015) if strong else 0.001
    elif effect == "drift":
        eff["drift"] = _u(rng, 0.15, 0.3) if strong else 0.05
    elif effect == "oil_column":
        return eff  # drawn by _draw_oil, before the tests
    eff["kh"], eff["tau"] = kh, tau
    return eff


def _draw_oil(rng, size, p, loop):
    """Compressible oil: the open column (empty deck) at f with damping z (valve flow-pressure
    coefficient, leakage); strong 8-14 Hz, 5-10 %; weak 16-25 Hz, 15-25 %."""
    if size == "strong":
        f, z = _u(rng, 8, 14), _u(rng, 0.05, 0.10)
    else:
        f, z = _u(rng, 16, 25), _u(rng, 0.15, 0.25)
    w = 2 * math.pi * f
    return {"oil_frequency": f, "oil_damping": z, "kh": p["Me"] * w ** 2, "tau": 1 / (2 * z * w)}


SIZE_KEY = {"stiction": "static_ratio", "nonlinear_stiffness": "cubic_stiffness",
            "position_friction": "position_friction", "specimen": "specimen_mass", "channel_delay": "delay",
            "drift": "drift"}


def _rescale(eff, factor):
    key = SIZE_KEY[eff["name"]]
    if key == "static_ratio":
        eff[key] = 1 + (eff[key] - 1) * factor
    else:
        eff[key] *= factor


# ------------------------------------------------------------------------------------- generate
def _run(seed, p, tests, eff, loop, spool, sens, which, sdF=None):
    n_tests = len(tests)
    sims = {}
    for k in which:
        t = tests[k]
        _, cmd, win = _command(t, p)
        c = _test_coefficients(np.random.default_rng([seed, 55, k]), p, t, eff, n_tests)
        noise = np.random.default_rng([seed, 66, k]).normal(size=len(cmd)) * sens["sig_u"]
        sim = _simulate(cmd, c, p, loop, spool, noise, loop["ref"])
        if win is not None:  # share of the steady cycles with the deck stuck (exactly v = 0)
            m = slice(int(win[0] * FS_SIM), int(win[1] * FS_SIM))
            c["stuck_fraction"] = float(np.mean(sim["v"][m] == 0.0))
            c["longest_stick_s"] = float(_longest_run(sim["v"][m] == 0.0) * DT)
        delay = eff["delay"] if eff["name"] == "channel_delay" else 0.0
        ef = {"force": _effect_force(sim, c, eff), "delay": delay}
        sims[k] = (cmd, win, c, sim, ef)
    if sdF is None:
        peaks = [np.abs(sims[k][3]["F"]).max() for k in which if tests[k]["kind"] != "broadband"]
        sdF = sens["frac_F"] * float(np.median(peaks))
    recs, e2, n2, cnt = {}, 0.0, 0.0, 0
    for k in which:
        cmd, win, c, sim, ef = sims[k]
        rec, noise, eff_rec, truth = _record(sim, cmd, ef, tests[k], p, sens, seed, k, sdF)
        recs[k] = (rec, truth, win, c)
        if win is not None:
            m = (rec["t"] >= win[0]) & (rec["t"] <= win[1])
            e2 += float(np.sum(eff_rec[m] ** 2))
            n2 += float(np.sum(noise[m] ** 2))
            cnt += int(m.sum())
    return recs, sdF, math.sqrt(e2 / cnt) if cnt else 0.0, math.sqrt(n2 / cnt) if cnt else 0.0


def _setup(seed, effect, size, rate):
    """Draw the table, the loop, the campaign, the sensors and the effect from the seed."""
    p = _draw_table(np.random.default_rng([seed, 1]), rate)
    loop = _design_loop(p)
    if effect == "oil_column":  # the lab lowered the feedback gain until the loop was damped again
        oil = _draw_oil(np.random.default_rng([seed, 5]), size, p, loop)
        loop = _detune(loop, p, oil["kh"], oil["tau"], 0.7 * oil["oil_damping"])
    ff = np.linspace(0.05, 20, 800)  # periodic tests only where |u/u_cmd| stays within 7 % of 1
    H = np.abs(_closed_loop_response(ff, loop["Kv"], loop["wf"], p, p["Me"], loop["kh"], loop["tau"]))
    f_ok = ff[np.argmax(np.abs(H - 1) > 0.07)] if np.any(np.abs(H - 1) > 0.07) else 20.0
    loop["f_track"] = float(min(loop["fn"] / 2.5, f_ok))
    tests = _draw_tests(np.random.default_rng([seed, 2]), p, effect, loop["f_track"] * 2.5)
    per = [t for t in tests if t["kind"] != "broadband"]
    p["v_median"] = float(np.median([t["peak_speed"] for t in per]))
    p["Ce"] = p["r_visc"] * p["Fmu"] / p["v_median"] ** p["alpha"]
    sens = _draw_sensors(np.random.default_rng([seed, 3]), p)
    eff = _draw_effect(np.random.default_rng([seed, 4]), effect, size, p, tests)
    if effect == "oil_column":
        eff.update(oil)
    spool = _spool_matrices(p)
    loop["ref"] = _spool_matrices(p, p["loop_fn_target"], p["loop_zeta_target"])
    return p, tests, sens, eff, loop, spool


def generate(seed, out_dir, verbose=False, effect=None, size=None, name=None, rate=None):
    """Write one test series (series.json, CSVs, truth.json) into out_dir; returns the truth dict."""
    started = time.perf_counter()
    if effect is not None and effect not in EFFECTS:
        raise ValueError(f"unknown effect {effect!r}; one of {EFFECTS}")
    size = (size or "strong") if effect else None
    p, tests, sens, eff, loop, spool = _setup(seed, effect, size, rate)
    periodic = [k for k, t in enumerate(tests) if t["kind"] != "broadband"]
    history = []
    for it in range(6):
        recs, sdF, e_rms, n_rms = _run(seed, p, tests, eff, loop, spool, sens, periodic)
        ratio = e_rms / n_rms
        history.append((dict((k, eff[k]) for k in eff if k in SIZE_KEY.values()), ratio))
        if effect is None or effect == "oil_column":
            break
        if size == "weak":
            if 0.27 <= ratio <= 0.33:
                break
            _rescale(eff, WEAK_TARGET / max(ratio, 1e-6))
        else:
            if ratio >= 1.0:
                break
            if effect == "stiction" and eff["stribeck_velocity"] < 0.02:
                eff["stribeck_velocity"] = min(0.02, eff["stribeck_velocity"] * 1.2 / max(ratio, 0.2))
            elif effect == "stiction":
                eff["static_ratio"] = min(1.6, 1 + (eff["static_ratio"] - 1) * 1.2 / max(ratio, 0.2))
                if eff["static_ratio"] >= 1.6:
                    break
            else:
                _rescale(eff, 1.2 / max(ratio, 0.2))
        if verbose:
            print(f"  sizing {effect} {size}: ratio {ratio:.3f}, {history[-1][0]}", flush=True)
    bb = [k for k, t in enumerate(tests) if t["kind"] == "broadband"]
    if bb:
        recs.update(_run(seed, p, tests, eff, loop, spool, sens, bb, sdF)[0])

    os.makedirs(out_dir, exist_ok=True)
    manifest_tests, per_test = [], []
    for k, t in enumerate(tests):
        rec, truth_sig, win, c = recs[k]
        cols = ["t", "u", "F", "a", "u_cmd"] + (["v"] if "v" in rec else [])
        fmts = {"t": "%.4f", "u": "%.7f", "F": "%.1f", "a": "%.4f", "u_cmd": "%.7f", "v": "%.5f"}
        data = np.column_stack([rec[col] for col in cols])
        np.savetxt(os.path.join(out_dir, f"{t['id']}.csv"), data, fmt=[fmts[col] for col in cols],
                   delimiter=",", header=",".join(cols), comments="")
        entry = {"id": t["id"], "file": f"{t['id']}.csv", "kind": t["kind"]}
        if t["kind"] != "broadband":
            entry.update(frequency_hz=t["frequency_hz"], amplitude_m=t["amplitude_m"])
        entry.update(payload_kg=t["payload_kg"], order=t["order"])
        manifest_tests.append(entry)
        info = {"id": t["id"], "rate_hz": t.get("rate", p["rate"]),
                **{k2: c[k2] for k2 in ("Me", "Ke", "Ce", "alpha", "Fk", "Fs", "M")}}
        if win is not None:
            m = (rec["t"] >= win[0]) & (rec["t"] <= win[1])
            info["steady_window_s"] = list(win)
            info["steady_amplitude_ratio"] = float(np.ptp(truth_sig["u"][m]) / np.ptp(rec["u_cmd"][m]))
            info["peak_speed"] = float(np.abs(truth_sig["v"][m]).max())
            info["stuck_fraction"] = c["stuck_fraction"]
            info["longest_stick_s"] = c["longest_stick_s"]
        if effect == "drift":
            info["drift_factor"] = c["drift_factor"]
        per_test.append(info)
    table = {"deck_mass_kg": round(p["Me"], 1),
             "strut": {"p0_pa": round(p["p0"], 1), "area_m2": round(p["strut_area"], 6), "h_m": round(p["h"], 4),
                       "l0_m": round(p["l0"], 4), "gamma": round(p["gamma"], 3)},
             "oil": {"bulk_modulus_pa": round(p["beta"], -5), "piston_area_m2": round(p["A_p"], 6),
                     "oil_volume_m3": float(f"{p['V']:.5g}")}}
    manifest = {"format": "sst-series/1", "name": name or f"ninth-seed{seed}", "table": table,
                "tests": manifest_tests}
    with open(os.path.join(out_dir, "series.json"), "w") as fh:
        json.dump(manifest, fh, indent=1)
    params = None
    if effect:
        keys = {"stiction": ("static_ratio", "stribeck_velocity"), "nonlinear_stiffness": ("cubic_stiffness", "h"),
                "position_friction": ("position_friction", "h"),
                "specimen": ("specimen_mass", "specimen_frequency", "specimen_damping"),
                "channel_delay": ("delay",), "drift": ("drift",), "oil_column": ("oil_frequency",)}[effect]
        params = {k2: float(eff[k2]) for k2 in keys}
    oil_kh = eff["kh"]
    truth = {"Me": p["Me"], "Ke": p["Ke"], "Ce": p["Ce"], "alpha": p["alpha"], "Fmu": p["Fmu"], "mu_e": p["mu_e"],
             "F_hd": p["F_hd"], "effect": effect, "effect_params": params, "size": size, "seed": seed,
             "sample_rate_hz": p["rate"], "noise_rms_N": n_rms, "effect_rms_N": e_rms,
             "effect_to_noise": ratio if effect != "oil_column" else None,
             "residual_rms_raise": math.sqrt(1 + ratio ** 2) - 1 if effect != "oil_column" else None,
             "sizing_history": history,
             "force_noise_sd_N": sdF,
             "oil_damping": eff.get("oil_damping"),
             "oil_frequency_analytic_hz": p["f_oil_nominal"],
             "oil_frequency_simulated_hz": math.sqrt(oil_kh / p["Me"]) / (2 * math.pi),
             "static_ratio": eff.get("static_ratio", p["static_ratio_clean"]),
             "stribeck_velocity": eff.get("stribeck_velocity", p["stribeck_v_clean"]),
             "loop": {"Kv_per_s": loop["Kv"], "filter_hz": loop["wf"] / (2 * math.pi),
                      "zeta": p["loop_zeta_target"], "fn_hz": p["loop_fn_target"],
                      "feedback_zeta": loop["zeta"], "feedback_fn_hz": loop["fn"], "f_track_hz": loop["f_track"],
                      "gain_scale": loop["gain_scale"], "controller_hz": FS_SIM,
                      "valve_hz": p["f_valve"], "valve_zeta": p["z_valve"], "vmax": p["vmax"], "Fmax_N": p["Fmax"]},
             "variation_sd": p["sd"], "common_share_Ce_Fmu": p["common_share"], "viscous_share_at_median": p["r_visc"],
             "median_peak_speed": p["v_median"], "sensors": sens, "tests": per_test,
             "generator": "ninth_generator", "seconds": round(time.perf_counter() - started, 1)}
    if effect == "oil_column":
        truth["note"] = "oil_column changes the motion, not the force balance: effect_rms_N is 0 by construction"
    with open(os.path.join(out_dir, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=1, default=float)
    if verbose:
        print(f"{out_dir}: {len(tests)} tests, {p['rate']} Hz, effect {effect} {size}, ratio {ratio:.3f}, "
              f"{truth['seconds']} s", flush=True)
    return truth


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", required=True)
    parser.add_argument("--effect", default=None, choices=EFFECTS)
    parser.add_argument("--size", default=None, choices=("strong", "weak"))
    parser.add_argument("--rate", type=int, default=None, choices=RATES)
    parser.add_argument("--name", default=None)
    args = parser.parse_args()
    generate(args.seed, args.out, verbose=True, effect=args.effect, size=args.size, name=args.name, rate=args.rate)


if __name__ == "__main__":
    main()
