#!/usr/bin/env python
"""A second independent simulator of a servo-hydraulic 1-DOF shaking table (LuGre friction).

Written on 2026-11-26 by a helper session that was given only the data format and the
physics, not this package's code, as a blind check (the first such check is
independent_generator.py). It differs from the virtual table and from that generator in its
friction (LuGre bristles: pre-sliding, Stribeck peak, genuine sticking), its loop (orifice-law
valve, PI + velocity feed-forward), its recording (block-averaged samples, u quantised) and its
sensors (AR(1) drift on a and F besides white noise). tests/test_fit.py fits one of its series.

Writes an "sst-series/1" folder (series.json + one CSV per test) plus truth.json.

    python benchmarks/lugre_generator.py --seed N --out DIR [--effect NAME] [--rate HZ] [--size strong|weak|random]

Effects: stiction, nonlinear_stiffness (cubic), position_friction (hinge), specimen,
channel_delay (delay), drift.   See README.txt for the physics.
"""
import argparse
import json
import os

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.signal import lfilter

G = 9.81
RATES = (200, 256, 500, 1000)
# internal rate = record rate * decimation (8000 or 8192 Hz)
DECIM = {200: 40, 256: 32, 500: 16, 1000: 8}
EFFECT_ALIAS = {"cubic": "nonlinear_stiffness", "hinge": "position_friction",
                "delay": "channel_delay"}
EFFECTS = ("stiction", "nonlinear_stiffness", "position_friction", "specimen",
           "channel_delay", "drift")
EPS_V = 5e-5  # m/s, regularisation of |v|^alpha at v = 0 (slope cap)


# ----------------------------------------------------------------------------- plan
def make_plan(rng, n_tests, allow_payload):
    """Stratified test plan: log-spread frequencies, feasible amplitudes."""
    lf = np.linspace(np.log(0.2), np.log(4.0), n_tests)
    lf = lf + rng.uniform(-0.5, 0.5, n_tests) * (lf[1] - lf[0])
    freqs = np.clip(np.exp(lf), 0.2, 4.0)
    tri_idx = set(rng.choice(n_tests, size=max(2, n_tests // 5), replace=False).tolist())
    big_idx = int(rng.integers(0, max(1, n_tests // 4)))  # one low-f test at ~100 mm
    tests = []
    for i, f in enumerate(freqs):
        f = float(np.round(f, 3))
        kind = "triangle" if i in tri_idx else "sine"
        vfac = 4.0 if kind == "triangle" else 2 * np.pi
        a_max = min(0.100, 0.40 / (vfac * f))
        a_min = min(max(0.005, 0.015 / (vfac * f)), a_max)
        if i == big_idx:
            amp = a_max
        else:
            amp = np.exp(rng.uniform(np.log(a_min), np.log(a_max)))
        amp = float(np.round(amp, 4))
        n_st = int(max(5, min(int(rng.integers(5, 16)), np.floor(30.0 * f))))
        n_in = 2 if f < 0.5 else int(rng.integers(2, 4))
        n_out = 1.5 if f < 0.5 else 2
        payload = 0.0
        if allow_payload and rng.random() < 0.25:
            payload = float(rng.choice([1000.0, 2000.0, 3000.0, 5000.0]))
        tests.append(dict(kind=kind, frequency_hz=f, amplitude_m=amp, payload_kg=payload,
                          n_in=n_in, n_steady=n_st, n_out=n_out))
    order = rng.permutation(n_tests) + 1
    for t, o in zip(tests, order):
        t["order"] = int(o)
    # ids follow campaign order
    tests.sort(key=lambda t: t["order"])
    for t in tests:
        t["id"] = "T%02d" % t["order"]
        t["file"] = t["id"] + ".csv"
    return tests


def command(tests, t):
    """Commanded displacement on time grid t (nt,), returns (nt, n) arrays u_cmd, v_cmd."""
    nt, n = len(t), len(tests)
    dt = t[1] - t[0]
    uc = np.zeros((nt, n))
    for j, ts in enumerate(tests):
        f, A = ts["frequency_hz"], ts["amplitude_m"]
        t0 = ts["t0"]
        tin, tst, tout = ts["n_in"] / f, ts["n_steady"] / f, ts["n_out"] / f
        tp = t - t0
        env = np.zeros(nt)
        m = (tp >= 0) & (tp < tin)
        env[m] = 0.5 * (1 - np.cos(np.pi * tp[m] / tin))
        m = (tp >= tin) & (tp < tin + tst)
        env[m] = 1.0
        m = (tp >= tin + tst) & (tp < tin + tst + tout)
        env[m] = 0.5 * (1 + np.cos(np.pi * (tp[m] - tin - tst) / tout))
        ph = 2 * np.pi * f * tp
        if ts["kind"] == "sine":
            w = np.sin(ph)
        else:
            w = (2 / np.pi) * np.arcsin(np.clip(np.sin(ph), -1, 1))
            # round the corners: two passes of a moving average of 3 % of the period
            win = max(3, int(round(0.03 / f / dt)) | 1)
            w = uniform_filter1d(uniform_filter1d(w, win, mode="nearest"), win, mode="nearest")
        uc[:, j] = A * env * w
    vc = np.gradient(uc, dt, axis=0)
    return uc, vc


# ----------------------------------------------------------------------------- core
def simulate(p, uc, vc, dt, store_v=False):
    """Vectorised closed-loop simulation, all tests at once.

    p: dict of (n,) arrays; uc, vc: (nt, n) command.  Returns dict of (nt, n) arrays.
    """
    nt, n = uc.shape
    z0 = np.zeros(n)
    u, v, z, pL, xv, ie, ys, yv = (z0.copy() for _ in range(8))
    U = np.empty((nt, n)); FA = np.empty((nt, n)); AC = np.empty((nt, n))
    V = np.empty((nt, n)) if store_v else None
    A = p["A"]; Ps = p["Ps"]; invPs = 1.0 / Ps; Kq = p["Kq"]
    ch = dt * 4.0 * p["beta"] / p["Vt"]; den = 1.0 + ch * p["Kc"]
    av = 1.0 - np.exp(-dt / p["tau_v"])
    Kp, Ki, Kff = p["Kp"], p["Ki"], p["Kff"]
    invM = 1.0 / p["M"]
    Ke, K3, Ce = p["Ke"], p["K3"], p["Ce"]
    hexp = 0.5 * (p["alpha"] - 1.0)
    Fc, dF, ivs2, ch2 = p["Fc"], p["Fs"] - p["Fc"], 1.0 / p["vs"] ** 2, p["ch_h2"]
    s0, s1 = p["sigma0"], p["sigma1"]
    is0 = 1.0 / s0
    idt = 1.0 / dt
    eps2 = EPS_V ** 2
    cubic = bool(np.any(K3 != 0)); hinge = bool(np.any(ch2 != 0))
    spec = bool(np.any(p["ms"] > 0))
    if spec:
        ks, cs = p["ks"], p["cs"]
        invms = 1.0 / np.where(p["ms"] > 0, p["ms"], 1.0)
    ff = Kff * vc                                  # velocity feed-forward, precomputed
    mKi = Ki * dt
    pdec = 1.0 / den
    chd = ch / den
    nS0dt = -s0 * dt
    s1idt = s1 * idt
    nivs2 = -ivs2
    Kqs = Kq * np.sqrt(1.0)  # flow gain at full spool, no load
    mx, mn, mul, sgn, ex = np.maximum, np.minimum, np.multiply, np.sign, np.exp
    for k in range(nt):
        # state at the start of the step is what the sensors see
        U[k] = u
        if store_v:
            V[k] = v
        # controller: P + I + velocity feed-forward, spool command clipped to +-1
        e = uc[k] - u
        ie += e * mKi
        xc = Kp * e + ie + ff[k]
        mx(xc, -1.0, out=xc)
        mn(xc, 1.0, out=xc)
        xv += (xc - xv) * av                       # first-order servo valve (exact step)
        dp = 1.0 - sgn(xv) * pL * invPs             # orifice pressure drop / Ps
        mx(dp, 0.0, out=dp)
        Q = Kqs * xv * np.sqrt(dp)
        pL = pL * pdec + chd * (Q - A * v)          # compressibility, implicit leakage
        Fa = A * pL
        # LuGre friction, bristle state integrated exactly for frozen v
        vv = v * v
        g = Fc + dF * ex(vv * nivs2)
        if hinge:
            g = g + ch2 * (u * u)
        zss = sgn(v) * g * is0
        znew = zss + (z - zss) * ex(nS0dt * np.abs(v) / g)
        Ffr = s0 * znew + s1idt * (znew - z)
        z = znew
        net = Fa - Ffr - Ce * v * (vv + eps2) ** hexp - Ke * u
        if cubic:
            net -= K3 * u * u * u
        if spec:
            Fsp = ks * ys + cs * yv
            net += Fsp
        acc = net * invM
        if spec:
            yv += (-Fsp * invms - acc) * dt
            ys += yv * dt
        v += acc * dt
        u += v * dt
        FA[k] = Fa
        AC[k] = acc
    out = dict(u=U, F=FA, a=AC)
    if store_v:
        out["v"] = V
    return out


def block_mean(x, D):
    nb = x.shape[0] // D
    return x[: nb * D].reshape(nb, D, *x.shape[1:]).mean(axis=1)


def ar1(rng, n, sigma, fc, fs):
    phi = np.exp(-2 * np.pi * fc / fs)
    w = rng.standard_normal(n) * sigma * np.sqrt(1 - phi * phi)
    x = lfilter([1.0], [1.0, -phi], w)
    return x


# ----------------------------------------------------------------------------- series
def draw_effect(rng, effect, size, base, tests, table):
    """Returns (effect_params, modifications dict)."""
    strong = size == "strong"
    weak = size == "weak"

    def pick(lo, hi, lo_s, hi_s, lo_w, hi_w):
        if strong:
            return rng.uniform(lo_s, hi_s)
        if weak:
            return rng.uniform(lo_w, hi_w)
        return rng.uniform(lo, hi)

    amax = max(t["amplitude_m"] for t in tests)
    if effect == "stiction":
        r = pick(1.3, 1.6, 1.5, 1.6, 1.3, 1.33)
        vs = pick(0.005, 0.020, 0.012, 0.020, 0.005, 0.006)
        return dict(Fs_over_Fmu=r, Fs=r * base["Fmu"], v_stribeck=vs), None
    if effect == "nonlinear_stiffness":
        frac = pick(0.03, 0.10, 0.08, 0.10, 0.03, 0.035)
        # peak force of the largest-amplitude test (rough upper estimate)
        tb = max(tests, key=lambda t: t["amplitude_m"])
        w = 2 * np.pi * tb["frequency_hz"]
        fpk = (abs(base["Ke"] - base["Me"] * w * w) * amax
               + base["Ce"] * (w * amax) ** base["alpha"] + base["Fmu"])
        K3 = frac * fpk / amax ** 3
        return dict(K3=K3, force_change_fraction_at_max_amplitude=frac,
                    reference_amplitude_m=amax, reference_peak_force_n=fpk), None
    if effect == "position_friction":
        frac = pick(0.05, 0.15, 0.12, 0.15, 0.05, 0.055)
        h = table["strut"]["h_m"]
        c_h = frac * base["Fmu"] / (amax / h) ** 2
        return dict(c_h=c_h, h_m=h, fraction_of_Fmu_at_max_amplitude=frac,
                    reference_amplitude_m=amax,
                    note="extra friction c_h*(u/h)^2 added to the LuGre friction level "
                         "(so it also sticks); h = table.strut.h_m"), None
    if effect == "specimen":
        ms = pick(1000, 4000, 3000, 4000, 1000, 1200)
        fs = pick(3, 15, 4.5, 6.0, 13, 15)
        zeta = pick(0.02, 0.05, 0.02, 0.03, 0.04, 0.05)
        return dict(mass_kg=ms, frequency_hz=fs, damping_ratio=zeta,
                    stiffness_n_per_m=ms * (2 * np.pi * fs) ** 2,
                    damping_n_s_per_m=2 * zeta * ms * 2 * np.pi * fs,
                    note="specimen not declared in payload_kg; its weight is not added "
                         "to the friction normal load"), None
    if effect == "channel_delay":
        d = pick(0.001, 0.010, 0.006, 0.010, 0.001, 0.0015)
        return dict(delay_s=d, note="recorded F(t) = actuator force at t - delay_s"), None
    if effect == "drift":
        d = pick(0.10, 0.25, 0.20, 0.25, 0.10, 0.11)
        return dict(drop_fraction=d,
                    note="Ce and Fmu (and Fs) scale by 1 - drop_fraction*(order-1)/(N-1); "
                         "population Ce/Fmu in truth.json are the order-1 values",
                    Ce_last=base["Ce"] * (1 - d), Fmu_last=base["Fmu"] * (1 - d)), None
    raise ValueError(effect)


def generate(seed, out, effect=None, rate=None, size="random", name=None, verbose=True,
             return_internal=False, _ideal=False):
    rng = np.random.default_rng(seed)
    if effect is not None:
        effect = EFFECT_ALIAS.get(effect, effect)
        assert effect in EFFECTS, effect
    if rate is None:
        rate = int(rng.choice(RATES))
    assert rate in DECIM
    D = DECIM[rate]
    fs_int = rate * D
    dt = 1.0 / fs_int

    # ---- population parameters
    base = dict(Me=rng.uniform(10e3, 16e3), Ke=rng.uniform(0.55e6, 0.9e6),
                Ce=rng.uniform(22e3, 38e3), alpha=rng.uniform(0.4, 0.85),
                Fmu=rng.uniform(9e3, 16e3))
    fs_ratio = rng.uniform(1.0, 1.05)
    vs = rng.uniform(0.002, 0.005)
    x_pre = rng.uniform(10e-6, 30e-6)          # LuGre presliding displacement
    test_sd = rng.uniform(0.01, 0.03)
    if _ideal:  # diagnostics only: no test-to-test variation, no Stribeck peak
        test_sd, fs_ratio = 0.0, 1.0

    # ---- hydraulics and controller
    f_oil = rng.uniform(20, 35)
    beta = rng.uniform(1.2e9, 1.6e9)
    Ap = rng.uniform(0.025, 0.04)
    Vt = 4 * beta * Ap ** 2 / (base["Me"] * (2 * np.pi * f_oil) ** 2)
    zeta_h = rng.uniform(0.2, 0.3)
    Kc = 2 * zeta_h * 2 * np.pi * f_oil * Vt / (4 * beta)
    Ps = 21e6
    Qmax = Ap * rng.uniform(0.8, 1.0)           # no-load flow at full spool (m^3/s)
    f_valve = rng.uniform(50, 100)
    Kv = rng.uniform(20, 30)                    # position loop gain, 1/s
    Kp = Kv * Ap / Qmax
    Ki = Kp * 2 * np.pi * rng.uniform(0.2, 0.5)
    Kff = Ap / Qmax * rng.uniform(0.97, 1.0)

    n_tests = int(rng.integers(12, 25))
    allow_payload = effect != "specimen"
    tests = make_plan(rng, n_tests, allow_payload)
    table = {
        "deck_mass_kg": float(np.round(base["Me"] * (1 + 0.05 * rng.standard_normal()), -1)),
        "strut": {"p0_pa": float(np.round(rng.uniform(1.2e6, 2.0e6), -3)),
                  "area_m2": float(np.round(rng.uniform(0.008, 0.015), 4)),
                  "h_m": float(np.round(rng.uniform(1.0, 1.5), 2)),
                  "l0_m": float(np.round(rng.uniform(0.6, 1.0), 2)),
                  "gamma": float(np.round(rng.uniform(1.35, 1.45), 2))},
        "oil": {"bulk_modulus_pa": float(beta), "piston_area_m2": float(Ap),
                "oil_volume_m3": float(Vt)},
    }
    eparams = None
    if effect is not None:
        eparams, _ = draw_effect(rng, effect, size, base, tests, table)

    # ---- per-test parameters
    n = n_tests
    pre, post = 0.5, 1.0
    for ts in tests:
        f = ts["frequency_hz"]
        ts["t0"] = pre
        ts["duration"] = pre + (ts["n_in"] + ts["n_steady"] + ts["n_out"]) / f + post
    var = {k: base[k] * (1 + test_sd * rng.standard_normal(n)) for k in base}
    payload = np.array([t["payload_kg"] for t in tests])
    order = np.array([t["order"] for t in tests], float)
    N0 = base["Me"] * G                          # friction normal load without payload
    nl = 1.0 + payload * G / N0
    Fc = var["Fmu"] * nl
    r_s = fs_ratio
    vs_t = np.full(n, vs)
    if effect == "stiction":
        r_s, vs_t = eparams["Fs_over_Fmu"], np.full(n, eparams["v_stribeck"])
    Ce_t = var["Ce"].copy()
    if effect == "drift":
        fac = 1 - eparams["drop_fraction"] * (order - 1) / max(1, n - 1)
        Ce_t *= fac
        Fc *= fac
    Fs = Fc * r_s
    sigma0 = Fs / x_pre
    M = var["Me"] + payload
    sigma1 = 2 * 0.3 * np.sqrt(sigma0 * M)
    p = dict(A=np.full(n, Ap), Ps=np.full(n, Ps), Kq=np.full(n, Qmax), beta=np.full(n, beta),
             Vt=np.full(n, Vt), Kc=np.full(n, Kc), tau_v=np.full(n, 1 / (2 * np.pi * f_valve)),
             Kp=np.full(n, Kp), Ki=np.full(n, Ki), Kff=np.full(n, Kff), M=M, Ke=var["Ke"],
             K3=np.zeros(n), Ce=Ce_t, alpha=var["alpha"], Fc=Fc, Fs=Fs, vs=vs_t,
             ch_h2=np.zeros(n), sigma0=sigma0, sigma1=sigma1, ms=np.zeros(n),
             ks=np.zeros(n), cs=np.zeros(n))
    if effect == "nonlinear_stiffness":
        p["K3"][:] = eparams["K3"]
    if effect == "position_friction":
        p["ch_h2"][:] = eparams["c_h"] / eparams["h_m"] ** 2
    if effect == "specimen":
        p["ms"][:] = eparams["mass_kg"]
        p["ks"][:] = eparams["stiffness_n_per_m"]
        p["cs"][:] = eparams["damping_n_s_per_m"]

    # ---- simulate: internal sample j at t = (j - (D-1)/2) dt -> block k centred at k/rate
    T = max(ts["duration"] for ts in tests)
    nb = int(np.ceil(T * rate)) + 1
    nt = nb * D
    t_int = (np.arange(nt) - (D - 1) / 2) * dt
    uc, vc = command(tests, t_int)
    res = simulate(p, uc, vc, dt, store_v=return_internal)
    Fint = res["F"]
    if effect == "channel_delay":
        d = eparams["delay_s"]
        Fd = np.empty_like(Fint)
        for j in range(n):
            Fd[:, j] = np.interp(t_int - d, t_int, Fint[:, j], left=0.0)
        Fint = Fd
    ub = block_mean(res["u"], D); Fb = block_mean(Fint, D); ab = block_mean(res["a"], D)
    ucb = block_mean(uc, D)
    tb = np.arange(nb) / rate

    # ---- sensors
    noise = dict(F_frac=rng.uniform(0.003, 0.01), u_white=rng.uniform(8e-6, 20e-6),
                 u_col=rng.uniform(5e-6, 15e-6), u_quant=float(rng.choice([1e-6, 2e-6, 5e-6])),
                 a_white=rng.uniform(0.01, 0.04), a_col=rng.uniform(0.003, 0.01),
                 col_corner_hz=rng.uniform(0.1, 0.5))
    os.makedirs(out, exist_ok=True)
    man_tests = []
    per_test = {}
    fcn = noise["col_corner_hz"]
    for j, ts in enumerate(tests):
        m = int(np.floor(ts["duration"] * rate)) + 1
        t = tb[:m]
        u_true, F_true, a_true = ub[:m, j], Fb[:m, j], ab[:m, j]
        Fpk = np.max(np.abs(F_true))
        sF = noise["F_frac"] * Fpk
        Fm = (F_true + 0.7 * sF * rng.standard_normal(m) + ar1(rng, m, 0.7 * sF, fcn, rate)
              + rng.normal(0, 0.002) * Fpk)
        um = (u_true + noise["u_white"] * rng.standard_normal(m)
              + ar1(rng, m, noise["u_col"], fcn, rate) + rng.normal(0, 1e-4))
        q = noise["u_quant"]
        um = np.round(um / q) * q
        am = (a_true + noise["a_white"] * rng.standard_normal(m)
              + ar1(rng, m, noise["a_col"], fcn, rate) + rng.normal(0, 0.01))
        data = np.column_stack([t, um, Fm, am, ucb[:m, j]])
        fn = os.path.join(out, ts["file"])
        with open(fn, "w") as fh:
            fh.write("t,u,F,a,u_cmd\n")
            np.savetxt(fh, data, fmt=["%.6f", "%.7e", "%.6e", "%.6e", "%.7e"], delimiter=",")
        f = ts["frequency_hz"]
        ss = ts["t0"] + ts["n_in"] / f
        man_tests.append({"id": ts["id"], "file": ts["file"], "kind": ts["kind"],
                          "frequency_hz": f, "amplitude_m": ts["amplitude_m"],
                          "payload_kg": ts["payload_kg"], "order": ts["order"],
                          "steady_start_s": round(ss, 6),
                          "steady_end_s": round(ss + ts["n_steady"] / f, 6),
                          "n_steady_cycles": ts["n_steady"]})
        per_test[ts["id"]] = dict(Me=var["Me"][j], Ke=var["Ke"][j], Ce=Ce_t[j],
                                  alpha=var["alpha"][j], Fmu=Fc[j], Fs=Fs[j],
                                  Fmu_no_payload=Fc[j] / nl[j], M_total=M[j],
                                  peak_F=Fpk)
    series = {"format": "sst-series/1",
              "name": name or ("gen3-seed%d%s" % (seed, "-" + effect if effect else "")),
              "table": table, "tests": man_tests}
    with open(os.path.join(out, "series.json"), "w") as fh:
        json.dump(series, fh, indent=1)
    truth = dict(Me=base["Me"], Ke=base["Ke"], Ce=base["Ce"], alpha=base["alpha"],
                 Fmu=base["Fmu"], Fs=base["Fmu"] * r_s, v_stribeck=float(vs_t[0]),
                 friction_model="LuGre (sigma0=Fs/x_pre, sigma1=0.6*sqrt(sigma0*M))",
                 lugre_presliding_m=x_pre,
                 friction_normal_load_n=N0,
                 friction_payload_rule="Fmu_test = Fmu*(1 + payload_kg*9.81/friction_normal_load_n)",
                 test_to_test_sd=test_sd, record_rate_hz=rate, internal_rate_hz=fs_int,
                 seed=seed, size=size if effect else None,
                 effect=effect, effect_params=eparams,
                 hydraulics=dict(oil_column_hz_rigid=f_oil, oil_stiffness_n_per_m=4 * beta * Ap ** 2 / Vt,
                                 supply_pa=Ps, q_max_m3s=Qmax, leak_coef=Kc, zeta_oil=zeta_h,
                                 valve_bandwidth_hz=f_valve),
                 controller=dict(Kv_per_s=Kv, Kp=Kp, Ki=Ki, Kff=Kff),
                 noise=noise, per_test=per_test)
    with open(os.path.join(out, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=1, default=float)
    if verbose:
        print("wrote %s: %d tests, rate %d Hz, effect %s" % (out, n, rate, effect))
    if return_internal:
        return dict(tests=tests, p=p, t_int=t_int, res=res, uc=uc, D=D, truth=truth)
    return truth


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--effect", default=None)
    ap.add_argument("--rate", type=int, default=None, choices=RATES)
    ap.add_argument("--size", default="random", choices=("strong", "weak", "random"))
    ap.add_argument("--name", default=None)
    a = ap.parse_args()
    generate(a.seed, a.out, a.effect, a.rate, a.size, a.name)


if __name__ == "__main__":
    main()
