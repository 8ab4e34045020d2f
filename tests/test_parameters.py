"""Generated from the declarations (issue 25): every public entry point × every bad value of each parameter
kind it declares → an :class:`~xtopo.XtopoError` (or the declared subclass) that names the parameter.

One item per entry point (the values loop inside). The per-function rejection tests this replaces
asserted the same thing by hand; message tests remain only where a message carries advice.
"""

from __future__ import annotations

import importlib
import inspect
import math
import os
import pkgutil

import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo import params
from xtopo.errors import XtopoError
from xtopo.datasets import Shape
from xtopo.filtration import Cutoff, Form


def _import_all():
    for info in pkgutil.walk_packages(xtopo.__path__, "xtopo."):
        if not info.name.endswith("__main__"):
            importlib.import_module(info.name)
    return sorted({f for f in params.DECLARED if f.__module__.startswith("xtopo.")},
                  key=lambda f: (f.__module__, f.__qualname__))


ENTRY_POINTS = _import_all()


def bad_values(kind) -> list:
    """Values each kind must refuse (None too, unless the kind takes it or the default is None)."""
    t = type(kind)
    if t is params.Count:
        return [kind.min - 1, 2.5, "3", True] + ([] if kind.max is None else [kind.max + 1])
    if t is params.Positive:
        return [0, -1.0, math.nan, "1", True] + ([] if kind.infinite else [math.inf])
    if t is params.Real:
        return ([math.nan, math.inf, "1", True] + [kind.low - 1] * math.isfinite(kind.low)
                + [kind.high + 1] * math.isfinite(kind.high))
    if t is params.Interval:
        return [(2.0 + kind.low, 1.0 + kind.low), (kind.low - 1, kind.low + 1), "ab", 3.0]
    if t in (params.Numbers, params.Lengths):
        return (["1", [1.0, math.nan], [[1.0]], [True]] + [[]] * (not kind.empty)
                + [kind.low - 1] * math.isfinite(kind.low) + [kind.high + 1] * math.isfinite(kind.high)
                + [0.0] * (t is params.Lengths))
    return {params.Flag: ["yes", 2, 0.5], params.Choice: ["no-such-option", 3.5, True], params.Text: [3, ["a"]],
            params.Dict: [3, ["a"], "a"], params.LengthUnit: ["s", 5], params.Path: [3, ""],
            params.Data: [np.zeros(3), "data"], Cutoff: ["0.8 s", "-1 mm", "short", 0.0, True],
            params.Names: ["nope", ["psd", "nope"], 3], Form: ["cubic", 9, 1.0, True], Shape: [0, 4.5, "8", (2, 3, 4), (), (4, 0), True, 10**30]}[t]


def good_value(kind):
    """One value of each kind (the other required arguments of a call get one)."""
    t = type(kind)
    if t in (params.Numbers, params.Lengths, params.Interval, params.Real):
        lo = max(kind.low, -1.0)
        return [lo + 0.5] if t in (params.Numbers, params.Lengths) else (lo, lo + 1) if t is params.Interval else (
            lo + 0.5 if lo + 0.5 <= kind.high else kind.low)
    if t is params.Data:
        da = xr.DataArray(np.zeros(4), dims="x", coords={"x": np.arange(4.0)}, name="height")
        return {"DataArray": da, "Dataset": da.to_dataset(), "DataTree": xr.DataTree(da.to_dataset())}[kind.types[0]]
    return {params.Count: getattr(kind, "min", 1) + 2, params.Choice: getattr(kind, "options", ("",))[0],
            params.Names: getattr(kind, "options", ())[:1],
            params.Flag: True, params.Positive: 0.5, params.Text: "a", params.Dict: {}, params.LengthUnit: "um",
            params.Path: os.path.join(os.sep, "nonexistent-xtopo-path"), Cutoff: "0.8 mm", Form: "line",
            Shape: 4}[t]


def _required(func, decl: dict) -> dict:
    """Arguments a call needs besides the one under test: a good value if declared, else a placeholder
    (the declarations are checked before the body runs), and the first of each OneOf rule."""
    out = {}
    for name, p in inspect.signature(func).parameters.items():
        if p.default is p.empty and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            out[name] = good_value(decl[name]) if name in decl else object()
    for rule in func.__xtopo_params__.rules:
        out[rule.names[0]] = _given(decl, rule.names[0])
    return out


def _given(decl: dict, name: str):
    """A value for a member of a OneOf rule (undeclared members take any value that is not None)."""
    return good_value(decl[name]) if name in decl else object()


def test_the_entry_points_declare_their_parameters():
    names = {f"{f.__module__}.{f.__qualname__}" for f in ENTRY_POINTS}
    assert len(ENTRY_POINTS) >= 40, sorted(names)
    assert {"xtopo.analysis.psd.psd", "xtopo.filtration.filter", "xtopo.stitching.twin_psd"} <= names


@pytest.mark.parametrize("func", ENTRY_POINTS, ids=lambda f: f"{f.__module__}.{f.__qualname__}")
def test_every_bad_value_of_a_declared_parameter_is_refused_naming_it(func):
    decl = params.declarations(func)
    defaults = {n: p.default for n, p in inspect.signature(func).parameters.items()}
    base = _required(func, decl)
    refused = 0
    for name, kind in decl.items():
        rule = next((r for r in func.__xtopo_params__.rules if name in r.names), None)
        call = {k: v for k, v in base.items() if rule is None or k not in rule.names}
        nones = [] if kind.takes_none or defaults[name] is None else [None]
        for bad in bad_values(kind) + nones:
            with pytest.raises(XtopoError) as info:
                func(**{**call, name: bad})
            assert name in str(info.value), (name, bad, str(info.value))
            assert kind.error is None or isinstance(info.value, kind.error)
            refused += 1
        # the good value passes the declarations (preflight: the call itself is not made)
        params.preflight(func, {name: good_value(kind)}, rules=False) if defaults[name] is not inspect.Parameter.empty \
            else None
    assert refused or not decl


@pytest.mark.parametrize("func", [f for f in ENTRY_POINTS if f.__xtopo_params__.rules],
                         ids=lambda f: f"{f.__module__}.{f.__qualname__}")
def test_one_of_rules_refuse_none_and_two(func):
    decl = params.declarations(func)
    for rule in func.__xtopo_params__.rules:
        call = {k: v for k, v in _required(func, decl).items() if k not in rule.names}
        for given in ((), rule.names[:2])[rule.optional:]:
            with pytest.raises(XtopoError, match="one of " + rule.names[0]):
                func(**call, **{n: _given(decl, n) for n in given})
