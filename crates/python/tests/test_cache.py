"""The operator cache, on by default: where it lives (FERROFMM_CACHE,
XDG_CACHE_HOME, a path), how to turn it off, what ``info`` says, several
threads filling one entry, an unusable folder, a damaged entry. Every test
names its folder through the environment or an argument (conftest.py points
the default at a temporary folder)."""

import concurrent.futures
import warnings

import numpy as np
import pytest

import ferrofmm

rng = np.random.default_rng(7)
X = rng.random((2000, 3))
Q = rng.random(2000) - 0.5


# Cache files of one run: the operators and the M2L scheme (the auto
# scheme, FFT here, when the folder comes from the environment); with a
# folder given, the auto scheme counts no SVD precomputation, takes the SVD
# and keeps its bases as a third file.
ENTRIES = 2
ENTRIES_SVD = 3


def run(**kw):
    # A leaf size given: a tree with its cache files (2,000 points with an
    # order alone would be a direct sum, with order-2 operators only).
    return ferrofmm.Fmm(X, order=3, leaf_size=150, **kw).evaluate(Q)


def files(d):
    return sorted(p.name for p in d.iterdir()) if d.exists() else []


def test_default_folder_from_ferrofmm_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("FERROFMM_CACHE", str(tmp_path / "c"))
    first = run()
    assert first.info["cache_dir"] == str(tmp_path / "c")
    assert first.info["cache"] == "miss (computed, saved)"
    assert len(files(tmp_path / "c")) == ENTRIES
    second = run()
    assert second.info["cache"] == "hit"
    np.testing.assert_array_equal(first.potential, second.potential)


def test_default_folder_from_xdg_cache_home(tmp_path, monkeypatch):
    monkeypatch.delenv("FERROFMM_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    r = run()
    assert r.info["cache_dir"] == str(tmp_path / "ferrofmm")
    assert len(files(tmp_path / "ferrofmm")) == ENTRIES


def test_cache_false_and_off_write_nothing(tmp_path, monkeypatch):
    monkeypatch.setenv("FERROFMM_CACHE", str(tmp_path / "c"))
    r = run(cache=False)
    assert r.info["cache"] == "off (cache=False)"
    assert r.info["cache_dir"] is None
    monkeypatch.setenv("FERROFMM_CACHE", "off")
    r = run()
    assert r.info["cache"] == "off (FERROFMM_CACHE=off)"
    assert not (tmp_path / "c").exists()


def test_cache_path_and_cache_dir(tmp_path):
    r = run(cache=tmp_path / "p")
    assert r.info["cache_dir"] == str(tmp_path / "p")
    assert len(files(tmp_path / "p")) == ENTRIES_SVD
    r = run(cache_dir=str(tmp_path / "d"), cache=True)
    assert r.info["cache_dir"] == str(tmp_path / "d")
    with pytest.raises(ValueError, match="cache=False contradicts cache_dir"):
        run(cache_dir=tmp_path, cache=False)
    with pytest.raises(ValueError, match="give cache or cache_dir, not both"):
        run(cache_dir=tmp_path, cache=tmp_path)
    with pytest.raises(TypeError, match="cache must be True, False or a path"):
        run(cache=3)
    with pytest.raises(ValueError, match="cache is an empty path"):
        run(cache="")


def test_unusable_default_folder_falls_back_to_memory(tmp_path, monkeypatch):
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    monkeypatch.setenv("FERROFMM_CACHE", str(blocker / "cache"))
    with pytest.warns(RuntimeWarning, match="operator cache was not saved"):
        r = run()
    assert r.info["cache"].startswith("memory only (computed, not saved: ")
    np.testing.assert_allclose(r.potential, run(cache=False).potential, rtol=1e-6, atol=0)


def test_bad_cache_size_is_a_value_error(tmp_path, monkeypatch):
    monkeypatch.setenv("FERROFMM_CACHE_SIZE", "lots")
    with pytest.raises(ValueError, match='FERROFMM_CACHE_SIZE="lots" is not a size'):
        run()
    # Not read without a folder.
    run(cache=False)


def test_size_cap_keeps_the_newest(tmp_path, monkeypatch):
    monkeypatch.setenv("FERROFMM_CACHE", str(tmp_path))
    monkeypatch.setenv("FERROFMM_CACHE_SIZE", "1")
    run()
    ferrofmm.Fmm(X, order=4, leaf_size=150).evaluate(Q)
    names = files(tmp_path)
    assert len(names) == 1 and "_p4_" in names[0], names


def test_threads_fill_one_entry_at_once(tmp_path, monkeypatch):
    monkeypatch.setenv("FERROFMM_CACHE", str(tmp_path))
    with concurrent.futures.ThreadPoolExecutor(4) as pool:
        results = list(pool.map(lambda _: run().potential, range(4)))
    for r in results[1:]:
        np.testing.assert_array_equal(results[0], r)
    names = files(tmp_path)
    assert len(names) == ENTRIES and all(n.endswith(".ffmm") for n in names), names
    again = run()
    assert again.info["cache"] == "hit"
    np.testing.assert_array_equal(again.potential, results[0])


def test_damaged_entry_is_recomputed(tmp_path, monkeypatch):
    monkeypatch.setenv("FERROFMM_CACHE", str(tmp_path))
    first = run()
    for f in tmp_path.iterdir():
        data = bytearray(f.read_bytes())
        data[-1] ^= 0xFF
        f.write_bytes(bytes(data))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        second = run()
    # Every file was damaged: the two the report names (operators, M2L) are
    # each rejected (their checksum), recomputed and saved again; the SVD's
    # bases, which the report does not name, are recomputed with them.
    words = second.info["cache"]
    assert words.count("recomputed (cached file rejected: checksum") == 2, words
    assert words.count("(corrupt); saved)") == 2, words
    np.testing.assert_array_equal(first.potential, second.potential)
    assert run().info["cache"] == "hit"
