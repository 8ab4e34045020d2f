"""Height distribution and material ratio (Abbott–Firestone) curve, numpy + numba.

One pass over the heights (no sort) gives the amplitude moments and a fine class count:
``m`` equal-height classes between the lowest and highest height, each with its number of
points and the sum of their heights. Everything on the material ratio curve follows
from the cumulative counts and sums:

* the material ratio at a level ``c`` (ISO 25178-2 §4.5.1, ISO 13565-2): the fraction of
  points at or above ``c`` — exact at class edges, linear inside a class;
* its inverse, the height at a material ratio (``Smc(mr)``, the curve itself);
* the material above and the void below a level, ``(1/n) Σ max(z - c, 0)`` and
  ``(1/n) Σ max(c - z, 0)`` (ISO 25178-2 §4.5.6-4.5.7 volumes, the peak and dale
  areas of ISO 13565-2) — exact sums over whole classes, the class holding ``c``
  taken as uniformly filled.

With ``m = min(16 n, 2**18)`` classes (at least 4096) a class is narrower than ``Sz / m``: on a
2048² map that is 4·10⁻⁶ Sz, below any tolerance of the parameters, for the cost of one
pass (a sort of the same heights costs ~10 times more). A few extreme spikes widen the
classes (Sz grows): the height resolution of the curve is Sz/m, its ratios stay exact.

Heights are deviations from their mean (the reference plane of ISO 25178-2). The same
functions serve profiles (ISO 21920-2 / 13565-2 Rk family) and areas: they take any array
of values and ignore NaN.
"""

from __future__ import annotations

import numpy as np

from . import material_ratio_rows as _rows
from ._lazy import LazyJit

njit = LazyJit(globals())  # numba imported, the kernels wrapped, on first use (startup time, issue 26)

__all__ = ["Distribution", "FUNCTIONAL", "functional", "CURVE_SAMPLES"]

_JIT = dict(nogil=True, cache=True)

#: samples of the material ratio curve (0 to 100 % in steps of 0.01 %) on which the central region is
#: located and the equivalent straight line fitted (:func:`~xtopo._kernels.material_ratio_rows.equivalent_line`)
CURVE_SAMPLES = 10001
_MIN_CLASSES = 4096
#: classes per point below the cap: a class rarely holds more than a few points
_CLASSES_PER_POINT = 16
_MAX_CLASSES = 2**18


@njit(**_JIT)
def _range(z):
    """Number of finite values, their sum, min and max."""
    n = 0
    s = 0.0
    lo = np.inf
    hi = -np.inf
    for i in range(z.size):
        v = z[i]
        if v == v and abs(v) != np.inf:
            n += 1
            s += v
            if v < lo:
                lo = v
            if v > hi:
                hi = v
    return n, s, lo, hi


@njit(**_JIT)
def _classes(z, mean, lo, hi, counts, sums):
    """Central moments Σd, Σ|d|, Σd², Σd³, Σd⁴ of ``d = z - mean``; fills the class counts and sums."""
    m = counts.size
    scale = m / (hi - lo) if hi > lo else 0.0
    s1 = 0.0
    sa = 0.0
    s2 = 0.0
    s3 = 0.0
    s4 = 0.0
    for i in range(z.size):
        v = z[i]
        if v == v and abs(v) != np.inf:
            d = v - mean
            d2 = d * d
            s1 += d
            sa += abs(d)
            s2 += d2
            s3 += d2 * d
            s4 += d2 * d2
            k = int((v - lo) * scale)
            if k >= m:
                k = m - 1
            counts[k] += 1
            sums[k] += d
    return s1, sa, s2, s3, s4


class Distribution:
    """Heights of one measurement (``values`` of any shape, NaN ignored) classed for the material ratio curve.

    Attributes: ``n`` (finite points), ``moments`` (Σ|d|, Σd², Σd³, Σd⁴ over n of the deviations ``d`` from
    the mean), ``lo``/``hi`` (lowest/highest deviation), ``edges`` (``m + 1`` class edges), ``above`` / ``sum_above``
    (points, and the sum of their deviations, in the classes from edge ``k`` up).
    """

    __slots__ = ("n", "moments", "lo", "hi", "edges", "counts", "above", "sum_above")

    def __init__(self, values):
        z = np.ascontiguousarray(values, dtype=float).ravel()
        n, s, lo, hi = _range(z)
        self.n = n
        if n == 0:
            self.moments = np.full(4, np.nan)
            self.lo = self.hi = np.nan
            return
        mean = s / n
        m = int(min(max(_CLASSES_PER_POINT * n, _MIN_CLASSES), _MAX_CLASSES))
        counts = np.zeros(m, np.int64)
        sums = np.zeros(m)
        s1, sa, s2, s3, s4 = _classes(z, mean, lo, hi, counts, sums)
        # the mean of a first pass is off by round-off: correct the moments to the exact mean of d
        c = s1 / n
        s2c = s2 - n * c * c
        self.moments = np.array([sa / n, max(s2c, 0.0) / n,
                                 (s3 - 3 * c * s2 + 2 * n * c**3) / n,
                                 (s4 - 4 * c * s3 + 6 * c * c * s2 - 3 * n * c**4) / n])
        self.lo, self.hi = lo - mean - c, hi - mean - c
        self.edges = np.linspace(self.lo, self.hi, m + 1)
        self.counts = counts
        self.above = np.append(np.cumsum(counts[::-1])[::-1], 0)
        self.sum_above = np.append(np.cumsum((sums - c * counts)[::-1])[::-1], 0.0)

    def _locate(self, c):
        """Class index and position inside it (0..1) of levels ``c``; levels outside are clipped."""
        m = self.counts.size
        width = (self.hi - self.lo) / m
        if width <= 0:
            return np.zeros(np.shape(c), np.intp), np.zeros(np.shape(c))
        x = (np.clip(c, self.lo, self.hi) - self.lo) / width
        k = np.minimum(np.floor(x).astype(np.intp), m - 1)
        return k, x - k

    def ratio(self, c):
        """Material ratio (fraction 0..1) at levels ``c``: the share of points at or above ``c``."""
        c = np.asarray(c, dtype=float)
        k, t = self._locate(c)
        r = (self.above[k + 1] + self.counts[k] * (1 - t)) / self.n
        return np.where(c > self.hi, 0.0, np.where(c <= self.lo, 1.0, r))

    def height(self, f):
        """Height (deviation from the mean) at material ratios ``f`` (fractions 0..1): the inverse of :meth:`ratio`."""
        f = np.clip(np.asarray(f, dtype=float), 0.0, 1.0)
        if self.hi <= self.lo:
            return np.full(f.shape, self.hi)
        target = f * self.n
        # edges where at most `target` points lie above: the curve crosses f inside the class below
        j = np.searchsorted(-self.above, -target, side="left")
        k = np.clip(j - 1, 0, self.counts.size - 1)
        cnt = self.counts[k]
        with np.errstate(invalid="ignore", divide="ignore"):
            t = np.where(cnt > 0, 1 - (target - self.above[k + 1]) / cnt, 1.0)
        h = self.edges[k] + np.clip(t, 0.0, 1.0) * (self.edges[k + 1] - self.edges[k])
        return np.where(j == 0, self.lo, h)

    def excess(self, c):
        """Material above levels ``c`` per unit area, ``(1/n) Σ max(z - c, 0)`` (length)."""
        c = np.asarray(c, dtype=float)
        k, t = self._locate(c)
        e = self.edges
        part = self.counts[k] * (1 - t) * (e[k + 1] - np.clip(c, self.lo, self.hi)) / 2
        v = (self.sum_above[k + 1] - self.above[k + 1] * c + part) / self.n
        v = np.where(c >= self.hi, 0.0, np.where(c <= self.lo, self.sum_above[0] / self.n - c, v))
        return np.maximum(v, 0.0)

    def deficit(self, c):
        """Void below levels ``c`` per unit area, ``(1/n) Σ max(c - z, 0)`` (length)."""
        c = np.asarray(c, dtype=float)
        # Σ max(c - z, 0) = Σ max(z - c, 0) - Σ (z - c), and the deviations sum to sum_above[0]
        return np.maximum(self.excess(c) - self.sum_above[0] / self.n + c, 0.0)


#: names and order of :func:`functional`'s outputs
FUNCTIONAL = tuple("S" + name for name in _rows.FUNCTIONAL)


def functional(dist: Distribution) -> np.ndarray:
    """Sk, Spk, Svk, Smr1, Smr2 (heights in the values' unit, ratios in %) of ISO 13565-2 / 25178-2.

    Sk is the height of the equivalent straight line between 0 % and 100 %; Smr1/Smr2 the
    material ratios at its upper and lower ends; Spk and Svk the heights of the triangles
    with bases Smr1 and 100 % - Smr2 whose areas equal the areas of the peaks above and the
    dales below the core (0 when there are none).
    """
    if dist.n == 0:
        return np.full(len(FUNCTIONAL), np.nan)
    curve = dist.height(np.linspace(0.0, 1.0, CURVE_SAMPLES))
    upper, lower = (float(v[0]) for v in _rows.equivalent_line(curve[None], np.array([CURVE_SAMPLES])))
    mr1 = float(dist.ratio(upper)) * 100
    mr2 = float(dist.ratio(lower)) * 100
    a1 = float(dist.excess(upper)) * 100   # peak area, % × length
    a2 = float(dist.deficit(lower)) * 100  # dale area
    spk = 2 * a1 / mr1 if mr1 > 0 and a1 > 0 else 0.0
    svk = 2 * a2 / (100 - mr2) if mr2 < 100 and a2 > 0 else 0.0
    return np.array([upper - lower, spk, svk, mr1, mr2])
