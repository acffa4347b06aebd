"""scripts/bench_checkpoint_gap.py runs on a small set, compressed or not, and refuses a bad
--compress. The gaps it prints are not checked (unit tests never check wall-clock time)."""

from __future__ import annotations

import runpy

import pytest

from ..reference import REPO

SCRIPT = REPO / "scripts" / "bench_checkpoint_gap.py"


def _main():
    return runpy.run_path(str(SCRIPT), run_name="bench_checkpoint_gap")["main"]


@pytest.mark.parametrize("compress", ["auto", "off"])
def test_gaps_are_listed_for_either_path(capsys, compress):
    assert _main()(["--points", "30", "--lines", "512", "--compress", compress]) == 0
    out = capsys.readouterr().out
    assert f"compress={compress} (measured)" in out
    assert "longest gap:" in out and "from -> to" in out


def test_a_bad_compress_is_refused(capsys):
    with pytest.raises(SystemExit) as err:
        _main()(["--compress", "fast"])
    assert err.value.code == 2
    assert "--compress: expected auto, off or an int, got 'fast'" in capsys.readouterr().err
