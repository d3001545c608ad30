"""The GIL is released while the library works, and Ctrl-C is not swallowed."""

import _thread
import signal
import threading
import time

import numpy as np
import pytest

import ferrofmm


def test_gil_released_during_setup_and_evaluation():
    rng = np.random.default_rng(1)
    n = 150_000
    x = rng.random((n, 3))
    q = rng.random(n) - 0.5
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.005)

    t = threading.Thread(target=count)
    t.start()
    try:
        start = time.perf_counter()
        ferrofmm.laplace(x, q, order=7, gradient=True, verify=False)
        end = time.perf_counter()
    finally:
        stop.set()
        t.join()
    during = [s for s in ticks if start <= s <= end]
    assert end - start > 0.2, "the run must be long enough to tell"
    # With the GIL held the counter could not run at all during the call.
    assert len(during) >= 0.2 * (end - start) / 0.005
    gaps = np.diff([start] + during + [end])
    assert gaps.max() < 0.5


def test_ctrl_c_interrupts_within_a_second(monkeypatch):
    rng = np.random.default_rng(2)
    x = rng.random((20_000, 3))
    # A long precomputation: every M2L operator of a high order, dense
    # (about 4 s in a release build on 2 cores; cancelled after 0.5 s, long
    # before its memory, about 2.6 GB, is allocated).
    monkeypatch.setenv("FERROFMM_MEMORY_LIMIT", "unlimited")
    # Python's own SIGINT handler, which `interrupt_main` needs: a process
    # started in the background by a non-interactive shell (`cmd &`)
    # inherits SIGINT ignored, and then `interrupt_main` does nothing.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    interrupt_at = []

    def interrupt():
        interrupt_at.append(time.perf_counter())
        _thread.interrupt_main()

    timer = threading.Timer(0.5, interrupt)
    timer.start()
    start = time.perf_counter()
    try:
        with pytest.raises(KeyboardInterrupt):
            ferrofmm.Fmm(x, order=14, leaf_size=5, scheme="dense")
        caught = time.perf_counter()
    finally:
        timer.join()
        signal.signal(signal.SIGINT, previous)
    assert interrupt_at, "the interrupt fired"
    assert caught - interrupt_at[0] < 1.0
    assert caught - start < 5.0
