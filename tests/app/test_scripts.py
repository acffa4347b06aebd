"""The benchmark scripts in scripts/ run from the command line on small data.

Figures are not checked here (unit tests never check wall-clock time); the scripts must run to
the end and print their sections.
"""

from __future__ import annotations

import runpy

import pytest

from ..reference import REPO

SCRIPTS = REPO / "scripts"


def _main(name: str):
    return runpy.run_path(str(SCRIPTS / name), run_name=name.removesuffix(".py"))["main"]


def test_reproduce_paper_small(capsys):
    assert _main("reproduce_paper.py")(["--seeds", "2", "--noise", "0.15", "0", "--no-speed"]) == 0
    out = capsys.readouterr().out
    assert "Tables 1-2 equivalent" in out and "Tables 3-6 equivalent" in out
    assert "Monte Carlo: 15 % noise" in out and "Cramér-Rao bound" in out
    assert "Monte Carlo: noise-free" in out
    # noise-free data: the default (refined) method is exact to rounding
    assert "< 1e-6" in out


@pytest.mark.slow
@pytest.mark.parametrize(
    "args", [["--samples", "200000", "--points", "4", "--chunk", "65536", "--slice", "65536"]]
)
def test_bench_frf_small(capsys, tmp_path, monkeypatch, args):
    # the script writes its record in a subprocess: make this checkout importable there
    monkeypatch.setenv("PYTHONPATH", str(SCRIPTS.parent))
    code = _main("bench_frf.py")([*args, "--dir", str(tmp_path)])
    assert code == 0
    out = capsys.readouterr().out
    assert "samples/s" in out
