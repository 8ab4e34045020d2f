"""Polonsky–Keer constrained conjugate gradients for the contact problem eq. (20), numpy only.

Problem (paper §5.4): a rigid surface with heights ``w ≤ 0`` (measured from its highest
point) is pressed by ``δ`` (the penetration) into an elastic flat. With displacements
``u = G * p`` the gap is ``g = u - w - δ`` and the linear complementarity conditions are

    p ≥ 0,  g ≥ 0,  p g = 0          (and p ≤ H where a hardness H caps the pressure).

Either the total load ``F = ΔA Σ p`` is prescribed (``δ`` then follows as the mean of
``u - w`` over the contact) or the penetration ``δ``.

Iteration (Polonsky & Keer, Wear 231, 206 (1999)), on the CG set ``I = {0 < p < H}``:

1. ``g = u - w - δ`` (load control: ``δ = mean_I(u - w)``), ``G = Σ_I g²``;
2. direction ``t = g + β (G/G_old) t`` on ``I`` (0 elsewhere; ``β = 0`` after a reset);
3. ``r = G * t`` — the one FFT convolution of a plain step; under load control ``r``
   is shifted by its mean over ``I`` for the step length;
4. step ``τ = Σ_I g t / Σ_I r t``, ``p ← p - τ t``, ``u ← u - τ r`` (exact, by linearity);
5. projection: ``p < 0 → 0``; ``p > H → H``; points outside ``I`` that overlap
   (``p = 0, g < 0``) or plastic points whose gap opened (``p = H, g > 0``) get
   ``p ← p - τ g`` and the CG restarts (``β = 0``);
6. load control: ``p ← p F/(ΔA Σ p)`` (then the cap again).

The displacement is carried along incrementally; only when the projection changed a
pressure does a second convolution correct ``u`` (``u ← u + G * Δp``), and ``u`` is
recomputed from ``p`` every ``refresh`` iterations and before convergence is accepted.

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

__all__ = ["polonsky_keer", "PKResult"]


def _dot(a, b, work=None) -> float:
    """Inner product without BLAS (multiply into ``work``, then sum).

    BLAS dot products wake a pool of threads that contend with the FFT threads; on a
    loaded machine that costs far more than the extra pass.
    """
    if work is None:
        work = np.empty_like(a)
    np.multiply(a, b, out=work)
    return float(np.sum(work, dtype=np.float64))


class PKResult(dict):
    """Dict with keys ``pressure``, ``displacement``, ``gap``, ``penetration``, ``load``,
    ``iterations``, ``residual``, ``converged``, ``convolutions``, ``plastic``."""

    __getattr__ = dict.__getitem__


def _length_scale(w, u=None):
    s = float(-np.min(w)) if w.size else 0.0
    if s > 0:
        return s
    if u is not None and np.any(u):
        return float(np.max(np.abs(u)))
    return 1.0


def polonsky_keer(conv, w, *, pixel_area: float, load: float | None = None, penetration: float | None = None,
                  hardness: float | None = None, tol: float = 1e-8, maxiter: int = 1000, initial=None,
                  refresh: int = 50) -> PKResult:
    """Solve eq. (20) for the pressures under ``w`` at prescribed ``load`` or ``penetration``.

    Parameters
    ----------
    conv : callable
        ``conv(p, out)`` writes ``G * p`` into ``out`` (:class:`~xtopo._kernels.convolution.Convolution`).
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
        Largest number of iterations.
    initial : numpy.ndarray, optional
        Starting pressures (a previous solution).
    refresh : int
        Recompute ``u = G * p`` from scratch every ``refresh`` iterations.

    Returns
    -------
    PKResult
    """
    if (load is None) == (penetration is None):
        raise ValueError("give exactly one of load and penetration")
    if hardness is not None and load is not None and load > 0:
        return _plastic_load_control(conv, w, pixel_area=pixel_area, load=load, hardness=hardness, tol=tol,
                                     maxiter=maxiter, initial=initial, refresh=refresh)
    dtype = w.dtype
    shape = w.shape
    H = None if hardness is None else dtype.type(hardness)
    scale = _length_scale(w)
    load_control = load is not None
    p = np.zeros(shape, dtype)
    u = np.zeros(shape, dtype)
    nconv = 0

    def result(p, u, delta, it, res, conv_ok):
        g = u - w - dtype.type(delta)
        plastic = (p >= H) if H is not None else np.zeros(shape, bool)
        return PKResult(pressure=p, displacement=u, gap=np.maximum(g, 0), penetration=float(delta),
                        load=float(pixel_area * np.sum(p, dtype=np.float64)), iterations=it, residual=float(res),
                        converged=bool(conv_ok), convolutions=nconv, plastic=plastic)

    if load_control and load <= 0:
        return result(p, u, 0.0, 0, 0.0, True)

    # -- initial pressures ------------------------------------------------------------------
    if initial is not None:
        p[...] = np.maximum(np.asarray(initial, dtype=dtype), 0)
        if H is not None:
            np.minimum(p, H, out=p)
    if load_control:
        total = float(np.sum(p, dtype=np.float64))
        if total <= 0:
            p.fill(load / (pixel_area * p.size))
        else:
            p *= dtype.type(load / (pixel_area * total))
        conv(p, u)
        nconv += 1
    else:
        if not np.any(p):
            np.subtract(-w, penetration, out=p)          # overlap without deformation
            np.maximum(p, 0, out=p)
            if not np.any(p):
                return result(p, u, penetration, 0, 0.0, True)
            conv(p, u)
            nconv += 1
            ov = p > 0
            ku = u[ov]
            c0 = float(_dot(ku, p[ov]) / max(_dot(ku, ku), np.finfo(float).tiny))
            p *= dtype.type(c0)
            u *= dtype.type(c0)
        else:
            conv(p, u)
            nconv += 1
    if H is not None:
        np.minimum(p, H, out=p)
        conv(p, u)
        nconv += 1

    # Jacobi step: fallback for τ when no CG set exists (fully plastic)
    unit = np.zeros(shape, dtype)
    unit[tuple(n // 2 for n in shape)] = 1
    kii = float(conv(unit, np.empty(shape, dtype))[tuple(n // 2 for n in shape)])
    nconv += 1
    del unit
    # damped Jacobi step (a single pixel's stiffness over-counts a patch of neighbours)
    tau_fallback = 0.25 / kii if kii > 0 else 0.0

    # -- work arrays (no allocation inside the loop but for np.nonzero-free masks) -----------
    g = np.empty(shape, dtype)
    gc = np.empty(shape, dtype)
    t = np.zeros(shape, dtype)
    r = np.empty(shape, dtype)
    dp = np.zeros(shape, dtype)
    tmp = np.empty(shape, dtype)
    c = np.empty(shape, bool)
    cb = np.empty(shape, bool)
    free = np.empty(shape, bool)
    cf = np.empty(shape, dtype)
    work = np.empty(shape, dtype)

    delta = float(penetration) if not load_control else 0.0
    restart = True
    G_old = 1.0
    tau = 0.0
    since_exact = 0
    residual = math.inf
    converged = False
    it = 0
    for it in range(1, maxiter + 1):
        # contact (CG) set
        np.greater(p, 0, out=c)
        if H is not None:
            np.less(p, H, out=cb)
            c &= cb
        nc = int(np.count_nonzero(c))
        np.copyto(cf, c)
        np.subtract(u, w, out=g)
        if load_control and nc > 0:
            delta = float(_dot(g, cf, work)) / nc
        g -= dtype.type(delta)
        np.multiply(g, cf, out=gc)
        # residual: contact-set gaps, overlaps outside, opened plastic points
        res = float(np.max(np.abs(gc))) if nc else 0.0
        np.less_equal(p, 0, out=free)
        np.negative(g, out=tmp)
        tmp *= free
        res = max(res, float(np.max(tmp)))
        if H is not None:
            np.greater_equal(p, H, out=cb)
            np.multiply(g, cb, out=tmp)
            res = max(res, float(np.max(tmp)))
        residual = res / scale
        if H is not None and load_control:
            residual = max(residual, abs(pixel_area * float(np.sum(p, dtype=np.float64)) - load) / load)
        if residual <= tol:
            if since_exact == 0:
                converged = True
                break
            conv(p, u)           # verify with exact displacements
            nconv += 1
            since_exact = 0
            restart = True
            continue
        # conjugate direction
        G = float(_dot(gc, gc, work))
        if not restart and G_old > 0:
            t *= dtype.type(G / G_old)
            t += gc
            t *= cf
        else:
            np.copyto(t, gc)
        G_old = G
        tau = 0.0
        if nc > 0 and G > 0:
            conv(t, r)
            nconv += 1
            denom = float(_dot(r, t, work))
            if load_control:
                denom -= float(_dot(r, cf, work)) / nc * float(np.sum(t, dtype=np.float64))
            tau = float(_dot(gc, t, work)) / denom if denom > 0 else 0.0
            if tau != 0.0:
                np.multiply(t, dtype.type(tau), out=tmp)
                p -= tmp
                np.multiply(r, dtype.type(tau), out=tmp)
                u -= tmp
        step = tau if tau > 0 else tau_fallback
        # projection onto 0 ≤ p ≤ H, overlap points join (and the CG restarts)
        changed = False
        np.less(p, 0, out=cb)
        if cb.any():
            np.negative(p, out=dp)
            dp *= cb
            p[cb] = 0
            changed = True
        else:
            dp.fill(0)
        if H is not None:
            np.greater(p, H, out=cb)
            if cb.any():
                dp[cb] += H - p[cb]
                p[cb] = H
                changed = True
        # overlapping free points (p was 0 before the step, g < 0)
        np.less(g, 0, out=cb)
        cb &= free
        if H is not None:
            np.greater(g, 0, out=c)
            np.greater_equal(p, H, out=free)
            c &= free
            cb |= c
        if cb.any():
            np.multiply(g, dtype.type(-step), out=tmp)
            tmp *= cb
            p += tmp
            dp += tmp
            np.maximum(p, 0, out=p)
            if H is not None:
                np.minimum(p, H, out=p)
            changed = True
            restart = True
        else:
            restart = False
        if load_control:
            total = pixel_area * float(np.sum(p, dtype=np.float64))
            s = dtype.type(load / total) if total > 0 else dtype.type(1)
        since_exact += 1
        if H is not None:
            if load_control:
                p *= s
                np.minimum(p, H, out=p)
            conv(p, u)
            nconv += 1
            since_exact = 0
        else:
            if changed:
                conv(dp, r)
                nconv += 1
                u += r
            if load_control:
                p *= s
                u *= s
            if since_exact >= refresh:
                conv(p, u)
                nconv += 1
                since_exact = 0
    else:
        it = maxiter
    if since_exact:
        conv(p, u)
        nconv += 1
    if load_control:
        np.greater(p, 0, out=c)
        if H is not None:
            np.less(p, H, out=cb)
            c &= cb
        nc = int(np.count_nonzero(c))
        if nc:
            delta = float(np.mean((u - w)[c]))
    return result(p, u, delta, it, residual, converged)


def _plastic_load_control(conv, w, *, pixel_area, load, hardness, tol, maxiter, initial, refresh):
    """Load control with a hardness: find the penetration whose solution carries ``load``.

    The load is a monotonic function of the penetration; Brent's method on
    ``F(δ) - load`` with every solve warm-started from the last one. The bracket starts at
    the rigid-plastic (bearing-area) penetration, where ``H · area = load``, which
    carries at most ``load`` once the elastic deflection is accounted for.
    """
    from scipy.optimize import brentq

    state = {"p": initial, "iterations": 0, "convolutions": 0, "last": None, "ok": True, "solves": 0}
    load_tol = max(tol, 1e-9)

    def solve_at(delta):
        res = polonsky_keer(conv, w, pixel_area=pixel_area, penetration=delta, hardness=hardness, tol=tol,
                            maxiter=maxiter, initial=state["p"], refresh=refresh)
        state["iterations"] += res.iterations
        state["solves"] += 1
        state["convolutions"] += res.convolutions
        state["ok"] = state["ok"] and res.converged
        if np.any(res.pressure):
            state["p"] = res.pressure
        state["last"] = res
        return res.load - load

    depth = np.sort(-w, axis=None)
    if load >= pixel_area * hardness * depth.size:
        raise ValueError(f"the load {load:g} needs more than the whole nominal area at the hardness "
                         f"({pixel_area * hardness * depth.size:g})")
    k = int(min(depth.size - 1, max(0, math.ceil(load / (pixel_area * hardness)))))
    lo = float(depth[k]) if k < depth.size else float(depth[-1])
    f_lo = solve_at(lo)
    if f_lo > 0:  # never expected; fall back towards zero
        hi, f_hi, lo = lo, f_lo, 0.0
        f_lo = solve_at(lo)
    else:
        hi = 2 * lo if lo > 0 else float(depth[-1]) / 100 + np.finfo(float).tiny
        f_hi = solve_at(hi)
        for _ in range(200):
            if f_hi >= 0:
                break
            lo, f_lo, hi = hi, f_hi, 2 * hi
            f_hi = solve_at(hi)
    brentq(lambda d: solve_at(d), lo, hi, xtol=load_tol * max(hi, 1e-300), rtol=4 * np.finfo(float).eps,
           maxiter=100)
    res = state["last"]
    load_err = abs(res.load - load) / load
    res["iterations"] = state["iterations"]
    res["convolutions"] = state["convolutions"]
    res["residual"] = max(res.residual, load_err)
    # F(δ) is only known to the inner tolerance: accept a relative load error up to 100 tol
    res["converged"] = bool(state["ok"] and load_err <= 100 * tol)
    res["solves"] = state["solves"]
    return res
