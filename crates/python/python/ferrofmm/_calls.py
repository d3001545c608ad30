"""The one-call functions :func:`laplace`, :func:`yukawa`, :func:`helmholtz` and
:func:`stokes`: build an :class:`~ferrofmm.Fmm` for the arguments and evaluate it once."""

from __future__ import annotations

from typing import Any, Callable, Optional

from ._checks import _check_densities, _kernel, _points
from ._fmm import Fmm, FmmResult, _check_progress


def _one_call(
    kernel: str,
    k: Optional[complex],
    sources: Any,
    charges: Any,
    dipoles: Any,
    strslet: Any = None,
    strsvec: Any = None,
    **kw: Any,
) -> FmmResult:
    if charges is None and dipoles is None and strslet is None:
        raise ValueError("give charges, dipoles or both")
    if (strslet is None) != (strsvec is None):
        raise ValueError("a stresslet needs both its strength strslet and orientation strsvec")
    progress = kw.pop("progress", None)
    _check_progress(progress)
    # Every argument's shape before any work (the build takes seconds).
    n = len(_points("sources", sources))
    names = {"charges": _kernel(kernel)["density_name"]}
    given = [
        (names.get(key, key), key, value)
        for key, value in (
            ("charges", charges), ("dipoles", dipoles), ("strslet", strslet),
            ("strsvec", strsvec),
        )
        if value is not None
    ]
    checked = _check_densities(kernel, n, given)
    fmm = Fmm(
        sources, kw.pop("targets"), kernel, k=k, charges=charges is not None,
        dipoles=dipoles is not None, stresslets=strslet is not None, **kw,
    )
    return fmm._evaluate(*checked, stacklevel=4, progress=progress)


def laplace(
    sources: Any,
    charges: Any = None,
    *,
    dipoles: Any = None,
    targets: Any = None,
    eps: Optional[float] = None,
    order: Optional[int] = None,
    gradient: bool = False,
    hessian: bool = False,
    dtype: Any = None,
    threads: Optional[int] = None,
    leaf_size: Optional[int] = None,
    scheme: str = "auto",
    verify: bool = True,
    at_sources: bool = False,
    box: Any = None,
    box_origin: Any = None,
    periodic: Optional[str] = None,
    surface: Optional[str] = None,
    progress: Optional[Callable[[int, int], Any]] = None,
) -> FmmResult:
    """Laplace potentials ``phi(y) = sum_i q_i / (4 pi |y - x_i|)`` by the FMM.

    Parameters
    ----------
    sources : array_like, shape (n, 3)
        Float64 or float32 positions, any memory order (copied, never modified).
    charges : array_like, shape (n,) or (k, n), optional
        One charge per source, or ``k`` charge vectors evaluated at once.
    dipoles : array_like, shape (n, 3) or (k, n, 3), optional
        One dipole vector ``n`` per source: each adds
        ``n . grad_x K(x, y)`` (a double-layer potential). At least one of
        ``charges`` and ``dipoles``.
    targets : array_like, shape (m, 3), optional
        Evaluation points; the sources when ``None`` (self-interaction excluded).
    eps : float, optional
        Requested relative L2 error (default 1e-6 in float64, 1e-4 in
        float32); checked on a sample of targets after evaluating.
    order : int, optional
        Expansion order instead of ``eps``.
    gradient : bool
        Also return the gradient with respect to the target.
    hessian : bool
        Also return the gradient and the Hessian (``xx, yy, zz, xy, xz, yz``).
    dtype : {None, "float32", "float64"}
        Float type of the run (default: that of ``sources``).
    threads : int, optional
        Number of threads (default: one per core).
    leaf_size : int, optional
        Points per leaf (default: chosen by the cost model).
    scheme : {"auto", "svd", "dense", "fft"}
        M2L translation scheme. ``"auto"`` (default): with ``eps``, the
        SVD or the FFT scheme, whichever the cost model predicts faster for
        these points (the SVD precomputation counts unless ``cache_dir`` is
        given); with ``order``, ``"svd"``. For the Helmholtz and Stokes
        kernels, ``"fft"``.
    verify : bool
        Estimate the achieved error against direct summation on a sample.
    at_sources : bool
        With ``targets``: also the values at the sources (each excluding
        itself) from the same run, as ``result.at_sources`` (FMM3D's ``pg``
        with ``pgt``).
    box : float or sequence of 3 floats, optional
        Periodic boundaries: the side ``L`` of the cubic cell that repeats
        (three equal sides are accepted too); every target sees every
        image of every source, points outside the cell are wrapped into
        it, and each charge vector must sum to zero. Charges only, no
        Hessians. See :class:`Fmm` and :func:`ewald` (the reference sum).
    box_origin : sequence of 3 floats, optional
        The cell's lower corner (default ``(0, 0, 0)``).
    periodic : {"xyz", "xy", "x"}, optional
        Repeating axes (default ``"xyz"``; only ``"xyz"`` runs in this release).
    surface : {"tin-foil", "vacuum"}, optional
        How the lattice sum is closed (default ``"tin-foil"``).
    progress : callable, optional
        Called as ``progress(done, total)`` while the FMM passes run (rough
        cost units; at most every 0.1 s, with the GIL held, and once at the
        end with ``done == total``); see :meth:`Fmm.evaluate`. The other
        one-call functions take it too.

    Returns
    -------
    FmmResult
        ``.potential`` (m,) or (k, m), ``.gradient`` (m, 3) or (k, m, 3)
        or None, ``.hessian`` (m, 6) or (k, m, 6) or None, ``.energy``
        (``1/2 sum q phi`` without ``targets``, else None), ``.info`` (dict).

    Examples
    --------
    >>> import numpy as np, ferrofmm
    >>> x = np.random.default_rng(0).random((2000, 3))
    >>> r = ferrofmm.laplace(x, np.ones(2000), eps=1e-6)
    >>> r.potential.shape
    (2000,)

    The Madelung constant of rock salt (8 ions in the conventional cell of
    side 1, nearest neighbours 0.5 apart):

    >>> ions = np.array([[i, j, k] for i in (0, .5) for j in (0, .5) for k in (0, .5)])
    >>> q = np.where(ions.sum(axis=1) * 2 % 2 == 0, 1.0, -1.0)
    >>> r = ferrofmm.laplace(ions, q, box=1.0, eps=1e-8)
    >>> round(float(-r.potential[0] * 4 * np.pi * 0.5), 7)
    1.7475646
    """
    return _one_call("laplace", None, **locals())  # locals(): the parameters


def _with_wavenumber(kernel: str, doc: str) -> Callable[..., FmmResult]:
    """The one-call function of ``kernel``, a kernel with a wavenumber ``k`` (keyword
    only, required); its parameters are otherwise those of :func:`laplace`, ``doc`` its
    docstring."""

    def call(
        sources: Any,
        charges: Any = None,
        *,
        k: complex,
        dipoles: Any = None,
        targets: Any = None,
        eps: Optional[float] = None,
        order: Optional[int] = None,
        gradient: bool = False,
        hessian: bool = False,
        dtype: Any = None,
        threads: Optional[int] = None,
        leaf_size: Optional[int] = None,
        scheme: str = "auto",
        verify: bool = True,
        at_sources: bool = False,
        box: Any = None,
        box_origin: Any = None,
        periodic: Optional[str] = None,
        surface: Optional[str] = None,
        progress: Optional[Callable[[int, int], Any]] = None,
    ) -> FmmResult:
        arguments = dict(locals())  # the parameters, and ``kernel`` (a free variable)
        del arguments["kernel"]
        return _one_call(kernel, **arguments)

    call.__name__ = call.__qualname__ = kernel
    call.__doc__ = doc
    return call


yukawa = _with_wavenumber(
    "yukawa",
    """Yukawa (modified Helmholtz) potentials ``phi(y) = sum_i q_i exp(-k r) / (4 pi r)``.

    ``r = |y - x_i|`` and ``k >= 0`` is the screening wavenumber (inverse
    length). The other parameters and the result are as for :func:`laplace`.
    With ``box`` (periodic boundaries) the lattice sum converges absolutely:
    any charges (no neutrality), no ``surface`` term, checked against
    ``ewald(..., k=k)``.

    Examples
    --------
    >>> import numpy as np, ferrofmm
    >>> x = np.random.default_rng(0).random((2000, 3))
    >>> r = ferrofmm.yukawa(x, np.ones(2000), k=3.0, box=1.0, eps=1e-6)
    >>> ref = ferrofmm.ewald(x, np.ones(2000), 1.0, k=3.0)
    >>> bool(np.linalg.norm(r.potential - ref.potential) < 1e-6 * np.linalg.norm(ref.potential))
    True
    """,
)

helmholtz = _with_wavenumber(
    "helmholtz",
    """Helmholtz potentials ``u(y) = sum_i q_i exp(i k r) / (4 pi r) + n_i . grad_x (...)``.

    ``r = |y - x_i|``, ``k >= 0`` the wavenumber, or a complex ``k = a + bj``
    with ``b >= 0`` for damped waves ``exp(-b r) exp(i a r) / (4 pi r)`` (an
    absorbing medium; the oscillation ``a`` sets the limit below). ``charges`` is complex
    ``(n,)`` or ``(k, n)``, ``dipoles`` complex ``(n, 3)`` or ``(k, n, 3)``
    (real arrays are taken as complex); ``.potential`` is complex ``(m,)``,
    ``.gradient`` complex ``(m, 3)``, with ``hessian=True`` ``.hessian``
    complex ``(m, 6)`` (``xx, yy, zz, xy, xz, yz``). The low-frequency
    method: ``k`` times the width of the points' bounding cube is limited
    (about 6 wavelengths across), beyond it ``ValueError`` names the limit.
    ``scheme="auto"`` is the FFT scheme (it builds 7-40x faster
    than SVD at N = 2e4, to the same accuracy). The other parameters are as for
    :func:`laplace`.

    Examples
    --------
    >>> import numpy as np, ferrofmm
    >>> x = np.random.default_rng(0).random((2000, 3))
    >>> r = ferrofmm.helmholtz(x, np.ones(2000) + 0.5j, k=10.0, eps=1e-6)
    >>> r.potential.dtype
    dtype('complex128')
    >>> damped = ferrofmm.helmholtz(x, np.ones(2000), k=10.0 + 2.0j, eps=1e-6)
    >>> bool(np.abs(damped.potential).max() < np.abs(r.potential).max())
    True
    """,
)


def stokes(
    sources: Any,
    forces: Any = None,
    *,
    strslet: Any = None,
    strsvec: Any = None,
    pressure: bool = False,
    targets: Any = None,
    eps: Optional[float] = None,
    order: Optional[int] = None,
    gradient: bool = False,
    dtype: Any = None,
    threads: Optional[int] = None,
    leaf_size: Optional[int] = None,
    scheme: str = "auto",
    verify: bool = True,
    at_sources: bool = False,
    box: Any = None,
    box_origin: Any = None,
    periodic: Optional[str] = None,
    surface: Optional[str] = None,
    progress: Optional[Callable[[int, int], Any]] = None,
) -> FmmResult:
    """Stokes flow of point forces and stresslets, and its pressure (FMM3D's ``stfmm3d``).

    ``u(y) = sum_i G(y - x_i) f_i`` with the Stokeslet
    ``G(d) = (I / r + d d^T / r^3) / (8 pi)`` (viscosity 1; for viscosity
    ``mu`` divide the velocity by ``mu``; FMM3D's ``stfmm3d`` uses the same
    normalisation), plus for stresslets (``strslet`` strengths ``m`` and
    ``strsvec`` orientations ``n``, FMM3D's names) ``3 d (d . m)(d . n) /
    (4 pi r^5)``, ``d`` the target minus the source. ``forces``, ``strslet``
    and ``strsvec`` are ``(n, 3)`` or ``(k, n, 3)``; give forces,
    stresslets or both. ``.potential`` is the velocity ``(m, 3)``,
    ``.gradient`` the velocity gradient ``(m, 3, 3)`` with
    ``[j, a, c] = d u_a / d x_c`` at target ``j``. With ``pressure=True``,
    ``.pressure`` is the pressure ``(m,)`` (FMM3D's ``pre``: ``f . d / (4 pi
    r^3)`` for a force, ``(6 (d . m)(d . n) / r^5 - 2 (m . n) / r^3) / (4
    pi)`` for a stresslet) and, with ``gradient=True``,
    ``.pressure_gradient`` its gradient ``(m, 3)``. Stresslets and the
    pressure run one Laplace FMM beside the Stokes one, in free space only.
    No Hessians. ``scheme="auto"`` is the FFT scheme (as for
    :func:`helmholtz`). The other parameters are as for :func:`laplace`.

    Examples
    --------
    >>> import numpy as np, ferrofmm
    >>> x = np.random.default_rng(0).random((2000, 3))
    >>> r = ferrofmm.stokes(x, np.ones((2000, 3)), eps=1e-6, gradient=True)
    >>> r.potential.shape, r.gradient.shape
    ((2000, 3), (2000, 3, 3))
    >>> normals = x - 0.5
    >>> r = ferrofmm.stokes(x, strslet=np.ones((2000, 3)), strsvec=normals, pressure=True)
    >>> r.potential.shape, r.pressure.shape
    ((2000, 3), (2000,))
    """
    if forces is None and strslet is None:
        raise ValueError("give the forces, shape (n, 3), or stresslets (strslet and strsvec)")
    return _one_call(
        "stokes", None, sources, forces, None, strslet, strsvec, pressure=pressure,
        targets=targets, eps=eps, order=order,
        gradient=gradient, dtype=dtype, threads=threads, leaf_size=leaf_size,
        scheme=scheme, verify=verify, at_sources=at_sources,
        box=box, box_origin=box_origin, periodic=periodic, surface=surface,
        progress=progress,
    )
