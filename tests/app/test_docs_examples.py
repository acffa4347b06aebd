"""The documentation's examples, run as written (issue 24: every code example in the docs runs).

* Every ```` ```python ```` block of README.md and of each ``docs/*.md`` page runs, in document
  order and in one namespace per page, together with every ``ami-xr ...`` line of the page's
  ```` ```bash ```` blocks (through the CLI entry point, as a user would type it). The working
  directory is a fresh temporary folder holding ``sample_data/`` (the repository's) and, beside
  it, ``../shared/data`` (the measured files, where present).
* A block or command that reads ``../shared/data`` runs only where those files exist; otherwise
  it is left out (with the rest of its bash block) and the page reports what it left out.
* ``docs/testlab.md`` (the hammer walkthrough) is checked in detail by the tests at the end: the
  hits it rejects, the band it reports, the files its Python code opens in other tools.

Blocks in other fences (``text``, or scripts that take minutes such as the benchmarks) are output
or commands shown, not examples; the scripts have their own tests.
"""

from __future__ import annotations

import importlib
import importlib.util
import re
import shlex
import shutil
import warnings
from pathlib import Path

import pytest

from ami_xr.app.cli import main
from tests.reference import REPO, SHARED_DATA

DOCS = REPO / "docs"
SHARED = "../shared/data"
HAMMER = SHARED_DATA / "impact_hammer.lvm"
# pages whose examples a dedicated test below runs (they need the measured hammer file)
DEDICATED = {"testlab.md"}
PAGES = [REPO / "README.md", *sorted(DOCS.glob("*.md"))]
FENCE = re.compile(r"^```(python|bash)\n(.*?)^```", flags=re.S | re.M)


def _blocks(text: str, language: str) -> list[str]:
    return [code for lang, code in FENCE.findall(text) if lang == language]


def _work_dir(tmp_path: Path) -> Path:
    """``tmp/work`` with ``sample_data/`` inside and ``tmp/shared/data`` beside it."""
    work = tmp_path / "work"
    work.mkdir()
    shutil.copytree(REPO / "sample_data", work / "sample_data")
    if SHARED_DATA.is_dir():
        (tmp_path / "shared").mkdir()
        (tmp_path / "shared" / "data").symlink_to(SHARED_DATA.resolve(), target_is_directory=True)
    return work


def _run_page(page: Path) -> tuple[int, list[str]]:
    """Run the page's examples in the current directory; return (blocks run, what was left out)."""
    text = page.read_text(encoding="utf-8")
    namespace: dict = {"__name__": f"docs_{page.stem}"}
    ran, left_out = 0, []
    for number, (language, code) in enumerate(FENCE.findall(text), start=1):
        where = f"{page.name}, {language} block {number}"
        if SHARED in code and not SHARED_DATA.is_dir():
            left_out.append(f"{where} (needs {SHARED})")
            continue
        if language == "python":
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # examples may show a warning; it is not an error
                exec(compile(code, where, "exec"), namespace)
        else:
            for line in code.splitlines():
                if line.startswith("ami-xr "):
                    argv = shlex.split(line, comments=True)[1:]
                    assert main(argv) == 0, f"{where}: {line}"
        ran += 1
    return ran, left_out


def _pages_with_examples() -> list[Path]:
    return [
        p for p in PAGES if p.name not in DEDICATED and FENCE.search(p.read_text(encoding="utf-8"))
    ]


@pytest.mark.parametrize("page", _pages_with_examples(), ids=lambda p: p.name)
def test_examples_of_the_page_run(page, tmp_path, monkeypatch, capsys):
    pytest.importorskip("matplotlib")  # ami-xr report, in the test extra
    monkeypatch.chdir(_work_dir(tmp_path))
    ran, left_out = _run_page(page)
    capsys.readouterr()
    assert ran + len(left_out) > 0
    if left_out:
        pytest.skip(f"ran {ran} example(s); left out: {'; '.join(left_out)}")


def test_the_examples_cover_the_guide():
    """Each chapter with code has examples here, and no page hides Python in an unrun fence."""
    covered = {p.name for p in _pages_with_examples()} | DEDICATED
    for name in (
        "README.md",
        "data-model.md",
        "time-to-frf.md",
        "identification.md",
        "refinement.md",
        "simulators.md",
        "cli.md",
    ):
        assert name in covered, name
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        assert "```py\n" not in text and "```python3\n" not in text, page.name


# --- the README and the site -----------------------------------------------------------------


def test_readme_is_short_and_its_test_command_is_the_one_ci_runs():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 300
    command = 'python -m pip install ".[test]" && python -m pytest -q'
    assert f"```bash\n{command}\n```" in readme
    ci = (REPO / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    at = ci.index("# --- the README's test command (keep identical) ---")
    assert ci[at + 1] == command


def test_every_docs_page_is_in_the_site_navigation():
    nav = (REPO / "mkdocs.yml").read_text(encoding="utf-8")
    for page in DOCS.glob("*.md"):
        assert re.search(rf":\s+{re.escape(page.name)}\s*$", nav, flags=re.M), page.name
    assert ": cli-reference.md" in nav  # generated at build time by docs/hooks/cli_reference.py


def test_the_api_page_lists_exactly_the_public_names():
    import ami_xr

    listed = re.findall(r"^::: ami_xr\.(\S+)$", (DOCS / "api.md").read_text(), flags=re.M)
    last = {path.rsplit(".", 1)[-1] for path in listed if path != "simulate"}
    assert last == set(ami_xr._PUBLIC)
    for path in listed:  # each entry leads to the public object (mkdocstrings renders that path)
        if path != "simulate":
            module, name = f"ami_xr.{path}".rsplit(".", 1)
            assert getattr(importlib.import_module(module), name) is getattr(ami_xr, name), path


def _cli_reference():
    spec = importlib.util.spec_from_file_location(
        "cli_reference", DOCS / "hooks" / "cli_reference.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_cli_reference_is_each_subcommands_help(monkeypatch):
    from ami_xr.app.cli import build_parser

    page = _cli_reference().render()
    monkeypatch.setenv("COLUMNS", "100")
    parser = build_parser()
    (sub,) = [a for a in parser._actions if a.dest == "command"]
    assert list(sub.choices) == re.findall(r"^## `ami-xr (\S+)`$", page, flags=re.M)
    for name, command in sub.choices.items():
        assert command.format_help().rstrip("\n") in page, name
    assert parser.format_help().rstrip("\n") in page


# --- docs/testlab.md: the hammer walkthrough ---------------------------------------------------


def _testlab() -> str:
    return (DOCS / "testlab.md").read_text(encoding="utf-8")


def test_testlab_has_the_workflow_and_the_other_tools():
    (shell,) = _blocks(_testlab(), "bash")
    commands = [ln.split()[1] for ln in shell.splitlines() if ln.startswith("ami-xr ")]
    assert commands == ["frf", "identify", "report", "convert"]
    (code,) = _blocks(_testlab(), "python")
    for tool in ("xarray", "netCDF4", "pyuff", "pandas"):
        assert f"import {tool}" in code


@pytest.mark.slow
@pytest.mark.skipif(not HAMMER.is_file(), reason="../shared/data/impact_hammer.lvm is absent")
def test_testlab_runs_as_written(tmp_path, monkeypatch, capsys):
    pytest.importorskip("matplotlib")
    pytest.importorskip("pyuff")
    pytest.importorskip("pandas")
    shutil.copy(HAMMER, tmp_path / HAMMER.name)
    monkeypatch.chdir(tmp_path)
    section = _testlab()
    for line in _blocks(section, "bash")[0].splitlines():
        if line.startswith("ami-xr "):
            assert main(shlex.split(line)[1:]) == 0, line
    out = capsys.readouterr()
    assert "hit 0 rejected: overload" in out.out and "hit 2 rejected: double impact" in out.out
    band = re.search(r"here (\d+)-(\d+) Hz", section)
    assert band, "the page names the band identify reports"
    assert f"analysis band {band[1]}-{band[2]} Hz" in out.err  # the page says what identify says
    import netCDF4

    if tuple(int(x) for x in netCDF4.__version__.split(".")[:2]) < (1, 7):
        pytest.skip("auto_complex, used by the page's Python code, needs netCDF4 >= 1.7")
    namespace: dict = {}
    exec(compile(_blocks(section, "python")[0], "docs/testlab.md", "exec"), namespace)
    modes, phi, sets, table = (namespace[k] for k in ("modes", "phi", "sets", "table"))
    assert modes.eigenvalue.dtype.kind == "c" and phi.dtype.kind == "c"
    assert {s["type"] for s in sets} == {55, 58}
    assert len(table) == modes.sizes["mode"] and table["frequency_hz"].dtype.kind == "f"
    assert (tmp_path / "hammer_report" / "index.html").is_file()
