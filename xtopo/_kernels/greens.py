"""Elastic surface Green's functions of a half-space (paper §5.3), numpy only.

Displacements ``u`` (positive into the solid) follow from pressures ``p`` (positive in
compression) by ``u = G * p`` (eq. 14). Every function here returns the *Fourier
coefficients* of the discrete convolution operator in ``rfft`` layout, real-valued
(the kernels are even), such that ``u = irfftn(G̃ · rfftn(p))`` on the grid that
function describes — *folded*: the kernels are even along ``y`` too, so row ``r`` of an
``M``-row spectrum equals row ``M - r`` and only rows ``0 … M//2`` are stored (half the
memory). Units: ``G̃`` has units of length / modulus when the spacing is
given in length units and ``modulus`` in pressure units.

* periodic, area: eq. (17), ``G̃(q) = 2/(E*|q|)`` on the native grid, ``G̃(0) = 0``
  (the mean displacement of a periodic solid is undefined; it is set to zero).
* periodic, line (plane strain): the same expression with ``q = q_x``.
* free, area: the Love solution for uniform pressure on a ``Δx × Δy`` rectangle,
  eq. (19), sampled on a ``2N_y × 2N_x`` grid (Hockney padding, at least
  ``(2N-1)`` as the paper requires) and transformed.
* free, line (plane strain): uniform pressure on a strip of width ``Δx``,
  ``u(x) = (2/πE*)[(x-a) ln|x-a|/ℓ - (x+a) ln|x+a|/ℓ]`` with ``a = Δx/2``. Plane-strain
  displacements are defined up to a constant; the reference length ``ℓ = e·L``
  (``L`` the measurement length) makes the operator positive definite on the grid.
"""

from __future__ import annotations

import math

import numpy as np

from .derivatives import wavevectors
from .fft import sfft  # imported on first use (startup time, issue 26)

__all__ = ["love_rectangle", "strip_displacement", "periodic_greens", "free_greens", "padded_shape"]


def love_rectangle(x, y, a: float, b: float, modulus: float = 1.0) -> np.ndarray:
    """Surface displacement at ``(x, y)`` under unit pressure on ``[-a, a] × [-b, b]``, eq. (19).

    Written with ``asinh`` on ``|x|``, ``|y|`` (the function is even in both), which is
    algebraically eq. (19) and free of the cancellation that the logarithms suffer far
    from the loaded rectangle.

    Parameters
    ----------
    x, y : array_like
        Positions (length units), broadcast against each other.
    a, b : float
        Half sizes of the loaded rectangle (``Δx/2``, ``Δy/2``).
    modulus : float
        Contact modulus ``E*``.

    Returns
    -------
    numpy.ndarray
        Displacement per unit pressure (length / modulus).
    """
    x = np.abs(np.asarray(x, dtype=float))
    y = np.abs(np.asarray(y, dtype=float))
    xp, xm, yp, ym = x + a, x - a, y + b, y - b

    def term(c, s1, s2):
        ac = np.abs(c)
        with np.errstate(divide="ignore", invalid="ignore"):
            v = c * (np.arcsinh(s1 / ac) - np.arcsinh(s2 / ac))
        return np.where(ac > 0, v, 0.0)

    g = term(xp, yp, ym) + term(yp, xp, xm) + term(xm, ym, yp) + term(ym, xm, xp)
    return g / (np.pi * modulus)


def strip_displacement(x, a: float, reference: float, modulus: float = 1.0) -> np.ndarray:
    """Plane-strain surface displacement under unit pressure on ``[-a, a]``.

    ``u(x) = (2/πE*) [(x-a) ln(|x-a|/ℓ) - (x+a) ln(|x+a|/ℓ)]`` with ``ℓ = reference``.
    """
    x = np.asarray(x, dtype=float)

    def xlogx(s):
        s_abs = np.abs(s)
        with np.errstate(divide="ignore", invalid="ignore"):
            v = s * np.log(s_abs / reference)
        return np.where(s_abs > 0, v, 0.0)

    return 2.0 / (np.pi * modulus) * (xlogx(x - a) - xlogx(x + a))


def padded_shape(shape) -> tuple[int, ...]:
    """FFT grid of a free-boundary problem: ``2N`` along each axis (≥ ``2N-1``, Hockney)."""
    return tuple(2 * int(n) for n in shape)


def periodic_greens(shape, spacing, modulus: float = 1.0, dtype=np.float64) -> np.ndarray:
    """``G̃ = 2/(E*|q|)`` (eq. 17) in folded rfft layout of a periodic grid ``shape`` with ``spacing``.

    ``shape``/``spacing`` are ``(ny, nx)``/``(dy, dx)`` or ``(nx,)``/``(dx,)``; an area's
    result has ``ny//2 + 1`` rows (``|q_y|`` of rows ``r`` and ``ny - r`` are equal).
    The ``q = 0`` entry is 0.
    """
    shape = tuple(int(n) for n in shape)
    spacing = tuple(float(d) for d in spacing)
    qx = wavevectors(shape[-1], spacing[-1], real=True)
    if len(shape) == 1:
        q = np.abs(qx)
    else:
        qy = wavevectors(shape[0], spacing[0])[: shape[0] // 2 + 1]
        q = np.hypot(qy[:, None], qx[None, :])
    q[q == 0] = np.inf  # G̃(0) = 0
    np.divide(2.0 / modulus, q, out=q)
    return q.astype(dtype, copy=False)


def free_greens(shape, spacing, modulus: float = 1.0, dtype=np.float64) -> np.ndarray:
    """Fourier coefficients (folded rfft layout, real) of the free-boundary operator on the padded grid.

    The real-space kernel eq. (19) (areas) or the strip solution (lines) is sampled at
    pixel distances ``m Δx`` with ``m ∈ [0, N-1] ∪ [-(N-1), -1]`` on a ``2N`` grid; the
    remaining entry ``m = N`` is filled symmetrically and never couples two active pixels.
    The sampled kernel is even along both axes, so its transform is the type-I discrete cosine
    transform of one quadrant (``m ∈ [0, N]``): ``(N_y + 1) × (N_x + 1)`` values for an area,
    without building the padded kernel.
    """
    shape = tuple(int(n) for n in shape)
    spacing = tuple(float(d) for d in spacing)
    if len(shape) == 1:
        reference = math.e * shape[0] * spacing[0]
        g = strip_displacement(np.arange(shape[0] + 1) * spacing[0], spacing[0] / 2, reference, modulus)
        return sfft.dct(g, type=1, overwrite_x=True).astype(dtype, copy=False)
    xq = np.arange(shape[1] + 1) * spacing[1]
    quad = np.empty((shape[0] + 1, shape[1] + 1))
    rows = max(1, 2**22 // (shape[1] + 1))   # evaluated in row blocks: temporaries stay small
    for start in range(0, shape[0] + 1, rows):
        yq = np.arange(start, min(start + rows, shape[0] + 1)) * spacing[0]
        quad[start:start + yq.size] = love_rectangle(xq[None, :], yq[:, None], spacing[1] / 2, spacing[0] / 2,
                                                     modulus)
    return sfft.dctn(quad, type=1, overwrite_x=True).astype(dtype, copy=False)
