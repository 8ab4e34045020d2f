"""Vectorised averaging over logarithmically spaced bins (``np.bincount``)."""

from __future__ import annotations

import numpy as np

__all__ = ["log_edges", "bin_index", "BinPlan"]


def log_edges(lo: float, hi: float, nb_points: int) -> np.ndarray:
    """``nb_points + 1`` logarithmically spaced bin edges covering ``[lo, hi]``.

    ``hi`` below ``lo`` by round-off only (e.g. the one wavevector of a 1×2 map, computed
    two ways) counts as ``hi == lo``.
    """
    if lo > 0 and lo * (1 - 1e-9) <= hi < lo:
        hi = lo
    if not (lo > 0 and hi >= lo):
        raise ValueError(f"log bins need 0 < lo <= hi, got lo={lo}, hi={hi}")
    if hi == lo:
        hi = lo * (1 + 1e-9)
    e = np.geomspace(lo, hi, int(nb_points) + 1)
    e[0] *= 1 - 1e-12
    e[-1] *= 1 + 1e-12
    return e


def bin_index(values: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Bin number of each value; values outside ``edges`` get ``len(edges) - 1`` (the overflow bin)."""
    nb = len(edges) - 1
    idx = np.searchsorted(edges, values, side="right") - 1
    idx[(idx < 0) | (idx >= nb)] = nb
    return idx


class BinPlan:
    """Precomputed bin membership of a fixed set of abscissae.

    Parameters
    ----------
    values : ndarray
        Abscissae (e.g. |q| of every FFT mode), any shape.
    edges : ndarray
        Bin edges (see :func:`log_edges`).
    multiplicity : ndarray, optional
        Weight of each abscissa (e.g. 2 for modes that stand for ± q in a real FFT).

    Attributes
    ----------
    centers : ndarray
        Weighted mean abscissa of the non-empty bins.
    keep : ndarray of bool
        Which bins are non-empty.
    """

    def __init__(self, values, edges, multiplicity=None):
        values = np.asarray(values, dtype=float)
        self.ndim = values.ndim
        w = np.ones(values.size) if multiplicity is None else np.broadcast_to(multiplicity, values.shape).ravel()
        values = values.ravel()
        self.nbins = len(edges) - 1
        self.index = bin_index(values, edges)
        counts = np.bincount(self.index, weights=w, minlength=self.nbins + 1)[: self.nbins]
        sums = np.bincount(self.index, weights=w * values, minlength=self.nbins + 1)[: self.nbins]
        self.keep = counts > 0
        self.centers = sums[self.keep] / counts[self.keep]
        norm = np.zeros(self.nbins + 1)
        norm[: self.nbins][self.keep] = 1.0 / counts[self.keep]
        #: per-abscissa weight so that one bincount yields the weighted mean
        self.weights = w * norm[self.index]

    def __len__(self):
        return int(self.keep.sum())

    def mean(self, data: np.ndarray) -> np.ndarray:
        """Average ``data[..., values]`` per non-empty bin; leading dims broadcast."""
        data = np.asarray(data, dtype=float)
        lead = data.shape[: data.ndim - self.ndim]
        flat = data.reshape(-1, self.index.size)
        out = np.empty((flat.shape[0], len(self)))
        for b in range(flat.shape[0]):  # loop over the batch only, never over values
            s = np.bincount(self.index, weights=flat[b] * self.weights, minlength=self.nbins + 1)
            out[b] = s[: self.nbins][self.keep]
        return out.reshape(lead + (len(self),))
