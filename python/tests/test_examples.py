"""The examples, run on small sizes."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def load(name):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def test_identification_recovers_e_and_nu_within_one_percent():
    pytest.importorskip("scipy")
    r = load("identify_parameters").main(["--depths", "3"])
    assert r["e_error"] < 0.01
    assert r["nu_error"] < 0.01


def test_ray_sweep_writes_one_row_per_case_and_force_scales_with_e(tmp_path):
    ray = pytest.importorskip("ray")
    out = tmp_path / "sweep.csv"
    try:
        rows = load("sweep_ray").main(
            ["--models", "fem-static,fem-corotational", "--moduli", "3000,6000", "--depths", "0.003",
             "--settle", "0.2", "--out", str(out), "--num-cpus", "2"]
        )
    finally:
        ray.shutdown()
    assert out.is_file()
    assert len(rows) == 4 and all(r["error"] == "" for r in rows)
    by = {(r["model"], r["young_modulus"]): r["force"] for r in rows}
    # fem-static is linear: doubling E doubles the force.
    assert by[("fem-static", 6000.0)] == pytest.approx(2 * by[("fem-static", 3000.0)], rel=1e-9)
    assert all(np.isfinite(r["force"]) and r["force"] > 0 for r in rows)
