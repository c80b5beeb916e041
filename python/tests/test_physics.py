"""Physics through the Python API: the same numbers as the Rust side, and invariants."""

import csv

import numpy as np
import pytest

import tissue

SOFT = {"young_modulus": 3000.0, "poisson_ratio": 0.3, "density": 1000.0}


def test_demo_probe_force_equals_the_cli_to_1e12(tmp_path, tissue_bin):
    import subprocess

    out = tmp_path / "cli"
    subprocess.run([tissue_bin, "demo", "--out", str(out)], check=True, capture_output=True)
    with open(out / "forces.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    cli = np.array([[float(r["fx"]), float(r["fy"]), float(r["fz"])] for r in rows[1:]])

    forces = []
    summary = tissue.demo().run(callback=lambda r: forces.append(r["forces"][0]))
    py = np.array(forces)
    assert summary["error"] is None
    assert py.shape == cli.shape
    scale = np.abs(cli).max()
    assert scale > 1e-3  # the probe does press
    np.testing.assert_allclose(py, cli, rtol=0, atol=1e-12 * scale)


def test_a_rigid_translation_of_the_supports_gives_no_force(liver):
    """fem-static: moving every constrained vertex by the same vector is a rigid motion."""
    m = tissue.Model("fem-static", liver, SOFT)
    fixed = np.array([3, 39, 64])
    probe = np.array([100, 120])
    rest = m.rest_surface()
    shift = np.array([0.002, -0.001, 0.003])
    m.set_constraints(
        prescribed=np.concatenate([fixed, probe]),
        positions=rest[np.concatenate([fixed, probe])] + shift,
    )
    m.step(0.01)
    _, r = m.reactions()
    assert np.abs(r).max() < 1e-9
    pos, _ = m.surface()
    np.testing.assert_allclose(pos - rest, np.broadcast_to(shift, rest.shape), atol=1e-12)


def test_reactions_balance_and_scale_with_young_modulus(liver):
    """Static equilibrium: fixed + prescribed reactions sum to zero; force is linear in E."""
    forces = []
    for e in (3000.0, 6000.0):
        m = tissue.Model("fem-static", liver, dict(SOFT, young_modulus=e))
        rest = m.rest_surface()
        m.set_constraints(fixed=[3, 39, 64], prescribed=[120], positions=rest[[120]] + [0.0, -0.005, 0.0])
        m.step(0.01)
        rf, rp = m.reactions()
        assert np.abs(rf.sum(axis=0) + rp.sum(axis=0)).max() < 1e-9 * np.abs(rp).max()
        forces.append(rp.sum(axis=0))
    np.testing.assert_allclose(forces[1], 2.0 * forces[0], rtol=1e-10)


def test_every_kind_builds_and_steps_from_python(liver):
    """Every kind the library has, built by name from Python on the liver (or its surface)."""
    names = tissue.kinds()
    assert "fem-static" in names and len(names) >= 15
    centre = liver.vertices.mean(axis=0).tolist()
    tube = tissue.Mesh.tube(0.01, 0.1, 16, 10)
    for kind in names:
        body, params, fixed = liver, None, [3, 39, 64]
        if kind == "spline":  # a spline shell fits a sheet or a tube, not a closed organ
            body, fixed = tube, [0, 1, 2, 3]
        if kind == "hybrid":  # the cut region is the hybrid's one required setting
            params = {"cut_region": {"sphere": {"center": centre, "radius": 0.03}}}
        m = tissue.Model(kind, body, SOFT, params)
        assert m.kind == kind
        pos, tri = m.surface()
        assert len(pos) > 0 and len(tri) > 0
        m.set_constraints(fixed=fixed)
        info = m.step(1e-4)
        assert np.isfinite(m.surface()[0]).all(), kind
        assert info["iterations"] >= 0
