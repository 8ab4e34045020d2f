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

from ._checks import real_array
from ._units import normalize_units
from .errors import UnitsError, XtopoError

__all__ = ["Kind", "Refused", "Flag", "Count", "Positive", "Real", "Interval", "Choice", "Names", "Text", "Dict", "Numbers",
           "Lengths", "LengthUnit", "Path", "Data", "OneOf", "checked", "preflight", "declarations", "DECLARED"]

#: every function decorated with :func:`checked`, in the order they were defined (the generated test loops over it).
DECLARED: list = []


class Refused(Exception):
    """Raised by :meth:`Kind.convert`; ``message`` replaces the "must be ..., got ..." one, ``error`` the class."""

    def __init__(self, message: str | None = None, error: type[XtopoError] | None = None):
        super().__init__(message)
        self.message, self.error = message, error


class Kind:
    """A kind of parameter: :meth:`convert` returns the value normalised or raises :class:`Refused`.

    ``expects`` completes "<name> must be ..."; ``error`` (optional) is the XtopoError subclass raised;
    ``takes_none`` (``optional=True``): ``None`` is a value of this kind (not only where the default is ``None``).
    """

    expects = "valid"
    error: type[XtopoError] | None = None
    takes_none = False

    def __init__(self, *, error: type[XtopoError] | None = None, optional: bool = False):
        if error is not None:
            self.error = error
        if optional:
            self.takes_none = True

    def convert(self, value):
        return value

    def check(self, value, name: str, error: type[XtopoError] = XtopoError):
        """``value`` normalised, or the error naming ``name``."""
        try:
            return self.convert(value)
        except Refused as exc:
            message = exc.message or f"{name} must be {self.expects}, got {_shown(value)}"
            raise (exc.error or self.error or error)(message.replace("{name}", name)) from None

    def __repr__(self):
        return f"{type(self).__name__}({self.expects!r})"


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
        raise Refused


class Count(Kind):
    """An integer (not a bool, not a float) of at least ``min`` (and at most ``max``) → int."""

    def __init__(self, min: int = 1, max: int | None = None, *, error=None):  # noqa: A002 - reads Count(min=0)
        super().__init__(error=error)
        self.min, self.max = min, max
        self.expects = f"an integer >= {min}" + ("" if max is None else f" and <= {max}")

    def convert(self, value):
        if (isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) or value < self.min
                or (self.max is not None and value > self.max)):
            raise Refused
        return int(value)


class Positive(Kind):
    """A real number above 0, finite unless ``infinite`` (a 0-d array counts) → float."""

    def __init__(self, *, infinite: bool = False, error=None):
        super().__init__(error=error)
        self.infinite = infinite
        self.expects = f"a positive {'' if infinite else 'finite '}number"

    def convert(self, value):
        number = _real(value)
        if number is None or not number > 0 or not (self.infinite or math.isfinite(number)):
            raise Refused
        return number


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
            raise Refused
        return number


class Interval(Kind):
    """Two real numbers ``(lo, hi)`` with ``low <= lo < hi <= high`` (``hi`` may be ``high`` = inf) → a tuple."""

    def __init__(self, low: float = 0.0, high: float = math.inf, *, what: str = "numbers", error=None):
        super().__init__(error=error)
        self.low, self.high = low, high
        self.expects = f"two {what} (lo, hi) with {low:g} <= lo < hi <= {high:g}"

    def convert(self, value):
        try:
            lo, hi = (_real(v) for v in value) if not isinstance(value, (str, bytes)) else (None, None)
        except (TypeError, ValueError):
            lo = hi = None
        if lo is None or hi is None or not (self.low <= lo < hi <= self.high) or math.isnan(hi):
            raise Refused
        return lo, hi


class Choice(Kind):
    """One of ``options`` (strings, or None/False where those mean "none")."""

    def __init__(self, *options, error=None):
        super().__init__(error=error)
        self.options = options
        self.takes_none = None in options
        self.expects = f"one of {options}"

    def convert(self, value):
        for option in self.options:  # `is` for None/False: 0 is not False, nor an array compared elementwise
            if value is option or (isinstance(value, str) and value == option) or (
                    type(option) is int and isinstance(value, numbers.Integral)
                    and not isinstance(value, (bool, np.bool_)) and value == option):
                return option
        raise Refused


class Names(Choice):
    """One of ``options`` (strings) or a sequence of them → a tuple (e.g. the analyses of a report)."""

    def __init__(self, *options, error=None):
        super().__init__(*options, error=error)
        self.expects = f"a name or a sequence of names from {options}"

    def convert(self, value):
        try:
            return tuple(map(super().convert, (value,) if isinstance(value, str) else value))
        except TypeError:
            raise Refused from None


class Text(Kind):
    """A string: a title, a label, a variable name."""

    expects = "a string"

    def convert(self, value):
        if not isinstance(value, str):
            raise Refused
        return value


class Dict(Kind):
    """A mapping (not an xarray Dataset) → dict, e.g. legend labels by name."""

    expects = "a dict"

    def convert(self, value):
        import xarray as xr

        if not isinstance(value, Mapping) or isinstance(value, (xr.Dataset, xr.DataTree)):
            raise Refused
        return dict(value)


class Numbers(Kind):
    """A number or a 1D sequence of finite real numbers in ``[low, high]`` → a float array (0-d for a number)."""

    def __init__(self, low: float = -math.inf, high: float = math.inf, *, what: str = "numbers", empty: bool = False,
                 error=None):
        super().__init__(error=error)
        self.low, self.high, self.what, self.empty = low, high, what, empty
        self.expects = f"a number or a 1D sequence of numbers ({what})"

    def convert(self, values):
        v = real_array(values)  # True is not the length 1, nor "1" a number
        if v is None or v.ndim > 1 or (v.size == 0 and not self.empty):
            raise Refused
        bad = v[~(np.isfinite(v) & (v >= self.low) & (v <= self.high))]
        if bad.size:
            raise Refused(f"{{name}} must be {self.what}, got {np.atleast_1d(bad).tolist()}")
        return v


class Lengths(Numbers):
    """A number or a 1D sequence of positive finite numbers (lengths, or wavevectors) → 1D float array.

    A bound from the data (no longer than the measurement) is checked where the data is.
    """

    def __init__(self, *, empty: bool = True, error=None):
        super().__init__(0.0, what="positive finite lengths", empty=empty, error=error)

    def convert(self, values):
        v = np.atleast_1d(super().convert(values))
        if np.any(v == 0):
            raise Refused(f"{{name}} must be positive finite lengths, got {v[v == 0].tolist()}")
        return v


class LengthUnit(Kind):
    """A length unit such as ``"m"`` or ``"µm"`` → its UDUNITS ASCII spelling (``"um"``); ``optional``: None too."""

    expects = "a length unit"
    error = UnitsError

    def convert(self, value):
        try:
            return normalize_units(value)
        except UnitsError as exc:
            raise Refused(f"{{name}}={value!r:.60} is not a length unit ({exc})") from None


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
            raise Refused(f"{{name}} must be a {self.what} (str or os.PathLike), got {type(value).__name__}") from None
        if not text:
            raise Refused(f"{{name}} must be a {self.what}, got an empty string")
        return text


class Data(Kind):
    """An xarray object of one of ``types`` (names: ``"Dataset"``, ``"DataArray"``, ``"DataTree"``)."""

    def __init__(self, *types: str, error=None):
        super().__init__(error=error)
        self.types = types or ("Dataset", "DataArray")
        self.expects = f"an xarray {' or '.join(self.types)}"

    def convert(self, value):
        import xarray as xr

        if not isinstance(value, tuple(getattr(xr, t) for t in self.types)):
            raise Refused(f"{{name}} needs an xarray {' or '.join(self.types)}, got {type(value).__name__}")
        return value


class OneOf:
    """A rule on a whole call: exactly one (``optional``: at most one) of the arguments ``names`` is not None."""

    def __init__(self, *names: str, optional: bool = False, error: type[XtopoError] | None = None):
        self.names, self.optional, self.error = names, optional, error

    def check(self, values: dict, error: type[XtopoError] = XtopoError) -> None:
        given = [n for n in self.names if values.get(n) is not None]
        if len(given) > 1 or not (given or self.optional):
            listed = ", ".join(f"{n}=" for n in self.names[:-1]) + f" or {self.names[-1]}="
            extra = f" (got {', '.join(given)})" if given else ""
            raise (self.error or error)(f"give {'at most' if self.optional else 'exactly'} one of {listed}{extra}")

    def given(self, values: Mapping) -> tuple[str, object]:
        """``(name, value)`` of the one argument given (the call checked by :func:`checked` first)."""
        return next((n, values[n]) for n in self.names if values.get(n) is not None)


class _Spec:
    """The declarations of one function, read from its signature and type hints when it is decorated (on its
    first call where a hint names what is defined later in its module)."""

    def __init__(self, func, rules, error):
        self.func, self.rules, self.error = func, rules, error
        self.signature = inspect.signature(func)
        self.entries = None  # (name, position or None, kind, default is None)
        names = list(self.signature.parameters)
        self.ruled = {n: names.index(n) for rule in rules for n in rule.names}
        try:
            self.parse()
        except NameError:
            pass

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

    def apply(self, args: tuple, kwargs: dict, rules: bool = True):
        entries = self.entries or self.parse()
        n = len(args)
        if n:
            args = list(args)
        for name, position, kind, none_ok in entries:
            if name in kwargs:
                kwargs[name] = self.one(kind, kwargs[name], name, none_ok)
            elif position is not None and position < n:
                args[position] = self.one(kind, args[position], name, none_ok)
        if rules and self.rules:
            params = self.signature.parameters
            values = {name: kwargs[name] if name in kwargs else args[i] if i < n else params[name].default
                      for name, i in self.ruled.items()}
            for rule in self.rules:
                rule.check(values, self.error)
        return args, kwargs


def checked(*rules, error: type[XtopoError] = XtopoError):
    """Decorator: check and normalise the arguments a function declares (see the module docstring).

    ``rules``: :class:`OneOf` declarations on the whole call; ``error``: the XtopoError subclass raised
    for every parameter whose kind names none. ``@checked`` without arguments works too. On a dataclass
    the fields are the declarations, and its ``__post_init__`` checks them with :func:`preflight`.
    """
    if len(rules) == 1 and callable(rules[0]) and not isinstance(rules[0], OneOf):
        return checked()(rules[0])

    def decorate(func):
        spec = _Spec(func, rules, error)
        if isinstance(func, type):
            func.__xtopo_params__ = spec
            DECLARED.append(func)
            return func

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
    Names that are not options of ``func`` are refused: names it does not take, and its positional
    parameters without a default (the data each item brings; a dataclass's fields are all options).
    ``where`` (e.g. ``"read_options"``) prefixes the messages. ``rules=False`` skips the :class:`OneOf`
    rules (an item adds the missing argument later).
    """
    spec = getattr(func, "__xtopo_params__", None)
    parameters = inspect.signature(func).parameters
    options = [n for n, p in parameters.items()  # not the data, nor **kwargs
               if p.default is not p.empty or p.kind is p.KEYWORD_ONLY or isinstance(func, type)]
    takes_any = any(p.kind is p.VAR_KEYWORD for p in parameters.values())
    unknown = [k for k in kwargs if k not in options and (k in parameters or not takes_any)]
    if unknown:
        raise XtopoError(f"{where + ' ' if where else ''}has no option {', '.join(map(repr, unknown))}; its options: "
                         f"{', '.join(options) or 'none'}")
    if spec is None:
        return dict(kwargs)
    try:
        return spec.apply((), dict(kwargs), rules)[1]
    except XtopoError as exc:
        if where:
            raise type(exc)(f"{where}: {exc}") from None
        raise
