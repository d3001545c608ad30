"""Type stubs of the native module (use the wrappers in ``ferrofmm``)."""

from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np
import numpy.typing as npt

__version__: str
MIN_ORDER: int
MAX_ORDER: int
DEFAULT_LEAF_SIZE: int
DEFAULT_TOLERANCE: float
DEFAULT_F32_TOLERANCE: float
DEEPEST_LEVEL: int
#: The kernel registry: name -> description.
KERNELS: Dict[str, Dict[str, Any]]
#: The M2L scheme names.
SCHEMES: List[str]
#: Whether this build has the distributed module (the `mpi` feature).
HAS_MPI: bool
#: `MPI_Get_library_version` of the MPI linked in (builds with MPI only).
MPI_LIBRARY: str

def check_run_memory(
    what: str,
    dtype: str,
    n_sources: int,
    n_targets: Optional[int],
    values_per_source: int,
    values_per_target: int,
    n_vectors: int,
    build: bool = ...,
) -> None: ...

def stokes_ewald_sum(
    sources: npt.NDArray[np.floating],
    forces: npt.NDArray[np.floating],
    lengths: List[float],
    origin: List[float],
    targets: Optional[npt.NDArray[np.floating]],
    gradient: bool,
    eps: float,
    threads: Optional[int] = ...,
) -> Tuple[npt.NDArray[np.float64], str]:
    """Hasimoto's Ewald sum of the point ``forces`` (flat, three per source)
    at ``sources`` in the cell ``origin + [0, lengths)``, viscosity 1, at the
    sources or at ``targets``: the flat values (``u`` (3), then with
    ``gradient`` ``d_c u_a`` at ``3 + 3 c + a``, per target) and a JSON
    report."""
    ...

def ewald_sum(
    sources: npt.NDArray[np.floating],
    charges: npt.NDArray[np.floating],
    lengths: List[float],
    origin: List[float],
    targets: Optional[npt.NDArray[np.floating]],
    gradient: bool,
    eps: float,
    threads: Optional[int] = ...,
    k: float = ...,
) -> Tuple[npt.NDArray[np.float64], Optional[float], str]:
    """The Ewald sum (Laplace with tin-foil surroundings, or Yukawa with
    screening ``k > 0``) of ``charges`` at ``sources`` (flat, x y z
    interleaved) in the cell ``origin + [0, lengths)``, at the sources or
    at ``targets``: the flat values (``phi`` or ``phi, gx, gy, gz`` per
    target), the energy ``1/2 sum q phi`` (at the sources, else ``None``)
    and a JSON report. The GIL is released during the sum."""
    ...

def read_file(
    path: str, what: str, components: int, complex: bool
) -> Tuple[npt.NDArray[np.float64], int, bool]: ...
def write_file(
    path: str, values: npt.NDArray[np.floating], names: List[str], complex: bool
) -> None: ...
def column_names(values_per_target: int, component_names: List[str]) -> List[str]: ...

class NativeFmm:
    def __init__(
        self,
        sources: npt.NDArray[np.floating],
        targets: Optional[npt.NDArray[np.floating]],
        kernel: str,
        k: Optional[float],
        eps: Optional[float],
        order: Optional[int],
        leaf_size: Optional[int],
        scheme: str,
        gradient: bool,
        verify: bool,
        threads: Optional[int],
        cache_dir: Optional[str],
        hessian: bool = ...,
        source: str = ...,
        dtype: Optional[str] = ...,
        cache: bool = ...,
        cell_lengths: Optional[List[float]] = ...,
        cell_origin: Optional[List[float]] = ...,
        periodic: Optional[str] = ...,
        surface: Optional[str] = ...,
        layers: Optional[Tuple[bool, bool, bool]] = ...,
        progress: Optional[Callable[[str, int, int], Any]] = ...,
    ) -> None:
        """``cell_lengths`` (one side or three), ``cell_origin``, ``periodic``
        (``"xyz"``, ``"xy"``, ``"x"``) and ``surface`` (``"tin-foil"``,
        ``"vacuum"``): the periodic cell of ``box=`` (``None``: free space).
        The JSON of ``evaluate`` then holds ``periodic`` (the cell) and
        ``energy`` (per vector: ``1/2 sum q phi`` or ``null``).
        ``layers = (forces, stresslets, pressure)`` (``"stokes"`` only): the
        densities per source are ``[f, m, n]`` (those carried, three values
        each) and the values per target the velocity then the pressure.
        ``progress(step, done, total)``: the build's progress (see ``Fmm``)."""
    def evaluate(
        self,
        charges: npt.NDArray[np.floating],
        n_vectors: int,
        progress: Optional[Callable[[int, int], Any]] = None,
    ) -> Tuple[npt.NDArray[np.floating], str]: ...
    def summary_json(self) -> str: ...
    def setup_timings_json(self) -> str: ...
    @property
    def values_per_target(self) -> int: ...
    @property
    def dtype(self) -> str: ...
    @property
    def n_sources(self) -> int: ...
    @property
    def n_targets(self) -> int: ...
    @property
    def threads(self) -> int: ...

class NativeOctree:
    def __init__(
        self,
        sources: npt.NDArray[np.floating],
        targets: Optional[npt.NDArray[np.floating]],
        leaf_size: int,
        balance: bool,
        max_level: int,
    ) -> None: ...
    n_boxes: int
    depth: int
    has_lists: bool
    sources_are_targets: bool
    domain: Tuple[Tuple[float, float, float], float]
    keys: npt.NDArray[np.uint64]
    morton: npt.NDArray[np.uint64]
    levels: npt.NDArray[np.uint32]
    anchors: npt.NDArray[np.uint32]
    parents: npt.NDArray[np.int64]
    leaves: npt.NDArray[np.int64]
    centers: npt.NDArray[np.float64]
    half_widths: npt.NDArray[np.float64]
    source_ranges: npt.NDArray[np.int64]
    target_ranges: npt.NDArray[np.int64]
    source_permutation: npt.NDArray[np.int64]
    target_permutation: npt.NDArray[np.int64]
    def list_csr(self, kind: str) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]: ...

def calibrate(points: int, cache_dir: Optional[str], threads: Optional[int]) -> str: ...

# Only in builds with MPI (HAS_MPI); the wrappers are in ferrofmm.distributed.
class NativeDistStokesLayers:
    def __init__(
        self,
        comm: int,
        sources: npt.NDArray[np.float64],
        targets: Optional[npt.NDArray[np.float64]],
        eps: Optional[float],
        order: Optional[int],
        leaf_size: Optional[int],
        scheme: str,
        gradient: bool,
        verify: bool,
        samples: int,
        threads: Optional[int],
        cache_dir: Optional[str],
        cache: bool,
        dtype: str,
        forces: bool,
        stresslets: bool,
        pressure: bool,
    ) -> None: ...
    def evaluate(
        self,
        forces: Optional[npt.NDArray[np.float64]],
        strslet: Optional[npt.NDArray[np.float64]],
        strsvec: Optional[npt.NDArray[np.float64]],
    ) -> Tuple[npt.NDArray[np.float64], Optional[npt.NDArray[np.float64]], str]: ...
    n_sources: int
    n_targets: int
    input_counts: List[int]
    carries: Tuple[bool, bool, bool]

class NativeDistFmm:
    def __init__(
        self,
        comm: int,
        sources: npt.NDArray[np.float64],
        targets: Optional[npt.NDArray[np.float64]],
        kernel: str,
        k: Optional[float],
        eps: Optional[float],
        order: Optional[int],
        leaf_size: Optional[int],
        scheme: str,
        gradient: bool,
        verify: bool,
        samples: int,
        threads: Optional[int],
        cache_dir: Optional[str],
        cache: bool,
        source: str,
        dtype: str,
    ) -> None: ...
    def evaluate(self, densities: npt.NDArray[np.float64]) -> Tuple[npt.NDArray[np.float64], str]: ...
    values_per_source: int
    values_per_target: int
    n_sources: int
    n_targets: int
    input_counts: List[int]
    target_counts: List[int]

class NativeDistOctree:
    def __init__(
        self, comm: int, points: npt.NDArray[np.float64], leaf_size: int, max_level: int
    ) -> None: ...
    rank: int
    size: int
    domain: Tuple[Tuple[float, float, float], float]
    keys: npt.NDArray[np.uint64]
    is_leaf: npt.NDArray[np.bool_]
    counts: npt.NDArray[np.int64]
    coarse_keys: npt.NDArray[np.uint64]
    cuts: npt.NDArray[np.uint64]
    points: npt.NDArray[np.float64]
    point_ids: npt.NDArray[np.uint64]
    input_counts: npt.NDArray[np.uint64]
    points_per_rank: npt.NDArray[np.uint64]
    ghost_keys: npt.NDArray[np.uint64]
    ghost_is_leaf: npt.NDArray[np.bool_]
    ghost_counts: npt.NDArray[np.int64]
    partners: npt.NDArray[np.int64]
    list_keys: npt.NDArray[np.uint64]
    def list_csr(self, kind: str) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]: ...
    def build_stats(self) -> Tuple[List[str], List[float], List[int], int]: ...
