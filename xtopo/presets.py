"""Speed-versus-accuracy presets: one name for a set of solver knobs (issue 9).

``preset="fast" | "default" | "accurate"`` on :class:`xtopo.contact.Scene`,
:meth:`~xtopo.contact.Scene.solve`, :meth:`~xtopo.contact.Scene.curve` and
:func:`xtopo.contact.contact` picks the knob values of :data:`PRESETS`; a keyword given
explicitly (``tol=``, ``maxiter=``, ``dtype=``) always wins over the preset.

The values sit at the knees of the error-vs-time curves measured by
``benchmarks/tradeoffs.py`` (``docs/tradeoffs.md`` shows the figure and the measured
error and time of each preset).  The analyses (PSD, SDRP) have no preset: their
defaults (10 log bins per decade, Hann window for nonperiodic data) are already the
most accurate choice and changing them saves no time.
"""

from __future__ import annotations

from types import MappingProxyType

from .errors import XtopoError

__all__ = ["PRESETS", "NAMES", "resolve"]

#: Knob values of each preset, per family of functions.
#:
#: ``contact`` (Scene, solve, curve, contact):
#:   ``dtype``  floating point type of the solver;
#:   ``tol``    largest contact-condition violation / peak-to-valley height
#:              (``None``: :func:`xtopo.contact.solve.default_tol` of the dtype);
#:   ``maxiter`` iteration limit (a cap: it costs nothing when the solver converges sooner).
PRESETS = MappingProxyType({
    "contact": MappingProxyType({
        "fast": MappingProxyType({"dtype": "float32", "tol": 1e-4, "maxiter": 500}),
        "default": MappingProxyType({"dtype": "float64", "tol": None, "maxiter": 1000}),
        "accurate": MappingProxyType({"dtype": "float64", "tol": 1e-8, "maxiter": 10000}),
    }),
})

#: Preset names, fastest first.
NAMES = ("fast", "default", "accurate")


def resolve(family: str, preset: str | None = None, **explicit) -> dict:
    """Knob values of ``preset`` for ``family``, with explicitly given keywords winning.

    Parameters
    ----------
    family : str
        Key of :data:`PRESETS` (e.g. ``"contact"``).
    preset : {"fast", "default", "accurate"} or None
        ``None`` means ``"default"``.
    **explicit
        Knob values the caller gave; ``None`` means "not given" (take the preset's).

    Returns
    -------
    dict
        Every knob of the family; keys the caller named but the family lacks are an error.
    """
    if not isinstance(family, str) or family not in PRESETS:  # (a list would raise TypeError: unhashable)
        raise XtopoError(f"no presets for {family!r}; families: {sorted(PRESETS)}")
    name = "default" if preset is None else preset
    table = PRESETS[family]
    if not isinstance(name, str) or name not in table:
        raise XtopoError(f"preset must be one of {NAMES} (or None for 'default'), got {preset!r}")
    values = dict(table[name])
    unknown = set(explicit) - set(values)
    if unknown:
        raise XtopoError(f"preset family {family!r} has no knob(s) {sorted(unknown)}; knobs: {sorted(values)}")
    values.update({k: v for k, v in explicit.items() if v is not None})
    return values
