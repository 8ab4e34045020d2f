"""Hypothesis profile of the property tests: reproducible (derandomized) and small by default.

The slow twins made by :func:`tests.properties.strategies.property_tests` use more examples
and run with ``ci/nightly`` (``pytest -m slow``).
"""

from hypothesis import settings

from .strategies import COMMON

settings.register_profile("xtopo", max_examples=15, **COMMON)
settings.load_profile("xtopo")
