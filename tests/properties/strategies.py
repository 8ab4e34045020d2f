"""Hypothesis strategies for height maps and line scans (metres), and the fast/nightly test pair."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import xtopo

COMMON = dict(deadline=None, derandomize=True, database=None, print_blob=True,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
#: settings of the nightly (``slow``) twins
NIGHTLY = settings(max_examples=300, **COMMON)


def property_tests(*args, **kwargs):
    """Decorate a property ``check``: returns ``(fast, nightly)`` tests with the same strategies.

    ``fast`` runs under the default profile (conftest); ``nightly`` is marked ``slow`` and
    draws :data:`NIGHTLY` examples. Bind both at module level::

        test_x, test_x_nightly = property_tests(h=heights())(check_x)
    """
    def deco(check):
        fast = given(*args, **kwargs)(check)
        slow = pytest.mark.slow(NIGHTLY(given(*args, **kwargs)(check)))
        return fast, slow

    return deco

#: overall height scales (m): a map of values in [-1, 1] times one of these
SCALES = [1e-9, 1e-3, 1.0, 1e3]


@st.composite
def heights(draw, *, min_side: int = 1, max_side: int = 12, area: bool | None = None):
    """A finite height array, 1D or 2D, of small size, scaled by one of :data:`SCALES`."""
    if area is None:
        area = draw(st.booleans())
    side = st.integers(min_side, max_side)
    shape = (draw(side), draw(side)) if area else (draw(side),)
    h = draw(hnp.arrays(np.float64, shape, elements=st.floats(-1, 1, allow_subnormal=False)))
    return h * draw(st.sampled_from(SCALES))


@st.composite
def measurements(draw, *, periodic=None, **kw):
    """A measurement Dataset from :func:`heights` on pixels of 1e-9…1 m."""
    h = draw(heights(**kw))
    dx = draw(st.sampled_from([1e-9, 1e-6, 1.0]))
    per = draw(st.booleans()) if periodic is None else periodic
    return xtopo.make_measurement(h, spacing=dx, periodic=per)


@st.composite
def masks(draw, shape):
    """A boolean mask of ``shape`` that leaves at least one point present."""
    m = draw(hnp.arrays(bool, shape))
    m.flat[draw(st.integers(0, m.size - 1))] = False
    return m
