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
import math

import numpy as np
import xarray as xr

from ._kernels import fft as _fft
from ._kernels.derivatives import fourier_first, wavevectors
from .conventions import HEIGHT, make_measurement, normalize_units, spacing, height_of, is_periodic, append_history
from .errors import GridError, XtopoError

__all__ = ["FractalPSD", "fractal_surface", "prescribed_psd", "sphere", "sinusoid", "measure", "example_twin"]


@dataclasses.dataclass(frozen=True)
class FractalPSD:
    """Isotropic self-affine PSD with roll-off and short-wavelength cutoff.

    ``C_iso(q) = prefactor · max(q, q_L)^(-2-2H)`` for ``q ≤ q_s`` and 0 above, with
    ``q_L = 2π/long_cutoff`` and ``q_s = 2π/short_cutoff`` (absent cutoffs are 0 / ∞).
    For line scans (``dim=1``) the exponent is ``-1-2H``.

    Units: ``prefactor`` in ``units^(4-2-2H)``-consistent form, i.e. ``C_iso`` in
    ``units^4`` (area) or ``units^3`` (line) for ``q`` in ``units^-1``.
    """

    hurst: float
    prefactor: float
    long_cutoff: float | None = None
    short_cutoff: float | None = None
    dim: int = 2

    @property
    def q_long(self) -> float:
        return 0.0 if self.long_cutoff is None else 2 * np.pi / self.long_cutoff

    @property
    def q_short(self) -> float:
        return np.inf if self.short_cutoff is None else 2 * np.pi / self.short_cutoff

    def _shape(self, q, exponent):
        q = np.abs(np.asarray(q, dtype=float))
        qq = np.maximum(q, self.q_long) if self.q_long > 0 else q
        with np.errstate(divide="ignore"):
            c = np.where(qq > 0, qq ** np.where(qq > 0, exponent, 0.0), 0.0)
        return np.where(q <= self.q_short, c, 0.0)

    def c_native(self, q):
        """The PSD in the surface's own dimension (C_iso for areas, C1D for lines)."""
        exponent = -2 - 2 * self.hurst if self.dim == 2 else -1 - 2 * self.hurst
        return self.prefactor * self._shape(q, exponent)

    def c_iso(self, q):
        """Radially averaged 2D PSD (area surfaces only)."""
        if self.dim != 2:
            raise XtopoError("a line-scan fractal has no 2D PSD")
        return self.c_native(q)

    def c1d(self, q, *, nodes: int = 400):
        """1D PSD of profiles: ``C1D(q) = (1/π) ∫_0^∞ C_iso(√(q²+k²)) dk`` for areas."""
        if self.dim == 1:
            return self.c_native(q)
        q = np.atleast_1d(np.abs(np.asarray(q, dtype=float)))
        kmax = np.sqrt(np.maximum(self.q_short**2 - q**2, 0.0)) if np.isfinite(self.q_short) else None
        # Gauss-Legendre in t with k = q_ref * sinh(t) resolves the kink at q_L and the tail.
        t, w = np.polynomial.legendre.leggauss(nodes)
        out = np.empty_like(q)
        for i, qi in enumerate(q):
            scale = max(qi, self.q_long, 1e-300)
            tmax = np.arcsinh(kmax[i] / scale) if kmax is not None else np.arcsinh(1e8)
            if tmax <= 0:
                out[i] = 0.0
                continue
            tt = 0.5 * tmax * (t + 1)
            k = scale * np.sinh(tt)
            jac = scale * np.cosh(tt) * 0.5 * tmax
            # kink at k where sqrt(q²+k²) = q_L: split there for accuracy
            vals = self.c_native(np.sqrt(qi**2 + k**2))
            out[i] = np.sum(w * vals * jac) / np.pi
        return out

    def __call__(self, q, kind: str = "native"):
        return {"native": self.c_native, "iso": self.c_iso, "1d": self.c1d}[kind](q)

    def to_attrs(self) -> dict:
        return {"psd_hurst": self.hurst, "psd_prefactor": self.prefactor,
                "psd_long_cutoff": np.nan if self.long_cutoff is None else self.long_cutoff,
                "psd_short_cutoff": np.nan if self.short_cutoff is None else self.short_cutoff,
                "psd_dim": self.dim}


def prescribed_psd(ds) -> FractalPSD:
    """Rebuild the ground-truth :class:`FractalPSD` from a synthetic surface's attrs."""
    a = ds.attrs
    if "psd_prefactor" not in a:
        raise XtopoError("this dataset carries no prescribed PSD (it was not made by fractal_surface)")
    lc, sc = float(a["psd_long_cutoff"]), float(a["psd_short_cutoff"])
    return FractalPSD(float(a["psd_hurst"]), float(a["psd_prefactor"]),
                      None if np.isnan(lc) else lc, None if np.isnan(sc) else sc, int(a["psd_dim"]))


def _grid_q(shape, spacings):
    """|q| on an rfft grid and the per-mode symbols of the forward difference."""
    if len(shape) == 1:
        qx = wavevectors(shape[0], spacings[0], real=True)
        return np.abs(qx), [(qx, spacings[0])]
    qy = wavevectors(shape[0], spacings[0])[:, None]
    qx = wavevectors(shape[1], spacings[1], real=True)[None, :]
    return np.sqrt(qx**2 + qy**2), [(qy, spacings[0]), (qx, spacings[1])]


def _rfft_weights(shape):
    """Multiplicity of each rfft mode in the full spectrum (1 or 2)."""
    n = shape[-1]
    w = np.full(n // 2 + 1, 2.0)
    w[0] = 1.0
    if n % 2 == 0:
        w[-1] = 1.0
    return np.broadcast_to(w, tuple(shape[:-1]) + (n // 2 + 1,))


def fractal_surface(shape, size, *, hurst: float, rms_height: float | None = None, rms_slope: float | None = None,
                    prefactor: float | None = None, short_cutoff: float | None = None,
                    long_cutoff: float | None = None, periodic: bool = True, seed: int = 0,
                    units: str = "m") -> xr.Dataset:
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
    shape = (int(shape),) if np.ndim(shape) == 0 else tuple(int(s) for s in shape)
    size = np.broadcast_to(np.asarray(size, dtype=float), (len(shape),)).copy()
    if len(shape) not in (1, 2) or min(shape) < 1:
        raise GridError(f"shape must be (nx,) or (ny, nx) with positive sizes, got {shape}")
    if not 0 < hurst < 1:
        raise XtopoError(f"hurst must lie in (0, 1), got {hurst}")
    if sum(v is not None for v in (rms_height, rms_slope, prefactor)) > 1:
        raise XtopoError("give at most one of rms_height, rms_slope and prefactor")
    if rms_height is None and rms_slope is None and prefactor is None:
        rms_height = 1.0
    units = normalize_units(units)
    spacings = size / np.asarray(shape)
    gshape = shape if periodic else tuple(2 * n for n in shape)
    gsize = size if periodic else 2 * size
    dim = len(shape)
    psd = FractalPSD(hurst, 1.0, long_cutoff, short_cutoff, dim)
    qabs, symbols = _grid_q(gshape, spacings)
    c = psd.c_native(qabs)
    area = float(np.prod(gsize))
    weights = _rfft_weights(gshape)
    # Expected measured quantity per unit prefactor (discrete Parseval, paper eq. 1-2)
    if rms_slope is not None:
        d2 = sum(np.abs(fourier_first(q, dx)) ** 2 for q, dx in symbols)
        expected = np.sum(weights * c * d2) / area
        target = rms_slope
    else:
        expected = np.sum(weights * c) / area
        target = rms_height
    if prefactor is None:
        if expected <= 0:
            raise XtopoError("the requested spectrum is empty on this grid (check the cutoffs)")
        prefactor = target**2 / expected
    psd = dataclasses.replace(psd, prefactor=float(prefactor))
    rng = np.random.default_rng(seed)
    amp = np.sqrt(psd.c_native(qabs) * area) / np.sqrt(2.0)
    ht = amp * (rng.standard_normal(qabs.shape) + 1j * rng.standard_normal(qabs.shape))
    ht.flat[0] = 0.0
    # modes that are their own conjugate must be real with full variance
    _make_self_conjugate_real(ht, gshape, amp, rng)
    h = _fft.irfftn(ht, s=gshape, axes=tuple(range(-dim, 0))) * (int(np.prod(gshape)) / area)
    if rms_height is not None or rms_slope is not None:
        if rms_slope is not None:
            from ._kernels.derivatives import forward_difference

            meas = np.sqrt(sum(np.mean(forward_difference(h, dx, periodic=True, axis=ax) ** 2)
                               for ax, (_, dx) in zip(range(-dim, 0), symbols)))
        else:
            meas = np.sqrt(np.mean(h**2))
        h = h * (target / meas)
    if not periodic:
        h = h[tuple(slice(0, n) for n in shape)]
    ds = make_measurement(h, spacing=tuple(spacings) if dim == 2 else spacings[0], units=units, periodic=periodic,
                          title="fractal surface", source="xtopo.datasets.fractal_surface",
                          **psd.to_attrs(), seed=int(seed))
    return append_history(ds, f"fractal_surface(shape={shape}, hurst={hurst}, seed={seed}, periodic={periodic})")


def _make_self_conjugate_real(ht, shape, amp, rng):
    idx_last = [0] + ([shape[-1] // 2] if shape[-1] % 2 == 0 else [])
    idx_first = [0] + ([shape[0] // 2] if len(shape) == 2 and shape[0] % 2 == 0 else []) if len(shape) == 2 else [None]
    for j in idx_last:
        for i in idx_first:
            sl = (j,) if i is None else (i, j)
            ht[sl] = amp[sl] * np.sqrt(2.0) * rng.standard_normal()
    if len(shape) == 2:
        # columns 0 and n/2 of an rfft2 must be Hermitian along y: mirror the upper half
        ny = shape[0]
        for j in idx_last:
            col = ht[:, j]
            for i in range(1, (ny + 1) // 2):
                col[ny - i] = np.conj(col[i])
    ht.flat[0] = 0.0


def sphere(shape, size, radius: float, *, center=None, kind: str = "sphere", periodic: bool = False,
           units: str = "m") -> xr.Dataset:
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
    """
    shape = (int(shape),) if np.ndim(shape) == 0 else tuple(int(s) for s in shape)
    size = np.broadcast_to(np.asarray(size, dtype=float), (len(shape),))
    sp = size / np.asarray(shape)
    center = size / 2 if center is None else np.broadcast_to(np.asarray(center, dtype=float), (len(shape),))
    axes = [np.arange(n) * d - c for n, d, c in zip(shape, sp, center)]
    r2 = sum(a**2 for a in np.meshgrid(*axes, indexing="ij"))
    if kind == "sphere":
        h = np.sqrt(np.maximum(radius**2 - r2, 0.0)) - radius
    elif kind == "paraboloid":
        h = -r2 / (2 * radius)
    else:
        raise XtopoError(f"kind must be 'sphere' or 'paraboloid', got {kind!r}")
    ds = make_measurement(h, spacing=tuple(sp) if len(shape) == 2 else sp[0], units=units, periodic=periodic,
                          title=f"{kind} R={radius:g} {units}", source="xtopo.datasets.sphere")
    ds.attrs["sphere_radius"] = float(radius)
    return ds


def sinusoid(shape, size, *, amplitude: float = 1.0, wavelength: float | None = None, direction: str = "x",
             periodic: bool = True, units: str = "m") -> xr.Dataset:
    """``h = A cos(2π x/λ)`` (``direction="x"``), along y, or ``"xy"`` (egg crate, sum of both).

    With ``periodic=True`` and ``wavelength`` dividing the size the surface is exactly periodic.
    """
    shape = (int(shape),) if np.ndim(shape) == 0 else tuple(int(s) for s in shape)
    size = np.broadcast_to(np.asarray(size, dtype=float), (len(shape),))
    sp = size / np.asarray(shape)
    lam = float(size[-1]) if wavelength is None else float(wavelength)
    axes = np.meshgrid(*[np.arange(n) * d for n, d in zip(shape, sp)], indexing="ij")
    xx = axes[-1]
    yy = axes[0] if len(shape) == 2 else None
    if direction == "x":
        h = amplitude * np.cos(2 * np.pi * xx / lam)
    elif direction == "y" and yy is not None:
        h = amplitude * np.cos(2 * np.pi * yy / lam)
    elif direction == "xy" and yy is not None:
        h = amplitude * (np.cos(2 * np.pi * xx / lam) + np.cos(2 * np.pi * yy / lam))
    else:
        raise XtopoError(f"direction must be 'x', 'y' or 'xy' (the latter two for area scans), got {direction!r}")
    ds = make_measurement(h, spacing=tuple(sp) if len(shape) == 2 else sp[0], units=units, periodic=periodic,
                          title=f"sinusoid λ={lam:g} {units}", source="xtopo.datasets.sinusoid")
    ds.attrs.update(sinusoid_amplitude=float(amplitude), sinusoid_wavelength=lam)
    return ds
