"""FFT convolution with an elastic Green's function, plans and buffers reused (paper §5.3).

:class:`Convolution` applies ``u = G * p`` for pressures on the *active* grid (the
measurement grid) and returns displacements on the same grid.  Periodic problems
transform on the native grid; free-boundary problems on the ``2N`` padded grid with
the padding handled inside: the forward transform along ``x`` runs only over the
``N_y`` rows that carry pressure (the others are zero) and the inverse along ``x``
only over the ``N_y`` rows that are returned, so one application costs about 3/4 of
a full padded forward+inverse real FFT pair.

Besides ``conv(p, out)`` the class exposes the two halves of a convolution, which is
what the contact solver uses (one forward transform of the search direction and one
convolution of the pressures per iteration):

* :attr:`input` — the real input buffer on the active grid; write into it (only the
  pixels that change: the rest keeps its values), then
* :meth:`forward` — its spectrum (unnormalised ``rfft``), kept in an internal buffer;
* :meth:`energy` — ``Σ x (G * x)`` of the buffered input from its spectrum (Parseval),
  no inverse transform;
* :meth:`inverse` — ``G * x`` on the active grid (a view valid until the next call).

Backends (``backend=``): ``"pyfftw"`` (FFTW plans built once on preallocated, aligned
buffers; no allocation per call) or ``"scipy"`` (``scipy.fft``, pocketfft caches its
plans but allocates its outputs). ``"auto"`` takes pyFFTW when it is installed: planned
FFTW transforms run 1.4–2× faster than pocketfft on 256²–2048² grids. Measured plans
(``FFTW_MEASURE``, from 256² on) run about 1.25× faster than estimated ones, but measuring
the three plans of a 1024² solve costs 8 s, twice the solve: a grid FFTW's wisdom (kept in the
user cache directory) does not know yet is planned by estimate, and measured once the operator
has served :data:`_MEASURE_AFTER` solves (load curves, batches), which stores the wisdom for every
later process. ``XTOPO_FFTW_PLANNER=estimate|measure|patient`` overrides; ``patient`` plans the
column transforms of 2-D grids by ``FFTW_PATIENT`` (strided transforms: 512² float32 0.22 → 0.18
ms, 1024² 0.95 → 0.85 ms, 2048² 5.3 → 4.6–5.1 ms; rows gain nothing and stay measured) at 3 s
(512²) to 23 s (2048²) of planning per precision: it pays back only after some hundred solves of
the grid, so it is the user's choice (one run with it stores the plans, and every later process
starts from the most rigorous plans the wisdom knows). One FFT thread unless ``XTOPO_FFT_THREADS``
says otherwise (:func:`xtopo._kernels.fft.workers`).
"""

from __future__ import annotations

import os
import threading

import numpy as np
import scipy.fft as sfft

from ..errors import XtopoError
from . import fft as _fft
from . import compiled
from ._cache_dir import default_directory
from .greens import free_greens, padded_shape, periodic_greens

__all__ = ["Convolution"]

_COMPLEX = {np.dtype(np.float32): np.complex64, np.dtype(np.float64): np.complex128}
_MEASURE_FROM = 256 * 256
#: solves on one operator after which estimated plans are replaced by measured ones (saved as wisdom)
_MEASURE_AFTER = 3
_WISDOM = {"loaded": False}


def _planner(fft_shape) -> str:
    """The planner flag ``XTOPO_FFTW_PLANNER=estimate|measure|patient`` asks for, or the default ``"auto"``:
    the most rigorous plans FFTW's wisdom knows, estimated ones otherwise (see :meth:`Convolution.begin_solve`)."""
    env = os.environ.get("XTOPO_FFTW_PLANNER", "").strip().lower()
    if env in ("estimate", "measure", "patient"):
        return "FFTW_" + env.upper()
    if env not in ("", "auto"):   # a misspelt choice would silently plan otherwise
        raise XtopoError(f"XTOPO_FFTW_PLANNER={env!r}: use estimate, measure or patient, or leave it unset (auto)")
    return "auto" if int(np.prod(fft_shape)) >= _MEASURE_FROM else "FFTW_ESTIMATE"


def _wisdom_path() -> str:
    return os.path.join(default_directory(), "fftw-wisdom.npz")


def _load_wisdom(pyfftw) -> None:
    if _WISDOM["loaded"]:
        return
    _WISDOM["loaded"] = True
    try:
        with np.load(_wisdom_path(), allow_pickle=False) as stored:
            pyfftw.import_wisdom(tuple(stored[f"arr_{i}"].tobytes() for i in range(len(stored.files))))
    except Exception:  # no wisdom yet, or from another FFTW build: plan afresh
        pass


def _save_wisdom(pyfftw) -> None:
    """Store this process's wisdom with what other processes stored meanwhile (FFTW adds imported wisdom)."""
    path = _wisdom_path()
    _WISDOM["loaded"] = False
    _load_wisdom(pyfftw)
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        tmp = f"{path}.{os.getpid()}.tmp"
        with open(tmp, "wb") as f:
            np.savez(f, *(np.frombuffer(w, dtype=np.uint8) for w in pyfftw.export_wisdom()))
        os.replace(tmp, path)
    except OSError:  # a read-only cache directory only costs the next process a re-plan
        pass


class Convolution:
    """``u = G * p`` on a grid of ``shape`` (``(ny, nx)`` or ``(nx,)``).

    Parameters
    ----------
    shape : tuple of int
        Active grid (the measurement's pixels).
    spacing : tuple of float
        Pixel sizes, same order as ``shape`` (length units).
    modulus : float
        Contact modulus ``E*``.
    periodic : bool
        Periodic Green's function eq. (17) on the native grid, or the free-boundary
        kernel (eq. 19 / plane-strain strip) on the padded grid.
    dtype : {"float64", "float32"}
        Floating point type of the arrays and transforms.
    backend : {"auto", "scipy", "pyfftw"}
        FFT library (see the module docstring).

    Notes
    -----
    Memory (pyFFTW): the operator keeps its Green's function folded (half the rows, one array per
    precision, shared by its workspaces) and one spectrum-sized buffer that its transforms run in
    place in: :meth:`forward` consumes the input. Its :meth:`workspace` operators keep an input
    buffer of their own (written point by point, never consumed) and transform into the same
    buffer, so their spectra and outputs are valid only until the next transform of any of them.

    The buffers, work arrays and replicas are shared state: a caller that uses them across
    several calls (the contact solver) holds :attr:`lock` meanwhile, and ``conv(p)`` takes it
    itself, so solves on one operator from several threads run one after the other instead
    of overwriting each other's buffers.
    """

    def __init__(self, shape, spacing, modulus: float = 1.0, *, periodic: bool, dtype="float64",
                 backend: str = "auto", _owner: "Convolution | None" = None, _in_place: bool = False):
        self.shape = tuple(int(n) for n in shape)
        self._geometry = (tuple(spacing), modulus)
        self.ndim = len(self.shape)
        self.periodic = bool(periodic)
        self.dtype = np.dtype(dtype)
        self.cdtype = np.dtype(_COMPLEX[self.dtype])
        self.fft_shape = self.shape if self.periodic else padded_shape(self.shape)
        self._owner = _owner  # a workspace transforms in its owner's buffer, with its owner's operator
        self._in_place = _owner is None or _in_place
        self.backend = _owner.backend if _owner is not None else _fft.choose_backend(self.fft_shape, backend,
                                                                                     planned=True)
        self.workers = _fft.workers()   # one thread unless XTOPO_FFT_THREADS says otherwise (issue 27)
        m = float(np.prod(self.fft_shape))
        self._rows = self.fft_shape[0] if self.ndim == 2 else 1      # rows of the spectrum
        self._halve_last = self.fft_shape[-1] % 2 == 0
        # FFTW does not normalise the inverse: 1/M goes into the multiplier; Parseval takes 1/M where the
        # transform normalises itself (scipy)
        self._energy_scale = 1.0 if self.backend == "pyfftw" else 1.0 / m
        if _owner is not None:
            self._gmul = _owner._multiplier(self.dtype)
        else:
            make = periodic_greens if self.periodic else free_greens
            g = make(self.shape, spacing, modulus)
            if self.backend == "pyfftw":
                g *= 1.0 / m
            self._gmul = g.astype(self.dtype, copy=False)
        self._multipliers = {self.dtype: self._gmul}
        self._real_shape = self.shape[:-1] + (self.fft_shape[-1],)
        self._plan = None
        self._buffers = None
        self._workspaces = {}
        self._scratch = {}
        self._self_stiffness = None
        self._planned = None      # the rigor its plans were made with (auto: what the wisdom knew)
        self._wanted = None       # the rigor to plan with next (None: what the wisdom knows)
        self._solves = 0
        self.lock = _owner.lock if _owner is not None else threading.RLock()

    def _multiplier(self, dtype) -> np.ndarray:
        """The folded spectral multiplier in ``dtype`` (one array per precision, shared with the workspaces)."""
        dtype = np.dtype(dtype)
        if dtype not in self._multipliers:
            self._multipliers[dtype] = self._gmul.astype(dtype)
        return self._multipliers[dtype]

    @property
    def self_stiffness(self) -> float:
        """``G(0)``: the displacement of a pixel under a unit pressure on itself (length/modulus units).

        A unit impulse has ``|x̂| = 1`` at every frequency, so by Parseval its energy is the mean of
        the Green's function over the FFT grid (rfft multiplicities counted) — no transform needed.
        """
        if self._self_stiffness is None:
            nc = self.fft_shape[-1] // 2 + 1
            ones = np.ones(2 * self._rows * nc)
            self._self_stiffness = self._energy_scale * compiled.energy(
                self._gmul.reshape(-1), ones, self._rows, self._halve_last) / 2
        return self._self_stiffness

    def single_precision(self) -> "Convolution":
        """The same operator in float32 (itself when already float32), built once.

        A float32 transform costs 0.5–0.7 of a float64 one; the solver iterates on float32
        increments (:mod:`xtopo._kernels.pk_solver`).
        """
        return self if self.dtype == np.float32 else self.workspace("single", "float32")

    def workspace(self, name: str, dtype=None, *, in_place: bool = False) -> "Convolution":
        """A work operator kept under ``name``: built (planned, allocated) once, then reused.

        It transforms in this operator's buffer (see the class notes), from an input buffer of its own
        that :meth:`forward` leaves intact, or (``in_place``) from that buffer itself, which its
        :meth:`forward` consumes; ``dtype`` (default this one's) may not be wider than this operator's. The solver's float32 operators live here, so that repeated solves on one scene
        (load curves, benchmarks) plan, allocate and write FFTW wisdom nothing. Callers own the buffers'
        contents only while they use them.
        """
        dtype = np.dtype(dtype or self.dtype)
        key = (name, dtype.name, in_place)
        if key not in self._workspaces:
            spacing, modulus = self._geometry
            self._workspaces[key] = Convolution(self.shape, spacing, modulus, periodic=self.periodic, dtype=dtype,
                                                _owner=self, _in_place=in_place)
        return self._workspaces[key]

    def begin_solve(self) -> None:
        """Count a solve on this operator; the :data:`_MEASURE_AFTER`-th replaces estimated plans (the grid
        was new to FFTW's wisdom) by measured ones and stores the wisdom (``auto`` planning only). Call with
        :attr:`lock` held, before the buffers hold anything (planning overwrites them)."""
        self._solves += 1
        ops = [self, *self._workspaces.values()]
        if (self._solves >= _MEASURE_AFTER and _planner(self.fft_shape) == "auto"
                and any(op._planned == "FFTW_ESTIMATE" for op in ops)):
            for op in ops:   # all of them: the workspaces' spectra live in this operator's buffer
                op._wanted, op._plan, op._buffers = "FFTW_MEASURE", None, None

    def scratch(self, name: str, size: int, dtype) -> np.ndarray:
        """A 1-D work array of ``size`` kept under ``name`` (contents undefined; allocated once).

        The solver's per-grid arrays live here: a fresh array costs a page fault per 4 KiB page on
        its first pass (about 8 ms for 8 MB here), which repeated solves on one scene pay only once.
        """
        dtype = np.dtype(dtype)
        a = self._scratch.get(name)
        if a is None or a.size != size or a.dtype != dtype:
            a = self._scratch[name] = np.empty(size, dtype)
        return a

    def release(self, name: str) -> np.ndarray:
        """Take the work array ``name`` out of :meth:`scratch` (the caller keeps it; the next use allocates anew)."""
        return self._scratch.pop(name)

    # -- plans and buffers ----------------------------------------------------------------------
    def __getstate__(self):
        state = dict(self.__dict__)
        state["_plan"] = None  # FFTW plans do not pickle; rebuilt on first use
        state["_buffers"] = None
        state["_workspaces"] = {}
        state["_scratch"] = {}
        state["_multipliers"] = {self.dtype: self._gmul}
        state.update(_planned=None, _wanted=None, _solves=0)   # a copy elsewhere plans from that machine's wisdom
        del state["lock"]
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self.lock = threading.RLock()

    def _ensure(self):
        if self._buffers is None:
            if self.backend == "pyfftw":
                self._build_pyfftw()
            else:
                self._build_scipy()
        return self._buffers

    def _build_scipy(self):
        r_in = np.zeros(self._real_shape, dtype=self.dtype)
        self._buffers = {"in": r_in, "active": r_in[..., : self.shape[-1]], "spec": None}

    def _build_pyfftw(self):
        import pyfftw

        _load_wisdom(pyfftw)
        flag = _planner(self.fft_shape)
        if flag == "auto" and self._wanted is None:
            # the most rigorous plans the wisdom knows cost nothing; not known: estimate now, plan with more rigor
            # once the operator has proved its use (begin_solve)
            for known in ("FFTW_PATIENT", "FFTW_MEASURE") if self.ndim == 2 else ("FFTW_MEASURE",):  # lines: no columns
                try:
                    self._plan_pyfftw(pyfftw, known, ("FFTW_WISDOM_ONLY",))
                    self._planned = known
                    return
                except RuntimeError:
                    pass
            flag = "FFTW_ESTIMATE"
        elif flag == "auto":
            flag = self._wanted
        self._plan_pyfftw(pyfftw, flag)
        self._planned = flag
        if flag != "FFTW_ESTIMATE":
            _save_wisdom(pyfftw)

    def _plan_pyfftw(self, pyfftw, rigor, extra=()):
        """Plans at ``rigor`` (an FFTW planner flag; rows and lines at most ``FFTW_MEASURE``, where patience finds
        nothing faster) on this operator's buffers."""
        cols = dict(threads=self.workers, flags=(rigor, *extra))
        row_flags = ("FFTW_MEASURE" if rigor == "FFTW_PATIENT" else rigor, *extra)
        rows = dict(threads=self.workers, flags=row_flags)
        destroy = dict(threads=self.workers, flags=(*row_flags, "FFTW_DESTROY_INPUT"))
        nxc = self.fft_shape[-1] // 2 + 1
        nfx = self.fft_shape[-1]
        spec_shape = self.fft_shape[:-1] + (nxc,)
        if self._owner is None:
            arena = pyfftw.zeros_aligned(spec_shape, dtype=self.cdtype)
        else:
            arena = self._owner._ensure()["arena"]
        # this operator's spectrum at the start of the buffer, and its real view (rows of 2·nxc values)
        spec = arena.reshape(-1).view(np.uint8)[: int(np.prod(spec_shape)) * self.cdtype.itemsize]
        spec = spec.view(self.cdtype).reshape(spec_shape)
        real = spec.view(self.dtype).reshape(self.fft_shape[:-1] + (2 * nxc,))
        ny = self.shape[0]
        if self._in_place:
            r_in = real   # transforms in place: the input is consumed
        else:
            r_in = pyfftw.zeros_aligned(self.shape[:-1] + (2 * nxc,), dtype=self.dtype)
        if self.ndim == 1:
            fwd = [pyfftw.FFTW(r_in[..., :nfx], spec, axes=(-1,), direction="FFTW_FORWARD", **rows)]
            bwd = [pyfftw.FFTW(spec, real[..., :nfx], axes=(-1,), direction="FFTW_BACKWARD", **destroy)]
        else:
            # rows along x (on a free grid into the top half, the bottom half zeroed), then columns in place: as
            # fast as one 2-D plan at the same rigor, and the columns can be planned with more (in-place column
            # transforms run ~3x faster than out-of-place ones here)
            fwd = [pyfftw.FFTW(r_in[:ny, :nfx], spec[:ny], axes=(-1,), direction="FFTW_FORWARD", **rows),
                   *([spec[ny:]] if ny < spec.shape[0] else []),
                   pyfftw.FFTW(spec, spec, axes=(0,), direction="FFTW_FORWARD", **cols)]
            bwd = [pyfftw.FFTW(spec, spec, axes=(0,), direction="FFTW_BACKWARD", **cols),
                   pyfftw.FFTW(spec[:ny], real[:ny, :nfx], axes=(-1,), direction="FFTW_BACKWARD", **destroy)]
        self._plan = (fwd, bwd)
        n = self.shape[-1]
        # an in-place input shares its row with the output: the zero padding of a free grid is restored
        # before each forward transform
        zero = [r_in[n:] if self.ndim == 1 else r_in[:ny, n:]] if self._in_place and not self.periodic else []
        r_in.fill(0)
        self._buffers = {"in": r_in, "active": r_in[..., :n] if self.ndim == 1 else r_in[:ny, :n], "spec": spec,
                         "out": real[..., :n] if self.ndim == 1 else real[:ny, :n], "out_full": real,
                         "arena": arena, "zero": zero}

    # -- the two halves ---------------------------------------------------------------------------
    @property
    def input(self) -> np.ndarray:
        """Real input buffer on the active grid (the padding around it stays zero)."""
        return self._ensure()["active"]

    @property
    def input_flat(self) -> np.ndarray:
        """The whole input buffer, flattened (laid out as :attr:`buffer_layout` says)."""
        return self._ensure()["in"].reshape(-1)

    @property
    def output_flat(self) -> np.ndarray:
        """The whole real output buffer of :meth:`inverse`, flattened (laid out as :attr:`buffer_layout` says).

        Valid after :meth:`inverse` (its values are those of the last call) until the next transform.
        """
        return self._ensure()["out_full"].reshape(-1)

    @property
    def buffer_layout(self) -> tuple[int, int]:
        """``(nx, pad)``: active row length and the extra values of a buffer row (0 on line grids). Flat
        active index ``i`` sits at ``i + (i // nx) * pad`` in the input and output buffers."""
        if self.ndim == 1:
            return self.shape[-1], 0
        row = self._ensure()["in"].shape[-1]
        return self.shape[-1], row - self.shape[-1]

    def forward(self) -> np.ndarray:
        """Spectrum of the input buffer on the FFT grid (unnormalised, ``rfft`` layout).

        With pyFFTW the operator's own input is consumed (the transform runs in place); a
        workspace's input stays.
        """
        b = self._ensure()
        if self.backend == "pyfftw":
            for z in b["zero"]:
                z.fill(0)
            for plan in self._plan[0]:
                if isinstance(plan, np.ndarray):
                    plan.fill(0)  # the zero padding rows of a free-boundary spectrum
                else:
                    plan.execute()
            return b["spec"]
        w = self.workers
        if self.periodic or self.ndim == 1:
            b["spec"] = sfft.rfftn(b["in"], axes=tuple(range(-self.ndim, 0)), workers=w)
        else:
            f = sfft.rfft(b["in"], axis=-1, workers=w)
            b["spec"] = sfft.fft(f, n=self.fft_shape[0], axis=0, workers=w, overwrite_x=True)
        return b["spec"]

    def energy(self, spectrum: np.ndarray) -> float:
        """``Σ x (G * x)`` over the grid for the input ``x`` whose spectrum is given (Parseval)."""
        v = np.ascontiguousarray(spectrum).view(self.dtype).reshape(-1)
        return self._energy_scale * compiled.energy(self._gmul.reshape(-1), v, self._rows, self._halve_last)

    def inverse(self, spectrum: np.ndarray) -> np.ndarray:
        """``G * x`` on the active grid from the spectrum of ``x`` (which is overwritten).

        With pyFFTW the result is a view of an internal buffer, valid until the next transform.
        """
        b = self._ensure()
        if not spectrum.flags.c_contiguous:  # scaled in place through a flat view: a copy would be lost
            raise ValueError("the spectrum must be C-contiguous (as forward() returns it)")
        if self.backend == "pyfftw" and spectrum is not b["spec"]:
            b["spec"][...] = spectrum
            spectrum = b["spec"]
        compiled.scale_spectrum(spectrum.view(self.dtype).reshape(-1), self._gmul.reshape(-1), self._rows)
        if self.backend == "pyfftw":
            for plan in self._plan[1]:
                plan.execute()
            return b["out"]
        w = self.workers
        n = self.shape[-1]
        if self.periodic or self.ndim == 1:
            axes = tuple(range(-self.ndim, 0))
            r = sfft.irfftn(spectrum, s=self.fft_shape, axes=axes, workers=w, overwrite_x=True)
        else:
            f = sfft.ifft(spectrum, axis=0, workers=w, overwrite_x=True)[: self.shape[0]]
            r = sfft.irfft(f, n=self.fft_shape[-1], axis=-1, workers=w, overwrite_x=True)
        b["out_full"] = r
        return r[..., :n]

    # -- whole convolution ----------------------------------------------------------------------
    def __call__(self, p: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Displacements ``G * p`` on the active grid (written into ``out`` when given)."""
        if out is None:
            out = np.empty(self.shape, dtype=self.dtype)
        with self.lock:
            self.input[...] = p
            out[...] = self.inverse(self.forward())
        return out
