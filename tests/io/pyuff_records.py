"""Dataset-58 records and files made by pyuff's own writer, for the tests of files other tools
write (``pytest.importorskip("pyuff")`` first)."""

from __future__ import annotations

import warnings

import numpy as np


def frf_record(data, freq, rsp_node=1, ref_node=1, **fields):
    """A dataset 58 as ``pyuff.prepare_58`` builds it: an accelerance FRF (m/s^2 per N) from
    DOF ``ref_node`` +Z to ``rsp_node`` +Z on an even grid; ``fields`` replace any field."""
    import pyuff

    record = {
        "binary": 0,
        "id1": "peer",
        "func_type": 4,
        "rsp_node": rsp_node,
        "rsp_dir": 3,
        "ref_node": ref_node,
        "ref_dir": 3,
        "ord_data_type": 6,
        "num_pts": freq.size,
        "abscissa_spacing": 1,
        "abscissa_min": float(freq[0]),
        "abscissa_inc": float(freq[1] - freq[0]),
        "abscissa_spec_data_type": 18,
        "ordinate_spec_data_type": 12,
        "ordinate_axis_units_lab": "m/s^2",
        "orddenom_spec_data_type": 13,
        "orddenom_axis_units_lab": "N",
        "data": np.asarray(data),
        "x": freq,
    }
    record.update(fields)
    return pyuff.prepare_58(**record)


def write_sets(path, sets):
    """``sets`` written by pyuff (its notes on optional fields silenced); returns ``path``."""
    import pyuff

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pyuff.UFF(str(path)).write_sets(list(sets), mode="add")
    return path


def read_sets(path):
    """Every dataset of ``path`` as pyuff reads it (a list, also for one dataset)."""
    import pyuff

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sets = pyuff.UFF(str(path)).read_sets()
    return [sets] if isinstance(sets, dict) else sets
