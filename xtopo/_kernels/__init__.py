"""Pure numpy kernels (no xarray import): FFT backend, derivative stencils, binning, ...

Kernels take arrays with the core dims last and return arrays; physical units
are the caller's business.
"""

#: detrend modes → polynomial degree (:mod:`xtopo._kernels.polyfit`); here, without numpy, for the command
#: line's --detrend choices (``xtopo --help`` imports no numpy)
DEGREES = {"mean": 0, "plane": 1, "curvature": 2}
