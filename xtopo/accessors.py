"""``.topo`` accessors on DataArray, Dataset and DataTree: one-line delegations only.

Every method calls the public function of the same name with the wrapped object
as first argument (``functools.wraps`` carries the docstring over). No state.
"""

from __future__ import annotations

import functools

import xarray as xr

from . import conventions
from .analysis import distribution as _distribution
from .analysis import scalars as _scalars
from .contact import curves as _contact_curves
from .io import netcdf as _netcdf


def _delegate(func):
    @functools.wraps(func)
    def method(self, *args, **kwargs):
        return func(self._obj, *args, **kwargs)

    return method


class _TopoAccessor:
    __slots__ = ("_obj",)

    def __init__(self, xarray_obj):
        self._obj = xarray_obj

    # foundation (issue 2)
    to_units = _delegate(conventions.convert_length)
    validate = _delegate(conventions.validate)
    scalars = _delegate(_scalars.scalars)
    distribution = _delegate(_distribution.distribution)
    to_netcdf = _delegate(_netcdf.to_netcdf)

    # contact mechanics (issue 5)
    contact = _delegate(_contact_curves.contact)

    @property
    def height(self):
        """The height DataArray with missing data as NaN (see :func:`xtopo.conventions.height_of`)."""
        return conventions.height_of(self._obj)

    @property
    def periodic(self) -> bool:
        """Whether the measurement is periodic (attr ``periodic``)."""
        return conventions.is_periodic(self._obj)


@xr.register_dataset_accessor("topo")
class TopoDatasetAccessor(_TopoAccessor):
    """``ds.topo``: analyses of a measurement Dataset."""

    __slots__ = ()


@xr.register_dataarray_accessor("topo")
class TopoDataArrayAccessor(_TopoAccessor):
    """``da.topo``: analyses of a height DataArray."""

    __slots__ = ()
