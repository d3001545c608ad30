"""Argument checks shared by the package's classes: dtypes, shapes, ranges and the kernel rules,
read from the native module's kernel registry (``_ferrofmm.KERNELS``), so every front end of the
library agrees on names, components and messages."""

from __future__ import annotations

import os
import sys
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from . import _ferrofmm
from ._ferrofmm import MAX_ORDER, MIN_ORDER

_FLOATS = (np.dtype(np.float32), np.dtype(np.float64))

def _float_dtype(dtype: Any) -> Optional[np.dtype]:
    if dtype is None:
        return None
    try:
        d = np.dtype(dtype)
    except TypeError as e:
        raise TypeError(f"dtype must be float32 or float64, got {dtype!r}") from e
    if d not in _FLOATS:
        raise TypeError(f"dtype must be float32 or float64, got {d}")
    return d


def _as_float_array(name: str, value: Any) -> np.ndarray:
    """The caller's array as a NumPy array of float32 or float64 (no copy yet)."""
    if isinstance(value, np.ndarray):
        a = value
    else:
        try:
            a = np.asarray(value)
        except (ValueError, TypeError) as e:
            raise ValueError(f"{name} is not a numeric array: {e}") from e
        if a.dtype.kind in "iu":  # plain Python numbers: lists of ints are fine
            a = a.astype(np.float64)
    kind = a.dtype.kind
    if kind == "c":
        raise TypeError(f"{name} must be real (float32 or float64), got complex dtype {a.dtype}")
    if kind in "iub":
        raise TypeError(
            f"{name} must be float32 or float64, got {a.dtype} (convert with .astype(np.float64))"
        )
    if a.dtype not in _FLOATS and _native(a.dtype) not in _FLOATS:
        raise TypeError(f"{name} must be float32 or float64, got {a.dtype}")
    return a


def _native(dtype: np.dtype) -> np.dtype:
    """``dtype`` in the machine's byte order (``>f8`` is float64 too)."""
    return dtype.newbyteorder("=")


def _bool(name: str, value: Any) -> bool:
    """A flag: ``True`` / ``False`` (or NumPy's), nothing else (``"no"`` is truthy)."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise TypeError(f"{name} must be True or False, got {type(value).__name__} {value!r}")


def _real(name: str, value: Any) -> Optional[float]:
    """A real number (int or float, not bool, str or complex), or None."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise TypeError(f"{name} must be a float, got {type(value).__name__}")
    return float(value)


def _wavenumber(value: Any) -> Optional[Tuple[float, float]]:
    """A wavenumber as ``(re, im)``: a real number, or a complex one (damped Helmholtz
    waves; the kernel refuses a negative imaginary part), or None."""
    if value is None:
        return None
    if isinstance(value, (complex, np.complexfloating)):
        return (float(value.real), float(value.imag))
    re = _real("k", value)
    return None if re is None else (re, 0.0)


def _kernel(name: str) -> Dict[str, Any]:
    """The registry's description of kernel ``name`` (see ``_ferrofmm.KERNELS``), else ValueError
    naming the kernels there are."""
    if not isinstance(name, str):
        raise TypeError(f"kernel must be a string, got {type(name).__name__}")
    d = _ferrofmm.KERNELS.get(name)
    if d is None:
        known = ", ".join(repr(k) for k in _ferrofmm.KERNELS)
        raise ValueError(f"unknown kernel {name!r}: use one of {known}")
    return d


def _vector_valued(kernel: str) -> bool:
    """Whether the kernel's densities and values are real vectors (Stokes), one axis more."""
    d = _kernel(kernel)
    return d["components"] > 1 and not d["complex"]


def _density_tail(kernel: str, key: str) -> Tuple[int, ...]:
    """Trailing shape of one source's density: ``()`` for a charge of a scalar or complex kernel,
    ``(c,)`` for a kernel with ``c`` real components (Stokes forces), ``(3,)`` for a dipole of a
    scalar or complex kernel and for a stresslet's strength or orientation, ``(3, c)`` for a
    dipole of a kernel with ``c`` real components (a Stokes force dipole ``D[k, c]``)."""
    if key in ("strslet", "strsvec"):
        return (3,)
    if key == "dipoles":
        return (3, _kernel(kernel)["components"]) if _vector_valued(kernel) else (3,)
    return (_kernel(kernel)["components"],) if _vector_valued(kernel) else ()


def _as_number_array(name: str, value: Any) -> np.ndarray:
    """``value`` as a NumPy array of numbers (no copy), else TypeError."""
    try:
        a = np.asarray(value)
    except Exception as e:  # noqa: BLE001 - anything numpy cannot take
        raise TypeError(f"{name} must be an array of numbers: {e}") from None
    if a.dtype.kind not in "biufc":
        raise TypeError(f"{name} must hold numbers, got dtype {a.dtype}")
    return a


def _as_complex_array(name: str, value: Any) -> np.ndarray:
    """``value`` as a complex array (real input allowed), rejecting non-numbers and non-finite values."""
    a = _as_number_array(name, value).astype(np.complex128)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} holds NaN or infinite values")
    return a


def _points(name: str, value: Any, allow_empty: bool = False) -> np.ndarray:
    """An ``(n, 3)`` float array (``n = 0`` only with ``allow_empty``: one rank's share)."""
    a = _as_float_array(name, value)
    if a.ndim != 2 or a.shape[1] != 3:
        if allow_empty and a.size == 0:
            return np.zeros((0, 3), dtype=a.dtype)
        raise ValueError(f"{name} must have shape (n, 3), got {a.shape}")
    if a.shape[0] == 0 and not allow_empty:
        raise ValueError(f"{name} are empty")
    return a


def _flat(a: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """``a`` as a C-contiguous array of ``dtype``, flattened (x, y, z interleaved).

    No copy when ``a`` already is one (the native module copies what it
    keeps); call it only after :func:`_check_memory`.
    """
    return np.ascontiguousarray(a, dtype=dtype).reshape(-1)


def _check_memory(what: str, dtype: np.dtype, n: int, m: Optional[int], per_source: int,
                  per_target: int, k: int, build: bool = True) -> None:
    """MemoryError, before anything is copied, when the run cannot fit (see the native check)."""
    _ferrofmm.check_run_memory(what, str(dtype), n, m, per_source, per_target, k, build)


def _check_eps_order(eps: Optional[float], order: Optional[int]) -> None:
    """Types here; ranges in the library (one message for every front end)."""
    _real("eps", eps)
    if order is not None:
        if isinstance(order, bool) or not isinstance(order, (int, np.integer)):
            raise TypeError(f"order must be an int, got {type(order).__name__}")
        # The library's message; an order beyond any integer the library
        # takes (-3, 10**30) would be an OverflowError on the way.
        if not (MIN_ORDER <= order <= MAX_ORDER):
            raise ValueError(
                f"expansion order {order} is not supported (use {MIN_ORDER}..={MAX_ORDER})"
            )


def _positive_int(name: str, value: Optional[int]) -> Optional[int]:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an int, got {type(value).__name__}")
    if value < 1:
        raise ValueError(f"{name} must be at least 1 (got {value})")
    # Beyond any size the native module takes: one leaf, or every core.
    return min(int(value), sys.maxsize)


def _cache_dir(value: Any, name: str = "cache_dir") -> Optional[str]:
    if value is None:
        return None
    if not isinstance(value, (str, bytes, os.PathLike)):
        raise TypeError(f"{name} must be a path (str or os.PathLike), got {type(value).__name__}")
    path = os.fsdecode(os.fspath(value))
    if not path:
        raise ValueError(f"{name} is an empty path")
    return path


def _cache(cache: Any, cache_dir: Any) -> Tuple[Optional[str], bool]:
    """``(folder, use_default)``: the folder named by ``cache="path"`` or
    ``cache_dir=``, else ``None`` and whether the default folder is used
    (``cache=True``) or none (``cache=False``)."""
    folder = _cache_dir(cache_dir)
    if isinstance(cache, (bool, np.bool_)):
        if folder is not None and not cache:
            raise ValueError("cache=False contradicts cache_dir: give one of them")
        return folder, bool(cache)
    if not isinstance(cache, (str, bytes, os.PathLike)):
        raise TypeError(
            f"cache must be True, False or a path (str or os.PathLike), got {type(cache).__name__}"
        )
    if folder is not None:
        raise ValueError("give cache or cache_dir, not both")
    return _cache_dir(cache, "cache"), True


def _per_target(kernel: str, gradient: bool, hessian: bool, pressure: bool = False) -> int:
    """Values per target and vector: quantities times the kernel's components (and the Stokes
    pressure, with its gradient, after the velocity)."""
    quantities = 10 if hessian else 4 if gradient else 1
    return quantities * (_kernel(kernel)["components"] + int(pressure))


def _per_source(kernel: str, charges: bool, dipoles: bool, stresslets: bool = False) -> int:
    """Values per source and vector (a stresslet: its strength and orientation, six)."""
    return (int(charges) + 3 * int(dipoles)) * _kernel(kernel)["components"] + 6 * int(stresslets)


def _check_float32_range(name: str, a: np.ndarray) -> None:
    """Densities beyond float32 would become infinite in a float32 run: refuse them before any
    setup, naming the caller's argument (the library's ``check_representable`` message)."""
    largest = float(np.finfo(np.float32).max)
    beyond = np.abs(a) > largest
    if np.any(beyond):
        i = int(np.flatnonzero(beyond)[0])
        raise ValueError(
            f"{name} value {i} ({a.reshape(-1)[i]:.3e}) exceeds the largest f32 number "
            f"({largest:.3e}): use dtype=\"float64\" or scale the densities down (the result is "
            "linear in them)"
        )


def _carried(
    carries: Dict[str, bool], values: Dict[str, Any], names: Optional[Dict[str, str]] = None
) -> List[Tuple[str, str, Any]]:
    """The densities given (``values``: key -> array or ``None``), each checked against
    what an Fmm's sources carry (``carries``: key -> bool), as ``(name shown, key,
    value)`` for :func:`_check_densities`. ``names`` renames keys in messages (``forces``
    for ``charges``)."""
    flag = {"strslet": "stresslets", "strsvec": "stresslets"}
    given = []
    for key, value in values.items():
        shown = (names or {}).get(key, key)
        if value is None:
            if carries[key]:
                raise ValueError(f"this Fmm's sources carry {shown}: give {shown}")
            continue
        if not carries[key]:
            carried = (
                "charges" if carries["charges"] else "dipoles" if carries["dipoles"]
                else "stresslets"
            )
            raise ValueError(
                f"this Fmm's sources carry no {shown} (only {carried}): "
                f"build it with {flag.get(key, key)}=True"
            )
        given.append((shown, key, value))
    return given


def _check_densities(
    kernel: str, n: int, given: List[Tuple[str, str, Any]]
) -> Tuple[List[Tuple[str, np.ndarray, Tuple[int, ...]]], int, bool]:
    """Dtypes and shapes of the densities, before anything is built or copied.

    ``given`` holds ``(name the caller used, "charges" or "dipoles", value)``;
    returns ``(name shown, array as given, not converted, trailing shape)``
    per density, the number of vectors and
    whether they were batched. Messages name the caller's argument
    (``forces`` for :func:`stokes`).
    """
    out = []
    shapes = set()
    for shown, key, value in given:
        if _kernel(kernel)["complex"]:
            a = _as_number_array(shown, value)
        else:
            a = _as_float_array(shown, value)
        tail = _density_tail(kernel, key)
        one = "(" + ", ".join(["n"] + [str(t) for t in tail]) + (",)" if tail == () else ")")
        many = "(" + ", ".join(["k", "n"] + [str(t) for t in tail]) + ")"
        if a.ndim == 1 + len(tail):
            batched = False
        elif a.ndim == 2 + len(tail):
            batched = True
        else:
            raise ValueError(f"{shown} must have shape {one} or {many}, got {a.shape}")
        rows = a.shape[1:] if batched else a.shape
        if rows != (n,) + tail:
            if tail == () and not batched:
                raise ValueError(f"{shown} has {a.shape[0]} values but there are {n} sources")
            if tail == ():
                raise ValueError(
                    f"{shown} must have shape (k, {n}) (one row per charge vector), got {a.shape}"
                )
            dims = ", ".join(str(t) for t in tail)
            raise ValueError(
                f"{shown} has shape {a.shape} but there are {n} sources: use "
                f"({n}, {dims}) or (k, {n}, {dims})"
            )
        k = a.shape[0] if batched else 1
        if k == 0:
            what = "charge vector" if tail == () else "vector set"
            raise ValueError(f"{shown} holds no {what} (shape {a.shape})")
        out.append((shown, a, tail))
        shapes.add((k, batched))
    if len(shapes) > 1:
        raise ValueError(
            "charges and dipoles must both be single or hold the same number of vectors"
        )
    k, batched = shapes.pop()
    return out, k, batched


def _numbers(name: str, value: Any, counts: Tuple[int, ...], shape: str) -> List[float]:
    """``value`` as a list of ``counts`` real numbers (a single number counts as one), else
    ValueError naming ``shape`` (the forms allowed)."""
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be {shape}, got {value!r}")
    if isinstance(value, (int, float, np.integer, np.floating)):
        values = [value]
    else:
        try:
            a = np.asarray(value)
        except Exception as e:  # noqa: BLE001 - anything numpy cannot take
            raise TypeError(f"{name} must be {shape}: {e}") from None
        if a.dtype.kind not in "iuf":
            raise TypeError(f"{name} must be {shape}, got {value!r}")
        if a.ndim > 1:
            raise ValueError(f"{name} must be {shape}, got shape {a.shape}")
        values = list(a.reshape(-1))
    if len(values) not in counts:
        raise ValueError(f"{name} must be {shape}, got {len(values)} values")
    return [float(v) for v in values]


def _cell(
    box: Any, box_origin: Any, periodic: Any, surface: Any
) -> Tuple[Optional[List[float]], Optional[List[float]], Optional[str], Optional[str]]:
    """The periodic cell's arguments for the native module: ``box`` (one side, or three),
    ``box_origin`` (three numbers), ``periodic`` (axes) and ``surface`` (names the library
    parses and checks; its messages). Without ``box``, the others are an error."""
    if box is None:
        for name, value in (("box_origin", box_origin), ("periodic", periodic),
                            ("surface", surface)):
            if value is not None:
                raise ValueError(
                    f"{name}= needs box= (the side L of the periodic cell, or its sides "
                    "(Lx, Ly, Lz))"
                )
        return None, None, None, None
    lengths = _numbers("box", box, (1, 3), "a side L or three sides (Lx, Ly, Lz)")
    origin = None if box_origin is None else _numbers(
        "box_origin", box_origin, (3,), "three numbers (x, y, z)"
    )
    for name, value in (("periodic", periodic), ("surface", surface)):
        if value is not None and not isinstance(value, str):
            raise TypeError(f"{name} must be a string, got {type(value).__name__}")
    return lengths, origin, periodic, surface
