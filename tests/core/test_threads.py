"""identify runs with one BLAS thread (ami_xr.core.threads) and restores the caller's setting."""

from __future__ import annotations

import numpy as np
import pytest

import ami_xr
from ami_xr.core import threads

threadpoolctl = pytest.importorskip("threadpoolctl")


def _blas_threads() -> list[int]:
    return [i["num_threads"] for i in threadpoolctl.threadpool_info() if i["user_api"] == "blas"]


def test_limit_inside_and_restored_after_nested_use():
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        with threads.single_blas_thread():
            assert set(_blas_threads()) == {1}
            with threads.single_blas_thread():  # nested: still one, not restored early
                assert set(_blas_threads()) == {1}
            assert set(_blas_threads()) == {1}
        assert _blas_threads() == before


def test_identify_runs_with_one_blas_thread(monkeypatch, paper_benchmark_clean):
    seen = []
    real = np.linalg.cholesky

    def spy(a):
        seen.append(set(_blas_threads()))
        return real(a)

    monkeypatch.setattr(np.linalg, "cholesky", spy)
    ami_xr.identify(paper_benchmark_clean[1])
    assert seen and all(s == {1} for s in seen)
