"""A report a colleague can read without the docs (issue 29 item 4): a legend of the flags that
appear, "found by the refinement" instead of "none" for a mode the refinement added, and the
limits that ended a phase in words, superseded subtraction caps included."""

from __future__ import annotations

import csv
import html
import warnings

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.app.report import report
from ami_xr.core import flags
from ami_xr.tables import FOUND_BY_REFINEMENT, flag_legend, format_modal_table, modal_table

pytest.importorskip("matplotlib")


def _identify(ds: xr.Dataset, **options) -> xr.Dataset:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the warnings are not what is tested
        return ami_xr.identify(ds, **options)


@pytest.fixture(scope="module")
def benchmark_result(paper_benchmark_noisy) -> xr.Dataset:
    """The paper benchmark (15 % noise, seed 0): modes 1 and 2 carry low_drive_point_snr and
    single_frf, the others no flag."""
    _, g, _ = paper_benchmark_noisy
    return _identify(g)


@pytest.fixture(scope="module")
def five_modes() -> xr.Dataset:
    g, _ = ami_xr.simulate.random_system(
        n_points=5, n_modes=5, noise=0.01, seed=1, n_frequencies=512
    )
    return g


@pytest.fixture(scope="module")
def superseded_result(five_modes) -> xr.Dataset:
    """max_modes=1: the subtraction stops at its cap at every point, the refinement adds the
    other modes and completes the model, so the cap is superseded."""
    return _identify(five_modes, max_modes=1)


def _page(ds: xr.Dataset, folder) -> str:
    index = report(ds, folder, figures=("modal_table",))
    return index.read_text(encoding="utf-8")


def _present(ds: xr.Dataset) -> set[str]:
    return {
        f
        for text in flags.flag_text(np.atleast_1d(ds[names.QUALITY_FLAGS].values))
        for f in str(text).split(",")
    } - {""}


def test_legend_lists_every_flag_present_with_its_words(tmp_path, benchmark_result):
    present = _present(benchmark_result)
    assert {names.FLAG_LOW_DRIVE_SNR, names.FLAG_SINGLE_FRF} <= present
    page = _page(benchmark_result, tmp_path / "rep")
    assert "<h3>Flags</h3>" in page
    legend = page[page.index("<h3>Flags</h3>") :]
    for flag in names.FLAG_MEANINGS:
        row = f"<td class='l flag'>{flag}</td>"
        if flag in present:
            assert row in legend
            assert html.escape(flags.DESCRIPTIONS[flag]) in legend
        else:  # only the flags that appear
            assert row not in legend and html.escape(flags.DESCRIPTIONS[flag]) not in page
    # with the modes that carry each flag
    legend_rows = {flag: modes for flag, _, modes in flag_legend(modal_table(benchmark_result))}
    carriers = [
        m
        for m, f in zip(
            benchmark_result[names.MODE].values.tolist(),
            flags.flag_text(benchmark_result[names.QUALITY_FLAGS].values),
            strict=True,
        )
        if names.FLAG_SINGLE_FRF in str(f)
    ]
    assert legend_rows[names.FLAG_SINGLE_FRF] == carriers


def test_legend_is_in_bit_order_and_names_an_unknown_flag(benchmark_result):
    rows = modal_table(benchmark_result)
    rows[0]["flags"] = f"from_a_newer_version,{names.FLAG_REPEATED_ROOT},{names.FLAG_SINGLE_FRF}"
    legend = flag_legend(rows)
    got = [flag for flag, _, _ in legend]
    known = [f for f in got if f in names.FLAG_MEANINGS]
    assert known == sorted(known, key=names.FLAG_MEANINGS.index)
    assert got[-1] == "from_a_newer_version" and "not a flag" in legend[-1][1]


def test_no_flag_no_legend_but_a_sentence(tmp_path, benchmark_result):
    clean = benchmark_result.assign(
        {
            names.QUALITY_FLAGS: benchmark_result[names.QUALITY_FLAGS].copy(
                data=np.zeros(4, np.int32)
            )
        }
    )
    page = _page(clean, tmp_path / "rep")
    assert "<h3>Flags</h3>" not in page and "No mode carries a quality flag." in page


def test_added_mode_reads_found_by_the_refinement(tmp_path, superseded_result):
    res = superseded_result
    added = flags.has(res[names.QUALITY_FLAGS].values, names.FLAG_ADDED_BY_REFINE)
    assert added.any() and not added.all()
    det = res[names.DETECTED].transpose(names.POINT, names.MODE).values
    assert not det[:, added].any()  # no FRF detected them: the table said "none"
    rows = modal_table(res)
    for row, is_added in zip(rows, added, strict=True):
        if is_added:
            assert row["detected_in"] == FOUND_BY_REFINEMENT
        else:
            assert row["detected_in"] not in (FOUND_BY_REFINEMENT, "none")
    # the terminal table, however few points it lists, and the CSV say the same
    for max_points in (1, 6):
        text = format_modal_table(res, max_points=max_points)
        assert text.count(FOUND_BY_REFINEMENT) == added.sum()
        assert " none " not in text
    page = _page(res, tmp_path / "rep")
    assert page.count(f"<td class='l'>{FOUND_BY_REFINEMENT}</td>") == added.sum()
    assert "<td class='l'>none</td>" not in page
    with (tmp_path / "rep" / "modal_table.csv").open(newline="") as fh:
        column = [r["detected_in"] for r in csv.DictReader(fh)]
    assert column.count(FOUND_BY_REFINEMENT) == added.sum()
    # and the legend explains the flag
    assert f"<td class='l flag'>{names.FLAG_ADDED_BY_REFINE}</td>" in page


def test_a_constructed_added_mode_and_a_mode_nobody_detected(benchmark_result):
    """The text follows the flag, not the refinement having run: a mode with no detecting FRF
    and without added_by_refine still reads "none"."""
    res = benchmark_result.copy(deep=True)
    res[names.DETECTED].values[:, :2] = False
    mask = res[names.QUALITY_FLAGS].values.copy()
    mask[0] = flags.bit(names.FLAG_ADDED_BY_REFINE)
    mask[1] = 0
    res[names.QUALITY_FLAGS] = res[names.QUALITY_FLAGS].copy(data=mask)
    rows = modal_table(res)
    assert rows[0]["detected_in"] == FOUND_BY_REFINEMENT
    assert rows[1]["detected_in"] == "none"
    assert rows[2]["detected_in"] not in (FOUND_BY_REFINEMENT, "none")


def test_superseded_caps_are_said_in_the_report(tmp_path, superseded_result):
    attrs = superseded_result.attrs
    assert attrs[names.ATTR_AMI_CAPPED] == 0
    superseded = flags.run_status(attrs, names.ATTR_AMI_CAPPED_SUPERSEDED)
    assert superseded & flags.RunStatus.SUBTRACT_MAX_MODES
    page = _page(superseded_result, tmp_path / "rep")
    limits = page[page.index("<h3>Limits reached</h3>") :]
    assert "Limit superseded:" in limits and "[subtract:max_modes]" in limits
    assert "candidate modes per FRF (max_modes)" in limits
    assert "Incomplete" not in page
    text = format_modal_table(superseded_result, legend=True)
    assert "Limit superseded:" in text and f"{names.FLAG_ADDED_BY_REFINE}: " in text
    assert "Limit superseded" not in format_modal_table(superseded_result)  # default unchanged


def test_a_capped_result_is_said_incomplete(tmp_path, five_modes):
    res = _identify(five_modes, max_modes=1, refine=False)
    assert flags.run_status(res.attrs) & flags.RunStatus.SUBTRACT_MAX_MODES
    page = _page(res, tmp_path / "rep")
    assert "<li class=flag>Incomplete: " in page and "Modes may be missing" in page
    assert "Limit superseded" not in page


def test_no_cap_no_limits_section(tmp_path, benchmark_result):
    assert not benchmark_result.attrs.get(names.ATTR_AMI_CAPPED)
    assert names.ATTR_AMI_CAPPED_SUPERSEDED not in benchmark_result.attrs
    assert "Limits reached" not in _page(benchmark_result, tmp_path / "rep")
