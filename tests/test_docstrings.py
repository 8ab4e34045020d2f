"""The numpydoc ``Parameters`` sections of the public API agree with the signatures.

Checked strictly (a Parameters section is required, here or in the function a one-line
docstring defers to with "see :func:`...`"): the functions and classes of ``xtopo.__all__``,
every ``.topo`` accessor method (Dataset, DataArray and DataTree) and
:class:`xtopo.contact.Scene` with ``solve`` and ``curve``. Checked where a Parameters section
exists: everything else listed in the ``__all__`` of xtopo's public modules.

For each documented callable: the documented names are exactly the signature's (``**kwargs``
as ``**kwargs``); a parameter typed ``optional`` has a default; a literal default that the
description states ("default 10", "default ``"auto"``") is the signature's.
"""

from __future__ import annotations

import importlib
import inspect
import re

import pytest

import xtopo
from xtopo import accessors
from xtopo.contact import Scene

SECTION = re.compile(r"^(?:Parameters|Other Parameters)\n-+\n(.*?)(?=^\S[^\n]*\n-{3,}\n|\Z)", re.S | re.M)
SEE = re.compile(r"see :(?:func|meth):`~?([\w.]+)`")

#: modules whose ``__all__`` is checked where documented
MODULES = ["xtopo.filtration", "xtopo.analysis.iso21920",
           "xtopo.conventions", "xtopo.datasets", "xtopo.io", "xtopo.preprocess", "xtopo.batch", "xtopo.cache",
           "xtopo.twins", "xtopo.stitching", "xtopo.contact", "xtopo.plot", "xtopo.presets",
           "xtopo.analysis.scalars", "xtopo.analysis.distribution", "xtopo.analysis.psd", "xtopo.analysis.acf",
           "xtopo.analysis.vbm", "xtopo.analysis.sdrp", "xtopo.analysis.hurst", "xtopo.analysis.reliability",
           "xtopo.analysis.iso25178"]


def parameters_section(doc: str | None) -> dict[str, tuple[str, str, bool]] | None:
    """``{name: (type, description, combined)}`` of the Parameters sections of ``doc`` (None: no section);
    ``combined``: documented in one entry with others (``x, y : str``)."""
    doc = inspect.cleandoc(doc or "")
    sections = SECTION.findall(doc)
    if not sections:
        return None
    out, current = {}, []
    for body in sections:
        for line in body.splitlines():
            if line and not line[0].isspace():
                head, _, kind = line.partition(" : ")
                current = [n.strip() for n in head.split(",") if n.strip()]
                for n in current:
                    out[n] = (kind.strip(), "", len(current) > 1)
            elif current and line.strip():
                for n in current:
                    kind, text, combined = out[n]
                    out[n] = (kind, f"{text} {line.strip()}".strip(), combined)
    return out


def _resolve(path: str):
    module, _, name = path.rpartition(".")
    while module:
        try:
            obj = importlib.import_module(module)
        except ImportError:
            module, _, outer = module.rpartition(".")
            name = f"{outer}.{name}"
            continue
        for part in name.split("."):
            obj = getattr(obj, part)
        return obj
    raise LookupError(path)


def documented(obj) -> dict | None:
    """The Parameters of ``obj``'s docstring, or of the function a short docstring defers to."""
    params = parameters_section(obj.__doc__)
    if params is None and obj.__doc__ and "\n\n" not in obj.__doc__.strip():
        m = SEE.search(obj.__doc__)
        if m:  # a method deferring to a function of its object (Scene.solve → solve(scene, ...))
            target = parameters_section(_resolve(m.group(1)).__doc__)
            if target and inspect.isfunction(obj) and "." in obj.__qualname__:
                target = dict(list(target.items())[1:])
            return target
    return params


def signature_parameters(obj) -> list[inspect.Parameter]:
    sig = inspect.signature(obj.__init__ if inspect.isclass(obj) else obj)
    params = list(sig.parameters.values())
    if params and params[0].name in ("self", "cls"):
        params = params[1:]
    return params


def strict_items():
    for name in xtopo.__all__:
        obj = getattr(xtopo, name)
        if inspect.isfunction(obj):
            yield f"xtopo.{name}", obj
    for cls in (accessors.TopoAccessor, accessors.TopoTreeAccessor):
        for name in dir(cls):
            member = getattr(cls, name)
            if not name.startswith("_") and inspect.isfunction(member):
                yield f"{cls.__name__}.{name}", member
    yield "Scene", Scene
    yield "Scene.solve", Scene.solve
    yield "Scene.curve", Scene.curve


def module_items():
    for modname in MODULES:
        module = importlib.import_module(modname)
        for name in getattr(module, "__all__", ()):
            obj = getattr(module, name)
            if (inspect.isfunction(obj) or (inspect.isclass(obj) and not issubclass(obj, BaseException))):
                yield f"{modname}.{name}", obj


def _label(p: inspect.Parameter) -> str:
    return {p.VAR_KEYWORD: f"**{p.name}", p.VAR_POSITIONAL: f"*{p.name}"}.get(p.kind, p.name)


_STATED_DEFAULT = re.compile(r"\bdefault(?:s to|:)?\s+(``[^`]+``|\"[^\"]+\"|'[^']+'|[-+\w.]+)", re.I)


def problems(obj) -> list[str]:
    params = signature_parameters(obj)
    docs = documented(obj)
    if docs is None:
        return ["no Parameters section"]
    labels = [_label(p) for p in params]
    out = []
    missing = [n for n in labels if n not in docs]
    extra = [n for n in docs if n not in labels]
    if missing:
        out.append(f"undocumented parameters {missing}")
    if extra:
        out.append(f"documented parameters not in the signature {extra}")
    for p in params:
        if p.name not in docs:
            continue
        kind, text, combined = docs[p.name]
        if "optional" in kind and p.default is inspect.Parameter.empty:
            out.append(f"{p.name} is documented optional but has no default")
        if isinstance(p.default, (bool, int, float, str)) and not combined:
            for stated in _STATED_DEFAULT.findall(text):
                value = stated.strip("`").rstrip(".,;:)")
                if value.lower() in ("from", "the", "a", "an", "all", "one", "none", "is", "of", "only"):
                    continue
                expected = {repr(p.default), str(p.default), f'"{p.default}"', f"'{p.default}'"}
                if value not in expected and not (isinstance(p.default, bool) is False
                                                  and isinstance(p.default, (int, float))
                                                  and _same_number(value, p.default)):
                    out.append(f"{p.name}: the docstring states default {stated}, the signature {p.default!r}")
    return out


def _same_number(text: str, value) -> bool:
    try:
        return float(text) == float(value)
    except ValueError:
        return False


STRICT = dict(strict_items())


@pytest.mark.parametrize("name", list(STRICT))
def test_public_docstrings_document_the_signature(name):
    found = problems(STRICT[name])
    assert not found, f"{name}: " + "; ".join(found)


def test_documented_module_functions_match_their_signatures():
    bad = {}
    for name, obj in module_items():
        if documented(obj) is not None and problems(obj):
            bad[name] = problems(obj)
    assert not bad, "\n".join(f"{k}: {'; '.join(v)}" for k, v in bad.items())


def test_the_checker_sees_mismatches():
    def f(obj, kind: str = "1d", *, dim="x", reliable: bool = True, **kwargs):
        """Doc.

        Parameters
        ----------
        obj : xarray.Dataset
        kind : {"1d", "iso"}
            The kind (default ``"iso"``).
        dimension : str, optional
        reliable : bool
            Default True.
        """

    found = " ".join(problems(f))
    assert "undocumented parameters ['dim', '**kwargs']" in found
    assert "not in the signature ['dimension']" in found
    assert 'states default ``"iso"``' in found
    assert "reliable" not in found
    assert problems(lambda x: None) == ["no Parameters section"]
