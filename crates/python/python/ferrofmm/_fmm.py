"""The FMM classes of the package: :class:`Fmm` (built once, evaluated many times),
:class:`FmmResult` and :class:`AccuracyWarning`. The one-call functions are in
``_calls``, the Ewald reference sum in ``_ewald``."""

from __future__ import annotations

import json
import warnings
from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np

from . import _ferrofmm
from ._checks import (
    _bool,
    _cache,
    _carried,
    _cell,
    _check_densities,
    _check_eps_order,
    _check_memory,
    _flat,
    _float_dtype,
    _kernel,
    _native,
    _per_source,
    _per_target,
    _points,
    _positive_int,
    _wavenumber,
    _vector_valued,
)
from ._ferrofmm import (
    DEFAULT_F32_TOLERANCE,
    DEFAULT_LEAF_SIZE,
    DEFAULT_TOLERANCE,
    MAX_ORDER,
    MIN_ORDER,
)
from ._layout import _pack_densities, _shape_values

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
    pressure : numpy.ndarray or None
        Stokes with ``pressure=True``: the pressure, ``(m,)`` or ``(k, m)``
        (FMM3D's ``pre``); else ``None``.
    pressure_gradient : numpy.ndarray or None
        Its gradient, ``(m, 3)`` or ``(k, m, 3)``, with ``pressure=True``
        and ``gradient=True``; else ``None``.
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

    __slots__ = (
        "potential", "gradient", "hessian", "info", "at_sources", "energy", "pressure",
        "pressure_gradient",
    )

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
        self.pressure: Optional[np.ndarray] = None
        self.pressure_gradient: Optional[np.ndarray] = None

    def __repr__(self) -> str:
        g = None if self.gradient is None else self.gradient.shape
        h = "" if self.hessian is None else f", hessian={self.hessian.shape}"
        e = "" if self.energy is None or np.ndim(self.energy) else f", energy={self.energy:.6g}"
        p = "" if self.pressure is None else f", pressure={self.pressure.shape}"
        return (
            f"FmmResult(potential={self.potential.shape}, gradient={g}{h}{p}{e}, "
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
    k : float or complex, optional
        The wavenumber of the yukawa (screening) or helmholtz (oscillation)
        kernel (``k >= 0``). Helmholtz also takes a complex ``k = a + bj``
        with ``b >= 0``: damped waves ``exp(-b r) exp(i a r) / (4 pi r)``.
        Helmholtz is the low-frequency method: ``Re k`` times the domain
        width is limited (about 6 wavelengths), beyond it the build raises
        ``ValueError`` naming the limit.
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
        For ``"stokes"`` a dipole is a force dipole ``D``, ``(n, 3, 3)``
        with ``D[i, k, c]`` the derivative direction ``k`` of force
        component ``c`` (a stresslet without its source flow plus a
        rotlet); stresslets as FMM3D has them are ``stresslets=True``.
    stresslets : bool
        ``"stokes"`` only: the sources carry stresslets, a strength ``m``
        and an orientation ``n`` per source (FMM3D's ``strslet`` and
        ``strsvec``), velocity ``3 d (d . m)(d . n) / (4 pi r^5)`` with
        ``d`` the target minus the source; ``evaluate`` takes them as
        ``strslet=`` and ``strsvec=``. With ``charges=False``, stresslets
        only.
    pressure : bool
        ``"stokes"`` only: also the pressure (with ``gradient=True`` its
        gradient), as ``result.pressure`` and ``result.pressure_gradient``
        (FMM3D's ``pre``): ``f . d / (4 pi r^3)`` for a force,
        ``(6 (d . m)(d . n) / r^5 - 2 (m . n) / r^3) / (4 pi)`` for a
        stresslet. Stresslets and the pressure add one Laplace FMM on the
        same points, free space only; a tolerance is checked on both FMMs
        and ``info`` reports the check that missed, else the Stokes one.
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
        Periodic boundaries (Laplace, Yukawa or Stokes kernels, or damped
        Helmholtz waves, ``k`` with a positive imaginary part; charges): the side ``L`` of
        the cubic cell ``[box_origin, box_origin + L)^3`` that repeats
        along ``periodic``; every target sees every image of every source
        (the Ewald convention). Points outside the cell are wrapped into
        it; results come in the caller's order. With Laplace the charges
        of each vector must sum to zero (``ValueError`` at evaluation
        otherwise); Yukawa's sum converges for any charges.
        Three sides are accepted but only cubes run in this release;
        undamped waves, dipoles and Hessians with a box are refused
        (``ValueError``). ``eps`` is chosen and verified as in free space,
        against an Ewald sum.
    box_origin : sequence of 3 floats, optional
        The cell's lower corner (default ``(0, 0, 0)``); needs ``box``.
    periodic : {"xyz", "xy", "x"}, optional
        Axes that repeat (default ``"xyz"`` with ``box``; ``"xy"`` a slab,
        ``"x"`` a rod, not with Stokes). Needs ``box``.
    surface : {"tin-foil", "vacuum"}, optional
        How the lattice sum is closed at infinity: ``"tin-foil"``
        (default; conducting surroundings, Ewald without its ``k = 0``
        term, as particle-mesh Ewald codes) or ``"vacuum"`` (adds the
        cell's dipole term). Needs ``box``.
    progress : callable, optional
        Called as ``progress(step, done, total)`` while the FMM is built,
        with the GIL held, at most every 0.1 s and at the end of each step:
        ``step`` is ``"tuning"`` (choosing the order, leaf size and root),
        ``"tree"``, ``"operators"`` or ``"layout"``, in that order (a step
        that does not run reports nothing), and ``done`` rises to ``total``
        within each step, so a step's time left is about
        ``elapsed * (total - done) / done``. An exception it raises ends
        the construction with that exception. (``evaluate`` takes its own
        ``progress(done, total)``.)
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
        stresslets: bool = False,
        pressure: bool = False,
        progress: Optional[Callable[[str, int, int], Any]] = None,
    ) -> None:
        if progress is not None and not callable(progress):
            raise TypeError(
                "progress must be a callable taking (step, done, total) or None, "
                f"not {type(progress).__name__}"
            )
        cell = _cell(box, box_origin, periodic, surface)
        charges, dipoles = _bool("charges", charges), _bool("dipoles", dipoles)
        gradient, hessian = _bool("gradient", gradient), _bool("hessian", hessian)
        verify, at_sources = _bool("verify", verify), _bool("at_sources", at_sources)
        stresslets, pressure = _bool("stresslets", stresslets), _bool("pressure", pressure)
        if not (charges or dipoles or stresslets):
            raise ValueError("the sources carry nothing: set charges=True or dipoles=True")
        layered = stresslets or pressure
        if layered and kernel != "stokes":
            raise ValueError(
                f"stresslets and pressure belong to the stokes kernel, not {kernel!r}"
            )
        if layered and dipoles:
            raise ValueError(
                "force dipoles (dipoles=True) do not combine with stresslets or the pressure: "
                "give stresslets with stresslets=True"
            )
        if layered and box is not None:
            raise ValueError("stresslets and the pressure run in free space only (no box)")
        # Stresslets alone: the layers take what the sources carry from
        # `layers`, the kind is a placeholder.
        source = {
            (True, False): "charge",
            (False, True): "dipole",
            (True, True): "charge+dipole",
            (False, False): "charge",
        }[(charges, dipoles)]
        src = _points("sources", sources)
        tgt = None if targets is None else _points("targets", targets)
        run = _float_dtype(dtype) or _native(src.dtype)
        _check_eps_order(eps, order)
        if eps is None and order is None:
            eps = DEFAULT_EPS[run]
        _kernel(kernel)
        if not isinstance(scheme, str) or scheme not in _ferrofmm.SCHEMES:
            raise ValueError(f'unknown M2L scheme {scheme!r}: use "auto", "svd", "dense" or "fft"')
        k = _wavenumber(k)
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
            run, len(src), n_targets, _per_source(kernel, charges, dipoles, stresslets),
            _per_target(kernel, gradient, hessian, pressure), 1,
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
            (charges, stresslets, pressure) if layered else None,
            progress,
        )
        self._dtype = run
        self._kernel = kernel
        self._hessian = bool(hessian)
        self._gradient = bool(gradient) or self._hessian
        self._charges = charges
        self._dipoles = dipoles
        self._stresslets = stresslets
        self._pressure = pressure
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
        strslet: Any = None,
        strsvec: Any = None,
        progress: Optional[Callable[[int, int], Any]] = None,
    ) -> FmmResult:
        """Potentials (and gradients, Hessians) at the targets.

        ``charges`` is ``(n,)`` (one value per source) or ``(k, n)`` for
        ``k`` charge vectors evaluated in one call; ``dipoles`` is
        ``(n, 3)`` or ``(k, n, 3)`` (``(n, 3, 3)`` force dipoles for
        ``"stokes"``); ``strslet`` and ``strsvec`` are the stresslets'
        strengths and orientations, ``(n, 3)`` or ``(k, n, 3)`` each. Give
        what the sources were built to carry (``charges=True`` /
        ``dipoles=True`` / ``stresslets=True`` of :class:`Fmm`); nothing
        is rebuilt.

        ``progress``, when given, is called as ``progress(done, total)``
        while the FMM passes run: the work done and in all, in rough cost
        units (the time left is about ``elapsed * (total - done) / done``).
        It is called from the calling thread with the GIL held, at most
        every 0.1 s and once at the end with ``done == total``; ``total``
        may grow once when the accuracy check raises the order. An
        exception it raises ends the call with that exception.
        """
        _check_progress(progress)
        carries = dict(charges=self._charges, dipoles=self._dipoles,
                       strslet=self._stresslets, strsvec=self._stresslets)
        given = _carried(
            carries, dict(charges=charges, dipoles=dipoles, strslet=strslet, strsvec=strsvec)
        )
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
        pressure: Optional[np.ndarray] = None
        pressure_gradient: Optional[np.ndarray] = None
        if self._pressure:
            # [velocity, pressure] per target: the pressure's values last.
            wp = 4 if self._gradient else 1
            v = values.reshape(k, m, -1)
            p = np.ascontiguousarray(v[:, :, -wp:])
            values = np.ascontiguousarray(v[:, :, :-wp]).reshape(-1)
            pressure = p[:, :, 0] if batched else p[0, :, 0]
            if self._gradient:
                pressure_gradient = p[:, :, 1:] if batched else p[0, :, 1:]
        potential, gradient, hessian = _shape_values(
            self._kernel, values, k, m, self._gradient, self._hessian, batched
        )
        ns = self._n_at_sources

        def result(part: Callable[[Optional[np.ndarray]], Optional[np.ndarray]]) -> FmmResult:
            r = FmmResult(part(potential), part(gradient), info, part(hessian))
            r.pressure, r.pressure_gradient = part(pressure), part(pressure_gradient)
            return r

        if not ns:
            r = result(lambda a: a)
            r.energy = energy
            return r

        # The target axis: 0 for one vector, 1 for a batch.
        axis = 1 if batched else 0

        def split(a: Optional[np.ndarray], lo: int, hi: Optional[int]) -> Optional[np.ndarray]:
            if a is None:
                return None
            index = [slice(None)] * a.ndim
            index[axis] = slice(lo, hi)
            return np.ascontiguousarray(a[tuple(index)])

        out = result(lambda a: split(a, ns, None))
        out.at_sources = result(lambda a: split(a, 0, ns))
        return out

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


def _check_progress(progress: Any) -> None:
    """A clear error for a ``progress`` that cannot be called."""
    if progress is not None and not callable(progress):
        raise TypeError(
            "progress must be a callable taking (done, total) or None, "
            f"not {type(progress).__name__}"
        )
