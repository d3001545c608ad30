"""Shared fixtures: point sets, charges and a NumPy direct sum."""

import os

import numpy as np
import pytest


def direct(sources, charges, targets, *, k=None, gradient=False, exclude_self=True):
    """phi(y) = sum_i q_i K(|y - x_i|) with K = 1/(4 pi r) or exp(-k r)/(4 pi r),
    pairs at distance 0 excluded; and grad_y phi when asked. float64, chunked."""
    sources = np.asarray(sources, dtype=np.float64)
    targets = np.asarray(targets, dtype=np.float64)
    q = np.asarray(charges, dtype=np.float64)
    phi = np.zeros(q.shape[:-1] + (len(targets),))
    grad = np.zeros(q.shape[:-1] + (len(targets), 3))
    for s in range(0, len(targets), 256):
        d = targets[s : s + 256, None, :] - sources[None, :, :]
        r = np.sqrt((d * d).sum(-1))
        zero = r == 0
        rs = np.where(zero, 1.0, r)
        kern = 1.0 / (4 * np.pi * rs)
        # dK/dr / r, so that grad_y K = (dK/dr / r) (y - x)
        dk = -kern / rs**2
        if k is not None:
            e = np.exp(-k * rs)
            dk = -(1.0 + k * rs) * e * kern / rs**2
            kern = kern * e
        kern[zero] = 0.0
        dk[zero] = 0.0
        phi[..., s : s + 256] = q @ kern.T
        grad[..., s : s + 256, :] = np.einsum("...j,ij,ijc->...ic", q, dk, d)
    return (phi, grad) if gradient else phi


def rel(a, b):
    """Relative L2 error of a against the reference b."""
    return float(np.linalg.norm(np.asarray(a, dtype=np.float64) - b) / np.linalg.norm(b))


@pytest.fixture(autouse=True, scope="session")
def _operator_cache(tmp_path_factory):
    """The operator cache is on by default: point it at a temporary folder
    for the whole session (never the home folder of the machine running
    the tests). Tests that need another place set FERROFMM_CACHE
    themselves (monkeypatch)."""
    old = os.environ.get("FERROFMM_CACHE")
    os.environ["FERROFMM_CACHE"] = str(tmp_path_factory.mktemp("operator-cache"))
    yield
    if old is None:
        os.environ.pop("FERROFMM_CACHE", None)
    else:
        os.environ["FERROFMM_CACHE"] = old


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def cube(rng, n):
    return rng.random((n, 3))


def sphere(rng, n):
    p = rng.normal(size=(n, 3))
    return p / np.linalg.norm(p, axis=1, keepdims=True)


def two_clusters(rng, n):
    """A thin, clustered set: two small blobs far apart (relative to their size)."""
    a = rng.normal(scale=0.01, size=(n // 2, 3))
    b = rng.normal(scale=0.01, size=(n - n // 2, 3)) + [1.0, 0.0, 0.0]
    return np.concatenate([a, b])


def zero_mean(rng, n):
    return rng.random(n) - 0.5


def positive(rng, n):
    return rng.random(n)
