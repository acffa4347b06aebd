"""The fault campaign's audit (issue 42): every command a case runs is classed by its exit code
and stderr -- crashes, hangs, bug-class messages, raw tracebacks, foreign log lines, leaked
paths -- and ``--full`` fails on any of them, also in a case whose outcome looked fine."""

from __future__ import annotations

import importlib.util
import signal
import sys

import pytest

from ..reference import REPO


@pytest.fixture(scope="module")
def fc():
    name = "fault_campaign"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, REPO / "scripts" / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


@pytest.mark.parametrize(
    "code, err, want",
    [
        (1, "ami-xr identify: error: x.nc: not a netCDF file\n", []),
        (130, "ami-xr identify: interrupted\n", []),
        (-signal.SIGSEGV, "", ["crashes"]),
        (128 + signal.SIGBUS, "", ["crashes"]),
        (None, "", ["hangs"]),
        (1, "Traceback (most recent call last):\n  File 'x'\nValueError: y\n", ["raw tracebacks"]),
        (1, "ami-xr identify: error: unexpected KeyError: 'a' - a bug, please report it\n",
         ["bug-class messages"]),
        (0, "2026-11-28 03:00:00,000 - distributed.nanny - WARNING - Restarting worker\n",
         ["foreign log lines"]),
        (0, "x.py:3: RuntimeWarning: overflow encountered in ldexp\n", ["foreign log lines"]),
    ],
)
def test_each_failure_class_is_found(fc, code, err, want):
    assert fc.audit([(code, err)]) == want


def test_a_path_of_this_machine_in_a_message_is_a_leak(fc):
    import ami_xr

    source = str(ami_xr.__file__)
    assert fc.audit([(1, f"ami-xr identify: error: failed in {source}\n")]) == ["leaked paths"]
    assert fc.audit([(1, "ami-xr identify: error: /tmp/case/x.nc: truncated\n")]) == []


def test_an_audited_case_fails_the_campaign_whatever_its_outcome(fc):
    fine = fc.Result("cluster", "a", fc.CLEAN, "exit 1")
    leaked = fc.Result("cluster", "b", fc.CLEAN, "exit 1", audit=("leaked paths",))
    table, ok = fc.summarize([fine])
    assert ok and "leaked paths 0" in table
    table, ok = fc.summarize([fine, leaked])
    assert not ok and "leaked paths 1" in table and "[cluster] b" in table
