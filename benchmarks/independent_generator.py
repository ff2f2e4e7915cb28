"""A second, independently written virtual table: series for checking bayes_sst's fit against
a generator that shares no code with bayes_sst.twin (written in this project by a separate
session from the data format and the force equation only).

Per series: Me, Ke, Ce, Fmu within +-20 % of the SST values, alpha in [0.4, 0.8], 200 or
500 Hz, static/kinetic friction ratio 1.0-1.1. Per test (20): sine or (25 %) rounded triangle,
0.25-3 Hz log-uniform, peak speed 0.05-0.5 m/s, linear ramp-in of 1-2 cycles, 4-8 steady
cycles, 1 ramp-out cycle, 0.5 s rest at both ends; Me, Ke, Ce, Fmu times (1 + 0.02 N(0, 1)).
Deck integrated at 0.2 ms (semi-implicit Euler) under PID + nominal-model feedforward with a
3 ms first-order actuator lag, stick-slip friction (sticks at each velocity reversal until
|F_A - Ke u| exceeds Fs). Recorded: instantaneous samples; F with AR(1) noise (10-20 ms,
300-800 N) + 100 N white + an offset up to 1 kN; u with 20 um white + up to 1 mm offset; a with
0.05 m/s^2 white. truth.json holds the population and every test's values.

Optional withheld effects (make_series(..., effects={...}); none by default), each written
from its physics here, not from bayes_sst.twin:
  force_delay d (s): F recorded as F(t - d);
  specimen_mass, specimen_frequency, specimen_damping: an SDOF specimen on the deck whose base
      shear m_s*(a + x'') = -m_s*(2 zeta w x' + w^2 x) loads it, x'' + 2 zeta w x' + w^2 x = -a;
  cubic_stiffness K3 (N/m): strut force Ke*u + K3*(u/h)^2*u, h = 1.2 m;
  hinge_friction Fp (N): kinetic (and static) friction level Fk + Fp*(u/h)^2;
  drift: Fmu and Ce of test j multiplied by 1 - drift*j/(n-1);
  friction_drift: Fmu alone multiplied by 1 - friction_drift*j/(n-1) (not in the benchmark cases);
  static_ratio: Fs/Fk in place of the drawn 1.0-1.1 (stiction).

    python benchmarks/independent_generator.py OUT_DIR SEED [SEED ...]
"""
import json, math, os, sys
import numpy as np

REF = dict(Me=13200.0, Ke=7.2e5, Ce=29600.0, alpha=0.5, Fmu=12500.0)
DT = 2e-4  # integration step, s


def shape_fn(kind, w, t, delta):
    if kind == "sine":
        return np.sin(w * t)
    # rounded triangle: arcsin of a slightly shrunk sine, normalised to unit peak
    return np.arcsin((1 - delta) * np.sin(w * t)) / math.asin(1 - delta)


def command(kind, f, A, n_in, n_steady, n_out, delta, pre=0.5, post=0.5):
    T = 1.0 / f
    t_motion = (n_in + n_steady + n_out) * T
    t_total = pre + t_motion + post
    n = int(round(t_total / DT)) + 1
    t = np.arange(n) * DT
    tm = t - pre
    env = np.clip(tm / (n_in * T), 0, 1)
    t_end = t_motion
    env = np.minimum(env, np.clip((t_end - tm) / (n_out * T), 0, 1))
    env[(tm < 0) | (tm > t_end)] = 0.0
    u = A * env * shape_fn(kind, 2 * np.pi * f, np.clip(tm, 0, None), delta)
    v = np.gradient(u, DT)
    a = np.gradient(v, DT)
    steady = (pre + n_in * T, pre + (n_in + n_steady) * T)
    return t, u, v, a, steady


STRUT_H = 1.2  # m, the strut length of the written table description


def simulate_deck(t, uc, vc, ac, p, fs_ratio, nominal, effects=None):
    """Closed loop: PID + model feedforward -> actuator force (first-order lag) -> deck with
    stick-slip friction.  Returns F_A, u, v, a at every step (force balance exact)."""
    effects = effects or {}
    Me, Ke, Ce, al, Fk0 = p["Me"], p["Ke"], p["Ce"], p["alpha"], p["Fmu"]
    K3 = effects.get("cubic_stiffness", 0.0) / STRUT_H ** 2
    Fp = effects.get("hinge_friction", 0.0) / STRUT_H ** 2
    ms = effects.get("specimen_mass", 0.0)
    ws = 2 * math.pi * effects.get("specimen_frequency", 10.0)
    zs = effects.get("specimen_damping", 0.03)
    x = xd = 0.0
    Mn, Kn, Cn, aln, Fn = nominal
    wc = 2 * math.pi * 8.0
    Kp, Kd, Ki = Mn * wc * wc, 2 * 0.7 * wc * Mn, Mn * wc ** 3 / 10
    tau = 0.003
    n = len(t)
    FA_out = np.empty(n); u_out = np.empty(n); v_out = np.empty(n); a_out = np.empty(n)
    uc_l = uc.tolist(); vc_l = vc.tolist(); ac_l = ac.tolist()
    u = 0.0; v = 0.0; FA = 0.0; ie = 0.0
    stuck = True
    dt = DT
    k_dt = dt / tau
    for k in range(n):
        # controller output at t_k (uses state at t_k), actuator lag
        vck = vc_l[k]
        sgn_c = 1.0 if vck > 0 else (-1.0 if vck < 0 else 0.0)
        ff = Mn * ac_l[k] + Kn * uc_l[k] + (Cn * abs(vck) ** aln + Fn) * sgn_c
        e = uc_l[k] - u
        Fc = ff + Kp * e + Kd * (vck - v) + Ki * ie
        Fk = Fk0 + Fp * u * u
        Fs = fs_ratio * Fk
        shear = -ms * (2 * zs * ws * xd + ws * ws * x)  # m_s*(a + x''), what the specimen takes
        net = FA - Ke * u - K3 * u * u * u - shear
        if stuck:
            if abs(net) <= Fs:
                a = 0.0
            else:
                stuck = False
                s = 1.0 if net > 0 else -1.0
                a = (net - Fk * s) / Me
        else:
            s = 1.0 if v > 0 else -1.0
            a = (net - (Ce * abs(v) ** al + Fk) * s) / Me
        FA_out[k] = FA; u_out[k] = u; v_out[k] = v; a_out[k] = a
        if ms > 0.0:
            xdd = -a - 2 * zs * ws * xd - ws * ws * x
            xd += xdd * dt
            x += xd * dt
        # advance
        if not stuck:
            vn = v + a * dt
            if v != 0.0 and vn * v <= 0.0:
                vn = 0.0
                stuck = True
            v = vn
        u += v * dt
        ie += e * dt
        FA += k_dt * (Fc - FA)
    return FA_out, u_out, v_out, a_out


def ar1(rng, n, fs, tc, sd):
    phi = math.exp(-1.0 / (fs * tc))
    w = rng.normal(0, sd * math.sqrt(1 - phi * phi), n)
    x = np.empty(n); x[0] = rng.normal(0, sd)
    for i in range(1, n):
        x[i] = phi * x[i - 1] + w[i]
    return x


def make_series(seed, out, n_tests=20, effects=None, sample_rate_hz=None, population=None, spread=0.02,
                spread_seed=None, noise_seed=None, noise_scale=None):
    """spread_seed, noise_seed: draw the tests' factors (1 + spread*N(0, 1)) or the sensors' noise
    (force, displacement, acceleration; not the offsets) from a stream of their own, seeded so;
    every other draw of the series stays as it was (the series' own stream is consumed the same).
    noise_scale multiplies every sensor noise (default: $GEN_NOISE_SCALE, else 1; 0: ideal sensors).
    """
    rng = np.random.default_rng(1000 + seed)
    spread_rng = None if spread_seed is None else np.random.default_rng([int(spread_seed), 7])
    pop = {k: REF[k] * rng.uniform(0.8, 1.2) for k in ("Me", "Ke", "Ce", "Fmu")}
    pop["alpha"] = rng.uniform(0.4, 0.8)
    pop.update(population or {})  # after the draws, so the rest of the series does not change
    fs = int(rng.choice([200, 500]))
    fs = int(sample_rate_hz or fs)  # the draw stays, so the rest of the series does not change
    fs_ratio = rng.uniform(1.0, 1.1)
    fs_ratio = (effects or {}).get("static_ratio", fs_ratio)
    ns = float(os.environ.get("GEN_NOISE_SCALE", "1")) if noise_scale is None else float(noise_scale)
    noise = dict(F_ar_sd=ns * rng.uniform(300, 800), F_tc=rng.uniform(0.010, 0.020), F_white=ns * 100.0,
                 u_white=ns * 20e-6, a_white=ns * 0.05)
    nominal = (REF["Me"], REF["Ke"], REF["Ce"], REF["alpha"], REF["Fmu"])
    os.makedirs(out, exist_ok=True)
    tests, truth_tests = [], []
    step = int(round(1.0 / (fs * DT)))
    for j in range(n_tests):
        kind = "triangle" if rng.random() < 0.25 else "sine"
        f = float(np.exp(rng.uniform(np.log(0.25), np.log(3.0))))
        vmax = rng.uniform(0.05, 0.5)
        gain = 4.0 if kind == "triangle" else 2 * np.pi
        A = min(vmax / (gain * f), 0.1)
        A = float(max(A, 0.005))
        if gain * f * A > 0.5:
            A = 0.5 / (gain * f)
        A = round(A, 4)
        n_in = int(rng.integers(1, 3)); n_steady = int(rng.integers(4, 9)); n_out = 1
        delta = rng.uniform(0.01, 0.03)
        p = {k: pop[k] * (1 + spread * rng.normal()) for k in ("Me", "Ke", "Ce", "Fmu")}
        if spread_rng is not None:
            p = {k: pop[k] * (1 + spread * spread_rng.normal()) for k in ("Me", "Ke", "Ce", "Fmu")}
        p["alpha"] = pop["alpha"]
        drift = (effects or {}).get("drift", 0.0) * j / (n_tests - 1)
        p["Ce"] *= 1 - drift
        p["Fmu"] *= 1 - drift
        p["Fmu"] *= 1 - (effects or {}).get("friction_drift", 0.0) * j / (n_tests - 1)
        t, uc, vc, ac, steady = command(kind, f, A, n_in, n_steady, n_out, delta)
        FA, u, v, a = simulate_deck(t, uc, vc, ac, p, fs_ratio, nominal, effects)
        idx = np.arange(0, len(t), step)
        ts, us, vs, as_ = t[idx], u[idx], v[idx], a[idx]
        Fs_ = np.interp(ts - (effects or {}).get("force_delay", 0.0), t, FA)
        n = len(idx)
        off_F = rng.uniform(-1000, 1000); off_u = rng.uniform(-1e-3, 1e-3)
        sensor_noise = [ar1(rng, n, fs, noise["F_tc"], max(noise["F_ar_sd"], 1e-9)) + rng.normal(0, noise["F_white"], n),
                        rng.normal(0, noise["u_white"], n), rng.normal(0, noise["a_white"], n)]
        if noise_seed is not None:
            own = np.random.default_rng([int(noise_seed), j])
            sensor_noise = [ar1(own, n, fs, noise["F_tc"], max(noise["F_ar_sd"], 1e-9)) + own.normal(0, noise["F_white"], n),
                            own.normal(0, noise["u_white"], n), own.normal(0, noise["a_white"], n)]
        F_rec = Fs_ + sensor_noise[0] + off_F
        u_rec = us + sensor_noise[1] + off_u
        a_rec = as_ + sensor_noise[2]
        tid = f"T{j + 1:02d}"
        fname = f"{tid}.csv"
        with open(os.path.join(out, fname), "w") as fh:
            fh.write("t,u,F,a\n")
            for row in zip(ts, u_rec, F_rec, a_rec):
                fh.write("%.6f,%.9e,%.9e,%.9e\n" % row)
        tests.append({"id": tid, "file": fname, "kind": kind, "frequency_hz": round(f, 6),
                      "amplitude_m": A, "payload_kg": 0, "order": j + 1})
        track = float(np.max(np.abs(u - uc)))
        truth_tests.append(dict(id=tid, params=p, steady_s=steady, n_in=n_in, n_steady=n_steady,
                                kind=kind, f=f, A=A, peak_v=float(np.max(np.abs(v))),
                                tracking_max_err=track, fs=fs,
                                stuck_share=float(np.mean(v == 0.0))))
    manifest = {"format": "sst-series/1", "name": f"probe-{seed}",
                "table": {"deck_mass_kg": 12000, "strut": {"p0_pa": 6.9e6, "area_m2": 0.0314,
                                                           "h_m": 1.2, "l0_m": 0.8, "gamma": 1.4}},
                "tests": tests}
    with open(os.path.join(out, "series.json"), "w") as fh:
        json.dump(manifest, fh, indent=1)
    with open(os.path.join(out, "truth.json"), "w") as fh:
        json.dump(dict(seed=seed, population=pop, fs=fs, fs_ratio=fs_ratio, noise=noise,
                       **({} if spread_seed is None else {"spread_seed": spread_seed}),
                       **({} if noise_seed is None else {"noise_seed": noise_seed}),
                       effects=effects or {}, tests=truth_tests), fh, indent=1)


if __name__ == "__main__":
    for s in map(int, sys.argv[2:]):
        make_series(s, os.path.join(sys.argv[1], f"s{s:02d}"))
        print("done", s, flush=True)
