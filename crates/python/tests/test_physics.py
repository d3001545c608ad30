"""Dipole sources and Hessians against a NumPy direct sum written here from
the formulas (independent of the library), and their bad input.

For K = k(r) with d = x - y, f1 = k'(r)/r, f2 = f1'(r)/r, f3 = f2'(r)/r:
a charge gives u = q k, grad u = -q f1 d, H = q (f2 d d^T + f1 I); a dipole
n gives u = f1 (n . d), grad u = -(f2 (n . d) d + f1 n),
H = f3 (n . d) d d^T + f2 (n d^T + d n^T + (n . d) I).
"""

import numpy as np
import pytest

import ferrofmm

N = 4000
SAMPLE = 200
FOUR_PI = 4.0 * np.pi


def radial(r, k):
    """f0..f3 of exp(-k r) / (4 pi r) (k = 0: Laplace; k = -i kappa: the
    Helmholtz kernel exp(i kappa r) / (4 pi r))."""
    x = k * r
    e = np.exp(-x) / FOUR_PI
    return (
        e / r,
        -e * (1 + x) / r**3,
        e * (3 + 3 * x + x**2) / r**5,
        -e * (15 + 15 * x + 6 * x**2 + x**3) / r**7,
    )


def direct(sources, targets, charges=None, dipoles=None, k=0.0):
    """Potential (m,), gradient (m, 3), Hessian (m, 6: xx yy zz xy xz yz)."""
    d = sources[None, :, :] - targets[:, None, :]  # (m, n, 3)
    r = np.linalg.norm(d, axis=2)
    same = r == 0  # coincident pairs add nothing
    f0, f1, f2, f3 = (np.where(same, 0.0, f) for f in radial(np.where(same, 1.0, r), k))
    eye = np.eye(3)
    dd = d[..., :, None] * d[..., None, :]  # (m, n, 3, 3)
    dtype = np.result_type(f0, *(a for a in (charges, dipoles) if a is not None))
    u = np.zeros(len(targets), dtype)
    g = np.zeros((len(targets), 3), dtype)
    h = np.zeros((len(targets), 3, 3), dtype)
    if charges is not None:
        q = charges[None, :]
        u += (q * f0).sum(1)
        g += -((q * f1)[..., None] * d).sum(1)
        h += ((q * f2)[..., None, None] * dd + (q * f1)[..., None, None] * eye).sum(1)
    if dipoles is not None:
        p = (d * dipoles[None]).sum(2)
        nd = dipoles[None, :, :, None] * d[..., None, :]
        u += (f1 * p).sum(1)
        g += -((f2 * p)[..., None] * d + f1[..., None] * dipoles[None]).sum(1)
        h += (
            (f3 * p)[..., None, None] * dd
            + f2[..., None, None] * (nd + np.swapaxes(nd, -1, -2) + p[..., None, None] * eye)
        ).sum(1)
    six = np.stack([h[:, 0, 0], h[:, 1, 1], h[:, 2, 2], h[:, 0, 1], h[:, 0, 2], h[:, 1, 2]], 1)
    return u, g, six


def rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


@pytest.mark.parametrize("kernel", ["laplace", "yukawa"])
@pytest.mark.parametrize("carry", ["dipoles", "both"])
def test_dipoles_and_hessians_meet_eps(rng, kernel, carry):
    x = rng.random((N, 3))
    q = rng.random(N) - 0.5 if carry == "both" else None
    n = rng.random((N, 3)) - 0.5
    k = 3.0 if kernel == "yukawa" else 0.0
    call = ferrofmm.laplace if kernel == "laplace" else ferrofmm.yukawa
    extra = {} if kernel == "laplace" else {"k": k}
    r = call(x, q, dipoles=n, eps=1e-6, hessian=True, **extra)
    assert r.potential.shape == (N,)
    assert r.gradient.shape == (N, 3) and r.hessian.shape == (N, 6)
    assert r.info["measured_error"]["hessian"] is not None
    idx = np.random.default_rng(3).choice(N, SAMPLE, replace=False)
    u, g, h = direct(x, x[idx], q, n, k)
    for got, want in ((r.potential[idx], u), (r.gradient[idx], g), (r.hessian[idx], h)):
        assert rel(got, want) <= 3e-6


@pytest.mark.parametrize("carry", ["charges", "both"])
def test_helmholtz_hessians_meet_eps(rng, carry):
    """Complex charges (and dipoles) with zero mean, k D = 5 on the unit cube."""
    n_pts = 3000
    x = rng.random((n_pts, 3))
    q = rng.random(n_pts) - 0.5 + 1j * (rng.random(n_pts) - 0.5)
    n = rng.random((n_pts, 3)) - 0.5 + 1j * (rng.random((n_pts, 3)) - 0.5)
    n = n if carry == "both" else None
    r = ferrofmm.helmholtz(x, q, dipoles=n, k=5.0, eps=1e-6, hessian=True)
    assert r.potential.shape == (n_pts,) and r.potential.dtype == np.complex128
    assert r.gradient.shape == (n_pts, 3) and r.hessian.shape == (n_pts, 6)
    assert r.hessian.dtype == np.complex128
    assert r.info["measured_error"]["hessian"] is not None
    idx = np.random.default_rng(4).choice(n_pts, SAMPLE, replace=False)
    u, g, h = direct(x, x[idx], q, n, -5.0j)
    for got, want in ((r.potential[idx], u), (r.gradient[idx], g), (r.hessian[idx], h)):
        assert rel(got, want) <= 3e-6


def test_batched_dipoles_and_separate_targets(rng):
    x = rng.random((N, 3))
    t = rng.random((500, 3)) + 0.25
    n = rng.random((2, N, 3)) - 0.5
    q = rng.random((2, N)) - 0.5
    fmm = ferrofmm.Fmm(x, t, order=7, charges=True, dipoles=True, gradient=True)
    r = fmm.evaluate(q, n)
    assert r.potential.shape == (2, 500) and r.gradient.shape == (2, 500, 3)
    assert r.hessian is None
    for v in range(2):
        u, g, _ = direct(x, t, q[v], n[v])
        assert rel(r.potential[v], u) < 1e-5
        assert rel(r.gradient[v], g) < 1e-5
    one = fmm.evaluate(q[1], n[1])
    np.testing.assert_allclose(one.potential, r.potential[1], rtol=0, atol=1e-14)


def test_bad_dipole_input_is_a_value_error(rng):
    x = rng.random((300, 3))
    with pytest.raises(ValueError, match="dipoles"):
        ferrofmm.laplace(x, dipoles=np.ones((299, 3)), order=4)
    with pytest.raises(ValueError, match="dipoles"):
        ferrofmm.laplace(x, dipoles=np.ones(300), order=4)
    with pytest.raises(ValueError, match="charges, dipoles or both"):
        ferrofmm.laplace(x, order=4)
    fmm = ferrofmm.Fmm(x, order=4, dipoles=True, charges=False)
    with pytest.raises(ValueError, match="carry no charges .only dipoles"):
        fmm.evaluate(np.ones(300))
    with pytest.raises(ValueError, match="carry dipoles: give dipoles"):
        fmm.evaluate()
    with pytest.raises(ValueError, match="carry no charges"):
        fmm.evaluate(np.ones(300), np.ones((300, 3)))
    with pytest.raises(ValueError, match="carry nothing"):
        ferrofmm.Fmm(x, order=4, charges=False)
    n = np.ones((300, 3))
    n[5, 1] = np.nan
    with pytest.raises(ValueError):
        fmm.evaluate(dipoles=n)
    fmm2 = ferrofmm.Fmm(x, order=4, dipoles=True)
    with pytest.raises(ValueError, match="same number of vectors"):
        fmm2.evaluate(np.ones((2, 300)), np.ones((3, 300, 3)))
