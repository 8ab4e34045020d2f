"""One contact solution of a :class:`~xtopo.contact.scene.Scene` as a Dataset (paper §5.4)."""

from __future__ import annotations

import numpy as np
import xarray as xr

from .._apply import rescaled
from ..params import Count, OneOf, Positive, checked
from ..conventions import append_history
from ..errors import ContactError, ConvergenceWarning, warn
from ..presets import resolve as resolve_preset

__all__ = ["solve", "default_tol", "solver_settings", "solver_parameters", "ONE_CONTROL", "ONE_SEQUENCE",
           "control_value", "load_and_area", "run_solver"]

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
    """``(tol, maxiter)`` checked (a :class:`~xtopo.errors.ContactError` names a bad one); None passes.

    ``tol`` is in (0, 1), ``maxiter`` an integer ≥ 1.
    """
    tol = None if tol is None else Positive(error=ContactError).check(tol, "tol")
    if tol is not None and tol >= 1:
        raise ContactError(f"tol must be below 1, got {tol:g}: it is the largest contact-condition violation as a "
                           "fraction of the peak-to-valley height, and tol ≥ 1 accepts the starting pressures "
                           "without a single iteration")
    maxiter = None if maxiter is None else Count(error=ContactError).check(maxiter, "maxiter")
    return tol, maxiter


def load_and_area(line: bool, length: str, pressure: str) -> tuple[dict, dict]:
    """Attributes (units, long_name) of a load and of a contact area: on a line scan a force per unit length
    and a contact length, on an area scan a force and an area; lengths in ``length``, pressures in ``pressure``."""
    area = length if line else f"{length}2"
    return ({"units": f"{pressure} {area}", "long_name": "normal load" + (" per unit length" if line else "")},
            {"units": area, "long_name": "contact " + ("length" if line else "area")})


#: The rule of every contact entry point, declared once (``@checked``): exactly one control, a value
#: (``solve``, ``contact``) or a sequence of values (``curve``, :func:`xtopo.batch.contact`); its value is
#: checked in the body (:func:`control_value`), with the models' advice.
ONE_CONTROL = OneOf("load", "mean_pressure", "penetration", error=ContactError)
ONE_SEQUENCE = OneOf("loads", "mean_pressures", "penetrations", error=ContactError)


def control_value(name: str, v, models=(), *, label: str | None = None, scene=None) -> float:
    """One ``load``/``mean_pressure``/``penetration`` value checked, returned as a float: a finite real
    scalar, ≥ 0 unless a penetration, and one that each of ``models`` (:mod:`xtopo.contact.models`) can
    reach — on the grid of ``scene`` where one is given, else as far as it is known without it (a mean
    pressure below the hardness).

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
    for model in models:
        model.check_control(name, float(v), label, scene)
    return float(v)


def _control(scene, load=None, mean_pressure=None, penetration=None):
    """``(load, penetration)`` of a solve of ``scene`` (one of them None), checked."""
    name, value = ONE_CONTROL.given(dict(load=load, mean_pressure=mean_pressure, penetration=penetration))
    value = control_value(name, value, scene.models, scene=scene)
    if name == "penetration":
        return None, value
    return (value * scene.nominal_area if name == "mean_pressure" else value), None


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


@checked(ONE_CONTROL)
def solve(scene, *, load=None, mean_pressure=None, penetration=None, tol=None, maxiter: int | None = None,
          initial=None, preset: str | None = None, callback=None) -> xr.Dataset:
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
    """Polonsky–Keer on ``scene``, its models composed (returns a :class:`~xtopo._kernels.pk_solver.PKResult`)."""
    from .._kernels.pk_solver import polonsky_keer  # deferred on purpose: numba (startup time, issue 26)

    e = scene.height_exponent  # scene.w is in units of 2**e: so are the controls and pressures given to the solver

    def down(v):
        return None if v is None else np.ldexp(np.asarray(v, dtype=np.float64), -e)

    kw = {}
    for model in scene.models:
        kw.update(model.kernel_arguments(scene, -e))
    load, penetration = (None if v is None else float(down(v)) for v in (load, penetration))
    res = polonsky_keer(w=scene.w, load=load, penetration=penetration, pixel_area=scene.pixel_area, tol=tol,
                        maxiter=int(maxiter), initial=down(initial), callback=callback, **kw)
    if e:  # pressures, displacements and gaps are linear in the heights (E* fixed)
        for key in ("pressure", "displacement", "gap"):
            res[key] = rescaled(res[key], e, 1, "contact")
        for key in ("penetration", "load"):
            res[key] = float(rescaled(np.float64(res[key]), e, 1, "contact"))
    return res


def to_dataset(scene, res, tol) -> xr.Dataset:
    """Wrap a :class:`~xtopo._kernels.pk_solver.PKResult` of ``scene`` as a Dataset with units."""
    pu, lu = scene.modulus_units, scene.length_units
    load_attrs, area_attrs = load_and_area(scene.line, lu, pu)
    dims = scene.dims
    contact = res.pressure > 0
    n = contact.size
    data = {
        "pressure": (dims, res.pressure, {"units": pu, "long_name": "contact pressure"}),
        "displacement": (dims, res.displacement, {"units": lu, "long_name": "normal displacement of the "
                                                  "elastic surface (positive into the solid)"}),
        "gap": (dims, res.gap, {"units": lu, "long_name": "gap between the surfaces"}),
        "contact": (dims, contact, {"units": "1", "long_name": "in contact (pressure > 0)"}),
        "load": ((), res.load, load_attrs),
        "mean_pressure": ((), res.load / scene.nominal_area, {"units": pu,
                                                              "long_name": "mean pressure over the nominal area"}),
        "area_fraction": ((), np.count_nonzero(contact) / n, {"units": "1",
                                                              "long_name": "relative contact area A/A0"}),
        "contact_area": ((), np.count_nonzero(contact) * scene.pixel_area, area_attrs),
        "penetration": ((), res.penetration, {"units": lu,
                                              "long_name": "rigid-body approach from first contact"}),
        "iterations": ((), res.iterations, {"units": "1", "long_name": "Polonsky-Keer iterations"}),
        "residual": ((), res.residual, {"units": "1", "long_name": "largest contact-condition violation / "
                                        "peak-to-valley height"}),
        "converged": ((), res.converged, {"units": "1", "long_name": "solver reached tol"}),
    }
    for model in scene.models:
        data.update(model.outputs(scene, res))
    ds = xr.Dataset(data, coords=scene.coords)
    ds.attrs = {k: v for model in scene.models for k, v in model.attrs.items()}
    ds.attrs.update({
        "periodic": int(scene.periodic), "boundary": "periodic" if scene.periodic else "free",
        "solver": "Polonsky-Keer constrained CG", "tolerance": tol, "dtype": scene.dtype.name,
        "convolutions": int(res.convolutions), "exact_convolutions": int(res.exact_convolutions),
    })
    ds.attrs.update(scene.provenance)  # the measurement's file, checksum and history
    models = ", ".join(m.label for m in scene.models)
    return append_history(ds, f"xtopo.contact.solve(load={res.load:.6g}, boundary="
                              f"{'periodic' if scene.periodic else 'free'}, {models})")
