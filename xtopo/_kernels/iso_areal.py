"""ISO 25178-2 field parameters of area scans, numpy + numba.

Maps arrive as ``h[..., ny, nx]`` (leading dims a batch); heights are deviations from
their mean plane. Groups of parameters and their discretisation:

* height (§4.2) and functional/volume (§4.5): one pass over the heights,
  :mod:`xtopo._kernels.material_ratio`; NaN ignored;
* hybrid (§4.4): Sdq with the seven-point slope of ISO 21920-2 / ISO 4287 in x and y,
  Sdr from the area of the triangulated surface (each grid cell the mean of its two
  triangulations, ISO 25178-2:2021 Annex D); stencils and cells touching NaN are skipped;
* spatial (§4.3): Sal and Str from the normalised autocorrelation ``C(τ)/C(0)`` (linear, each
  lag divided by its number of pairs; circular for periodic maps) by casting rays from
  ``τ = 0``, Std from the angular amplitude density of the Fourier transform. Maps with
  missing data give NaN here (fill them first);
* feature (§5): watershed segmentation with Wolf pruning, :mod:`xtopo._kernels.features`;
  maps with missing data give NaN.
"""

from __future__ import annotations

import math

import numpy as np
from ._lazy import LazyJit

njit = LazyJit(globals())  # numba imported, the kernels wrapped, on first use (startup time, issue 26)

from . import fft as _fft
from . import features as _features
from . import material_ratio as _mr
from . import profile_iso as _profile
from .spectra import BACKEND as _BACKEND
from .spectra import power as _power
from .windows import radial_hann

__all__ = ["PARAMETERS", "GROUPS", "areal_parameters", "slope_sums", "decay_lengths", "texture_direction",
           "curve", "volumes", "ratios"]

_JIT = dict(nogil=True, cache=True)

#: names and order of :func:`areal_parameters`' outputs, by group
GROUPS = {
    "height": ("Sa", "Sq", "Sp", "Sv", "Sz", "Ssk", "Sku"),
    "hybrid": ("Sdq", "Sdr"),
    "spatial": ("Sal", "Str", "Std"),
    "functional": ("Sk", "Spk", "Svk", "Smr1", "Smr2", "Sxp", "Smr", "Smc", "Sdc"),
    "volume": ("Vmp", "Vmc", "Vvv", "Vvc"),
    "feature": _features.FEATURES,
}
PARAMETERS = tuple(name for names in GROUPS.values() for name in names)

#: angular resolution of the texture direction, degrees
STD_STEP = 0.5
#: number of directions (over 180°) along which the autocorrelation decay is found
DIRECTIONS = 720


#: the profiles' stencil, compiled (``+ 0 × centre`` where it is used: a NaN centre skips the slope)
seven_point = njit(**_JIT)(_profile.seven_point)


# reductions may be reordered (vectorised); NaN keeps its meaning (the skip tests use it)
_SUM = dict(_JIT, fastmath={"reassoc", "contract", "arcp"})


@njit(**_SUM)
def _rows_x(z, sx, nxs, periodic):
    """Σ and count of the squared x slopes (× 60Δx) of every row (periodic rows wrapped 3 values each side)."""
    ny, nx = z.shape
    wrapped = np.empty(nx + 6)
    for r in range(ny):
        row = z[r]
        if periodic:
            wrapped[3:nx + 3] = row
            for j in range(3):
                wrapped[j] = row[(j - 3) % nx]
                wrapped[nx + 3 + j] = row[j % nx]
            row = wrapped
        for c in range(3, row.size - 3):
            g = seven_point(row[c - 3], row[c - 2], row[c - 1], row[c + 1], row[c + 2], row[c + 3]) + 0.0 * row[c]
            if g == g:
                sx += g * g
                nxs += 1
    return sx, nxs


@njit(inline="always")
def _cell(a, b, d, e, ix2, iy2):
    """4 × the excess area of the cell with corners ``a``, ``b`` (one row) and ``d``, ``e`` (the next): the sum
    over its four corner triangles (each ``g / (1 + √(1 + g))``, ``g`` its squared gradient)."""
    bottom = (b - a) * (b - a) * ix2
    top = (e - d) * (e - d) * ix2
    left = (d - a) * (d - a) * iy2
    right = (e - b) * (e - b) * iy2
    g1 = bottom + left
    g2 = bottom + right
    g3 = top + left
    g4 = top + right
    return (g1 / (1.0 + math.sqrt(1.0 + g1)) + g2 / (1.0 + math.sqrt(1.0 + g2))
            + g3 / (1.0 + math.sqrt(1.0 + g3)) + g4 / (1.0 + math.sqrt(1.0 + g4)))


@njit(**_SUM)
def _cells(z, dy, dx, periodic):
    """Σ of the cells' excess areas and the number of complete cells."""
    ny, nx = z.shape
    area = 0.0
    cells = 0
    ry = ny if periodic else ny - 1
    ix2 = 1.0 / (dx * dx)
    iy2 = 1.0 / (dy * dy)
    for r in range(ry):
        top_row = z[(r + 1) % ny]
        row = z[r]
        for c in range(nx - 1):
            s = _cell(row[c], row[c + 1], top_row[c], top_row[c + 1], ix2, iy2)
            if s == s:
                area += s
                cells += 1
        if periodic:
            s = _cell(row[nx - 1], row[0], top_row[nx - 1], top_row[0], ix2, iy2)
            if s == s:
                area += s
                cells += 1
    return area / 4.0, cells


@njit(**_JIT)
def slope_sums(z, dy, dx, periodic):
    """Σ(∂z/∂x)², count, Σ(∂z/∂y)², count (seven-point slopes) and Σ excess area, cell count (Sdr).

    ``z[ny, nx]``. A cell's excess area is its triangulated area over its projected area minus
    one, computed as ``g / (1 + √(1 + g))`` (no cancellation on smooth surfaces), the mean of
    its four corner triangles (the two triangulations averaged). Slopes whose stencil, and
    cells whose corners, touch NaN are skipped; nonperiodic maps have slopes from the fourth
    sample from each edge inwards.
    """
    sx, nxs = _rows_x(z, 0.0, 0, periodic)
    sy, nys = _rows_x(np.ascontiguousarray(z.T), 0.0, 0, periodic)
    area, cells = _cells(z, dy, dx, periodic)
    return sx / (60.0 * dx) ** 2, nxs, sy / (60.0 * dy) ** 2, nys, area, cells


@njit(**_JIT)
def _acf_at(corr, ly, lx, ny, nx, periodic):
    """Normalised-count autocorrelation at integer lag (ly, lx) of a (padded or circular) correlation."""
    py, px = corr.shape
    v = corr[ly % py, lx % px]
    if periodic:
        return v / (ny * nx)
    return v / ((ny - abs(ly)) * (nx - abs(lx)))


@njit(**_JIT)
def _rays(corr, ny, nx, dy, dx, periodic, s, ndir):
    """Distance along each of ``ndir`` directions (0..180°) at which C(τ)/C(0) first falls to ``s`` (inf: never)."""
    c0 = _acf_at(corr, 0, 0, ny, nx, periodic)
    out = np.full(ndir, np.inf)
    if not c0 > 0:
        return out
    limy = ny // 2 if periodic else ny - 1
    limx = nx // 2 if periodic else nx - 1
    dr = 0.5 * min(dx, dy)
    for k in range(ndir):
        th = math.pi * k / ndir
        ux = math.cos(th) / dx
        uy = math.sin(th) / dy
        prev = 1.0
        r = 0.0
        while True:
            r += dr
            fx = r * ux
            fy = r * uy
            if abs(fx) >= limx or abs(fy) >= limy:
                break
            ix = math.floor(fx)
            iy = math.floor(fy)
            tx = fx - ix
            ty = fy - iy
            ix = int(ix)
            iy = int(iy)
            v = ((1 - ty) * ((1 - tx) * _acf_at(corr, iy, ix, ny, nx, periodic)
                             + tx * _acf_at(corr, iy, ix + 1, ny, nx, periodic))
                 + ty * ((1 - tx) * _acf_at(corr, iy + 1, ix, ny, nx, periodic)
                         + tx * _acf_at(corr, iy + 1, ix + 1, ny, nx, periodic))) / c0
            if v <= s:
                out[k] = r - dr + dr * (prev - s) / (prev - v) if prev > v else r
                break
            prev = v
    return out


def decay_lengths(z: np.ndarray, dy: float, dx: float, periodic: bool, s: float) -> np.ndarray:
    """Autocorrelation decay length (to ``s``) along :data:`DIRECTIONS` directions from 0 to 180°.

    ``z[ny, nx]`` finite, mean removed. Nonperiodic maps are zero padded (linear correlation).
    """
    ny, nx = z.shape
    shape = (ny, nx) if periodic else tuple(_fft.sfft.next_fast_len(2 * n - 1, real=True) for n in (ny, nx))
    # single precision: the correlation at a lag with N pairs is off by ~1e-6·n/N of C(0), far below
    # any threshold s, and the transforms run twice as fast
    p = _power(_fft.rfftn(z.astype(np.float32), s=shape, axes=(-2, -1), backend=_BACKEND))
    corr = _fft.irfftn(p, s=shape, axes=(-2, -1), backend=_BACKEND)
    return _rays(corr, ny, nx, dy, dx, periodic, s, DIRECTIONS)


@njit(**_JIT)
def _angular(amp, ny, nx, dy, dx, nbins):
    """Angular amplitude density of a rfft2 half plane: Σ|F| per direction bin (centred on multiples of 180°/nbins).

    A Fourier sample stands for a cell of the frequency lattice, which a direction sees under the
    angle ``δ = √(Δf_x Δf_y)/|f|``: its amplitude is spread over the bins by a tent of half-width
    ``max(δ, bin width)`` centred on its direction. A sample right on a direction still gives
    that direction its largest share, and a spectral peak spread over several samples (windowed
    or off-lattice) is not out-voted by bins that happen to catch more samples.
    """
    out = np.zeros(nbins)
    step = 180.0 / nbins
    nxr = amp.shape[1]
    cell = math.degrees(math.sqrt(1.0 / (ny * dy) / (nx * dx)))
    for i in range(ny):
        ky = i if i < (ny + 1) // 2 else i - ny
        fy = ky / (ny * dy)
        for j in range(nxr):
            if i == 0 and j == 0:
                continue
            fx = j / (nx * dx)
            w = (1.0 if (j == 0 or (nx % 2 == 0 and j == nx // 2)) else 2.0) * amp[i, j]
            th = math.degrees(math.atan2(fy, fx)) / step  # in bins
            half = max(cell / math.hypot(fx, fy) / step, 1.0)
            if half >= nbins / 2:
                out += w / nbins
                continue
            lo = int(math.ceil(th - half))
            hi = int(math.floor(th + half))
            total = 0.0
            for b in range(lo, hi + 1):
                total += 1.0 - abs(b - th) / half
            if total > 0:
                for b in range(lo, hi + 1):
                    out[b % nbins] += w * (1.0 - abs(b - th) / half) / total
    return out


def texture_direction(z: np.ndarray, dy: float, dx: float, periodic: bool) -> float:
    """Std: the direction (degrees from +x towards +y, 0 ≤ Std < 180) of the largest angular amplitude density.

    ``z[ny, nx]`` finite, mean removed; nonperiodic maps are multiplied by the radial Hann
    window (:func:`xtopo._kernels.windows.radial_hann`) so the edges do not pile up
    amplitude along the axes.
    """
    ny, nx = z.shape
    if not periodic:
        z = z * radial_hann(ny, nx, dy, dx)
    f = _fft.rfftn(z, axes=(-2, -1), backend=_BACKEND)
    amp = np.abs(f)
    spec = _angular(amp, ny, nx, dy, dx, int(round(180.0 / STD_STEP)))
    if not spec.max() > 0:
        return np.nan
    return float(np.argmax(spec) * STD_STEP)


def curve(dist: _mr.Distribution, mr: np.ndarray) -> np.ndarray:
    """Heights of the material ratio curve at ratios ``mr`` (%)."""
    return dist.height(np.asarray(mr, dtype=float) / 100)


def ratios(dist: _mr.Distribution, c: np.ndarray) -> np.ndarray:
    """Smr(c) in % at heights ``c`` above the mean plane."""
    return dist.ratio(np.asarray(c, dtype=float)) * 100


def volumes(dist: _mr.Distribution, p: np.ndarray, kind: str) -> np.ndarray:
    """Vm(p) (``kind="material"``) or Vv(p) (``"void"``) per unit area at material ratios ``p`` (%)."""
    level = curve(dist, p)
    return dist.excess(level) if kind == "material" else dist.deficit(level)


def _one(z, dy, dx, periodic, groups, s, p, q, c, mr, sxp, sdc, pruning):
    out = {}
    dist = None
    if {"height", "functional", "volume"} & groups:
        dist = _mr.Distribution(z)
    if "height" in groups:
        sa, s2, s3, s4 = dist.moments
        sq = math.sqrt(s2) if dist.n else np.nan
        with np.errstate(invalid="ignore", divide="ignore"):
            sk = s3 / sq**3 if sq > 0 else np.nan
            ku = s4 / sq**4 if sq > 0 else np.nan
        out.update(Sa=sa, Sq=sq, Sp=dist.hi, Sv=0.0 - dist.lo, Sz=dist.hi - dist.lo, Ssk=sk, Sku=ku)
    if "functional" in groups:
        sk_, spk, svk, mr1, mr2 = _mr.functional(dist)
        if dist.n:
            h = curve(dist, [sxp[0], sxp[1], sdc[0], sdc[1], mr])
            smr = float(ratios(dist, c))
        else:
            h = np.full(5, np.nan)
            smr = np.nan
        out.update(Sk=sk_, Spk=spk, Svk=svk, Smr1=mr1, Smr2=mr2, Sxp=h[0] - h[1], Smr=smr, Smc=h[4],
                   Sdc=h[2] - h[3])
    if "volume" in groups:
        if dist.n:
            vm = volumes(dist, [p, q], "material")
            vv = volumes(dist, [p, q], "void")
        else:
            vm = vv = np.full(2, np.nan)
        out.update(Vmp=vm[0], Vmc=vm[1] - vm[0], Vvv=vv[1], Vvc=vv[0] - vv[1])
    if "hybrid" in groups:
        zc = np.ascontiguousarray(z, dtype=float)
        sx, nxs, sy, nys, area, cells = slope_sums(zc, float(dy), float(dx), bool(periodic))
        out["Sdq"] = math.sqrt(sx / nxs + sy / nys) if nxs and nys else np.nan
        out["Sdr"] = 100.0 * area / cells if cells else np.nan
    if "spatial" in groups:
        if np.isfinite(z).all() and z.size > 1:
            d = z - z.mean()
            r = decay_lengths(d, dy, dx, periodic, s)
            sal = float(r.min())
            out["Sal"] = sal if np.isfinite(sal) else np.nan
            out["Str"] = sal / float(r.max()) if np.isfinite(r).all() else np.nan
            out["Std"] = texture_direction(d, dy, dx, periodic)
        else:
            out.update(Sal=np.nan, Str=np.nan, Std=np.nan)
    if "feature" in groups:
        z = np.asarray(z, dtype=float)
        zc = z - z.mean() if np.isfinite(z).all() else z
        out.update(zip(_features.FEATURES, _features.feature_parameters(zc, dy, dx, periodic, pruning)))
    return out


def areal_parameters(h: np.ndarray, *, dy: float, dx: float, periodic: bool, names: tuple, s: float = 0.2,
                     p: float = 10.0, q: float = 80.0, c: float = 0.0, mr: float = 10.0,
                     sxp=(2.5, 50.0), sdc=(10.0, 80.0), pruning: float = 5.0) -> np.ndarray:
    """The ISO 25178-2 parameters ``names`` (a subset of :data:`PARAMETERS`) of ``h[..., ny, nx]``, stacked last.

    Units: heights and lengths as ``h`` and ``dx``; Ssk, Sku, Sdq, Str dimensionless; Sdr,
    Smr1, Smr2, Smr in %; Std in degrees; volumes in length³/length² (length).
    ``s``: autocorrelation threshold; ``p``, ``q``: material ratios (%) of the volume
    parameters; ``c``: height above the mean plane of Smr(c); ``mr``: ratio (%) of Smc(mr);
    ``sxp``, ``sdc``: the ratio pairs (%) of Sxp and Sdc; ``pruning``: the Wolf pruning threshold
    of the feature parameters in % of Sz (Spd in length⁻², Spc in length⁻¹).
    """
    h = np.asarray(h, dtype=float)
    groups = {g for g, members in GROUPS.items() if set(members) & set(names)}
    out = np.empty(h.shape[:-2] + (len(names),))
    for idx in np.ndindex(h.shape[:-2]):
        vals = _one(h[idx], dy, dx, periodic, groups, s, p, q, c, mr, sxp, sdc, pruning)
        out[idx] = [vals[n] for n in names]
    return out
