"""The published method: symmetric-instant loop split, Ke/Me/friction fits, CLI, physics priors.

Closed-form answers first (ideal loops built here from the force model), then the quiet
virtual table against its truth, which is the acceptance figure of the classical method.
"""

import argparse
import json

import numpy as np
import pytest

from bayes_sst.classical import (
    classical_identification,
    decompose_test,
    fit_dissipative,
    quadruple_times,
    split_force,
    symmetric_instants,
    table_stiffness,
)
from bayes_sst.classical._command import add_parser
from bayes_sst.classical._identify import _flank, stiffness_from_flanks
from bayes_sst.io import OutputExistsError, Series, SeriesFormatError, TestRecord, TestSpec, write_series

ME, KE, CE, ALPHA, FMU = 13_000.0, 700_000.0, 30_000.0, 0.5, 12_000.0
P0, AREA, H, L0, GAMMA = 6.9e6, 0.0314, 1.2, 0.8, 1.4


def dissipative(v):
    return (CE * np.abs(v) ** ALPHA + FMU) * np.sign(v)


def sine_signals(t, frequency, amplitude, offset):
    w = 2 * np.pi * frequency
    phase = w * (t - offset)
    return amplitude * np.sin(phase), amplitude * w * np.cos(phase), -amplitude * w * w * np.sin(phase)


def triangle_signals(t, frequency, amplitude, corner):
    """Triangle with constant-velocity flanks and parabolic corners (constant deceleration
    over `corner` seconds either side of each reversal), built from its quarter-cycle shape
    by the symmetries u(-t) = -u(t), u(T/2 - t) = u(t)."""
    period = 1.0 / frequency
    quarter = period / 4
    speed = amplitude / (quarter - corner / 2)
    phi = np.mod(t, period)
    # quarter-cycle coordinate q in [0, T/4], sign of u, and dq/dphi
    q = np.select([phi < quarter, phi < 2 * quarter, phi < 3 * quarter], [phi, 2 * quarter - phi, phi - 2 * quarter],
                  period - phi)
    sign = np.where(phi < 2 * quarter, 1.0, -1.0)
    dq = np.select([phi < quarter, phi < 2 * quarter, phi < 3 * quarter], [1.0, -1.0, 1.0], -1.0)
    s = q - (quarter - corner)
    flank = s <= 0
    g = np.where(flank, speed * q, speed * (quarter - corner) + speed * (s - s * s / (2 * corner)))
    dg = np.where(flank, speed, speed * (1 - s / corner))
    d2g = np.where(flank, 0.0, -speed / corner)
    return sign * g, sign * dg * dq, sign * d2g


def record(kind, frequency, amplitude, signals, *, fs, n_cycles, test_id, with_a=True):
    t = np.arange(int(round(n_cycles * fs / frequency)) + 1) / fs
    u, v, a = signals(t)
    columns = {"t": t, "u": u, "F": ME * a + KE * u + dissipative(v)}
    if with_a:
        columns["a"] = a
    spec = TestSpec(id=test_id, file=f"{test_id}.csv", kind=kind, frequency_hz=frequency, amplitude_m=amplitude)
    return TestRecord(spec, columns)


# ----------------------------------------------------------------- (a) the split itself


def test_instants_and_algebra_of_the_split():
    period = 0.8
    t1 = symmetric_instants(period, 10)
    assert np.all((t1 > 0) & (t1 < period / 4))
    times = quadruple_times(2.0, period, t1)
    np.testing.assert_allclose(times[:, 1] + times[:, 0], 2 * 2.0 + period / 2)
    np.testing.assert_allclose(times[:, 3] - times[:, 2], period / 2 - 2 * t1)
    # analytic ideal sine: the split of F_A gives F_D(v) and Me*a + Ke*u at machine precision
    u, v, a = sine_signals(times, 1 / period, 0.05, 2.0)
    F = ME * a + KE * u + dissipative(v)
    F_D, F_ie = split_force(F)
    np.testing.assert_allclose(F_D, dissipative(np.concatenate([v[:, 0], v[:, 1]])), rtol=1e-12)
    np.testing.assert_allclose(F_ie, np.concatenate([(ME * a + KE * u)[:, 0], (ME * a + KE * u)[:, 2]]), rtol=1e-9)


@pytest.mark.parametrize("offset_samples", [0.0, 0.37, 0.81])
def test_sampled_ideal_sine_splits_into_the_model_forces(offset_samples):
    fs, f, amplitude = 2000.0, 1.0, 0.04
    rng = np.random.default_rng(int(offset_samples * 100))
    offset = (offset_samples + rng.integers(0, 50)) / fs  # the cycle origin falls between samples
    rec = record("sine", f, amplitude, lambda t: sine_signals(t, f, amplitude, offset), fs=fs, n_cycles=6,
                 test_id="S1")
    loop = decompose_test(rec, cutoff_multiple=None)
    # origin found to sub-sample accuracy
    shift = (loop.t0 - offset) * f
    assert abs(shift - round(shift)) < 1e-9
    u, v, a = sine_signals(loop.times, f, amplitude, offset)
    # away from reversals (where the spline meets the friction step) the split is exact
    k = loop.keep_D
    assert k.mean() > 0.7
    v_pairs = np.concatenate([v[:, 0], v[:, 1]])
    np.testing.assert_allclose(loop.v_D[k], v_pairs[k], rtol=1e-6)
    np.testing.assert_allclose(loop.F_D[k], dissipative(v_pairs[k]), rtol=1e-6)
    G = ME * a + KE * u
    ki = loop.keep_ie
    np.testing.assert_allclose(loop.F_ie[ki], np.concatenate([G[:, 0], G[:, 2]])[ki], rtol=1e-6,
                               atol=1e-6 * np.max(np.abs(G)))


def test_filtered_ideal_sines_keep_the_inertial_elastic_part_and_the_consistent_fit_is_exact():
    # the 4f low-pass smears the friction step, but (i) zero phase keeps F_ie = Me*a_f + Ke*u_f
    # exactly and (ii) the friction fit that filters its model like the force recovers it.
    # The origin sits half a sample off the grid, so the sampled friction steps are placed
    # symmetrically too (a step's position is only known to the sample it falls in).
    fs, f = 400.0, 1.0
    loops = []
    for i, amplitude in enumerate((0.02, 0.06)):
        rec = record("sine", f, amplitude, lambda t, A=amplitude: sine_signals(t, f, A, 0.5 / fs), fs=fs,
                     n_cycles=10, test_id=f"S{i}")
        loops.append(decompose_test(rec, cycle=4, cutoff_multiple=4.0))
    for lp in loops:
        k = lp.keep_ie
        G = ME * lp.a_ie + KE * lp.u_ie
        np.testing.assert_allclose(lp.F_ie[k], G[k], rtol=1e-6, atol=1e-6 * np.max(np.abs(G)))
    from bayes_sst.classical import fit_dissipative_loops

    got = fit_dissipative_loops(loops, Me=ME, Ke=KE)
    assert got["Fmu"] == pytest.approx(FMU, rel=1e-5)
    assert got["Ce"] == pytest.approx(CE, rel=1e-5)
    assert got["alpha"] == pytest.approx(ALPHA, rel=1e-5)
    # the study's literal |F_D| against |v| on the filtered loop is what the consistent fit fixes
    literal = fit_dissipative_loops(loops, Me=ME, Ke=KE, friction_fit="pointwise")
    assert abs(literal["Fmu"] / FMU - 1) > 0.05


def test_a_cycle_that_is_not_there_is_a_clear_error():
    rec = record("sine", 1.0, 0.02, lambda t: sine_signals(t, 1.0, 0.02, 0.0), fs=200.0, n_cycles=5, test_id="S1")
    with pytest.raises(SeriesFormatError, match="steady cycle 9"):
        decompose_test(rec, cycle=9)


# ----------------------------------------------------------------- (b) Ke from a triangle


def test_triangle_flanks_give_ke_exactly():
    f, amplitude, corner = 0.5, 0.05, 0.08
    period = 1 / f
    times = quadruple_times(0.0, period, symmetric_instants(period, 200))
    u, v, a = triangle_signals(times, f, amplitude, corner)
    assert np.all(np.abs(v[a == 0.0]) == pytest.approx(amplitude / (period / 4 - corner / 2)))
    F_D, F_ie = split_force(ME * a + KE * u + dissipative(v))
    u_ie = np.concatenate([u[:, 0], u[:, 2]])
    a_ie = np.concatenate([a[:, 0], a[:, 2]])
    flank = a_ie == 0.0
    assert flank.sum() > 100
    # the hand method: on constant-velocity stretches F_ie = Ke*u, no mass needed
    assert stiffness_from_flanks(u_ie[flank], a_ie[flank], F_ie[flank]) == pytest.approx(KE, rel=1e-12)
    np.testing.assert_allclose(F_D, dissipative(np.concatenate([v[:, 0], v[:, 1]])), rtol=1e-12)


def test_sampled_triangle_and_sine_series_give_ke_and_me():
    fs = 4000.0
    tri = record("triangle", 0.5, 0.05, lambda t: triangle_signals(t - 0.11013, 0.5, 0.05, 0.08), fs=fs, n_cycles=5,
                 test_id="T1")
    sine = record("sine", 1.0, 0.04, lambda t: sine_signals(t, 1.0, 0.04, 0.07), fs=fs, n_cycles=5, test_id="S1")
    series = Series(name="synthetic", tests=(sine, tri))
    result = classical_identification(series, cutoff_multiple=None)
    loop = result.loops[1]
    assert _flank(loop, 0.2).sum() > 40
    # exact up to the cubic-spline reading of the samples (about 1e-9 here)
    assert result.pooled["Ke"] == pytest.approx(KE, rel=1e-6)
    assert result.pooled["Me"] == pytest.approx(ME, rel=1e-6)
    assert result.pooled["Fmu"] == pytest.approx(FMU, rel=1e-6)
    assert result.pooled["alpha"] == pytest.approx(ALPHA, rel=1e-6)
    assert "triangle" in result.method["Ke_source"]


# ----------------------------------------------------------------- (c) the dissipative fit


def test_dissipative_fit_recovers_friction_damping_and_exponent():
    speed = np.linspace(0.02, 0.6, 60)
    force = FMU + CE * speed**ALPHA
    got = fit_dissipative(speed, force)
    assert got["Fmu"] == pytest.approx(FMU, rel=1e-6)
    assert got["Ce"] == pytest.approx(CE, rel=1e-6)
    assert got["alpha"] == pytest.approx(ALPHA, rel=1e-6)
    # signs do not matter (|F_D| against |v|), and a fixed exponent makes it linear
    fixed = fit_dissipative(-speed, -force, alpha=ALPHA)
    assert fixed["Fmu"] == pytest.approx(FMU, rel=1e-9) and fixed["Ce"] == pytest.approx(CE, rel=1e-9)
    laminar = fit_dissipative(speed, 5_000.0 + 40_000.0 * speed)
    assert laminar["alpha"] == pytest.approx(1.0, rel=1e-6)
    with pytest.raises(ValueError, match="distinct speeds"):
        fit_dissipative(np.full(5, 0.1), np.full(5, 1.0))


# ----------------------------------------------------------------- (d) the quiet virtual table


@pytest.fixture(scope="module")
def quiet_series():
    from bayes_sst.twin import simulate

    return simulate("sst-paper", seed=1, noise="quiet")


@pytest.fixture(scope="module")
def quiet_result(quiet_series):
    return classical_identification(quiet_series)


def test_quiet_virtual_table_within_five_percent(quiet_series, quiet_result):
    truth = quiet_series.extra["truth"]
    errors = {name: quiet_result.pooled[name] / truth[name] - 1 for name in ("Me", "Ke", "Ce", "alpha", "Fmu")}
    print("classical relative errors, quiet twin seed 1:", {k: f"{100 * e:+.2f}%" for k, e in errors.items()})
    for name in ("Me", "Ke", "Fmu"):  # the acceptance figure
        assert abs(errors[name]) < 0.05, (name, errors[name])
    assert abs(errors["Ce"]) < 0.05 and abs(errors["alpha"]) < 0.05


def test_per_test_values_and_spread(quiet_series, quiet_result):
    rows = {row["id"]: row for row in quiet_result.per_test}
    assert len(rows) == 20
    sines = [r for r in rows.values() if r["kind"] == "sine"]
    triangles = [r for r in rows.values() if r["kind"] == "triangle"]
    assert all({"Me", "Ce", "Fmu"} <= set(r) and "Ke" not in r for r in sines)
    # a triangle fixes Ke, but not Fmu apart from Ce (its points sit at one flank speed)
    assert all("Ke" in r and not {"Me", "Ce", "Fmu"} & set(r) for r in triangles)
    spread = quiet_result.spread
    assert spread["Me"]["n"] == 16 and spread["Ke"]["n"] == 4 and spread["Fmu"]["n"] == 16
    ke = [r["Ke"] for r in triangles]
    assert spread["Ke"]["sd"] == pytest.approx(np.std(ke, ddof=1))
    assert spread["Ke"]["relative_sd"] == pytest.approx(np.std(ke, ddof=1) / np.mean(ke))
    # no spread in the twin: per-test Ke, Fmu agree with the truth to a few per cent
    truth = quiet_series.extra["truth"]
    assert all(abs(k / truth["Ke"] - 1) < 0.03 for k in ke)
    assert all(abs(r["Fmu"] / truth["Fmu"] - 1) < 0.06 for r in sines)
    data = quiet_result.to_json()
    json.dumps(data, allow_nan=False)
    assert set(data["pooled"]) == {"Me", "Ke", "Ce", "alpha", "Fmu"}


def test_records_the_fit_refuses_are_refused_here_too(quiet_series):
    """u in millimetres, or a displacement channel that does not move, gave numbers without a word."""
    from dataclasses import replace

    first = quiet_series.periodic_tests[0]
    for columns, words in ((dict(first.columns, u=1000.0 * first.u), "is u in metres"),
                           (dict(first.columns, u=np.zeros(len(first.u))), "u does not move")):
        spoiled = replace(quiet_series, tests=(TestRecord(first.spec, columns),) + tuple(quiet_series.tests[1:]))
        with pytest.raises(SeriesFormatError, match=words):
            classical_identification(spoiled)


# ----------------------------------------------------------------- (e) Ke from the table


def test_fallback_ke_from_the_table_description():
    table = {"deck_mass_kg": 12_000.0, "strut": {"p0_pa": P0, "area_m2": AREA, "h_m": H}}
    by_hand = 4 * P0 * AREA / H
    assert table_stiffness(table) == pytest.approx(by_hand, rel=1e-15)
    assert table_stiffness({"strut": {"p0_pa": P0, "area_m2": AREA}}) is None
    sines = tuple(
        record("sine", f, A, lambda t, f=f, A=A: sine_signals(t, f, A, 0.01), fs=1000.0, n_cycles=5, test_id=f"S{i}")
        for i, (f, A) in enumerate(((0.5, 0.05), (1.5, 0.02)))
    )
    result = classical_identification(Series(name="no-triangles", tests=sines, table=table), cutoff_multiple=None)
    assert result.pooled["Ke"] == pytest.approx(by_hand, rel=1e-15)
    assert "4*p0*A/h" in result.method["Ke_source"]
    assert "Ke" not in result.spread or result.spread["Ke"]["n"] == 0
    with pytest.raises(SeriesFormatError, match="no triangle test"):
        classical_identification(Series(name="bare", tests=sines), cutoff_multiple=None)


# ----------------------------------------------------------------- (f) the command


def _parser():
    parser = argparse.ArgumentParser(prog="bayes-sst")
    add_parser(parser.add_subparsers(dest="command", required=True))
    return parser


def test_command_writes_classical_json_and_refuses_an_existing_folder(tmp_path, quiet_series, capsys):
    series_dir = tmp_path / "series"
    write_series(quiet_series, series_dir)
    out = tmp_path / "classical"
    args = _parser().parse_args(["classical", str(series_dir), "--out", str(out)])
    assert args.cycle == -2 and args.cutoff_multiple == 4.0 and not args.force
    assert args.handler(args) == 0
    printed = capsys.readouterr().out
    assert "Me" in printed and "kN" in printed and " t " in printed
    data = json.loads((out / "classical.json").read_text())
    assert set(data) >= {"method", "pooled", "per_test", "spread"}
    assert data["pooled"]["Ke"] == pytest.approx(720_000.0, rel=0.05)
    assert len(data["per_test"]) == 20 and {"mean", "sd", "relative_sd", "n"} <= set(data["spread"]["Me"])

    before = (out / "classical.json").read_text()
    again = _parser().parse_args(["classical", str(series_dir), "--out", str(out), "--cycle", "-3"])
    with pytest.raises(OutputExistsError, match="--force"):
        again.handler(again)
    assert (out / "classical.json").read_text() == before
    forced = _parser().parse_args(["classical", str(series_dir), "--out", str(out), "--cycle", "-3", "--force"])
    assert forced.handler(forced) == 0
    assert json.loads((out / "classical.json").read_text())["method"]["cycle"] == -3
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


# ----------------------------------------------------------------- physics priors, summary


def test_physics_prior_report_by_hand():
    from bayes_sst.inference._priors import make_priors, physics_centres, physics_prior_report

    table = {
        "deck_mass_kg": 12_000.0,
        "actuator_mass_kg": 900.0,
        "moving_parts_kg": {"swivel": 200.0, "rod": 100.0},
        "bearing_friction": {"mu": 0.0127},
        "strut": {"p0_pa": P0, "area_m2": AREA, "h_m": H, "l0_m": L0, "gamma": GAMMA},
    }
    report = physics_prior_report(table)
    f_hd = 4 * P0 * AREA
    ke = f_hd / H
    assert report["Me"]["value"] == pytest.approx(13_200.0)
    assert report["Ke"]["value"] == pytest.approx(ke, rel=1e-15)
    assert report["F_hd"]["value"] == pytest.approx(f_hd, rel=1e-15)
    assert report["Kpe"]["value"] == pytest.approx(0.5 * (GAMMA * H / L0 - 1) * ke, rel=1e-15)
    assert report["Fmu"]["value"] == pytest.approx(0.0127 * (f_hd + 12_000.0 * 9.80665), rel=1e-15)
    assert all("relation" in entry and "inputs" in entry for entry in report.values())
    centres = physics_centres(table)
    assert centres["Me"] == pytest.approx(13_200.0) and centres["Ce"] == 20_000.0
    assert make_priors("physics", table).describe()["relations"]["Fmu"].startswith("Fmu = mu_e")
    # what the description lacks stays generic, and says why
    bare = physics_prior_report({"deck_mass_kg": 9_500.0})
    assert bare["Ke"]["value"] is None and "missing" in bare["Ke"]["relation"]
    assert physics_centres({"deck_mass_kg": 9_500.0})["Ke"] == 1.0e6


def test_summary_shows_published_classical_posterior_and_prior_movement():
    from bayes_sst.inference._summary import format_summary

    parameters = {
        name: {"mean": value * 1.01, "sd": value * 0.02, "q05": value * 0.98, "q95": value * 1.04,
               "r_hat": 1.001, "ess_bulk": 900.0, "ess_tail": 800.0}
        for name, value in {"Me": 13_200.0, "Ke": 720_000.0, "Ce": 29_600.0, "alpha": 0.5, "Fmu": 12_500.0}.items()
    }
    summary = {
        "series": "x", "parameters": parameters, "divergences": 0, "n_tests": 20, "n_samples": 40_000,
        "seconds": 12.0, "warnings": [], "converged": True, "max_r_hat": 1.001, "min_ess_bulk": 900.0,
        "between_test_spread": {n: {"relative_sd_mean": 0.02, "relative_sd_q05": 0.01, "relative_sd_q95": 0.03}
                                for n in ("Me", "Ke", "Ce", "Fmu")},
    }
    plain = format_summary(summary)
    assert "published" in plain and "classical" not in plain and "moved" not in plain
    assert "WARNING" not in plain
    note = "a note about the data"
    noted = format_summary(dict(summary, warnings=[note], notes=[note]))
    assert "read these before using the numbers" in noted and "did not pass" not in noted
    failed = format_summary(dict(summary, warnings=["R-hat 1.02 exceeds 1.01"], converged=False))
    assert "the sampler did not pass its checks" in failed and "read these" not in failed
    both = format_summary(dict(summary, warnings=["R-hat 1.02 exceeds 1.01", note], notes=[note], converged=False))
    head, _, tail = both.partition("read these before using the numbers")
    assert "R-hat 1.02" in head and note not in head and note in tail
    classical = {"pooled": {"Me": 13_100.0, "Ke": 715_000.0, "Ce": 30_000.0, "alpha": 0.49, "Fmu": 12_300.0}}
    priors = {"source": "physics", "centres": {"Me": 12_000.0, "Ke": 720_000.0, "Ce": 20_000.0, "Fmu": 12_500.0},
              "alpha": {"mean": 0.75}, "relations": {"Me": "Me = deck_mass_kg"}}
    text = format_summary(summary, classical=classical, priors=priors)
    assert "classical" in text and "moved" in text and "Me = deck_mass_kg" in text
    assert "Ke, Ce, alpha, Fmu: no component relation" in text
    me_line = next(line for line in text.splitlines() if line.startswith("Me "))
    assert "13.1" in me_line and "+11.1%" in me_line  # 13.332 t / 12 t - 1
    # generic priors: no "moved" column
    assert "moved" not in format_summary(summary, classical=classical, priors={"source": "generic"})


def test_a_classical_coefficient_at_or_below_zero_is_flagged():
    from bayes_sst.classical._identify import format_classical, unphysical_warning

    pooled = {"Me": 13_200.0, "Ke": 7.2e5, "Ce": 29_600.0, "alpha": 0.15, "Fmu": 12_500.0}
    assert unphysical_warning(pooled) is None
    pooled["Fmu"] = -13_260.0
    assert unphysical_warning(pooled).startswith("Fmu at or below zero")
    text = format_classical({"series": "x", "method": {}, "pooled": pooled, "per_test": []})
    assert text.splitlines()[-1].startswith("WARNING: Fmu at or below zero")
