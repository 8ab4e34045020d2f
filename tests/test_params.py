"""The declared-parameter vocabulary (xtopo.params): checking, normalising, naming, pre-flight."""

from __future__ import annotations

from typing import Annotated

import numpy as np
import pytest

from xtopo.errors import ContactError, UnitsError, XtopoError
from xtopo.params import Count, LengthUnit, OneOf, Positive, Real, checked, declarations, preflight

@checked(OneOf("load", "penetration", error=ContactError))
def _demo(n: Annotated[int, Count()], x: Annotated[float, Positive()] = 1.0, *,
          unit: Annotated[str, LengthUnit()] = "m", width: Annotated[float | None, Positive()] = None,
          load: Annotated[float | None, Real(0.0)] = None, penetration: Annotated[float | None, Real()] = None):
    return n, x, unit, width, load, penetration


def test_arguments_arrive_normalised_positionally_or_by_keyword():
    assert _demo(np.int64(3), np.float32(2), unit="µm", load=0) == (3, 2.0, "um", None, 0.0, None)
    assert type(_demo(n=3, load=1)[0]) is int
    assert _demo(3, width=None, penetration=-1.0)[5] == -1.0  # a None default accepts None


def test_errors_name_the_parameter_and_use_the_declared_subclass():
    with pytest.raises(XtopoError, match=r"^x must be a positive finite number, got 0$"):
        _demo(3, 0, load=1)
    with pytest.raises(UnitsError, match="unit='s' is not a length unit"):
        _demo(3, unit="s", load=1)
    with pytest.raises(ContactError, match=r"exactly one of load= or penetration="):
        _demo(3)
    with pytest.raises(ContactError, match=r"got load, penetration"):
        _demo(3, load=1, penetration=1)


def test_preflight_checks_a_call_without_making_it():
    assert preflight(_demo, {"unit": "µm", "x": 2}, rules=False) == {"unit": "um", "x": 2.0}
    with pytest.raises(XtopoError, match=r"^read_options has no option 'colour'; its options: x, unit"):
        preflight(_demo, {"colour": 1}, "read_options")
    with pytest.raises(ContactError, match=r"^opts: give exactly one"):
        preflight(_demo, {"x": 2}, "opts")
    assert set(declarations(_demo)) == {"n", "x", "unit", "width", "load", "penetration"}


def test_preflight_refuses_what_is_not_an_option():
    """A positional parameter without a default is the data each item brings, not an option: given once for
    many items (``read_options={"path": ...}``, a step's ``{"obj": ...}``) it failed later, in every item, with
    a TypeError."""
    from xtopo.io import open_topography
    from xtopo.preprocess import checked_steps

    with pytest.raises(XtopoError, match=r"^opts has no option 'n'"):
        preflight(_demo, {"n": 3, "x": 2}, "opts")
    with pytest.raises(XtopoError, match=r"^read_options has no option 'path'"):
        preflight(open_topography, {"path": "a.txt"}, "read_options")
    with pytest.raises(XtopoError, match=r"step 'detrend' has no option 'obj'"):
        checked_steps([("detrend", {"obj": 1})])
