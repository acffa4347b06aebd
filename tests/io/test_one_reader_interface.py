"""One reader interface (issue 39, item 5): a registry of readers with one signature, one options
record, one unit parser for every format and one force-channel rule."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

import ami_xr
from ami_xr import names
from ami_xr.errors import AmiXrValueError, DataFileError
from ami_xr.io import readers
from ami_xr.io.build import OPTION_KEYS, ReadOptions, force_channels
from ami_xr.io.frf_tables import read_frf_csv
from ami_xr.io.units import force_unit, frf_unit, response_unit

from .pyuff_records import frf_record, write_sets

FREQ = np.arange(1.0, 9.0)
H = (np.arange(FREQ.size) + 1.0) + 0.5j

# (label as a file writes it, (response units, force units)): every spelling both formats take
SPELLINGS = [
    ("m/s^2/N", ("m/s^2", "N")),
    ("m/s²/N", ("m/s^2", "N")),
    ("m/s2/N", ("m/s^2", "N")),
    ("m/s**2/N", ("m/s^2", "N")),
    ("(m/s^2)/N", ("m/s^2", "N")),
    ("(m/s²)/(N)", ("m/s^2", "N")),
    ("(1/N)*(m/s²)", ("m/s^2", "N")),
    ("(m/s^2)*(1/N)", ("m/s^2", "N")),
    ("m / s^2 / N", ("m/s^2", "N")),
    ("G/N", ("g", "N")),
    ("g/lbf", ("g", "lbf")),
    ("mm/s/N", ("mm/s", "N")),
    ("m/N", ("m", "N")),
    ("µm/N", ("um", "N")),
    ("in/s2/lbf", ("in/s^2", "lbf")),
    ("m/s/kn", ("m/s", "kN")),
]


def _csv(path, unit):
    lines = [f"freq [Hz],p1_re [{unit}],p1_im [{unit}]"]
    lines += [f"{f},{h.real},{h.imag}" for f, h in zip(FREQ.tolist(), H.tolist(), strict=True)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _uff(path, unit):
    pytest.importorskip("pyuff")
    # ordinate type 0 (unknown): the quantity comes from the unit label
    record = frf_record(
        H,
        FREQ,
        ordinate_spec_data_type=0,
        ordinate_axis_units_lab=unit,
        orddenom_axis_units_lab="NONE",
    )
    return write_sets(path, [record])


@pytest.mark.parametrize(("label", "expected"), SPELLINGS)
def test_csv_and_uff_accept_the_same_unit_spellings(tmp_path, label, expected):
    assert frf_unit(label) == expected
    csv_ds = read_frf_csv(_csv(tmp_path / "h.csv", label))
    uff_ds = ami_xr.read_uff(_uff(tmp_path / "h.uff", label))
    for ds in (csv_ds, uff_ds):
        got = (ds.attrs[names.ATTR_RESPONSE_UNITS], ds.attrs[names.ATTR_FORCE_UNITS])
        assert got == expected
        quantity = {u: q for q, us in names.RESPONSE_UNITS.items() for u in us}[expected[0]]
        assert ds.attrs[names.ATTR_QUANTITY] == quantity
        np.testing.assert_allclose(ds[names.FRF].values[0], H)


@pytest.mark.parametrize("label", ["m/s^3/N", "furlong/N", "m/s^2/kg", "N"])
def test_both_refuse_what_the_parser_does_not_know(tmp_path, label):
    assert frf_unit(label) is None
    with pytest.raises(DataFileError, match="not understood"):
        read_frf_csv(_csv(tmp_path / "h.csv", label))
    with pytest.raises(DataFileError, match="name no response quantity"):
        ami_xr.read_uff(_uff(tmp_path / "h.uff", label))


def test_single_units_as_the_time_readers_see_them():
    assert [force_unit(u) for u in ("Newtons", "n", "KN", "lbs", "V", "")] == [
        "N",
        "N",
        "kN",
        "lbf",
        None,
        None,
    ]
    assert [response_unit(u) for u in ("m/s/s", "G", "MM/S", "m/s³")] == [
        "m/s^2",
        "g",
        "mm/s",
        None,
    ]


def test_every_registered_reader_has_one_signature_and_known_options():
    seen = readers.readers()
    assert {r.name for r in seen} >= {"netCDF", "UFF", "LabVIEW .lvm input"}
    fields = set(inspect.signature(ReadOptions).parameters)
    for reader in seen:
        assert list(inspect.signature(reader.read).parameters) == ["path", "options", "want"]
        assert set(reader.accepts) <= fields, reader.name
        for suffix in reader.suffixes:
            assert readers.reader_for(f"x{suffix.upper()}") is reader
    assert set(OPTION_KEYS) == {
        "points",
        "drive_point",
        "response_quantity",
        "frf_type",
        "response_units",
        "force_units",
    }
    with pytest.raises(DataFileError, match="unknown file type '.xyz'"):
        readers.reader_for("data.xyz")


def test_an_option_a_format_does_not_take_names_those_that_do(tmp_path):
    path = _csv(tmp_path / "h.csv", "m/N")
    nc = ami_xr.to_netcdf(read_frf_csv(path, drive_point="p1"), tmp_path / "h.nc")
    with pytest.raises(AmiXrValueError, match=r"force_units: only for LabVIEW .*text tables"):
        readers.read_any(nc, force_units="N")
    with pytest.raises(AmiXrValueError, match=r"colour: not an option"):
        readers.read_any(path, colour="red")
    with pytest.raises(AmiXrValueError, match=r"colour: not an option of read_frf_csv"):
        read_frf_csv(path, colour="red")


def test_one_force_channel_rule():
    titles, units = ["Force", "a1", "a2", "F2"], ["Newtons", "g", "g", "V"]
    assert force_channels(None, titles, units, _P) == [0]  # the one force unit
    assert force_channels(None, ["hammer force", "a"], ["V", "V"], _P) == [0]  # the title
    assert force_channels("Force, F2", titles, units, _P) == [0, 3]
    assert force_channels([3, "a1"], titles, units, _P) == [3, 1]
    with pytest.raises(AmiXrValueError, match="cannot tell the force channel of x.csv"):
        force_channels(None, ["a", "b"], ["g", "g"], _P)
    with pytest.raises(AmiXrValueError, match=r"expected a channel index 0\.\.3 or one of"):
        force_channels("F9", titles, units, _P)
    with pytest.raises(AmiXrValueError, match="given twice"):
        force_channels([0, "Force"], titles, units, _P)


class _Path:
    name = "x.csv"

    def __str__(self):
        return self.name


_P = _Path()
