"""Quality flags as named bits decided once (issue 19, item 3): the codec, and the same flags
from ``ami_xr.refine`` on the phases' output as from ``ami_xr.identify``."""

from __future__ import annotations

import json
import re
import warnings

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.ami import resolution
from ami_xr.core import flags
from ami_xr.errors import AmiXrValueError, AssumptionWarning
from ami_xr.io import cf
from ami_xr.io.netcdf import open_dataset, to_netcdf

from ..reference import REPO


def test_text_and_from_text_round_trip_in_bit_order():
    mask = np.array([0, 1 | 4, 2**8, 2 ** len(names.FLAG_MEANINGS) - 1], np.int32)
    text = flags.flag_text(mask)
    assert text[0] == ""
    assert text[1] == f"{names.FLAG_LOW_DRIVE_SNR},{names.FLAG_NOT_CONVERGED}"
    assert text[2] == names.FLAG_REPEATED_ROOT_SEPARATED
    assert text[3].split(",") == list(names.FLAG_MEANINGS)
    np.testing.assert_array_equal(flags.from_text(text), mask)
    # order and blanks do not matter when reading
    assert flags.from_text([f"{names.FLAG_NOT_CONVERGED}, {names.FLAG_LOW_DRIVE_SNR}"])[0] == 5
    # decode: the bit field as it is, or the text of an earlier file
    np.testing.assert_array_equal(flags.decode(mask), mask)
    np.testing.assert_array_equal(flags.decode(text), mask)


def test_the_table_is_one_record_per_bit():
    assert [f.name for f in flags.TABLE] == list(names.FLAG_MEANINGS)
    assert [f.mask for f in flags.TABLE] == [1 << k for k in range(len(flags.TABLE))]
    assert all(f.description == flags.DESCRIPTIONS[f.name] for f in flags.TABLE)
    assert flags.ALL == 2 ** len(flags.TABLE) - 1


def test_set_where_sets_and_clears_one_bit_only():
    mask = np.array([1, 1, 0], np.int32)
    out = flags.set_where(mask, names.FLAG_SINGLE_FRF, [True, False, True])
    np.testing.assert_array_equal(out, [1 | 8, 1, 8])
    out = flags.set_where(out, names.FLAG_LOW_DRIVE_SNR, False)
    np.testing.assert_array_equal(out, [8, 0, 8])
    np.testing.assert_array_equal(flags.has(out, names.FLAG_SINGLE_FRF), [True, False, True])


def test_unknown_flag_or_bit_is_an_error_naming_it():
    with pytest.raises(AmiXrValueError, match="quality flag: expected one of .* got 'bogus'"):
        flags.from_text(["not_converged,bogus"])
    with pytest.raises(AmiXrValueError, match="quality_flags: bits 0x400 are not in the flag"):
        flags.decode(np.array([1 << len(flags.TABLE)], np.int32))
    with pytest.raises(AmiXrValueError, match="quality_flags: expected an integer bit field"):
        flags.decode(np.array([1.5]))
    # a mode xarray's reindex added (NaN in the promoted floats) has no flag yet
    assert flags.decode(np.array([5.0, np.nan])).tolist() == [5, 0]
    assert flags.decode(np.array([5, flags.MISSING])).tolist() == [5, 0]


def test_every_flag_round_trips():
    for k, flag in enumerate(names.FLAG_MEANINGS):
        mask = np.array([1 << k], np.int32)
        assert flags.flag_text(mask)[0] == flag
        np.testing.assert_array_equal(flags.from_text(flags.flag_text(mask)), mask)
    every = np.arange(2 ** len(names.FLAG_MEANINGS), dtype=np.int32)
    np.testing.assert_array_equal(flags.from_text(flags.flag_text(every)), every)


def test_the_file_bits_are_the_same_bits():
    """The CF bit field on disk uses the bits of the one table: every flag, none left out."""
    assert tuple(cf.FLAG_MEANINGS) == names.FLAG_MEANINGS == flags.MEANINGS
    np.testing.assert_array_equal(cf.FLAG_MASKS, flags.MASKS)
    every = np.arange(2 ** len(names.FLAG_MEANINGS), dtype=np.int32)
    np.testing.assert_array_equal(cf.flag_mask(flags.flag_text(every)), every)
    # a flag the table cannot name has no bit in the file (and is an error in memory)
    assert cf.flag_mask([f"{names.FLAG_SINGLE_FRF},from_the_future"]).tolist() == [8]
    with pytest.raises(AmiXrValueError, match="unknown: expected 'raise' or 'ignore'"):
        flags.from_text([""], unknown="skip")


def _every_flag_mask() -> np.ndarray:
    """One mode per flag, one with none and one with all."""
    n = len(names.FLAG_MEANINGS)
    return np.array([1 << k for k in range(n)] + [0, 2**n - 1], np.int32)


def test_written_file_holds_every_flag(tmp_path):
    """A file written by to_netcdf: ``quality_flags`` is the bit field in memory and on disk,
    flag_meanings/flag_masks are the core table, and open_dataset gives the bits back."""
    mask = _every_flag_mask()
    ds = xr.Dataset(
        {names.QUALITY_FLAGS: ((names.MODE,), mask)},
        coords={names.MODE: np.arange(1, mask.size + 1)},
    )
    path = to_netcdf(ds, tmp_path / "flags.nc")
    with xr.open_dataset(path, engine="netcdf4") as raw:
        var = raw[names.QUALITY_FLAGS]
        assert var.dtype == np.int32
        assert var.attrs["flag_meanings"].split() == list(flags.MEANINGS)
        np.testing.assert_array_equal(var.attrs["flag_masks"], flags.MASKS)
        np.testing.assert_array_equal(var.values, mask)
        assert cf.QUALITY_FLAG_MASK not in raw.variables  # no second copy of the bits
    back = open_dataset(path)
    assert back[names.QUALITY_FLAGS].dtype == np.int32
    np.testing.assert_array_equal(back[names.QUALITY_FLAGS].values, mask)
    assert back[names.QUALITY_FLAGS].attrs == {}  # the CF table is an on-disk encoding


def _old_format_file(path, text, caps: str):
    """A modal file as versions before issue 39 wrote it: ``quality_flags`` the comma text, the
    bits beside it in ``quality_flag_mask`` (listed in ``ami_xr_cf_added``), caps as text."""
    n = len(text)
    mask = cf.flag_mask(text)
    ds = xr.Dataset(
        {
            names.QUALITY_FLAGS: ((names.MODE,), np.asarray(text, dtype=str)),
            cf.QUALITY_FLAG_MASK: (
                (names.MODE,),
                mask,
                {"flag_masks": flags.MASKS, "flag_meanings": " ".join(flags.MEANINGS)},
            ),
            names.NATURAL_FREQUENCY: ((names.MODE,), np.linspace(10.0, 20.0, n)),
        },
        coords={names.MODE: np.arange(1, n + 1)},
        attrs={
            names.ATTR_AMI_CAPPED: caps,
            names.ATTR_AMI_CAPPED_SUPERSEDED: "",
            cf.ATTR_CF_ADDED: json.dumps(
                {"variables": [cf.QUALITY_FLAG_MASK], "attrs": {}, "global": {}}
            ),
        },
    )
    ds.to_netcdf(path, engine="netcdf4")
    return mask


def test_a_file_of_the_previous_version_reads_as_bits(tmp_path):
    """Text flags and text caps (the previous format) read back as the same bits, and a file
    written again from them holds the bit field: the round trip keeps every flag."""
    text = list(flags.flag_text(_every_flag_mask()))
    mask = _old_format_file(tmp_path / "old.nc", text, "subtract:max_modes,refine:max_iter")
    old = open_dataset(tmp_path / "old.nc")
    assert old[names.QUALITY_FLAGS].dtype == np.int32
    assert cf.QUALITY_FLAG_MASK not in old
    np.testing.assert_array_equal(old[names.QUALITY_FLAGS].values, _every_flag_mask())
    np.testing.assert_array_equal(mask, _every_flag_mask())
    caps = flags.run_status(old.attrs)
    assert caps == flags.RunStatus.SUBTRACT_MAX_MODES | flags.RunStatus.REFINE_MAX_ITER
    assert flags.run_status(old.attrs, names.ATTR_AMI_CAPPED_SUPERSEDED) == 0
    new = open_dataset(to_netcdf(old, tmp_path / "new.nc"))
    np.testing.assert_array_equal(new[names.QUALITY_FLAGS].values, _every_flag_mask())
    assert flags.run_status(new.attrs) == caps
    # the tables show the same words as before
    from ami_xr.tables import modal_table

    assert [r["flags"] for r in modal_table(new)] == text


def test_a_foreign_flag_in_an_old_file_is_left_out_with_a_warning(tmp_path):
    _old_format_file(tmp_path / "old.nc", [f"{names.FLAG_SINGLE_FRF},from_the_future", ""], "")
    with pytest.warns(AssumptionWarning, match="from_the_future"):
        old = open_dataset(tmp_path / "old.nc")
    assert old[names.QUALITY_FLAGS].values.tolist() == [flags.bit(names.FLAG_SINGLE_FRF), 0]


def test_run_status_is_bits_with_one_word_table():
    s = flags.RunStatus
    assert [c.status for c in flags.CAPS] == [1 << k for k in range(len(flags.CAPS))]
    assert s.of("refine:add_modes, isolate:max_iter") == s.REFINE_ADD_MODES | s.ISOLATE_MAX_ITER
    assert s.of(None) == s.of("") == s.of(0) == s.NONE
    assert s.of(5).text() == "subtract:max_modes,isolate:max_iter"
    with pytest.raises(AmiXrValueError, match="run status: expected caps among .* 'bogus'"):
        s.of("bogus")
    attrs: dict = {}
    flags.add_caps(attrs, ["refine:max_iter"])
    flags.add_caps(attrs, s.SUBTRACT_MAX_MODES)
    assert attrs[names.ATTR_AMI_CAPPED] == 9 and isinstance(attrs[names.ATTR_AMI_CAPPED], int)


def _quiet(function, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return function(*args, **kwargs)


@pytest.fixture(scope="module")
def capped():
    """A system whose isolation stops at its cap (one sweep): every mode gets not_converged."""
    ds, _ = ami_xr.simulate.random_system(seed=2, n_points=5, n_frequencies=1024, noise=0.01)
    return ds


def test_refine_and_identify_report_the_same_flags(capped):
    out = _quiet(ami_xr.identify, capped, max_iter=1)
    sub = _quiet(ami_xr.subtract, capped)
    iso = _quiet(ami_xr.isolate, sub, max_iter=1)
    glob = _quiet(ami_xr.global_fit, iso)
    assert flags.has(glob[names.QUALITY_FLAGS].values, names.FLAG_NOT_CONVERGED).any()
    ref = _quiet(ami_xr.refine, glob)
    ref = ref.sortby(names.NATURAL_FREQUENCY)
    # under_resolved is identify's, decided on the final modes (issue 37 item 4)
    ref = _quiet(resolution.resolution_checked, ref, capped)
    assert out.sizes[names.MODE] == ref.sizes[names.MODE]
    np.testing.assert_allclose(
        out[names.EIGENVALUE].values, ref[names.EIGENVALUE].values, rtol=1e-12
    )
    assert list(out[names.QUALITY_FLAGS].values) == list(ref[names.QUALITY_FLAGS].values)


def test_refine_supersedes_the_isolation_cap_where_it_converged(capped):
    sub = _quiet(ami_xr.subtract, capped)
    glob = _quiet(ami_xr.global_fit, _quiet(ami_xr.isolate, sub, max_iter=1))
    ref = _quiet(ami_xr.refine, glob)
    mask = ref[names.QUALITY_FLAGS].values
    trouble = flags.has(mask, names.FLAG_REFINE_FALLBACK) | flags.has(
        mask, names.FLAG_REFINE_NOT_CONVERGED
    )
    # not_converged stays only on modes the refinement did not move to a converged estimate
    assert not np.any(flags.has(mask, names.FLAG_NOT_CONVERGED) & ~trouble)
    assert np.any(~trouble)


# --- the words of each flag: one table in the code, the same in the docs (issue 29 item 4) -------
def _docs_flag_table() -> dict[str, list[str]]:
    """The rows of docs/identification.md's flag table: flag -> its cells after the name."""
    page = (REPO / "docs" / "identification.md").read_text(encoding="utf-8")
    table = page[page.index("| flag | means (the report's legend) |") :].split("\n\n")[0]
    rows = {}
    for line in table.splitlines()[2:]:
        cells = [c.strip() for c in line.strip().strip("|").split(" | ")]
        rows[cells[0].strip("`")] = cells[1:]
    return rows


def test_every_flag_has_one_line_in_words():
    assert tuple(flags.DESCRIPTIONS) == names.FLAG_MEANINGS  # every flag, in bit order
    for flag, text in flags.DESCRIPTIONS.items():
        assert flags.describe(flag) == text
        # one line a reader takes in at once, that a markdown table cell and HTML can hold
        assert 20 < len(text) <= 200 and "\n" not in text and "|" not in text
        assert text[0].isupper() and text.endswith(".")
    with pytest.raises(AmiXrValueError, match="quality flag: expected one of .* got 'bogus'"):
        flags.describe("bogus")


def test_docs_flag_table_states_the_code_texts():
    rows = _docs_flag_table()
    assert set(rows) == set(names.FLAG_MEANINGS)
    for flag, (means, _set_by) in rows.items():
        assert means == flags.DESCRIPTIONS[flag], flag
    # no other flag table on the page with other words for the same flags
    page = (REPO / "docs" / "identification.md").read_text(encoding="utf-8")
    for flag in names.FLAG_MEANINGS:
        assert len(re.findall(rf"^\| `{flag}` \|", page, flags=re.M)) == 1, flag


def test_docs_say_repeated_root_suspected_is_set_on_single_reference_data():
    """The band-rank check (ami_xr.ami.repeated) runs at the end of every identification: the
    docs must not call the flag multi-reference only (tests/ami/test_pipeline_hooks.py sets it
    on a SIMO Dataset)."""
    means, set_by = _docs_flag_table()[names.FLAG_REPEATED_ROOT]
    assert not means.lower().startswith("multi-reference")
    assert "single" in set_by and "ami_xr.ami.repeated" in set_by
