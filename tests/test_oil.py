"""The oil column: analytic frequency, the twin's broadband tests, and the resonance measured from them."""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest

from bayes_sst.io import OutputExistsError, Series, SeriesFormatError, TestRecord, TestSpec, load_series, write_series
from bayes_sst.oil import (
    analytic_oil_frequency,
    frequency_response,
    locate_resonance,
    oil_column_resonance,
    oil_frequency_vs_payload,
)
from bayes_sst.oil._command import add_parser
from bayes_sst.twin import PRESETS, simulate
from bayes_sst.twin._broadband import broadband_command
from bayes_sst.twin._linear import closed_loop_response, closed_loop_resonance_hz
from bayes_sst.twin._plan import as_plan_item, broadband_plan

TRUTH = PRESETS["sst-paper"]
TABLE = {
    "deck_mass_kg": 13200.0,
    "oil": {"bulk_modulus_pa": 1.4e9, "piston_area_m2": 0.02, "oil_volume_m3": 0.0026276},
}
PAYLOADS = (0.0, 10_000.0, 25_000.0)
# One noise test per payload and an earthquake on the empty table (pooled with its noise test).
PLAN = broadband_plan(PAYLOADS, ("noise",)) + broadband_plan((0.0,), ("earthquake",))


# --- analytic ------------------------------------------------------------------------------------

def test_analytic_frequency_matches_hand_values():
    # k_oil = 2*1.4e9*0.02^2/0.0026276 = 4.2624e8 N/m; f = sqrt(k_oil/M)/(2*pi).
    assert analytic_oil_frequency(TABLE) == pytest.approx(28.600, abs=0.005)
    assert analytic_oil_frequency(TABLE, 10_000.0) == pytest.approx(21.573, abs=0.005)
    assert analytic_oil_frequency(TABLE, 25_000.0) == pytest.approx(16.812, abs=0.005)
    # Total volume split in two halves: 4*beta, sqrt(2) higher.
    assert analytic_oil_frequency(TABLE, chambers=4) == pytest.approx(40.446, abs=0.005)
    curve = oil_frequency_vs_payload(TABLE, PAYLOADS)
    assert [p for p, _ in curve] == list(PAYLOADS)
    assert [f for _, f in curve] == pytest.approx([28.600, 21.573, 16.812], abs=0.005)


def test_analytic_moving_mass_sources_and_errors():
    deck_only = dict(TABLE, deck_mass_kg=12_000.0)
    assert analytic_oil_frequency(deck_only, moving_mass_kg=13_200.0) == pytest.approx(28.600, abs=0.005)
    assert analytic_oil_frequency(dict(deck_only, moving_mass_kg=13_200.0)) == pytest.approx(28.600, abs=0.005)
    assert analytic_oil_frequency(deck_only) == pytest.approx(analytic_oil_frequency(TABLE) * math.sqrt(13.2 / 12.0))
    with pytest.raises(ValueError, match="oil.oil_volume_m3"):
        analytic_oil_frequency({"deck_mass_kg": 1.0, "oil": {"bulk_modulus_pa": 1e9, "piston_area_m2": 0.01}})
    with pytest.raises(ValueError, match="deck_mass_kg"):
        analytic_oil_frequency({"oil": TABLE["oil"]})
    with pytest.raises(ValueError, match="chambers"):
        analytic_oil_frequency(TABLE, chambers=3)


# --- the twin's broadband tests ---------------------------------------------------------------------

@pytest.fixture(scope="module")
def broadband():
    return simulate(plan=PLAN, seed=1)


def test_broadband_commands_are_consistent_and_within_limits():
    dt = 1.0 / 4000.0
    t = np.arange(int(21.0 / dt)) * dt
    for signal in ("noise", "earthquake"):
        c = broadband_command(signal, t, rng=np.random.default_rng(4), duration_s=20.0,
                              peak_acceleration=5.0, rest_s=0.5)
        assert c.u[0] == c.v[0] == 0.0 and abs(c.u[-1]) < 1e-12 and abs(c.v[-1]) < 1e-12
        assert np.abs(c.a).max() == pytest.approx(5.0)
        # Central differences against the exact (spectral) derivatives: agreement to their own error.
        assert np.allclose(np.gradient(c.u, dt), c.v, atol=1e-3 * np.abs(c.v).max())
        assert np.allclose(np.gradient(c.v, dt), c.a, atol=1e-2 * np.abs(c.a).max())


def test_broadband_tests_in_the_series(broadband, tmp_path):
    assert [r.id for r in broadband.tests] == ["B01", "B02", "B03", "B04"]
    for record in broadband.tests:
        spec = record.spec
        assert spec.kind == "broadband" and spec.frequency_hz is None and spec.amplitude_m is None
        assert record.sample_rate_hz == pytest.approx(1000.0)
        assert {"u_cmd", "a_cmd", "a"} <= set(record.columns)
        assert spec.extra["peak_displacement_m"] < TRUTH.stroke
        truth = spec.extra["truth"]
        mass = TRUTH.Me + spec.payload_kg
        assert truth["f_oil_hz"] == pytest.approx(TRUTH.f_oil_hz(mass))
        assert truth["resonance_hz"] == pytest.approx(closed_loop_resonance_hz(TRUTH, mass))
    resonances = [broadband.tests[i].spec.extra["truth"]["resonance_hz"] for i in range(3)]
    assert resonances[0] > resonances[1] > resonances[2]  # payload lowers it
    assert broadband.extra["truth"]["resonance_hz"] == pytest.approx(resonances[0])
    # Written, loaded and run again from the loaded specs: the same commands.
    write_series(broadband, tmp_path / "bb")
    loaded = load_series(tmp_path / "bb")
    assert loaded.tests[3].spec.extra["signal"] == "earthquake"
    again = simulate(plan=[r.spec for r in loaded.tests], seed=1, noise="quiet")
    for a, b in zip(broadband.tests, again.tests):
        assert np.array_equal(a.get("a_cmd"), b.get("a_cmd"))


def test_broadband_plan_items_are_checked():
    with pytest.raises(ValueError, match="signal"):
        as_plan_item({"kind": "broadband"})
    with pytest.raises(ValueError, match="frequency_hz"):
        as_plan_item({"kind": "broadband", "signal": "noise", "frequency_hz": 2.0})
    with pytest.raises(ValueError, match="stroke"):
        simulate(plan=[{"kind": "broadband", "signal": "earthquake", "peak_acceleration_m_s2": 11.0,
                        "duration_s": 5.0}], seed=0)
    item = as_plan_item({"kind": "broadband", "signal": "noise", "sample_rate_hz": 500})
    assert item.sample_rate_hz == 500.0 and item.duration_s > 0 and item.peak_acceleration_m_s2 > 0


def test_linear_twin_frf_is_the_linearised_closed_loop():
    # Damping and friction off, no sensor noise: the measured H1 must be the model's H.
    series = simulate(plan=broadband_plan((0.0, 25_000.0), ("noise",), duration_s=30.0), seed=2,
                      noise="quiet", truth_overrides={"Ce": 0.0, "Fmu": 0.0})
    for record in series.tests:
        frf = frequency_response([record])
        band = (frf.frequency_hz >= 5.0) & (frf.frequency_hz <= 50.0)
        model = closed_loop_response(TRUTH, TRUTH.Me + record.spec.payload_kg, frf.frequency_hz[band])
        assert np.allclose(np.abs(frf.h[band]), np.abs(model), rtol=0.03)
        found = locate_resonance(frf, n_bootstrap=50).frequency_hz
        assert found == pytest.approx(record.spec.extra["truth"]["resonance_hz"], rel=0.005)


# --- resonance from data ---------------------------------------------------------------------------

def test_resonance_of_the_twin_within_three_percent_per_payload(broadband):
    result = oil_column_resonance(broadband)
    assert [p.payload_kg for p in result.per_payload] == list(PAYLOADS)
    errors = {}
    for p in result.per_payload:
        true = next(r for r in broadband.tests if r.spec.payload_kg == p.payload_kg).spec.extra["truth"]
        r = p.resonance
        errors[p.payload_kg] = r.frequency_hz / true["resonance_hz"] - 1.0
        assert abs(errors[p.payload_kg]) < 0.03, (p.payload_kg, errors)
        assert r.low_hz <= true["resonance_hz"] <= r.high_hz
        assert r.interval == "half-power" and r.interval_rule == "wider"
        assert r.bootstrap_low_hz <= r.frequency_hz <= r.bootstrap_high_hz
        assert r.coherence_mean > 0.9 and r.fit.method == "second-order"
        peak_bin = np.argmin(np.abs(p.response.frequency_hz - r.frequency_hz))
        assert p.response.coherence[peak_bin] > 0.9
        assert p.analytic_hz == pytest.approx(TRUTH.f_oil_hz(12_000.0 + p.payload_kg))  # deck_mass_kg
    assert len(result.per_payload[0].response.tests) == 2  # noise and earthquake pooled
    print("relative errors of the located resonance:", {k: f"{100 * v:+.2f} %" for k, v in errors.items()})


def _second_order_record(test_id, fs, seed, seconds=120.0, f_n=20.0, zeta=0.05):
    """A broadband test whose motion is white command through w_n^2/(s^2 + 2 zeta w_n s + w_n^2),
    with output noise of 0.3 times the command's sd."""
    n = int(seconds * fs)
    rng = np.random.default_rng(seed)
    x = rng.standard_normal(n)
    f = np.fft.rfftfreq(n, 1.0 / fs)
    s, w_n = 2j * np.pi * f, 2.0 * np.pi * f_n
    y = np.fft.irfft(np.fft.rfft(x) * w_n**2 / (s**2 + 2.0 * zeta * w_n * s + w_n**2), n)
    y += 0.3 * rng.standard_normal(n)
    t = np.arange(n) / fs
    return TestRecord(TestSpec(test_id, f"{test_id}.csv", "broadband"), {"t": t, "u": y, "F": 0 * t, "a": y, "a_cmd": x})


def test_second_order_system_recovers_its_natural_frequency():
    f_n, zeta = 20.0, 0.05
    record = _second_order_record("B1", 500.0, 7, f_n=f_n, zeta=zeta)
    frf = frequency_response([record])
    r = locate_resonance(frf, interval="random", n_bootstrap=200)
    assert r.fit.natural_frequency_hz == pytest.approx(f_n, rel=0.01)
    assert r.fit.damping_ratio == pytest.approx(zeta, abs=0.01)
    assert r.low_hz <= f_n * math.sqrt(1.0 - 2.0 * zeta**2) <= r.high_hz
    assert r.high_hz - r.low_hz < 0.02 * f_n


def test_tests_at_different_rates_are_pooled_on_the_bins_they_share():
    """An independent generator recorded two broadband tests of one payload at 250 and 1000 Hz,
    and the pooled estimate refused them (diagnose stopped there). A 2 s segment gives both
    0.5 Hz bins: they are pooled up to the lower Nyquist, less its bin, with every segment
    counted, and the resonance read as from either alone."""
    slow, fast = _second_order_record("B1", 250.0, 1), _second_order_record("B2", 1000.0, 2)
    pooled = frequency_response([fast, slow])
    alone = frequency_response([slow])
    np.testing.assert_allclose(pooled.frequency_hz, alone.frequency_hz[:-1])
    assert pooled.frequency_hz[-1] == pytest.approx(124.5) and pooled.resolution_hz == pytest.approx(0.5)
    assert pooled.n_segments == alone.n_segments + frequency_response([fast]).n_segments
    assert pooled.tests == ("B2", "B1") and pooled.sample_rate_hz == 250.0
    # the exact response at 10 Hz, by hand: w_n^2/(w_n^2 - w^2 + 2j*zeta*w_n*w)
    k = int(np.argmin(np.abs(pooled.frequency_hz - 10.0)))
    exact = 20.0**2 / (20.0**2 - 10.0**2 + 2j * 0.05 * 20.0 * 10.0)
    assert abs(pooled.h[k] - exact) < 0.02 * abs(exact)
    r = locate_resonance(pooled, interval="random", n_bootstrap=50)
    assert r.fit.natural_frequency_hz == pytest.approx(20.0, rel=0.01)
    # a rate whose 2 s segment is no whole number of samples has other bins: named, not pooled
    odd = _second_order_record("B3", 333.3, 3, seconds=60.0)
    with pytest.raises(ValueError, match=r"same bin spacing.*'B3'"):
        frequency_response([slow, odd])


def test_a_broadband_test_without_a_response_is_noted_by_the_diagnosis_not_fatal():
    from bayes_sst.diagnosis._oil import oil_column_check

    good = _second_order_record("B1", 500.0, 4, seconds=60.0)
    short = TestRecord(TestSpec("B2", "B2.csv", "broadband", payload_kg=5000.0),
                       {name: values[:750] for name, values in good.columns.items()})  # 1.5 s < one segment
    skipped = []
    check = oil_column_check(Series("mixed", (good, short)), skipped=skipped)
    assert [p["payload_kg"] for p in check["per_payload"]] == [0.0]
    assert len(skipped) == 1 and "['B2'] at 5000 kg" in skipped[0] and "shorter than one" in skipped[0]
    skipped = []
    assert oil_column_check(Series("short", (short,)), skipped=skipped) is None and len(skipped) == 1


# --- command line ----------------------------------------------------------------------------------

def _ocrf(*argv):
    parser = argparse.ArgumentParser()
    add_parser(parser.add_subparsers())
    args = parser.parse_args(["ocrf", *map(str, argv)])
    return args.handler(args)


def test_cli_writes_ocrf_json_and_refuses_an_existing_folder(broadband, tmp_path, capsys):
    write_series(broadband, tmp_path / "series")
    out = tmp_path / "ocrf"
    assert _ocrf(tmp_path / "series", "--out", out) == 0
    data = json.loads((out / "ocrf.json").read_text())
    assert {"f_oil_hz", "f_oil_low_hz", "f_oil_high_hz", "f_oil_analytic_hz", "chambers", "per_payload",
            "method"} <= set(data)
    assert data["chambers"] == 2 and data["interval"] == "half-power"
    assert [p["payload_kg"] for p in data["per_payload"]] == list(PAYLOADS)
    assert {"payload_kg", "f_oil_hz", "low", "high", "analytic_hz", "n_tests"} <= set(data["per_payload"][0])
    assert data["f_oil_hz"] == pytest.approx(28.6, rel=0.03)
    assert "28." in capsys.readouterr().out
    with pytest.raises(OutputExistsError):
        _ocrf(tmp_path / "series", "--out", out)
    assert _ocrf(tmp_path / "series", "--out", out, "--force", "--chambers", "4", "--interval", "random") == 0
    data = json.loads((out / "ocrf.json").read_text())
    assert data["chambers"] == 4 and data["interval"] == "random"
    assert data["f_oil_analytic_hz"] == pytest.approx(TRUTH.f_oil_hz(12_000.0) * math.sqrt(2.0))


def test_cli_names_the_series_file_when_it_has_no_broadband_tests(tmp_path):
    t = np.arange(400) / 100.0
    spec = TestSpec("S01", "S01.csv", "sine", frequency_hz=1.0, amplitude_m=0.01)
    series = Series("sines", (TestRecord(spec, {"t": t, "u": np.sin(t), "F": t}),))
    write_series(series, tmp_path / "sines")
    with pytest.raises(SeriesFormatError, match=r"sines/series\.json.*no broadband tests"):
        _ocrf(tmp_path / "sines", "--out", tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_a_payload_without_a_usable_response_is_skipped_not_fatal(broadband):
    short = broadband.tests[0]
    spec = TestSpec("X01", "X01.csv", "broadband", payload_kg=5000.0)
    stub = TestRecord(spec, {name: values[:1500] for name, values in short.columns.items()})  # 1.5 s < one segment
    series = Series("mixed", broadband.tests[:1] + (stub,), table=broadband.table)
    result = oil_column_resonance(series, n_bootstrap=20).to_json()
    assert [p["payload_kg"] for p in result["per_payload"]] == [0.0]
    assert result["skipped"][0]["tests"] == ["X01"] and "shorter than one" in result["skipped"][0]["reason"]
    with pytest.raises(ValueError, match="no resonance could be located"):
        oil_column_resonance(Series("stub", (stub,)))
