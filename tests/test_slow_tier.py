"""The slow tier (tests/conftest.py): tests marked ``slow`` are skipped by default with a reason
that says how to run them, run with ``--runslow`` (or ``AMI_XR_SLOW=1``), and alone with
``-m slow --runslow``; CI runs the default tier and then the slow one."""

from __future__ import annotations

from pathlib import Path

pytest_plugins = ("pytester",)

REPO = Path(__file__).resolve().parents[1]
PROBE = """
import pytest

@pytest.mark.slow
def test_long():
    pass

def test_short():
    pass
"""


def _probe(pytester):
    pytester.makeconftest(
        "from tests.conftest import pytest_addoption, pytest_collection_modifyitems  # noqa: F401"
    )
    pytester.makeini("[pytest]\nmarkers =\n    slow: the slow tier\n")
    pytester.makepyfile(test_tier_probe=PROBE)


def test_a_slow_test_is_skipped_by_default_saying_how_to_run_it(pytester, monkeypatch):
    monkeypatch.delenv("AMI_XR_SLOW", raising=False)
    _probe(pytester)
    result = pytester.runpytest("-rs", "--strict-markers", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=1, skipped=1)
    result.stdout.fnmatch_lines(
        ["SKIPPED*slow tier: run with 'python -m pytest -q -m slow --runslow'*"]
    )


def test_runslow_runs_both_tiers_and_with_m_slow_only_the_slow_one(pytester, monkeypatch):
    monkeypatch.delenv("AMI_XR_SLOW", raising=False)
    _probe(pytester)
    pytester.runpytest("--runslow", "-p", "no:cacheprovider").assert_outcomes(passed=2)
    only = pytester.runpytest("-m", "slow", "--runslow", "-p", "no:cacheprovider")
    only.assert_outcomes(passed=1, deselected=1)
    monkeypatch.setenv("AMI_XR_SLOW", "1")
    pytester.runpytest("-p", "no:cacheprovider").assert_outcomes(passed=2)


def test_the_marker_is_registered_and_ci_runs_the_slow_tier(request):
    assert any(line.startswith("slow:") for line in request.config.getini("markers"))
    ci = (REPO / ".ci" / "run").read_text(encoding="utf-8")
    assert "python -m pytest -q -m slow --runslow" in ci
