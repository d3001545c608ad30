"""Every bad input is a ValueError or TypeError with a clear message, never a crash."""

import numpy as np
import pytest

import ferrofmm

rng = np.random.default_rng(3)
X = rng.random((500, 3))
Q = rng.random(500) - 0.5


@pytest.mark.parametrize(
    "sources, match",
    [
        (np.zeros((10, 2)), r"shape \(n, 3\)"),
        (np.zeros(9), r"shape \(n, 3\)"),
        (np.zeros((2, 3, 3)), r"shape \(n, 3\)"),
        (np.zeros((0, 3)), "empty"),
    ],
)
def test_bad_shapes(sources, match):
    with pytest.raises(ValueError, match=match):
        ferrofmm.laplace(sources, np.zeros(len(sources)), order=4)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite(bad):
    x = X.copy()
    x[17, 1] = bad
    with pytest.raises(ValueError, match="sources coordinate .* not finite"):
        ferrofmm.laplace(x, Q, order=4)
    y = X[:20].copy()
    y[3, 2] = bad
    with pytest.raises(ValueError, match="targets coordinate .* not finite"):
        ferrofmm.laplace(X, Q, targets=y, order=4)
    q = Q.copy()
    q[5] = bad
    with pytest.raises(ValueError, match="charge 5 is not finite"):
        ferrofmm.laplace(X, q, order=4)
    with pytest.raises(ValueError, match="point 2 has a non-finite coordinate"):
        ferrofmm.Octree(np.where(np.arange(1500).reshape(500, 3) == 7, bad, X))


def test_mismatched_lengths():
    with pytest.raises(ValueError, match="499 values but there are 500 sources"):
        ferrofmm.laplace(X, Q[:-1], order=4)
    with pytest.raises(ValueError, match=r"shape \(k, 500\)"):
        ferrofmm.laplace(X, np.zeros((2, 499)), order=4)
    with pytest.raises(ValueError, match="no charge vector"):
        ferrofmm.laplace(X, np.zeros((0, 500)), order=4)
    with pytest.raises(ValueError, match=r"\(n,\) or \(k, n\)"):
        ferrofmm.laplace(X, np.zeros((1, 1, 500)), order=4)
    with pytest.raises(ValueError, match="targets"):
        ferrofmm.laplace(X, Q, targets=np.zeros((0, 3)), order=4)


@pytest.mark.parametrize("eps", [0.0, 1.0, -1e-6, 2.0, float("nan"), 1e-30])
def test_bad_eps(eps):
    with pytest.raises(ValueError, match="tolerance"):
        ferrofmm.laplace(X, Q, eps=eps)


@pytest.mark.parametrize("order", [0, 1, 100, -3])
def test_bad_order(order):
    with pytest.raises(ValueError, match="order"):
        ferrofmm.laplace(X, Q, order=order)


@pytest.mark.parametrize(
    "kwargs, exc, match",
    [
        ({"order": 2.5}, TypeError, "order must be an int"),
        ({"eps": "1e-6"}, TypeError, "eps must be a float"),
        ({"eps": 1e-6, "order": 6}, ValueError, "not both"),
        ({"eps": 1e-6, "leaf_size": 10}, ValueError, "leaf_size is chosen from eps"),
        ({"order": 4, "leaf_size": 0}, ValueError, "leaf_size must be at least 1"),
        ({"order": 4, "threads": 0}, ValueError, "threads must be at least 1"),
        ({"order": 4, "scheme": "fmm"}, ValueError, "unknown M2L scheme"),
        ({"order": 4, "dtype": np.int32}, TypeError, "dtype must be float32 or float64"),
        ({"order": 4, "dtype": "float16"}, TypeError, "dtype must be float32 or float64"),
        ({"order": 4, "eps": None, "dtype": "nonsense"}, TypeError, "dtype"),
    ],
)
def test_bad_parameters(kwargs, exc, match):
    with pytest.raises(exc, match=match):
        ferrofmm.laplace(X, Q, **kwargs)


def test_tolerance_beyond_float32():
    with pytest.raises(ValueError, match="beyond what f32 can promise"):
        ferrofmm.laplace(X.astype(np.float32), Q, eps=1e-9)


@pytest.mark.parametrize(
    "dtype, exc",
    [(np.int64, TypeError), (np.int32, TypeError), (np.complex128, TypeError), (bool, TypeError), (np.float16, TypeError)],
)
def test_bad_dtypes(dtype, exc):
    with pytest.raises(exc, match="float32 or float64|real"):
        ferrofmm.laplace(X.astype(dtype), Q, order=4)
    with pytest.raises(exc, match="float32 or float64|real"):
        ferrofmm.laplace(X, Q.astype(dtype), order=4)


def test_bad_kernels():
    with pytest.raises(ValueError, match="unknown kernel"):
        ferrofmm.Fmm(X, kernel="maxwell", order=4)
    with pytest.raises(ValueError, match="needs k"):
        ferrofmm.Fmm(X, kernel="yukawa", order=4)
    with pytest.raises(ValueError, match="k"):
        ferrofmm.yukawa(X, Q, k=-1.0, order=4)
    with pytest.raises(ValueError, match="k"):
        ferrofmm.yukawa(X, Q, k=float("nan"), order=4)
    with pytest.raises(ValueError, match="not laplace"):
        ferrofmm.Fmm(X, kernel="laplace", k=1.0, order=4)


def test_not_arrays():
    with pytest.raises((ValueError, TypeError)):
        ferrofmm.laplace("points", Q, order=4)
    with pytest.raises((ValueError, TypeError)):
        ferrofmm.laplace([[0, 0, 0], [1, 1]], [1, 2], order=4)
    with pytest.raises(TypeError):
        ferrofmm.laplace(X, Q, order=4, threads="two")


def test_octree_bad_parameters():
    with pytest.raises(ValueError, match="leaf_size"):
        ferrofmm.Octree(X, leaf_size=0)
    with pytest.raises(ValueError, match="max_level"):
        ferrofmm.Octree(X, max_level=99)
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        ferrofmm.Octree(np.zeros((4, 4)))
    with pytest.raises(TypeError):
        ferrofmm.Octree(X.astype(np.complex64))
