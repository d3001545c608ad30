"""``ferrofmm.calibrate``: the cost model measured on this machine."""

from __future__ import annotations

import json

import numpy as np
from typing import Any, Dict, Optional

from . import _ferrofmm
from ._checks import _cache, _positive_int


def calibrate(points: int = 200_000, *, cache: Any = True,
              threads: Optional[int] = None) -> Dict[str, Any]:
    """Measure how fast this machine runs each kind of FMM work, and save it where the
    parameter chooser finds it.

    The chooser weighs the near field (P2P), the far field, the M2L (SVD and FFT) and the
    tree with a cost model fitted on one machine; another machine has other ratios between
    them (AVX2 against AVX-512, memory bandwidth), and with them other best leaf sizes and
    schemes. This times six Laplace FMMs on ``points`` uniform points (seconds to a
    minute) and saves, for each kind of work, the measured over the predicted time in the
    operator cache folder: ``cache`` as :class:`Fmm` takes it (``True``: the default
    folder, ``FERROFMM_CACHE``, else ``$XDG_CACHE_HOME/ferrofmm``, else
    ``~/.cache/ferrofmm``; or a path). Later runs with that cache folder, on this processor
    and with as many ``threads`` (default: one per core, or ``RAYON_NUM_THREADS``), use it:
    their ``info["model"]`` then says "calibrated on this machine". The command line's
    ``ferrofmm calibrate`` does the same.

    Returns ``{"processor", "threads", "scales": {"p2p", "far", "m2l_compressed",
    "m2l_fft", "tree"}, "file"}``.
    """
    if isinstance(points, bool) or not isinstance(points, (int, np.integer)):
        raise TypeError(f"points must be an int, got {type(points).__name__}")
    if points < 1000:
        raise ValueError(f"points must be at least 1000, got {points}")
    folder, use_default = _cache(cache, None)
    if not use_default:
        raise ValueError("cache=False leaves no folder to keep the calibration in: give a path")
    return json.loads(_ferrofmm.calibrate(points, folder, _positive_int("threads", threads)))
