"""Where xtopo keeps files between runs: below every layer, so that the kernels may keep FFTW's
wisdom there and :mod:`xtopo.cache` its results."""

import os

from platformdirs import user_cache_dir

__all__ = ["default_directory"]


def default_directory() -> str:
    """``$XTOPO_CACHE_DIR`` or the platform's user cache directory for xtopo."""
    return os.environ.get("XTOPO_CACHE_DIR") or user_cache_dir("xtopo")
