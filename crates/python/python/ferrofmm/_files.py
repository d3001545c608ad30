"""Files: :func:`load` and :func:`save`, through the reader and writer of the ``ferrofmm`` and
``ferrofmm-mpi`` commands (the Rust crate ``ferrofmm-io``), so the three front ends take the same
files and give the same messages."""

from __future__ import annotations

import os
from typing import Any, List, Optional, Sequence

import numpy as np

from . import _ferrofmm
from ._checks import _kernel, _vector_valued

_WHAT = ("points", "charges", "dipoles")


def _path(path: Any) -> str:
    if not isinstance(path, (str, bytes, os.PathLike)):
        raise TypeError(f"path must be a str or os.PathLike, got {type(path).__name__}")
    p = os.fsdecode(os.fspath(path))
    if not p:
        raise ValueError("path is empty")
    return p


def load(path: Any, what: str = "points", *, kernel: str = "laplace") -> np.ndarray:
    """Read points, charges or dipole vectors from a file, as ``ferrofmm eval`` reads them.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.csv`` file (one record per line, commas or whitespace, an optional header line,
        ``#`` comments), a ``.npy`` file (float64 or float32; complex128 or complex64 for a
        complex kernel's densities; either byte order, C or Fortran order) or a raw ``.f64``
        file (little-endian float64, one record after the other).
    what : {"points", "charges", "dipoles"}
        What the file holds, which fixes the shape of its records.
    kernel : str
        The kernel the densities are for (a name of :data:`ferrofmm.KERNELS`): its components
        fix the shape of charges and dipoles.

    Returns
    -------
    numpy.ndarray
        Points: ``(n, 3)`` float64. Charges: ``(n,)`` float64 for a scalar kernel, ``(n,)``
        complex128 for a complex one (from a complex array, ``re, im`` records or real charges
        alone, whose imaginary parts are zero), ``(n, 3)`` for Stokes forces. Dipoles:
        ``(n, 3)``, complex128 for a complex kernel; Stokes force dipoles ``(n, 3, 3)`` (nine
        values a record, ``D[k, c]``).

    Raises
    ------
    ValueError
        A malformed file (ragged rows, a bad number, a dtype or shape that does not fit, a
        truncated ``.npy``, no records), with the message the commands print.
    OSError
        A missing or unreadable file (``FileNotFoundError``, ``PermissionError``,
        ``IsADirectoryError``).
    MemoryError
        The values would not fit in the memory limit (``FERROFMM_MEMORY_LIMIT``).
    """
    p = _path(path)
    if what not in _WHAT:
        raise ValueError(f"what must be 'points', 'charges' or 'dipoles', got {what!r}")
    d = _kernel(kernel)
    if what == "dipoles" and not d["dipoles"]:
        raise ValueError(
            f"kernel {kernel!r} does not support dipole sources (its sources are point "
            f"{d['density_name']})"
        )
    values, columns, _ = _ferrofmm.read_file(p, what, d["components"], d["complex"])
    if what == "points":
        return values.reshape(-1, 3)
    if d["complex"] and what != "points":
        z = values.view(np.complex128)
        return z if what == "charges" else z.reshape(-1, 3)
    if columns == 1:
        return values
    if what == "dipoles" and d["components"] > 1:
        return values.reshape(-1, 3, d["components"])
    return values.reshape(-1, columns)


def _result_columns(result: Any) -> tuple:
    """The values of an :class:`FmmResult` as the commands write them: one row per target,
    potential then gradient then Hessian, each once per kernel component; and the kernel's
    component names."""
    kernel = result.info.get("kernel_name", "laplace")
    d = _kernel(kernel)
    m = result.potential.shape[-2 if _vector_valued(kernel) else -1]
    expected_ndim = 2 if _vector_valued(kernel) else 1
    if result.potential.ndim != expected_ndim:
        raise ValueError(
            f"save writes one result at a time: this one holds {result.potential.shape[0]} "
            "vectors (save result.potential[i] and the others as arrays)"
        )
    parts = [result.potential.reshape(m, -1)]
    if result.gradient is not None:
        g = result.gradient
        if _vector_valued(kernel):
            # gradient[a, c] = d u_a / d x_c; the commands' grad_c_a is d u_a / d x_c.
            g = np.swapaxes(g, -1, -2)
        parts.append(g.reshape(m, -1))
    if result.hessian is not None:
        parts.append(result.hessian.reshape(m, -1))
    table = np.concatenate(parts, axis=1)
    quantities = table.shape[1] // (1 if d["complex"] else d["components"])
    return table, _ferrofmm.column_names(quantities, list(d["component_names"]))


def save(path: Any, values: Any, *, names: Optional[Sequence[str]] = None) -> None:
    """Write an array, or an evaluation's result, as ``ferrofmm eval --out`` writes its output.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.csv`` file (a header line of the column names, then one record per line) or a
        ``.npy`` file. Written atomically: through a temporary file, renamed when complete; an
        existing file is replaced only then.
    values : numpy.ndarray or FmmResult
        An array ``(n,)`` or ``(n, c)`` of float64, float32, complex128 or complex64 (a
        complex array is written as a complex ``.npy`` array, or as ``_re``, ``_im`` columns in
        a ``.csv`` file); or the :class:`FmmResult` of one density vector, written with the
        columns and header of ``ferrofmm eval``'s output (``potential``, ``grad_x``, ...;
        ``potential_re``, ``potential_im``, ... for Helmholtz in ``.csv``; a complex ``.npy``
        array).
    names : sequence of str, optional
        Column names of an array (one per column; complex columns get ``_re`` and ``_im``
        suffixes in ``.csv``); by default ``value`` for one column, else ``value_1``,
        ``value_2``, ...
    """
    p = _path(path)
    from ._fmm import FmmResult

    if isinstance(values, FmmResult):
        if names is not None:
            raise ValueError("names are given by the result: potential, grad_x, ...")
        table, columns = _result_columns(values)
    else:
        table = np.asarray(values)
        if table.dtype.kind not in "fc" or table.dtype.itemsize not in (4, 8, 16):
            raise TypeError(
                f"values must be float64, float32, complex128 or complex64, got {table.dtype}"
            )
        if table.ndim not in (1, 2) or table.shape[0] == 0 or table.size == 0:
            raise ValueError(f"values must have shape (n,) or (n, c) with n, c > 0, got {table.shape}")
        c = 1 if table.ndim == 1 else table.shape[1]
        if names is None:
            base: List[str] = ["value"] if c == 1 else [f"value_{i + 1}" for i in range(c)]
        else:
            base = [str(n) for n in names]
            if len(base) != c:
                raise ValueError(f"{len(base)} names for {c} columns")
        table = table.reshape(table.shape[0], c)
        if table.dtype.kind == "c":
            columns = [f"{n}_{part}" for n in base for part in ("re", "im")]
        else:
            columns = base
    complex_values = table.dtype.kind == "c"
    real = np.dtype(np.float32) if table.dtype.itemsize in (4, 8) and (
        table.dtype == np.float32 or table.dtype == np.complex64
    ) else np.dtype(np.float64)
    if complex_values:
        flat = np.ascontiguousarray(table, dtype=np.complex64 if real == np.float32 else np.complex128)
        flat = flat.view(real).reshape(-1)
    else:
        flat = np.ascontiguousarray(table, dtype=real).reshape(-1)
    if not np.all(np.isfinite(flat)):
        raise ValueError("values hold NaN or infinite numbers")
    _ferrofmm.write_file(p, flat, list(columns), complex_values)
