"""Without MPI in the build, ``import ferrofmm.distributed`` says how to get it."""

import pytest

import ferrofmm
from ferrofmm import _ferrofmm


def test_import_without_mpi_says_how_to_get_it():
    if _ferrofmm.HAS_MPI:
        pytest.skip("this build has MPI: tests/distributed covers the module")
    with pytest.raises(ImportError, match="FERROFMM_MPI=1"):
        import ferrofmm.distributed  # noqa: F401
    assert ferrofmm.__version__
