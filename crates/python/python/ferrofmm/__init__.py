"""ferrofmm: the kernel-independent fast multipole method (KIFMM) in 3D.

Computes, for N sources x_i with charges q_i (and / or dipole vectors n_i)
and M targets y_j,

    phi(y_j) = sum_i q_i K(x_i, y_j) + n_i . grad_x K(x_i, y_j)   (K(x, x) := 0)

and optionally grad phi(y_j) and its Hessian, in O(N + M) work to a
requested accuracy, for the Laplace kernel K = 1 / (4 pi r), the Yukawa
(modified Helmholtz) kernel K = exp(-k r) / (4 pi r), the Helmholtz kernel
K = exp(i k r) / (4 pi r) (complex charges and results, :func:`helmholtz`)
and the Stokeslet (forces in, velocities out, :func:`stokes`).

One call::

    import numpy as np, ferrofmm
    x = np.random.rand(100_000, 3)
    q = np.random.rand(100_000) - 0.5
    r = ferrofmm.laplace(x, q, eps=1e-6, gradient=True)
    r.potential            # (100000,)
    r.gradient             # (100000, 3)
    r.info["measured_error"]

Build once, evaluate many times (iterative solvers)::

    fmm = ferrofmm.Fmm(x, eps=1e-6)
    for q in charge_vectors:
        phi = fmm.evaluate(q).potential

Periodic boundaries (Laplace, a neutral cubic cell of side L; points are wrapped into it)::

    r = ferrofmm.laplace(x, q - q.mean(), box=1.0, eps=1e-8, gradient=True)
    r.energy               # 1/2 sum q phi, per cell
    ferrofmm.ewald(x, q - q.mean(), 1.0)     # the Ewald reference sum
    ferrofmm.yukawa(x, q, k=3.0, box=1.0)    # screened: any charges
    ferrofmm.ewald(x, q, 1.0, k=3.0)         # its reference sum
    ferrofmm.stokes(x, f, box=1.0)           # Hasimoto: any forces, zero mean velocity
    ferrofmm.stokes_ewald(x, f, 1.0)         # its reference sum

The octree on its own: ``ferrofmm.Octree(points, leaf_size=64)``.

The cost model measured on this machine (once; later runs with the same cache folder,
processor and threads choose their leaf size and scheme with it): ``ferrofmm.calibrate()``.

Files as the ``ferrofmm`` command reads and writes them (``.csv``, ``.npy``, raw ``.f64``)::

    x = ferrofmm.load("points.csv")                       # (n, 3)
    q = ferrofmm.load("q.npy", "charges", kernel="helmholtz")   # (n,) complex128
    ferrofmm.save("out.npy", ferrofmm.helmholtz(x, q, k=2.0))

Arrays are (n, 3) float64 or float32, in any memory order; they are copied,
never modified. The run's float type follows the sources unless ``dtype``
says otherwise. Bad input raises ValueError or TypeError; the GIL is
released while the library works, and Ctrl-C interrupts within a second.
"""

from __future__ import annotations

from . import _ferrofmm
from ._ferrofmm import DEEPEST_LEVEL, DEFAULT_LEAF_SIZE, MAX_ORDER, MIN_ORDER
from ._calibration import calibrate
from ._calls import helmholtz, laplace, stokes, yukawa
from ._ewald import ewald, stokes_ewald
from ._fmm import DEFAULT_EPS, AccuracyWarning, Fmm, FmmResult
from ._files import load, save
from ._octree import Octree

__version__: str = _ferrofmm.__version__

#: The built-in kernels: name -> description (components, whether complex, the parameter's
#: keyword, ...), read from the library's kernel registry.
KERNELS = _ferrofmm.KERNELS

__all__ = [
    "laplace",
    "yukawa",
    "helmholtz",
    "stokes",
    "ewald",
    "stokes_ewald",
    "Fmm",
    "FmmResult",
    "Octree",
    "load",
    "save",
    "calibrate",
    "AccuracyWarning",
    "KERNELS",
    "DEFAULT_EPS",
    "MIN_ORDER",
    "MAX_ORDER",
    "DEFAULT_LEAF_SIZE",
    "DEEPEST_LEVEL",
    "__version__",
]
