"""The published method: hysteresis-loop identification of Me, Ke, Ce, alpha and Fmu.

For every periodic test, one steady cycle is split at symmetric instants (see _loops.py)
into a dissipative force against velocity and an inertial-plus-elastic force against
displacement and acceleration. Then, in the order of the study:

1. Ke from the triangle tests. On a triangle's constant-velocity flanks the acceleration is
   small and the inertial-plus-elastic force is Ke*u: Ke is the least-squares slope of F_ie
   on u over the instants whose |a| is at most `accel_band` times the cycle's peak |a|.
   The low-pass leaves some acceleration on the flanks (the corners are smeared), so Me*a
   is subtracted first, with the Me of step 2: the two regressions are solved together
   (two normal equations, two unknowns). Without triangle tests Ke = 4*p0*A/h from the
   series' `table` description (table.strut.p0_pa, area_m2, h_m).
2. Me from the sine tests: the least-squares slope of F_ie - Ke*u on a (a sine alone
   cannot separate the two, since a = -w^2*u; Ke must come from elsewhere). A test's
   payload is subtracted (Me is the empty table's), i.e. F_ie - Ke*u - payload*a on a.
3. Fmu, Ce, alpha from the dissipative force pooled over all tests: F_D = Fmu + Ce*|v|^alpha
   fitted to |F_D| against |v| by nonlinear least squares, alpha bounded. Literally done on
   low-passed records this is badly biased (friction_fit='pointwise'): the low-pass at 4f
   smears the Coulomb step over a quarter cycle, so the filtered F_D is not F_D(v) at any
   instant (on the quiet twin series Fmu comes out near zero and alpha near 0.3). The
   default (friction_fit='consistent') fits the same model to the same dissipative pairs,
   but predicts them from the model force filtered and split exactly like the measured
   force: F_D ~ Fmu*split(filter(sign v)) + Ce*split(filter(|v|^alpha*sign v)), linear in
   Fmu and Ce, with alpha found by least_squares on the projected residual.

Only instants outside the reversal band enter (see _loops.py). Per-test values refit one
test alone where it identifies something: Me of each sine test given the pooled Ke (the
test's own moving mass, payload included), Ke of each triangle test given the pooled Me,
and Fmu and Ce of each sine test with alpha fixed at the pooled value. A triangle's
dissipative points sit almost all at its one flank speed, so alone it fixes
Fmu + Ce*v_flank^alpha but not the split (in noise the two trade by tens of per cent);
triangles give Fmu and Ce per test only in a series without sines. The spread over tests
is what a campaign's test-to-test variation looks like through this method.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from bayes_sst.reference import DISPLAY_UNITS
from bayes_sst.classical._loops import (
    DEFAULT_POINTS,
    DEFAULT_REVERSAL_BAND,
    DEFAULT_STEADY_TOLERANCE,
    DEFAULT_VELOCITY_CUTOFF_MULTIPLE,
    Loop,
    decompose_test,
)
from bayes_sst.io import Series, SeriesFormatError
from bayes_sst.signals._prepare import SignalOptions, check_record

PARAMETERS = ("Me", "Ke", "Ce", "alpha", "Fmu")
SPREAD_PARAMETERS = ("Me", "Ke", "Ce", "Fmu")
DEFAULT_ACCEL_BAND = 0.2
DEFAULT_ALPHA_BOUNDS = (0.05, 2.0)
METHOD_NAME = "symmetric-instant hysteresis-loop identification"


# --------------------------------------------------------------------------- pieces


def fit_dissipative(
    speed,
    force,
    *,
    alpha: float | None = None,
    alpha_bounds: tuple[float, float] = DEFAULT_ALPHA_BOUNDS,
) -> dict[str, float]:
    """Fmu, Ce, alpha of |F_D| = Fmu + Ce*|v|^alpha by least squares.

    speed, force : |v| (m/s) and |F_D| (N) of the dissipative points, equal length.
    alpha : fix the exponent (then the fit is linear in Fmu and Ce); None fits it too,
        within alpha_bounds, by scipy.optimize.least_squares started from the best point of
        a grid over alpha.

    Returns {"Fmu", "Ce", "alpha"} in N, N/(m/s)^alpha and -.
    """
    speed = np.abs(np.asarray(speed, dtype=float))
    force = np.abs(np.asarray(force, dtype=float))
    if speed.shape != force.shape or speed.ndim != 1:
        raise ValueError("speed and force must be one-dimensional and of equal length")
    moving = speed > 0.0
    speed, force = speed[moving], force[moving]
    if speed.size < (2 if alpha is not None else 3) or np.ptp(speed) <= 0.0:
        raise ValueError("the dissipative fit needs points at several distinct speeds")
    # scaled units: speeds up to 1, forces of order 1, so the exponent is well conditioned
    s_scale = float(speed.max())
    f_scale = float(np.max(force)) or 1.0
    s = speed / s_scale
    y = force / f_scale

    def linear(a: float) -> tuple[np.ndarray, float]:
        design = np.column_stack([np.ones_like(s), s**a])
        coef, *_ = np.linalg.lstsq(design, y, rcond=None)
        return coef, float(np.sum((design @ coef - y) ** 2))

    def unscaled(fmu_s: float, ce_s: float, a: float) -> dict[str, float]:
        return {"Fmu": float(fmu_s * f_scale), "Ce": float(ce_s * f_scale / s_scale**a), "alpha": float(a)}

    if alpha is not None:
        coef, _ = linear(float(alpha))
        return unscaled(coef[0], coef[1], float(alpha))

    from scipy.optimize import least_squares

    low, high = (float(b) for b in alpha_bounds)
    if not 0.0 < low < high:
        raise ValueError(f"alpha_bounds must satisfy 0 < low < high, got {alpha_bounds!r}")
    grid = np.linspace(low, high, 40)
    best = min(grid, key=lambda a: linear(a)[1])
    coef, _ = linear(best)
    x0 = np.array([max(coef[0], 0.0), max(coef[1], 1e-9), best])

    def residual(x):
        return x[0] + x[1] * s ** x[2] - y

    def jacobian(x):
        p = s ** x[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            dp = np.where(s > 0.0, x[1] * p * np.log(np.where(s > 0.0, s, 1.0)), 0.0)
        return np.column_stack([np.ones_like(s), p, dp])

    fit = least_squares(
        residual,
        x0,
        jac=jacobian,
        bounds=([0.0, 0.0, low], [np.inf, np.inf, high]),
        x_scale=[1.0, 1.0, 0.1],
        xtol=1e-14,
        ftol=1e-14,
        gtol=1e-14,
        max_nfev=2000,
    )
    return unscaled(*fit.x)


def _sign(v):
    return np.sign(v)


def _power(alpha: float):
    def g(v):
        return np.abs(v) ** alpha * np.sign(v)

    return g


def fit_dissipative_loops(
    loops,
    *,
    Me: float,
    Ke: float,
    alpha: float | None = None,
    alpha_bounds: tuple[float, float] = DEFAULT_ALPHA_BOUNDS,
    friction_fit: str = "consistent",
) -> dict[str, float]:
    """Fmu, Ce, alpha from the dissipative pairs of split loops.

    The observed dissipative force of each kept pair is F_D - (Me + payload)*a_D - Ke*u_D:
    the residual inertia and stiffness of the pair (a_D, u_D vanish for an ideal loop) are
    taken off once Me and Ke are known.

    friction_fit : 'pointwise' fits |F_D| = Fmu + Ce*|v|^alpha to the points, against the
        velocity at the instants (the study's plot; see fit_dissipative). 'consistent'
        (default) compares F_D with the model force treated exactly like the measured
        force, Fmu*split(filter(sign v)) + Ce*split(filter(|v|^alpha*sign v)): the low-pass
        smears the Coulomb step over about 1/f_c, which at f_c = 4f reaches the whole
        quarter cycle and would otherwise bias Fmu low and Ce high. Both agree when the
        loops are unfiltered, and then the pointwise fit is used.
    alpha : fix the exponent (per-test fits); None fits it within alpha_bounds.
    """
    if friction_fit not in ("consistent", "pointwise"):
        raise ValueError(f"friction_fit must be 'consistent' or 'pointwise', got {friction_fit!r}")
    observed, speeds, kept = [], [], []
    for lp in loops:
        keep = lp.keep_D
        y = lp.F_D - (Me + lp.payload_kg) * lp.a_D - Ke * lp.u_D
        observed.append(y[keep])
        speeds.append(lp.v_D[keep])
        kept.append(keep)
    y = np.concatenate(observed)
    if y.size < 3:
        raise ValueError("too few dissipative points outside the reversal band")
    filtered = any(lp.cutoff_hz is not None for lp in loops)
    if friction_fit == "pointwise" or not filtered:
        return fit_dissipative(np.abs(np.concatenate(speeds)), np.abs(y), alpha=alpha, alpha_bounds=alpha_bounds)

    r_sign = np.concatenate([lp.dissipative_regressor(_sign)[k] for lp, k in zip(loops, kept)])
    f_scale = float(np.max(np.abs(y))) or 1.0

    def linear(a: float):
        r_pow = np.concatenate([lp.dissipative_regressor(_power(a))[k] for lp, k in zip(loops, kept)])
        design = np.column_stack([r_sign, r_pow])
        coef, *_ = np.linalg.lstsq(design, y, rcond=None)
        return coef, (design @ coef - y) / f_scale

    def result(a: float) -> dict[str, float]:
        coef, _ = linear(a)
        return {"Fmu": float(coef[0]), "Ce": float(coef[1]), "alpha": float(a)}

    if alpha is not None:
        return result(float(alpha))

    from scipy.optimize import least_squares

    low, high = (float(b) for b in alpha_bounds)
    if not 0.0 < low < high:
        raise ValueError(f"alpha_bounds must satisfy 0 < low < high, got {alpha_bounds!r}")
    # variable projection: Fmu and Ce are linear, so the residual is a function of alpha alone
    grid = np.linspace(low, high, 24)
    costs = [float(np.sum(linear(a)[1] ** 2)) for a in grid]
    start = float(grid[int(np.argmin(costs))])
    fit = least_squares(lambda x: linear(x[0])[1], [start], bounds=([low], [high]), diff_step=1e-6,
                        xtol=1e-12, ftol=1e-12, gtol=1e-12)
    return result(float(fit.x[0]))


def table_stiffness(table: Mapping[str, Any]) -> float | None:
    """Ke = 4*p0*A/h from table.strut (p0_pa, area_m2, h_m), or None when any is missing."""
    strut = table.get("strut") if isinstance(table, Mapping) else None
    if not isinstance(strut, Mapping):
        return None
    values = [strut.get(k) for k in ("p0_pa", "area_m2", "h_m")]
    if not all(isinstance(x, (int, float)) and not isinstance(x, bool) and x > 0 for x in values):
        return None
    # the physics package's relation (imported here: bayes_sst.physics brings in jax)
    from bayes_sst.physics import strut_stiffness

    return float(strut_stiffness(*(float(x) for x in values)))


def _flank(loop: Loop, accel_band: float) -> np.ndarray:
    """Inertial-elastic points of a triangle's constant-velocity flanks: kept, |a| small."""
    peak = float(np.max(np.abs(loop.a_ie))) if loop.a_ie.size else 0.0
    return loop.keep_ie & (np.abs(loop.a_ie) <= accel_band * peak)


def stiffness_from_flanks(u, a, F_ie, *, mass: float = 0.0) -> float:
    """Ke: least-squares slope through the origin of F_ie - mass*a on u."""
    u, a, F_ie = (np.asarray(x, dtype=float) for x in (u, a, F_ie))
    suu = float(u @ u)
    if suu <= 0.0:
        raise ValueError("no displacement on the selected flank points")
    return float(u @ (F_ie - mass * a)) / suu


def mass_from_loop(u, a, F_ie, *, Ke: float) -> float:
    """Me: least-squares slope through the origin of F_ie - Ke*u on a."""
    u, a, F_ie = (np.asarray(x, dtype=float) for x in (u, a, F_ie))
    saa = float(a @ a)
    if saa <= 0.0:
        raise ValueError("no acceleration on the selected points")
    return float(a @ (F_ie - Ke * u)) / saa


def _spread(values: list[float]) -> dict[str, float | int | None]:
    x = np.asarray(values, dtype=float)
    n = int(x.size)
    if n == 0:
        return {"mean": None, "sd": None, "relative_sd": None, "n": 0}
    mean = float(x.mean())
    sd = float(x.std(ddof=1)) if n > 1 else None
    relative = None if sd is None or mean == 0.0 else sd / abs(mean)
    return {"mean": mean, "sd": sd, "relative_sd": relative, "n": n}


def _finite_or_none(x):
    return None if x is None or not math.isfinite(x) else float(x)


# --------------------------------------------------------------------------- result


@dataclass(frozen=True)
class ClassicalResult:
    """What the hysteresis-loop method identifies from a series (SI units throughout).

    pooled : {"Me", "Ke", "Ce", "alpha", "Fmu"} from all tests together.
    per_test : one dict per periodic test: id, kind, frequency_hz, amplitude_m, payload_kg
        and the parameters that test identifies alone (Me, Ce and Fmu for sines, with alpha
        fixed at the pooled value; Ke for triangles).
    spread : {param: {"mean", "sd", "relative_sd", "n"}} of the per-test values (Me with
        each test's payload removed).
    method : settings and where Ke and Me came from.
    loops : the split cycles, for plots and checks (not written to JSON).
    """

    series: str
    pooled: dict[str, float]
    per_test: list[dict[str, Any]]
    spread: dict[str, dict[str, Any]]
    method: dict[str, Any]
    loops: tuple[Loop, ...] = field(default=(), repr=False, compare=False)

    def to_json(self) -> dict[str, Any]:
        """The content of classical.json: JSON types only, null where a value is undefined."""
        per_test = [{k: (_finite_or_none(v) if isinstance(v, float) else v) for k, v in row.items()}
                    for row in self.per_test]
        return {
            "series": self.series,
            "method": dict(self.method),
            "pooled": {k: float(v) for k, v in self.pooled.items()},
            "per_test": per_test,
            "spread": {k: dict(v) for k, v in self.spread.items()},
        }


def classical_identification(
    series: Series,
    *,
    cycle: int = -2,
    cutoff_multiple: float | None = 4.0,
    n_points: int = DEFAULT_POINTS,
    reversal_band: float = DEFAULT_REVERSAL_BAND,
    accel_band: float = DEFAULT_ACCEL_BAND,
    alpha_bounds: tuple[float, float] = DEFAULT_ALPHA_BOUNDS,
    steady_tolerance: float = DEFAULT_STEADY_TOLERANCE,
    friction_fit: str = "consistent",
    velocity_cutoff_multiple: float | None = DEFAULT_VELOCITY_CUTOFF_MULTIPLE,
    alpha: float | None = None,
    check_records: bool = True,
) -> ClassicalResult:
    """Identify Me, Ke, Ce, alpha, Fmu of a series by the study's hysteresis-loop method.

    Parameters
    ----------
    series : Series
        Its sine and triangle tests are used; broadband tests are ignored.
    cycle : int, default -2
        Which steady cycle of each test (Python index; -2 is the second-to-last).
    cutoff_multiple : float or None, default 4.0
        Zero-phase low-pass of u, F, a at this multiple of each test's frequency; None
        leaves the signals unfiltered.
    n_points : int
        Symmetric instants t1 per quarter cycle.
    reversal_band : float
        Instants slower than this share of the cycle's peak speed are left out.
    accel_band : float
        A triangle's flank points are those with |a| at most this share of its peak |a|.
    alpha_bounds : (float, float)
        Bounds of the damping exponent in the pooled dissipative fit.
    friction_fit : 'consistent' or 'pointwise'
        How the dissipative force is fitted (see fit_dissipative_loops); 'pointwise' is the
        study's literal |F_D| against |v|, biased by the low-pass around reversals.
    velocity_cutoff_multiple : float or None
        Band of the velocity that the consistent friction fit feeds its regressors (see
        decompose_test).
    alpha : float or None
        Fix the damping exponent (0.5: turbulent orifice flow) instead of fitting it. The
        pooled fit hardly separates alpha from Fmu: Fmu + Ce*|v|^alpha curves with
        (Fmu, alpha) = (12.5 kN, 0.5) and (10 kN, 0.4) differ by under 1 % over
        0.05-0.5 m/s, so a few per cent of test-to-test variation can move both by 20 %.
    check_records : bool, default True
        Run the fit's checks of each record against its manifest entry
        (bayes_sst.signals.check_record); False where they have run already (beside a fit).

    Raises
    ------
    SeriesFormatError
        No periodic test; a test without enough steady cycles; no triangle test and no
        strut description to compute Ke from.
    """
    where = series.path or series.name
    records = series.periodic_tests
    if not records:
        raise SeriesFormatError(where, "tests", "no sine or triangle test: the loop method needs periodic tests")
    loops = []
    check_options = SignalOptions(cutoff_multiple=cutoff_multiple or SignalOptions().cutoff_multiple)
    for record in records:
        source = str(series.path / record.spec.file) if series.path else record.spec.file
        # the fit's refusals hold here too: a still or mis-scaled u gave Me = 2.4 t and alpha at
        # its bound without a word
        if check_records:
            check_record(record, check_options, source=source)
        loops.append(
            decompose_test(
                record,
                cycle=cycle,
                cutoff_multiple=cutoff_multiple,
                n_points=n_points,
                reversal_band=reversal_band,
                steady_tolerance=steady_tolerance,
                velocity_cutoff_multiple=velocity_cutoff_multiple,
                source=source,
            )
        )
    triangles = [lp for lp in loops if lp.kind == "triangle"]
    sines = [lp for lp in loops if lp.kind == "sine"]
    mass_loops = sines or triangles
    mass_source = "sine tests" if sines else "triangle tests (no sine test in the series)"

    # Me enters the sine equation through F_ie - Ke*u - payload*a = Me*a
    def stacked(group, select):
        parts = [(lp.u_ie[select(lp)], lp.a_ie[select(lp)], lp.F_ie[select(lp)], lp.payload_kg) for lp in group]
        u = np.concatenate([p[0] for p in parts]) if parts else np.empty(0)
        a = np.concatenate([p[1] for p in parts]) if parts else np.empty(0)
        F = np.concatenate([p[2] - p[3] * p[1] for p in parts]) if parts else np.empty(0)
        return u, a, F

    u_s, a_s, F_s = stacked(mass_loops, lambda lp: lp.keep_ie)
    if not a_s.size or float(a_s @ a_s) <= 0.0:
        raise SeriesFormatError(where, "tests", "no usable inertial-elastic points to identify Me from")
    if triangles:
        u_t, a_t, F_t = stacked(triangles, lambda lp: _flank(lp, accel_band))
        if float(u_t @ u_t) <= 0.0:
            raise SeriesFormatError(where, "tests", "the triangle tests have no usable flank points for Ke")
        # Ke*Suu_t + Me*Sua_t = SuF_t  (flanks);  Ke*Sua_s + Me*Saa_s = SaF_s  (sines)
        system = np.array([[u_t @ u_t, u_t @ a_t], [u_s @ a_s, a_s @ a_s]])
        rhs = np.array([u_t @ F_t, a_s @ F_s])
        Ke, Me = (float(x) for x in np.linalg.solve(system, rhs))
        stiffness_source = "triangle tests' constant-velocity flanks: " + ", ".join(lp.id for lp in triangles)
    else:
        Ke = table_stiffness(series.table)
        if Ke is None:
            raise SeriesFormatError(
                where,
                "table.strut",
                "no triangle test to identify Ke from, and no strut description (p0_pa, area_m2, h_m) "
                "to compute Ke = 4*p0*A/h from",
            )
        Me = mass_from_loop(u_s, a_s, F_s, Ke=Ke)
        stiffness_source = "table description: Ke = 4*p0*A/h (no triangle test)"

    friction = fit_dissipative_loops(
        loops, Me=Me, Ke=Ke, alpha=alpha, alpha_bounds=alpha_bounds, friction_fit=friction_fit
    )
    pooled = {"Me": Me, "Ke": Ke, "Ce": friction["Ce"], "alpha": friction["alpha"], "Fmu": friction["Fmu"]}

    per_test = []
    for lp in loops:
        row: dict[str, Any] = {
            "id": lp.id,
            "kind": lp.kind,
            "frequency_hz": lp.frequency_hz,
            "amplitude_m": lp.amplitude_m,
            "payload_kg": lp.payload_kg,
        }
        if lp.kind == "sine" or not sines:
            k = lp.keep_ie
            if np.any(k) and float(lp.a_ie[k] @ lp.a_ie[k]) > 0.0:
                row["Me"] = mass_from_loop(lp.u_ie[k], lp.a_ie[k], lp.F_ie[k], Ke=Ke)
        if lp.kind == "triangle" and triangles:
            k = _flank(lp, accel_band)
            if np.any(k) and float(lp.u_ie[k] @ lp.u_ie[k]) > 0.0:
                row["Ke"] = stiffness_from_flanks(lp.u_ie[k], lp.a_ie[k], lp.F_ie[k], mass=Me + lp.payload_kg)
        own = None
        if lp.kind == "sine" or not sines:
            try:
                own = fit_dissipative_loops([lp], Me=Me, Ke=Ke, alpha=pooled["alpha"], friction_fit=friction_fit)
            except ValueError:
                own = None
        if own is not None:
            row["Ce"] = own["Ce"]
            row["Fmu"] = own["Fmu"]
        per_test.append(row)

    spread = {}
    for name in SPREAD_PARAMETERS:
        values = [row[name] - (row["payload_kg"] if name == "Me" else 0.0) for row in per_test if name in row]
        spread[name] = _spread(values)

    method = {
        "name": METHOD_NAME,
        "cycle": int(cycle),
        "cutoff_multiple": None if cutoff_multiple is None else float(cutoff_multiple),
        "n_points": int(n_points),
        "reversal_band": float(reversal_band),
        "accel_band": float(accel_band),
        "alpha_bounds": [float(b) for b in alpha_bounds],
        "alpha_fixed": None if alpha is None else float(alpha),
        "Ke_source": stiffness_source,
        "Me_source": mass_source,
        "per_test": "Me, Ce, Fmu from each sine test (alpha fixed at the pooled value); Ke from each triangle",
        "n_tests": len(loops),
        "velocity_cutoff_multiple": None if velocity_cutoff_multiple is None else float(velocity_cutoff_multiple),
        "friction_fit": friction_fit if cutoff_multiple is not None else "pointwise",
        "n_dissipative_points": int(sum(int(lp.keep_D.sum()) for lp in loops)),
    }
    return ClassicalResult(
        series=series.name,
        pooled=pooled,
        per_test=per_test,
        spread=spread,
        method=method,
        loops=tuple(loops),
    )


# --------------------------------------------------------------------------- text




def format_classical(result: ClassicalResult | Mapping[str, Any]) -> str:
    """A short table of the pooled values (t, kN), the published ones, and the test-to-test spread."""
    from bayes_sst.reference import PUBLISHED_SST

    data = result.to_json() if isinstance(result, ClassicalResult) else result
    method = data.get("method", {})
    lines = [
        f"classical (hysteresis-loop) identification of series '{data.get('series', '')}': "
        f"{method.get('n_tests', len(data.get('per_test', [])))} tests, cycle {method.get('cycle')}, "
        f"cut-off {method.get('cutoff_multiple')} x f",
        f"Ke from {method.get('Ke_source', '?')}",
        "",
    ]
    header = f"{'parameter':<10}{'unit':<12}{'pooled':>10}{'published':>11}{'test sd':>9}{'n':>4}"
    lines += [header, "-" * len(header)]
    for name in PARAMETERS:
        scale, unit = DISPLAY_UNITS[name]
        value = data["pooled"][name]
        published = PUBLISHED_SST.get(name)
        spread = data.get("spread", {}).get(name) or {}
        rel = spread.get("relative_sd")
        lines.append(
            f"{name:<10}{unit:<12}{value * scale:>10.4g}"
            f"{(published * scale if published is not None else float('nan')):>11.4g}"
            + (f"{100 * rel:>8.2f}%" if rel is not None else f"{'-':>9}")
            + f"{spread.get('n', 0) if spread else 0:>4}"
        )
    warning = unphysical_warning(data["pooled"])
    if warning:
        lines += ["", f"WARNING: {warning}; use bayes-sst fit"]
    return "\n".join(lines)


def unphysical_warning(pooled: Mapping[str, Any]) -> str | None:
    """Words for pooled classical coefficients at or below zero, or None: no table has them, and
    the hand method does not hold on such tests (a series of triangles gave Fmu = -13 kN)."""
    names = [name for name in ("Me", "Ke", "Ce", "Fmu")
             if isinstance(pooled.get(name), (int, float)) and pooled[name] <= 0.0]
    if not names:
        return None
    return (f"{', '.join(names)} at or below zero, which no table has: the hand method (symmetric instants of "
            "one steady cycle) does not hold on these tests (triangles, say, or friction that dominates the cycle)")
