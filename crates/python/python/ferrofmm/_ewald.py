"""The Ewald reference sum :func:`ewald` of charges in a periodic cell (direct summation
split by Ewald's method, in the native module)."""

from __future__ import annotations

import json
from typing import Any, Optional

import numpy as np

from . import _ferrofmm
from ._checks import _bool, _cell, _check_densities, _flat, _points, _positive_int, _real
from ._fmm import FmmResult


def _axes(periodic: Any) -> str:
    """``periodic=`` as the library reads it (a ValueError names a bad one)."""
    if not isinstance(periodic, str):
        raise TypeError(f"periodic must be a str (\"xyz\", \"xy\" or \"x\"), got {periodic!r}")
    return periodic


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
    k: float = 0.0,
    periodic: str = "xyz",
) -> FmmResult:
    """The Ewald sum of charges in a periodic cell: the reference of ``laplace(..., box=)``
    and ``yukawa(..., box=)``.

    ``phi(y) = sum_i sum_n q_i / (4 pi |y - x_i - n L|)`` over every image
    ``n`` of every charge (a source leaves out its own direct term, its
    images kept), closed with tin-foil (conducting) surroundings as
    :func:`laplace` with ``box`` and ``surface="tin-foil"``; with ``k > 0``
    the Yukawa sum ``sum_i sum_n q_i exp(-k r_n) / (4 pi r_n)``, which
    converges absolutely (no background, any charges), as :func:`yukawa`
    with ``box``. Direct summation split by Ewald's method, ``O(N^1.5)``: a
    reference for a few thousand points, not a solver.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Charge positions (float64 or float32; computed in float64).
        Points outside the cell are wrapped into it.
    charges : array_like, shape (n,)
        One charge per point. A Laplace cell that is not neutral gets a
        uniform background of total charge ``-sum q`` (Ewald's convention;
        the periodic FMM refuses such a cell); a Yukawa cell needs none.
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
    k : float
        The Yukawa screening wavenumber ``k >= 0`` (inverse length); ``0``
        (the default) is Laplace.
    periodic : str
        The axes that repeat: ``"xyz"`` (default), ``"xy"`` (a slab: Parry's
        two-dimensional Ewald sum, ``z`` free space) or ``"x"`` (a rod: the
        one-dimensional sum, ``y`` and ``z`` free space). A slab or rod has
        no surface term; a Laplace one must be neutral for the sum to mean
        anything (its divergent constant is dropped). Summed pair by pair,
        the nearest images directly and the rest through a Chebyshev grid
        for many points: the reference of ``laplace(..., box=,
        periodic="xy")``.

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
    k_value = _real("k", k)
    if k_value is None or not (np.isfinite(k_value) and k_value >= 0.0):
        raise ValueError(f"k must be a finite float >= 0, got {k!r}")
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
        k_value,
        _axes(periodic),
    )
    info = json.loads(info_json)
    info["kernel_name"] = "yukawa" if k_value > 0.0 else "laplace"
    v = values.reshape(-1, 4 if gradient else 1)
    potential = np.ascontiguousarray(v[:, 0])
    grad = np.ascontiguousarray(v[:, 1:4]) if gradient else None
    return FmmResult(potential, grad, info, None, energy)


def stokes_ewald(
    points: Any,
    forces: Any,
    box: Any,
    *,
    targets: Any = None,
    box_origin: Any = (0.0, 0.0, 0.0),
    gradient: bool = False,
    eps: float = 1e-12,
    threads: Optional[int] = None,
) -> FmmResult:
    """Hasimoto's Ewald sum of point forces in a periodic cell: the reference of
    ``stokes(..., box=)``.

    ``u(y) = sum_i G_per(y - x_i) f_i`` with the periodic Stokeslet of
    viscosity 1 (``G = (I / r + d d^T / r^3) / (8 pi)`` summed over every
    image with the ``k = 0`` Fourier term dropped): the mean velocity over
    the cell is zero, and a net force is balanced by a uniform pressure
    gradient, so any forces are accepted. A source leaves out its own
    direct term (its images kept). Direct summation split by Hasimoto's
    method: a reference for a few thousand points, not a solver.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Force positions (computed in float64); wrapped into the cell.
    forces : array_like, shape (n, 3)
        One force per point.
    box : float or sequence of 3 floats
        The cell's side ``L``, or its sides ``(Lx, Ly, Lz)``.
    targets, box_origin, gradient, eps, threads
        As for :func:`ewald`.

    Returns
    -------
    FmmResult
        ``.potential`` the velocity (m, 3), ``.gradient`` (m, 3, 3) with
        ``[j, a, c] = d u_a / d x_c`` or None, ``.energy`` None, ``.info``
        (``method`` ``"ewald"``, ``eps``, ``alpha``, ``r_cut``, ``k_cut``,
        ``total_force``, ``periodic``, ``timings``).

    Examples
    --------
    >>> import numpy as np, ferrofmm
    >>> r = ferrofmm.stokes_ewald([[0.5, 0.5, 0.5]], [[1.0, 0.0, 0.0]], 1.0)
    >>> round(float(-r.potential[0, 0] * 6 * np.pi), 9)  # Hasimoto's constant
    2.837297479
    """
    gradient = _bool("gradient", gradient)
    src = _points("points", points)
    tgt = None if targets is None else _points("targets", targets)
    f = np.asarray(forces, dtype=np.float64) if not isinstance(forces, np.ndarray) else forces
    if f.dtype.kind in "iu":
        f = f.astype(np.float64)
    if f.dtype.kind != "f" or f.shape != (len(src), 3):
        raise ValueError(
            f"forces must be a float array of shape ({len(src)}, 3), got {f.dtype} {f.shape}"
        )
    if not np.all(np.isfinite(f)):
        raise ValueError("forces must be finite (no NaN or infinity)")
    lengths, origin, _, _ = _cell(box, box_origin, None, None)
    eps_value = _real("eps", eps)
    if eps_value is None:
        raise TypeError("eps must be a float, got None")
    threads = _positive_int("threads", threads)
    wide = np.dtype(np.float64)
    values, info_json = _ferrofmm.stokes_ewald_sum(
        _flat(src, wide),
        _flat(f, wide),
        lengths,
        origin if origin is not None else [0.0, 0.0, 0.0],
        None if tgt is None else _flat(tgt, wide),
        gradient,
        eps_value,
        threads,
    )
    info = json.loads(info_json)
    info["kernel_name"] = "stokes"
    v = values.reshape(-1, 4 if gradient else 1, 3)
    velocity = np.ascontiguousarray(v[:, 0, :])
    grad = np.ascontiguousarray(np.swapaxes(v[:, 1:4, :], 1, 2)) if gradient else None
    return FmmResult(velocity, grad, info, None, None)
