"""The command line: verbs, refusals, error messages, start-up cost."""

import json
import subprocess
import sys

import pytest

from bayes_sst.cli import main


def test_help_does_not_import_the_numerical_stack():
    code = (
        "import sys, contextlib, io\n"
        "from bayes_sst.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    try: main(['--help'])\n"
        "    except SystemExit: pass\n"
        "heavy = [m for m in ('jax', 'numpyro', 'arviz', 'matplotlib', 'xarray', 'scipy') if m in sys.modules]\n"
        "print(','.join(heavy))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_physics_layer_does_not_pull_in_inference_or_plotting():
    code = "import sys, bayes_sst.physics; print(','.join(m for m in ('numpyro', 'matplotlib', 'arviz') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_simulate_fit_summary_round_trip(tmp_path, capsys):
    series = tmp_path / "series"
    assert main(["simulate", "--out", str(series), "--seed", "3"]) == 0
    manifest = json.loads((series / "series.json").read_text())
    assert manifest["format"] == "sst-series/1" and len(manifest["tests"]) == 20

    run = tmp_path / "run"
    assert main(["fit", str(series), "--out", str(run), "--chains", "2", "--draws", "60", "--warmup", "60",
                 "--extensions", "1"]) == 0
    printed = capsys.readouterr().out
    assert "published" in printed and "Me" in printed
    summary = json.loads((run / "summary.json").read_text())
    assert summary["n_tests"] == 20
    # 2 x 60 draws are far from a bulk ESS of 400: the chains went on once for 60 more
    from bayes_sst.io import read_run_tree

    assert json.loads(read_run_tree(run).attrs["sampler"])["draws"] == 120
    assert (run / "posterior.nc").is_file() and (run / "summary.txt").is_file()

    assert main(["summary", str(run)]) == 0
    assert "kN" in capsys.readouterr().out

    # an existing run folder is refused, untouched, unless --force
    before = (run / "summary.json").read_text()
    assert main(["fit", str(series), "--out", str(run)]) == 2
    err = capsys.readouterr().err
    assert "already exists" in err and "--force" in err
    assert (run / "summary.json").read_text() == before


def test_malformed_series_gives_a_message_not_a_traceback(tmp_path, capsys):
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "series.json").write_text('{"format": "sst-series/2", "name": "x", "tests": []}')
    assert main(["fit", str(bad), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert "series.json" in err and "sst-series/2" in err and "Traceback" not in err
    assert not (tmp_path / "run").exists()


def test_summary_of_a_folder_that_is_not_a_run(tmp_path, capsys):
    assert main(["summary", str(tmp_path)]) == 2
    assert "summary.json" in capsys.readouterr().err


def test_a_library_fault_inside_the_package_is_reported_as_internal_with_its_place(tmp_path, capsys, monkeypatch):
    import numpy as np

    import bayes_sst.cli as cli
    from bayes_sst.signals._filters import zero_phase_lowpass

    # scipy's filtfilt refuses a record shorter than its padding: a ValueError that bayes_sst
    # did not word, which must not pass for a message about the input
    monkeypatch.setattr(cli, "_cmd_summary", lambda args: zero_phase_lowpass(np.zeros(3), 10.0, 100.0))
    assert main(["summary", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "internal error at bayes_sst/signals/_filters.py:" in err and "padlen" in err
    assert "Traceback" not in err
    monkeypatch.setenv("BAYES_SST_TRACEBACK", "1")
    assert main(["summary", str(tmp_path)]) == 2
    assert "Traceback" in capsys.readouterr().err
    # the package's own messages stay plain errors
    monkeypatch.undo()
    assert main(["summary", str(tmp_path / "nothing")]) == 2
    err = capsys.readouterr().err
    assert "error:" in err and "internal" not in err


@pytest.mark.parametrize("argv", [["fit"], ["simulate"], ["nonsense"]])
def test_usage_errors_exit_nonzero(argv):
    with pytest.raises(SystemExit) as excinfo:
        main(argv)
    assert excinfo.value.code == 2


def test_fit_shared_option_fixes_the_mass_between_tests(tmp_path):
    series = tmp_path / "series"
    assert main(["simulate", "--out", str(series), "--seed", "4"]) == 0
    run = tmp_path / "run"
    argv = ["fit", str(series), "--out", str(run), "--chains", "2", "--draws", "60", "--warmup", "60", "--shared", "Me",
            "--extensions", "0"]
    assert main(argv) == 0
    summary = json.loads((run / "summary.json").read_text())
    assert summary["between_test_spread"]["Me"]["relative_sd_q95"] == 0.0
    assert summary["between_test_spread"]["Ke"]["relative_sd_q95"] > 0.0
    assert "shared by all tests" in (run / "summary.txt").read_text()


def test_a_test_the_analysis_refuses_can_be_left_out_and_the_run_remembers_it(tmp_path, capsys):
    from dataclasses import replace

    import numpy as np

    from bayes_sst.inference._predictive import run_prepared, run_series
    from bayes_sst.io import load_series, read_run_tree, write_series
    from bayes_sst.signals._cycles import fundamental_phase
    from bayes_sst.twin import simulate

    made = simulate("sst-paper", seed=5)
    spoiled_id = made.tests[3].id
    record = made.tests[3]
    # every other cycle (from an upward crossing of the fundamental, as the analysis counts
    # them) at 80 % of the amplitude: no two steady cycles in a row
    _, phase = fundamental_phase(record.u, record.t, record.spec.frequency_hz)
    cycle = np.floor((2 * np.pi * record.spec.frequency_hz * record.t + phase) / (2 * np.pi)).astype(int)
    columns = dict(record.columns, u=record.u * np.where(cycle % 2 == 0, 1.0, 0.8))
    tests = list(made.tests)
    tests[3] = replace(record, columns=columns)
    series = tmp_path / "series"
    write_series(replace(made, tests=tuple(tests)), series)

    run = tmp_path / "run"
    fit_argv = ["fit", str(series), "--out", str(run), "--chains", "2", "--draws", "60", "--warmup", "60",
                "--extensions", "0"]
    assert main(fit_argv) == 2
    err = capsys.readouterr().err
    assert f"{spoiled_id}.csv" in err and "steady cycle" in err and f"--exclude-test {spoiled_id}" in err, err
    assert not run.exists()

    assert main(fit_argv + ["--exclude-test", spoiled_id]) == 0
    assert f"tests {spoiled_id} of the manifest are left out" in capsys.readouterr().out
    summary = json.loads((run / "summary.json").read_text())
    assert summary["left_out"] == [spoiled_id] and summary["n_tests"] == len(made.tests) - 1
    # the report, diagnosis and design read the run's series back from its folder without it
    prepared = run_prepared(read_run_tree(run))
    assert [t.id for t in prepared] == [t.id for t in made.tests if t.id != spoiled_id]
    # and a series passed whole is prepared without it as well
    assert len(run_prepared(read_run_tree(run), load_series(series))) == len(made.tests) - 1
    # the test's file is not read back at all: a broken one does not matter, whether the series
    # comes from the run's record or from --series (report, design, diagnose --run)
    (series / f"{spoiled_id}.csv").write_text("t,u,F\nbroken\n")
    tree = read_run_tree(run)
    assert len(run_prepared(tree)) == len(made.tests) - 1
    assert spoiled_id not in [t.id for t in run_series(tree, "diagnose", path=series).tests]
    # leaving a test out of a report without --series is refused: the run's series is its own
    assert main(["report", str(run), "--out", str(tmp_path / "report"), "--exclude-test", "T01"]) == 2
    assert "--series" in capsys.readouterr().err and not (tmp_path / "report").exists()


@pytest.mark.parametrize("option, first, second, expected, spoiled, named", [
    ("--exclude-test", "T05,T11", "T02", ["T05", "T11", "T02"], ",", None),
    ("--shared", "Me,Ke", "Fmu", ["Me", "Ke", "Fmu"], "Me,mass", "'Me,mass'"),
])
def test_list_options_take_comma_separated_items_and_repeat_without_swallowing_the_series(
        capsys, option, first, second, expected, spoiled, named):
    """--exclude-test ID[,ID...] and --shared NAME[,NAME...]: one token per use (nargs='+'
    swallowed a SERIES written after it), repeatable; a spoiled value is refused, by name."""
    from bayes_sst.cli import build_parser

    parser = build_parser()
    attribute = option.lstrip("-").replace("-", "_")
    args = parser.parse_args(["fit", option, first, "SERIES", "--out", "RUN", option, second])
    assert args.series == "SERIES" and getattr(args, attribute) == expected
    assert getattr(parser.parse_args(["fit", "SERIES", "--out", "RUN"]), attribute) == []
    with pytest.raises(SystemExit):
        parser.parse_args(["fit", "SERIES", "--out", "RUN", option, spoiled])
    if named:
        assert named in capsys.readouterr().err


def _small_series(folder):
    from bayes_sst.io import write_series
    from bayes_sst.twin import default_plan, simulate

    write_series(simulate("sst-paper", seed=2, plan=default_plan()[:3]), folder)
    return folder


def test_force_never_replaces_the_input_or_a_folder_of_another_kind(tmp_path, capsys, monkeypatch):
    series = _small_series(tmp_path / "series")
    files = sorted(p.name for p in series.iterdir())
    # the series itself, a folder holding it, the folder the command runs in
    monkeypatch.chdir(tmp_path)
    for out, words in ((series, "would replace the series folder"), (tmp_path, "would replace the series folder"),
                       (".", "would replace the series folder")):
        assert main(["fit", str(series), "--out", str(out), "--force"]) == 2
        assert words in capsys.readouterr().err
    assert sorted(p.name for p in series.iterdir()) == files
    # another series, and a run, are not an earlier output of fit or of simulate
    other = _small_series(tmp_path / "other")
    assert main(["fit", str(series), "--out", str(other), "--force"]) == 2
    assert "holds a test series (series.json)" in capsys.readouterr().err
    assert (other / "series.json").is_file()
    run = tmp_path / "run"
    run.mkdir()
    (run / "posterior.nc").write_bytes(b"kept")
    assert main(["simulate", "--out", str(run), "--force"]) == 2
    assert "holds a run of bayes-sst fit (posterior.nc)" in capsys.readouterr().err
    assert main(["report", str(run), "--out", str(run), "--force"]) == 2
    assert "would replace the run folder" in capsys.readouterr().err
    assert (run / "posterior.nc").read_bytes() == b"kept"
    # a file in the output's place is refused before any work, --force or not
    taken = tmp_path / "notes.txt"
    taken.write_text("mine")
    assert main(["fit", str(series), "--out", str(taken), "--force"]) == 2
    assert "exists and is not a folder" in capsys.readouterr().err
    assert main(["fit", str(series), "--out", str(taken / "run")]) == 2
    assert f"cannot write {taken / 'run'}" in capsys.readouterr().err
    assert taken.read_text() == "mine"
    assert main(["fit", str(series), "--out", ""]) == 2
    assert "the output path is empty" in capsys.readouterr().err
    # a run refused after the output check (here: no series) leaves no new parent folders behind
    assert main(["fit", str(tmp_path / "missing"), "--out", str(tmp_path / "new" / "deeper" / "run")]) == 2
    assert "missing" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()
    # nothing hidden left behind by the checks
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize("content, words", [
    (b"[1, 2]", "not a run summary: an array, not a JSON object"),
    (b"null", "not a run summary: null, not a JSON object"),
    (b"{}", "not a run summary: parameters, between_test_spread, n_tests"),
    (b"\xff\xfe{", "byte 0: not UTF-8 text"),
    (b'{"parameters": [], "between_test_spread": {}, "n_tests": 1, "n_samples": 1, "divergences": 0, '
     b'"max_r_hat": 1, "min_ess_bulk": 1, "converged": true, "warnings": []}', "parameters: not an object"),
])
def test_a_damaged_run_summary_is_named_with_its_fault(tmp_path, capsys, content, words):
    (tmp_path / "summary.json").write_bytes(content)
    assert main(["summary", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert f"{tmp_path / 'summary.json'}: " in err and words in err and "internal" not in err


def test_a_damaged_posterior_file_is_named(tmp_path):
    from bayes_sst.io import SeriesFormatError, read_run_tree

    (tmp_path / "posterior.nc").write_bytes(b"CDF\x01 truncated")
    with pytest.raises(SeriesFormatError, match="posterior.nc: cannot be read as a run's posterior"):
        read_run_tree(tmp_path)


@pytest.mark.parametrize("argv, words", [
    (["fit", "S", "--out", "R", "--seed", "-1"], "-1 is negative; a seed is an integer >= 0"),
    (["simulate", "--out", "R", "--seed", "-3"], "-3 is negative"),
    (["fit", "S", "--out", "R", "--reversal-band", "2"], "2 is not a share of the peak speed"),
    (["fit", "S", "--out", "R", "--reversal-band", "-0.5"], "-0.5 is not a share of the peak speed"),
    (["fit", "S", "--out", "R", "--reversal-speed", "nan"], "'nan' is not a finite number"),
    (["fit", "S", "--out", "R", "--reversal-speed", "-1"], "-1 is negative"),
    (["fit", "S", "--out", "R", "--cutoff-multiple", "inf"], "'inf' is not a finite number"),
    (["fit", "S", "--out", "R", "--presliding", "-0.0001"], "-0.0001 is negative"),
    (["fit", "S", "--out", "R", "--presliding-floor", "nan"], "'nan' is not a finite number"),
    (["classical", "S", "--out", "R", "--alpha", "-1"], "-1 is not a damping exponent"),
    (["classical", "S", "--out", "R", "--alpha", "nan"], "'nan' is not a finite number"),
    (["report", "R", "--seed", "-2"], "-2 is negative"),
])
def test_bad_option_values_are_refused_with_the_rule(argv, words, capsys):
    with pytest.raises(SystemExit) as excinfo:
        main(argv)
    assert excinfo.value.code == 2
    assert words in capsys.readouterr().err


def test_fit_passes_the_signal_options_it_is_given():
    from bayes_sst.cli import build_parser, fit_signal_options
    from bayes_sst.signals import SignalOptions

    parse = build_parser().parse_args
    assert fit_signal_options(parse(["fit", "S", "--out", "R"])) == SignalOptions()
    options = fit_signal_options(parse(["fit", "S", "--out", "R", "--presliding", "8e-5", "--presliding-floor", "0",
                                        "--reversal-band", "0.15", "--cutoff-multiple", "6"]))
    assert (options.presliding, options.presliding_floor, options.cutoff_multiple) == (8e-5, 0.0, 6.0)
    assert options.reversal_band == 0.15 and options.reversal_band_without_accelerometer is None
    assert fit_signal_options(parse(["fit", "S", "--out", "R", "--presliding", "0"])).presliding == 0.0


def test_report_figure_names_are_distinct_and_short():
    from bayes_sst.report._build import test_figure_name

    assert test_figure_name("S01") == "test_S01.png"
    names = {test_figure_name(i) for i in ("S 13", "S_13", "S/13", "X" * 300, "X" * 300 + "Y")}
    assert len(names) == 5
    assert test_figure_name("S_13") == "test_S_13.png"
    assert max(len(n) for n in names) <= 80


def test_a_run_is_not_read_against_another_series(tmp_path):
    import xarray as xr

    from bayes_sst.inference._predictive import run_series
    from bayes_sst.io import load_series

    series = _small_series(tmp_path / "series")
    name = load_series(series).name
    tree = xr.DataTree()
    tree.attrs.update({"series": name, "left_out": "[]"})
    assert run_series(tree, "report", path=series).name == name
    tree.attrs["series"] = "another campaign"
    with pytest.raises(ValueError, match=f"named '{name}', but the run was fitted on 'another campaign'"):
        run_series(tree, "report", path=series)
