"""The complex Helmholtz kernel and the Stokeslet against NumPy direct sums
written here from the formulas, their array shapes, and their bad input.

Helmholtz, d = y - x, r = |d|: G = exp(ikr) / (4 pi r); a charge q gives
u = q G, grad u = q G (ikr - 1) d / r^2; a dipole n gives
u = n . grad_x G = -G (ikr - 1) (n . d) / r^2.
Stokes: u = sum (f / r + d (d . f) / r^3) / (8 pi).
"""

import numpy as np
import pytest

import ferrofmm

N = 3000
SAMPLE = 150


def rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def helmholtz_direct(x, y, k, q=None, n=None):
    d = y[:, None, :] - x[None, :, :]  # (m, n, 3), target minus source
    r = np.linalg.norm(d, axis=2)
    same = r == 0
    r = np.where(same, 1.0, r)
    g = np.where(same, 0.0, np.exp(1j * k * r) / (4 * np.pi * r))
    f1 = g * (1j * k * r - 1) / r**2
    u = np.zeros(len(y), complex)
    grad = np.zeros((len(y), 3), complex)
    if q is not None:
        u += (g * q[None]).sum(1)
        grad += ((f1 * q[None])[..., None] * d).sum(1)
    if n is not None:
        nd = (n[None] * d).sum(2)
        u -= (f1 * nd).sum(1)  # dipole gradients: tested in Rust
    return u, grad


def stokes_direct(x, y, f):
    d = y[:, None, :] - x[None, :, :]
    r = np.linalg.norm(d, axis=2)
    same = r == 0
    r = np.where(same, 1.0, r)
    inv = np.where(same, 0.0, 1.0 / r)
    df = (d * f[None]).sum(2)
    u = (f[None] * inv[..., None] + d * (df * inv**3)[..., None]).sum(1) / (8 * np.pi)
    return u


def test_helmholtz_charges_and_dipoles_meet_eps(rng):
    x = rng.random((N, 3))
    q = (rng.random(N) - 0.5) + 1j * (rng.random(N) - 0.5)
    n = (rng.random((N, 3)) - 0.5) + 1j * (rng.random((N, 3)) - 0.5)
    k = 12.0
    r = ferrofmm.helmholtz(x, q, k=k, dipoles=n, eps=1e-6, gradient=True)
    assert r.potential.shape == (N,) and r.potential.dtype == np.complex128
    assert r.gradient.shape == (N, 3) and r.gradient.dtype == np.complex128
    assert r.info["kernel"] == "helmholtz3d"
    assert r.info["scheme"] == "fft"  # "auto" for a kernel with components
    idx = np.random.default_rng(5).choice(N, SAMPLE, replace=False)
    u, _ = helmholtz_direct(x, x[idx], k, q, n)
    assert rel(r.potential[idx], u) < 1e-5
    # Charges alone, through SVD: the gradient too.
    r = ferrofmm.helmholtz(x, q, k=k, eps=1e-6, gradient=True, scheme="svd")
    assert r.info["scheme"] == "svd"
    u, g = helmholtz_direct(x, x[idx], k, q)
    assert rel(r.potential[idx], u) < 1e-5
    assert rel(r.gradient[idx], g) < 1e-5


def test_helmholtz_batches_real_input_and_targets(rng):
    x = rng.random((N, 3))
    t = rng.random((500, 3)) + 0.2
    q = rng.random((2, N)) - 0.5  # real charges, taken as complex
    fmm = ferrofmm.Fmm(x, t, "helmholtz", k=5.0, order=7)
    r = fmm.evaluate(q)
    assert r.potential.shape == (2, 500)
    for j in range(2):
        u, _ = helmholtz_direct(x, t, 5.0, q[j])
        assert rel(r.potential[j], u) < 1e-5


def test_damped_helmholtz_takes_a_complex_wavenumber(rng):
    """k = a + bj: exp(-b r) exp(i a r) / (4 pi r), the direct sum's formulas
    with the complex k as they are; the report names the complex wavenumber."""
    x = rng.random((N, 3))
    q = (rng.random(N) - 0.5) + 1j * (rng.random(N) - 0.5)
    n = (rng.random((N, 3)) - 0.5) + 1j * (rng.random((N, 3)) - 0.5)
    idx = np.random.default_rng(7).choice(N, SAMPLE, replace=False)
    for k in (10.0 + 2.0j, np.complex128(3.0 + 12.0j)):
        r = ferrofmm.helmholtz(x, q, k=k, dipoles=n, eps=1e-6)
        u, _ = helmholtz_direct(x, x[idx], k, q, n)
        assert rel(r.potential[idx], u) < 1e-5, k
        assert r.info["verified"] is True and r.info["measured_error"]["potential"] <= 1e-6
    r = ferrofmm.helmholtz(x, q, k=10.0 + 2.0j, eps=1e-6, gradient=True)
    u, g = helmholtz_direct(x, x[idx], 10.0 + 2.0j, q)
    assert rel(r.potential[idx], u) < 1e-5 and rel(r.gradient[idx], g) < 1e-5
    # A complex k with no imaginary part is the real one.
    a = ferrofmm.helmholtz(x, q, k=5.0 + 0j, order=5).potential
    b = ferrofmm.helmholtz(x, q, k=5.0, order=5).potential
    assert np.array_equal(a, b)
    with pytest.raises(ValueError, match="k"):
        ferrofmm.helmholtz(x, q, k=5.0 - 1.0j, order=4)
    with pytest.raises(ValueError, match="real"):
        ferrofmm.yukawa(x, q.real, k=1.0 + 1.0j, order=4)
    with pytest.raises(TypeError):
        ferrofmm.helmholtz(x, q, k="5+1j", order=4)
    # The registry says which parameters may be complex.
    assert ferrofmm.KERNELS["helmholtz"]["parameter_complex"] is True
    assert ferrofmm.KERNELS["yukawa"]["parameter_complex"] is False
    assert ferrofmm.KERNELS["laplace"]["parameter_complex"] is None


def test_stokes_velocity_and_gradient(rng):
    x = rng.random((N, 3))
    f = rng.random((N, 3)) - 0.5
    r = ferrofmm.stokes(x, f, eps=1e-6, gradient=True)
    assert r.potential.shape == (N, 3) and r.gradient.shape == (N, 3, 3)
    idx = np.random.default_rng(6).choice(N, SAMPLE, replace=False)
    assert rel(r.potential[idx], stokes_direct(x, x[idx], f)) < 1e-5
    # The gradient [a, c] = d u_a / d x_c against central differences of
    # the direct velocity; its trace (the divergence) vanishes.
    h = 1e-5
    t = x[idx[:20]]
    for c in range(3):
        e = np.zeros(3)
        e[c] = h
        fd = (stokes_direct(x, t + e, f) - stokes_direct(x, t - e, f)) / (2 * h)
        assert rel(r.gradient[idx[:20], :, c], fd) < 1e-4
    div = np.trace(r.gradient, axis1=1, axis2=2)
    assert np.abs(div).max() < 1e-3 * np.abs(r.gradient).max()


def test_bad_input_is_a_value_error(rng):
    x = rng.random((200, 3))
    with pytest.raises(ValueError, match="needs k"):
        ferrofmm.Fmm(x, kernel="helmholtz", order=4)
    with pytest.raises(ValueError, match="low-frequency limit"):
        ferrofmm.helmholtz(x, np.ones(200), k=1e4, order=4)
    with pytest.raises(ValueError, match="not stokes"):
        ferrofmm.Fmm(x, kernel="stokes", k=1.0, order=4)
    # Stokes dipoles are force dipoles, (n, 3, 3) (test_stokes_layers.py).
    with pytest.raises(ValueError, match=r"\(n, 3, 3\)"):
        ferrofmm.Fmm(x, kernel="stokes", order=4, charges=False, dipoles=True).evaluate(
            dipoles=np.ones((200, 3))
        )
    with pytest.raises(ValueError):
        ferrofmm.Fmm(x, kernel="stokes", order=4, hessian=True)
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        ferrofmm.stokes(x, np.ones(200), order=4)
    with pytest.raises(ValueError, match="NaN"):
        ferrofmm.helmholtz(x, np.full(200, np.nan + 0j), k=1.0, order=4)
    with pytest.raises(TypeError):
        ferrofmm.helmholtz(x, np.array(["a"] * 200), k=1.0, order=4)


def test_values_at_sources_and_targets_in_one_run(rng):
    x = rng.random((N, 3))
    t = rng.random((400, 3)) + 0.5
    f = rng.random((N, 3)) - 0.5
    r = ferrofmm.stokes(x, f, targets=t, order=7, at_sources=True)
    assert r.potential.shape == (400, 3)
    assert r.at_sources.potential.shape == (N, 3)
    assert rel(r.potential, stokes_direct(x, t, f)) < 1e-5
    idx = np.random.default_rng(8).choice(N, SAMPLE, replace=False)
    assert rel(r.at_sources.potential[idx], stokes_direct(x, x[idx], f)) < 1e-5
    q = rng.random(N) - 0.5
    fmm = ferrofmm.Fmm(x, t, order=7, gradient=True, at_sources=True)
    assert fmm.n_targets == 400
    r = fmm.evaluate(np.stack([q, -q]))
    assert r.potential.shape == (2, 400) and r.gradient.shape == (2, 400, 3)
    assert r.at_sources.gradient.shape == (2, N, 3)
    assert np.allclose(r.at_sources.potential[0], -r.at_sources.potential[1])
    assert ferrofmm.laplace(x, q, targets=t, order=5).at_sources is None
