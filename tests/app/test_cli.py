"""The ami-xr command line (ami_xr.app.cli): help texts, exit codes, one-line errors, commands."""

from __future__ import annotations

import argparse
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.app.cli import EXIT_ERROR, EXIT_OK, EXIT_USAGE, build_parser, main

from ..reference import HAMMER_LVM, REPO, SUBPROCESS_ENV

COMMANDS = ("demo", "simulate", "frf", "identify", "report", "convert", "batch")


def _run(*args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "ami_xr.app.cli", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=SUBPROCESS_ENV,
    )


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def test_top_level_help_lists_every_command():
    proc = _run("--help")
    assert proc.returncode == 0
    for cmd in COMMANDS:
        assert cmd in proc.stdout
    assert _run("--version").stdout.startswith("ami_xr ")


@pytest.mark.parametrize("command", COMMANDS)
def test_every_option_has_help_and_default(command, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([command, "--help"])
    assert exit_info.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    sub = _subparsers()[command]
    for action in sub._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        assert action.help, f"{command}: {action.dest} has no help"
        for option in action.option_strings:
            assert option in text
        if action.option_strings and action.default is not argparse.SUPPRESS:
            shown = sub._get_formatter()._get_help_string(action)
            assert "(default:" in shown or "%(default)" in shown, f"{command}: {action.dest}"


def test_help_compiles_nothing_and_imports_no_extras():
    code = (
        "import sys\n"
        "from numba.core.dispatcher import Dispatcher\n"
        "from ami_xr.app.cli import main\n"
        "for cmd in ('identify', 'batch', 'demo'):\n"
        "    try:\n"
        "        main([cmd, '--help'])\n"
        "    except SystemExit:\n"
        "        pass\n"
        "compiled = [f'{m}.{k}' for m, mod in list(sys.modules.items()) if m.startswith('ami_xr')\n"
        "            for k, v in vars(mod).items() if isinstance(v, Dispatcher) and v.signatures]\n"
        "extras = [m for m in ('matplotlib', 'pyuff', 'tqdm', 'netCDF4') if m in sys.modules]\n"
        "print('COMPILED', compiled, 'EXTRAS', extras)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        env=SUBPROCESS_ENV,
    )
    assert proc.returncode == 0, proc.stderr
    assert "COMPILED [] EXTRAS []" in proc.stdout


def test_library_error_is_one_line_and_nonzero(tmp_path):
    proc = _run("identify", str(tmp_path / "missing.nc"))
    assert proc.returncode == EXIT_ERROR
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("ami-xr identify: error:")
    assert "missing.nc" in lines[0]
    assert "Traceback" not in proc.stderr


def test_verbose_shows_the_traceback(tmp_path, capsys):
    assert main(["-v", "identify", str(tmp_path / "missing.nc")]) == EXIT_ERROR
    err = capsys.readouterr().err
    assert "Traceback" in err and err.strip().splitlines()[-1].startswith("ami-xr identify:")
    assert main(["identify", "-v", str(tmp_path / "missing.nc")]) == EXIT_ERROR
    assert "Traceback" in capsys.readouterr().err


def test_bad_option_value_is_a_clear_error(tmp_path, capsys):
    # an out-of-range option is a usage error that names the option, before any work
    with pytest.raises(SystemExit) as exit_info:
        main(["simulate", "beam-absorbers", "-o", str(tmp_path / "x.nc"), "--noise", "-1"])
    assert exit_info.value.code == EXIT_USAGE
    err = capsys.readouterr().err
    assert "--noise" in err and ">= 0" in err
    assert not (tmp_path / "x.nc").exists()


def test_usage_error_exits_2():
    proc = _run("identify")
    assert proc.returncode == EXIT_USAGE
    assert "usage:" in proc.stderr


def test_schema_error_becomes_one_line(tmp_path, capsys):
    bad = xr.Dataset({"frf": (("point", "frequency"), np.ones((2, 3)))})  # real, no coords
    path = ami_xr.to_netcdf(bad, tmp_path / "bad.nc")
    assert main(["identify", str(path)]) == EXIT_ERROR
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ami-xr identify: error:")


def test_simulate_identify_report_convert(tmp_path, capsys):
    frf = tmp_path / "bench.nc"
    truth = tmp_path / "truth.nc"
    assert (
        main(
            [
                "simulate",
                "beam-absorbers",
                "-o",
                str(frf),
                "--noise",
                "0.15",
                "--seed",
                "1",
                "--truth-output",
                str(truth),
            ]
        )
        == EXIT_OK
    )
    g = ami_xr.open_dataset(frf)
    ami_xr.validate(g)
    assert g.attrs["noise_seed"] == 1
    modes = tmp_path / "modes.nc"
    assert main(["identify", str(frf), "-o", str(modes), "-q"]) == EXIT_OK
    out = capsys.readouterr().out
    for column in ("f [Hz]", "w [rad/s]", "zeta [%]", "detected in", "flags"):
        assert column in out
    result = ami_xr.open_dataset(modes)
    assert names.EIGENVALUE in result and names.FRF in result
    assert main(["report", str(modes), "-o", str(tmp_path / "rep")]) == EXIT_OK
    assert (tmp_path / "rep" / "index.html").is_file()
    # netCDF -> UFF (FRFs as 58, modes as 55) -> netCDF
    uff = tmp_path / "modes.uff"
    assert main(["convert", str(modes), "-o", str(uff), "--binary"]) == EXIT_OK
    back = tmp_path / "back.nc"
    assert main(["convert", str(uff), "-o", str(back)]) == EXIT_OK
    # netCDF -> binary UFF -> netCDF keeps float64: no arithmetic
    np.testing.assert_array_equal(ami_xr.open_dataset(back)[names.FRF].values, g[names.FRF].values)
    assert main(["convert", str(modes), "-o", str(tmp_path / "x.csv")]) == EXIT_ERROR


def test_demo_prints_paper_comparison_and_writes_results(tmp_path):
    proc = _run("demo", "-o", str(tmp_path / "demo"))
    assert proc.returncode == 0, proc.stderr
    assert "paper AMI" in proc.stdout and "exact" in proc.stdout
    assert (tmp_path / "demo" / "modes.nc").is_file()
    assert (tmp_path / "demo" / "report" / "index.html").is_file()
    result = ami_xr.open_dataset(tmp_path / "demo" / "modes.nc")
    fn = np.sort(np.atleast_1d(result[names.NATURAL_FREQUENCY].values))
    exact = np.abs(ami_xr.simulate.paper_tables()["eigenvalue"]) / (2 * np.pi)
    assert fn.size == 4
    # identification from the noisy benchmark: the paper's own AMI row is within ~1e-3 of the exact
    # frequencies; 2e-3 still fails a mode matched to the wrong peak (modes >= 1.4 % apart)
    np.testing.assert_allclose(fn, exact, rtol=2e-3)


def test_demo_uses_sample_data_of_working_directory_and_skips_report_without_matplotlib(
    tmp_path, monkeypatch, capsys
):
    # the README runs `pip install . && ami-xr demo` from the repository root: the package then
    # lives in site-packages, so the demo must find ./sample_data, and the report (an optional
    # extra) must not make the main job fail
    import importlib.util
    import shutil

    work = tmp_path / "work"
    (work / "sample_data").mkdir(parents=True)
    shutil.copy(REPO / "sample_data" / "benchmark_frf.nc", work / "sample_data")
    monkeypatch.chdir(work)
    real_find_spec = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util,
        "find_spec",
        lambda name, *a, **k: None if name == "matplotlib" else real_find_spec(name, *a, **k),
    )
    assert main(["demo", "-o", str(tmp_path / "demo")]) == EXIT_OK
    out = capsys.readouterr().out
    assert f"benchmark FRFs: {work / 'sample_data' / 'benchmark_frf.nc'}" in out
    assert "no report: it needs matplotlib" in out
    assert (tmp_path / "demo" / "modes.nc").is_file()
    assert not (tmp_path / "demo" / "report").exists()


@pytest.mark.skipif(not HAMMER_LVM.is_file(), reason="shared/data folder absent")
def test_frf_from_hammer_lvm_reports_rejected_hits(tmp_path, capsys):
    out = tmp_path / "hammer_frf.nc"
    assert main(["frf", str(HAMMER_LVM), "-o", str(out)]) == EXIT_OK
    text = capsys.readouterr().out
    assert "hit 0 rejected: overload" in text and "hit 2 rejected: double impact" in text
    g = ami_xr.open_dataset(out)
    ami_xr.validate(g)
    assert names.COHERENCE in g


def test_frf_bad_option_is_one_line(tmp_path, capsys):
    rng = np.random.default_rng(0)
    ts = ami_xr.make_time_dataset(
        rng.normal(size=(2, 512)),
        fs=256.0,
        force=rng.normal(size=512),
        points=["a", "b"],
        drive_point="a",
    )
    path = ami_xr.to_netcdf(ts, tmp_path / "t.nc")
    code = main(["frf", str(path), "-o", str(tmp_path / "f.nc"), "--nperseg", "4096"])
    assert code == EXIT_ERROR
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nperseg" in err[0]
    assert main(["frf", str(path), "-o", str(tmp_path / "f.nc"), "--nperseg", "128"]) == EXIT_OK


def test_pure_noise_gives_zero_modes_and_one_line_warnings(tmp_path, capsys):
    rng = np.random.default_rng(0)
    g = ami_xr.make_frf_dataset(
        rng.normal(size=(3, 400)) + 1j * rng.normal(size=(3, 400)),
        np.linspace(1, 100, 400),
        points=[1, 2, 3],
        drive_point=1,
    )
    path = ami_xr.to_netcdf(g, tmp_path / "noise.nc")
    assert main(["identify", str(path), "-o", str(tmp_path / "m.nc")]) == EXIT_OK
    captured = capsys.readouterr()
    assert "no modes identified" in captured.out
    warnings_lines = [line for line in captured.err.splitlines() if line.strip()]
    assert warnings_lines
    assert all(
        line.startswith("ami-xr identify: warning: NoModesWarning:") for line in warnings_lines
    )
    assert main(["report", str(tmp_path / "m.nc"), "-o", str(tmp_path / "rep")]) == EXIT_OK


def test_simulate_random_system(tmp_path, capsys):
    out, truth = tmp_path / "r.nc", tmp_path / "t.nc"
    assert (
        main(
            [
                "simulate",
                "random",
                "-o",
                str(out),
                "--points",
                "5",
                "--noise",
                "0.01",
                "--seed",
                "2",
                "--truth-output",
                str(truth),
            ]
        )
        == EXIT_OK
    )
    g = ami_xr.validate(ami_xr.open_dataset(out))
    assert g.sizes[names.POINT] == 5
    assert names.EIGENVALUE in ami_xr.open_dataset(truth)
    code = main(
        [
            "simulate",
            "random",
            "-o",
            str(tmp_path / "x.nc"),
            "--time-output",
            str(tmp_path / "y.nc"),
        ]
    )
    assert code == EXIT_ERROR
    assert "--time-output" in capsys.readouterr().err
    assert not (tmp_path / "x.nc").exists()


def test_building_the_parser_imports_no_library_module():
    # option defaults come from the functions' signatures, looked up only when shown
    code = (
        "import sys\n"
        "from ami_xr.app.cli import build_parser\n"
        "build_parser()\n"
        "mods = ('ami_xr.ami.identify', 'ami_xr.dsp.frf', 'ami_xr.simulate', 'ami_xr.demo')\n"
        "print('LOADED', [m for m in mods if m in sys.modules])\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        env=SUBPROCESS_ENV,
    )
    assert proc.returncode == 0, proc.stderr
    assert "LOADED []" in proc.stdout


@pytest.mark.parametrize(
    ("command", "dest", "function", "parameter"),
    [
        ("identify", "delta", ami_xr.identify, "delta"),
        ("identify", "max_iter", ami_xr.identify, "max_iter"),
        ("batch", "weak_force_ratio", ami_xr.impact_frf, "weak_force_ratio"),
        ("batch", "n_average", ami_xr.frf, "n_average"),
        ("simulate", "samples", ami_xr.simulate.benchmark, "n_samples"),
        ("simulate", "points", ami_xr.simulate.random_system, "n_points"),
    ],
)
def test_option_defaults_are_the_functions_defaults(command, dest, function, parameter):
    import inspect

    expected = inspect.signature(function).parameters[parameter].default
    default = _subparsers()[command].get_default(dest)
    assert default == expected and str(default) == str(expected)


def test_options_left_at_or_set_to_their_default_are_not_passed_on():
    from ami_xr.app.options import frf_options, identify_options

    parser = build_parser()
    delta = str(_subparsers()["identify"].get_default("delta"))
    assert identify_options(parser.parse_args(["identify", "x.nc"])) == {}
    assert identify_options(parser.parse_args(["identify", "x.nc", "--delta", delta])) == {}
    args = parser.parse_args(["batch", "d", "-o", "o", "--delta", "0.3", "--min-force", "2"])
    assert identify_options(args) == {"delta": 0.3}
    assert frf_options(args) == {"min_force": 2.0}


def test_progress_counts_on_stderr_and_stays_silent_when_disabled(capsys, monkeypatch):
    from ami_xr.progress import Progress, elapsed

    with Progress("files", total=2, unit="file") as bar:
        bar.update()
        bar.update()
    assert "files" in capsys.readouterr().err
    with Progress("files", total=2, enabled=False) as bar:
        bar.update()
    with Progress("files", total=0) as bar:
        bar.update()
    assert capsys.readouterr().err == ""
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False, raising=False)
    assert not elapsed("identify", 100).enabled  # not on a terminal: no ticking line


def test_formats_choose_by_suffix_and_name_the_file(tmp_path):
    from ami_xr.errors import AmiXrValueError, DataFileError
    from ami_xr.io.formats import read_any, write_any

    (tmp_path / "data.xyz").write_text("1,2\n")  # a regular file: the suffix decides
    with pytest.raises(DataFileError, match=r"data\.xyz.*unknown file type"):
        read_any(tmp_path / "data.xyz")
    with pytest.raises(AmiXrValueError, match=r"out\.txt"):
        write_any(xr.Dataset(), tmp_path / "out.txt")


def test_demo_finds_the_sample_and_tables_the_paper(monkeypatch):
    from ami_xr.app.demo import comparison_table, find_sample_frf
    from ami_xr.simulate.paper import AMI_EIGENVALUES, ANALYTICAL_EIGENVALUES

    monkeypatch.chdir(REPO)
    assert find_sample_frf() == REPO / "sample_data" / "benchmark_frf.nc"
    table = comparison_table(ANALYTICAL_EIGENVALUES, ANALYTICAL_EIGENVALUES, AMI_EIGENVALUES)
    lines = table.splitlines()
    assert lines[0].startswith("mode  identified [rad/s]") and len(lines) == 2 + 4
    assert "+0.000 / " in lines[2]  # exact input: zero error of ours
