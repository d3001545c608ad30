"""Periodic boundaries (``box=``): the Madelung constant of rock salt, a random
neutral cell against the Ewald sum (``ferrofmm.ewald``), wrapping, the cell's
origin, energies, reuse, and every refusal as a ValueError with the library's
message."""

import warnings

import numpy as np
import pytest

import ferrofmm

from conftest import direct, rel

MADELUNG_NACL = 1.747564594633182
N = 1000


def rock_salt():
    """The conventional cell of NaCl, side 1: 8 ions 0.5 apart, Na+ at the origin."""
    ions = np.array(
        [[i, j, k] for i in (0.0, 0.5) for j in (0.0, 0.5) for k in (0.0, 0.5)]
    )
    q = np.where(np.rint(2 * ions.sum(axis=1)) % 2 == 0, 1.0, -1.0)
    return ions, q


@pytest.fixture(scope="module")
def cell():
    """1000 random points in the unit cell, zero-mean charges, and their Ewald sum."""
    rng = np.random.default_rng(2024)
    x = rng.random((N, 3))
    q = rng.standard_normal(N)
    q -= q.mean()
    truth = ferrofmm.ewald(x, q, 1.0, gradient=True, eps=1e-12)
    return x, q, truth


def test_madelung_constant_of_rock_salt():
    ions, q = rock_salt()
    d = 0.5
    expected = -q * MADELUNG_NACL / (4 * np.pi * d)
    # eps=1e-10 is below what float64 can promise (the library refuses it,
    # smallest 1.2e-10), and the order chosen for 2e-10 is not verified on
    # this cell (12 after two raises: 2e-9); order 14 is 1e-10.
    r = ferrofmm.laplace(ions, q, box=1.0, order=14)
    assert np.max(np.abs(r.potential / expected - 1)) < 1e-9
    # With a tolerance: chosen, verified (against an Ewald sum) and met.
    tuned = ferrofmm.laplace(ions, q, box=1.0, eps=1e-8)
    assert tuned.info["verified"] is True
    assert np.max(np.abs(tuned.potential / expected - 1)) < 1e-8
    # E = 1/2 sum q phi = -8 M / (2 * 4 pi d) per cell.
    energy = -len(q) * MADELUNG_NACL / (2 * 4 * np.pi * d)
    assert isinstance(r.energy, float)
    assert abs(r.energy / energy - 1) < 1e-9
    assert r.energy == pytest.approx(0.5 * float(q @ r.potential), rel=1e-14)
    assert r.info["periodic"] == {
        "box": [1.0, 1.0, 1.0],
        "origin": [0.0, 0.0, 0.0],
        "axes": "xyz",
        "surface": "tin-foil",
    }
    # The reference sum agrees.
    e = ferrofmm.ewald(ions, q, 1.0)
    assert np.max(np.abs(e.potential / expected - 1)) < 1e-12
    assert abs(e.energy / energy - 1) < 1e-12
    assert e.info["method"] == "ewald"


def test_tight_tolerances_on_a_tiny_cell_never_panic():
    # Every target is sampled: a verification in the noise band could not
    # grow its sample (the budget overflowed: a panic, RuntimeError).
    ions, q = rock_salt()
    for eps in (1e-9, 2e-10):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ferrofmm.AccuracyWarning)
            r = ferrofmm.laplace(ions, q, box=1.0, eps=eps)
        assert r.info["measured_error"]["sampled_targets"] == len(q)
        assert np.all(np.isfinite(r.potential))
    with pytest.raises(ValueError, match="beyond what f64 can promise"):
        ferrofmm.laplace(ions, q, box=1.0, eps=1e-10)


@pytest.mark.parametrize("eps", [1e-4, 1e-8])
def test_random_neutral_cell_against_ewald(cell, eps):
    x, q, truth = cell
    r = ferrofmm.laplace(x, q, box=1.0, eps=eps, gradient=True)
    assert rel(r.potential, truth.potential) < eps
    assert rel(r.gradient, truth.gradient) < eps
    # The tolerance was verified as in free space (against an Ewald sum).
    assert r.info["verified"] is True
    assert r.info["measured_error"]["potential"] < eps
    assert r.info["measured_error"]["gradient"] < eps
    assert r.info["periodic"]["axes"] == "xyz"
    assert r.energy == pytest.approx(truth.energy, rel=10 * eps)


def test_ewald_at_targets_and_orthorhombic_cells(cell):
    x, q, truth = cell
    # At the sources as separate targets: each pair at distance 0 is left out.
    at = ferrofmm.ewald(x, q, 1.0, targets=x[:50], gradient=True)
    assert rel(at.potential, truth.potential[:50]) < 1e-11
    assert rel(at.gradient, truth.gradient[:50]) < 1e-11
    assert at.energy is None
    # Three sides: equal ones are the cube; other boxes run too (the FMM
    # takes cubes only).
    y, qq = x[:40], q[:40] - q[:40].mean()
    cube = ferrofmm.ewald(y, qq, 1.0, gradient=True)
    same = ferrofmm.ewald(y, qq, (1.0, 1.0, 1.0), gradient=True)
    np.testing.assert_allclose(same.potential, cube.potential, rtol=1e-12, atol=0)
    stretched = ferrofmm.ewald(y, qq, (1.0, 1.5, 2.0), gradient=True)
    assert stretched.info["periodic"]["box"] == [1.0, 1.5, 2.0]
    assert rel(stretched.potential, cube.potential) > 1e-3


def test_points_outside_the_cell_are_wrapped(cell):
    x, q, _ = cell
    rng = np.random.default_rng(7)
    shifted = x + rng.integers(-3, 4, size=x.shape)
    a = ferrofmm.laplace(x, q, box=1.0, order=6, verify=False, gradient=True)
    b = ferrofmm.laplace(shifted, q, box=1.0, order=6, verify=False, gradient=True)
    assert rel(b.potential, a.potential) < 1e-10
    assert rel(b.gradient, a.gradient) < 1e-10
    e = ferrofmm.ewald(shifted, q, 1.0)
    assert rel(e.potential, a.potential) < 1e-4


def test_box_origin(cell):
    x, q, truth = cell
    origin = np.array([-0.5, 0.25, 3.0])
    r = ferrofmm.laplace(x + origin, q, box=1.0, box_origin=origin, eps=1e-6, gradient=True)
    assert rel(r.potential, truth.potential) < 1e-6
    assert rel(r.gradient, truth.gradient) < 1e-6
    assert r.info["periodic"]["origin"] == list(origin)
    e = ferrofmm.ewald(x + origin, q, 1.0, box_origin=origin)
    assert rel(e.potential, truth.potential) < 1e-11
    # The same points with the cell at 0 wrap differently (another cut of
    # the same crystal): the same potentials.
    w = ferrofmm.laplace(x + origin, q, box=1.0, eps=1e-6)
    assert rel(w.potential, truth.potential) < 1e-6


def test_vacuum_adds_the_dipole_term(cell):
    x, q, _ = cell
    tin = ferrofmm.laplace(x, q, box=1.0, order=8, verify=False, gradient=True)
    vac = ferrofmm.laplace(
        x, q, box=1.0, order=8, verify=False, gradient=True, surface="vacuum"
    )
    assert vac.info["periodic"]["surface"] == "vacuum"
    centre = np.full(3, 0.5)
    dipole = q @ (x - centre)
    np.testing.assert_allclose(
        vac.gradient - tin.gradient,
        np.broadcast_to(dipole / 3.0, tin.gradient.shape),
        atol=1e-8 * np.abs(tin.gradient).max(),
    )
    np.testing.assert_allclose(
        vac.potential - tin.potential,
        (x - centre) @ dipole / 3.0,
        atol=1e-8 * np.abs(tin.potential).max(),
    )


def test_fmm_reused_with_new_neutral_charges(cell):
    x, q, truth = cell
    fmm = ferrofmm.Fmm(x, box=1.0, eps=1e-6, gradient=True)
    first = fmm.evaluate(q)
    assert rel(first.potential, truth.potential) < 1e-6
    rng = np.random.default_rng(3)
    q2 = rng.standard_normal(N)
    q2 -= q2.mean()
    second = fmm.evaluate(q2)
    ref = ferrofmm.ewald(x, q2, 1.0, gradient=True)
    assert rel(second.potential, ref.potential) < 1e-6
    assert rel(second.gradient, ref.gradient) < 1e-6
    assert second.info["periodic"]["box"] == [1.0, 1.0, 1.0]
    both = fmm.evaluate(np.stack([q, q2]))
    assert both.energy.shape == (2,)
    np.testing.assert_allclose(both.energy, [first.energy, second.energy], rtol=1e-12)
    # A charged vector is refused at evaluation; the Fmm still works.
    with pytest.raises(ValueError, match="not neutral"):
        fmm.evaluate(q2 + 1.0)
    again = fmm.evaluate(q2)
    np.testing.assert_array_equal(again.potential, second.potential)


def test_periodic_targets(cell):
    x, q, truth = cell
    rng = np.random.default_rng(11)
    y = rng.random((200, 3)) * 3 - 1
    r = ferrofmm.laplace(x, q, targets=y, box=1.0, eps=1e-6, gradient=True)
    ref = ferrofmm.ewald(x, q, 1.0, targets=y, gradient=True)
    assert rel(r.potential, ref.potential) < 1e-6
    assert rel(r.gradient, ref.gradient) < 1e-6
    assert r.energy is None


def test_energy_in_free_space():
    rng = np.random.default_rng(5)
    x = rng.random((300, 3))
    q = rng.standard_normal(300)
    r = ferrofmm.laplace(x, q, eps=1e-8)
    exact = 0.5 * float(q @ direct(x, q, x))
    assert r.energy == pytest.approx(exact, rel=1e-7)
    assert r.info["periodic"] is None
    y = ferrofmm.yukawa(x, q, k=2.0, eps=1e-8)
    assert y.energy == pytest.approx(0.5 * float(q @ direct(x, q, x, k=2.0)), rel=1e-7)
    assert ferrofmm.laplace(x, q, targets=x[:10], eps=1e-6).energy is None
    assert ferrofmm.laplace(x, dipoles=np.ones((300, 3)), eps=1e-6).energy is None
    assert ferrofmm.helmholtz(x, q + 0j, k=1.0, eps=1e-6).energy is None
    assert ferrofmm.stokes(x, np.ones((300, 3)), eps=1e-6).energy is None


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"box": 0.0}, "finite and positive"),
        ({"box": -1.0}, "finite and positive"),
        ({"box": float("nan")}, "finite and positive"),
        ({"box": (1.0, 2.0, 3.0)}, "only cubic cells"),
        ({"box": (1.0, 1.0)}, "a side L or three"),
        ({"box": 1.0, "periodic": "xy", "surface": "vacuum"}, "converges without one"),
        ({"box": 1.0, "periodic": "xz"}, "periodic axes"),
        ({"box": 1.0, "surface": "metal"}, "surface term"),
        ({"box": 1.0, "box_origin": (0.0, 0.0)}, "three numbers"),
        ({"box": 1.0, "box_origin": (0.0, np.inf, 0.0)}, "origin"),
        ({"periodic": "xyz"}, "needs box="),
        ({"box_origin": (0.0, 0.0, 0.0)}, "needs box="),
        ({"surface": "vacuum"}, "needs box="),
        ({"box": 1.0, "hessian": True}, "not Hessians"),
    ],
)
def test_bad_cells_are_value_errors(kwargs, message):
    x, q = rock_salt()
    with pytest.raises(ValueError, match=message):
        ferrofmm.laplace(x, q, eps=1e-6, **kwargs)
    if "hessian" not in kwargs:
        with pytest.raises(ValueError, match=message):
            ferrofmm.Fmm(x, eps=1e-6, **kwargs)


def test_unsupported_periodic_problems_are_value_errors():
    x, q = rock_salt()
    with pytest.raises(ValueError, match="not neutral"):
        ferrofmm.laplace(x, q + 0.1, box=1.0, eps=1e-6)
    with pytest.raises(ValueError, match="not dipoles"):
        ferrofmm.laplace(x, dipoles=np.ones((8, 3)), box=1.0, eps=1e-6)
    with pytest.raises(ValueError, match="charges only"):
        ferrofmm.laplace(x, q, dipoles=np.ones((8, 3)), box=1.0, eps=1e-6)
    with pytest.raises(ValueError, match=r"helmholtz \(helmholtz3d\) has no periodic lattice sum"):
        ferrofmm.helmholtz(x, q + 0j, k=1.0, box=1.0, eps=1e-6)
    with pytest.raises(ValueError, match="Hasimoto"):
        ferrofmm.stokes(x, np.ones((8, 3)), box=1.0, eps=1e-6, surface="vacuum")
    with pytest.raises(ValueError, match="vacuum surface term"):
        ferrofmm.yukawa(x, q, k=1.0, box=1.0, eps=1e-6, surface="vacuum")
    with pytest.raises(ValueError, match="vacuum surface term"):
        ferrofmm.Fmm(x, kernel="yukawa", k=1.0, box=1.0, eps=1e-6, surface="vacuum")


@pytest.mark.parametrize("k", [0.5, 6.0])
def test_periodic_yukawa_against_the_screened_ewald_sum(k):
    # Positive charges: a Yukawa cell need not be neutral.
    rng = np.random.default_rng(7)
    x = rng.random((N, 3))
    q = rng.random(N)
    truth = ferrofmm.ewald(x, q, 1.0, k=k, gradient=True, eps=1e-13)
    assert truth.info["kernel"] == "yukawa"
    for eps in (1e-4, 1e-8):
        r = ferrofmm.yukawa(x, q, k=k, box=1.0, eps=eps, gradient=True)
        assert rel(r.potential, truth.potential) < eps
        assert rel(r.gradient, truth.gradient) < eps
        assert r.info["verified"] is True
        assert r.energy == pytest.approx(truth.energy, rel=10 * eps)
    # The same through Fmm, reused with other charges.
    fmm = ferrofmm.Fmm(x, kernel="yukawa", k=k, box=1.0, eps=1e-6)
    q2 = rng.standard_normal(N)
    r2 = fmm.evaluate(q2)
    t2 = ferrofmm.ewald(x, q2, 1.0, k=k, eps=1e-13)
    assert rel(r2.potential, t2.potential) < 1e-6


def test_ewald_bad_input():
    x, q = rock_salt()
    with pytest.raises(ValueError, match="finite and > 0"):
        ferrofmm.ewald(x, q, 0.0)
    with pytest.raises(ValueError, match="a side L or three"):
        ferrofmm.ewald(x, q, (1.0, 1.0))
    with pytest.raises(ValueError, match="three numbers"):
        ferrofmm.ewald(x, q, 1.0, box_origin=(0.0,))
    with pytest.raises(ValueError, match="tolerance"):
        ferrofmm.ewald(x, q, 1.0, eps=2.0)
    with pytest.raises(ValueError, match="8 sources"):
        ferrofmm.ewald(x, q[:5], 1.0)
    with pytest.raises(ValueError, match="shape"):
        ferrofmm.ewald(x[:, :2], q, 1.0)
    with pytest.raises(ValueError, match="NaN|finite"):
        ferrofmm.ewald(np.where(x == 0.5, np.nan, x), q, 1.0)
    with pytest.raises(ValueError, match="one charge vector"):
        ferrofmm.ewald(x, np.stack([q, q]), 1.0)
    for k in (-1.0, np.inf, np.nan):
        with pytest.raises(ValueError, match="k must be"):
            ferrofmm.ewald(x, q, 1.0, k=k)
    # A charged cell gets a neutralising background (Ewald's convention).
    r = ferrofmm.ewald(x, q + 0.25, 1.0)
    assert r.info["total_charge"] == pytest.approx(2.0)


def test_periodic_stokes_against_hasimotos_sum():
    # Equal forces (a sedimenting suspension: the net force is balanced by
    # the pressure) and zero-sum ones.
    rng = np.random.default_rng(9)
    x = rng.random((N, 3))
    # (Each force set at one tolerance: the Rust suite runs every
    # tolerance; this checks the Python path.)
    for f, eps in ((np.tile([0.0, 0.0, -1.0], (N, 1)), 1e-4), (rng.standard_normal((N, 3)), 1e-7)):
        truth = ferrofmm.stokes_ewald(x, f, 1.0, gradient=True, eps=1e-13)
        assert truth.info["kernel"] == "stokes"
        r = ferrofmm.stokes(x, f, box=1.0, eps=eps, gradient=True)
        assert r.potential.shape == (N, 3) and r.gradient.shape == (N, 3, 3)
        assert rel(r.potential, truth.potential) < eps
        assert rel(r.gradient, truth.gradient) < eps
        assert r.info["verified"] is True
    # The velocity gradient is the Jacobian, traceless (incompressible).
    assert np.abs(np.trace(truth.gradient, axis1=1, axis2=2)).max() < 1e-10
    # Through Fmm, reused with other forces, at separate targets.
    t = rng.random((300, 3)) * 2.0 - 0.5
    fmm = ferrofmm.Fmm(x, kernel="stokes", targets=t, box=1.0, eps=1e-6)
    f2 = rng.random((N, 3))
    r2 = fmm.evaluate(f2)
    t2 = ferrofmm.stokes_ewald(x, f2, 1.0, targets=t, eps=1e-13)
    assert rel(r2.potential, t2.potential) < 1e-6


def test_stokes_ewald_bad_input():
    x = np.random.default_rng(1).random((8, 3))
    f = np.ones((8, 3))
    with pytest.raises(ValueError, match="shape \\(8, 3\\)"):
        ferrofmm.stokes_ewald(x, f[:, :2], 1.0)
    with pytest.raises(ValueError, match="finite"):
        ferrofmm.stokes_ewald(x, np.where(f == 1.0, np.nan, f), 1.0)
    with pytest.raises(ValueError, match="finite and > 0"):
        ferrofmm.stokes_ewald(x, f, -1.0)
    with pytest.raises(ValueError, match="tolerance"):
        ferrofmm.stokes_ewald(x, f, 1.0, eps=0.0)


@pytest.mark.parametrize("axes", ["xy", "x"])
def test_slabs_and_rods_against_their_sums(axes):
    """A slab (x and y repeat) and a rod (x repeats): Laplace with zero-mean
    charges and Yukawa with positive ones against ``ferrofmm.ewald(...,
    periodic=)``; a tolerance is met and verified."""
    rng = np.random.default_rng(7)
    x = rng.random((800, 3))
    q = rng.standard_normal(800)
    q -= q.mean()
    truth = ferrofmm.ewald(x, q, 1.0, gradient=True, periodic=axes)
    assert truth.info["periodic"]["axes"] == axes
    r = ferrofmm.laplace(x, q, box=1.0, periodic=axes, eps=1e-7, gradient=True)
    assert r.info["verified"] is True
    assert r.info["periodic"]["axes"] == axes
    assert rel(r.potential, truth.potential) < 1e-7
    assert rel(r.gradient, truth.gradient) < 1e-7
    assert r.energy == pytest.approx(0.5 * float(q @ truth.potential), rel=1e-6)
    pos = q - q.min() + 0.1
    ytruth = ferrofmm.ewald(x, pos, 1.0, gradient=True, periodic=axes, k=2.0)
    y = ferrofmm.yukawa(x, pos, k=2.0, box=1.0, periodic=axes, eps=1e-6, gradient=True)
    assert rel(y.potential, ytruth.potential) < 1e-6
    assert rel(y.gradient, ytruth.gradient) < 1e-6


def test_slab_points_outside_the_cell_along_the_open_axis_are_value_errors():
    x = np.array([[0.1, 0.2, 0.3], [0.6, 0.7, 1.4]])
    with pytest.raises(ValueError, match="open axis"):
        ferrofmm.laplace(x, [1.0, -1.0], box=1.0, periodic="xy", eps=1e-6)
    with pytest.raises(ValueError, match="runs fully periodic"):
        ferrofmm.stokes(x, np.ones((2, 3)), box=1.0, periodic="x", eps=1e-6)
    with pytest.raises(ValueError, match="periodic axes"):
        ferrofmm.ewald(x, [1.0, -1.0], 1.0, periodic="yz")


def test_damped_waves_in_a_periodic_cell():
    """Damped Helmholtz waves (``k`` with a positive imaginary part) are summed over
    their images (their lattice sum converges): against a NumPy image sum over the
    cells ``|n|_inf <= 3`` (the waves fall as ``exp(-8 r)``: ``1e-9`` at the first
    cell left out)."""
    rng = np.random.default_rng(4)
    x = rng.random((60, 3))
    q = rng.random(60) - 0.5 + 1j * (rng.random(60) - 0.5)
    k = 6.0 + 8.0j
    r = ferrofmm.helmholtz(x, q, k=k, box=1.0, order=6, gradient=False)
    shifts = np.array([[i, j, l] for i in range(-3, 4) for j in range(-3, 4) for l in range(-3, 4)])
    d = x[:, None, None, :] - x[None, None, :, :] - shifts[None, :, None, :]
    dist = np.linalg.norm(d, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.where(dist > 0, np.exp(1j * k * dist) / (4 * np.pi * dist), 0.0)
    truth = (g * q[None, None, :]).sum(axis=(1, 2))
    err = np.linalg.norm(r.potential - truth) / np.linalg.norm(truth)
    assert err < 1e-4, err
