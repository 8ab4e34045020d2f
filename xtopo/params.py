"""Declared parameters: the kinds of argument a public entry point takes, checked once by one decorator.

A public function declares each argument it checks in its type hint, ``typing.Annotated[<type>, <kind>]``::

    @checked
    def psd(obj, kind: Annotated[str, Choice("1d", "2d", "iso")] = "1d", *,
            nb_points: Annotated[int | None, Count()] = None, equivalent_1d: Annotated[bool, Flag()] = False):

:func:`checked` reads those declarations once (when first called) and, on every call, checks and
normalises each argument the caller gave (``nb_points=np.int64(3)`` arrives as ``3``); a bad one is an
:class:`~xtopo.errors.XtopoError` (or the subclass the kind or the decorator names) that names the
parameter, says what it got and what it expects. Defaults are not checked; a parameter whose default is
``None`` accepts ``None``. :class:`OneOf` declares "exactly one of these keyword arguments".
:func:`preflight` checks a call's keyword arguments without making it (the CLI and batch check options
given once for many files before any work starts). Private helpers trust their callers.

Data-dependent limits (a length no longer than the measurement, a bin count against the values binned)
stay in the function body, next to the data they depend on. Modelled on xclim's ``declare_units`` and
xarray's ``detect_parameters`` (parameters read from the signature, not re-listed).
"""

from __future__ import annotations

import functools
import inspect
import math
import numbers
import os
import typing
from collections.abc import Mapping

import numpy as np

from .errors import UnitsError, XtopoError

__all__ = ["Kind", "Flag", "Count", "Positive", "Real", "Choice", "Text", "Dict", "Lengths", "LengthUnit", "Path",
           "Data", "OneOf", "checked", "preflight", "declarations", "DECLARED"]

#: every function decorated with :func:`checked`, in the order they were defined (the generated test loops over it).
DECLARED: list = []


class _Refused(Exception):
    """Raised by :meth:`Kind.convert`; ``message`` replaces the standard "must be ..., got ..." one."""

    def __init__(self, message: str | None = None):
        super().__init__(message)
        self.message = message


class Kind:
    """A kind of parameter: :meth:`convert` returns the value normalised or raises :class:`_Refused`.

    ``expects`` completes "<name> must be ..."; ``error`` (optional) is the XtopoError subclass raised;
    ``takes_none``: ``None`` is a value of this kind (not only where the default is ``None``).
    """

    expects = "valid"
    error: type[XtopoError] | None = None
    takes_none = False

    def __init__(self, *, error: type[XtopoError] | None = None):
        if error is not None:
            self.error = error

    def convert(self, value):
        return value

    def check(self, value, name: str, error: type[XtopoError] = XtopoError):
        """``value`` normalised, or the error naming ``name``."""
        try:
            return self.convert(value)
        except _Refused as exc:
            message = exc.message or f"{name} must be {self.expects}, got {_shown(value)}"
            raise (self.error or error)(message.replace("{name}", name)) from None

    def bad(self) -> list:
        """Values of the wrong kind (the generated test calls every entry point with each)."""
        return ["not-a-value", object()]

    def good(self):
        """One value of this kind."""
        raise NotImplementedError

    def __repr__(self):
        return f"{type(self).__name__}()"


def _shown(value) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _real(value) -> float | None:
    """``value`` as a float if it is a real number (not a bool; a 0-d array counts), else None.

    ``float()``, not ``np.isfinite``, decides: an int beyond float64 (``10**400``) is None, not a TypeError.
    """
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    if not isinstance(value, numbers.Real) or isinstance(value, (bool, np.bool_)):
        return None
    try:
        return float(value)
    except OverflowError:
        return None


class Flag(Kind):
    """True or False (numpy's bool and the integers 0 and 1 too; not a string, not None) → bool."""

    expects = "True or False"

    def convert(self, value):
        if isinstance(value, (bool, np.bool_)) or (isinstance(value, numbers.Integral) and value in (0, 1)):
            return bool(value)
        raise _Refused

    def bad(self):
        return ["yes", 2, 0.5]

    def good(self):
        return True


class Count(Kind):
    """An integer (not a bool, not a float) of at least ``min`` → int."""

    def __init__(self, min: int = 1, *, error=None):  # noqa: A002 - the declaration reads Count(min=0)
        super().__init__(error=error)
        self.min = min
        self.expects = f"an integer >= {min}"

    def convert(self, value):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) or value < self.min:
            raise _Refused
        return int(value)

    def bad(self):
        return [self.min - 1, 2.5, "3", True]

    def good(self):
        return self.min + 2

    def __repr__(self):
        return f"Count(min={self.min})"


class Positive(Kind):
    """A real number above 0, finite unless ``infinite`` (a 0-d array counts) → float."""

    def __init__(self, *, infinite: bool = False, error=None):
        super().__init__(error=error)
        self.infinite = infinite
        self.expects = f"a positive {'' if infinite else 'finite '}number"

    def convert(self, value):
        number = _real(value)
        if number is None or not number > 0 or not (self.infinite or math.isfinite(number)):
            raise _Refused
        return number

    def bad(self):
        return [0, -1.0, math.nan, "1", True] + ([] if self.infinite else [math.inf])

    def good(self):
        return 0.5


class Real(Kind):
    """A finite real number in ``[low, high]`` (``(low, high)`` unless ``closed``) → float."""

    def __init__(self, low: float = -math.inf, high: float = math.inf, *, closed: bool = True, error=None):
        super().__init__(error=error)
        self.low, self.high, self.closed = low, high, closed
        if (low, high) == (-math.inf, math.inf):
            bounds = ""
        elif high == math.inf:
            bounds = f" {'>=' if closed else '>'} {low:g}"
        else:
            bounds = f" in [{low:g}, {high:g}]" if closed else f" in ({low:g}, {high:g})"
        self.expects = f"a finite number{bounds}"

    def convert(self, value):
        number = _real(value)
        lo, hi = self.low, self.high
        if (number is None or not math.isfinite(number)
                or not (lo <= number <= hi if self.closed else lo < number < hi)):
            raise _Refused
        return number

    def bad(self):
        out = [math.nan, math.inf, "1", True]
        if self.low > -math.inf:
            out.append(self.low - 1)
        if self.high < math.inf:
            out.append(self.high + 1)
        return out

    def good(self):
        if math.isfinite(self.low) and math.isfinite(self.high):
            return (self.low + self.high) / 2
        return self.low + 1 if math.isfinite(self.low) else min(self.high - 1, 0.0)


class Choice(Kind):
    """One of ``options`` (strings, or None/False where those mean "none")."""

    def __init__(self, *options, error=None):
        super().__init__(error=error)
        self.options = options
        self.takes_none = None in options
        self.expects = f"one of {options}"

    def convert(self, value):
        for option in self.options:  # `is` for None/False: 0 is not False, nor an array compared elementwise
            if value is option or (isinstance(value, str) and value == option):
                return value
        raise _Refused

    def bad(self):
        return ["no-such-option", 3]

    def good(self):
        return self.options[0]

    def __repr__(self):
        return f"Choice{self.options}"


class Text(Kind):
    """A string: a title, a label, a variable name."""

    expects = "a string"

    def convert(self, value):
        if not isinstance(value, str):
            raise _Refused
        return value

    def bad(self):
        return [3, ["a"]]

    def good(self):
        return "a"


class Dict(Kind):
    """A mapping (not an xarray Dataset) → dict, e.g. legend labels by name."""

    expects = "a dict"

    def convert(self, value):
        import xarray as xr

        if not isinstance(value, Mapping) or isinstance(value, (xr.Dataset, xr.DataTree)):
            raise _Refused
        return dict(value)

    def bad(self):
        return [3, ["a"], "a"]

    def good(self):
        return {}


class Lengths(Kind):
    """A number or a 1D sequence of positive finite numbers (lengths, or wavevectors) → 1D float array.

    A bound from the data (no longer than the measurement) is checked where the data is.
    """

    expects = "a number or a 1D sequence of numbers (positive finite lengths)"

    def convert(self, values):
        v = None
        if not isinstance(values, (str, bytes)):
            try:
                raw = np.asarray(values)
                if raw.dtype.kind not in "bcSUO":  # True is not the length 1, nor "1" a number
                    v = np.atleast_1d(np.asarray(raw, dtype=float))
            except (TypeError, ValueError, OverflowError):
                v = None
        if v is None or v.ndim != 1 or v.size == 0:
            raise _Refused
        bad = v[~(np.isfinite(v) & (v > 0))]
        if bad.size:
            raise _Refused(f"{{name}} must be positive finite lengths, got {bad.tolist()}")
        return v

    def bad(self):
        return ["1", -1.0, [1.0, math.nan], [[1.0]], [True]]

    def good(self):
        return [0.5]


class LengthUnit(Kind):
    """A length unit such as ``"m"`` or ``"µm"`` → its UDUNITS ASCII spelling (``"um"``)."""

    expects = "a length unit"
    error = UnitsError

    def convert(self, value):
        from .conventions import normalize_units

        try:
            return normalize_units(value)
        except UnitsError as exc:
            raise _Refused(f"{{name}}={value!r:.60} is not a length unit ({exc})") from None

    def bad(self):
        return ["s", 5]

    def good(self):
        return "um"


class Path(Kind):
    """A path (str, bytes or os.PathLike, not empty: that would mean the working directory) → str."""

    def __init__(self, what: str = "path", *, error=None):
        super().__init__(error=error)
        self.what = what
        self.expects = f"a {what} (str or os.PathLike)"

    def convert(self, value):
        try:
            text = os.fsdecode(os.fspath(value))  # bytes too: a str, as the callers join it with str
        except TypeError:
            raise _Refused(f"{{name}} must be a {self.what} (str or os.PathLike), got {type(value).__name__}") from None
        if not text:
            raise _Refused(f"{{name}} must be a {self.what}, got an empty string")
        return text

    def bad(self):
        return [3, ""]

    def good(self):
        return os.path.join(os.path.abspath(os.sep), "nonexistent-xtopo-path")


class Data(Kind):
    """An xarray object of one of ``types`` (names: ``"Dataset"``, ``"DataArray"``, ``"DataTree"``)."""

    def __init__(self, *types: str, error=None):
        super().__init__(error=error)
        self.types = types or ("Dataset", "DataArray")
        self.expects = f"an xarray {' or '.join(self.types)}"

    def convert(self, value):
        import xarray as xr

        if not isinstance(value, tuple(getattr(xr, t) for t in self.types)):
            raise _Refused(f"{{name}} needs an xarray {' or '.join(self.types)}, got {type(value).__name__}")
        return value

    def bad(self):
        return [np.zeros(3), "data"]

    def good(self):
        import xarray as xr

        da = xr.DataArray(np.zeros(4), dims="x", coords={"x": np.arange(4.0)}, name="heights")
        return {"DataArray": da, "Dataset": da.to_dataset(), "DataTree": xr.DataTree(da.to_dataset())}[self.types[0]]


class OneOf:
    """A rule on a whole call: exactly one of the keyword arguments ``names`` is given (not None)."""

    def __init__(self, *names: str, error: type[XtopoError] | None = None):
        self.names, self.error = names, error

    def check(self, values: dict, error: type[XtopoError] = XtopoError) -> None:
        given = [n for n in self.names if values.get(n) is not None]
        if len(given) != 1:
            listed = ", ".join(f"{n}=" for n in self.names[:-1]) + f" or {self.names[-1]}="
            extra = f" (got {', '.join(given)})" if given else ""
            raise (self.error or error)(f"give exactly one of {listed}{extra}")

    def __repr__(self):
        return f"OneOf{self.names}"


class _Spec:
    """The declarations of one function, read from its signature and type hints on first use."""

    def __init__(self, func, rules, error):
        self.func, self.rules, self.error = func, rules, error
        self.signature = inspect.signature(func)
        self.entries = None  # (name, position or None, kind, default is None)
        names = list(self.signature.parameters)
        self.ruled = {n: names.index(n) for rule in rules for n in rule.names}

    def parse(self):
        hints = typing.get_type_hints(self.func, include_extras=True)
        entries = []
        for i, (name, p) in enumerate(self.signature.parameters.items()):
            kinds = [m for m in getattr(hints.get(name), "__metadata__", ()) if isinstance(m, Kind)]
            if kinds:
                position = i if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) else None
                entries.append((name, position, kinds[0], p.default is None))
        self.entries = tuple(entries)
        return self.entries

    def one(self, kind, value, name, none_ok):
        if value is None and (none_ok or kind.takes_none):
            return None
        return kind.check(value, name, self.error)

    def apply(self, args: tuple, kwargs: dict):
        entries = self.entries or self.parse()
        n = len(args)
        if n:
            args = list(args)
        for name, position, kind, none_ok in entries:
            if name in kwargs:
                kwargs[name] = self.one(kind, kwargs[name], name, none_ok)
            elif position is not None and position < n:
                args[position] = self.one(kind, args[position], name, none_ok)
        if self.rules:
            params = self.signature.parameters
            values = {name: kwargs[name] if name in kwargs else args[i] if i < n else params[name].default
                      for name, i in self.ruled.items()}
            for rule in self.rules:
                rule.check(values, self.error)
        return args, kwargs


def checked(*rules, error: type[XtopoError] = XtopoError):
    """Decorator: check and normalise the arguments a function declares (see the module docstring).

    ``rules``: :class:`OneOf` declarations on the whole call; ``error``: the XtopoError subclass raised
    for every parameter whose kind names none. ``@checked`` without arguments works too.
    """
    if len(rules) == 1 and callable(rules[0]) and not isinstance(rules[0], OneOf):
        return checked()(rules[0])

    def decorate(func):
        spec = _Spec(func, rules, error)

        @functools.wraps(func)
        def wrapper(*args, **kwargs):
            args, kwargs = spec.apply(args, kwargs)
            return func(*args, **kwargs)

        wrapper.__xtopo_params__ = spec
        DECLARED.append(wrapper)
        return wrapper

    return decorate


def declarations(func) -> dict:
    """``{name: kind}`` of the parameters ``func`` declares (empty if it declares none)."""
    spec = getattr(func, "__xtopo_params__", None)
    if spec is None:
        return {}
    return {name: kind for name, _, kind, _ in (spec.entries or spec.parse())}


def preflight(func, kwargs: Mapping, where: str | None = None, *, rules: bool = True) -> dict:
    """``kwargs`` of a call of ``func`` checked and normalised without making the call.

    For options given once for many items (a batch, a CLI run): a bad value fails before any work.
    Names ``func`` does not take are refused; ``where`` (e.g. ``"read_options"``) prefixes the
    messages. ``rules=False`` skips the :class:`OneOf` rules (an item adds the missing argument later).
    """
    spec = getattr(func, "__xtopo_params__", None)
    parameters = inspect.signature(func).parameters
    takes_any = any(p.kind is p.VAR_KEYWORD for p in parameters.values())
    unknown = [k for k in kwargs if k not in parameters and not takes_any]
    prefix = f"{where}: " if where else ""
    if unknown:
        raise XtopoError(f"{prefix}{func.__name__}() takes no option(s) {', '.join(map(repr, unknown))}; "
                         f"it takes {', '.join(parameters)}")
    out = dict(kwargs)
    if spec is None:
        return out
    try:
        for name, _, kind, none_ok in spec.entries or spec.parse():
            if name in out:
                out[name] = spec.one(kind, out[name], name, none_ok)
        if rules:
            for rule in spec.rules:
                rule.check({n: out.get(n, parameters[n].default) for n in rule.names}, spec.error)
    except XtopoError as exc:
        if where:
            raise type(exc)(f"{prefix}{exc}") from None
        raise
    return out
