"""The README's "For test-lab users" section, run as written: its shell commands through the
``ami-xr`` entry point on the measured hammer file, then its Python code on what they wrote.
Skipped where ../shared/data (the measured files) is absent."""

from __future__ import annotations

import re
import shlex
import shutil

import pytest

from ami_xr.app.cli import main
from tests.reference import REPO, SHARED_DATA

HAMMER = SHARED_DATA / "impact_hammer.lvm"


def _section() -> str:
    return (REPO / "docs" / "testlab.md").read_text(encoding="utf-8")


def _blocks(section: str, language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", section, flags=re.S)


def test_the_section_has_the_workflow_and_the_other_tools():
    section = _section()
    (shell,) = _blocks(section, "bash")
    commands = [ln.split()[1] for ln in shell.splitlines() if ln.startswith("ami-xr ")]
    assert commands == ["frf", "identify", "report", "convert"]
    (code,) = _blocks(section, "python")
    for tool in ("xarray", "netCDF4", "pyuff", "pandas"):
        assert f"import {tool}" in code


@pytest.mark.skipif(not HAMMER.is_file(), reason="../shared/data/impact_hammer.lvm is absent")
def test_the_section_runs_as_written(tmp_path, monkeypatch, capsys):
    pytest.importorskip("matplotlib")
    pytest.importorskip("pyuff")
    pytest.importorskip("pandas")
    shutil.copy(HAMMER, tmp_path / HAMMER.name)
    monkeypatch.chdir(tmp_path)
    section = _section()
    for line in _blocks(section, "bash")[0].splitlines():
        if line.startswith("ami-xr "):
            assert main(shlex.split(line)[1:]) == 0, line
    out = capsys.readouterr()
    assert "hit 0 rejected: overload" in out.out and "hit 2 rejected: double impact" in out.out
    assert "analysis band 1-" in out.err  # identify said which band it analysed
    import netCDF4

    if tuple(int(x) for x in netCDF4.__version__.split(".")[:2]) < (1, 7):
        pytest.skip("auto_complex, used by the section's Python code, needs netCDF4 >= 1.7")
    namespace: dict = {}
    exec(compile(_blocks(section, "python")[0], "README test-lab section", "exec"), namespace)
    modes, phi, sets, table = (namespace[k] for k in ("modes", "phi", "sets", "table"))
    assert modes.eigenvalue.dtype.kind == "c" and phi.dtype.kind == "c"
    assert {s["type"] for s in sets} == {55, 58}
    assert len(table) == modes.sizes["mode"] and table["frequency_hz"].dtype.kind == "f"
    assert (tmp_path / "hammer_report" / "index.html").is_file()
