"""Hostile inputs (issue 37): each test fails on the module before its fix.

Resources (memory, the cache directory, RAYON_NUM_THREADS), messages that
name the cause and the caller's argument, flags that must be booleans, and
tolerances that are not met. Small N throughout.
"""

import os
import subprocess
import sys
import textwrap
import warnings

import numpy as np
import pytest

import ferrofmm

rng = np.random.default_rng(37)
X = rng.random((600, 3))
Q = rng.random(600) - 0.5


# --- Row 4: memory, refused before anything is copied ----------------------


def test_huge_broadcast_view_is_refused_before_copying(monkeypatch):
    # 1e9 points as a view of 24 bytes: copying it took 24 GB (the OOM
    # killer, or an abort under RLIMIT_AS).
    monkeypatch.setenv("FERROFMM_MEMORY_LIMIT", "8G")
    x = np.broadcast_to(np.zeros(3), (10**9, 3))
    q = np.broadcast_to(np.zeros(1), (10**9,))
    with pytest.raises(MemoryError, match=r"predicted to need at least .* GiB but the limit is 8.0 GiB"):
        ferrofmm.laplace(x, q, order=4)
    with pytest.raises(MemoryError, match="predicted to need"):
        ferrofmm.Fmm(x, order=4, kernel="stokes")
    with pytest.raises(MemoryError, match="octree of 1000000000 points"):
        ferrofmm.Octree(x)


@pytest.mark.skipif(not os.path.exists("/proc/meminfo"), reason="reads /proc (Linux)")
def test_huge_view_without_a_configured_limit(monkeypatch):
    # No FERROFMM_MEMORY_LIMIT: the memory available. 1e11 points need
    # terabytes.
    monkeypatch.delenv("FERROFMM_MEMORY_LIMIT", raising=False)
    x = np.broadcast_to(np.zeros(3), (10**11, 3))
    with pytest.raises(MemoryError, match="predicted to need"):
        ferrofmm.Fmm(x, order=4)


def test_many_density_vectors_are_refused_before_copying(monkeypatch):
    fmm = ferrofmm.Fmm(X, order=3)
    monkeypatch.setenv("FERROFMM_MEMORY_LIMIT", "1G")
    q = np.broadcast_to(Q, (10**6, len(Q)))  # 4.8 GB of charges, 4.8 GB of results
    with pytest.raises(MemoryError, match=r"evaluating 1000000 density vector"):
        fmm.evaluate(q)
    monkeypatch.setenv("FERROFMM_MEMORY_LIMIT", "unlimited")
    assert fmm.evaluate(Q).potential.shape == (len(Q),)


def _run_limited(code: str, headroom: int) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter whose address space is limited to
    its size after importing ferrofmm plus ``headroom`` bytes."""
    prelude = textwrap.dedent(
        f"""
        import resource, re
        import numpy as np, ferrofmm
        size = int(re.search(r"VmSize:\\s+(\\d+) kB", open("/proc/self/status").read()).group(1)) * 1024
        resource.setrlimit(resource.RLIMIT_AS, (size + {headroom}, resource.RLIM_INFINITY))
        """
    )
    env = {k: v for k, v in os.environ.items() if k != "FERROFMM_MEMORY_LIMIT"}
    env["RAYON_NUM_THREADS"] = "1"
    return subprocess.run(
        [sys.executable, "-c", prelude + textwrap.dedent(code)],
        capture_output=True, text=True, timeout=120, env=env,
    )


@pytest.mark.skipif(not os.path.exists("/proc/self/limits"), reason="reads /proc (Linux)")
def test_rlimit_as_is_the_limit():
    # Under `ulimit -v` the machine's free memory is not what a process can
    # allocate: 1e8 points were copied until the interpreter aborted
    # ("memory allocation of 2400000000 bytes failed").
    r = _run_limited(
        """
        x = np.broadcast_to(np.zeros(3), (10**8, 3))
        try:
            ferrofmm.laplace(x, np.broadcast_to(np.zeros(1), (10**8,)), order=4)
        except MemoryError as e:
            print("MemoryError:", e)
        """,
        headroom=1 << 30,
    )
    assert r.returncode == 0, r.stderr
    assert "MemoryError: an FMM of 100000000 sources" in r.stdout, r.stdout
    assert "RLIMIT_AS" in r.stdout


@pytest.mark.skipif(not os.path.exists("/proc/self/limits"), reason="reads /proc (Linux)")
def test_failed_copy_is_memory_error_not_abort():
    # Past the prediction (the native class called directly), the copy of
    # the points itself fails: MemoryError, not an abort of the interpreter.
    r = _run_limited(
        """
        x = np.zeros(3 * 10**8)  # 2.4 GB, mapped lazily
        try:
            ferrofmm._ferrofmm.NativeFmm(x, None, "laplace", None, None, 4, None, "svd",
                                         False, False, 1, None)
        except MemoryError as e:
            print("MemoryError:", e)
        """,
        headroom=(3 << 30) + (1 << 29),
    )
    assert r.returncode == 0, (r.returncode, r.stderr[-500:])
    assert "MemoryError: cannot allocate 2400000000 bytes for a copy of sources" in r.stdout


# --- Row 10: the cause, not "smallest: inf" --------------------------------


@pytest.mark.parametrize(
    "scale, dtype", [(1e300, np.float64), (1e-300, np.float64), (1e20, np.float32)]
)
def test_domain_beyond_the_float_type_with_eps(scale, dtype):
    with pytest.raises(ValueError, match="domain width .* is outside the range"):
        ferrofmm.laplace((X * scale).astype(dtype), Q, eps=1e-3)


def test_helmholtz_beyond_low_frequency_with_eps():
    with pytest.raises(ValueError, match=r"k \* width = .* exceeds the low-frequency limit 100"):
        ferrofmm.helmholtz(X, Q, k=1e6)
    with pytest.raises(ValueError, match=r"exceeds the low-frequency limit"):
        ferrofmm.helmholtz(X, Q, k=1e6, eps=1e-3)


# --- Row 12: every argument's shape first, under the caller's name ---------


@pytest.fixture
def no_build(monkeypatch):
    """Fail the test if an FMM is built: shapes must be refused before."""

    def built(*args, **kwargs):
        raise AssertionError("the FMM was built before the arguments were checked")

    monkeypatch.setattr(ferrofmm._ferrofmm, "NativeFmm", built)


@pytest.mark.parametrize(
    "forces, match",
    [
        (np.ones((600, 2)), r"forces has shape \(600, 2\) but there are 600 sources"),
        (np.ones(600), r"forces must have shape \(n, 3\) or \(k, n, 3\), got \(600,\)"),
        (np.ones((599, 3)), r"forces has shape \(599, 3\)"),
        (np.ones((2, 600, 3, 1)), r"forces must have shape"),
        (np.ones((600, 3), dtype=np.int64), r"forces must be float32 or float64"),
    ],
)
def test_stokes_forces_checked_before_setup(no_build, forces, match):
    with pytest.raises((ValueError, TypeError), match=match):
        ferrofmm.stokes(X, forces)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: ferrofmm.laplace(X, Q[:-1]), "charges has 599 values"),
        (lambda: ferrofmm.laplace(X, dipoles=np.ones((600, 2))), r"dipoles has shape \(600, 2\)"),
        (lambda: ferrofmm.yukawa(X, np.ones((2, 3)), k=1.0), r"charges must have shape \(k, 600\)"),
        (lambda: ferrofmm.helmholtz(X, np.ones(5), k=1.0), "charges has 5 values"),
        (lambda: ferrofmm.helmholtz(X, np.array(["a"] * 600), k=1.0), "charges must hold numbers"),
    ],
)
def test_densities_checked_before_setup(no_build, call, match):
    with pytest.raises((ValueError, TypeError), match=match):
        call()


# --- Row 16: flags, the cache directory, threads ----------------------------


@pytest.mark.parametrize("flag", ["verify", "gradient", "hessian", "at_sources"])
@pytest.mark.parametrize("value", ["no", 1, None, np.array([True])])
def test_flags_must_be_booleans(flag, value):
    with pytest.raises(TypeError, match=f"{flag} must be True or False"):
        ferrofmm.laplace(X, Q, order=4, **{flag: value})


def test_numpy_booleans_are_flags():
    r = ferrofmm.laplace(X, Q, order=3, gradient=np.bool_(True), verify=np.True_)
    assert r.gradient.shape == (600, 3)


def test_cache_dir_that_is_a_file(tmp_path):
    f = tmp_path / "file"
    f.write_text("not a directory")
    with pytest.raises(ValueError, match="cache_dir .*file exists and is not a directory"):
        ferrofmm.Fmm(X, order=4, cache_dir=f)
    with pytest.raises(ValueError, match="cache_dir .*file/sub cannot be created"):
        ferrofmm.Fmm(X, order=4, cache_dir=f / "sub")
    with pytest.raises(TypeError, match="cache_dir must be a path"):
        ferrofmm.Fmm(X, order=4, cache_dir=3)


def test_cache_dir_is_created_and_used(tmp_path):
    d = tmp_path / "a" / "b"
    ferrofmm.Fmm(X, order=3, cache_dir=d)
    assert len(list(d.iterdir())) >= 1


def test_cache_not_saved_is_a_warning(tmp_path):
    # Directories where the cache files go: reading fails, writing fails
    # (a file cannot replace a directory), whoever runs the test.
    ferrofmm.Fmm(X, order=3, cache_dir=tmp_path)
    for f in list(tmp_path.iterdir()):
        f.unlink()
        f.mkdir()
    with pytest.warns(RuntimeWarning, match="operator cache was not saved"):
        fmm = ferrofmm.Fmm(X, order=3, cache_dir=tmp_path)
    assert fmm.evaluate(Q).potential.shape == (600,)


def test_unparsable_rayon_num_threads_warns(monkeypatch):
    monkeypatch.setenv("RAYON_NUM_THREADS", "abc")
    with pytest.warns(RuntimeWarning, match=r"RAYON_NUM_THREADS=\"abc\" is not a number of threads"):
        ferrofmm.laplace(X, Q, order=3)


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="needs 2 cores to tell 1 thread apart")
def test_rayon_num_threads_is_honoured(monkeypatch):
    monkeypatch.setenv("RAYON_NUM_THREADS", "1")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert ferrofmm.laplace(X, Q, order=3).info["threads"] == 1


def test_order_beyond_any_integer():
    # Was an OverflowError on the way to the native module.
    with pytest.raises(ValueError, match=r"expansion order 10{30} is not supported \(use 2..=20\)"):
        ferrofmm.laplace(X, Q, order=10**30)


def test_huge_thread_and_leaf_counts_are_lowered():
    # Beyond a machine integer: lowered (to the cores, to one leaf), as
    # any count above those is; was an OverflowError.
    r = ferrofmm.laplace(X, Q, order=3, threads=10**30, leaf_size=10**30)
    assert r.info["threads"] <= (os.cpu_count() or 1)
    assert r.info["leaves"] == 1


@pytest.mark.parametrize("k", [True, "1"])
def test_wavenumber_must_be_a_number(k):
    with pytest.raises(TypeError, match="k must be a float"):
        ferrofmm.yukawa(X, Q, k=k, order=4)


def test_screening_wavenumber_must_be_real():
    # Complex wavenumbers are Helmholtz's (damped waves), not Yukawa's.
    with pytest.raises(ValueError, match="wavenumber of yukawa is real"):
        ferrofmm.yukawa(X, Q, k=1j, order=4)


def test_byte_swapped_floats_are_floats():
    r = ferrofmm.laplace(X.astype(">f8"), Q.astype(">f4"), order=4)
    assert r.potential.dtype == np.float64
    ref = ferrofmm.laplace(X, Q.astype(np.float32), order=4)
    np.testing.assert_array_equal(r.potential, ref.potential)


# --- Tolerance not met: a warning, not silence -----------------------------


def test_tolerance_not_met_warns():
    # A rock-salt lattice (alternating charges): its potential far away is
    # a tiny difference of large terms, and float32 cannot reach 5e-6 on it.
    n = 12
    g = np.arange(n)
    x = np.array(np.meshgrid(g, g, g, indexing="ij")).reshape(3, -1).T / n
    q = (-1.0) ** np.rint(x * n).sum(axis=1)
    y = rng.normal(size=(300, 3))
    y = 1.5 * y / np.linalg.norm(y, axis=1)[:, None] + 0.45
    with pytest.warns(ferrofmm.AccuracyWarning, match="eps=5e-06 was not met") as w:
        r = ferrofmm.laplace(x.astype(np.float32), q, targets=y.astype(np.float32), eps=5e-6)
    assert r.info["verified"] is False
    assert w[0].filename == __file__
    fmm = ferrofmm.Fmm(x.astype(np.float32), y.astype(np.float32), eps=5e-6)
    with pytest.warns(ferrofmm.AccuracyWarning):
        fmm.evaluate(q)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fmm.evaluate(q)  # once per Fmm


# --- Row 8: overflow is an error naming it, never NaN or inf --------------


@pytest.mark.parametrize("kwargs", [{"order": 4}, {"eps": 1e-6}])
def test_overflowing_charges(kwargs):
    with pytest.raises(ValueError, match=r"the result overflowed f64 \(output \d+ of target \d+ is (-?inf|NaN);"):
        ferrofmm.laplace(X, Q * 1e307, **kwargs)


def test_overflowing_charges_float32():
    with pytest.raises(ValueError, match="the result overflowed f32"):
        ferrofmm.laplace(X.astype(np.float32), (Q * 1e37).astype(np.float32), order=4)
    # float64 charges beyond float32 in a float32 run: named, not "charge 0
    # is not finite (-inf)" after a silent cast.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match=r"charges value 0 \(.*\) exceeds the largest f32"):
            ferrofmm.laplace(X, np.full(600, 1e300), order=4, dtype="float32")
        with pytest.raises(ValueError, match=r"forces value 5 .* exceeds the largest f32"):
            ferrofmm.stokes(X, np.where(np.arange(1800) == 5, 1e39, 1.0).reshape(600, 3),
                            order=4, dtype="float32")


def test_octree_parameters():
    with pytest.raises(TypeError, match="balance must be True or False"):
        ferrofmm.Octree(X, balance="no")
    with pytest.raises(TypeError, match="leaf_size must be an int, got NoneType"):
        ferrofmm.Octree(X, leaf_size=None)
