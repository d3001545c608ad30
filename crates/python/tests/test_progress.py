"""progress= of the evaluating entry points (issue 36): a callable told
(done, total) at a bounded rate, with the GIL held; its exceptions end the
call; anything not callable is a TypeError before any work. The Fmm
constructor's progress= is told (step, done, total) for each build step."""

import numpy as np
import pytest

import ferrofmm
from conftest import cube, zero_mean


def _check_reports(seen):
    assert seen, "no progress reported"
    dones = [d for d, _ in seen]
    assert all(isinstance(d, int) and isinstance(t, int) for d, t in seen)
    assert dones == sorted(dones), seen
    assert all(0 <= d <= t for d, t in seen), seen
    last_done, last_total = seen[-1]
    assert last_done == last_total > 0, seen
    # At most one call per 0.1 s poll plus the last: far fewer than boxes.
    assert len(seen) < 1000


def test_fmm_evaluate_reports_progress_and_changes_nothing(rng):
    n = 20000
    x = cube(rng, n)
    q = zero_mean(rng, n)
    fmm = ferrofmm.Fmm(x, order=5, scheme="fft", verify=False)
    plain = fmm.evaluate(q)
    seen = []
    watched = fmm.evaluate(q, progress=lambda done, total: seen.append((done, total)))
    _check_reports(seen)
    np.testing.assert_array_equal(plain.potential, watched.potential)

    # Several vectors: one rising count over the whole call.
    seen.clear()
    fmm.evaluate(np.stack([q, 2 * q]), progress=lambda d, t: seen.append((d, t)))
    _check_reports(seen)


def test_one_call_functions_take_progress(rng):
    x = cube(rng, 3000)
    seen = []
    r = ferrofmm.laplace(x, zero_mean(rng, 3000), order=4, progress=lambda d, t: seen.append((d, t)))
    _check_reports(seen)
    assert r.potential.shape == (3000,)
    seen.clear()
    ferrofmm.yukawa(x, zero_mean(rng, 3000), k=1.0, order=4, progress=lambda d, t: seen.append((d, t)))
    _check_reports(seen)


def test_an_exception_in_the_callback_ends_the_call(rng):
    x = cube(rng, 3000)
    fmm = ferrofmm.Fmm(x, order=4, verify=False)

    class Stop(Exception):
        pass

    def stop(done, total):
        raise Stop(f"stopped at {done}/{total}")

    with pytest.raises(Stop, match="stopped at"):
        fmm.evaluate(zero_mean(rng, 3000), progress=stop)
    # The Fmm still works afterwards.
    assert fmm.evaluate(zero_mean(rng, 3000)).potential.shape == (3000,)


@pytest.mark.parametrize("bad", [1, "bar", [1, 2], {"every": 0.1}])
def test_a_progress_that_cannot_be_called_is_a_type_error(rng, bad):
    x = cube(rng, 500)
    fmm = ferrofmm.Fmm(x, order=3, verify=False)
    with pytest.raises(TypeError, match="progress must be a callable"):
        fmm.evaluate(zero_mean(rng, 500), progress=bad)
    with pytest.raises(TypeError, match="progress must be a callable"):
        ferrofmm.laplace(x, zero_mean(rng, 500), order=3, progress=bad)
    with pytest.raises(TypeError, match="progress must be a callable"):
        fmm._native.evaluate(np.zeros(500), 1, bad)
    with pytest.raises(TypeError, match="progress must be a callable"):
        ferrofmm.Fmm(x, order=3, progress=bad)


STEPS = ["tuning", "tree", "operators", "layout"]


def test_the_constructor_reports_each_build_step(rng):
    n = 20000
    x = cube(rng, n)
    q = zero_mean(rng, n)
    seen = []
    fmm = ferrofmm.Fmm(
        x, eps=1e-5, gradient=True, cache=False,
        progress=lambda step, done, total: seen.append((step, done, total)),
    )
    steps = [s for s, _, _ in seen]
    assert set(steps) == set(STEPS), seen
    assert [STEPS.index(s) for s in steps] == sorted(STEPS.index(s) for s in steps), seen
    for step in STEPS:
        of = [(d, t) for s, d, t in seen if s == step]
        assert all(isinstance(d, int) and isinstance(t, int) and 0 <= d <= t for d, t in of)
        assert [d for d, _ in of] == sorted(d for d, _ in of), (step, of)
        assert of[-1][0] == of[-1][1] > 0, (step, of)
    plain = ferrofmm.Fmm(x, eps=1e-5, gradient=True, cache=False)
    np.testing.assert_array_equal(fmm.evaluate(q).gradient, plain.evaluate(q).gradient)


def test_an_exception_in_the_build_callback_ends_the_construction(rng):
    class Stop(Exception):
        pass

    def stop(step, done, total):
        raise Stop(step)

    with pytest.raises(Stop):
        ferrofmm.Fmm(cube(rng, 5000), eps=1e-4, progress=stop)
