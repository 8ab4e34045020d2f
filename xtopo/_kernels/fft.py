"""FFT backend: scipy.fft or pyFFTW, chosen by :func:`choose_backend`.

One-shot transforms (the analyses) use scipy.fft below 2048² points and pyFFTW from there;
transforms whose plans are built once and reused (the contact operator) use planned pyFFTW at
any size (docs/tradeoffs.md, FFT backend). ``backend="auto"`` follows that rule; users may force one.
"""

from __future__ import annotations

import functools
import os

import numpy as np

from ..errors import XtopoError
from ._lazy import Lazy

sfft = Lazy("scipy.fft")  # imported on first use (startup time, issue 26)

__all__ = ["rfftn", "irfftn", "fftn", "choose_backend", "workers"]

_PYFFTW_THRESHOLD = 2048 * 2048


def workers() -> int:
    """Threads for FFTs: ``XTOPO_FFT_THREADS``, else one.

    Threaded transforms synchronise on every call: where the cores are busy (other processes,
    parallel tasks) a waiting thread stalls the others. On the loaded 2-core development machine
    a 1024-point batch of 1024² row transforms took 2.8 ms at best on one thread and 12–20 ms on
    two; contact solves were up to 22× slower (issue 27), while on an idle machine two threads gain
    them at most 1.6× from 2048² on (benchmarks/bench_contact.py --threads). Parallel work
    (:mod:`xtopo.batch`) uses the cores without that risk; set ``XTOPO_FFT_THREADS`` on a machine of
    one's own.
    """
    env = os.environ.get("XTOPO_FFT_THREADS", "").strip()
    if not env:
        return 1
    if not env.isdigit() or int(env) < 1:
        raise XtopoError(f"XTOPO_FFT_THREADS={env!r}: a whole number of threads, at least 1, or leave it unset (1)")
    return int(env)


def choose_backend(shape, backend: str = "auto", *, planned: bool = False) -> str:
    """Return ``"scipy"`` or ``"pyfftw"`` for transforms of ``shape``.

    ``"auto"`` takes pyFFTW when it imports and either the plans are built once and reused
    (``planned``: the contact operator, where planned FFTW runs 1.4–2× faster than pocketfft
    from 256² on) or the grid has at least 2048² points (one-shot transforms, where planning
    costs more than it saves on smaller grids). Explicit choices pass.
    """
    if backend not in ("auto", "scipy", "pyfftw"):
        raise ValueError(f"unknown FFT backend {backend!r}; use 'auto', 'scipy' or 'pyfftw'")
    if backend != "auto":
        return backend
    if not planned and int(np.prod(shape)) < _PYFFTW_THRESHOLD:
        return "scipy"
    try:
        import pyfftw  # noqa: F401
    except ImportError:  # the optional [fftw] extra is not installed
        return "scipy"
    return "pyfftw"


def _call(name, a, s=None, axes=None, *, backend="auto"):
    """``scipy.fft.<name>`` of ``a``, or pyFFTW's where :func:`choose_backend` picks it."""
    if choose_backend(a.shape if s is None else s, backend) == "pyfftw":
        import pyfftw.interfaces.scipy_fft as pfft

        return getattr(pfft, name)(a, s=s, axes=axes, workers=workers())
    return getattr(sfft, name)(a, s=s, axes=axes, workers=workers())


#: ``f(a, s=None, axes=None, *, backend="auto")``: the real-input n-dim FFT, its inverse (normalised by 1/N) and the
#: complex n-dim FFT (unnormalised), numpy's sign convention
rfftn, irfftn, fftn = (functools.partial(_call, name) for name in ("rfftn", "irfftn", "fftn"))
