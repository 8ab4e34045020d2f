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
from . import preprocess as _preprocess
from . import filtration as _filtration
from .analysis import iso21920 as _iso21920
from .analysis import acf as _acf
from .analysis import hurst as _hurst
from .analysis import iso25178 as _iso25178
from .analysis import psd as _psd
from .analysis import reliability as _reliability
from .analysis import sdrp as _sdrp
from .analysis import vbm as _vbm
from .contact import scene as _contact_scene
from .io import netcdf as _netcdf
from . import stitching as _stitching
from . import plot as _plot
from . import twins as _twin
from .io.formats import st_netcdf as _st_netcdf


def _delegate(func):
    @functools.wraps(func)
    def method(self, *args, **kwargs):
        return func(self._obj, *args, **kwargs)

    return method


class _Accessor:
    __slots__ = ("_obj",)

    def __init__(self, xarray_obj):
        self._obj = xarray_obj


@xr.register_dataset_accessor("topo")
@xr.register_dataarray_accessor("topo")
class TopoAccessor(_Accessor):
    """``ds.topo`` and ``da.topo``: analyses of a measurement Dataset or of a height DataArray."""

    __slots__ = ()

    # foundation (issue 2)
    to_units = _delegate(conventions.convert_length)
    validate = _delegate(conventions.validate)
    scalars = _delegate(_scalars.scalars)
    distribution = _delegate(_distribution.distribution)
    to_netcdf = _delegate(_netcdf.to_netcdf)

    # io and preprocessing (issue 4)
    detrend = _delegate(_preprocess.detrend)
    fill_missing = _delegate(_preprocess.fill_missing)
    # ISO filtration and profile parameters (issue 22)
    filter = _delegate(_filtration.filter)
    iso21920 = _delegate(_iso21920.iso21920)
    to_surfacetopography_netcdf = _delegate(_st_netcdf.to_surfacetopography_netcdf)
    # scale-dependent analyses (issue 3)
    psd = _delegate(_psd.psd)
    acf = _delegate(_acf.acf)
    vbm = _delegate(_vbm.vbm)
    sdrp = _delegate(_sdrp.sdrp)
    reliability_cutoff = _delegate(_reliability.reliability_cutoff)
    hurst = _delegate(_hurst.hurst)
    # ISO 25178-2 areal parameters (issue 22)
    iso25178 = _delegate(_iso25178.iso25178)
    material_ratio = _delegate(_iso25178.material_ratio)
    # figures (issue 8)
    plot = _delegate(_plot.plot)
    # contact mechanics (issue 5)
    contact = _delegate(_contact_scene.contact)

    @property
    def height(self):
        """The height DataArray with missing data as NaN (see :func:`xtopo.conventions.height_of`)."""
        return conventions.height_of(self._obj)

    @property
    def periodic(self) -> bool:
        """Whether the measurement is periodic (attr ``periodic``)."""
        return conventions.is_periodic(self._obj)


@xr.register_datatree_accessor("topo")
class TopoTreeAccessor(_Accessor):
    """``tree.topo``: a digital surface twin (one child node per measurement)."""

    __slots__ = ()

    to_netcdf = _delegate(_twin.to_netcdf)
    measurements = _delegate(_twin.measurements)
    # twin averages (issue 6)
    psd = _delegate(_stitching.twin_psd)
    acf = _delegate(_stitching.twin_acf)
    vbm = _delegate(_stitching.twin_vbm)
    sdrp = _delegate(_stitching.twin_sdrp)

    # figures (issue 8)
    plot = _delegate(_plot.plot)  # the paper's Figure 5 (issue 21)
    plot_measurements = _delegate(_plot.measurement_maps)
