"""Seeded synthetic surfaces, simulated instruments and the example twin.

Everything here is deterministic for a given ``seed``.  The ground-truth power
spectrum of a :func:`fractal_surface` is available as a :class:`FractalPSD`
(``ds.attrs`` hold its parameters; :func:`prescribed_psd` rebuilds it), so tests
can compare measured spectra against the truth.

Spectral conventions follow paper §4.1/§4.6: ``C2D = |h̃|²/(Lx Ly)`` with
``h̃ = Δx Δy Σ h e^{-iq·r}``, hence ``Sq² = Σ_q C2D / (Lx Ly)`` (Parseval).
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import math
from typing import Annotated

import numpy as np
import xarray as xr

from ._checks import per_axis, real_array
from ._kernels import fft as _fft
from ._kernels.derivatives import forward_difference, fourier_first, wavevectors
from ._kernels.spectra import rfft_multiplicity
from .conventions import append_history, height_of, lateral_dims, make_measurement, spacing
from ._progress import progress_bar
from .errors import GridError, XtopoError
from .params import Choice, Count, Flag, Kind, Lengths, LengthUnit, OneOf, Positive, Real, Refused, checked, preflight

__all__ = ["FractalPSD", "fractal_surface", "prescribed_psd", "sphere", "sinusoid", "measure", "example_twin"]


#: most points of a synthetic surface or simulated measurement (8 GiB per float64 array)
MAX_POINTS = 2**30


class Shape(Kind):
    """``(nx,)`` or ``(ny, nx)`` of positive ints (an int, a tuple, a list or an array of them), of at most
    :data:`MAX_POINTS` points."""

    expects = "nx, (nx,) or (ny, nx) of positive integers"
    error = GridError

    def convert(self, shape):
        items = np.asarray(shape, dtype=object).ravel() if np.ndim(shape) <= 1 else ()
        try:
            out = tuple(Count().convert(n) for n in items)
        except Refused:
            out = ()
        if len(out) not in (1, 2):
            raise Refused
        if math.prod(out) > MAX_POINTS:
            raise Refused(f"{{name}}={shape!r} is {math.prod(out):.3g} points, more than the {MAX_POINTS} (8 GiB per "
                          "float64 array) a synthetic surface or measurement may have")
        return out



@functools.lru_cache(maxsize=8)
def _gauss_legendre(nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on [-1, 1] (cached: numpy solves an eigenproblem each time)."""
    t, w = np.polynomial.legendre.leggauss(nodes)
    t.flags.writeable = False
    w.flags.writeable = False
    return t, w

@checked
@dataclasses.dataclass(frozen=True)
class FractalPSD:
    """Isotropic self-affine PSD with roll-off and short-wavelength cutoff.

    ``C_iso(q) = prefactor · max(q, q_L)^(-2-2H)`` for ``q ≤ q_s`` and 0 above, with
    ``q_L = 2π/long_cutoff`` and ``q_s = 2π/short_cutoff`` (absent cutoffs are 0 / ∞).
    For line scans (``dim=1``) the exponent is ``-1-2H``.

    Units: ``prefactor`` in ``units^(4-2-2H)``-consistent form, i.e. ``C_iso`` in
    ``units^4`` (area) or ``units^3`` (line) for ``q`` in ``units^-1``.
    """

    hurst: Annotated[float, Real(0.0, 1.0, closed=False)]
    prefactor: Annotated[float, Positive()]
    long_cutoff: Annotated[float | None, Positive()] = None
    short_cutoff: Annotated[float | None, Positive()] = None
    dim: Annotated[int, Choice(1, 2)] = 2

    def __post_init__(self):
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        for key, value in preflight(FractalPSD, fields).items():  # frozen: set them as the dataclass would
            object.__setattr__(self, key, value)

    @property
    def q_long(self) -> float:
        return 0.0 if self.long_cutoff is None else 2 * np.pi / self.long_cutoff

    @property
    def q_short(self) -> float:
        return np.inf if self.short_cutoff is None else 2 * np.pi / self.short_cutoff

    def _shape(self, q, exponent):
        q = np.abs(_finite_values(q, "q (wavevectors)"))
        qq = np.maximum(q, self.q_long) if self.q_long > 0 else q
        with np.errstate(divide="ignore"):
            c = np.where(qq > 0, qq ** np.where(qq > 0, exponent, 0.0), 0.0)
        return np.where(q <= self.q_short, c, 0.0)

    def c_native(self, q):
        """The PSD in the surface's own dimension (C_iso for areas, C1D for lines)."""
        return self.prefactor * self._shape(q, -self.dim - 2 * self.hurst)

    def c_iso(self, q):
        """Radially averaged 2D PSD (area surfaces only)."""
        if self.dim != 2:
            raise XtopoError("a line-scan fractal has no 2D PSD")
        return self.c_native(q)

    def c1d(self, q, *, nodes: int = 400):
        """1D PSD of profiles: ``C1D(q) = (1/π) ∫_0^∞ C_iso(√(q²+k²)) dk`` for areas."""
        if self.dim == 1:
            return self.c_native(q)
        q = np.atleast_1d(np.abs(_finite_values(q, "q (wavevectors)")))
        shape, q = q.shape, q.ravel()
        kmax = np.sqrt(np.maximum(self.q_short**2 - q**2, 0.0)) if np.isfinite(self.q_short) else None
        # Gauss-Legendre in t with k = q_ref * sinh(t) resolves the kink at q_L and the tail.
        t, w = _gauss_legendre(nodes)
        out = np.zeros_like(q)
        for i, qi in enumerate(q):
            scale = max(qi, self.q_long, 1e-300)
            tmax = np.arcsinh(kmax[i] / scale) if kmax is not None else np.arcsinh(1e8)
            if tmax <= 0:
                continue
            tt = 0.5 * tmax * (t + 1)
            k = scale * np.sinh(tt)
            jac = scale * np.cosh(tt) * 0.5 * tmax
            vals = self.c_native(np.sqrt(qi**2 + k**2))
            out[i] = np.sum(w * vals * jac) / np.pi
        return out.reshape(shape)

    @checked
    def acf(self, distance: Annotated[np.ndarray, Lengths(empty=False)], *,
            q_max: Annotated[float | None, Positive()] = None, nodes: int = 4000):
        """Height-difference ACF of profiles, ``A(ℓ) = (1/π) ∫_0^∞ C1D(q) (1 - cos qℓ) dq`` (paper eq. 11).

        ``q_max`` truncates the integral (e.g. at the Nyquist wavevector of the grid the
        surface was synthesised on); default: the short cutoff or 10⁴/min(ℓ).
        """
        ell = distance
        top = q_max if q_max is not None else (self.q_short if np.isfinite(self.q_short) else 1e4 / ell.min())
        bottom = min(self.q_long if self.q_long > 0 else np.inf, 1.0 / ell.max()) * 1e-4
        lq = np.linspace(np.log(bottom), np.log(top), nodes)
        q = np.exp(lq)
        grid = np.geomspace(bottom, top, 300)
        c = np.exp(np.interp(lq, np.log(grid), np.log(np.maximum(self.c1d(grid), 1e-300))))
        integrand = c[None, :] * (1 - np.cos(q[None, :] * ell[:, None])) * q[None, :]
        return np.trapezoid(integrand, lq, axis=-1) / np.pi

    @checked
    def slope(self, distance: Annotated[np.ndarray, Lengths(empty=False)], **kw):
        """Scale-dependent RMS slope of profiles, ``sqrt(2 A(ℓ))/ℓ`` (paper §4.7)."""
        return np.sqrt(2 * self.acf(distance, **kw)) / distance

    @checked
    def __call__(self, q, kind: Annotated[str, Choice("native", "iso", "1d")] = "native"):
        return {"native": self.c_native, "iso": self.c_iso, "1d": self.c1d}[kind](q)

    def to_attrs(self) -> dict:
        return {"psd_hurst": self.hurst, "psd_prefactor": self.prefactor,
                "psd_long_cutoff": np.nan if self.long_cutoff is None else self.long_cutoff,
                "psd_short_cutoff": np.nan if self.short_cutoff is None else self.short_cutoff,
                "psd_dim": self.dim}


def _finite_values(values, name: str) -> np.ndarray:
    """``values`` as a float array of finite real numbers (any shape), else an XtopoError naming ``name``."""
    v = real_array(values)
    if v is None or not np.all(np.isfinite(v)):
        raise XtopoError(f"{name} must be finite real numbers, got {values!r}")
    return v


def prescribed_psd(ds) -> FractalPSD:
    """Rebuild the ground-truth :class:`FractalPSD` from a synthetic surface's attrs."""
    a = getattr(ds, "attrs", {})
    if "psd_prefactor" not in a:
        raise XtopoError("this dataset carries no prescribed PSD (it was not made by fractal_surface)")
    lc, sc = float(a["psd_long_cutoff"]), float(a["psd_short_cutoff"])
    return FractalPSD(float(a["psd_hurst"]), float(a["psd_prefactor"]),
                      None if np.isnan(lc) else lc, None if np.isnan(sc) else sc, int(a["psd_dim"]))


def _grid_q(shape, spacings):
    """|q| on an rfft grid and the per-mode symbols of the forward difference."""
    qs = np.ix_(*[wavevectors(n, d, real=k == len(shape) - 1) for k, (n, d) in enumerate(zip(shape, spacings))])
    return np.sqrt(sum(q**2 for q in qs)), list(zip(qs, spacings))


_HURST = Real(0.0, 1.0, closed=False)


@checked(OneOf("rms_height", "rms_slope", "prefactor", optional=True))
def fractal_surface(shape: Annotated[tuple, Shape()], size, *, hurst: Annotated[float, _HURST],
                    rms_height: Annotated[float | None, Positive()] = None,
                    rms_slope: Annotated[float | None, Positive()] = None,
                    prefactor: Annotated[float | None, Positive()] = None,
                    short_cutoff: Annotated[float | None, Positive()] = None,
                    long_cutoff: Annotated[float | None, Positive()] = None, periodic: Annotated[bool, Flag()] = True,
                    seed: Annotated[int, Count(min=0)] = 0, units: Annotated[str, LengthUnit()] = "m") -> xr.Dataset:
    """Self-affine random surface by Fourier synthesis.

    Parameters
    ----------
    shape : int or tuple of int
        ``(ny, nx)`` for an area scan, ``nx`` or ``(nx,)`` for a line scan.
    size : float or tuple of float
        Physical size ``(Ly, Lx)`` or ``Lx`` in ``units``.
    hurst : float
        Hurst exponent H in (0, 1).
    rms_height, rms_slope : float, optional
        Normalise the realisation so that its measured Sq (or SΔq / RΔq with the
        Table 1 forward difference) equals this value exactly (periodic surfaces;
        nonperiodic windows are normalised on the periodic parent). Give at most one.
    prefactor : float, optional
        Fix the PSD prefactor instead (no normalisation of the realisation); the
        surface is then one sample of a fixed ground truth, as in :func:`example_twin`.
    short_cutoff, long_cutoff : float, optional
        Wavelengths (in ``units``) below which the PSD is zero / above which it is flat.
    periodic : bool
        A periodic surface of the given size, or a nonperiodic window cut from a
        periodic surface twice as large.
    seed : int
        Seed of the random phases and amplitudes.
    units : str
        Length unit.

    Returns
    -------
    xarray.Dataset
        A measurement with ``attrs`` holding the PSD parameters (see :func:`prescribed_psd`).
    """
    size = per_axis(size, len(shape), "size")
    if rms_height is None and rms_slope is None and prefactor is None:
        rms_height = 1.0
    spacings = size / np.asarray(shape)
    gshape = shape if periodic else tuple(2 * n for n in shape)
    if math.prod(gshape) > MAX_POINTS:
        raise GridError(f"shape={shape!r}: a nonperiodic window is cut from a periodic surface twice as large "
                        f"({gshape}), more than the {MAX_POINTS} points a synthetic surface may have")
    gsize = size if periodic else 2 * size
    dim = len(shape)
    psd = FractalPSD(hurst, 1.0, long_cutoff, short_cutoff, dim)
    qabs, symbols = _grid_q(gshape, spacings)
    c = psd.c_native(qabs)
    area = float(np.prod(gsize))
    weights = rfft_multiplicity(gshape[-1])  # of each rfft mode in the full spectrum (1 or 2)
    # Expected measured quantity per unit prefactor (discrete Parseval, paper eq. 1-2): Sq², or SΔq² with the
    # squared symbols of the forward difference
    d2 = 1.0 if rms_slope is None else sum(np.abs(fourier_first(q, dx)) ** 2 for q, dx in symbols)
    expected = np.sum(weights * c * d2) / area
    target = rms_height if rms_slope is None else rms_slope
    if prefactor is None:
        if expected <= 0:
            raise XtopoError(f"the requested spectrum has no power on a grid of {shape} points: it needs a nonzero "
                             f"wavevector below the short cutoff ({short_cutoff}), i.e. more than one point along "
                             "an axis and a short_cutoff longer than twice the spacing")
        prefactor = target**2 / expected
    psd = dataclasses.replace(psd, prefactor=float(prefactor))
    h = _synthesize(gshape, gsize, psd.c_native(qabs), np.random.default_rng(seed))
    if rms_slope is not None:
        h = h * (target / np.sqrt(sum(np.mean(forward_difference(h, dx, periodic=True, axis=ax) ** 2)
                                      for ax, (_, dx) in zip(range(-dim, 0), symbols))))
    elif rms_height is not None:
        h = h * (target / np.sqrt(np.mean(h**2)))
    if not periodic:
        h = h[tuple(slice(0, n) for n in shape)]
    ds = make_measurement(h, spacing=tuple(spacings) if dim == 2 else spacings[0], units=units, periodic=periodic,
                          title="fractal surface", source="xtopo.datasets.fractal_surface",
                          **psd.to_attrs(), seed=int(seed))
    return append_history(ds, f"fractal_surface(shape={shape}, hurst={hurst}, seed={seed}, periodic={periodic})")


def _synthesize(shape, size, c, rng) -> np.ndarray:
    """Gaussian random field on a periodic grid whose expected PSD is ``c`` (on the rfft grid).

    ``E|h̃|² = c · area`` for every mode, i.e. the expected C2D (or C1D) equals ``c``.
    """
    area = float(np.prod(size))
    amp = np.sqrt(c * area) / np.sqrt(2.0)
    ht = amp * (rng.standard_normal(c.shape) + 1j * rng.standard_normal(c.shape))
    _make_hermitian(ht, shape, amp, rng)
    return _fft.irfftn(ht, s=shape, axes=tuple(range(-len(shape), 0))) * (int(np.prod(shape)) / area)


def _make_hermitian(ht, shape, amp, rng):
    """Make the rfft coefficients ``ht`` those of a real field: real self-conjugate modes, no mean."""
    selfconj = [[0, n // 2] if n % 2 == 0 else [0] for n in shape]
    for j, *i in itertools.product(*selfconj[::-1]):
        ht[(*i, j)] = amp[(*i, j)] * np.sqrt(2.0) * rng.standard_normal()
    if len(shape) == 2:  # columns 0 and n/2 of an rfft2 must be Hermitian along y: mirror the upper half
        rows = np.arange(1, (shape[0] + 1) // 2)
        ht[np.ix_(shape[0] - rows, selfconj[-1])] = np.conj(ht[np.ix_(rows, selfconj[-1])])
    ht.flat[0] = 0.0


@checked
def sphere(shape: Annotated[tuple, Shape()], size, radius: Annotated[float, Positive()], *, center=None,
           kind: Annotated[str, Choice("sphere", "paraboloid")] = "sphere", periodic: Annotated[bool, Flag()] = False,
           units: Annotated[str, LengthUnit()] = "m") -> xr.Dataset:
    """A sphere (or paraboloid) cap with apex height 0 and heights decreasing outward.

    Parameters
    ----------
    shape, size : as in :func:`fractal_surface`
    radius : float
        Radius of curvature R at the apex, in ``units``.
    center : tuple of float, optional
        Apex position ``(y, x)`` or ``x``; default the centre of the window.
    kind : {"sphere", "paraboloid"}
        Exact sphere ``sqrt(R²-r²) - R`` (``-R`` outside) or ``-r²/(2R)``.
    periodic : bool
        Value of the ``periodic`` attribute (the cap itself is not made periodic).
    units : str
        Length unit of ``size``, ``radius``, ``center`` and the result.
    """
    size = per_axis(size, len(shape), "size")
    sp = size / np.asarray(shape)
    center = size / 2 if center is None else per_axis(center, len(shape), "center", sign="any")
    axes = [np.arange(n) * d - c for n, d, c in zip(shape, sp, center)]
    r2 = sum(a**2 for a in np.meshgrid(*axes, indexing="ij"))
    h = np.sqrt(np.maximum(radius**2 - r2, 0.0)) - radius if kind == "sphere" else -r2 / (2 * radius)
    return make_measurement(h, spacing=tuple(sp) if len(shape) == 2 else sp[0], units=units, periodic=periodic,
                            title=f"{kind} R={radius:g} {units}", source="xtopo.datasets.sphere",
                            sphere_radius=float(radius))


@checked
def sinusoid(shape: Annotated[tuple, Shape()], size, *, amplitude: Annotated[float, Real()] = 1.0,
             wavelength: Annotated[float | None, Positive()] = None,
             direction: Annotated[str, Choice("x", "y", "xy")] = "x", periodic: Annotated[bool, Flag()] = True,
             units: Annotated[str, LengthUnit()] = "m") -> xr.Dataset:
    """``h = A cos(2π x/λ)`` (``direction="x"``), along y, or ``"xy"`` (egg crate, sum of both).

    With ``periodic=True`` and ``wavelength`` dividing the size the surface is exactly periodic.
    """
    size = per_axis(size, len(shape), "size")
    sp = size / np.asarray(shape)
    lam = float(size[-1]) if wavelength is None else wavelength
    if direction != "x" and len(shape) == 1:
        raise XtopoError(f"direction must be 'x', 'y' or 'xy' (the latter two for area scans), got {direction!r}")
    axes = np.meshgrid(*[np.arange(n) * d for n, d in zip(shape, sp)], indexing="ij")
    chosen = {"x": axes[-1:], "y": axes[:1], "xy": axes[::-1]}[direction]
    h = amplitude * sum(np.cos(2 * np.pi * a / lam) for a in chosen)
    return make_measurement(h, spacing=tuple(sp) if len(shape) == 2 else sp[0], units=units, periodic=periodic,
                            title=f"sinusoid λ={lam:g} {units}", source="xtopo.datasets.sinusoid",
                            sinusoid_amplitude=float(amplitude), sinusoid_wavelength=lam)


def _tip_reach(h: np.ndarray, radius: float) -> float:
    """Lateral distance within which a sphere of ``radius`` touching ``h`` can be lifted by another point.

    ``sqrt(r² - (r - ptp)²)`` written as ``sqrt(ptp (2r - ptp))``: ``r²`` overflows for a huge (flat) tip.
    """
    ptp = float(np.nanmax(h) - np.nanmin(h)) if h.size else 0.0
    return radius if ptp >= radius else float(np.sqrt(ptp * (2 * radius - ptp)))


def _sphere_drop(radius: float, d2):
    """How far below its apex a sphere of ``radius`` is at squared lateral distance ``d2`` (≤ radius²).

    ``r - sqrt(r² - d²)`` written as ``d² / (r + sqrt(r - d) sqrt(r + d))``: no overflow of ``r²``, no
    cancellation for a large tip.
    """
    d = np.sqrt(d2)
    return d2 / (radius + np.sqrt(radius - d) * np.sqrt(radius + d))


def _tip_dilate(h: np.ndarray, spacings, radius: float) -> np.ndarray:
    """Morphological dilation of a profile or map ``h`` by a sphere of ``radius`` (apex at the origin);
    only offsets whose drop can matter are visited."""
    reach = _tip_reach(h, radius)
    reaches = [range(-m, m + 1) for m in (min(int(np.ceil(reach / d)), n - 1) for d, n in zip(spacings, h.shape))]
    out = h.copy()
    for offset in itertools.product(*reaches):
        r2 = sum((k * d) ** 2 for k, d in zip(offset, spacings))
        if not any(offset) or r2 > reach**2:
            continue
        # out[y, x] = max(out[y, x], h[y+i, x+j] - drop)
        into = tuple(slice(max(0, -k), n - max(0, k)) for k, n in zip(offset, h.shape))
        src = tuple(slice(max(0, k), n - max(0, -k)) for k, n in zip(offset, h.shape))
        np.maximum(out[into], h[src] - _sphere_drop(radius, r2), out=out[into])
    return out


def _missing_patches(shape, fraction: float, rng) -> np.ndarray:
    """Boolean mask with roughly ``fraction`` of the points in compact random patches."""
    mask = np.zeros(shape, dtype=bool)
    if fraction <= 0:
        return mask
    if fraction >= 1:
        return ~mask
    target = int(round(fraction * np.prod(shape)))
    # patches scale with the shorter axis; an axis of one pixel (a 1×N map) would make them single
    # points, and covering a large fraction with those takes ~N log N draws of O(N) each
    patch = max(1, int(0.05 * min([n for n in shape if n > 1] or [1])))
    while mask.sum() < target:
        centre = [rng.integers(0, n) for n in shape]
        radius = rng.uniform(0.5, 1.0) * patch
        grids = np.ogrid[tuple(slice(0, n) for n in shape)]
        r2 = sum((g - c) ** 2 for g, c in zip(grids, centre))
        mask |= r2 <= radius**2
    return mask


@checked
def measure(surface: xr.Dataset, *, size=None, pixels: Annotated[tuple | None, Shape()] = None, offset=None,
            tip_radius: Annotated[float | None, Positive()] = None, noise: Annotated[float, Real(0.0)] = 0.0,
            missing_fraction: Annotated[float, Real(0.0, 1.0)] = 0.0,
            resolution: Annotated[float | None, Positive()] = None, line: Annotated[bool, Flag()] = False,
            seed: Annotated[int, Count(min=0)] = 0, instrument: str = "simulated instrument") -> xr.Dataset:
    """Simulate an instrument measuring ``surface``.

    The window of ``size`` at ``offset`` is cut from the ground truth, dilated by a
    spherical tip of ``tip_radius`` at the ground truth's resolution (morphological
    dilation: the apex height where the sphere first touches the surface, as a
    scanning probe or stylus records it), sampled at ``pixels`` points (linear
    interpolation), perturbed by white noise of RMS ``noise`` and punched with
    missing-data patches covering ``missing_fraction`` of the points.

    Parameters
    ----------
    surface : xarray.Dataset
        Ground truth (area or line), finer than the simulated instrument.
    size : float or tuple of float, optional
        Physical size of the measured window in the surface's unit (default: all of it).
    pixels : int or tuple of int, optional
        Number of samples (default: those of the window at the ground-truth spacing).
    offset : float or tuple of float, optional
        Position of the window's lower-left corner (default 0).
    tip_radius : float, optional
        Tip radius in the surface's unit; recorded in ``attrs["tip_radius"]``.
    noise : float
        RMS of additive Gaussian white noise, in the surface's unit.
    missing_fraction : float
        Fraction of points to mark missing (NaN in ``height``, ``True`` in ``mask``).
    resolution : float, optional
        Lateral resolution recorded in attrs (for optical instruments).
    line : bool
        Measure a single profile along x (the first row) of an area surface.
    seed : int
        Seed for noise and missing patches.
    instrument : str
        Recorded in ``attrs["instrument"]``.

    Returns
    -------
    xarray.Dataset
        A nonperiodic measurement in the surface's unit.
    """
    h = height_of(surface)
    dims = lateral_dims(h)
    if h.ndim != len(dims):
        raise GridError(f"measure needs one surface, got extra dims {tuple(d for d in h.dims if d not in dims)}; "
                        "measure each with .isel")
    h = h.transpose(*dims)
    units = h.coords["x"].attrs.get("units", "m") if "x" in h.coords else "m"
    area = len(dims) == 2
    sp = np.array([spacing(h, d) for d in dims])
    n = np.array([h.sizes[d] for d in dims])
    full = sp * n
    size = full if size is None else per_axis(size, len(dims), "size")
    offset = np.zeros(len(dims)) if offset is None else per_axis(offset, len(dims), "offset", sign="non-negative")
    if pixels is not None and len(pixels) not in (1, len(dims)):
        raise GridError(f"pixels must be one number or one per axis {dims}, got {pixels!r}")
    if np.any(offset + size > full * (1 + 1e-12)):
        raise GridError(f"window offset={tuple(offset.tolist())} size={tuple(size.tolist())} does not fit into the "
                        f"surface {tuple(full.tolist())}")
    values = np.asarray(h.values, dtype=float)
    # crop with a margin of one tip reach so the dilation near the window edge sees its neighbours
    margin = np.zeros(len(dims), dtype=int)
    if tip_radius is not None:
        margin = np.minimum(np.ceil(tip_radius / sp), n).astype(int)  # a huge tip reaches the whole surface
    lo = np.maximum(np.floor(offset / sp).astype(int) - margin, 0)
    hi = np.minimum(np.ceil((offset + size) / sp).astype(int) + 1 + margin, n)
    crop = values[tuple(slice(a, b) for a, b in zip(lo, hi))]
    if tip_radius is not None:
        crop = _tip_dilate(crop, sp, tip_radius)
    if pixels is None:
        pixels = np.maximum(np.round(size / sp).astype(int), 1)
    pixels = np.broadcast_to(np.asarray(pixels, dtype=int), (len(dims),))
    if line and area:
        pixels = np.array([1, pixels[-1]])
    new_sp = size / pixels
    # sample positions relative to the crop origin, in crop pixels
    pos = [(offset[k] + np.arange(pixels[k]) * new_sp[k]) / sp[k] - lo[k] for k in range(len(dims))]
    from scipy.ndimage import map_coordinates

    grid = np.meshgrid(*pos, indexing="ij")
    sampled = map_coordinates(crop, grid, order=1, mode="nearest")
    rng = np.random.default_rng(seed)
    if noise:
        sampled = sampled + noise * rng.standard_normal(sampled.shape)
    if line and area:
        sampled = sampled[0]
        new_sp = new_sp[1:]
    missing = _missing_patches(sampled.shape, missing_fraction, rng)
    ds = make_measurement(np.where(missing, np.nan, sampled), spacing=tuple(new_sp) if sampled.ndim == 2 else new_sp[0],
                          units=units, periodic=False, tip_radius=tip_radius, resolution=resolution,
                          instrument=instrument, source="xtopo.datasets.measure")
    # the ground truth's PSD (a profile of an area surface keeps psd_dim 2: compare with FractalPSD.c1d)
    ds.attrs.update({key: surface.attrs[key] for key in ("psd_hurst", "psd_prefactor", "psd_long_cutoff",
                                                          "psd_short_cutoff", "psd_dim") if key in surface.attrs})
    return append_history(ds, f"measure(size={[float(v) for v in size]}, pixels={[int(p) for p in pixels]}, "
                              f"tip_radius={tip_radius}, noise={noise}, missing_fraction={missing_fraction}, seed={seed})")


def _long_modes(truth: FractalPSD, q_split: float, q_low: float, rng, *, per_decade: int = 8, angles: int = 16):
    """Random Fourier modes of the isotropic field ``truth`` restricted to ``|q| < q_split``.

    The half plane ``q_low ≤ |q| < q_split`` is cut into cells of equal width in ``ln q`` and
    angle; each cell gets one mode at a uniformly random position inside it whose squared
    amplitude is the cell's power at that position, ``a² = 4 C(q) q² Δ(ln q) Δθ / (2π)²``.
    The expected height-height correlation of ``Σ a cos(q·r + φ)`` is then exactly that of
    ``truth`` over the band (randomised quadrature: no discretisation bias at any distance,
    unlike a periodic grid, which holds no wavelength longer than its period). Power below
    ``q_low`` (a constant offset in the flat roll-off region) is left out.

    Returns ``(qy, qx, c)`` with complex coefficients ``c = a e^{iφ}``.
    """
    decades = max(np.log10(q_split / q_low), 1e-9)
    nr = max(1, int(np.ceil(decades * per_decade)))
    dlnq = np.log(q_split / q_low) / nr
    dth = np.pi / angles
    lnq = np.log(q_low) + (np.arange(nr)[:, None] + rng.uniform(size=(nr, angles))) * dlnq
    th = (np.arange(angles)[None, :] + rng.uniform(size=(nr, angles))) * dth
    q = np.exp(lnq).ravel()
    th = th.ravel()
    amp = np.sqrt(4 * truth.c_native(q) * dlnq * dth) * q / (2 * np.pi)
    c = amp * np.exp(2j * np.pi * rng.uniform(size=q.size))
    return q * np.sin(th), q * np.cos(th), c


def _eval_modes(modes, y: np.ndarray, x: np.ndarray, block: int = 4096) -> np.ndarray:
    """``Σ_m Re(c_m e^{i(qy_m y + qx_m x)})`` on the grid ``y × x`` (``x`` evenly spaced from 0).

    Separable: one matrix product per block of ``x`` (its real part as two real products: half the
    work of a complex one). The phases of a block are those of the first block shifted,
    ``e^{iq(x_j + x_0)} = e^{iqx_j} e^{iqx_0}``, and those of the first block products of a coarse
    and a fine step, ``e^{iq x_(as+b)} = e^{iq x_(as)} e^{iq x_b}``, so few exponentials are taken
    (a profile of 16 000 points: 60 → 23–27 ms; equal to round-off: 2e-15 of the largest value).
    """
    qy, qx, c = modes
    rows = c[None, :] * np.exp(1j * np.outer(y, qy))
    width = min(block, x.size)
    step = max(1, int(np.sqrt(width)))
    coarse = np.exp(1j * np.outer(qx, x[:width:step]))
    fine = np.exp(1j * np.outer(qx, x[:step]))
    first = (coarse[:, :, None] * fine[:, None, :]).reshape(qx.size, -1)[:, :width]
    first_re, first_im = np.ascontiguousarray(first.real), np.ascontiguousarray(first.imag)
    out = np.empty((y.size, x.size))
    for j in range(0, x.size, block):
        w = min(block, x.size - j)
        shifted = rows * np.exp(1j * qx * x[j])
        out[:, j:j + w] = shifted.real @ first_re[:, :w] - shifted.imag @ first_im[:, :w]
    return out


def _c1d_above(truth: FractalPSD, qx: np.ndarray, q_split: float, nodes: int = 200) -> np.ndarray:
    """1D PSD of profiles of ``truth`` restricted to 2D wavevectors ``|q| ≥ q_split``.

    ``C1D(qx) - (1/π) ∫_0^{k0} C_iso(√(qx²+k²)) dk`` with ``k0 = √(q_split² - qx²)`` (the part of
    ``C1D = (1/π) ∫_0^∞ C_iso dk`` that the shared 2D modes below ``q_split`` do not carry).
    """
    qx = np.atleast_1d(np.asarray(qx, dtype=float))
    k0 = np.sqrt(np.maximum(q_split**2 - qx**2, 0.0))
    t, w = _gauss_legendre(nodes)
    k = 0.5 * k0[:, None] * (t[None, :] + 1)
    inner = np.sum(w * truth.c_native(np.sqrt(qx[:, None] ** 2 + k**2)), axis=1) * 0.5 * k0
    return np.maximum(truth.c1d(qx) - inner / np.pi, 0.0)


def _area_truth(truth: FractalPSD, n: int, dx: float, rng) -> np.ndarray:
    """An ``n × n`` window (spacing ``dx``) of the isotropic surface ``truth``, all wavelengths included.

    Wavelengths shorter than half the window come from a periodic grid twice the window's
    size, longer ones (down to the roll-off and beyond) from :func:`_long_modes`.
    """
    size = n * dx
    q_split = 4 * np.pi / size
    q = _grid_q((2 * n, 2 * n), (dx, dx))[0]
    short = _synthesize((2 * n, 2 * n), (2 * size, 2 * size), np.where(q >= q_split, truth.c_native(q), 0.0), rng)
    axis = np.arange(n) * dx
    q_low = min(truth.q_long or np.inf, 2 * np.pi / size) / 100
    return short[:n, :n] + _eval_modes(_long_modes(truth, q_split, q_low, rng), axis, axis)


def _profiles_truth(truth: FractalPSD, rows: int, row_spacing: float, n: int, dx: float, rng) -> np.ndarray:
    """``rows`` parallel profiles ``row_spacing`` apart, ``n`` points each, of the isotropic surface ``truth``.

    2D wavevectors ``|q| < q_split = max(4π/L, 2π/row_spacing)`` are shared by the
    profiles (:func:`_long_modes` evaluated on every row: the profiles are correlated at
    long wavelengths as on a real surface); shorter ones are drawn independently per
    profile on a periodic line twice the profile's length with the matching 1D spectrum
    (:func:`_c1d_above`), as profiles further apart than the wavelength decorrelate.
    """
    length = n * dx
    q_split = 4 * np.pi / length if rows == 1 else max(4 * np.pi / length, 2 * np.pi / row_spacing)
    q = np.abs(wavevectors(2 * n, dx, real=True))
    qpos = q[q > 0]
    grid = np.geomspace(qpos.min(), qpos.max(), 256)
    c = np.zeros_like(q)
    c[q > 0] = np.exp(np.interp(np.log(qpos), np.log(grid), np.log(np.maximum(_c1d_above(truth, grid, q_split), 1e-300))))
    short = np.stack([_synthesize((2 * n,), (2 * length,), c, rng)[:n] for _ in range(rows)])
    q_low = min(truth.q_long or np.inf, 2 * np.pi / length) / 100
    long = _eval_modes(_long_modes(truth, q_split, q_low, rng), np.arange(rows) * row_spacing, np.arange(n) * dx)
    return short + long


#: Instruments of the example twin: (name, kind, size [m], pixels, oversampling, tip radius [m], extra).
#: ``profiles``: parallel stylus profiles, ``pixels = (profiles, points)``, spaced ``size/20`` apart.
#: ``extra["replicates"]``: measurements of that kind at independent places (names ``-2``, ``-3``, ... after the first).
_TWIN_PLAN = (
    ("stylus-5mm", "profiles", 5e-3, (8, 5000), 4, 2e-6, {"noise": 2e-9, "replicates": 2}),
    ("stylus-500um", "profiles", 5e-4, (8, 5000), 4, 1e-6, {"noise": 1e-9, "replicates": 2}),
    ("optical-1mm", "area", 1e-3, 256, 2, None, {"resolution": 1.6e-5, "noise": 5e-9, "missing_fraction": 0.03}),
    ("afm-50um", "area", 5e-5, 256, 2, 5e-8, {"noise": 2e-10, "replicates": 3}),
    ("afm-5um", "area", 5e-6, 256, 2, 2e-8, {"noise": 1e-10, "missing_fraction": 0.02, "replicates": 3}),
    ("afm-500nm", "area", 5e-7, 256, 2, 5e-9, {"replicates": 3}),
    ("tem-profile-1um", "nonuniform", 1e-6, 4000, 4, None, {"resolution_spacings": 12, "replicates": 10}),
)
#: spacing of the parallel stylus profiles, as a fraction of their length
_PROFILE_SPACING = 1 / 20


@functools.lru_cache(maxsize=2)
def _example_twin_cached(seed: int):
    truth = FractalPSD(hurst=0.8, prefactor=1.5e-4, long_cutoff=2e-4, dim=2)
    nodes = {}
    runs = [(k, f"{name}-{r + 1}" if r else name, name, r, row)
            for k, (name, *row) in enumerate(_TWIN_PLAN) for r in range(row[-1].get("replicates", 1))]
    for k, name, instrument, r, (kind, size, pixels, over, tip, extra) in progress_bar(
            runs, desc="simulating the example twin", unit="measurement"):  # ~9 s: a bar in notebooks/terminals
        s = seed * 1000 + 10 * k + r
        rng = np.random.default_rng(s)
        extra = {key: v for key, v in extra.items() if key != "replicates"}
        n = (pixels[-1] if kind == "profiles" else pixels) * over  # points of the ground truth along x
        dx, dy = size / n, size * _PROFILE_SPACING
        if kind in ("area", "profiles"):
            surf = (make_measurement(_area_truth(truth, n, dx, rng), spacing=dx, units="m") if kind == "area" else
                    make_measurement(_profiles_truth(truth, pixels[0], dy, n, dx, rng), spacing=(dy, dx), units="m"))
            meas = measure(surf, pixels=pixels, tip_radius=tip, seed=s, instrument=instrument, **extra)
        else:  # cross-section contour digitised at irregular positions (jittered about a regular step)
            line = _profiles_truth(truth, 1, 0.0, n, dx, rng)[0]
            step = (n - 1) * dx / (pixels - 1)
            x = (np.arange(pixels) + np.concatenate([[0.0], rng.uniform(-0.35, 0.35, pixels - 2), [0.0]])) * step
            h = np.interp(x, np.arange(n) * dx, line)
            resolution = extra["resolution_spacings"] * float(np.mean(np.diff(x)))
            meas = make_measurement(h, x=x, units="m", instrument=instrument, resolution=resolution,
                                    source="xtopo.datasets.example_twin")
        nodes[name] = meas.assign_attrs(truth.to_attrs(), title=name, measurement_kind=kind)
    root = xr.Dataset(attrs={"title": "example digital surface twin",
                             "summary": "A campaign of 24 simulated measurements (stylus profiles, optical, AFM, cross-sections) of "
                                        "one self-affine surface (H = 0.8, roll-off at 200 µm) spanning 5 mm down to "
                                        "3 nm (the resolution of the cross-sections).",
                             "Conventions": "CF-1.12, ACDD-1.3", **truth.to_attrs()})
    return root, nodes


@checked
def example_twin(seed: Annotated[int, Count(min=0)] = 0) -> xr.DataTree:
    """The built-in example twin: simulated measurements of one ground-truth surface.

    A campaign of 24 measurements of an isotropic self-affine surface (Hurst exponent 0.8,
    flat roll-off of the PSD above 200 µm, the surface's correlation length, which the
    5 mm stylus scans sample) spanning more than six decades of length, with replicates
    where one measurement's statistics would not suffice (names ``-2``, ``-3``, ...):

    * 2 + 2 stylus campaigns of 8 parallel profiles each (5 mm and 0.5 mm long, 5000
      points, profiles ``L/20`` apart, tip radii 2 µm and 1 µm, white noise), stored as
      ``(y, x)`` maps whose rows are the profiles (1D PSDs and ACFs average over them);
    * an optical area scan (1 mm, 256², lateral resolution 16 µm, noise, 3% missing data);
    * 3 AFM area scans at each of 50 µm, 5 µm and 0.5 µm (256², spherical tips of 50, 20
      and 5 nm applied by morphological dilation, noise, 2% missing data on the 5 µm ones);
    * 10 TEM cross-section contours (1 µm) digitised at 4000 irregular points each
      (jittered by up to ±35% of the 0.25 nm step); their ``resolution`` is 12 mean
      spacings, where linear interpolation between the digitised points and the
      resampling of the spectrum (each a low-pass of about ``sinc⁴(qΔ/2)`` in power)
      cost < 10%. Single profiles: only the replicates together reach the statistical
      criterion of the twin averages at nanometre scales.

    Every measurement is taken at its own place on the specimen (independent
    realisations) and its ground truth contains *all* wavelengths of the surface:
    wavelengths shorter than half the window come from a periodic grid twice the
    window's size (sampled at 2× or 4× the instrument's pixel density, so the
    instrument aliases as a real one does), longer ones down to the roll-off from
    randomised Fourier modes (``_long_modes``: exact expected correlations at any
    distance), so a small scan carries the random tilt and curvature a real one
    does. Stylus profiles share the 2D modes longer than their spacing. Each node
    carries the ground-truth PSD parameters (see :func:`prescribed_psd`).

    Parameters
    ----------
    seed : int
        Seed of the whole twin (realisations, noise, missing data).

    Returns
    -------
    xarray.DataTree
        One child node per measurement, surface description on the root.
    """
    root, nodes = _example_twin_cached(seed)
    return xr.DataTree.from_dict({"/": root.copy(), **{f"/{k}": v.copy(deep=True) for k, v in nodes.items()}})
