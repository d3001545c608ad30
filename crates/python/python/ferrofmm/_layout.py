"""The layout of the flat arrays the native module reads and returns: densities packed
per source (:func:`_pack_densities`) and values shaped per target (:func:`_shape_values`),
shared by :class:`ferrofmm.Fmm` and :class:`ferrofmm.distributed.Fmm`."""

from __future__ import annotations

from typing import List, Optional, Tuple

import numpy as np

from ._checks import _as_complex_array, _check_float32_range, _kernel, _vector_valued


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
