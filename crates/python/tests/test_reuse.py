"""One Fmm, many charge vectors (the iterative-solver case)."""

import numpy as np

import ferrofmm
from conftest import cube, direct, rel, zero_mean


def test_new_charges_without_rebuilding(rng):
    n = 5000
    x = cube(rng, n)
    fmm = ferrofmm.Fmm(x, eps=1e-6, gradient=True)
    setup = fmm.timings()["setup"]["total"]
    q1, q2 = zero_mean(rng, n), zero_mean(rng, n)
    r1 = fmm.evaluate(q1)
    r2 = fmm.evaluate(q2)
    # Linearity: the FMM is a fixed linear map once built.
    r12 = fmm.evaluate(2.0 * q1 - q2)
    np.testing.assert_allclose(
        r12.potential, 2.0 * r1.potential - r2.potential, rtol=0, atol=1e-12 * np.abs(r12.potential).max()
    )
    idx = np.arange(0, n, 17)
    assert rel(r2.potential[idx], direct(x, q2, x[idx])) <= 3e-6
    # The setup happened once.
    assert fmm.timings()["setup"]["total"] == setup
    # The first evaluation was verified, and later ones report it.
    assert r1.info["verified"] is True
    assert r2.info["measured_error"] == r1.info["measured_error"]
    assert fmm.n_sources == n and fmm.n_targets == n


def test_summary_and_timings(rng):
    x = cube(rng, 4000)
    fmm = ferrofmm.Fmm(x, order=5, leaf_size=50, scheme="dense")
    s = fmm.summary()
    assert s["n_sources"] == 4000 and s["order"] == 5 and s["leaf_size"] == 50
    assert s["n_leaves"] > 1 and s["depth"] >= 2
    assert "evaluate" not in fmm.timings()
    fmm.evaluate(zero_mean(rng, 4000))
    t = fmm.timings()
    assert set(t) == {"setup", "evaluate"}
    assert t["evaluate"]["p2p"] > 0


def test_float32_object_takes_float64_charges(rng):
    x = cube(rng, 3000).astype(np.float32)
    fmm = ferrofmm.Fmm(x, order=4)
    assert fmm.dtype == np.float32
    out = fmm.evaluate(zero_mean(rng, 3000))  # float64 charges are cast
    assert out.potential.dtype == np.float32
