"""Multigrid preconditioner for Laplacians on the pixels of a map (numpy/scipy/numba).

For a symmetric positive definite sparse system ``A x = b`` whose unknowns are pixels
``(iy, ix)`` of a map and whose matrix couples neighbouring pixels (the masked Laplacian of
the harmonic fill, :mod:`xtopo._kernels.laplace_fill`), :class:`SmoothedAggregation` builds a
multigrid hierarchy; one V-cycle of it per iteration preconditions conjugate gradients
(:func:`scipy.sparse.linalg.cg` with ``M=`` a :class:`SmoothedAggregation`).

Hierarchy (smoothed aggregation, Vaněk, Mandel & Brezina 1996): the unknowns of a level are
aggregated by their position, ``a_y × a_x`` blocks of pixels (3×3; 3×1 or 1×3 while the
coupling along one axis is more than 4 times stronger, see ``anisotropy``); the tentative
prolongation ``P₀`` is piecewise constant on the aggregates, the prolongation is
``P = (I − ω D⁻¹A) P₀`` with ``ω = 4/(3ρ)`` (``ρ`` Gershgorin's bound of the spectral radius
of ``D⁻¹A``) and the coarse matrix is the Galerkin product ``Pᵀ A P``. Levels are added
until at most ``coarse_size`` unknowns remain, which are solved with a sparse LU
factorisation. The V-cycle smooths with one forward Gauss–Seidel sweep before and one
backward sweep after the coarse correction, so the preconditioner is symmetric (as CG needs).

Memory is a few times the matrix ``A`` (the hierarchy has about 1.3 times its nonzeros), far
less than the fill-in of a direct factorisation of a large 2-D system.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse
import scipy.sparse.linalg
from numba import njit

__all__ = ["SmoothedAggregation"]


@njit(nogil=True, cache=True)
def _gauss_seidel(indptr, indices, data, dinv, b, x, backward):
    """One Gauss–Seidel sweep over the rows of CSR ``A`` for ``A x = b``, in place (``dinv = 1/diag(A)``)."""
    n = b.size
    for k in range(n):
        i = n - 1 - k if backward else k
        s = b[i]
        for j in range(indptr[i], indptr[i + 1]):
            s -= data[j] * x[indices[j]]
        x[i] += s * dinv[i]


class SmoothedAggregation:
    """Smoothed-aggregation multigrid V-cycle for an SPD matrix on map pixels (see module doc).

    Parameters
    ----------
    A : scipy.sparse matrix, shape (n, n)
        Symmetric positive definite, coupling neighbouring pixels.
    iy, ix : ndarray of int, shape (n,)
        Row and column (pixel indices) of each unknown.
    anisotropy : float
        Ratio of the coupling weights along y and x (``w_y / w_x``, dimensionless; e.g.
        ``Δx²/Δy²`` for the Laplacian). Only steers the shape of the aggregates.
    coarse_size : int
        Number of unknowns at or below which a level is solved directly.

    ``matvec(r)`` of a residual ``r`` (shape (n,)) returns one V-cycle's approximation of ``A⁻¹ r``:
    the object is the preconditioner ``M`` of :func:`scipy.sparse.linalg.cg`.
    """

    def __init__(self, A, iy, ix, anisotropy: float = 1.0, coarse_size: int = 2000):
        A = scipy.sparse.csr_matrix(A)
        self.shape, self.dtype = A.shape, np.dtype(float)  # what scipy.sparse.linalg.aslinearoperator reads
        iy = np.asarray(iy, dtype=np.int64)
        ix = np.asarray(ix, dtype=np.int64)
        ratio = float(anisotropy)
        self.levels = []  # (A, 1/diag(A), P) per level
        while A.shape[0] > coarse_size and len(self.levels) < 40:
            ay = ax = 3
            if ratio > 4 and iy.max() > 0:
                ax = 1
            elif ratio < 0.25 and ix.max() > 0:
                ay = 1
            by, bx = iy // ay, ix // ax
            ncx = int(bx.max()) + 1
            keys, agg = np.unique(by * ncx + bx, return_inverse=True)
            agg = agg.ravel()
            ratio = ratio * ax * ax / (ay * ay)
            if keys.size > 0.8 * A.shape[0]:  # blocks too sparse to coarsen: try larger blocks
                iy, ix = by, bx
                continue
            level, A = self._level(A, agg, keys.size)
            self.levels.append(level)
            iy, ix = np.divmod(keys, ncx)
        self.coarse = scipy.sparse.linalg.splu(A.tocsc())

    @staticmethod
    def _level(A, agg, nc):
        """``(A, 1/diag(A), P)`` of a level whose unknowns form the aggregates ``agg``, and the next level's
        Galerkin matrix ``Pᵀ A P``."""
        n = A.shape[0]
        dinv = 1.0 / A.diagonal()
        rho = float(np.max(abs(A).sum(axis=1).A1 * dinv))
        P0 = scipy.sparse.csr_matrix((np.ones(n), (np.arange(n), agg)), shape=(n, nc))
        P = (P0 - scipy.sparse.diags((4.0 / 3.0 / rho) * dinv) @ (A @ P0)).tocsr()
        P.eliminate_zeros()
        Ac = (P.T.tocsr() @ (A @ P)).tocsr()
        Ac.eliminate_zeros()
        return (A, dinv, P), Ac

    def matvec(self, r):
        return self._cycle(0, np.asarray(r, dtype=float))

    def _cycle(self, k, b):
        if k == len(self.levels):
            return self.coarse.solve(b)
        A, dinv, P = self.levels[k]
        x = np.zeros_like(b)
        _gauss_seidel(A.indptr, A.indices, A.data, dinv, b, x, False)
        x += P @ self._cycle(k + 1, P.T @ (b - A @ x))
        _gauss_seidel(A.indptr, A.indices, A.data, dinv, b, x, True)
        return x

