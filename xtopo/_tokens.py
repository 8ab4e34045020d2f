"""Content tokens of callables, for the keys of cached results (:mod:`xtopo.cache`, the batch store).

dask's ``tokenize`` keys a function that pickles by reference — one defined at the top level of an
importable module, or a method of such a class — by its qualified name only. Editing the
function's body and running again (a reload, a new process) would then find the results of the
old code. The bytecode, constants and names of every Python function in the callable (a
``functools.partial``'s function, a bound method's function, nested functions) enter the token
too; functions that the callable calls do not.
"""

from __future__ import annotations

import functools
import sys
import types
import weakref

from ._optional import require

__all__ = ["callable_token"]


def _code_print(code: types.CodeType) -> tuple:
    """What the code does: bytecode, constants (nested code objects recursively) and names."""
    consts = tuple(_code_print(c) if isinstance(c, types.CodeType) else c for c in code.co_consts)
    return code.co_code, consts, code.co_names


def _codes(func, depth: int = 0) -> list:
    """Code prints of the Python functions inside ``func`` (partials and bound methods unwrapped)."""
    if depth > 32:  # a partial of a partial of ...: deep enough
        return []
    if isinstance(func, functools.partial):
        return _codes(func.func, depth + 1)
    inner = getattr(func, "__func__", None)  # a bound method
    if inner is not None:
        return _codes(inner, depth + 1)
    code = getattr(func, "__code__", None)
    if isinstance(code, types.CodeType):
        return [_code_print(code)]
    call = getattr(type(func), "__call__", None)  # an instance of a class with __call__
    code = getattr(call, "__code__", None)
    return [_code_print(code)] if isinstance(code, types.CodeType) else []


#: module-level functions -> (their code object, token): a cache hit's key costs a dict look-up instead
#: of a tokenize (0.2 ms). Only functions that pickle by reference (dask tokenizes them by name): the
#: token of any other (a lambda, a closure) may depend on values it captures, which can change.
_memo: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _by_reference(func) -> bool:
    """True for a function found under its own name in its (imported) module."""
    obj = sys.modules.get(getattr(func, "__module__", None) or "")
    for part in func.__qualname__.split("."):
        obj = getattr(obj, part, None)
    return obj is func


def callable_token(func) -> str:
    """A token of ``func`` by content: dask's ``tokenize`` plus the code of its Python functions."""
    tokenize = require("dask.base", "a token of a function (the result cache, batch stores)").tokenize  # [dask]

    if type(func) is not types.FunctionType or not _by_reference(func):
        return tokenize(func, _codes(func))
    hit = _memo.get(func)
    if hit is not None and hit[0] is func.__code__:
        return hit[1]
    token = tokenize(func, _codes(func))
    _memo[func] = (func.__code__, token)
    return token
