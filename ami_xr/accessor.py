"""The ``ds.ami`` accessor: a thin, stateless shell over the public functions.

``ds.ami.<name>(...)`` is ``ami_xr.<name>(ds, ...)``: it returns what the function returns (a new
Dataset or a figure; the caller's Dataset is never mutated). The AMI phases (``subtract``,
``isolate``, ``global_fit``, ``identify``, ``refine``) also take ``path=``: the result is then
written there with :func:`ami_xr.to_netcdf` as well as returned (the design card's "accessors that
write netCDF"; the functions themselves never write). ``__init__`` only stores the Dataset:
validation happens inside the functions.

The functions are looked up in :mod:`ami_xr` when a method is first used, so registering the
accessor imports none of them (plotting, reports and file formats load only when called).
"""

from __future__ import annotations

import functools
import importlib
import inspect
import os
from typing import Any

import xarray as xr


def _public(name: str) -> Any:
    return getattr(importlib.import_module("ami_xr"), name)


class _Method:
    """Accessor method ``name``: ``ami_xr.<name>(ds, ...)``, plus ``path=`` when ``writes``."""

    def __init__(self, writes: bool = False):
        self.writes = writes

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, accessor: Any, owner: type | None = None) -> Any:
        func = _public(self.name)
        if accessor is None:  # class attribute: the function itself, for help() and docs
            return func
        ds = accessor._ds
        sig = inspect.signature(func)
        params = list(sig.parameters.values())[1:]  # without ds
        if not self.writes:

            @functools.wraps(func)
            def method(*args: Any, **kwargs: Any) -> Any:
                return func(ds, *args, **kwargs)

            method.__signature__ = sig.replace(parameters=params)
            return method

        @functools.wraps(func)
        def method_writing(
            *args: Any, path: str | os.PathLike | None = None, **kwargs: Any
        ) -> xr.Dataset:
            out = func(ds, *args, **kwargs)
            if path is not None:
                _public("to_netcdf")(out, path)
            return out

        params.append(inspect.Parameter("path", inspect.Parameter.KEYWORD_ONLY, default=None))
        method_writing.__signature__ = sig.replace(parameters=params)
        method_writing.__doc__ = (func.__doc__ or "") + (
            "\n    Accessor only: ``path=`` (str or path-like, optional) also writes the result "
            "there\n    (atomic netCDF, :func:`ami_xr.to_netcdf`).\n"
        )
        return method_writing


@xr.register_dataset_accessor("ami")
class AmiAccessor:
    """``ds.ami.<name>(...)`` is ``ami_xr.<name>(ds, ...)``."""

    def __init__(self, ds: xr.Dataset):
        self._ds = ds

    # data model and files
    validate = _Method()
    to_netcdf = _Method()
    write_uff = _Method()
    # signal processing
    frf = _Method()
    impact_frf = _Method()
    convert_quantity = _Method()
    estimate_frf_noise = _Method()
    apply_window = _Method()
    impulse_to_frf = _Method()
    # the AMI phases (these take ``path=`` to write their result)
    subtract = _Method(writes=True)
    isolate = _Method(writes=True)
    global_fit = _Method(writes=True)
    identify = _Method(writes=True)
    refine = _Method(writes=True)
    stability = _Method()  # no path=: it takes **identify_kwargs
    # plots and reports
    plot_bode = _Method()
    plot_nyquist = _Method()
    plot_subtraction = _Method()
    plot_mode_vectors = _Method()
    plot_mac = _Method()
    plot_modal_table = _Method()
    plot_stability = _Method()
    plot_mode_shapes = _Method()
    animate_mode_shape = _Method()
    report = _Method()
    modal_table = _Method()
