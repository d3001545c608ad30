"""float32 runs on float64 points far from the origin.

The points used to be rounded to float32 before anything else: a unit cube
shifted by 1e4 lost three digits (error 7e-3 while the verification said
2e-7) and one shifted by 1e8 collapsed to a point (every potential 0). The
module now hands float64 points over as they are and the FMM rounds them
only relative to its tree's origin, so the error against the float64 truth
of the caller's own coordinates is the same wherever the cube lies.
"""

import numpy as np
import pytest

import ferrofmm
from conftest import direct, rel

N = 3000


@pytest.mark.parametrize("shift", [0.0, 1e4, 1e8, -3.5e6])
def test_float32_run_on_shifted_points_matches_the_float64_truth(shift):
    rng = np.random.default_rng(5)
    x = rng.random((N, 3)) + shift
    q = rng.random(N) - 0.5
    r = ferrofmm.laplace(x, q, order=5, dtype="float32", gradient=True)
    assert r.potential.dtype == np.float32
    idx = rng.choice(N, 300, replace=False)
    phi, grad = direct(x, q, x[idx], gradient=True)
    assert rel(r.potential[idx], phi) < 1e-3
    assert rel(r.gradient[idx], grad) < 1e-3


def test_float32_eps_on_shifted_points_is_verified_against_the_truth():
    rng = np.random.default_rng(6)
    x = rng.random((N, 3)) * 2.0 + np.array([1e8, -1e8, 4e6])
    q = rng.random(N) - 0.5
    eps = 1e-4
    r = ferrofmm.laplace(x, q, eps=eps, dtype="float32")
    assert r.info["verified"] is True
    assert r.info["measured_error"]["potential"] <= eps
    idx = rng.choice(N, 300, replace=False)
    # An independent sample of the same truth: within a few times eps.
    assert rel(r.potential[idx], direct(x, q, x[idx])) <= 3 * eps
