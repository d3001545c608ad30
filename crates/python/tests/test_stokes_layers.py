"""Stokes stresslets, force dipoles and the pressure (issue 35) through the Python module:
against direct sums of FMM3D's ``stfmm3d`` formulas written out here, the stresslet's
identity on a sphere, batches and ``at_sources``, and the refusals."""

import numpy as np
import pytest

import ferrofmm


def direct(x, f, m, n, y):
    """Velocity (m, 3), velocity gradient (m, 3, 3) as [a, c] = d u_a / d y_c, pressure (m,)
    and pressure gradient (m, 3) at ``y`` of forces ``f`` and stresslets ``(m, n)`` at ``x``
    (FMM3D's formulas at viscosity 1; coincident pairs skipped)."""
    d = y[:, None, :] - x[None, :, :]
    r2 = np.einsum("ijk,ijk->ij", d, d)
    with np.errstate(divide="ignore"):
        r = np.where(r2 > 0, np.sqrt(r2), np.inf)
    r3, r5, r7 = r**3, r**5, r**7
    eye = np.eye(3)
    u = np.zeros((len(y), 3))
    g = np.zeros((len(y), 3, 3))
    p = np.zeros(len(y))
    gp = np.zeros((len(y), 3))
    if f is not None:
        df = np.einsum("ijk,jk->ij", d, f)
        u += (np.einsum("jk,ij->ik", f, 1 / r) + np.einsum("ijk,ij->ik", d, df / r3)) / (8 * np.pi)
        g += (
            -np.einsum("ja,ijc,ij->iac", f, d, 1 / r3)
            + np.einsum("ac,ij->iac", eye, df / r3)
            + np.einsum("ija,jc,ij->iac", d, f, 1 / r3)
            - 3 * np.einsum("ija,ijc,ij->iac", d, d, df / r5)
        ) / (8 * np.pi)
        p += (df / r3).sum(1) / (4 * np.pi)
        gp += (np.einsum("jc,ij->ic", f, 1 / r3) - 3 * np.einsum("ijc,ij->ic", d, df / r5)) / (
            4 * np.pi
        )
    if m is not None:
        dm = np.einsum("ijk,jk->ij", d, m)
        dn = np.einsum("ijk,jk->ij", d, n)
        mn = np.einsum("jk,jk->j", m, n)
        u += 3 * np.einsum("ija,ij->ia", d, dm * dn / r5) / (4 * np.pi)
        g += (
            3
            * (
                np.einsum("ac,ij->iac", eye, dm * dn / r5)
                + np.einsum("ija,jc,ij->iac", d, m, dn / r5)
                + np.einsum("ija,jc,ij->iac", d, n, dm / r5)
                - 5 * np.einsum("ija,ijc,ij->iac", d, d, dm * dn / r7)
            )
            / (4 * np.pi)
        )
        p += (6 * dm * dn / r5 - 2 * mn[None, :] / r3).sum(1) / (4 * np.pi)
        gp += (
            6 * np.einsum("jc,ij->ic", m, dn / r5)
            + 6 * np.einsum("jc,ij->ic", n, dm / r5)
            - 30 * np.einsum("ijc,ij->ic", d, dm * dn / r7)
            + 6 * np.einsum("ijc,ij->ic", d, mn[None, :] / r5)
        ) / (4 * np.pi)
    return u, g, p, gp


def rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


@pytest.mark.parametrize("positive", [False, True])
def test_forces_and_stresslets_with_the_pressure_meet_eps(positive):
    rng = np.random.default_rng(3)
    n = 3000 if positive else 12000
    x = rng.random((n, 3))
    if positive:
        x = 0.5 + 0.15 * rng.standard_normal((n, 3))  # clustered
    f = rng.random((n, 3)) - (0.0 if positive else 0.5)
    m = rng.random((n, 3)) - (0.0 if positive else 0.5)
    nu = rng.standard_normal((n, 3))
    eps = 1e-6
    # On the clustered set the chooser takes a direct sum: a given order
    # and leaf size make it a tree.
    settings = dict(order=9, leaf_size=64) if positive else dict(eps=eps)
    r = ferrofmm.stokes(x, f, strslet=m, strsvec=nu, pressure=True, gradient=True, **settings)
    assert r.info["method"] == "fmm" and r.info["verified"] is not False, r.info
    sample = np.arange(0, n, n // 80)
    u, g, p, gp = direct(x, f, m, nu, x[sample])
    errors = {
        "velocity": rel(r.potential[sample], u),
        "velocity gradient": rel(r.gradient[sample], g),
        "pressure": rel(r.pressure[sample], p),
        "pressure gradient": rel(r.pressure_gradient[sample], gp),
    }
    for what, e in errors.items():
        assert 0 < e <= eps, (what, errors)
    # The stresslets alone, potentials only: no gradient arrays.
    r = ferrofmm.stokes(x, strslet=m, strsvec=nu, pressure=True, **settings)
    assert r.gradient is None and r.pressure_gradient is None
    u, _, p, _ = direct(x, None, m, nu, x[sample])
    assert rel(r.potential[sample], u) <= eps
    assert rel(r.pressure[sample], p) <= eps


def test_the_stresslet_sphere_identity():
    """Constant strength on the unit sphere, outward orientations: u = -m inside, 0 outside."""
    c, w = np.polynomial.legendre.leggauss(40)
    phi = 2 * np.pi * np.arange(80) / 80
    cc, pp = np.meshgrid(c, phi, indexing="ij")
    s = np.sqrt(1 - cc**2)
    y = np.stack([s * np.cos(pp), s * np.sin(pp), cc], -1).reshape(-1, 3)
    area = np.outer(w, np.full(80, 2 * np.pi / 80)).reshape(-1)
    mu = np.array([0.3, -0.7, 0.5])
    t = np.array([[0.1, 0.2, -0.3], [0.0, 0.0, 0.0], [1.6, 0.3, 0.2], [0.2, -2.0, 0.5]])
    r = ferrofmm.stokes(y, strslet=area[:, None] * mu, strsvec=y, targets=t, eps=1e-7)
    np.testing.assert_allclose(r.potential[:2], -np.tile(mu, (2, 1)), atol=1e-7)
    np.testing.assert_allclose(r.potential[2:], 0.0, atol=1e-7)


def test_force_dipoles_are_differences_of_forces():
    """A force dipole D[k, c] (dipoles=True with the stokes kernel) is the limit of forces
    D[k, :] / h at x + h e_k and -D[k, :] / h at x."""
    rng = np.random.default_rng(5)
    n = 300
    x = rng.random((n, 3))
    dip = rng.standard_normal((n, 3, 3))
    t = rng.random((50, 3)) + np.array([2.0, 0.0, 0.0])
    fmm = ferrofmm.Fmm(x, t, "stokes", charges=False, dipoles=True, order=10, gradient=True)
    got = fmm.evaluate(dipoles=dip)
    h = 1e-5
    want = np.zeros((50, 3))
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        up, _, _, _ = direct(x + e, dip[:, k, :], None, None, t)
        um, _, _, _ = direct(x - e, dip[:, k, :], None, None, t)
        want += (up - um) / (2 * h)
    assert rel(got.potential, want) < 1e-7
    assert got.gradient.shape == (50, 3, 3)


def test_batches_and_at_sources_split_the_pressure():
    rng = np.random.default_rng(7)
    n = 800
    x = rng.random((n, 3))
    t = rng.random((40, 3))
    f = rng.random((2, n, 3)) - 0.5
    fmm = ferrofmm.Fmm(x, t, "stokes", pressure=True, gradient=True, eps=1e-6, at_sources=True)
    r = fmm.evaluate(f)
    assert r.potential.shape == (2, 40, 3) and r.pressure.shape == (2, 40)
    assert r.pressure_gradient.shape == (2, 40, 3)
    assert r.at_sources.pressure.shape == (2, n)
    for v in range(2):
        _, _, p, gp = direct(x, f[v], None, None, t)
        assert rel(r.pressure[v], p) <= 1e-6
        assert rel(r.pressure_gradient[v], gp) <= 1e-6
        _, _, p, _ = direct(x, f[v], None, None, x[:50])
        assert rel(r.at_sources.pressure[v][:50], p) <= 1e-6
    assert "pressure=(2, 40)" in repr(r)


def test_what_the_layers_refuse():
    x = np.random.default_rng(1).random((100, 3))
    v = np.ones((100, 3))
    with pytest.raises(ValueError, match="strength strslet and orientation strsvec"):
        ferrofmm.stokes(x, strslet=v)
    with pytest.raises(ValueError, match="give the forces"):
        ferrofmm.stokes(x)
    with pytest.raises(ValueError, match="belong to the stokes kernel"):
        ferrofmm.Fmm(x, kernel="laplace", pressure=True)
    with pytest.raises(ValueError, match="free space only"):
        ferrofmm.stokes(x, v, pressure=True, box=2.0)
    with pytest.raises(ValueError, match="do not combine"):
        ferrofmm.Fmm(x, kernel="stokes", dipoles=True, pressure=True)
    with pytest.raises(ValueError, match=r"strslet has shape \(100, 2\)|strslet must have shape"):
        ferrofmm.stokes(x, strslet=np.ones((100, 2)), strsvec=v)
    fmm = ferrofmm.Fmm(x, kernel="stokes", stresslets=True, charges=False, order=4)
    with pytest.raises(ValueError, match="carry strslet: give strslet"):
        fmm.evaluate(strsvec=v)
    with pytest.raises(ValueError, match="carry no charges"):
        fmm.evaluate(v, strslet=v, strsvec=v)
    with pytest.raises(ValueError, match=r"must have shape \(n, 3, 3\)"):
        ferrofmm.Fmm(x, kernel="stokes", dipoles=True, charges=False, order=4).evaluate(
            dipoles=v
        )
