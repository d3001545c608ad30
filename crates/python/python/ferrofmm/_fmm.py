"""The FMM classes and one-call functions of the package: :class:`Fmm`, :class:`FmmResult`,
:func:`laplace`, :func:`yukawa`, :func:`helmholtz`, :func:`stokes`, and the Ewald reference sum
:func:`ewald`."""

from __future__ import annotations

import json
import warnings
from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np

from . import _ferrofmm
from ._checks import (
    _as_complex_array,
    _bool,
    _cache,
    _cell,
    _check_densities,
    _check_eps_order,
    _check_float32_range,
    _check_memory,
    _flat,
    _float_dtype,
    _kernel,
    _native,
    _per_source,
    _per_target,
    _points,
    _positive_int,
    _real,
    _vector_valued,
)
from ._ferrofmm import (
    DEFAULT_F32_TOLERANCE,
    DEFAULT_LEAF_SIZE,
    DEFAULT_TOLERANCE,
    MAX_ORDER,
    MIN_ORDER,
)

#: Tolerance used when neither ``eps`` nor ``order`` is given, per dtype
#: (the library's ``DEFAULT_TOLERANCE`` and ``DEFAULT_F32_TOLERANCE``, the
#: defaults of the command-line tools too).
DEFAULT_EPS = {
    np.dtype(np.float64): DEFAULT_TOLERANCE,
    np.dtype(np.float32): DEFAULT_F32_TOLERANCE,
}


class AccuracyWarning(UserWarning):
    """The error measured after an evaluation is above the ``eps`` asked for.

    Issued once per :class:`Fmm`, by the evaluation that verified the
    tolerance (``info["verified"]`` is then ``False`` and
    ``info["measured_error"]`` holds the estimate). Turn it into an error
    with ``warnings.simplefilter("error", ferrofmm.AccuracyWarning)``.
    """


class FmmResult:
    """What an evaluation returns.

    Attributes
    ----------
    potential : numpy.ndarray
        ``(m,)`` for one charge vector, ``(k, m)`` for ``k`` vectors.
    gradient : numpy.ndarray or None
        ``(m, 3)`` or ``(k, m, 3)``: the gradient of the potential with
        respect to the target; ``None`` unless ``gradient=True`` (or
        ``hessian=True``).
    hessian : numpy.ndarray or None
        ``(m, 6)`` or ``(k, m, 6)``: the second derivatives with respect to
        the target, ``xx, yy, zz, xy, xz, yz``; ``None`` unless
        ``hessian=True``.
    at_sources : FmmResult or None
        With ``at_sources=True`` and separate targets: the values at the
        sources (each excluding itself) from the same run, as an
        ``FmmResult`` of their own (FMM3D's ``pg`` with ``pgt``).
    energy : float or numpy.ndarray or None
        ``E = 1/2 sum_i q_i phi_i`` when charges of a scalar kernel
        (Laplace, Yukawa) were evaluated at the sources themselves (no
        ``targets``, no dipoles): a float, or ``(k,)`` for ``k`` charge
        vectors; in a periodic cell, the energy per cell. ``None``
        otherwise.
    info : dict
        ``order``, ``leaf_size``, ``scheme``, ``kernel``, ``kernel_name``
        (the name in :data:`KERNELS`), ``dtype``,
        ``eps``, ``predicted_error``, ``measured_error`` (estimated on a
        sample of targets against direct summation, for the first
        evaluation of a tolerance), ``verified``, ``threads``, tree figures
        and ``timings`` (seconds, ``setup`` and ``evaluate`` per operator);
        ``periodic``: ``None`` in free space, else the cell (``box``, the
        three sides; ``origin``; ``axes``, e.g. ``"xyz"``; ``surface``,
        ``"tin-foil"`` or ``"vacuum"``).
    """

    __slots__ = ("potential", "gradient", "hessian", "info", "at_sources", "energy")

    def __init__(
        self,
        potential: np.ndarray,
        gradient: Optional[np.ndarray],
        info: Dict[str, Any],
        hessian: Optional[np.ndarray] = None,
        energy: Any = None,
    ):
        self.potential = potential
        self.gradient = gradient
        self.hessian = hessian
        self.info = info
        self.at_sources: Optional["FmmResult"] = None
        self.energy = energy

    def __repr__(self) -> str:
        g = None if self.gradient is None else self.gradient.shape
        h = "" if self.hessian is None else f", hessian={self.hessian.shape}"
        e = "" if self.energy is None or np.ndim(self.energy) else f", energy={self.energy:.6g}"
        return (
            f"FmmResult(potential={self.potential.shape}, gradient={g}{h}{e}, "
            f"order={self.info.get('order')}, dtype={self.info.get('dtype')})"
        )


class Fmm:
    """A fast multipole method built once for fixed points, kernel and accuracy.

    Parameters
    ----------
    sources : array_like, shape (n, 3)
        Source positions, float64 or float32 (any memory order).
    targets : array_like, shape (m, 3), optional
        Where to evaluate; the sources when ``None`` (then a source does
        not act on itself).
    kernel : {"laplace", "yukawa", "helmholtz", "stokes"}
        ``1 / (4 pi r)``, ``exp(-k r) / (4 pi r)`` (give ``k``),
        ``exp(i k r) / (4 pi r)`` (give ``k``; complex charges, dipoles and
        results) or the Stokeslet ``(I / r + d d^T / r^3) / (8 pi)``
        (viscosity 1: forces ``(n, 3)`` in, velocities ``(m, 3)`` and
        velocity gradients ``(m, 3, 3)`` out, ``[..., a, c] = d u_a / d x_c``).
    k : float, optional
        The wavenumber of the yukawa (screening) or helmholtz (oscillation)
        kernel (``k >= 0``). Helmholtz is the low-frequency method: ``k``
        times the domain width is limited (about 6 wavelengths), beyond
        it the build raises ``ValueError`` naming the limit.
    eps : float, optional
        Requested relative L2 error of the potential (and of the gradient
        when ``gradient=True``). The order and leaf size are chosen from it;
        the first evaluation estimates the achieved error on a sample of
        targets and raises the order (at most twice) when it falls short.
        Default: 1e-6 in float64, 1e-4 in float32, unless ``order`` is given.
    order : int, optional
        Expansion order instead of ``eps`` (``MIN_ORDER..=MAX_ORDER``): the
        leaf size and (``scheme="auto"``) the scheme are chosen for it by
        the cost model, or a direct sum where that is faster.
    leaf_size : int, optional
        Points per leaf at most (default: chosen by the cost model; a given
        leaf size always builds a tree, never a direct sum).
    gradient : bool
        Also compute gradients.
    hessian : bool
        Also compute gradients and Hessians (``xx, yy, zz, xy, xz, yz``).
    charges : bool
        The sources carry charges (default ``True``).
    dipoles : bool
        The sources carry dipole vectors ``n`` (default ``False``): each
        adds ``n . grad_x K(x, y)``, a double-layer potential (FMM3D's
        ``dipvec``, same sign). With ``charges=False`` too, dipoles only.
    dtype : {None, "float32", "float64"}
        Float type of the run; ``None`` follows ``sources``.
    threads : int, optional
        Threads (lowered to the number of cores); ``None``: one per core
        (or ``RAYON_NUM_THREADS``).
    scheme : {"auto", "svd", "dense", "fft"}
        M2L translation scheme. ``"auto"`` (default): with ``eps``, the
        SVD or the FFT scheme, whichever the cost model predicts faster for
        these points (the SVD precomputation counts unless ``cache_dir`` is
        given); with ``order``, ``"svd"``. For the Helmholtz and Stokes
        kernels, ``"fft"``.
    verify : bool
        Check ``eps`` on the first evaluation (a few percent of its time).
    cache_dir : str or os.PathLike, optional
        Directory for the on-disk operator cache (as ``cache="path"``).
    cache : bool or str or os.PathLike
        The on-disk operator cache. ``True`` (default): the default folder,
        ``FERROFMM_CACHE`` (a folder, or ``off``), else
        ``$XDG_CACHE_HOME/ferrofmm``, else ``~/.cache/ferrofmm``, at most
        ``FERROFMM_CACHE_SIZE`` bytes of it kept (default 2 GiB, least
        recently used files deleted first); a default folder that cannot
        be written leaves the operators in memory (a ``RuntimeWarning``).
        ``False``: memory only. A path: that folder. ``info["cache"]`` and
        ``info["cache_dir"]`` say what happened and where.
    at_sources : bool
        With ``targets``: also evaluate at the sources in the same run
        (each source excluding itself); ``evaluate`` then returns them as
        ``result.at_sources``. The sources are added as targets.
    box : float or sequence of 3 floats, optional
        Periodic boundaries (Laplace kernel, charges): the side ``L`` of
        the cubic cell ``[box_origin, box_origin + L)^3`` that repeats
        along ``periodic``; every target sees every image of every source
        (the Ewald convention). Points outside the cell are wrapped into
        it; results come in the caller's order. The charges of each
        vector must sum to zero (``ValueError`` at evaluation otherwise).
        Three sides are accepted but only cubes run in this release; other
        kernels, dipoles and Hessians with a box are refused
        (``ValueError``). ``eps`` is chosen and verified as in free space,
        against an Ewald sum.
    box_origin : sequence of 3 floats, optional
        The cell's lower corner (default ``(0, 0, 0)``); needs ``box``.
    periodic : {"xyz", "xy", "x"}, optional
        Axes that repeat (default ``"xyz"`` with ``box``); only ``"xyz"``
        runs in this release. Needs ``box``.
    surface : {"tin-foil", "vacuum"}, optional
        How the lattice sum is closed at infinity: ``"tin-foil"``
        (default; conducting surroundings, Ewald without its ``k = 0``
        term, as particle-mesh Ewald codes) or ``"vacuum"`` (adds the
        cell's dipole term). Needs ``box``.
    """

    def __init__(
        self,
        sources: Any,
        targets: Any = None,
        kernel: str = "laplace",
        *,
        k: Optional[float] = None,
        eps: Optional[float] = None,
        order: Optional[int] = None,
        leaf_size: Optional[int] = None,
        gradient: bool = False,
        dtype: Any = None,
        threads: Optional[int] = None,
        scheme: str = "auto",
        verify: bool = True,
        cache_dir: Any = None,
        cache: Any = True,
        hessian: bool = False,
        charges: bool = True,
        dipoles: bool = False,
        at_sources: bool = False,
        box: Any = None,
        box_origin: Any = None,
        periodic: Optional[str] = None,
        surface: Optional[str] = None,
    ) -> None:
        cell = _cell(box, box_origin, periodic, surface)
        charges, dipoles = _bool("charges", charges), _bool("dipoles", dipoles)
        gradient, hessian = _bool("gradient", gradient), _bool("hessian", hessian)
        verify, at_sources = _bool("verify", verify), _bool("at_sources", at_sources)
        if not (charges or dipoles):
            raise ValueError("the sources carry nothing: set charges=True or dipoles=True")
        source = {(True, False): "charge", (False, True): "dipole", (True, True): "charge+dipole"}[
            (charges, dipoles)
        ]
        src = _points("sources", sources)
        tgt = None if targets is None else _points("targets", targets)
        run = _float_dtype(dtype) or _native(src.dtype)
        _check_eps_order(eps, order)
        if eps is None and order is None:
            eps = DEFAULT_EPS[run]
        _kernel(kernel)
        if not isinstance(scheme, str) or scheme not in _ferrofmm.SCHEMES:
            raise ValueError(f'unknown M2L scheme {scheme!r}: use "auto", "svd", "dense" or "fft"')
        k = _real("k", k)
        leaf_size = _positive_int("leaf_size", leaf_size)
        threads = _positive_int("threads", threads)
        cache_dir, default_cache = _cache(cache, cache_dir)
        # Values at the sources too: the sources lead the targets (a target
        # on a source skips it, K(x, x) := 0).
        self._n_at_sources = len(src) if (at_sources and tgt is not None) else 0
        n_targets = None if tgt is None else len(tgt) + self._n_at_sources
        # Nothing copied yet: refuse a run that cannot fit first.
        _check_memory(
            f"an FMM of {len(src)} sources and {n_targets or len(src)} targets ({run})",
            run, len(src), n_targets, _per_source(kernel, charges, dipoles),
            _per_target(kernel, gradient, hessian), 1,
        )
        if self._n_at_sources:
            tgt = np.concatenate([src, tgt])
        # Points go over in their own precision (float64 unless both sets
        # are float32): a float32 run rounds them only relative to the
        # tree's origin, so a domain far from zero keeps its separations.
        wide = _native(np.result_type(src, np.float32 if tgt is None else tgt))
        self._native = _ferrofmm.NativeFmm(
            _flat(src, wide),
            None if tgt is None else _flat(tgt, wide),
            kernel,
            k,
            None if eps is None else float(eps),
            None if order is None else int(order),
            leaf_size,
            scheme,
            gradient,
            verify,
            threads,
            cache_dir,
            hessian,
            source,
            str(run),
            default_cache,
            *cell,
        )
        self._dtype = run
        self._kernel = kernel
        self._hessian = bool(hessian)
        self._gradient = bool(gradient) or self._hessian
        self._charges = charges
        self._dipoles = dipoles
        self._last_info: Optional[Dict[str, Any]] = None
        self._accuracy_warned = False

    @property
    def n_sources(self) -> int:
        """Number of sources."""
        return self._native.n_sources

    @property
    def n_targets(self) -> int:
        """Number of targets (without the sources added by ``at_sources``)."""
        return self._native.n_targets - self._n_at_sources

    @property
    def dtype(self) -> np.dtype:
        """Float type of the run."""
        return self._dtype

    def evaluate(
        self,
        charges: Any = None,
        dipoles: Any = None,
        *,
        progress: Optional[Callable[[int, int], Any]] = None,
    ) -> FmmResult:
        """Potentials (and gradients, Hessians) at the targets.

        ``charges`` is ``(n,)`` (one value per source) or ``(k, n)`` for
        ``k`` charge vectors evaluated in one call; ``dipoles`` is
        ``(n, 3)`` or ``(k, n, 3)``. Give what the sources were built to
        carry (``charges=True`` / ``dipoles=True`` of :class:`Fmm`);
        nothing is rebuilt.

        ``progress``, when given, is called as ``progress(done, total)``
        while the FMM passes run: the work done and in all, in rough cost
        units (the time left is about ``elapsed * (total - done) / done``).
        It is called from the calling thread with the GIL held, at most
        every 0.1 s and once at the end with ``done == total``; ``total``
        may grow once when the accuracy check raises the order. An
        exception it raises ends the call with that exception.
        """
        _check_progress(progress)
        given = []
        for name, value, wanted, flag in (
            ("charges", charges, self._charges, "charges"),
            ("dipoles", dipoles, self._dipoles, "dipoles"),
        ):
            if value is None:
                if wanted:
                    raise ValueError(f"this Fmm's sources carry {name}: give {name}")
                continue
            if not wanted:
                carried = "charges" if self._charges else "dipoles"
                raise ValueError(
                    f"this Fmm's sources carry no {name} (only {carried}): "
                    f"build it with {flag}=True"
                )
            given.append((name, name, value))
        return self._evaluate(
            *_check_densities(self._kernel, self.n_sources, given), progress=progress
        )

    def _evaluate(
        self,
        arrays: List[Tuple[str, np.ndarray, Tuple[int, ...]]],
        k: int,
        batched: bool,
        stacklevel: int = 3,
        progress: Optional[Callable[[int, int], Any]] = None,
    ) -> FmmResult:
        """Evaluate densities checked by :func:`_check_densities`.

        ``stacklevel`` points an :class:`AccuracyWarning` at the caller's line.
        """
        n = self.n_sources
        m = self._native.n_targets
        _check_memory(
            f"evaluating {k} density vector(s) for {n} sources and {m} targets ({self._dtype})",
            self._dtype, n, m, _per_source(self._kernel, self._charges, self._dipoles),
            _per_target(self._kernel, self._gradient, self._hessian), k, build=False,
        )
        dens = _pack_densities(self._kernel, self._dtype, arrays, n, batched)
        values, info_json = self._native.evaluate(_flat(dens, self._dtype), k, progress)
        info = json.loads(info_json)
        info["kernel_name"] = self._kernel
        energies = info.pop("energy", None) or []
        energy: Any = None
        if energies and all(e is not None for e in energies):
            energy = float(energies[0]) if not batched else np.array(energies, dtype=np.float64)
        self._last_info = info
        if info.get("verified") is False and not self._accuracy_warned:
            self._accuracy_warned = True
            measured = info.get("measured_error") or {}
            errors = ", ".join(
                f"{q} {measured[q]:.2e}"
                for q in ("potential", "gradient", "hessian")
                if measured.get(q) is not None
            )
            warnings.warn(
                f"the tolerance eps={info.get('eps'):g} was not met: error measured on "
                f"{measured.get('sampled_targets')} sampled targets: {errors} at order "
                f"{info.get('order')} (info['verified'] is False); the results are returned. "
                f"Ask for a larger eps (or float64), or give order",
                AccuracyWarning,
                stacklevel=stacklevel,
            )
        m = self._native.n_targets
        potential, gradient, hessian = _shape_values(
            self._kernel, values, k, m, self._gradient, self._hessian, batched
        )
        ns = self._n_at_sources
        if not ns:
            return FmmResult(potential, gradient, info, hessian, energy)

        # The target axis is the last of the potential's axes.
        def split(a: Optional[np.ndarray], lo: int, hi: Optional[int]) -> Optional[np.ndarray]:
            if a is None:
                return None
            axis = potential.ndim - (2 if _vector_valued(self._kernel) else 1)
            index = [slice(None)] * a.ndim
            index[axis] = slice(lo, hi)
            return np.ascontiguousarray(a[tuple(index)])

        result = FmmResult(
            split(potential, ns, None), split(gradient, ns, None), info, split(hessian, ns, None)
        )
        result.at_sources = FmmResult(
            split(potential, 0, ns), split(gradient, 0, ns), info, split(hessian, 0, ns)
        )
        return result

    def summary(self) -> Dict[str, Any]:
        """Tree, operator and parameter figures (a dict; as the CLI's ``--json``)."""
        return json.loads(self._native.summary_json())

    def timings(self) -> Dict[str, Any]:
        """Seconds of the setup (``setup``) and of the last evaluation (``evaluate``)."""
        out: Dict[str, Any] = {"setup": json.loads(self._native.setup_timings_json())}
        if self._last_info is not None:
            out["evaluate"] = self._last_info["timings"]["evaluate"]
        return out

    def __repr__(self) -> str:
        return f"Fmm(n_sources={self.n_sources}, n_targets={self.n_targets}, dtype={self._dtype})"


def _pack_densities(
    kernel: str,
    dtype: np.dtype,
    arrays: List[Tuple[str, np.ndarray, Tuple[int, ...]]],
    n: int,
    batched: bool,
) -> np.ndarray:
    """Densities checked by :func:`_check_densities` as one ``(k, n, values per source)``
    array in the kernel's layout: complex values as ``(re, im)`` pairs, charges before
    dipoles."""
    parts = []
    for name, a, _tail in arrays:
        if not batched:
            a = a[None]
        if _kernel(kernel)["complex"]:
            a = _as_complex_array(name, a)
            # Complex values as (re, im) pairs, the kernel's layout.
            a = np.stack((a.real, a.imag), axis=-1)
        if dtype == np.float32 and a.dtype.itemsize > 4:
            _check_float32_range(name, a)
        parts.append(a.reshape(a.shape[0], n, int(np.prod(a.shape[2:], dtype=np.int64))))
    return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=2)


def _shape_values(
    kernel_name: str,
    values: np.ndarray,
    k: int,
    m: int,
    gradient: bool,
    hessian: bool,
    batched: bool,
) -> Tuple[np.ndarray, Optional[np.ndarray], Optional[np.ndarray]]:
    """The flat values of ``k`` vectors at ``m`` targets as ``(potential, gradient,
    hessian)``: complex for a complex kernel, ``(.., m, 3)`` velocities and ``(.., m, 3,
    3)`` velocity gradients for a vector-valued one; the leading ``k`` axis dropped
    unless ``batched``."""
    per = 10 if hessian else 4 if gradient else 1
    kernel = _kernel(kernel_name)
    v = values.reshape(k, m, per, kernel["components"])
    if kernel["complex"]:
        v = (v[..., 0] + 1j * v[..., 1])[..., None]
    if _vector_valued(kernel_name):
        # (k, m, quantity, component): velocity, then its derivatives;
        # the gradient as [a, c] = d u_a / d x_c.
        pot = np.ascontiguousarray(v[:, :, 0, :])
        grad = np.ascontiguousarray(np.swapaxes(v[:, :, 1:4, :], 2, 3)) if gradient else None
        hess = None
    else:
        v = v[..., 0]
        pot = np.ascontiguousarray(v[:, :, 0])
        grad = np.ascontiguousarray(v[:, :, 1:4]) if gradient else None
        hess = np.ascontiguousarray(v[:, :, 4:]) if hessian else None
    if not batched:
        pot = pot[0]
        grad = None if grad is None else grad[0]
        hess = None if hess is None else hess[0]
    return pot, grad, hess


def _check_progress(progress: Any) -> None:
    """A clear error for a ``progress`` that cannot be called."""
    if progress is not None and not callable(progress):
        raise TypeError(
            "progress must be a callable taking (done, total) or None, "
            f"not {type(progress).__name__}"
        )


def _one_call(
    kernel: str, k: Optional[float], sources: Any, charges: Any, dipoles: Any, **kw: Any
) -> FmmResult:
    if charges is None and dipoles is None:
        raise ValueError("give charges, dipoles or both")
    progress = kw.pop("progress", None)
    _check_progress(progress)
    # Every argument's shape before any work (the build takes seconds).
    n = len(_points("sources", sources))
    names = {"charges": _kernel(kernel)["density_name"]}
    given = [
        (names.get(key, key), key, value)
        for key, value in (("charges", charges), ("dipoles", dipoles))
        if value is not None
    ]
    checked = _check_densities(kernel, n, given)
    fmm = Fmm(
        sources, kw.pop("targets"), kernel, k=k, charges=charges is not None,
        dipoles=dipoles is not None, **kw,
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
    return _one_call(
        "laplace", None, sources, charges, dipoles, targets=targets, eps=eps, order=order,
        gradient=gradient, hessian=hessian, dtype=dtype, threads=threads,
        leaf_size=leaf_size, scheme=scheme, verify=verify, at_sources=at_sources,
        box=box, box_origin=box_origin, periodic=periodic, surface=surface,
        progress=progress,
    )


def yukawa(
    sources: Any,
    charges: Any = None,
    *,
    k: float,
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
    """Yukawa (modified Helmholtz) potentials ``phi(y) = sum_i q_i exp(-k r) / (4 pi r)``.

    ``r = |y - x_i|`` and ``k >= 0`` is the screening wavenumber (inverse
    length). The other parameters and the result are as for :func:`laplace`;
    periodic boundaries (``box``) run the Laplace kernel only in this
    release (``ValueError``).
    """
    return _one_call(
        "yukawa", k, sources, charges, dipoles, targets=targets, eps=eps, order=order,
        gradient=gradient, hessian=hessian, dtype=dtype, threads=threads,
        leaf_size=leaf_size, scheme=scheme, verify=verify, at_sources=at_sources,
        box=box, box_origin=box_origin, periodic=periodic, surface=surface,
        progress=progress,
    )


def helmholtz(
    sources: Any,
    charges: Any = None,
    *,
    k: float,
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
    """Helmholtz potentials ``u(y) = sum_i q_i exp(i k r) / (4 pi r) + n_i . grad_x (...)``.

    ``r = |y - x_i|``, ``k >= 0`` the wavenumber. ``charges`` is complex
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
    """
    return _one_call(
        "helmholtz", k, sources, charges, dipoles, targets=targets, eps=eps, order=order,
        gradient=gradient, hessian=hessian, dtype=dtype, threads=threads, leaf_size=leaf_size,
        scheme=scheme, verify=verify, at_sources=at_sources,
        box=box, box_origin=box_origin, periodic=periodic, surface=surface,
        progress=progress,
    )


def stokes(
    sources: Any,
    forces: Any,
    *,
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
    """Stokes flow of point forces: ``u(y) = sum_i G(y - x_i) f_i`` with the Stokeslet.

    ``G(d) = (I / r + d d^T / r^3) / (8 pi)`` (viscosity 1; for viscosity
    ``mu`` divide the result by ``mu``; FMM3D's ``stfmm3d`` uses the same
    normalisation). ``forces`` is ``(n, 3)`` or ``(k, n, 3)``; ``.potential`` is
    the velocity ``(m, 3)``, ``.gradient`` the velocity gradient
    ``(m, 3, 3)`` with ``[j, a, c] = d u_a / d x_c`` at target ``j``. No
    dipoles (stresslets) and no Hessians. ``scheme="auto"`` is the FFT
    scheme (as for :func:`helmholtz`). The other parameters are as for
    :func:`laplace`.

    Examples
    --------
    >>> import numpy as np, ferrofmm
    >>> x = np.random.default_rng(0).random((2000, 3))
    >>> r = ferrofmm.stokes(x, np.ones((2000, 3)), eps=1e-6, gradient=True)
    >>> r.potential.shape, r.gradient.shape
    ((2000, 3), (2000, 3, 3))
    """
    if forces is None:
        raise ValueError("give the forces, shape (n, 3)")
    return _one_call(
        "stokes", None, sources, forces, None, targets=targets, eps=eps, order=order,
        gradient=gradient, dtype=dtype, threads=threads, leaf_size=leaf_size,
        scheme=scheme, verify=verify, at_sources=at_sources,
        box=box, box_origin=box_origin, periodic=periodic, surface=surface,
        progress=progress,
    )


def ewald(
    points: Any,
    charges: Any,
    box: Any,
    *,
    targets: Any = None,
    box_origin: Any = (0.0, 0.0, 0.0),
    gradient: bool = False,
    eps: float = 1e-12,
    threads: Optional[int] = None,
) -> FmmResult:
    """The Ewald sum of charges in a periodic cell: the reference of ``laplace(..., box=)``.

    ``phi(y) = sum_i sum_n q_i / (4 pi |y - x_i - n L|)`` over every image
    ``n`` of every charge (a source leaves out its own direct term, its
    images kept), closed with tin-foil (conducting) surroundings as
    :func:`laplace` with ``box`` and ``surface="tin-foil"``. Direct
    summation split by Ewald's method, ``O(N^1.5)``: a reference for a
    few thousand points, not a solver.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Charge positions (float64 or float32; computed in float64).
        Points outside the cell are wrapped into it.
    charges : array_like, shape (n,)
        One charge per point. A cell that is not neutral gets a uniform
        background of total charge ``-sum q`` (Ewald's convention; the
        periodic FMM refuses such a cell).
    box : float or sequence of 3 floats
        The cell's side ``L``, or its sides ``(Lx, Ly, Lz)``: orthorhombic
        cells run here (the FMM takes cubes only).
    targets : array_like, shape (m, 3), optional
        Where to evaluate; the points themselves when ``None``.
    box_origin : sequence of 3 floats
        The cell's lower corner (default ``(0, 0, 0)``).
    gradient : bool
        Also the gradient with respect to the target.
    eps : float
        Relative truncation tolerance of the real and reciprocal sums, in
        ``(0, 1)`` (the errors stay below it relative to the root mean
        square of the values; the floor is a few ``1e-15``).
    threads : int, optional
        Threads (default: one per core, or ``RAYON_NUM_THREADS``).

    Returns
    -------
    FmmResult
        ``.potential`` (m,) float64, ``.gradient`` (m, 3) or None,
        ``.energy`` (``1/2 sum q phi`` per cell without ``targets``, else
        None), ``.info`` (``method`` ``"ewald"``, ``eps``, ``alpha``,
        ``r_cut``, ``k_cut``, ``wave_vectors``, ``total_charge``,
        ``periodic``, ``timings``).

    Examples
    --------
    >>> import numpy as np, ferrofmm
    >>> x = np.array([[0.0, 0.0, 0.0], [0.5, 0.5, 0.5]])      # CsCl
    >>> r = ferrofmm.ewald(x, [1.0, -1.0], 1.0)
    >>> round(float(-r.potential[0] * 4 * np.pi * np.sqrt(3) / 2), 9)  # Madelung constant
    1.762674773
    """
    gradient = _bool("gradient", gradient)
    src = _points("points", points)
    tgt = None if targets is None else _points("targets", targets)
    q = np.asarray(charges) if not isinstance(charges, np.ndarray) else charges
    if q.dtype.kind in "iu":
        q = q.astype(np.float64)
    checked, _, batched = _check_densities("laplace", len(src), [("charges", "charges", q)])
    if batched:
        raise ValueError(f"charges must have shape ({len(src)},): one charge vector")
    lengths, origin, _, _ = _cell(box, box_origin, None, None)
    eps_value = _real("eps", eps)
    if eps_value is None:
        raise TypeError("eps must be a float, got None")
    threads = _positive_int("threads", threads)
    wide = np.dtype(np.float64)
    values, energy, info_json = _ferrofmm.ewald_sum(
        _flat(src, wide),
        _flat(checked[0][1], wide),
        lengths,
        origin if origin is not None else [0.0, 0.0, 0.0],
        None if tgt is None else _flat(tgt, wide),
        gradient,
        eps_value,
        threads,
    )
    info = json.loads(info_json)
    info["kernel_name"] = "laplace"
    v = values.reshape(-1, 4 if gradient else 1)
    potential = np.ascontiguousarray(v[:, 0])
    grad = np.ascontiguousarray(v[:, 1:4]) if gradient else None
    return FmmResult(potential, grad, info, None, energy)
