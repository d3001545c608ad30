"""ferrofmm.distributed: the octree and the FMM across the ranks of an MPI job (mpi4py).

Each rank passes its own points (any number, none included) and gets its own results, in
its own order; every call is a collective over the communicator (any intracommunicator:
``MPI.COMM_WORLD``, or one of its splits)::

    # mpirun -n 4 python run.py
    from mpi4py import MPI
    import numpy as np
    import ferrofmm.distributed as fd

    comm = MPI.COMM_WORLD
    rng = np.random.default_rng(comm.rank)
    x = rng.random((250_000, 3))            # this rank's points
    q = rng.random(250_000) - 0.5           # and charges
    r = fd.laplace(comm, x, q, eps=1e-6, gradient=True)
    r.potential                             # (250000,): at this rank's points
    r.info["measured_error"]                # verified against a direct sum over all ranks

    fmm = fd.Fmm(comm, x, eps=1e-6)         # build once, evaluate many times
    phi = fmm.evaluate(q).potential

    tree = fd.Octree(comm, x, leaf_size=64) # this rank's piece of the global tree
    tree.keys, tree.ghost_keys, tree.points_per_rank

The tree is the one the single-machine :class:`ferrofmm.Octree` builds from all the
points (the union of the ranks' boxes and the coarse boxes), and the FMM with the same
order, leaf size and scheme gives the single-machine :class:`ferrofmm.Fmm`'s values to
rounding. ``eps`` chooses the order and leaf size from a sample of the points and verifies
the first evaluation as on one machine (against direct summation over all ranks at sampled
points).

Failures never hang: an argument that is wrong on one rank, or a library error on any,
raises the same exception (``ValueError``, ``TypeError``) on every rank, naming the rank.
The GIL is released while the library works. Threads per rank: ``threads``, else
``RAYON_NUM_THREADS``, else the node's cores shared among the ranks on it.

Available when the package was built with MPI (``pip install`` finds ``mpicc``; see the
package README) and mpi4py is installed against the same MPI library.
"""

from __future__ import annotations

import json
import warnings
from typing import Any, Callable, Dict, List, Optional, Tuple, TypeVar

import numpy as np

from . import _ferrofmm

if not getattr(_ferrofmm, "HAS_MPI", False):
    raise ImportError(
        "ferrofmm was built without MPI, so ferrofmm.distributed is not available: install an "
        "MPI implementation with its headers (Debian/Ubuntu: apt install libopenmpi-dev "
        "openmpi-bin libclang-dev) and reinstall with FERROFMM_MPI=1 pip install "
        "'ferrofmm @ ./crates/python' (the build then fails loudly if MPI is missing)"
    )
try:
    from mpi4py import MPI
except ImportError as _e:  # pragma: no cover - depends on the environment
    raise ImportError(
        "ferrofmm.distributed needs mpi4py (pip install mpi4py), built for the same MPI "
        f"library as ferrofmm ({_ferrofmm.MPI_LIBRARY.splitlines()[0]})"
    ) from _e


def _library_name(version: str) -> str:
    """The implementation's name and version from ``MPI_Get_library_version``."""
    first = version.strip().splitlines()[0] if version.strip() else ""
    return first.split(",")[0].strip()


if _library_name(MPI.Get_library_version()) != _library_name(_ferrofmm.MPI_LIBRARY):
    raise ImportError(
        "mpi4py and ferrofmm use different MPI libraries "
        f"({_library_name(MPI.Get_library_version())!r} and "
        f"{_library_name(_ferrofmm.MPI_LIBRARY)!r}): one process cannot run both; reinstall "
        "mpi4py against the MPI ferrofmm was built with (pip install --no-binary mpi4py mpi4py)"
    )

from ._checks import (  # noqa: E402  (after the MPI checks above)
    _flat,
    _bool,
    _cache,
    _carried,
    _check_densities,
    _check_eps_order,
    _float_dtype,
    _kernel,
    _points,
    _positive_int,
    _wavenumber,
)
from ._ferrofmm import DEEPEST_LEVEL, DEFAULT_LEAF_SIZE  # noqa: E402
from ._fmm import DEFAULT_EPS, AccuracyWarning, FmmResult  # noqa: E402
from ._layout import _pack_densities, _shape_values  # noqa: E402

__all__ = ["Octree", "Fmm", "laplace", "yukawa", "helmholtz", "stokes"]

_T = TypeVar("_T")

#: Points go to the library in float64 (the run's dtype is separate).
_F64 = np.dtype(np.float64)

#: Exceptions that an argument check on one rank raises on every rank.
_AGREED = {"ValueError": ValueError, "TypeError": TypeError, "MemoryError": MemoryError}


def _communicator(comm: Any) -> Any:
    """``comm`` if it is an mpi4py intracommunicator MPI is running on, else TypeError."""
    if not isinstance(comm, MPI.Comm):
        raise TypeError(
            f"comm must be an mpi4py communicator (e.g. MPI.COMM_WORLD), got {type(comm).__name__}"
        )
    if comm == MPI.COMM_NULL:
        raise ValueError("comm is MPI.COMM_NULL: this process is not in the communicator")
    if not isinstance(comm, MPI.Intracomm) or comm.Is_inter():
        raise TypeError("comm must be an intracommunicator (an intercommunicator has no one group)")
    if MPI.Is_finalized():
        raise RuntimeError("MPI has been finalized")
    return comm


def _agreed(comm: Any, check: Callable[[], _T]) -> _T:
    """Run this rank's argument checks, then agree with every rank (one ``allgather``): when
    any rank failed, every rank raises the same exception (the lowest failing rank's),
    so no rank enters the library's collectives alone."""
    try:
        value, failure = check(), None
    except tuple(_AGREED.values()) as e:
        value, failure = None, (type(e).__name__, str(e))
    failures = comm.allgather(failure)
    if not all(
        f is None or (isinstance(f, tuple) and len(f) == 2 and f[0] in _AGREED) for f in failures
    ):
        raise RuntimeError(
            "the ranks are out of step: another collective call on this communicator met "
            "ferrofmm's check of the arguments; every rank must make the same collective calls "
            "in the same order"
        )
    for rank, f in enumerate(failures):
        if f is not None:
            kind, message = f
            if comm.Get_size() > 1:
                message = f"rank {rank}: {message}"
            raise _AGREED[kind](message)
    return value  # type: ignore[return-value]


def _check_scheme(scheme: Any) -> None:
    if not isinstance(scheme, str) or scheme not in _ferrofmm.SCHEMES:
        raise ValueError(f'unknown M2L scheme {scheme!r}: use "auto", "svd", "dense" or "fft"')


def _targets_everywhere_or_nowhere(comm: Any, given_here: bool) -> None:
    """Targets given on some ranks only: the same ValueError on every rank (a
    collective)."""
    given = comm.allgather(given_here)
    if any(given) != all(given):
        raise ValueError(
            "targets must be given on every rank or on none (an empty (0, 3) array on a "
            f"rank without targets); given on ranks {[r for r, g in enumerate(given) if g]}"
        )


def _native_property(name: str, doc: str) -> property:
    """A read-only property that returns the native object's attribute ``name``."""
    return property(lambda self: getattr(self._native, name), doc=doc)


class Octree:
    """This rank's piece of the adaptive, 2:1-balanced octree of all ranks' points.

    Parameters
    ----------
    comm : mpi4py.MPI.Intracomm
        The ranks that build the tree together (a collective).
    points : array_like, shape (n, 3)
        This rank's points (any number, none included); float64 or float32.
    leaf_size : int
        Points per leaf at most.
    max_level : int
        Deepest level a box may have.

    After the build each rank holds one contiguous range of the Morton curve (``cuts``):
    its points (``points``, with their global input ids ``point_ids``: rank ``r``'s input
    numbered after the points of ranks ``< r``), its boxes (``keys``, ``is_leaf``,
    ``counts``), the coarse boxes that straddle cuts (``coarse_keys``, on every rank) and
    the ghost boxes its lists reference (``ghost_keys``...). The union over ranks of
    ``keys`` and ``coarse_keys`` is the single-machine tree of all points. Keys are
    ``MortonKey::raw`` values, as :attr:`ferrofmm.Octree.keys`.
    """

    def __init__(
        self,
        comm: Any,
        points: Any,
        leaf_size: int = DEFAULT_LEAF_SIZE,
        max_level: int = DEEPEST_LEVEL,
    ) -> None:
        comm = _communicator(comm)

        def check() -> Tuple[np.ndarray, int, int]:
            p = _points("points", points, allow_empty=True)
            ls = _positive_int("leaf_size", leaf_size)
            ml = _positive_int("max_level", max_level)
            return _flat(p, _F64), int(ls), int(ml)

        flat, ls, ml = _agreed(comm, check)
        self._native = _ferrofmm.NativeDistOctree(comm.py2f(), flat, ls, ml)

    rank = _native_property("rank", "This rank.")
    size = _native_property("size", "Ranks in the communicator.")
    domain_origin = property(
        lambda self: np.array(self._native.domain[0]), doc="Lower corner of the root cube."
    )
    domain_width = property(lambda self: self._native.domain[1], doc="Side of the root cube.")
    keys = _native_property("keys", "Keys of this rank's boxes, sorted.")
    is_leaf = _native_property("is_leaf", "Whether each box is a leaf.")
    counts = _native_property("counts", "Points in each of this rank's boxes.")
    coarse_keys = _native_property("coarse_keys", "Keys of the boxes straddling a cut.")
    cuts = _native_property(
        "cuts", "``cuts[r]:cuts[r + 1]``: the deepest-level Morton codes of rank ``r``."
    )
    points = _native_property("points", "This rank's points, in Morton order, ``(n, 3)``.")
    point_ids = _native_property("point_ids", "Global input id of each of ``points``.")
    input_counts = _native_property("input_counts", "Points each rank passed, in rank order.")
    points_per_rank = _native_property(
        "points_per_rank", "Points each rank holds after the partition, in rank order."
    )
    ghost_keys = _native_property("ghost_keys", "Keys of the ghost boxes this rank's lists use.")
    ghost_is_leaf = _native_property("ghost_is_leaf", "Whether each ghost is a global leaf.")
    ghost_counts = _native_property("ghost_counts", "Points in each ghost (0 for a coarse box).")
    partners = _native_property("partners", "Ranks asked for ghost boxes.")
    list_keys = _native_property(
        "list_keys",
        "The boxes :meth:`lists` rows and indices refer to (this rank's, coarse, ghosts, "
        "their ancestors), in the tree's order.",
    )

    def lists(self, kind: str) -> Tuple[np.ndarray, np.ndarray]:
        """Interaction list ``kind`` (``"u"``, ``"v"``, ``"w"``, ``"x"``) over
        :attr:`list_keys` as ``(offsets, indices)``; rows of this rank's boxes are those of
        the single-machine tree."""
        return self._native.list_csr(kind)

    @property
    def imbalance(self) -> float:
        """Largest over mean number of points per rank after the partition."""
        p = self.points_per_rank.astype(np.float64)
        return float(p.max() / p.mean()) if p.mean() > 0 else 1.0

    def build_stats(self) -> Dict[str, Any]:
        """This rank's build: seconds and bytes sent per phase, and balance rounds."""
        names, seconds, sent, rounds = self._native.build_stats()
        return {
            "seconds": dict(zip(names, seconds)),
            "bytes_sent": dict(zip(names, sent)),
            "balance_rounds": rounds,
        }

    def __repr__(self) -> str:
        return (
            f"Octree(rank={self.rank} of {self.size}, boxes={len(self.keys)}, "
            f"points={len(self.point_ids)}, ghosts={len(self.ghost_keys)})"
        )


class Fmm:
    """The distributed FMM built once for each rank's points, evaluated many times.

    Parameters are those of :class:`ferrofmm.Fmm` with the communicator first; each
    rank passes its own ``sources`` (``(n, 3)``, any ``n`` including 0) and, optionally,
    its own ``targets``. Not (yet): Hessians, periodic boxes, ``at_sources``.

    For ``"stokes"``, ``stresslets=True`` (sources with stresslets, given to
    :meth:`evaluate` as ``strslet`` and ``strsvec``) and ``pressure=True`` (the pressure, and
    its gradient with ``gradient=True``) run a distributed Laplace FMM beside the Stokes one,
    as :class:`ferrofmm.Fmm` does; with ``eps`` the first evaluation checks both FMMs and what
    is delivered (velocity and pressure against direct sums at sampled targets), raising the
    Laplace order while it misses.

    Parameters
    ----------
    comm : mpi4py.MPI.Intracomm
        The ranks of the run (every call is a collective over them).
    sources : array_like, shape (n, 3)
        This rank's points, also the targets unless ``targets`` is given (a point does not
        act on itself).
    targets : array_like, shape (m, 3), optional
        This rank's own evaluation points (anywhere: they need not lie near this rank's
        sources or inside the sources' cube; ``m = 0`` is fine). Give them on every rank
        or on none. Each rank gets the values at its own targets, in their order.
    kernel : {"laplace", "yukawa", "helmholtz", "stokes"}
        As :class:`ferrofmm.Fmm`; ``k`` for yukawa and helmholtz.
    eps, order, leaf_size, scheme, verify, gradient, charges, dipoles, stresslets, pressure, cache, cache_dir
        As :class:`ferrofmm.Fmm` (``eps`` chosen from a sample of at most 200,000 points
        gathered on rank 0, verified on the first evaluation against direct summation
        over all ranks at ``samples`` sampled points, default 200).
    dtype : {None, "float32", "float64"}
        Float type of the run; ``None``: float64 (the same on every rank whatever each
        rank's arrays are).
    threads : int, optional
        Threads per rank (default: ``RAYON_NUM_THREADS``, else the node's cores shared
        among its ranks).
    """

    def __init__(
        self,
        comm: Any,
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
        samples: Optional[int] = None,
        cache_dir: Any = None,
        cache: Any = True,
        charges: bool = True,
        dipoles: bool = False,
        stresslets: bool = False,
        pressure: bool = False,
    ) -> None:
        comm = _communicator(comm)

        def check() -> Dict[str, Any]:
            src = _points("sources", sources, allow_empty=True)
            tgt = None if targets is None else _points("targets", targets, allow_empty=True)
            with_charges, with_dipoles = _bool("charges", charges), _bool("dipoles", dipoles)
            with_stresslets = _bool("stresslets", stresslets)
            with_pressure = _bool("pressure", pressure)
            if not (with_charges or with_dipoles or with_stresslets):
                raise ValueError("the sources carry nothing: set charges=True or dipoles=True")
            _kernel(kernel)
            if (with_stresslets or with_pressure) and kernel != "stokes":
                raise ValueError(
                    f"stresslets and pressure belong to the stokes kernel, not {kernel!r}"
                )
            if (with_stresslets or with_pressure) and with_dipoles:
                raise ValueError(
                    "force dipoles (dipoles=True) do not combine with stresslets or the "
                    "pressure: give stresslets with stresslets=True"
                )
            run = _float_dtype(dtype) or np.dtype(np.float64)
            _check_eps_order(eps, order)
            _check_scheme(scheme)
            folder, default_cache = _cache(cache, cache_dir)
            return dict(
                src=_flat(src, _F64),
                tgt=None if tgt is None else _flat(tgt, _F64),
                n=len(src),
                m=len(src) if tgt is None else len(tgt),
                run=run,
                eps=None if eps is None and order is not None else
                float(DEFAULT_EPS[run] if eps is None else eps),
                order=None if order is None else int(order),
                k=_wavenumber(k),
                leaf_size=_positive_int("leaf_size", leaf_size),
                threads=_positive_int("threads", threads),
                samples=_positive_int("samples", samples) or 0,
                gradient=_bool("gradient", gradient),
                verify=_bool("verify", verify),
                charges=with_charges,
                dipoles=with_dipoles,
                stresslets=with_stresslets,
                pressure=with_pressure,
                cache_dir=folder,
                default_cache=default_cache,
            )

        a = _agreed(comm, check)
        _targets_everywhere_or_nowhere(comm, a["tgt"] is not None)
        self._comm = comm
        # Stresslets or the pressure: the Stokes and Laplace FMMs together.
        self._layered = a["stresslets"] or a["pressure"]
        if self._layered:
            self._native = _ferrofmm.NativeDistStokesLayers(
                comm.py2f(), a["src"], a["tgt"], a["eps"], a["order"], a["leaf_size"], scheme,
                a["gradient"], a["verify"], a["samples"], a["threads"], a["cache_dir"],
                a["default_cache"], str(a["run"]), a["charges"], a["stresslets"], a["pressure"],
            )
        else:
            source = {
                (True, False): "charge", (False, True): "dipole", (True, True): "charge+dipole"
            }[(a["charges"], a["dipoles"])]
            self._native = _ferrofmm.NativeDistFmm(
                comm.py2f(), a["src"], a["tgt"], kernel, a["k"], a["eps"], a["order"],
                a["leaf_size"], scheme, a["gradient"], a["verify"], a["samples"], a["threads"],
                a["cache_dir"], a["default_cache"], source, str(a["run"]),
            )
        self._n = a["n"]
        self._m = a["m"]
        self._dtype = a["run"]
        self._kernel = kernel
        self._gradient = a["gradient"]
        self._charges = a["charges"]
        self._dipoles = a["dipoles"]
        self._stresslets = a["stresslets"]
        self._pressure = a["pressure"]
        self._last_info: Optional[Dict[str, Any]] = None

    @property
    def n_sources(self) -> int:
        """Number of this rank's sources."""
        return self._n

    @property
    def n_targets(self) -> int:
        """Number of this rank's targets (its sources without separate targets)."""
        return self._m

    @property
    def dtype(self) -> np.dtype:
        """Float type of the run."""
        return self._dtype

    @property
    def input_counts(self) -> np.ndarray:
        """Sources each rank passed, in rank order."""
        return np.array(self._native.input_counts, dtype=np.int64)

    def evaluate(
        self,
        charges: Any = None,
        dipoles: Any = None,
        *,
        strslet: Any = None,
        strsvec: Any = None,
    ) -> FmmResult:
        """Potentials (and gradients) at this rank's targets for the densities of its
        sources (a collective: every rank passes its own).

        ``charges`` is ``(n,)`` or ``(k, n)`` for ``k`` vectors (evaluated one after
        another); ``dipoles`` ``(n, 3)`` or ``(k, n, 3)``; ``strslet`` and ``strsvec`` (the
        stresslets' strengths and orientations) ``(n, 3)`` or ``(k, n, 3)`` each, as
        :meth:`ferrofmm.Fmm.evaluate`. With ``pressure=True`` the result also holds
        ``pressure`` (and ``pressure_gradient`` with ``gradient=True``).
        """
        return self._evaluate(charges, dipoles, None, strslet, strsvec)

    def _given(
        self, names: Optional[Dict[str, str]], **values: Any
    ) -> List[Tuple[str, str, Any]]:
        """The densities given, each checked against what the sources carry."""
        carries = dict(charges=self._charges, dipoles=self._dipoles,
                       strslet=self._stresslets, strsvec=self._stresslets)
        return _carried(carries, values, names)
    def _evaluate(
        self,
        charges: Any,
        dipoles: Any,
        names: Optional[Dict[str, str]],
        strslet: Any = None,
        strsvec: Any = None,
    ) -> FmmResult:
        if self._layered:
            return self._evaluate_layers(charges, strslet, strsvec, names)

        def check() -> Tuple[np.ndarray, int, bool]:
            given = self._given(names, charges=charges, dipoles=dipoles, strslet=strslet,
                                strsvec=strsvec)
            arrays, k, batched = _check_densities(self._kernel, self._n, given)
            dens = _pack_densities(self._kernel, self._dtype, arrays, self._n, batched)
            return np.ascontiguousarray(dens, dtype=np.float64), k, batched

        dens, k, batched = _agreed(self._comm, check)
        values = []
        info: Dict[str, Any] = {}
        for i in range(k):
            v, info_json = self._native.evaluate(dens[i].reshape(-1))
            values.append(v)
            if i == 0:
                info = json.loads(info_json)
        flat = np.concatenate(values) if values else np.zeros(0)
        if self._dtype == np.float32:
            flat = flat.astype(np.float32)
        info["kernel_name"] = self._kernel
        info["dtype"] = str(self._dtype)
        self._last_info = info
        if info.get("verified") is False:
            measured = info.get("measured_error") or {}
            warnings.warn(
                f"the tolerance eps={info.get('eps'):g} was not met: error measured on "
                f"{measured.get('sampled_targets')} sampled targets: potential "
                f"{measured.get('potential'):.2e} at order {info.get('order')} "
                "(info['verified'] is False); the results are returned. Ask for a larger eps "
                "(or float64), or give order",
                AccuracyWarning,
                stacklevel=3,
            )
        potential, gradient, _ = _shape_values(
            self._kernel, flat, k, self._m, self._gradient, False, batched
        )
        return FmmResult(potential, gradient, info)

    def _evaluate_layers(
        self, forces: Any, strslet: Any, strsvec: Any, names: Optional[Dict[str, str]]
    ) -> FmmResult:
        """Forces and/or stresslets with the pressure: each vector set through both FMMs."""

        def check() -> Tuple[Dict[str, np.ndarray], int, bool]:
            given = self._given(names, charges=forces, strslet=strslet, strsvec=strsvec)
            arrays, k, batched = _check_densities("stokes", self._n, given)
            dens = {}
            for (_, key, _), (shown, a, _) in zip(given, arrays):
                flat = np.ascontiguousarray(a, dtype=np.float64).reshape(k, -1)
                if not np.all(np.isfinite(flat)):
                    raise ValueError(f"{shown} holds a NaN or infinite value")
                dens[key] = flat
            return dens, k, batched

        dens, k, batched = _agreed(self._comm, check)
        velocities, pressures = [], []
        info: Dict[str, Any] = {}
        for i in range(k):
            one = {key: d[i] for key, d in dens.items()}
            v, p, info_json = self._native.evaluate(
                one.get("charges"), one.get("strslet"), one.get("strsvec")
            )
            velocities.append(v)
            if p is not None:
                pressures.append(p)
            if i == 0:
                info = json.loads(info_json)
        info["kernel_name"] = "stokes"
        info["dtype"] = str(self._dtype)
        self._last_info = info
        m, g = self._m, self._gradient
        velocity = np.concatenate(velocities) if velocities else np.zeros(0)
        if self._dtype == np.float32:
            velocity = velocity.astype(np.float32)
        potential, grad, _ = _shape_values("stokes", velocity, k, m, g, False, batched)
        result = FmmResult(potential, grad, info)
        if self._pressure:
            p = np.concatenate(pressures).reshape(k, m, 4 if g else 1)
            if self._dtype == np.float32:
                p = p.astype(np.float32)
            if not batched:
                p = p[0]
            result.pressure = np.ascontiguousarray(p[..., 0])
            result.pressure_gradient = np.ascontiguousarray(p[..., 1:4]) if g else None
        if info.get("verified") is False:
            measured = info.get("measured_error") or {}
            warnings.warn(
                f"the tolerance eps={info.get('eps'):g} was not met: the worst error of "
                f"velocity and pressure measured on {measured.get('sampled_targets')} sampled "
                f"targets is {measured.get('worst'):.2e} (Stokes order {info.get('order')}, "
                f"Laplace order {info.get('laplace_order')}; info['verified'] is False); the "
                "results are returned. Ask for a larger eps (or float64), or give order",
                AccuracyWarning,
                stacklevel=4,
            )
        return result

    def __repr__(self) -> str:
        return (
            f"distributed.Fmm(rank {self._comm.Get_rank()} of {self._comm.Get_size()}, "
            f"n_sources={self._n}, n_targets={self._m}, dtype={self._dtype})"
        )


def _one_call(
    kernel: str,
    comm: Any,
    sources: Any,
    charges: Any,
    dipoles: Any,
    names: Optional[Dict[str, str]] = None,
    **kw: Any,
) -> FmmResult:
    comm = _communicator(comm)
    _agreed(comm, lambda: _given(charges, dipoles))
    fmm = Fmm(comm, sources, kw.pop("targets", None), kernel, charges=charges is not None,
              dipoles=dipoles is not None, **kw)
    return fmm._evaluate(charges, dipoles, names)


def _given(charges: Any, dipoles: Any) -> None:
    if charges is None and dipoles is None:
        raise ValueError("give charges, dipoles or both")


def laplace(comm: Any, sources: Any, charges: Any = None, *, dipoles: Any = None,
            targets: Any = None, eps: Optional[float] = None, order: Optional[int] = None,
            gradient: bool = False, **kw: Any) -> FmmResult:
    """Laplace potentials ``sum_i q_i / (4 pi |y - x_i|)`` at every rank's points, over the
    points of all ranks (a collective). Arguments as :func:`ferrofmm.laplace`, with the
    communicator first and each rank's own ``sources`` and ``charges`` / ``dipoles``;
    further keywords as :class:`Fmm`."""
    return _one_call("laplace", comm, sources, charges, dipoles, targets=targets, eps=eps,
                     order=order, gradient=gradient, **kw)


def yukawa(comm: Any, sources: Any, charges: Any = None, *, k: float, dipoles: Any = None,
           targets: Any = None, eps: Optional[float] = None, order: Optional[int] = None,
           gradient: bool = False, **kw: Any) -> FmmResult:
    """Yukawa potentials ``sum_i q_i exp(-k r) / (4 pi r)`` over all ranks' points (a
    collective); as :func:`ferrofmm.yukawa` with the communicator first."""
    return _one_call("yukawa", comm, sources, charges, dipoles, targets=targets, k=k, eps=eps,
                     order=order, gradient=gradient, **kw)


def helmholtz(comm: Any, sources: Any, charges: Any = None, *, k: float, dipoles: Any = None,
              targets: Any = None, eps: Optional[float] = None, order: Optional[int] = None,
              gradient: bool = False, **kw: Any) -> FmmResult:
    """Helmholtz potentials ``sum_i q_i exp(i k r) / (4 pi r)`` (complex charges and
    results) over all ranks' points (a collective); as :func:`ferrofmm.helmholtz` with the
    communicator first."""
    return _one_call("helmholtz", comm, sources, charges, dipoles, targets=targets, k=k,
                     eps=eps, order=order, gradient=gradient, **kw)


def stokes(comm: Any, sources: Any, forces: Any = None, *, strslet: Any = None,
           strsvec: Any = None, pressure: bool = False, targets: Any = None,
           eps: Optional[float] = None, order: Optional[int] = None, gradient: bool = False,
           **kw: Any) -> FmmResult:
    """Stokes flow over all ranks' points (a collective); as :func:`ferrofmm.stokes` with the
    communicator first and each rank's own rows.

    ``forces`` ``(n, 3)`` (Stokeslets ``sum_i (I / r + d d^T / r^3) f_i / (8 pi)``) and/or
    stresslets ``strslet`` (strengths ``m``) with ``strsvec`` (orientations ``n``), each
    ``(n, 3)`` (or ``(k, n, 3)`` for ``k`` vector sets); ``potential`` (velocities,
    ``(m, 3)``) and ``gradient`` (``(m, 3, 3)``, ``[j, a, c] = d u_a / d x_c``) out, and with
    ``pressure=True`` ``.pressure`` ``(m,)`` and, with ``gradient=True``,
    ``.pressure_gradient`` ``(m, 3)`` (FMM3D's ``stfmm3d`` conventions). Stresslets and the
    pressure run a distributed Laplace FMM beside the Stokes one; with ``eps`` both are
    verified, and so is what is delivered (velocity and pressure against direct sums at
    sampled targets, the Laplace FMM's order raised while it misses). Further keywords as
    :class:`Fmm`."""
    comm = _communicator(comm)

    def given() -> None:
        if (strslet is None) != (strsvec is None):
            raise ValueError("give strslet and strsvec together (stresslet strengths and "
                             "orientations, each (n, 3))")
        if forces is None and strslet is None:
            raise ValueError("give the forces, shape (n, 3), or stresslets (strslet and strsvec)")

    _agreed(comm, given)
    fmm = Fmm(comm, sources, targets, "stokes", eps=eps, order=order, gradient=gradient,
              charges=forces is not None, stresslets=strslet is not None,
              pressure=pressure, **kw)
    return fmm._evaluate(forces, None, {"charges": "forces"}, strslet, strsvec)
