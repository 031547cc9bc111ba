"""The Levenberg-Marquardt iteration of the LM planner as native code, with the same floats.

:func:`~solvers.planner.backends.banded_least_squares.levenberg_marquardt` spends most of a plan
in NumPy's per-call overhead around small arrays (about 25 us per iteration for a step kernel of
5 us). :class:`NativeBandedKernel` runs the same iteration in C: the CasADi step and cost
functions (App. B.2.3's kernels) and a driver that repeats the Python code operation by
operation are generated into one source file and compiled once per machine by
:mod:`solvers.native`. The two library calls of the iteration are made to the very functions
NumPy and SciPy call: the banded Cholesky solve (LAPACK ``dpbsv``, through SciPy's
``cython_lapack``) and the dot products of the Sherman-Morrison correction (``cblas_ddot`` of
the OpenBLAS that NumPy's ``@`` uses). Everything else is elementwise IEEE arithmetic in the
Python code's order, compiled without reassociation or fused multiply-add, so the plans are the
Python loop's bit for bit (``tests/test_native.py``).

:func:`native_banded_kernel` returns None (the caller keeps the Python loop) where that cannot
be guaranteed: no C compiler, or NumPy's BLAS not found in this process (it looks for
OpenBLAS's ``cblas_ddot`` in the libraries mapped into the process, Linux only).
"""

from __future__ import annotations

import ctypes
import logging
from functools import cache, lru_cache
from pathlib import Path

import casadi as ca
import numpy as np
import scipy.linalg.cython_lapack as cython_lapack

from solvers.native import native_library
from solvers.planner.backends.banded_least_squares import BandedKernel

logger = logging.getLogger(__name__)

#: The driver, appended to the CasADi code of the two kernels (``STEP`` and ``COST`` are
#: defined before it). Each statement mirrors a line of banded_least_squares.py.
DRIVER = r"""
#include <stdlib.h>

typedef void (*pbsv_fn)(char*, int*, int*, int*, double*, int*, double*, int*, int*);
typedef double (*dot64_fn)(long long, const double*, long long, const double*, long long);
typedef double (*dot32_fn)(int, const double*, int, const double*, int);

typedef struct {
  int n, nb;                              /* variables, band rows (bandwidth + 1) */
  const long long *perm, *inverse;
  const double *p;                        /* the parameters (the Python kernel's array) */
  double *w, *f, *g, *band, *a, *wc, *fc; /* kernel inputs and outputs */
  double *ab, *rhs, *step_w, *dir, *z, *trial;
  const casadi_real *step_arg[2], *cost_arg[2];
  casadi_real *step_res[4], *cost_res[1];
  casadi_int *iw; casadi_real *work;
  pbsv_fn pbsv; void *dot; int dot_ilp64;
} lm_t;

static double lm_dot(lm_t *h, const double *x, const double *y) {
  if (h->dot_ilp64) return ((dot64_fn)h->dot)(h->n, x, 1, y, 1);
  return ((dot32_fn)h->dot)(h->n, x, 1, y, 1);
}

/* BandedKernel.evaluate */
static double lm_evaluate(lm_t *h, const double *z) {
  for (int i = 0; i < h->n; ++i) h->w[i] = z[h->perm[i]];
  STEP(h->step_arg, h->step_res, h->iw, h->work, 0);
  return h->f[0];
}

/* BandedKernel.cost_at */
double lm_cost_at(lm_t *h, const double *z) {
  for (int i = 0; i < h->n; ++i) h->wc[i] = z[h->perm[i]];
  COST(h->cost_arg, h->cost_res, h->iw, h->work, 0);
  return h->fc[0];
}

/* BandedKernel.direction: 0, or LAPACK's info when the damped band is not positive definite */
static int lm_direction(lm_t *h, double mu) {
  int n = h->n, nb = h->nb, kd = nb - 1, nrhs = 2, info = 0;
  char lower = 'L';
  for (int j = 0; j < n; ++j)
    for (int r = 0; r < nb; ++r) h->ab[r + j * nb] = h->band[r * n + j];
  for (int j = 0; j < n; ++j) {
    double diag = h->band[j] + h->a[j] * h->a[j];
    double floor = isnan(diag) ? diag : (diag > 1e-9 ? diag : 1e-9);  /* np.maximum */
    h->ab[j * nb] = h->band[j] + (mu * floor + 1e-12);
  }
  for (int i = 0; i < n; ++i) { h->rhs[i] = h->g[i]; h->rhs[n + i] = h->a[i]; }
  h->pbsv(&lower, &n, &kd, &nrhs, h->ab, &nb, h->rhs, &n, &info);
  if (info != 0) return info;
  const double *u = h->rhs, *v = h->rhs + n;
  double au = lm_dot(h, h->a, u), av = lm_dot(h, h->a, v), denominator = 1.0 + av;
  for (int i = 0; i < n; ++i) h->step_w[i] = -(u[i] - v[i] * au / denominator);
  for (int i = 0; i < n; ++i) h->dir[i] = h->step_w[h->inverse[i]];
  return 0;
}

/* levenberg_marquardt: z (in: z0, out: the result); returns the iteration count */
int lm_run(lm_t *h, double *z_io, int iterations, double damping, int backtracks,
           double *cost_out) {
  int n = h->n, done = 0;
  double *z = h->z, *trial = h->trial;
  for (int i = 0; i < n; ++i) z[i] = z_io[i];
  double cost = lm_evaluate(h, z), mu = damping;
  for (done = 1; done <= iterations; ++done) {
    if (lm_direction(h, mu) != 0) { mu *= 10.0; continue; }
    double scale = 1.0, new_cost = 0.0;
    int accepted = 0;
    for (int b = 0; b < backtracks + 1; ++b) {
      for (int i = 0; i < n; ++i) trial[i] = z[i] + scale * h->dir[i];
      new_cost = lm_cost_at(h, trial);
      if (new_cost < cost) { accepted = 1; break; }
      scale *= 0.5;
    }
    if (!accepted) {
      mu *= 16.0;
      if (mu > 1e12) break;
      continue;
    }
    double improvement = cost - new_cost;
    for (int i = 0; i < n; ++i) z[i] = z[i] + scale * h->dir[i];
    cost = lm_evaluate(h, z);
    if (scale == 1.0) { double third = mu / 3.0; mu = (1e-12 > third) ? 1e-12 : third; }
    else mu = mu * 4.0;
    double floor = (1.0 > cost) ? 1.0 : cost;  /* Python's max(cost, 1.0) */
    if (improvement <= 1e-12 * floor || cost <= 1e-24) break;
  }
  if (done > iterations) done = iterations;
  for (int i = 0; i < n; ++i) z_io[i] = z[i];
  *cost_out = cost;
  return done;
}

lm_t *lm_new(int n, int nb, const long long *perm, const long long *inverse, const double *p,
             long long sz_iw, long long sz_w, void *pbsv, void *dot, int dot_ilp64) {
  lm_t *h = (lm_t*)calloc(1, sizeof(lm_t));
  if (!h) return NULL;
  h->n = n; h->nb = nb; h->perm = perm; h->inverse = inverse; h->p = p;
  double *block = (double*)calloc((size_t)(n * (nb * 2 + 12) + 1 + sz_w), sizeof(double));
  casadi_int *iw = (casadi_int*)calloc((size_t)(sz_iw + 1), sizeof(casadi_int));
  if (!block || !iw) { free(block); free(iw); free(h); return NULL; }
  double *q = block;
  h->w = q; q += n; h->f = q; q += 1; h->g = q; q += n; h->band = q; q += n * nb;
  h->a = q; q += n; h->wc = q; q += n; h->fc = q; q += 1; h->ab = q; q += n * nb;
  h->rhs = q; q += 2 * n; h->step_w = q; q += n; h->dir = q; q += n; h->z = q; q += n;
  h->trial = q; q += n; h->work = q;
  h->iw = iw;
  h->step_arg[0] = h->w; h->step_arg[1] = p;
  h->step_res[0] = h->f; h->step_res[1] = h->g; h->step_res[2] = h->band; h->step_res[3] = h->a;
  h->cost_arg[0] = h->wc; h->cost_arg[1] = p; h->cost_res[0] = h->fc;
  h->pbsv = (pbsv_fn)pbsv; h->dot = dot; h->dot_ilp64 = dot_ilp64;
  return h;
}

void lm_free(lm_t *h) {
  if (!h) return;
  free(h->w); free(h->iw); free(h);
}
"""


class NativeBandedKernel(BandedKernel):
    """:class:`BandedKernel` whose :meth:`minimise` and :meth:`cost_at` run in C (same floats).

    Built by :func:`native_banded_kernel`; :attr:`p` is shared with the C side, so the
    parameters are set in place as for the Python kernel.
    """

    def __init__(self, step: ca.Function, cost: ca.Function, perm: np.ndarray,
                 library: ctypes.CDLL, blas: tuple[int, int, bool]) -> None:
        super().__init__(step, cost, perm)
        self._perm64 = np.ascontiguousarray(self.perm, dtype=np.int64)
        self._inverse64 = np.ascontiguousarray(self.inverse, dtype=np.int64)
        if self.band.shape[1] != self.n_var:
            raise ValueError("unexpected band layout of the step kernel")
        sz_iw = max(step.sz_iw(), cost.sz_iw())
        sz_w = max(step.sz_w(), cost.sz_w())
        pbsv, dot, ilp64 = blas
        self._lib = library
        self._handle = library.lm_new(
            self.n_var, self.band.shape[0], self._perm64.ctypes.data, self._inverse64.ctypes.data,
            self.p.ctypes.data, sz_iw, sz_w, pbsv, dot, int(ilp64))
        if not self._handle:
            raise MemoryError("lm_new failed")
        self._z = np.zeros(self.n_var)
        self._cost = ctypes.c_double()
        self._z_ptr = self._z.ctypes.data
        self._cost_ref = ctypes.byref(self._cost)

    def cost_at(self, z: np.ndarray) -> float:
        """The penalty cost at ``z`` (C)."""
        self._z[:] = z
        return float(self._lib.lm_cost_at(self._handle, self._z_ptr))

    def minimise(self, z0: np.ndarray, *, iterations: int, damping: float,
                 backtracks: int = 8) -> tuple[np.ndarray, float, int]:
        """:func:`levenberg_marquardt` in C: (z, cost, iterations)."""
        self._z[:] = z0
        done = self._lib.lm_run(self._handle, self._z_ptr, int(iterations), float(damping),
                                int(backtracks), self._cost_ref)
        return self._z.copy(), float(self._cost.value), int(done)

    def __del__(self) -> None:
        handle, self._handle = getattr(self, "_handle", None), None
        if handle:
            self._lib.lm_free(handle)


def native_banded_kernel(step: ca.Function, cost: ca.Function,
                         perm: np.ndarray) -> NativeBandedKernel | None:
    """The kernel with the LM iteration in C, or None where the floats could differ or no
    compiler is found (module docstring)."""
    blas = _blas()
    if blas is None:
        return None
    library = _library(step, cost)
    if library is None:
        return None
    return NativeBandedKernel(step, cost, perm, library, blas)


def source(step: ca.Function, cost: ca.Function) -> str:
    """The C source: CasADi's code of both kernels, then :data:`DRIVER`."""
    generator = ca.CodeGenerator("lm_loop.c", {"with_header": False})
    generator.add(step)
    generator.add(cost)
    return "\n".join([generator.dump(), f"#define STEP {step.name()}",
                      f"#define COST {cost.name()}", DRIVER])


def _library(step: ca.Function, cost: ca.Function) -> ctypes.CDLL | None:
    path = native_library(f"lm_loop_{step.name()}", source(step, cost))
    if path is None:
        return None
    return _load(str(path))


@cache
def _load(path: str) -> ctypes.CDLL:
    library = ctypes.CDLL(path)
    library.lm_new.restype = ctypes.c_void_p
    library.lm_new.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p,
                               ctypes.c_void_p, ctypes.c_longlong, ctypes.c_longlong,
                               ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int]
    library.lm_free.argtypes = [ctypes.c_void_p]
    library.lm_cost_at.restype = ctypes.c_double
    library.lm_cost_at.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
    library.lm_run.restype = ctypes.c_int
    library.lm_run.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int, ctypes.c_double,
                               ctypes.c_int, ctypes.c_void_p]
    return library


@lru_cache(maxsize=1)
def _blas() -> tuple[int, int, bool] | None:
    """(address of SciPy's dpbsv, address of NumPy's cblas_ddot, whether it takes 64-bit
    integers), or None when NumPy's OpenBLAS is not found."""
    pbsv = _capsule_address(cython_lapack.__pyx_capi__["dpbsv"])
    dot = _numpy_ddot()
    if dot is None:
        logger.info("NumPy's cblas_ddot not found: the LM iteration stays in Python")
        return None
    return pbsv, dot[0], dot[1]


def _capsule_address(capsule: object) -> int:
    get_name = ctypes.pythonapi.PyCapsule_GetName
    get_name.restype, get_name.argtypes = ctypes.c_char_p, [ctypes.py_object]
    get_pointer = ctypes.pythonapi.PyCapsule_GetPointer
    get_pointer.restype, get_pointer.argtypes = ctypes.c_void_p, [ctypes.py_object,
                                                                  ctypes.c_char_p]
    return int(get_pointer(capsule, get_name(capsule)))


#: ``cblas_ddot`` as OpenBLAS builds name it, and whether that build takes 64-bit integers.
_DDOT_NAMES: tuple[tuple[str, bool], ...] = (
    ("scipy_cblas_ddot64_", True), ("cblas_ddot64_", True), ("scipy_cblas_ddot", False),
    ("cblas_ddot", False))


def _numpy_ddot() -> tuple[int, bool] | None:
    """NumPy's ``cblas_ddot``: found in the OpenBLAS library that NumPy loaded (its path in
    ``/proc/self/maps``, so never another BLAS that happens to be installed)."""
    import numpy  # noqa: F401  (NumPy's BLAS is mapped once numpy is imported)

    maps = Path("/proc/self/maps")
    if not maps.exists():
        return None
    libraries = {line.split()[-1] for line in maps.read_text().splitlines()
                 if "openblas" in line.lower() and line.split()[-1].startswith("/")}
    numpy_dir = str(Path(np.__file__).resolve().parent.parent)
    for path in sorted(libraries, key=lambda p: not p.startswith(numpy_dir)):
        if "numpy" not in path:
            continue
        library = ctypes.CDLL(path)
        for name, ilp64 in _DDOT_NAMES:
            function = getattr(library, name, None)
            if function is not None:
                return ctypes.cast(function, ctypes.c_void_p).value or 0, ilp64
    return None


__all__ = ["NativeBandedKernel", "native_banded_kernel", "source"]
