"""Arrays in and out: meshes round-trip through files and arrays exactly."""

import numpy as np
import pytest

import tissue


def test_box_round_trips_through_every_volume_format(tmp_path):
    box = tissue.Mesh.box_tets([0.0, 0.0, 0.0], [0.04, 0.02, 0.01], [4, 2, 1])
    v, t = box.vertices, box.tets
    assert v.shape == (15 * 2, 3) and v.dtype == np.float64
    assert t.shape == (8 * 6, 4) and t.dtype == np.uint32
    for ext in ("msh", "vtu", "vtk", "mesh"):
        path = tmp_path / f"box.{ext}"
        box.write(path)
        back = tissue.Mesh.read(path)
        np.testing.assert_array_equal(back.tets, t)
        np.testing.assert_allclose(back.vertices, v, rtol=0, atol=1e-15)


def test_mesh_from_arrays_equals_the_mesh_it_came_from(liver):
    again = tissue.Mesh(liver.vertices, tets=liver.tets.astype(np.int64))
    np.testing.assert_array_equal(again.vertices, liver.vertices)
    np.testing.assert_array_equal(again.tets, liver.tets)
    report = again.inspect()
    # The liver's volume from the inspection equals the sum of its tetrahedra's volumes.
    p = liver.vertices[liver.tets]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]).sum() / 6
    assert report["volume"] == pytest.approx(vol, rel=1e-12)


def test_refined_mesh_keeps_the_volume_with_eight_times_the_elements(liver):
    fine = liver.refined()
    assert len(fine.tets) == 8 * len(liver.tets)
    assert fine.inspect()["volume"] == pytest.approx(liver.inspect()["volume"], rel=1e-12)


def test_model_arrays_have_the_shapes_the_model_reports(liver):
    m = tissue.Model("fem-static", liver, {"young_modulus": 3000.0, "poisson_ratio": 0.3})
    pos, tri = m.surface()
    info = m.info()
    assert pos.shape == (info["surface_vertices"], 3)
    assert tri.shape[1] == 3 and tri.max() < len(pos)
    np.testing.assert_array_equal(m.rest_surface(), pos)
    vol = m.volume()
    assert vol is not None
    now, rest, tets = vol
    assert tets.shape == (info["elements"], 4)
    np.testing.assert_array_equal(now, rest)
