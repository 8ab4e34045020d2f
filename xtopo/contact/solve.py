"""One contact solution of a :class:`~xtopo.contact.scene.Scene` as a Dataset (paper §5.4)."""

from __future__ import annotations

from typing import Annotated

import numpy as np
import xarray as xr

from .._apply import rescaled
from ..conventions import append_history
from ..errors import ContactError, ConvergenceWarning, warn
from ..params import Count, OneOf, Positive, checked
from ..presets import resolve as resolve_preset

__all__ = ["solve", "default_tol", "solver_settings", "solver_parameters", "control_value", "result_units", "run_solver"]

#: Default tolerance of the relative gap residual (see :mod:`xtopo._kernels.pk_solver`): the knee of the
#: error-vs-time curve (benchmarks/tradeoffs.py, docs/tradeoffs.md); it was 1e-6 for float64 before issue 9.
_DEFAULT_TOL = {np.dtype("float64"): 1e-5, np.dtype("float32"): 1e-5}


def default_tol(dtype) -> float:
    """Tolerance used when ``tol=None`` and no preset: 1e-5 of the peak-to-valley height (float64 and float32)."""
    return _DEFAULT_TOL[np.dtype(dtype)]


#: Smallest tolerance a preset may ask of a float32 solve (float32 cannot resolve less).
_PRESET_TOL_FLOOR = {np.dtype("float64"): 0.0, np.dtype("float32"): 1e-6}


def solver_settings(scene, tol=None, maxiter=None, preset=None) -> tuple[float, int]:
    """``(tol, maxiter)`` of a solve of ``scene``: explicit values, else the preset's, else the defaults.

    ``preset=None`` falls back to the scene's preset (:class:`~xtopo.contact.Scene`), then
    ``"default"`` (:mod:`xtopo.presets`). A preset's tolerance is raised to 1e-6 for float32 scenes.
    """
    knobs = resolve_preset("contact", preset if preset is not None else getattr(scene, "preset", None),
                           tol=tol, maxiter=maxiter)
    if tol is None:
        tol = default_tol(scene.dtype) if knobs["tol"] is None else max(knobs["tol"],
                                                                          _PRESET_TOL_FLOOR[scene.dtype])
    return solver_parameters(tol, knobs["maxiter"])


def solver_parameters(tol, maxiter) -> tuple:
    """``(tol, maxiter)``; a ``tol`` of 1 or more is refused (declared: a positive ``tol``, an integer ``maxiter``)."""
    if tol is not None and tol >= 1:
        raise ContactError(f"tol must be below 1, got {tol:g}: it is the largest contact-condition violation as a "
                           "fraction of the peak-to-valley height, and tol ≥ 1 accepts the starting pressures "
                           "without a single iteration")
    return tol, maxiter


def result_units(scene) -> dict:
    """Units strings of the outputs of ``scene`` (pressure, length, load, area)."""
    pu, lu = scene.modulus_units, scene.length_units
    if scene.line:
        return {"pressure": pu, "length": lu, "load": f"{pu} {lu}", "area": lu}
    return {"pressure": pu, "length": lu, "load": f"{pu} {lu}2", "area": f"{lu}2"}


def control_value(name: str, v, hardness: float | None = None, *, label: str | None = None) -> float:
    """One ``load``/``mean_pressure``/``penetration`` value checked without a scene (a finite real
    scalar, ≥ 0 unless a penetration; a mean pressure below ``hardness``); returns it as a float.

    ``label``: what the messages call the value (default ``name``), e.g. the command-line option
    that gave it (``"--loads value"``).
    """
    label = name if label is None else label
    real = (not isinstance(v, (str, bytes, bool, np.bool_)) and np.ndim(v) == 0
            and not np.iscomplexobj(v) and np.issubdtype(np.asarray(v).dtype, np.number))
    if not real or not np.isfinite(float(v)):
        hint = " (use Scene.curve for sequences)" if isinstance(v, (list, tuple, np.ndarray)) else ""
        raise ContactError(f"{label} must be a finite scalar, got {v!r}{hint}")
    if name != "penetration" and float(v) < 0:
        raise ContactError(f"{label} must be ≥ 0 (adhesion is not modelled), got {v}")
    if name == "mean_pressure" and hardness is not None and float(v) >= hardness:
        raise ContactError(f"{label} {float(v):g} reaches the hardness ({hardness:g}): the whole surface "
                           "would flow; lower the mean pressure or raise the hardness")
    return float(v)


def _control(scene, load, mean_pressure, penetration):
    """The one control given (:data:`CONTROL` is declared by the callers) checked against the scene."""
    for name, v in (("load", load), ("mean_pressure", mean_pressure), ("penetration", penetration)):
        if v is not None:
            control_value(name, v, scene.hardness)  # a mean pressure is compared with the hardness itself
    if penetration is not None and scene.periodic and scene.hardness is None:
        # 0.0 - : a flat surface's is 0, not -0; scene.w is in units of 2**height_exponent
        limit = 0.0 - float(np.ldexp(np.mean(scene.w, dtype=np.float64), scene.height_exponent))
        if float(penetration) >= limit:
            raise ContactError(
                f"penetration {float(penetration):g} reaches the mean plane of the periodic surface (its highest "
                f"point is {limit:g} above the mean): a periodic elastic solid is pushed there only by an "
                "infinite pressure; prescribe load= or mean_pressure= instead")
    if mean_pressure is not None:
        load = float(mean_pressure) * scene.nominal_area
    if scene.hardness is not None and load is not None and float(load) >= scene.hardness * scene.nominal_area:
        raise ContactError(f"load {float(load):g} exceeds hardness × nominal area "
                           f"({scene.hardness * scene.nominal_area:g}): the whole surface would flow; lower the load "
                           "or raise the hardness")
    return (None if load is None else float(load)), (None if penetration is None else float(penetration))


def _initial(scene, initial):
    if initial is None:
        return None
    if isinstance(initial, xr.Dataset):
        if "pressure" not in initial.data_vars:
            raise ContactError("initial must be a contact result (a Dataset with a 'pressure' variable) or an array "
                               f"of pressures; this Dataset has only {list(initial.data_vars)}")
        initial = initial["pressure"]
    if isinstance(initial, xr.DataArray) and set(initial.dims) == set(scene.dims):
        initial = initial.transpose(*scene.dims)  # e.g. a result transposed to ("x", "y")
    p = np.asarray(getattr(initial, "values", initial))
    if p.shape != scene.shape:
        raise ContactError(f"initial pressures have shape {p.shape}, the scene {scene.shape}")
    if not np.issubdtype(p.dtype, np.number) or np.iscomplexobj(p):
        raise ContactError(f"initial pressures must be real numbers, got dtype {p.dtype}")
    bad = int(np.count_nonzero(~np.isfinite(p)))
    if bad:
        raise ContactError(f"initial pressures have {bad} non-finite (NaN or infinite) values; give finite "
                           "pressures (negative ones count as 0) or initial=None")
    return p


#: the one control of a solve (issue 25: the "exactly one" rule declared once)
CONTROL = OneOf("load", "mean_pressure", "penetration", error=ContactError)


@checked(CONTROL, error=ContactError)
def solve(scene, *, load=None, mean_pressure=None, penetration=None, tol: Annotated[float | None, Positive()] = None,
          maxiter: Annotated[int | None, Count()] = None, initial=None, preset: str | None = None,
          callback=None) -> xr.Dataset:
    """Solve the contact of ``scene`` at one load, mean pressure or penetration.

    Parameters
    ----------
    scene : xtopo.contact.Scene
    load : float, optional
        Total normal force, in modulus units × length² (area scans) or modulus units ×
        length (line scans: force per unit length).
    mean_pressure : float, optional
        Load divided by the nominal (measurement) area, in modulus units.
    penetration : float, optional
        Rigid-body approach from first contact of the highest point, in length units.
        Periodic scenes measure it with the mean displacement set to zero.
    tol : float, optional
        Largest violation of the contact conditions relative to the peak-to-valley height
        (see :mod:`xtopo._kernels.pk_solver`); default from ``preset``, else :func:`default_tol`.
    maxiter : int, optional
        Iteration limit (default from ``preset``: 1000). Non-convergence gives a
        :class:`~xtopo.errors.ConvergenceWarning` and ``converged=False``.
    initial : xarray.Dataset or array_like, optional
        Starting pressures (e.g. a previous result).
    preset : {"fast", "default", "accurate"}, optional
        Speed-versus-accuracy preset for ``tol`` and ``maxiter`` (:mod:`xtopo.presets`);
        default the scene's preset. Explicit ``tol``/``maxiter`` win.
    callback : callable, optional
        ``callback(iteration, residual)`` after every iteration of the elastic solver (progress
        of long solves; not called inside the penetration search of a capped load-controlled solve).

    Returns
    -------
    xarray.Dataset
        Maps ``pressure``, ``displacement``, ``gap``, ``contact`` (and ``plastic`` with a
        hardness) on the measurement grid; scalars ``load``, ``mean_pressure``,
        ``area_fraction``, ``contact_area``, ``penetration``, ``iterations``, ``residual``,
        ``converged``.
    """
    tol, maxiter = solver_settings(scene, tol, maxiter, preset)
    load, penetration = _control(scene, load, mean_pressure, penetration)
    if callback is not None and not callable(callback):
        raise ContactError(f"callback must be a function callback(iteration, residual) or None, got {callback!r}")
    res = run_solver(scene, load=load, penetration=penetration, tol=tol, maxiter=maxiter,
                     initial=_initial(scene, initial), callback=callback)
    if not res.converged:
        warn(f"contact solve did not converge in {res.iterations} iterations (relative residual "
             f"{res.residual:.3g} > tol {tol:g}); the result is flagged converged=False — raise maxiter or "
             "tol, or start from a nearby solution (initial=)", ConvergenceWarning)
    return to_dataset(scene, res, tol)


def run_solver(scene, *, load, penetration, tol, maxiter, initial, callback=None):
    """Polonsky–Keer on ``scene`` (returns a :class:`~xtopo._kernels.pk_solver.PKResult`).

    With a hardness under load control the elastic problem is solved first: where its
    pressures stay below the hardness it is also the solution of the capped problem
    (the cap is inactive), and the capped solver is not needed; otherwise the capped solver
    gets the iterations the elastic solve left of ``maxiter``.
    """
    from .._kernels.pk_solver import COUNTERS, polonsky_keer  # lazy: numba (startup time, issue 26)

    e = scene.height_exponent  # scene.w is in units of 2**e: so are the controls given to the solver

    def down(v):
        return None if v is None else np.ldexp(np.asarray(v, dtype=np.float64), -e)

    load, penetration, hardness = (float(down(v)) if v is not None else None
                                   for v in (load, penetration, scene.hardness))
    kw = dict(pixel_area=scene.pixel_area, tol=tol, maxiter=int(maxiter), initial=down(initial))
    elastic = None
    res = None
    if hardness is not None and load is not None and load > 0:
        elastic = polonsky_keer(scene.convolution, scene.w, load=load, callback=callback, **kw)
        if elastic.converged and float(np.max(elastic.pressure)) < hardness:
            res, elastic = elastic, None
        else:
            kw["maxiter"] = max(int(maxiter) - elastic.iterations, 0)
            if initial is None and np.any(elastic.pressure):
                kw["initial"] = elastic.pressure  # its penetration is a lower bound of the capped one's
    if res is None:
        if hardness is None or load is None:
            kw["callback"] = callback
        res = polonsky_keer(scene.convolution, scene.w, load=load, penetration=penetration, hardness=hardness, **kw)
    if elastic is not None:
        for key in COUNTERS:
            res[key] += elastic[key]
    if e:  # pressures, displacements and gaps are linear in the heights (E* fixed)
        for key in ("pressure", "displacement", "gap"):
            res[key] = rescaled(res[key], e, 1, "contact")
        for key in ("penetration", "load"):
            res[key] = float(rescaled(np.float64(res[key]), e, 1, "contact"))
    return res


def to_dataset(scene, res, tol) -> xr.Dataset:
    """Wrap a :class:`~xtopo._kernels.pk_solver.PKResult` of ``scene`` as a Dataset with units."""
    u = result_units(scene)
    dims = scene.dims
    contact = res.pressure > 0
    n = contact.size
    data = {
        "pressure": (dims, res.pressure, {"units": u["pressure"], "long_name": "contact pressure"}),
        "displacement": (dims, res.displacement, {"units": u["length"], "long_name": "normal displacement of the "
                                                  "elastic surface (positive into the solid)"}),
        "gap": (dims, res.gap, {"units": u["length"], "long_name": "gap between the surfaces"}),
        "contact": (dims, contact, {"units": "1", "long_name": "in contact (pressure > 0)"}),
        "load": ((), res.load, {"units": u["load"], "long_name": "normal load"
                                + (" per unit length" if scene.line else "")}),
        "mean_pressure": ((), res.load / scene.nominal_area, {"units": u["pressure"],
                                                              "long_name": "mean pressure over the nominal area"}),
        "area_fraction": ((), np.count_nonzero(contact) / n, {"units": "1",
                                                              "long_name": "relative contact area A/A0"}),
        "contact_area": ((), np.count_nonzero(contact) * scene.pixel_area,
                         {"units": u["area"], "long_name": "contact " + ("length" if scene.line else "area")}),
        "penetration": ((), res.penetration, {"units": u["length"],
                                              "long_name": "rigid-body approach from first contact"}),
        "iterations": ((), res.iterations, {"units": "1", "long_name": "Polonsky-Keer iterations"}),
        "residual": ((), res.residual, {"units": "1", "long_name": "largest contact-condition violation / "
                                        "peak-to-valley height"}),
        "converged": ((), res.converged, {"units": "1", "long_name": "solver reached tol"}),
    }
    if scene.hardness is not None:
        plastic = res.plastic if res.plastic is not None else np.zeros(scene.shape, bool)  # elastic: the cap idle
        data["plastic"] = (dims, plastic, {"units": "1", "long_name": "pressure at the hardness (flowing)"})
    ds = xr.Dataset(data, coords=scene.coords)
    ds.attrs = {
        "modulus": scene.modulus, "modulus_units": scene.modulus_units, "periodic": int(scene.periodic),
        "boundary": "periodic" if scene.periodic else "free", "solver": "Polonsky-Keer constrained CG",
        "tolerance": tol, "dtype": scene.dtype.name, "convolutions": int(res.convolutions),
        "exact_convolutions": int(res.exact_convolutions),
    }
    if scene.hardness is not None:
        ds.attrs["hardness"] = scene.hardness
    ds.attrs.update(scene.provenance)  # the measurement's file, checksum and history
    return append_history(ds, f"xtopo.contact.solve(load={res.load:.6g}, boundary="
                              f"{'periodic' if scene.periodic else 'free'}, hardness={scene.hardness})")
