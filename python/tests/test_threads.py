"""Stepping releases the GIL: a Python thread keeps running while a model steps."""

import threading
import time

import tissue


def test_python_thread_runs_while_a_model_steps(liver):
    m = tissue.Model("fem-static", liver.refined().refined(), {"young_modulus": 3e3, "poisson_ratio": 0.3})
    ticks = []
    stop = threading.Event()

    def ticker():
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=ticker)
    t.start()
    start = time.perf_counter()
    m.set_constraints(fixed=[3, 39, 64])
    m.step(0.01)  # a factorisation of ~38k tetrahedra: far longer than a tick
    end = time.perf_counter()
    stop.set()
    t.join()
    during = [x for x in ticks if start < x < end]
    assert end - start > 0.05
    assert len(during) >= 3, f"{len(during)} ticks in {end - start:.3f} s of stepping"
