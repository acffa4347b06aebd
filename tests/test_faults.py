"""Fault injection, fast subset: nothing lost, nothing hangs, no traceback (issue 9).

The generators and checks live in ``scripts/fault_campaign.py`` (the long campaign, over 1000
faults); this file runs a seeded subset of the same cases and asserts each one ends as a clean
error or a correct result, with no file lost or left partial. A case's message says how to
reproduce it (command, input, fault, seed).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "fault_campaign.py"
_spec = importlib.util.spec_from_file_location("fault_campaign", SCRIPT)
fc = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fc)

INPUTS = fc.INPUT_NAMES
# (input, command index into fc.commands_for(input), seed): 3 truncations, 2 flips each
TRUNCATIONS = [(n, k, s) for n in INPUTS for k in (0, 1) for s in (11, 12, 13)]
FLIPS = [(n, k, s) for n in INPUTS for k in (0, 1) for s in (21, 22)]
# From the campaign (seed 0): a binary UFF cut exactly between two datasets (undetectable).
TRUNCATIONS += [("frf_binary.uff", 1, 191731217)]

# Failure classes still open at the time of writing; each marked case fails today (strict).
# (kind, input, command index, seed) -> reason. Empty: the netCDF failure classes the campaign
# found (see the lead's report) are not pinned here, because a seed's byte positions hit other
# structures as soon as the netCDF writer's output changes.
KNOWN: dict[tuple[str, str, int, int], str] = {}
HANG_TIMEOUT_S = 20.0  # a hung case is killed after this, not after the campaign's 60 s


def _cases(kind: str, cases: list[tuple]) -> list:
    params = []
    for name, k, seed in cases:
        reason = KNOWN.get((kind, name, k, seed))
        marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
        cmd = fc.commands_for(name)[k][0]
        params.append(pytest.param(name, k, seed, marks=marks, id=f"{name}-{cmd}-{seed}"))
    return params


@pytest.fixture(scope="module")
def work(tmp_path_factory) -> Path:
    # Imported once here so that each forked case does only the command's work.
    import ami_xr.app.cli  # noqa: F401

    return tmp_path_factory.mktemp("faults")


@pytest.fixture(scope="module")
def inputs(work) -> dict[str, Path]:
    files = fc.make_inputs(work / "inputs", seed=0)
    fc.warm_up(work, files)  # numba kernels loaded once, not in every forked case
    return files


def _assert_ok(result) -> None:
    assert result.outcome != fc.OTHER and not result.lost, (
        f"{result.case}: {result.detail}; lost/partial: {list(result.lost)}"
    )


@pytest.mark.parametrize(("name", "k", "seed"), _cases("truncate", TRUNCATIONS))
def test_truncated_input_is_a_clean_error_or_the_intact_result(work, inputs, name, k, seed):
    _assert_ok(fc.file_fault_case("truncate", inputs[name], k, seed, work))


@pytest.mark.parametrize(("name", "k", "seed"), _cases("flip", FLIPS))
def test_changed_bytes_give_a_clean_error_or_a_complete_result(work, inputs, name, k, seed):
    _assert_ok(fc.file_fault_case("flip", inputs[name], k, seed, work, timeout=HANG_TIMEOUT_S))


@settings(
    max_examples=25,
    deadline=None,
    database=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(params=fc.dataset_strategy())
def test_random_datasets_through_validate_and_identify(params):
    outcome, detail = fc.check_dataset(params)
    assert outcome != fc.OTHER, f"{params}: {detail}"


@pytest.fixture(scope="module")
def big(work, inputs) -> tuple[Path, dict[str, float]]:
    path = fc.big_file(work / "inputs", megabytes=8.0)
    return path, fc.time_commands(work, path, inputs)


@pytest.mark.slow
@pytest.mark.parametrize("sig_name", ["SIGINT", "SIGTERM", "SIGKILL"])
def test_signal_during_a_large_write_leaves_old_or_new_file(work, big, sig_name):
    path, timings = big
    _assert_ok(fc.signal_case(5, work, path, timings["convert"], sig_name=sig_name))


@pytest.mark.slow
def test_ctrl_c_during_a_batch_loses_nothing(work, inputs, big):
    _, timings = big
    _assert_ok(fc.batch_case(7, work, inputs, timings["batch"], sig_name="SIGINT"))


def test_concurrent_writers_leave_one_complete_file(work):
    _assert_ok(fc.concurrent_case(3, work))


def test_campaign_table_counts_every_outcome():
    results = [
        fc.Result("flip", "a", fc.CLEAN),
        fc.Result("flip", "b", fc.OTHER, "hang", ["b: out lost"]),
        fc.Result("dataset", "c", fc.CORRECT),
    ]
    table, ok = fc.summarize(results)
    assert not ok
    assert "files lost or left partial: 1" in table
    assert "[flip] b: hang" in table
    assert fc.summarize(results[::2])[1]
