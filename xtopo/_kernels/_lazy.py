"""Deferred imports for the kernels: ``import xtopo`` stays fast (issue 26).

scipy.fft/ndimage take ~0.3 s each to import and numba ~0.4 s; the accessors import every analysis
module, so a kernel module that imports them at its top makes every ``import xtopo`` pay for them.
"""

from __future__ import annotations

import functools
import importlib

__all__ = ["Lazy", "LazyJit"]


class Lazy:
    """A module imported on first attribute access (``sfft = Lazy("scipy.fft")``)."""

    def __init__(self, name: str):
        self._name = name

    def __getattr__(self, attr):
        return getattr(importlib.import_module(self._name), attr)


class LazyJit:
    """``numba.njit`` deferred to the first call of any function it decorates in one module.

    ``njit = LazyJit(globals())`` then ``@njit(nogil=True)`` as with numba. At the first call of any
    such function (in any module) every decorated function is wrapped by numba (which compiles each on
    its own first call) and the modules' names are pointed at the dispatchers, so compiled functions
    that call each other, within a module or across, see dispatchers.
    """

    _instances: list = []

    def __init__(self, namespace: dict):
        self._namespace = namespace
        self._pending: dict = {}
        LazyJit._instances.append(self)

    def __call__(self, **options):
        def decorate(func):
            self._pending[func.__name__] = (func, options)

            @functools.wraps(func)
            def first_call(*args, **kwargs):
                for instance in LazyJit._instances:
                    instance._compile()
                return self._namespace[func.__name__](*args, **kwargs)

            return first_call

        return decorate

    def _compile(self):
        if not self._pending:
            return
        from numba import njit

        for name, (func, options) in list(self._pending.items()):
            self._namespace[name] = njit(**options)(func)
        self._pending.clear()
