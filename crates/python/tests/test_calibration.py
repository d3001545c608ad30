"""``ferrofmm.calibrate``: the cost model measured here, saved in the cache folder, used by
the runs with that folder (``info["model"]`` says so), bad arguments refused."""

import numpy as np
import pytest

import ferrofmm


def test_a_calibration_is_saved_and_used_by_runs_with_its_folder(tmp_path):
    r = ferrofmm.calibrate(20_000, cache=tmp_path)
    assert set(r["scales"]) == {"p2p", "far", "m2l_compressed", "m2l_fft", "tree"}
    assert all(np.isfinite(v) and v > 0 for v in r["scales"].values()), r
    assert r["threads"] >= 1 and r["processor"]
    assert (tmp_path / "machine-calibration.txt").is_file()
    assert r["file"] == str(tmp_path / "machine-calibration.txt")
    rng = np.random.default_rng(3)
    x = rng.random((20_000, 3))
    q = rng.random(20_000) - 0.5
    # The same threads as the calibration: its folder's runs use it.
    def model(**kw):
        return ferrofmm.Fmm(x, threads=r["threads"], **kw).evaluate(q).info["model"]

    assert "calibrated on this machine" in model(eps=1e-5, cache=tmp_path)
    # Another folder has none; given parameters choose nothing.
    assert "calibrated" not in model(eps=1e-5, cache=tmp_path / "other")
    assert model(order=5, leaf_size=64, cache=tmp_path) is None


def test_bad_arguments_are_refused(tmp_path):
    with pytest.raises(ValueError, match="at least 1000"):
        ferrofmm.calibrate(10, cache=tmp_path)
    with pytest.raises(TypeError, match="points must be an int"):
        ferrofmm.calibrate(2.5e4, cache=tmp_path)
    with pytest.raises(TypeError, match="cache must be True, False or a path"):
        ferrofmm.calibrate(20_000, cache=3)
    with pytest.raises(ValueError, match="cache=False leaves no folder"):
        ferrofmm.calibrate(20_000, cache=False)
    with pytest.raises(ValueError, match="threads must be at least 1"):
        ferrofmm.calibrate(20_000, cache=tmp_path, threads=0)
