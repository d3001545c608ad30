"""ferrofmm.distributed under ``mpirun -n 1..4`` (test.sh runs them; plain pytest runs them
on one rank).

Every assertion is made on data gathered to every rank, so all ranks reach the same verdict
and none is left waiting in a collective; ``pytest.raises`` checks that a failure on one rank
is the same exception on all of them.
"""

import numpy as np
import pytest

# A module built without MPI raises ImportError (with how to rebuild), which
# pytest.importorskip skips only when it is a ModuleNotFoundError (pytest 9).
try:
    import ferrofmm.distributed as fd
    from mpi4py import MPI
except ImportError as e:
    pytest.skip(f"ferrofmm built without MPI, or no mpi4py: {e}", allow_module_level=True)
import ferrofmm  # noqa: E402


COMM = MPI.COMM_WORLD
RANK, SIZE = COMM.Get_rank(), COMM.Get_size()


def share(n_total, rank=RANK, size=SIZE, empty_rank=True):
    """This rank's number of points: uneven shares, and rank 1 empty when there are
    several ranks (a rank with no points must work)."""
    if empty_rank and size > 1 and rank == 1:
        return 0
    ranks = [r for r in range(size) if not (empty_rank and size > 1 and r == 1)]
    weights = np.array([1.0 + 0.5 * i for i in range(len(ranks))])
    counts = np.floor(n_total * weights / weights.sum()).astype(int)
    return int(counts[ranks.index(rank)])


def local_points(n_total, geometry="cube", comm=COMM, seed=0):
    rank, size = comm.Get_rank(), comm.Get_size()
    rng = np.random.default_rng(seed + 1000 * rank)
    n = share(n_total, rank, size)
    if geometry == "cube":
        return rng.random((n, 3))
    if geometry == "clusters":
        # Thin and clustered: two blobs far apart relative to their size.
        a = rng.normal(scale=0.01, size=(n // 2, 3))
        b = rng.normal(scale=0.01, size=(n - n // 2, 3)) + [1.0, 0.0, 0.0]
        return np.concatenate([a, b])
    raise ValueError(geometry)


def rel(a, b):
    """Relative L2 error of ``a`` against the reference ``b`` (real or complex)."""
    return float(np.linalg.norm(np.asarray(a) - b) / np.linalg.norm(b))


def gathered(a, comm=COMM):
    """Every rank's array, concatenated in rank order (the global input order)."""
    return np.concatenate(comm.allgather(np.asarray(a)))


def test_tree_is_the_single_machine_tree():
    x = local_points(6000, "clusters")
    tree = fd.Octree(COMM, x, leaf_size=32)
    single = ferrofmm.Octree(gathered(x), leaf_size=32)
    # Boxes: the ranks' own boxes and the coarse tree make the global tree.
    keys = set(gathered(tree.keys).tolist()) | set(tree.coarse_keys.tolist())
    assert keys == set(single.keys.tolist())
    leaves = set(gathered(tree.keys[tree.is_leaf]).tolist())
    single_leaves = set(single.keys[single.leaves].tolist())
    assert leaves == single_leaves - set(tree.coarse_keys.tolist())
    # Every point once, in the tree's order, and the counts of the boxes.
    ids = gathered(tree.point_ids)
    assert np.array_equal(np.sort(ids), np.arange(len(ids)))
    assert np.array_equal(tree.points_per_rank, [len(p) for p in COMM.allgather(tree.points)])
    assert np.array_equal(tree.input_counts, [len(p) for p in COMM.allgather(x)])
    ranges = single.source_ranges
    count_of = {k: r[1] - r[0] for k, r in zip(single.keys.tolist(), ranges)}
    for k, c in zip(gathered(tree.keys).tolist(), gathered(tree.counts).tolist()):
        assert count_of[k] == c
    assert tree.imbalance >= 1.0
    assert tree.domain_width == single.domain_width
    assert np.array_equal(tree.domain_origin, single.domain_origin)
    # Lists: the rows of this rank's boxes are the single machine's rows.
    offsets, indices = tree.lists("v")
    lk = tree.list_keys
    single_row = {}
    s_off, s_idx = single.lists("v")
    for b, key in enumerate(single.keys.tolist()):
        single_row[key] = set(single.keys[s_idx[s_off[b] : s_off[b + 1]]].tolist())
    own = set(tree.keys.tolist())
    bad = [
        key
        for b, key in enumerate(lk.tolist())
        if key in own and set(lk[indices[offsets[b] : offsets[b + 1]]].tolist()) != single_row[key]
    ]
    assert COMM.allreduce(len(bad)) == 0
    stats = tree.build_stats()
    assert set(stats["seconds"]) == set(stats["bytes_sent"])


KERNELS = [
    ("laplace", {}, 1, False),
    ("yukawa", {"k": 3.0}, 1, False),
    ("helmholtz", {"k": 4.0}, 1, True),
    ("stokes", {}, 3, False),
]


@pytest.mark.parametrize("kernel,params,components,complex_", KERNELS)
def test_fmm_equals_single_machine(kernel, params, components, complex_):
    rng = np.random.default_rng(7 + RANK)
    x = local_points(4000, seed=11)
    shape = (len(x),) if components == 1 else (len(x), 3)
    q = rng.random(shape) - 0.5
    if complex_:
        q = q + 1j * (rng.random(shape) - 0.5)
    fixed = dict(order=6, leaf_size=48, scheme="fft", gradient=True, cache=False)
    fmm = fd.Fmm(COMM, x, None, kernel, **params, **fixed)
    r = fmm.evaluate(q)
    single = ferrofmm.Fmm(gathered(x), None, kernel, **params, **fixed).evaluate(gathered(q))
    assert rel(gathered(r.potential), single.potential) < 1e-12
    assert rel(gathered(r.gradient), single.gradient) < 1e-12
    assert r.potential.shape == ((len(x),) if components == 1 else (len(x), 3))
    # Reusable with new densities (nothing rebuilt).
    q2 = np.ones(shape) if not complex_ else np.ones(shape) * (1 - 2j)
    r2 = fmm.evaluate(q2)
    single2 = ferrofmm.Fmm(gathered(x), None, kernel, **params, **fixed).evaluate(gathered(q2))
    assert rel(gathered(r2.potential), single2.potential) < 1e-12


@pytest.mark.parametrize("kernel,params,eps", [("laplace", {}, 1e-6), ("yukawa", {"k": 2.0}, 1e-5),
                                               # damped waves (a complex k)
                                               ("helmholtz", {"k": 3.0 + 1.0j}, 1e-4),
                                               ("stokes", {}, 1e-4)])
def test_eps_is_met(kernel, params, eps):
    rng = np.random.default_rng(3 + RANK)
    x = local_points(5000, "clusters", seed=5)
    shape = (len(x),) if kernel != "stokes" else (len(x), 3)
    q = rng.random(shape)  # positive charges
    if kernel == "helmholtz":
        q = q + 1j * rng.random(shape)
    call = getattr(fd, kernel)
    r = call(COMM, x, q, **params, eps=eps, gradient=True, cache=False)
    assert r.info["verified"] is True
    assert r.info["measured_error"]["potential"] <= eps
    if kernel != "stokes":
        # No cache folder, so no calibration: the built-in costs chose.
        assert r.info["calibrated"] is False, r.info
    truth = getattr(ferrofmm, kernel)(
        gathered(x), gathered(q), **params, eps=eps / 100, gradient=True
    )
    assert rel(gathered(r.potential), truth.potential) <= eps
    assert rel(gathered(r.gradient), truth.gradient) <= eps


@pytest.mark.parametrize("kernel,params", [("laplace", {}), ("stokes", {})])
def test_separate_targets(kernel, params):
    """Each rank's own targets, partly outside the sources' cube, some ranks without
    targets (the last) or without sources (rank 1): the single machine's values."""
    rng = np.random.default_rng(60 + RANK)
    x = local_points(3000, seed=13)
    m = 0 if (SIZE > 1 and RANK == SIZE - 1) else 400 + 100 * RANK
    y = rng.random((m, 3)) * 1.5 + 0.25
    shape = (len(x),) if kernel == "laplace" else (len(x), 3)
    q = rng.random(shape) - 0.5
    fixed = dict(order=6, leaf_size=40, scheme="fft", gradient=True)
    r = getattr(fd, kernel)(COMM, x, q, targets=y, cache=False, **params, **fixed)
    assert len(r.potential) == m
    single = ferrofmm.Fmm(gathered(x), gathered(y), kernel, **params, **fixed).evaluate(
        gathered(q)
    )
    assert rel(gathered(r.potential), single.potential) < 1e-12
    assert rel(gathered(r.gradient), single.gradient) < 1e-12
    # A tolerance, verified at the targets against a direct sum over all sources.
    r = getattr(fd, kernel)(COMM, x, q, targets=y, eps=1e-5, gradient=True, cache=False)
    assert r.info["verified"] is True
    truth = ferrofmm.Fmm(gathered(x), gathered(y), kernel, eps=1e-7, gradient=True).evaluate(
        gathered(q)
    )
    assert rel(gathered(r.potential), truth.potential) <= 1e-5
    # Targets on some ranks only: refused everywhere.
    if SIZE > 1:
        with pytest.raises(ValueError, match="every rank or on none"):
            fd.Fmm(COMM, x, targets=y if RANK == 0 else None, order=4, cache=False)


def _stresslet_direct(x, m, nv, f, y):
    """Velocity and pressure at ``y`` of forces ``f`` and stresslets ``(m, nv)`` at ``x``
    by FMM3D's ``stfmm3d`` formulas, written out here (viscosity 1)."""
    d = y[:, None, :] - x[None, :, :]
    r2 = np.einsum("jia,jia->ji", d, d)
    r2[r2 == 0] = np.inf
    r = np.sqrt(r2)
    dm, dn, df = (np.einsum("jia,ia->ji", d, v) for v in (m, nv, f))
    u = (f[None] / r[..., None] + d * (df / r**3)[..., None]) / (8 * np.pi)
    u += 3 * d * (dm * dn / r**5)[..., None] / (4 * np.pi)
    p = df / (4 * np.pi * r**3) + (6 * dm * dn / r**5 - 2 * np.sum(m * nv, 1) / r**3) / (4 * np.pi)
    return u.sum(1), p.sum(1)


def test_stokes_stresslets_and_the_pressure():
    """Forces and stresslets with the pressure and gradients across the ranks (rank 1
    without points): the tolerance verified on what is delivered; velocity and pressure
    against the formulas, gradients against the single machine; bad input the same
    error on every rank."""
    rng = np.random.default_rng(70 + RANK)
    x = local_points(1500, seed=17)
    n = len(x)
    f, m = rng.random((n, 3)) - 0.5, rng.random((n, 3)) - 0.5
    nv = rng.normal(size=(n, 3))
    nv /= np.linalg.norm(nv, axis=1)[:, None]
    eps = 1e-6
    r = fd.stokes(COMM, x, f, strslet=m, strsvec=nv, pressure=True, gradient=True, eps=eps,
                  cache=False)
    assert r.potential.shape == (n, 3) and r.gradient.shape == (n, 3, 3)
    assert r.pressure.shape == (n,) and r.pressure_gradient.shape == (n, 3)
    assert r.info["verified"] is True and r.info["measured_error"]["worst"] <= eps, r.info
    X, F, M, NV = (gathered(a) for a in (x, f, m, nv))
    sample = np.arange(0, len(X), 13)
    u, p = _stresslet_direct(X, M, NV, F, X[sample])
    assert rel(gathered(r.potential)[sample], u) <= eps
    assert rel(gathered(r.pressure)[sample], p) <= eps
    single = ferrofmm.stokes(X, F, strslet=M, strsvec=NV, pressure=True, gradient=True,
                             eps=5e-8)
    # (Each within eps of the truth, so within 2 eps of each other.)
    assert rel(gathered(r.gradient), single.gradient) <= 2 * eps
    assert rel(gathered(r.pressure_gradient), single.pressure_gradient) <= 2 * eps
    # Stresslets alone at separate targets, the pressure without gradients.
    y = rng.random((300, 3)) * 1.2 - 0.1
    r = fd.stokes(COMM, x, strslet=m, strsvec=nv, targets=y, pressure=True, eps=1e-5,
                  cache=False)
    assert r.gradient is None and r.pressure_gradient is None and r.pressure.shape == (300,)
    u, p = _stresslet_direct(X, M, NV, np.zeros_like(X), gathered(y))
    assert rel(gathered(r.potential), u) <= 1e-5 and rel(gathered(r.pressure), p) <= 1e-5
    # Bad input on one rank: the same ValueError on all of them.
    with pytest.raises(ValueError, match="strslet and strsvec together"):
        fd.stokes(COMM, x, strslet=m, pressure=True)
    bad = nv[:-1] if RANK == 0 and n > 0 else nv
    with pytest.raises(ValueError, match="strsvec"):
        fd.stokes(COMM, x, f, strslet=m, strsvec=bad, cache=False, order=4)


def test_stokes_layers_built_once_evaluated_many_times():
    """``Fmm(..., "stokes", stresslets=True, pressure=True)``: built once, the first
    evaluation verified, a second density set and a batch of two through the same FMMs,
    each against the formulas; what the sources carry is checked on every rank."""
    rng = np.random.default_rng(80 + RANK)
    x = local_points(1200, seed=23)
    n = len(x)
    eps = 1e-5
    fmm = fd.Fmm(COMM, x, kernel="stokes", charges=False, stresslets=True, pressure=True,
                 eps=eps, cache=False)
    assert fmm.n_sources == n and list(fmm.input_counts) == [len(a) for a in COMM.allgather(x)]
    X = gathered(x)
    sample = np.arange(0, len(X), 7)

    def stresslets():
        m = rng.random((n, 3)) - 0.5
        nv = rng.normal(size=(n, 3))
        return m, nv / np.linalg.norm(nv, axis=1)[:, None]

    sets = [stresslets() for _ in range(2)]
    for i, (m, nv) in enumerate(sets):
        r = fmm.evaluate(strslet=m, strsvec=nv)
        # The first evaluation of a tolerance is verified, the next ones not.
        assert r.info["verified"] is (True if i == 0 else None), r.info
        assert r.potential.shape == (n, 3) and r.pressure.shape == (n,)
        assert r.gradient is None and r.pressure_gradient is None
        u, p = _stresslet_direct(X, gathered(m), gathered(nv), np.zeros_like(X), X[sample])
        assert rel(gathered(r.potential)[sample], u) <= eps
        assert rel(gathered(r.pressure)[sample], p) <= eps
        sets[i] = (m, nv, r)
    batch = fmm.evaluate(strslet=np.stack([s[0] for s in sets]),
                         strsvec=np.stack([s[1] for s in sets]))
    assert batch.potential.shape == (2, n, 3) and batch.pressure.shape == (2, n)
    for i, (_, _, r) in enumerate(sets):
        assert np.allclose(batch.potential[i], r.potential, rtol=1e-12, atol=0)
        assert np.allclose(batch.pressure[i], r.pressure, rtol=1e-12, atol=0)
    # Forces with stresslets, the pressure gradient, an order instead of eps.
    both = fd.Fmm(COMM, x, kernel="stokes", stresslets=True, pressure=True, gradient=True,
                  order=7, cache=False)
    f = rng.random((n, 3)) - 0.5
    m, nv, _ = sets[0]
    r = both.evaluate(f, strslet=m, strsvec=nv)
    assert r.gradient.shape == (n, 3, 3) and r.pressure_gradient.shape == (n, 3)
    u, p = _stresslet_direct(X, gathered(m), gathered(nv), gathered(f), X[sample])
    assert rel(gathered(r.potential)[sample], u) <= 1e-4
    assert rel(gathered(r.pressure)[sample], p) <= 1e-4
    # What the sources carry, the same error on every rank.
    with pytest.raises(ValueError, match="carry strsvec"):
        fmm.evaluate(strslet=m)
    with pytest.raises(ValueError, match="carry no charges"):
        fmm.evaluate(f, strslet=m, strsvec=nv)
    with pytest.raises(ValueError, match="carry no strslet"):
        fd.Fmm(COMM, x, kernel="stokes", order=4, cache=False).evaluate(f, strslet=m,
                                                                         strsvec=nv)
    with pytest.raises(ValueError, match="belong to the stokes kernel"):
        fd.Fmm(COMM, x, kernel="laplace", stresslets=True)
    with pytest.raises(ValueError, match="do not combine"):
        fd.Fmm(COMM, x, kernel="stokes", dipoles=True, pressure=True)


def test_charges_and_dipoles_and_batches():
    rng = np.random.default_rng(40 + RANK)
    x = local_points(3000, seed=9)
    q = rng.random((2, len(x))) - 0.5
    d = rng.random((2, len(x), 3)) - 0.5
    fixed = dict(order=5, leaf_size=40, scheme="svd")
    r = fd.laplace(COMM, x, q, dipoles=d, cache=False, **fixed)
    assert r.potential.shape == (2, len(x))
    single = ferrofmm.laplace(gathered(x), np.concatenate(COMM.allgather(q), axis=1),
                              dipoles=np.concatenate(COMM.allgather(d), axis=1), **fixed)
    mine = np.concatenate(COMM.allgather(r.potential), axis=1)
    assert rel(mine, single.potential) < 1e-12


def test_sub_communicator():
    # Two groups run two different problems at once.
    color = RANK % 2
    sub = COMM.Split(color, RANK)
    try:
        x = local_points(2500, comm=sub, seed=20 + color)
        q = np.random.default_rng(RANK).random(len(x)) - 0.5
        fixed = dict(order=5, leaf_size=32, scheme="fft")
        r = fd.laplace(sub, x, q, cache=False, **fixed)
        single = ferrofmm.laplace(gathered(x, sub), gathered(q, sub), **fixed)
        err = rel(gathered(r.potential, sub), single.potential)
    finally:
        sub.Free()
    assert max(COMM.allgather(err)) < 1e-12


def test_bad_input_on_one_rank_is_the_same_error_everywhere():
    x = local_points(2000, seed=30)
    last = SIZE - 1
    bad = x.copy()
    if RANK == last and len(bad):
        bad[0, 0] = np.nan
    elif RANK == last:
        bad = np.array([[np.nan, 0.0, 0.0]])
    with pytest.raises(ValueError, match="NaN|finite"):
        fd.laplace(COMM, bad, np.ones(len(bad)), order=4, cache=False)
    # A shape only one rank gets wrong: checked in Python, agreed before any work.
    with pytest.raises(ValueError, match=f"rank {last}" if SIZE > 1 else "charges"):
        fd.laplace(COMM, x, np.ones(len(x) + (RANK == last)), order=4, cache=False)
    fmm = fd.Fmm(COMM, x, order=4, cache=False)
    with pytest.raises(TypeError):
        fmm.evaluate(np.ones(len(x), dtype=np.int64) if RANK == last else np.ones(len(x)))
    # The object still works after a refused call.
    r = fmm.evaluate(np.ones(len(x)))
    assert np.all(np.isfinite(gathered(r.potential)))
    with pytest.raises(TypeError, match="communicator"):
        fd.laplace("COMM_WORLD", x, np.ones(len(x)))
    with pytest.raises(ValueError, match="kernel"):
        fd.Fmm(COMM, x, kernel="coulomb" if RANK == last else "laplace", order=4, cache=False)


def test_every_rank_empty_is_an_error():
    with pytest.raises(ValueError, match="no points"):
        fd.laplace(COMM, np.zeros((0, 3)), np.zeros(0), order=4, cache=False)


def test_ranks_out_of_step_are_told_not_misread():
    """A user's collective that meets ferrofmm's argument check on other ranks is an error
    there (RuntimeError), not a garbled check."""
    if SIZE == 1:
        pytest.skip("needs two ranks")
    if RANK == 0:
        COMM.allgather(["the", "caller's", "own", "data"])
    else:
        with pytest.raises(RuntimeError, match="out of step"):
            fd.Fmm(COMM, np.random.default_rng(RANK).random((10, 3)), order=4, cache=False)
