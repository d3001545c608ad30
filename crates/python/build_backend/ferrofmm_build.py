"""The package's PEP 517 build backend: maturin, with the Rust feature ``mpi`` (the module
``ferrofmm.distributed``) turned on when the build finds an MPI installation.

``FERROFMM_MPI`` decides:

* unset or empty: ``mpi`` when ``mpicc`` is on ``PATH`` (an MPI with its headers; the Rust
  ``mpi`` crate also needs libclang, which Debian's ``libclang-dev`` provides);
* ``1`` (``yes``, ``on``, ``true``): ``mpi``, and the build fails with a clear message when
  no ``mpicc`` is found;
* ``0`` (``no``, ``off``, ``false``): no ``mpi``; ``import ferrofmm.distributed`` then raises
  ``ImportError`` saying how to get it.

The choice is passed to maturin as ``--features mpi`` in ``MATURIN_PEP517_ARGS`` (added to
what is there already); everything else is maturin's own backend.
"""

from __future__ import annotations

import os
import shlex
import shutil
from typing import Any, Mapping, Optional

import maturin
from maturin import (  # noqa: F401  (re-exported PEP 517 hooks)
    build_sdist,
    get_requires_for_build_sdist,
    get_requires_for_build_wheel,
    prepare_metadata_for_build_wheel,
)

_ON = {"1", "yes", "on", "true"}
_OFF = {"0", "no", "off", "false"}


def _want_mpi() -> bool:
    value = os.environ.get("FERROFMM_MPI", "").strip().lower()
    found = shutil.which("mpicc") is not None
    if value in _OFF:
        return False
    if value in _ON:
        if not found:
            raise RuntimeError(
                "FERROFMM_MPI=1 asks for ferrofmm.distributed, but no MPI installation was "
                "found (mpicc is not on PATH): install one with its headers (Debian/Ubuntu: "
                "apt install libopenmpi-dev openmpi-bin libclang-dev), or set FERROFMM_MPI=0"
            )
        return True
    if value:
        raise RuntimeError(f"FERROFMM_MPI={value!r}: use 1 (with MPI) or 0 (without)")
    return found


def _with_features() -> None:
    args = shlex.split(os.environ.get("MATURIN_PEP517_ARGS", ""))
    if _want_mpi() and not any(a == "--features" or a.startswith("--features=") for a in args):
        args += ["--features", "mpi"]
        print("ferrofmm: MPI found (mpicc), building with ferrofmm.distributed")
    os.environ["MATURIN_PEP517_ARGS"] = shlex.join(args)


def build_wheel(
    wheel_directory: str,
    config_settings: Optional[Mapping[str, Any]] = None,
    metadata_directory: Optional[str] = None,
) -> str:
    _with_features()
    return maturin.build_wheel(wheel_directory, config_settings, metadata_directory)


def build_editable(
    wheel_directory: str,
    config_settings: Optional[Mapping[str, Any]] = None,
    metadata_directory: Optional[str] = None,
) -> str:
    _with_features()
    return maturin.build_editable(wheel_directory, config_settings, metadata_directory)
