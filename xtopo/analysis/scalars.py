"""Scalar roughness parameters of a measurement (paper §4.4, Table 2)."""

from __future__ import annotations

import numpy as np
import xarray as xr

from .._apply import apply_lateral
from .._kernels import scalars as _k
from ..conventions import X, Y, height_of, is_nonuniform, is_periodic, lateral_dims, shared_length_unit, spacing
from ._scale import provenance, split_parameters, unit_of

__all__ = ["scalars"]

#: name → (long name, unit kind of _scale.unit_of)
_META = {
    "Sq": ("root mean square height", "L"),
    "Sdq": ("root mean square gradient", "1"),
    "Sddq": ("root mean square curvature", "L-1"),
    "Sa": ("arithmetic mean height", "L"),
    "Sz": ("maximum height (peak to valley)", "L"),
    "Ssk": ("skewness of the height distribution", "1"),
    "Sku": ("kurtosis of the height distribution", "1"),
    "Rq": ("root mean square height of profiles", "L"),
    "Rdq": ("root mean square slope of profiles", "1"),
    "Rddq": ("root mean square curvature of profiles", "L-1"),
    "Ra": ("arithmetic mean height of profiles", "L"),
    "Rz": ("maximum height of profiles (mean peak to valley)", "L"),
    "Rsk": ("skewness of profiles", "1"),
    "Rku": ("kurtosis of profiles", "1"),
}


def _attrs(names, length_units) -> dict:
    return {name: {"units": unit_of(_META[name][1], length_units), "long_name": _META[name][0]} for name in names}


def scalars(obj) -> xr.Dataset:
    """Scalar roughness parameters of a measurement.

    Area scans give Sq, SΔq (``Sdq``, RMS gradient), SΔ²q (``Sddq``), Sa, Sz, Ssk, Sku and
    the profile parameters Rq, RΔq (``Rdq``), RΔ²q (``Rddq``), Ra, Rz, Rsk, Rku along a
    ``direction`` dimension (``"x"``: profiles along x, ``"y"``: along y). Line scans
    give the R-parameters only (``direction = ["x"]``).

    Discrete operators follow paper Table 1. Periodic data wrap around; nonperiodic
    differences use only the samples that exist. Heights are taken about their mean
    (S: global mean, R: mean of each profile). Missing data (NaN/mask) are ignored.
    Extra dims (a batch of measurements) broadcast; dask inputs stay lazy.

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        A measurement or its height.

    Returns
    -------
    xarray.Dataset
        Heights in the measurement's length unit, slopes dimensionless, curvatures
        in inverse length; every variable has ``units`` and ``long_name``.

    Notes
    -----
    Heights of any representable scale (1e±300 included) are analysed in scaled units: the parameters
    are finite, or an :class:`~xtopo.errors.XtopoError` says they lie beyond float64 (a curvature of
    heights 1e300 m on µm pixels). A parameter is NaN exactly where it is undefined, never from a
    numerical failure:

    * all parameters, when every height is missing;
    * skewness and kurtosis (Ssk, Sku, Rsk, Rku), when the RMS height is 0 (a flat surface), with an
      :class:`~xtopo.errors.UndefinedValueWarning` (when the kernel runs: at ``.compute()`` for dask data);
    * slopes (Sdq, Rdq) of nonperiodic data with fewer than 2 samples along a direction,
      curvatures (Sddq, Rddq) with fewer than 3 (SΔq and SΔ²q need both directions).
    """
    h = height_of(obj)
    lat = lateral_dims(h)
    units = shared_length_unit(h, "scalars")
    periodic = is_periodic(h)
    out = {}

    def run(kernel, core_dims=None, **kwargs):
        return apply_lateral(kernel, h, core_dims=core_dims, output_core_dims=[["parameter"]],
                             output_sizes={"parameter": len(_k.LINE_PARAMETERS)}, kwargs=kwargs,
                             height_power=(_k.HEIGHT_POWERS,), what="scalars")

    if lat == (Y, X):
        dy, dx = spacing(h, Y), spacing(h, X)
        out.update(split_parameters(run(_k.area_parameters, dy=dy, dx=dx, periodic=periodic),
                                    _attrs(_k.AREA_PARAMETERS, units)))
        r = xr.concat([run(_k.profile_parameters, dx=dx, periodic=periodic, rows=1),
                       run(_k.profile_parameters, (X, Y), dx=dy, periodic=periodic, rows=1)], dim="direction")
    elif is_nonuniform(h):
        r = run(_k.nonuniform_parameters, x=np.asarray(h[X].values, dtype=float)).expand_dims("direction")
    else:
        r = run(_k.profile_parameters, dx=spacing(h, X), periodic=periodic, rows=0).expand_dims("direction")
    # a fixed-width unicode label for line and area scans alike (expand_dims would make it an object array)
    r = r.assign_coords(direction=("direction", np.array([X, Y][: r.sizes["direction"]]),
                                   {"long_name": "direction of the profiles"}))
    out.update(split_parameters(r, _attrs(_k.LINE_PARAMETERS, units)))
    ds = xr.Dataset(out, attrs={"title": "scalar roughness parameters", "periodic": int(periodic)})
    return provenance(ds, obj, "scalars")
