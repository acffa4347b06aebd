"""A report folder is replaced whole or not at all (issue 25 items 7 and 8)."""

from __future__ import annotations

import os
import signal

import pytest

from ami_xr.io.atomic import atomic_folder


def _old_report(folder):
    folder.mkdir()
    (folder / "index.html").write_text("A")
    (folder / "a.png").write_text("A")


def test_success_replaces_the_whole_folder(tmp_path):
    rep = tmp_path / "rep"
    _old_report(rep)
    with atomic_folder(rep) as tmp:
        assert tmp != rep and tmp.is_dir() and not any(tmp.iterdir())
        (tmp / "index.html").write_text("B")
        (tmp / "b.png").write_text("B")
    assert sorted(p.name for p in rep.iterdir()) == ["b.png", "index.html"]  # no A left over
    assert (rep / "index.html").read_text() == "B"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rep"]


@pytest.mark.parametrize("stop", [KeyboardInterrupt, OSError, RuntimeError])
def test_an_interrupt_or_error_leaves_the_old_folder_untouched(tmp_path, stop):
    rep = tmp_path / "rep"
    _old_report(rep)
    with pytest.raises((stop, ValueError)), atomic_folder(rep) as tmp:
        (tmp / "b.png").write_text("B")  # half of B's figures written
        raise stop("stopped")
    assert sorted(p.name for p in rep.iterdir()) == ["a.png", "index.html"]
    assert (rep / "index.html").read_text() == "A"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rep"]


def test_new_folder_absent_after_a_signal(tmp_path):
    rep = tmp_path / "rep"
    with pytest.raises(KeyboardInterrupt), atomic_folder(rep) as tmp:
        (tmp / "a.png").write_text("B")
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(10**6):
            pass
    assert not rep.exists() and not list(tmp_path.iterdir())
