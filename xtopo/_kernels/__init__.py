"""Pure numpy kernels (no xarray import): FFT backend, derivative stencils, binning, ...

Kernels take arrays with the core dims last and return arrays; physical units
are the caller's business.
"""
