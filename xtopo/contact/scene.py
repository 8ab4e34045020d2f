"""What a contact calculation models, and nothing more (paper §5, DESIGN.md §5).

A :class:`Scene` takes one measurement (or two, ``h1 + h2``) and the models of the contact
(:mod:`xtopo.contact.models`: the elastic half-space of modulus ``E*``, a plastic cap where a
hardness is given), decides the boundary condition, and builds only the operators that scene
needs: the periodic Green's function eq. (17) on the native grid for periodic data; the Love
rectangle eq. (19) on a ``2N`` padded grid (Hockney) for free boundaries; the plane-strain
kernels for line scans; a pressure cap only with a hardness. The FFT plans are built on first
use and are not pickled. :func:`contact` solves a scene in one call.
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
import xarray as xr

from .._apply import scale_exponent
from .._kernels.fft import choose_backend
from .._kernels.greens import padded_shape
from .._optional import require
from ..conventions import LATERAL_DIMS, height_of, is_nonuniform, is_periodic, provenance_of, shared_length_unit, spacing
from ..errors import ContactError, GridError
from ..params import Choice, Flag, checked
from ..presets import resolve as resolve_preset
from .curves import curve as _curve
from .models import PlasticCap, scene_models
from .solve import ONE_CONTROL, solve as _solve

__all__ = ["Scene", "contact"]


def _heights(obj, what: str) -> xr.DataArray:
    h = height_of(obj)
    extra = [d for d in h.dims if d not in LATERAL_DIMS]
    if extra:
        raise ContactError(f"{what}: a Scene models one measurement, but 'height' has the extra dims {extra}; "
                           f"select one (e.g. .isel({extra[0]}=0)) or batch the solves (xtopo.batch)")
    if "x" not in h.dims:
        raise GridError(f"{what}: 'height' has no 'x' dimension (dims {h.dims}); rename the lateral dims to 'x'/'y'")
    if is_nonuniform(obj):
        raise GridError(f"{what}: contact mechanics needs a uniform grid; interpolate the nonuniform scan first")
    h = h.transpose(*[d for d in LATERAL_DIMS if d in h.dims])
    values = np.asarray(h.values)
    if not np.all(np.isfinite(values)):
        raise ContactError(f"{what}: 'height' has {int(np.count_nonzero(~np.isfinite(values)))} missing (NaN, "
                           "masked or infinite) points; fill them first (e.g. xtopo.preprocess.fill_missing) — a contact "
                           "calculation needs a height at every pixel")
    return h


class Scene:
    """A contact problem: rigid rough surface(s) on an elastic half-space.

    Parameters
    ----------
    topography : xarray.Dataset or xarray.DataArray
        A measurement (``height`` on ``("y", "x")`` or ``("x",)``, uniform grid, no
        missing data). Heights point toward the elastic body: the highest point touches first.
    modulus : float
        Contact modulus ``E*`` (``1/E* = (1-ν₁²)/E₁ + (1-ν₂²)/E₂``), default 1. Pressures, loads
        and the hardness are in the units of ``modulus``, named by ``modulus_units``.
    hardness : float, optional
        Indentation hardness ``p_y``: pressures are capped at this value (simple
        perfectly plastic model). Without it no cap is built.
    periodic : bool, optional
        Boundary condition; default the ``periodic`` attribute of the topography (and of
        the counter surface: both must be periodic).
    counter : xarray.Dataset or xarray.DataArray, optional
        A second rough surface on the same grid; the scene uses the compound topography
        ``h1 + h2`` (paper §5.2).
    dtype : {"float64", "float32"}, optional
        Floating point type of the solver; default from ``preset`` (``"float64"``).
    modulus_units : str, optional
        Units label of ``modulus`` (e.g. ``"GPa"``); default ``"E*"`` for the default modulus 1
        (pressures relative to ``E*``), ``"Pa"`` for any other value.
    backend : {"auto", "scipy", "pyfftw"}
        FFT library (default ``"auto"``: planned pyFFTW where it is installed, else scipy; see
        :func:`xtopo._kernels.fft.choose_backend`).
    preset : {"fast", "default", "accurate"}, optional
        Speed-versus-accuracy preset (:mod:`xtopo.presets`): sets ``dtype`` here and the
        ``tol``/``maxiter`` of :meth:`solve` and :meth:`curve` unless those are given.
    models : sequence of xtopo.contact.models.Model, optional
        Further models of the contact, composed by the solver with the elastic half-space
        (``modulus``) and the plastic cap (``hardness``); :attr:`models` holds them all.

    Notes
    -----
    A scene keeps its FFT plans and work arrays between solves. Solves on one scene from
    several threads are safe but run one at a time (they share those buffers); for parallel
    solves give each thread its own scene, or use :func:`xtopo.batch.contact`.
    """

    @checked
    def __init__(self, topography, *, modulus: float = 1.0, hardness: float | None = None,
                 periodic: Annotated[bool | None, Flag(error=ContactError)] = None, counter=None, dtype=None,
                 modulus_units: str | None = None,
                 backend: Annotated[str, Choice("auto", "scipy", "pyfftw", error=ContactError)] = "auto",
                 preset: str | None = None, models=()):
        h = _heights(topography, "topography")
        dtype = resolve_preset("contact", preset, dtype=dtype)["dtype"]
        self.preset = preset
        #: what is modelled (:mod:`xtopo.contact.models`): the elastic half-space first
        self.models = scene_models(modulus, hardness, modulus_units, models)
        self.modulus, self.modulus_units = self.models[0].modulus, self.models[0].units  # E* and the pressures' units
        self.hardness = next((m.hardness for m in self.models if isinstance(m, PlasticCap)), None)  # None: no cap
        try:
            floating = np.dtype(dtype) in (np.dtype("float32"), np.dtype("float64"))
        except TypeError:  # not a dtype at all ("foo", a list)
            floating = False
        if not floating:
            raise ContactError(f"dtype must be 'float64' or 'float32', got {dtype!r}")
        self.dtype = np.dtype(dtype)
        self.length_units = shared_length_unit(h, "topography")
        self.dims = tuple(h.dims)
        self.shape = tuple(h.shape)
        self.spacing = tuple(spacing(h, d) for d in self.dims)
        per_attr = is_periodic(topography)
        source = f"from the data's periodic attribute ({int(per_attr)})"
        values = np.asarray(h.values, dtype=np.float64)
        if counter is not None:
            h2 = _heights(counter, "counter")
            self._check_same_grid(h, h2)
            per_counter = is_periodic(counter)
            source = (f"from the periodic attributes of the topography ({int(per_attr)}) and the counter surface "
                      f"({int(per_counter)}): periodic only when both are")
            per_attr = per_attr and per_counter
            values = values + np.asarray(h2.values, dtype=np.float64)
        self.periodic = bool(per_attr) if periodic is None else periodic
        self._boundary_reason = source if periodic is None else "as requested"
        self._reasons = [] if counter is None else ["compound topography h1 + h2 (counter surface given)"]
        self.coords = {d: h.coords[d] for d in self.dims}
        #: what the results carry of the measurement: its file, checksum and processing history
        self.provenance = provenance_of(topography)
        self.heights = values
        # rigid surface relative to its highest point (≤ 0): first contact at penetration 0, in scaled units
        # w · 2**-height_exponent when its heights are extreme (see xtopo._apply: the solver's results are linear
        # in the heights, so solve.run_solver scales the controls down and the results back up)
        w = values - values.max()
        self.height_exponent = scale_exponent(w)
        self.w = np.ldexp(w, -self.height_exponent).astype(self.dtype)
        self.pixel_area = float(np.prod(self.spacing))
        self.nominal_area = self.pixel_area * int(np.prod(self.shape))
        self.backend_request = backend
        self.fft_shape = self.shape if self.periodic else padded_shape(self.shape)
        self._choose_backend()
        self._conv = None

    def _choose_backend(self):
        """The FFT backend of this process: ``auto`` takes pyFFTW where it imports (a worker may lack it);
        ``pyfftw`` needs the [fftw] extra."""
        self.backend = choose_backend(self.fft_shape, self.backend_request, planned=True)
        if self.backend == "pyfftw":
            require("pyfftw", "backend='pyfftw'")

    @staticmethod
    def _check_same_grid(h1, h2):
        if h1.dims != h2.dims or h1.shape != h2.shape:
            raise GridError(f"counter surface has dims {h2.dims} shape {h2.shape}, but the topography has "
                            f"{h1.dims} {h1.shape}; interpolate one onto the other's grid first")
        u1, u2 = shared_length_unit(h1, "topography"), shared_length_unit(h2, "counter")
        if u1 != u2:
            raise GridError(f"counter surface is in {u2!r} but the topography in {u1!r}; convert with "
                            f".topo.to_units({u1!r})")
        for d in h1.dims:
            if not np.isclose(spacing(h1, d), spacing(h2, d), rtol=1e-6):
                raise GridError(f"counter surface has spacing {spacing(h2, d)} along {d!r}, the topography "
                                f"{spacing(h1, d)}; both must share one grid")

    # -- what is modelled -----------------------------------------------------------------
    @property
    def line(self) -> bool:
        """True for a line scan (plane strain)."""
        return len(self.shape) == 1

    @property
    def convolution(self):
        """The elastic operator ``u = G * p`` (built on first use)."""
        if self._conv is None:
            self._conv = self.models[0].operator(self)
        return self._conv

    def __getstate__(self):
        state = dict(self.__dict__)
        state["_conv"] = None  # rebuilt lazily after unpickling
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._choose_backend()  # unpickled in another process (a dask worker)

    def __repr__(self) -> str:
        grid = "×".join(str(n) for n in self.shape)
        sp = "×".join(f"{d:g}" for d in self.spacing)
        kind = "line scan, plane strain" if self.line else "area scan"
        lines = [f"Scene({kind}, {grid} px of {sp} {self.length_units})",
                 f"  boundary: {'periodic' if self.periodic else 'free'} ({self._boundary_reason})"]
        lines += [f"  {m.describe(self)}" for m in self.models]
        if len(self.models) == 1:
            lines.append("  plasticity: none (no hardness given, no cap)")
        lines.append(f"  solver: Polonsky–Keer CG, {self.dtype.name}, FFT backend {self.backend} "
                     f"({'requested' if self.backend_request != 'auto' else 'planned FFTW when installed'})"
                     + (f", preset {self.preset!r}" if self.preset is not None else ""))
        lines += [f"  {r}" for r in self._reasons]
        return "\n".join(lines)

    # -- solving (implemented in solve.py / curves.py) ----------------------------------------
    def solve(self, load=None, *, mean_pressure=None, penetration=None, tol=None, maxiter: int | None = None,
              initial=None, preset: str | None = None, callback=None) -> xr.Dataset:
        """Solve for one load, mean pressure or penetration; see :func:`xtopo.contact.solve.solve`."""
        return _solve(self, load=load, mean_pressure=mean_pressure, penetration=penetration, tol=tol,
                      maxiter=maxiter, initial=initial, preset=preset, callback=callback)

    def curve(self, loads=None, *, mean_pressures=None, penetrations=None, tol=None, maxiter: int | None = None,
              gap_bins: int = 50, preset: str | None = None) -> xr.Dataset:
        """Solve a sequence of loads (warm-started); see :func:`xtopo.contact.curves.curve`."""
        return _curve(self, loads=loads, mean_pressures=mean_pressures, penetrations=penetrations, tol=tol,
                      maxiter=maxiter, gap_bins=gap_bins, preset=preset)


@checked(ONE_CONTROL)
def contact(topography, *, load=None, mean_pressure=None, penetration=None, modulus: float = 1.0,
            hardness: float | None = None, periodic: bool | None = None, counter=None, dtype=None,
            tol=None, maxiter: int | None = None, preset: str | None = None) -> xr.Dataset:
    """Contact of ``topography`` on an elastic flat: a :class:`~xtopo.contact.Scene` solved in one call.

    A scalar ``load``/``mean_pressure``/``penetration`` gives one solution
    (:func:`~xtopo.contact.solve.solve`); a sequence gives a load curve
    (:func:`~xtopo.contact.curves.curve`).

    Parameters
    ----------
    topography : xarray.Dataset or xarray.DataArray
        A measurement (uniform grid, no missing data), as in :class:`~xtopo.contact.Scene`.
    load, mean_pressure, penetration : float or sequence of float
        Exactly one: load in units of ``modulus`` × length² (area scans) or × length (line
        scans: force per unit length), mean pressure in units of ``modulus``, penetration in the
        measurement's length unit (see :func:`~xtopo.contact.solve.solve`).
    modulus : float
        Contact modulus ``E*`` (default 1: pressures and loads in units of ``E*``).
    hardness : float, optional
        Pressure cap, in units of ``modulus``; without it the contact is elastic.
    periodic : bool, optional
        Boundary condition (default: the measurement's ``periodic`` attribute).
    counter : xarray.Dataset or xarray.DataArray, optional
        A second rough surface on the same grid (compound topography ``h1 + h2``).
    dtype : {"float64", "float32"}, optional
        Floating point type of the solver (default from ``preset``: float64).
    tol, maxiter : optional
        Solver tolerance and iteration limit, as in :func:`~xtopo.contact.solve.solve`.
    preset : {"fast", "default", "accurate"}, optional
        Sets ``dtype``, ``tol`` and ``maxiter`` where they are not given (:mod:`xtopo.presets`).

    Returns
    -------
    xarray.Dataset
        As :func:`~xtopo.contact.solve.solve` (scalar control) or :func:`~xtopo.contact.curves.curve` (a sequence).
    """
    scene = Scene(topography, modulus=modulus, hardness=hardness, periodic=periodic, counter=counter, dtype=dtype,
                  preset=preset)
    key, value = ONE_CONTROL.given(dict(load=load, mean_pressure=mean_pressure, penetration=penetration))
    if np.ndim(value) == 0:
        return scene.solve(**{key: value}, tol=tol, maxiter=maxiter)
    return scene.curve(**{f"{key}s": value}, tol=tol, maxiter=maxiter)
