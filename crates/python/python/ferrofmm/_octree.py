"""The octree on its own: :class:`Octree`."""

from __future__ import annotations

from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from . import _ferrofmm
from ._checks import (
    _bool,
    _check_memory,
    _flat,
    _native,
    _points,
    _positive_int,
)
from ._ferrofmm import DEEPEST_LEVEL, DEFAULT_LEAF_SIZE


class Octree:
    """The linear adaptive octree of a point set (as the FMM builds it).

    Boxes are numbered in (level, Morton) order; every box holds a
    contiguous range of the points sorted along the Morton curve. Only
    boxes holding points exist. A box is split while it holds more than
    ``leaf_size`` points (the larger of the source and target counts),
    then the tree is 2:1 balanced (adjacent leaves differ by at most one
    level) unless ``balance=False``.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        The (source) points, float64 or float32.
    leaf_size : int
        Points per leaf at most (except at ``max_level``).
    balance : bool
        2:1-balance the tree; the interaction lists need it.
    targets : array_like, shape (m, 3), optional
        A separate target set sharing the tree.
    max_level : int
        Deepest level (at most ``DEEPEST_LEVEL``).

    Attributes (NumPy arrays, one entry per box unless said)
    --------------------------------------------------------
    keys (uint64: Morton code and level), morton (uint64), levels (uint32),
    anchors (n_boxes, 3), parents (-1 for the root), leaves (box indices),
    centers (n_boxes, 3), half_widths, source_ranges / target_ranges
    (n_boxes, 2: start, end in the sorted order), permutation /
    target_permutation (caller's index of each sorted point).
    """

    def __init__(
        self,
        points: Any,
        leaf_size: int = DEFAULT_LEAF_SIZE,
        balance: bool = True,
        *,
        targets: Any = None,
        max_level: int = DEEPEST_LEVEL,
    ) -> None:
        p = _points("points", points)
        t = None if targets is None else _points("targets", targets)
        if leaf_size is None:
            raise TypeError("leaf_size must be an int, got NoneType")
        leaf = _positive_int("leaf_size", leaf_size)
        balance = _bool("balance", balance)
        if isinstance(max_level, bool) or not isinstance(max_level, (int, np.integer)):
            raise TypeError(f"max_level must be an int, got {type(max_level).__name__}")
        if not (0 <= max_level <= DEEPEST_LEVEL):
            raise ValueError(f"max_level must lie in 0..={DEEPEST_LEVEL}, got {max_level}")
        f64 = np.dtype(np.float64)
        _check_memory(
            f"an octree of {len(p)} points" + ("" if t is None else f" and {len(t)} targets"),
            f64, len(p), None if t is None else len(t), 0, 0, 0,
        )
        self._native = _ferrofmm.NativeOctree(
            _flat(p, f64), None if t is None else _flat(t, f64), leaf, bool(balance), int(max_level)
        )
        n = self._native
        self.n_boxes: int = n.n_boxes
        self.depth: int = n.depth
        self.balanced: bool = n.has_lists
        origin, width = n.domain
        self.domain_origin = np.array(origin)
        self.domain_width: float = width
        self.keys: np.ndarray = n.keys
        self.morton: np.ndarray = n.morton
        self.levels: np.ndarray = n.levels
        self.anchors: np.ndarray = n.anchors
        self.parents: np.ndarray = n.parents
        self.leaves: np.ndarray = n.leaves
        self.centers: np.ndarray = n.centers
        self.half_widths: np.ndarray = n.half_widths
        self.source_ranges: np.ndarray = n.source_ranges
        self.target_ranges: np.ndarray = n.target_ranges
        self.permutation: np.ndarray = n.source_permutation
        self.target_permutation: np.ndarray = n.target_permutation
        self._lists: Dict[str, Any] = {}

    def lists(self, kind: str):
        """The ``kind`` (``"u"``, ``"v"``, ``"w"`` or ``"x"``) interaction list in
        CSR form ``(offsets, indices)``: row ``b`` is ``indices[offsets[b]:offsets[b+1]]``.

        U: adjacent leaves and the leaf itself (direct sums); V: same-level
        well-separated boxes (M2L); W: finer boxes near a leaf (M2P); X: the
        dual of W (P2L). Raises ValueError for a tree built with ``balance=False``.
        """
        if kind not in self._lists:
            self._lists[kind] = self._native.list_csr(kind)
        return self._lists[kind]

    def _row(self, kind: str, b: int) -> np.ndarray:
        if not (0 <= b < self.n_boxes):
            raise IndexError(f"box {b} out of range 0..{self.n_boxes}")
        offsets, indices = self.lists(kind)
        return indices[offsets[b] : offsets[b + 1]]

    def u_list(self, b: int) -> np.ndarray:
        """U list of box ``b`` (near field)."""
        return self._row("u", b)

    def v_list(self, b: int) -> np.ndarray:
        """V list of box ``b`` (M2L)."""
        return self._row("v", b)

    def w_list(self, b: int) -> np.ndarray:
        """W list of box ``b`` (M2P)."""
        return self._row("w", b)

    def x_list(self, b: int) -> np.ndarray:
        """X list of box ``b`` (P2L)."""
        return self._row("x", b)

    def __repr__(self) -> str:
        return (
            f"Octree(n_boxes={self.n_boxes}, depth={self.depth}, "
            f"leaves={len(self.leaves)}, balanced={self.balanced})"
        )
