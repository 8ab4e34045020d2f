"""Polonsky–Keer constrained conjugate gradients for the contact problem eq. (20).

Problem (paper §5.4): a rigid surface with heights ``w ≤ 0`` (measured from its highest
point) is pressed by ``δ`` (the penetration) into an elastic flat. With displacements
``u = G * p`` the gap is ``g = u - w - δ`` and the linear complementarity conditions are

    p ≥ 0,  g ≥ 0,  p g = 0          (and p ≤ H where a hardness H caps the pressure).

Either the total load ``F = ΔA Σ p`` is prescribed (``δ`` then follows as the mean of
``u - w`` over the contact) or the penetration ``δ``.

Iteration (Polonsky & Keer, Wear 231, 206 (1999)), on the CG set ``I = {0 < p < H}``:

1. ``g = u - w - δ`` (load control: ``δ = mean_I(u - w)``), ``G = Σ_I g²``;
2. direction ``t = g + (G/G_old) t`` on ``I`` (0 elsewhere, and on points that just
   joined); ``t = g`` at the start and whenever ``t`` is not a descent direction
   (``Σ_I g t ≤ 0``); under load control ``t`` is made zero-sum on ``I``, so a step keeps
   the load;
3. step ``τ = Σ_I g t / Σ t (G * t)``, ``p ← p - τ t``;
4. projection: ``p < 0 → 0``; ``p > H → H``; points outside ``I`` that overlap
   (``p = 0, g < 0``) or plastic points whose gap opened (``p = H, g > 0``) get
   ``p ← p - τ g`` — with ``τ`` capped by their own steepest-descent step
   ``Σ g² / Σ g (G*g)`` when more points join than ``I`` holds;
5. load control: ``p ← p F/(ΔA Σ p)``; then ``u = G * p``.

Polonsky & Keer restart the CG (``β = 0``) whenever points join. Keeping the conjugate
direction instead (the joined points start with ``t = 0``) cuts the iterations 2–5× on
fractal surfaces (69 instead of 379 on 1024², tol 1e-6; benchmarks/bench_contact.py)
to the same solution: the sets change in nearly every iteration, so restarting reduces
the method to steepest descent.

Cost per iteration (:class:`_Displacements`): three float32 transforms — the forward
transform of ``t`` whose spectrum gives the denominator ``Σ t (G*t)`` by Parseval (no
inverse), and the forward and inverse transforms of the pressure increment ``p - p_ref``
since the last exact reference ``u_ref = G * p_ref`` (working precision). A float32
transform costs 0.27–0.33 of a float64 forward+inverse pair, so the transforms of an
iteration cost about 0.9 of a float64 pair; the reference is refreshed (one working-precision
convolution) each time the residual has fallen by three decades and before convergence is
declared, so the residual that stops the iteration is always that of exact
displacements, and the returned ``u`` is exact. Everything else works on the CG set
(:class:`_ContactSet`: compact per-point arrays, a fraction of the grid) but for one pass over
the grid (the float32 overlap test, which skips row segments without overlaps on a vectorised
count, and clears the direction's buffer as it goes). These passes are compiled
(:mod:`xtopo._kernels.compiled`, numba): one pass each where numpy needed a chain of gathers,
temporaries and reductions; the set keeps each point's buffer position and reference gap and
pressure, so they read compact arrays and write the buffers without an integer division per
point. The increment's input buffer is written only where the pressures changed (by the step, which
also scales the pressures to the load, and the joins); the direction is written on the set into the
shared spectrum buffer (cleared by the scan), which its forward transform consumes in place. Per
iteration (``benchmarks/bench_iteration.py``, CPU time, load 11–13) periodic float64 scenes cost
1.30 pairs at 512², 1.14 at 1024² and 1.35 at 2048² (1.44, 1.24 and 1.47 before the step wrote the
increment), float32 1.36 at 512².

Three transforms, not two: a conjugate-gradient recurrence ``u ← u - τ G*t`` needs only the
pair of ``t`` (its forward gives the energy, its inverse the response), but the projection
and the points that join change ``p`` by a sparse correction ``e`` off the direction, and
``G*e`` costs a forward transform of its own (or ``|e|`` real-space kernel columns, and
``|e|`` reaches thousands in the first iterations); keeping the increment's spectrum instead
would add a grid-sized complex buffer (8 B per point periodic, 16 free).

Memory (periodic 1024², float64; ``benchmarks/bench_contact.py --memory``: 60 B per grid point
for setup and solve): the scene's heights ``w`` (8 B), the folded Green's functions (2 + 1 B),
one in-place float64 transform buffer that the float32 operators share for their spectra and
outputs (8 B), the increment's float32 input (4 B), ``c``/``c_low``/``p_ref`` (8 + 4 + 8 B),
the CG set (28 B per point of it while it holds more than an eighth of the grid, 44 B below; an
eighth more room) and compact overlap lists; the result
takes over ``p_ref`` (the pressures) and ``c`` (the gaps) instead of copying them. In a float32 scene the
increments are in the working precision already: the reference is computed at the start and refreshed only
at the end.

Convergence: ``residual ≤ tol`` where

    residual = max( max_I |g|,  max_{p=0} (-g)⁺,  max_{p=H} g⁺ ) / s,

the largest violation of the contact conditions in units of ``s``, the peak-to-valley
height of ``w`` (any length scale gives the same iterates; this one makes ``tol``
independent of the units and the height scale). Under load control with a hardness the
relative load error is included too.
"""

from __future__ import annotations

import math

import numpy as np

from . import compiled

__all__ = ["polonsky_keer", "PKResult", "COUNTERS"]

_NONE = np.empty(0, np.int32)   # flat indices are int32 (grids above 2**30 points are refused)
#: The work counters of a :class:`PKResult`, summed when one solve is made of several.
COUNTERS = ("iterations", "convolutions", "transforms", "exact_convolutions")
#: A float32 increment is trusted while the residual stays above this fraction of its value at the last
#: exact (working-precision) evaluation.
_REFRESH = 1e-3
#: The CG set keeps its points' reference gaps and pressures in arrays of its own (:class:`_ContactSet`)
#: once it holds at most this fraction of the grid (before, its passes read the grid's arrays).
_COMPACT = 0.25
#: Inner tolerance of the solves of a capped load-controlled solve while the penetration search is far from
#: the root (:func:`_plastic_load_control`).
_COARSE = 1e-3


class PKResult(dict):
    """Dict with keys ``pressure``, ``displacement``, ``gap``, ``penetration``, ``load``,
    ``iterations``, ``residual``, ``converged``, ``convolutions``, ``transforms``,
    ``exact_convolutions`` (those in the working precision), ``plastic`` (None without a hardness)."""

    __getattr__ = dict.__getitem__


def _length_scale(w) -> float:
    """Peak-to-valley height of ``w`` (0 for a flat surface)."""
    return float(-np.min(w)) if w.size else 0.0


def _dot(a, b) -> float:
    """Inner product in float64 without BLAS (its thread pool contends with the FFT threads)."""
    return float(np.einsum("i,i->", a, b, dtype=np.float64))


class _ContactSet:
    """The CG set ``I = {0 < p < H}``, compact: the first :attr:`n` entries of arrays with room to grow.

    Per point (44 B in float64, with an eighth more room): its position ``s`` in the transform
    buffers (:func:`compiled.slots`; the flat index follows by :meth:`flat`), the pressure ``p``, the
    search direction ``t``, the gaps of the current evaluation ``g``, and the reference gap ``c`` and
    pressure ``r`` (``c = u_ref - w - δ_ref`` and ``p_ref`` at the point, constant between refreshes).
    Keeping ``c`` and ``r`` with the point lets the iteration's passes read compact arrays instead of
    gathering from grid-sized ones; the set is compacted in place (:func:`compiled.step_project`) and
    joined points are appended (:func:`compiled.join`), so no array of the set is allocated per
    iteration.

    Memory: a cold start puts the whole grid in the set (uniform pressures), so the set starts lean —
    the indices ``idx`` become the slots in place and the pressures ``p`` are adopted, the first
    direction takes the gaps' array (``t`` is None until then), and while the set holds more than
    :data:`_COMPACT` of the grid (:attr:`grid`) its passes read ``c`` and ``r`` from the grid's
    ``u_ref - w - δ_ref`` and ``p_ref`` at the points' flat indices; below it they get arrays of their
    own. After each step :meth:`fit` shrinks arrays more than half again as long as the set needs.
    """

    _ARRAYS = ("s", "p", "t", "g", "c", "r")

    def __init__(self, idx, p, layout, buffer_size, grid_c, grid_r):
        self.n = n = idx.size
        self.layout = layout
        out = idx if buffer_size < 2**31 else np.empty(n, np.int64)   # int32 slots in place where they fit
        self.s = compiled.slots_into(idx, *layout, out)
        self.p = p
        self.t = self.g = None   # made when first needed (the gaps' array at the first evaluation)
        self.grid = True
        self.c, self.r = grid_c, grid_r

    def _compact(self):
        """Give ``c`` and ``r`` arrays of their own once the set holds at most :data:`_COMPACT` of the grid."""
        if not self.grid or self.n > _COMPACT * self.c.size:
            return
        idx = self.flat()
        for name in "cr":   # the grid's arrays, read at the points
            own = np.empty(self.s.size, self.p.dtype)
            own[:self.n] = getattr(self, name)[idx]
            setattr(self, name, own)
        self.grid = False

    def _resize(self, size, small):
        """Arrays shorter than ``size`` (or missing), or, with ``small``, longer than 1.5 ``size``, are made
        ``size`` long (their first :attr:`n` entries kept)."""
        for name in self._ARRAYS:
            old = getattr(self, name)
            if self.grid and name in "cr" or (old is not None and size <= old.size
                                              and not (small and 2 * old.size > 3 * size)):
                continue
            new = np.empty(size, self.s.dtype if name == "s" else self.p.dtype)
            if old is not None:
                new[:self.n] = old[:self.n]
            setattr(self, name, new)

    def reserve(self, k):
        """Room for ``k`` more points (the arrays are grown by a quarter more than needed)."""
        need = self.n + k
        if any(a is None or a.size < need for a in (getattr(self, name) for name in self._ARRAYS)):
            self._resize(need + need // 8, False)

    def fit(self):
        """After a step: the missing arrays made and those much longer than the set shrunk (the set's memory
        follows it down from a cold start's whole grid)."""
        self._resize(max(64, self.n + self.n // 8), True)
        self._compact()

    def flat(self):
        """The flat indices of the set's points (a new int32 array)."""
        return compiled.flat_indices(self.s_, *self.layout)


# ``cg.s_``, ``cg.p_``, …: the first ``cg.n`` entries of ``cg.s``, ``cg.p``, …
for _name in _ContactSet._ARRAYS:
    setattr(_ContactSet, _name + "_", property(lambda self, _name=_name: getattr(self, _name)[:self.n]))
del _name


class _Displacements:
    """The iterate's gaps: exact at a reference, single-precision increments in between.

    With reference pressures ``p_ref`` whose displacements ``u_ref = G * p_ref`` were computed
    in the working precision, ``u = u_ref + G * (p - p_ref)`` where the increment is a float32
    convolution. Its rounding (~1e-7 of the increment) shrinks with the increment, which
    shrinks with the residual: refreshing the reference whenever the residual has fallen by
    :data:`_REFRESH`, and before convergence is declared, keeps the gaps accurate well below
    the residual, at the price of a float32 instead of a float64 convolution per iteration.

    Buffers kept up to date point by point (only where the sets or pressures change):

    * the increment's input ``p - p_ref`` (zero right after a refresh);
    * the search direction's input (``t`` on the CG set, zero elsewhere), a second float32
      operator, so neither is cleared and rewritten each iteration;
    * ``c = u_ref - w - δ_ref`` on the active grid in the working precision, and in float32
      with ``+inf`` on the contact (the overlap test of the free points, one pass).
    """

    def __init__(self, conv, w, counts):
        self.conv = conv
        self.mixed = conv.dtype != np.float32
        self.low = conv.single_precision() if self.mixed else conv.workspace("increment")
        # the direction is written whole before each transform, which may then consume it (in place)
        self.direction = conv.workspace("direction", self.low.dtype, in_place=True)
        self.w = w.reshape(-1)
        self.counts = counts
        n = self.w.size
        work = conv.scratch                                # kept with the operator: paged in once
        self.c = work("gaps", n, w.dtype)
        self.c_low = work("gaps_low", n, self.low.dtype)
        # the overlap scan's output: overlaps are a few per cent of the grid; grown when more
        self.where = np.empty(min(n, max(1024, n // 64)), np.int32)
        self.where_gaps = np.empty(self.where.size, w.dtype)
        self.nx, self.pad = self.low.buffer_layout
        self.p_ref = work("reference_pressure", n, w.dtype)
        self.p_ref.fill(0)
        self.support = _NONE
        self.delta_ref = 0.0
        self.fresh = True                                 # no increment since the last refresh
        self._no_increment = np.zeros(1, self.low.dtype)

    # -- the reference ------------------------------------------------------------------------
    def refresh(self, cg, pl, H, delta):
        """Make the current pressures (the set ``cg`` and the plastic points ``pl`` at ``H``) the reference:
        one convolution in the working precision."""
        idx, pI = cg.flat(), cg.p_
        flat = self.conv.input_flat
        flat.fill(0)
        nx, pad = self.conv.buffer_layout
        compiled.scatter(idx, pI, nx, pad, flat)
        if pl.size:
            compiled.scatter(pl, np.full(1, H, flat.dtype), nx, pad, flat)
        self.counts["exact"] += 1
        self.counts["conv"] += 1
        self.counts["fft"] += 2
        u = self.conv.inverse(self.conv.forward())
        compiled.reference_gaps(u.reshape(-1, u.shape[-1]), self.w, self.c.dtype.type(delta), self.c, self.c_low)
        compiled.rebase(idx, pI, self.support, self.p_ref, self.c, self.c_low, cg.c_, cg.r_, not cg.grid)
        self.support = idx
        if pl.size:
            self.hide(pl)
            self.p_ref[pl] = H
            self.support = np.concatenate([idx, pl])
        self.delta_ref = float(delta)
        self.low.input_flat.fill(0)
        self.fresh = True

    def hide(self, where):
        """Leave points out of the overlap test (they joined the contact)."""
        self.c_low[where] = np.inf

    def show(self, where):
        """Put free points back into the overlap test."""
        self.c_low[where] = self.c[where]

    # -- the iterate --------------------------------------------------------------------------
    def _increment(self):
        """The float32 increment ``G * (p - p_ref)`` in its buffer layout (a placeholder when fresh)."""
        return self._no_increment if self.fresh else self.low.output_flat

    def update(self, changed):
        """Increment ``G * (p - p_ref)`` of the current pressures (one float32 convolution).

        The set's increments are written by :meth:`step`; ``changed``: ``(points, pressure)`` pairs of
        points outside the set whose pressure became 0 or the hardness since the last call and that
        :meth:`step` has not written (joins from the plastic set, or to it).
        """
        for where, value in changed:
            if where.size:
                compiled.scatter(where, value - self.p_ref[where], self.nx, self.pad, self.low.input_flat)
        self.counts["conv"] += 1
        self.counts["fft"] += 2
        self.low.inverse(self.low.forward())
        self.fresh = False

    def contact_gaps(self, cg, load_control, delta):
        """The gaps of the set ``cg`` into ``cg.g`` (:func:`compiled.contact_gaps`): ``(δ, shift, max |g|,
        Σ g²)``."""
        if cg.g is None:
            cg.g = np.empty(cg.s.size, cg.p.dtype)
        return compiled.contact_gaps(cg.c if cg.grid else cg.c_, self._increment(), cg.s_, self.fresh, cg.g_,
                                     load_control, delta, self.delta_ref, cg.grid, self.nx, self.pad)

    def at(self, slots):
        """``u - w - δ_ref`` at buffer positions ``slots`` (working precision) and their sum."""
        d = np.empty(slots.size, self.c.dtype)
        return d, compiled.gather_gaps(self.c, self._increment(), slots, self.fresh, d, True, self.nx, self.pad)

    def overlaps(self, shift):
        """Free points where ``u - w - δ_ref < shift`` (the gap is negative), their gaps and the lowest.

        The scan clears the direction's buffer on the way (:meth:`set_direction` writes the direction
        only on the set): every evaluation runs it before a direction is set.
        """
        k, low, self.where, self.where_gaps = compiled.scan_overlaps(
            self.c, self.c_low, self._increment(), self.nx, self.pad, self.fresh, shift, self.where, self.where_gaps,
            self.direction.input_flat)
        # views: the next scan overwrites them, after the step has used them
        return self.where[:k], self.where_gaps[:k], low

    def set_direction(self, cg, beta, zero_sum, first):
        """Make ``cg.t`` the conjugate direction (:func:`compiled.set_direction`; ``first``: the gradient),
        write it into the direction operator (zero elsewhere: :meth:`overlaps` cleared it) and return
        ``(slope, energy)``: ``Σ g t`` and ``Σ t (G*t)`` (one float32 forward transform, skipped when not
        downhill)."""
        if first:
            # the first direction is the gradient: the gaps' array becomes the direction's, its zero-sum
            # projection taken in place (the slope Σ t t); the gaps get an array of their own after the
            # step (:meth:`_ContactSet.fit`), once most of a cold start's points have left
            cg.t, cg.g = cg.g, None
            slope = compiled.set_direction(cg.t_, cg.t_, beta, zero_sum, cg.s_, self.direction.input_flat)
        else:
            slope = compiled.set_direction(cg.t_, cg.g_, beta, zero_sum, cg.s_, self.direction.input_flat)
        if not slope > 0:
            return slope, 0.0
        self.counts["fft"] += 1
        return slope, self.direction.energy(self.direction.forward())

    def step(self, cg, tau, H, target, joins):
        """``p ← p - τ t`` on the set and its projection (:func:`compiled.step_project`), then the points of
        ``joins`` (``(points, pressures)`` pairs) appended (:func:`compiled.join`); with a ``target`` (load
        control: the load over the pixel area, else 0) all pressures are scaled to it. The increment's input
        gets the set's pressures and those of the points that left, and the freed ones rejoin the overlap
        test. Returns ``(gone, capped)``."""
        if cg.t is None:   # no direction was set (an empty set)
            cg.t = np.zeros(cg.s.size, cg.p.dtype)
        joining = sum((float(np.sum(v, dtype=np.float64)) for _, v in joins), 0.0)   # a float also with no joins
        buf, nx, pad = self.low.input_flat, self.nx, self.pad
        m, gone, capped, scale = compiled.step_project(
            cg.s, cg.p, cg.t, cg.c, cg.r, cg.n, tau, H if H is not None else np.inf, H is not None, self.c_low,
            buf, nx, pad, cg.grid, target, joining)
        cg.n = m
        cg.fit()
        for where, values in joins:
            if where.size:
                cg.reserve(where.size)
                cg.n = compiled.join(cg.s, cg.p, cg.t, cg.c, cg.r, cg.n, where, values, cg.p.dtype.type(scale),
                                     self.c, self.p_ref, self.c_low, buf, nx, pad, cg.grid)
        return gone, capped

    def energy_of(self, pairs):
        """``Σ x (G*x)`` of a sparse field given as ``(points, values, ...)`` tuples (one float32 forward
        transform in the direction operator, which the next :meth:`set_direction` rewrites)."""
        flat, nx, pad = self.direction.input_flat, self.nx, self.pad
        self.direction.input.fill(0)
        for where, value, *_ in pairs:
            compiled.scatter(where, value, nx, pad, flat)
        self.counts["fft"] += 1
        return self.direction.energy(self.direction.forward())

    def displacement(self):
        """Dense exact displacements ``u`` (right after a refresh)."""
        return self.c + self.w + self.c.dtype.type(self.delta_ref)

    def take_result(self, delta):
        """``(p, u, g)`` right after a refresh: the reference pressures, displacements and gaps
        ``u - w - δ`` (not clipped). The pressures and gaps are the operator's work arrays, handed
        over (the next solve allocates them anew) rather than copied."""
        u = self.displacement()
        g = self.conv.release("gaps")
        g -= g.dtype.type(delta - self.delta_ref)
        return self.conv.release("reference_pressure"), u, g


def _initial_pressure(conv, w, *, pixel_area, load, penetration, H, initial):
    """Starting pressures (full grid) and their displacements; ``None`` when nothing touches."""
    dtype = w.dtype
    p = np.zeros(w.shape, dtype)
    if initial is not None:
        p[...] = np.maximum(np.asarray(initial, dtype=dtype), 0)
        if H is not None:
            np.minimum(p, H, out=p)
    if load is not None:
        total = float(np.sum(p, dtype=np.float64))
        if total <= 0:
            p.fill(load / (pixel_area * p.size))
        else:
            p *= dtype.type(load / (pixel_area * total))
    elif not np.any(p):
        np.add(w, penetration, out=p)                # overlap without deformation
        np.maximum(p, 0, out=p)
        if not np.any(p):
            return None
        u = conv(p)
        ov = p > 0
        ku = u[ov]
        c0 = _dot(ku, p[ov]) / max(_dot(ku, ku), np.finfo(float).tiny)
        p *= dtype.type(c0)
    if H is not None:
        np.minimum(p, H, out=p)
    return p


def polonsky_keer(conv, w, *, pixel_area: float, load: float | None = None, penetration: float | None = None,
                  hardness: float | None = None, tol: float = 1e-8, maxiter: int = 1000, initial=None,
                  callback=None) -> PKResult:
    """Solve eq. (20) for the pressures under ``w`` at prescribed ``load`` or ``penetration``.

    Parameters
    ----------
    conv : xtopo._kernels.convolution.Convolution
        The elastic operator ``G`` (``conv(p)``, and its forward/energy/inverse halves).
    w : numpy.ndarray
        Heights of the rigid surface minus their maximum (≤ 0), on the active grid.
    pixel_area : float
        ``Δx Δy`` (area) or ``Δx`` (line); the load is ``pixel_area · Σ p``.
    load, penetration : float
        Exactly one: the total force (modulus · pixel_area units) or the rigid-body
        approach ``δ`` (length) from first contact.
    hardness : float, optional
        Pressure cap ``H`` (modulus units).
    tol : float
        Tolerance of the relative residual defined in the module docstring.
    maxiter : int
        Largest number of iterations (under load control with a hardness, of all the inner
        solves at trial penetrations together).
    initial : numpy.ndarray, optional
        Starting pressures (a previous solution).
    callback : callable, optional
        ``callback(iteration, residual)`` after every residual evaluation (progress of long
        solves); its return value is ignored.

    Returns
    -------
    PKResult
        ``convolutions`` counts applications of ``G`` (forward + inverse transforms);
        ``transforms`` counts forward and inverse transforms together.
    """
    with conv.lock:  # the operator's buffers hold this solve's state until it returns
        if hardness is not None and load is not None and load > 0:
            # load control with a cap: the elastic solution where its pressures stay below the hardness (the cap
            # is idle), else the penetration search from its pressures with the iterations it left of maxiter
            elastic = polonsky_keer(conv, w, pixel_area=pixel_area, load=load, tol=tol, maxiter=maxiter,
                                    initial=initial, callback=callback)
            if elastic.converged and float(np.max(elastic.pressure)) < hardness:
                elastic["plastic"] = np.zeros(w.shape, bool)
                return elastic
            conv.begin_solve()
            res = _plastic_load_control(conv, w, pixel_area=pixel_area, load=load, hardness=hardness, tol=tol,
                                        maxiter=max(maxiter - elastic.iterations, 0),
                                        initial=elastic.pressure if initial is None and np.any(elastic.pressure)
                                        else initial)
            for key in COUNTERS:
                res[key] += elastic[key]
            return res
        conv.begin_solve()
        return _solve(conv, w, pixel_area=pixel_area, load=load, penetration=penetration, hardness=hardness,
                      tol=tol, maxiter=maxiter, initial=initial, callback=callback)


def _solve(conv, w, *, pixel_area, load, penetration, hardness, tol, maxiter, initial, callback):
    """:func:`polonsky_keer` with the operator's lock held."""
    w = np.ascontiguousarray(w)
    dtype = w.dtype
    shape = w.shape
    H = None if hardness is None else dtype.type(hardness)
    load_control = load is not None
    counts = {"conv": 0, "fft": 0, "exact": 0}

    def result(p, u, g, delta, it, res, ok):
        """The result from pressures ``p``, displacements ``u`` and gaps ``g = u - w - δ`` (clipped at 0 in place)."""
        plastic = (p >= H) if H is not None else None
        return PKResult(pressure=p, displacement=u, gap=np.maximum(g, 0, out=g), penetration=float(delta),
                        load=float(pixel_area * np.sum(p, dtype=np.float64)), iterations=it, residual=float(res),
                        converged=bool(ok), convolutions=counts["conv"], transforms=counts["fft"],
                        exact_convolutions=counts["exact"], plastic=plastic)

    p0 = None if load_control and load <= 0 else _initial_pressure(
        conv, w, pixel_area=pixel_area, load=load, penetration=penetration, H=H, initial=initial)
    if p0 is None:   # nothing touches
        z = np.zeros(shape, dtype)
        delta = 0.0 if load_control else penetration
        return result(z, z.copy(), -w - dtype.type(delta), delta, 0, 0.0, True)

    # -- sets: indices into the flat grid, with the pressures of the elastic ones ----------------
    p0 = p0.reshape(-1)
    idx, pl = compiled.split_sets(p0, np.inf if H is None else H)
    pI = p0[idx]
    del p0
    disp = _Displacements(conv, w, counts)
    cg = _ContactSet(idx, pI, (disp.nx, disp.pad), disp.low.input_flat.size, disp.c, disp.p_ref)
    del idx, pI   # the set holds them

    # damped Jacobi step (a pixel's self-stiffness G(0) = Σ_k G̃_k / M over-counts a patch):
    # the step of joining points when no CG step exists (e.g. fully plastic)
    kii = conv.self_stiffness
    tau_fallback = 0.25 / kii if kii > 0 else 0.0

    delta = float(penetration) if not load_control else 0.0
    disp.refresh(cg, pl, H, delta)
    scale = _length_scale(w)
    if not scale > 0:
        # a flat surface: the deformation by the starting pressures (at least one pixel's own
        # indentation under their mean — a periodic flat under uniform pressure does not move)
        p_mean = (float(np.sum(cg.p_, dtype=np.float64)) + (H or 0) * pl.size) / w.size
        scale = max(float(np.max(np.abs(disp.displacement()))), p_mean * kii) or 1.0
    G_old = 0.0
    residual = math.inf
    converged = False
    it = 0
    while True:
        # gaps relative to the reference: g = (u - w - δ_ref) - (δ - δ_ref); under load control δ is
        # the mean of u - w over the set
        delta, shift, res, G = disp.contact_gaps(cg, load_control, delta)
        nI = cg.n
        # plastic points whose gap opened
        if pl.size:
            g_pl = disp.at(compiled.slots(pl, disp.nx, disp.pad))[0] - shift
            opened = g_pl > 0
            if opened.any():
                res = max(res, float(np.max(g_pl[opened])))
        # overlaps outside the contact (free points with g < 0)
        over, g_over, lowest = disp.overlaps(shift)
        if over.size:
            res = max(res, -lowest)
        residual = res / scale
        if disp.fresh:
            refresh_below = residual * _REFRESH
        elif disp.mixed and residual <= max(tol, refresh_below):
            # the increment's float32 rounding scales with it: before trusting a small residual,
            # and whenever it has fallen by _REFRESH, evaluate in the working precision
            disp.refresh(cg, pl, H, delta)
            continue
        if callback is not None:
            callback(it, residual)
        if residual <= tol:
            converged = True
            break
        if it == maxiter:
            break
        it += 1
        # conjugate direction on the CG set: conjugate to the last one (t starts at 0, and is 0 on
        # points that just joined); one that is no longer downhill — the sets moved under it —
        # restarts from g
        tau = 0.0
        if nI:
            beta = G / G_old if G_old > 0 else 0.0
            slope, denom = disp.set_direction(cg, dtype.type(beta), load_control, it == 1)
            G_old = G
            if denom > 0 and slope > 0:
                tau = slope / denom
        step = dtype.type(tau if tau > 0 else tau_fallback)
        # joins: overlapping free points (from 0), plastic points whose gap opened (from H) → p ← p - step g
        moving = [(over, g_over, 0, False)] if over.size else []
        if pl.size and opened.any():
            moving.append((pl[opened], g_pl[opened], H, True))
            pl = pl[~opened]
        if sum(m.size for m, *_ in moving) > max(nI, 16):
            # more points join than the CG set holds (a warm start far from the solution, the first
            # iterations): the CG step says nothing about them and may push them all past the hardness
            # and back. Take the steepest-descent step of the joining points, Σ g² / Σ g (G*g), at most
            energy = disp.energy_of(moving)
            if energy > 0:
                step = min(step, dtype.type(sum(_dot(g, g) for _, g, *_ in moving) / energy))
        # joining points at H become plastic, plastic ones at 0 free; `changed` collects the points outside the set
        # whose pressure became 0 or H (the increment's input)
        changed, joins, capped_now = [], [], []
        for where, g, start, was_plastic in moving:
            value = start - step * g
            if H is not None:
                full = value >= H
                if full.any():
                    capped_now.append(where[full])
                    if not was_plastic:
                        changed.append((where[full], H))
                        disp.hide(where[full])
                    where, value = where[~full], value[~full]
            pos = value > 0
            if was_plastic and not pos.all():
                changed.append((where[~pos], 0))
                disp.show(where[~pos])
            if not pos.all():
                where, value = where[pos], value[pos]
            joins.append((where, value.astype(dtype, copy=False)))
        # projection: leave the CG set at p ≤ 0 (free) or p ≥ H (plastic), the set compacted in place, the
        # joins appended and (load control) all scaled to the load
        gone, capped = disp.step(cg, dtype.type(tau), H, load / pixel_area if load_control else 0.0, joins)
        if capped.any():
            pl = np.concatenate([pl, gone[capped]])
        if capped_now:
            pl = np.concatenate([pl, *capped_now])
        disp.update(changed)
    if not disp.fresh:  # the returned displacements are exact convolutions of the pressures
        disp.refresh(cg, pl, H, delta)
    if load_control and cg.n:
        delta = disp.delta_ref + disp.at(cg.s_)[1] / cg.n
    p, u, g = disp.take_result(delta)   # the reference pressures are the iterate's (fresh)
    return result(p.reshape(shape), u.reshape(shape), g.reshape(shape), delta, it, residual, converged)


def _secant_step(a, b):
    """``|δ_root - δ_b|`` by the secant through the bracket ends ``a`` and ``b`` (``[δ, F - load, ...]``) when
    both lie on one side of the root (inf where the secant says nothing): a bracket grown by twice its width
    may land where nearly all of the contact flows, the hardest solves of all (di-1.di at 97 % plastic)."""
    slope = (b[1] - a[1]) / (b[0] - a[0]) if b[0] != a[0] else 0.0
    return abs(b[1] / slope) if slope > 0 else math.inf


def _start_penetration(conv, w, initial, hardness):
    """The penetration of the starting pressures ``initial`` (capped at ``hardness``): the mean of
    ``G*p - w`` over their contact (one convolution); None without them."""
    if initial is None:
        return None
    p = np.minimum(np.maximum(np.asarray(initial, dtype=w.dtype), 0), hardness)
    on = p > 0
    if not on.any():
        return None
    delta = float(np.mean((conv(p) - w)[on], dtype=np.float64))
    return delta if delta > 0 else None


def _plastic_load_control(conv, w, *, pixel_area, load, hardness, tol, maxiter, initial):
    """Load control with a hardness: find the penetration whose solution carries ``load``.

    The load ``F(δ)`` is a monotonic function of the penetration. The root of
    ``F(δ) - load`` is bracketed and found by false position with the Illinois
    modification. It stops when the load is carried to the relative tolerance ``tol`` (the
    criterion is on the load, not on ``δ``: near full plasticity ``F`` is steep in ``δ``).

    The first bracket end is the penetration of the starting pressures ``initial`` (the
    mean of ``G*p - w`` over their contact: for the elastic solution at ``load``, which
    :func:`polonsky_keer` passes, a lower bound — a cap only softens the
    contact), else the rigid-plastic (bearing-area) penetration where ``H · area = load``.
    The latter ignores the elastic deflection, which dominates when ``H/E*`` is not small
    (opd-1.opd filled at E* = 2e9, H = 1e8, p = 5e7 needed 7 solves to bracket the root).
    Every solve is warm-started from the pressures interpolated linearly in ``δ`` between
    the bracket ends (extrapolated from the last two solves while the bracket grows):
    starting from the pressures of another ``δ`` shifts every gap by the change of ``δ``,
    which near full contact is many times the peak-to-valley height and costs as many
    iterations as a cold start, so the solves together ran past ``maxiter``.

    Points free or plastic in the bracket end nearer in δ start so (:func:`guess` inside): interpolated,
    they would join the CG set with their gap or plastic overlap as residual.

    The search is coarse-to-fine: each solve from a warm start costs about as many iterations
    per decade of the residual as the elastic solve (near full contact, e.g. a long line scan,
    60-100: the free 1D Green's function ~1/|k| is ill-conditioned), so the solves far from the
    root run to the inner tolerance :data:`_COARSE` only. Their loads may be off by about
    ``10 · tol_inner · s · dF/dδ`` (``s`` the peak-to-valley height, the slope from the
    bracket's secant); once a bracket end's ``|F - load|`` is within that, the inner tolerance
    becomes ``tol``, and the ends whose sign it leaves in doubt are solved again. Only solves at
    ``tol`` are returned (hfm-1.hfm at E* = 2e9, H = 1e8, p = 5e7: 1505 iterations with every
    solve at ``tol``, 889 now; the result equals the former within the solver tolerance).

    A warm start that already meets the inner tolerance says nothing about ``F`` at the new
    ``δ``: the inner tolerance is then tightened, and a bracket end whose load was computed
    at a looser tolerance is solved again before it is trusted (its load may be off by
    more than the target accuracy, and the bracket may not hold the root at all).

    ``maxiter`` bounds the iterations of all inner solves together (each gets what the
    previous ones left); when they are spent the best converged solve so far is returned,
    flagged unconverged unless it carries the load to ``tol``.
    """
    state = {"p": initial, "solves": 0, "tol": max(tol, _COARSE), "best": None, **dict.fromkeys(COUNTERS, 0)}
    scale = _length_scale(w)

    def load_error(end_tol, a, b):
        """Bound of the load error of a solve at the inner tolerance ``end_tol``: its gaps are off by at most
        ``end_tol · s`` (s the peak-to-valley height), as if δ were, so ``F`` by about the slope ``dF/dδ``
        (the secant through the solves ``a`` and ``b``) times that, with a margin of 10."""
        slope = (b[1] - a[1]) / (b[0] - a[0]) if b[0] != a[0] else math.inf
        return 10 * end_tol * scale * slope if slope > 0 else math.inf

    def budget():
        """Iterations left of ``maxiter``, which bounds the inner solves together."""
        return maxiter - state["iterations"]

    def guess(delta, a, b):
        """Pressures at ``delta`` interpolated (extrapolated) linearly in δ from the solves ``a`` and ``b``,
        kept in [0, H]; the last solve's when either is missing. Points free (0) or plastic (H) in the
        solve nearer in δ stay so: interpolated they would join the CG set with their gap or plastic overlap
        (~ the peak-to-valley height) as residual, and the CG steps that take them back disturb the whole
        contact — slow to settle when the contact is nearly full."""
        if a[3] is None or b[3] is None or a[0] == b[0]:
            return state["p"]
        f = (delta - a[0]) / (b[0] - a[0])
        p = np.clip(a[3] + w.dtype.type(f) * (b[3] - a[3]), 0, hardness)
        near = b[3] if f >= 0.5 else a[3]
        bound = (near <= 0) | (near >= hardness)
        p[bound] = near[bound]
        return p

    def solve_at(delta, start=None):
        start = state["p"] if start is None else start
        while True:
            cold = start is None
            res = polonsky_keer(conv, w, pixel_area=pixel_area, penetration=delta, hardness=hardness,
                                tol=state["tol"], maxiter=max(budget(), 0), initial=start)
            for key in COUNTERS:
                state[key] += res[key]
            state["solves"] += 1
            f = res.load - load
            fine = res.converged and state["tol"] <= tol  # only these may be returned
            if fine and (state["best"] is None or abs(f) < abs(state["best"][1])):
                state["best"] = (res, f)
            done = fine and abs(f) <= f_tol  # a start that meets the tolerance and carries the load
            if res.iterations > 0 or cold or done or state["tol"] <= 1e-13 or budget() <= 0:
                break
            # the warm start (the solution at another δ) already met the tolerance: its load
            # is not F(δ). Resolve finer — near the root F changes fast within a small δ step
            state["tol"] = max(state["tol"] * 0.1, 1e-13)
        pressure = res.pressure if np.any(res.pressure) else None
        if pressure is not None:
            state["p"] = pressure
        # a bracket end: δ, F(δ) - load, inner tolerance, pressures (the warm starts of the solves between ends)
        return [float(delta), f, state["tol"], pressure]

    depth = np.sort(-w, axis=None)
    f_tol = tol * load
    delta0 = _start_penetration(conv, w, initial, hardness)
    if delta0 is None:
        k = int(min(depth.size - 1, max(0, math.ceil(load / (pixel_area * hardness)))))
        delta0 = float(depth[k])
    lo = solve_at(delta0)
    if lo[1] > 0:  # above the root: step down towards zero
        hi, lo = lo, solve_at(0.5 * delta0)
    else:
        # the secant through F(0) = 0, 10 % beyond (F is concave once the cap bites), at most 2 δ
        carried = load + lo[1]
        ratio = min(2.0, 1.1 * load / carried) if carried > 0 else 2.0
        hi = solve_at(ratio * lo[0] if lo[0] > 0 else float(depth[-1]) / 100 + np.finfo(float).tiny)
    side = 0
    for _ in range(400):
        best = state["best"]
        if (best is not None and abs(best[1]) <= f_tol) or budget() <= 0:
            break
        # the search starts with coarse solves; where an end's load comes within what they may be off by,
        # the inner tolerance becomes tol
        if state["tol"] > tol and min(abs(lo[1]), abs(hi[1])) <= load_error(state["tol"], lo, hi):
            state["tol"] = tol
        # ends solved at a looser inner tolerance than the current one are solved again where their load
        # may be on the wrong side of the target
        for end in (lo, hi):
            if end[2] > state["tol"] and abs(end[1]) <= load_error(end[2], lo, hi):
                end[:] = solve_at(end[0], end[3])
        if hi[1] < 0:  # the root lies above: move the bracket up
            width = max(hi[0] - lo[0], abs(hi[0]) * 1e-12, np.finfo(float).tiny)
            d = hi[0] + min(2 * width, 1.5 * _secant_step(lo, hi))
            lo, hi, side = hi, solve_at(d, guess(d, lo, hi)), 0
            continue
        if lo[1] > 0:  # below (δ = 0 carries no load, so this ends)
            width = max(hi[0] - lo[0], abs(lo[0]) * 1e-12, np.finfo(float).tiny)
            d = max(lo[0] - min(2 * width, 1.5 * _secant_step(hi, lo)), 0.0)
            hi, lo, side = lo, solve_at(d, guess(d, lo, hi)), 0
            continue
        if hi[0] - lo[0] <= 4 * np.finfo(float).eps * abs(hi[0]):
            break
        (d_lo, f_lo, *_), (d_hi, f_hi, *_) = lo, hi
        d = d_hi - f_hi * (d_hi - d_lo) / (f_hi - f_lo) if f_hi != f_lo else 0.5 * (d_lo + d_hi)
        if not d_lo < d < d_hi:
            d = 0.5 * (d_lo + d_hi)
        end = solve_at(d, guess(d, lo, hi))
        if end[1] < 0:
            lo = end
            if side == -1:  # Illinois: the other end stayed twice, halve its weight
                hi[1] *= 0.5
            side = -1
        else:
            hi = end
            if side == 1:
                lo[1] *= 0.5
            side = 1
    if state["best"] is None:  # no inner solve converged: report the last bracket end (no iterations left)
        state["best"] = (polonsky_keer(conv, w, pixel_area=pixel_area, penetration=hi[0], hardness=hardness, tol=tol,
                                       maxiter=max(budget(), 0), initial=state["p"]), hi[1])
    res, f_best = state["best"]
    load_err = abs(f_best) / load
    for key in (*COUNTERS, "solves"):
        res[key] = state[key]
    res["residual"] = max(res.residual, load_err)
    res["converged"] = bool(res.converged and load_err <= tol)
    return res
