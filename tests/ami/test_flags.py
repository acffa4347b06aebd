"""Quality flags as named bits decided once (issue 19, item 3): the codec, and the same flags
from ``ami_xr.refine`` on the phases' output as from ``ami_xr.identify``."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
import xarray as xr

import ami_xr
from ami_xr import names
from ami_xr.ami import resolution
from ami_xr.core import flags
from ami_xr.errors import AmiXrValueError
from ami_xr.io import cf
from ami_xr.io.netcdf import open_dataset, to_netcdf

from ..reference import REPO


def test_encode_decode_round_trip_in_bit_order():
    mask = np.array([0, 1 | 4, 2**8, 2 ** len(names.FLAG_MEANINGS) - 1], np.int32)
    text = flags.encode(mask)
    assert text[0] == ""
    assert text[1] == f"{names.FLAG_LOW_DRIVE_SNR},{names.FLAG_NOT_CONVERGED}"
    assert text[2] == names.FLAG_REPEATED_ROOT_SEPARATED
    assert text[3].split(",") == list(names.FLAG_MEANINGS)
    np.testing.assert_array_equal(flags.decode(text), mask)
    # order and blanks do not matter when reading
    assert flags.decode([f"{names.FLAG_NOT_CONVERGED}, {names.FLAG_LOW_DRIVE_SNR}"])[0] == 5


def test_set_where_sets_and_clears_one_bit_only():
    mask = np.array([1, 1, 0], np.int32)
    out = flags.set_where(mask, names.FLAG_SINGLE_FRF, [True, False, True])
    np.testing.assert_array_equal(out, [1 | 8, 1, 8])
    out = flags.set_where(out, names.FLAG_LOW_DRIVE_SNR, False)
    np.testing.assert_array_equal(out, [8, 0, 8])
    np.testing.assert_array_equal(flags.has(out, names.FLAG_SINGLE_FRF), [True, False, True])


def test_unknown_flag_is_an_error_naming_it():
    with pytest.raises(AmiXrValueError, match="quality flag: expected one of .* got 'bogus'"):
        flags.decode(["not_converged,bogus"])


def test_every_flag_round_trips():
    for k, flag in enumerate(names.FLAG_MEANINGS):
        mask = np.array([1 << k], np.int32)
        assert flags.encode(mask)[0] == flag
        np.testing.assert_array_equal(flags.decode(flags.encode(mask)), mask)
    every = np.arange(2 ** len(names.FLAG_MEANINGS), dtype=np.int32)
    np.testing.assert_array_equal(flags.decode(flags.encode(every)), every)


def test_the_file_bits_are_the_same_bits():
    """The CF bit field on disk uses the bits of the one table: every flag, none left out."""
    assert tuple(cf.FLAG_MEANINGS) == names.FLAG_MEANINGS == flags.MEANINGS
    np.testing.assert_array_equal(cf.FLAG_MASKS, flags.MASKS)
    every = np.arange(2 ** len(names.FLAG_MEANINGS), dtype=np.int32)
    np.testing.assert_array_equal(cf.flag_mask(flags.encode(every)), every)
    # a flag the table cannot name has no bit in the file (and is an error in memory)
    assert cf.flag_mask([f"{names.FLAG_SINGLE_FRF},from_the_future"]).tolist() == [8]
    with pytest.raises(AmiXrValueError, match="unknown: expected 'raise' or 'ignore'"):
        flags.decode([""], unknown="skip")


def test_written_file_holds_every_flag(tmp_path):
    """A file written by to_netcdf: flag_meanings/flag_masks are the core table, each mode's
    bits decode to its flags, and open_dataset gives the flags back unchanged."""
    n = len(names.FLAG_MEANINGS)
    # one mode per flag, one with none and one with all
    mask = np.array([1 << k for k in range(n)] + [0, 2**n - 1], np.int32)
    text = flags.encode(mask)
    ds = xr.Dataset(
        {names.QUALITY_FLAGS: ((names.MODE,), text)},
        coords={names.MODE: np.arange(1, mask.size + 1)},
    )
    path = to_netcdf(ds, tmp_path / "flags.nc")
    with xr.open_dataset(path, engine="netcdf4") as raw:
        var = raw[cf.QUALITY_FLAG_MASK]
        assert var.attrs["flag_meanings"].split() == list(flags.MEANINGS)
        np.testing.assert_array_equal(var.attrs["flag_masks"], flags.MASKS)
        np.testing.assert_array_equal(var.values, mask)
        np.testing.assert_array_equal(flags.decode(raw[names.QUALITY_FLAGS].values), mask)
    back = open_dataset(path)
    assert list(back[names.QUALITY_FLAGS].values) == list(text)
    np.testing.assert_array_equal(flags.decode(back[names.QUALITY_FLAGS].values), mask)


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
    assert any(names.FLAG_NOT_CONVERGED in f for f in glob[names.QUALITY_FLAGS].values)
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
    mask = flags.decode(ref[names.QUALITY_FLAGS].values)
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
