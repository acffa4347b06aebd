"""Issue 34: progress with no usable stderr, no machine path in the batch summary, and the
scale-out options (--workers/--scheduler/--worker-memory) checked up front as usage errors."""

from __future__ import annotations

import csv
import io
import sys
import warnings

import pytest

import ami_xr
from ami_xr import progress as pg
from ami_xr.app.batch import SUMMARY_NAME, batch
from ami_xr.app.cli import EXIT_USAGE, main


# --- item 1: progress=True never fails the identification ---------------------------------------
@pytest.fixture(scope="module")
def small_frf():
    g, _ = ami_xr.simulate.random_system(
        n_points=5, n_modes=5, noise=0.01, seed=2, n_frequencies=400
    )
    return g


def _closed_file(tmp_path):
    fh = open(tmp_path / "stderr.txt", "w")  # noqa: SIM115 - closed at once, on purpose
    fh.close()
    return fh


def _closed_stringio():
    fh = io.StringIO()
    fh.close()
    return fh


STREAMS = {
    "none": lambda tmp_path: None,
    "closed_file": _closed_file,
    "closed_stringio": lambda tmp_path: _closed_stringio(),
}


@pytest.mark.parametrize("tqdm", [True, False], ids=["tqdm", "plain"])
@pytest.mark.parametrize("stream", list(STREAMS))
def test_progress_without_a_usable_stderr_does_nothing(
    small_frf, tmp_path, monkeypatch, stream, tqdm
):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        expected = ami_xr.identify(small_frf)
    if not tqdm:
        monkeypatch.setattr(pg, "_tqdm", lambda: None)
    monkeypatch.setattr(pg, "DELAY_SECONDS", 0.0)
    monkeypatch.setattr(sys, "stderr", STREAMS[stream](tmp_path))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # twice: a first failure inside tqdm left its lock held and the second call hung
        for _ in range(2):
            result = ami_xr.identify(small_frf, progress=True)
            assert result.sizes["mode"] == expected.sizes["mode"]


@pytest.mark.parametrize("stream", list(STREAMS))
def test_progress_helpers_without_a_usable_stderr(tmp_path, monkeypatch, stream):
    monkeypatch.setattr(pg, "TICK_SECONDS", 0.01)
    monkeypatch.setattr(sys, "stderr", STREAMS[stream](tmp_path))
    with pg.Progress("files", total=3) as bar:
        for _ in range(3):
            bar.update()
    with pg.Progress("open-ended"):
        pass
    assert pg.on_terminal() is False  # isatty() of a closed file raises ValueError
    assert not pg.elapsed("work", 100).enabled
    with pg.phases(True, "identify", ["a", "b"]) as step:
        step("a")
        pg.detail("1/2 FRFs")
        step("b")


def test_progress_survives_stderr_closed_during_the_work(monkeypatch):
    monkeypatch.setattr(pg, "_tqdm", lambda: None)
    monkeypatch.setattr(pg, "TICK_SECONDS", 0.01)
    stream = io.StringIO()
    monkeypatch.setattr(sys, "stderr", stream)
    with pg.Progress("files", total=3, live=True) as bar:
        bar.update()
        stream.close()
        bar.update()
        bar.describe("x")
    with pg.Progress("open-ended"):
        pass


# --- item 4: no machine path in batch_summary.csv ------------------------------------------------
def test_batch_summary_holds_no_machine_path(tmp_path, monkeypatch):
    camp = tmp_path / "camp"
    (camp / "day1").mkdir(parents=True)
    (camp / "day1" / "bad.nc").write_text("garbage, not netCDF\n")
    (camp / "bad.uff").write_text("x\n1,2\n")
    out = tmp_path / "out"
    for given in (camp, camp.relative_to(tmp_path)):  # absolute, and relative to the cwd
        monkeypatch.chdir(tmp_path)
        summary = batch(given, out, progress=False, force=True)
        assert summary.n_failed == 2
        text = (out / SUMMARY_NAME).read_text()
        assert str(tmp_path) not in text, text
        assert str(tmp_path.resolve()) not in text, text
        assert "camp/" not in text, text  # relative to the input folder, not to the cwd
        rows = {r["file"]: r for r in csv.DictReader(io.StringIO(text))}
        assert rows["day1/bad.nc"]["message"].startswith("DataFileError: day1/bad.nc:")
        assert "bad.uff" in rows["bad.uff"]["message"]
        for row in summary.rows:  # what ami-xr batch prints comes from the same rows
            assert str(tmp_path) not in row["message"]


# --- item 5: scale-out options are usage errors -------------------------------------------------
@pytest.fixture(scope="module")
def frf_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("frf") / "g.nc"
    g, _ = ami_xr.simulate.random_system(
        n_points=5, n_modes=5, noise=0.01, seed=1, n_frequencies=400
    )
    return str(ami_xr.to_netcdf(g, path))


@pytest.mark.parametrize(
    ("options", "named"),
    [
        (["--workers", "2", "--scheduler", "tcp://127.0.0.1:8786"], "--scheduler"),
        (["--scheduler", "not-an-address"], "--scheduler"),
        (["--scheduler", "foo://x"], "--scheduler"),
        (["--scheduler", ""], "--scheduler"),
        (["--scheduler", "tcp://"], "--scheduler"),
        (["--scheduler", "tcp://host"], "--scheduler"),
        (["--scheduler", "tcp://host:99999"], "--scheduler"),
        (["--scheduler", "inproc://x"], "--scheduler"),
        (["--workers", "2", "--worker-memory", "abc"], "--worker-memory"),
        (["--workers", "2", "--worker-memory=-1GB"], "--worker-memory"),
        (["--workers", "2", "--worker-memory", "0"], "--worker-memory"),
    ],
)
def test_scale_out_options_are_usage_errors(frf_file, capsys, options, named):
    with pytest.raises(SystemExit) as exit_info:
        main(["identify", frf_file, *options])
    assert exit_info.value.code == EXIT_USAGE
    err = capsys.readouterr().err
    last = err.strip().splitlines()[-1]
    assert last.startswith("ami-xr identify: error: argument")
    assert named in last and "expected" in last or "not allowed" in last, last
    assert "Traceback" not in err and "a bug" not in err


@pytest.mark.parametrize(
    "address",
    ["tcp://127.0.0.1:8786", "127.0.0.1:8786", "tls://scheduler.example:8786", "tcp://[::1]:8786"],
)
def test_good_scheduler_addresses_pass(address):
    from ami_xr.app.options import scheduler_address

    assert scheduler_address(address) == address


@pytest.mark.parametrize("size", ["2GB", "512MiB", "4e9", "1 GiB", "auto"])
def test_good_worker_memory_passes(size):
    pytest.importorskip("dask")
    from ami_xr.app.options import memory_size

    assert memory_size(size) == size
