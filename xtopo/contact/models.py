"""What a contact scene models (DESIGN.md §5): the elastic half-space, and what bounds its pressures.

A :class:`~xtopo.contact.Scene` holds a tuple of :class:`Model` s, the :class:`ElasticHalfSpace` first;
:func:`~xtopo.contact.solve.run_solver` and ``to_dataset`` compose them. A new model (adhesion, say) is
one subclass here that overrides what it contributes, plus its projection of the pressures in
:mod:`xtopo._kernels.pk_solver`.
"""

from __future__ import annotations

import numpy as np

from ..errors import ContactError
from ..params import Positive

__all__ = ["Model", "ElasticHalfSpace", "PlasticCap", "scene_models"]

_POSITIVE = Positive(error=ContactError)


class Model:
    """One thing a :class:`~xtopo.contact.Scene` models. :attr:`attrs` are its parameters (shown in a
    result's attributes, history lines and repr); each method is what it contributes (default nothing)."""

    attrs: dict = {}

    def kernel_arguments(self, scene, exponent: int) -> dict:
        """Keywords of :func:`~xtopo._kernels.pk_solver.polonsky_keer`, pressures × ``2**exponent``."""
        return {}

    def check_control(self, name: str, value: float, label: str, scene=None) -> None:
        """Raise a :class:`~xtopo.errors.ContactError` where control ``name`` = ``value`` (called ``label``)
        cannot be reached; without a ``scene``, as far as is known before the grid."""

    def outputs(self, scene, res) -> dict:
        """Variables added to a result: ``{name: (dims, values, attrs with units and long_name)}``."""
        return {}

    def describe(self, scene) -> str:
        """The model's line in the scene's repr."""
        return repr(self)

    @property
    def label(self) -> str:
        """The parameters in one phrase (``"hardness=0.1"``), for history lines."""
        return ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in self.attrs.items())

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.label})"


class ElasticHalfSpace(Model):
    """A linear elastic half-space (paper §5.1): Green's function eq. (17) for periodic scenes, the Love
    rectangle eq. (19) on a padded grid for free boundaries, plane strain for line scans.

    Parameters
    ----------
    modulus : float
        Contact modulus ``E*``; pressures and loads are in its units.
    modulus_units : str, optional
        Units label of ``modulus``; default ``"E*"`` for the modulus 1, else ``"Pa"``.
    """

    def __init__(self, modulus: float = 1.0, modulus_units: str | None = None):
        self.modulus = _POSITIVE.check(modulus, "modulus")
        if modulus_units is not None and not (isinstance(modulus_units, str) and modulus_units.strip()):
            raise ContactError(f"modulus_units must be a units label such as 'GPa' or 'E*', got {modulus_units!r}")
        # a modulus without units is a physical one in Pa (SI, as the lengths read from files); only the
        # default modulus 1 makes pressures relative to E*
        self.units = modulus_units.strip() if modulus_units is not None else ("E*" if self.modulus == 1.0 else "Pa")
        self.attrs = {"modulus": self.modulus, "modulus_units": self.units}

    def kernel_arguments(self, scene, exponent):
        return {"conv": scene.convolution}

    def operator(self, scene):
        """The operator ``u = G * p`` of ``scene``'s grid and boundary (:attr:`Scene.convolution` keeps it)."""
        from .._kernels.convolution import Convolution  # deferred on purpose: numba and scipy.fft (startup time)

        return Convolution(scene.shape, scene.spacing, self.modulus, periodic=scene.periodic, dtype=scene.dtype,
                           backend=scene.backend)

    def check_control(self, name, value, label, scene=None):
        if name != "penetration" or scene is None or not scene.periodic or scene.hardness is not None:
            return
        # 0.0 - : a flat surface's is 0, not -0; scene.w is in units of 2**height_exponent
        limit = 0.0 - float(np.ldexp(np.mean(scene.w, dtype=np.float64), scene.height_exponent))
        if value >= limit:
            raise ContactError(
                f"penetration {value:g} reaches the mean plane of the periodic surface (its highest point is "
                f"{limit:g} above the mean): a periodic elastic solid is pushed there only by an infinite "
                "pressure; prescribe load= or mean_pressure= instead")

    def describe(self, scene):
        grid = "×".join(str(n) for n in scene.shape)
        if scene.periodic:
            green = f"periodic Green's function 2/(E*|q|) (eq. 17) on the native {grid} grid, no padding"
        else:
            pgrid = "×".join(str(n) for n in scene.fft_shape)
            kernel = "plane-strain strip kernel" if scene.line else "Love rectangle (eq. 19)"
            green = f"free boundaries: {kernel} on a {pgrid} padded grid (Hockney), padding hidden"
        return f"elasticity: E* = {self.modulus:g} {self.units}; {green}"


class PlasticCap(Model):
    """Perfectly plastic flow: no pressure exceeds the indentation hardness ``p_y`` (paper §5.4).

    Parameters
    ----------
    hardness : float
        ``p_y``, in the units of the modulus.
    """

    def __init__(self, hardness: float):
        self.hardness = _POSITIVE.check(hardness, "hardness")
        self.attrs = {"hardness": self.hardness}

    def kernel_arguments(self, scene, exponent):
        return {"hardness": float(np.ldexp(np.float64(self.hardness), exponent))}

    def check_control(self, name, value, label, scene=None):
        h = self.hardness
        if name == "mean_pressure" and value >= h:
            raise ContactError(f"{label} {value:g} reaches the hardness ({h:g}): the whole surface would flow; "
                               "lower the mean pressure or raise the hardness")
        if scene is not None and name != "penetration":
            load = value * scene.nominal_area if name == "mean_pressure" else value
            if load >= h * scene.nominal_area:
                raise ContactError(f"load {load:g} exceeds hardness × nominal area ({h * scene.nominal_area:g}): "
                                   "the whole surface would flow; lower the load or raise the hardness")

    def outputs(self, scene, res):
        return {"plastic": (scene.dims, res.plastic, {"units": "1", "long_name": "pressure at the hardness (flowing)"})}

    def describe(self, scene):
        return f"plasticity: pressure capped at hardness {self.hardness:g} {scene.modulus_units}"


def scene_models(modulus: float = 1.0, hardness: float | None = None, modulus_units: str | None = None,
                 models=()) -> tuple:
    """The models of a scene: an :class:`ElasticHalfSpace` of ``modulus``, a :class:`PlasticCap` where a
    ``hardness`` is given, then ``models`` (each a :class:`Model`, one of each kind)."""
    models = (ElasticHalfSpace(modulus, modulus_units), *(() if hardness is None else (PlasticCap(hardness),)),
              *models)
    kinds = [type(m) for m in models]
    if not all(isinstance(m, Model) for m in models) or len(set(kinds)) != len(kinds):
        raise ContactError(f"models must be contact models (xtopo.contact.models), one of each kind beyond the "
                           f"elastic half-space (modulus=) and the plastic cap (hardness=); got {models!r}")
    return models
