"""Bad input raises tissue.TissueError with the library's message, never crashes."""

import numpy as np
import pytest

import tissue


def test_missing_file_names_the_file(tmp_path):
    with pytest.raises(tissue.TissueError, match="nope.msh"):
        tissue.Mesh.read(tmp_path / "nope.msh")


def test_unknown_kind_lists_the_known_ones(liver):
    with pytest.raises(tissue.TissueError, match="fem-static"):
        tissue.Model("fem-magic", liver, {"young_modulus": 1e3, "poisson_ratio": 0.3})


def test_unknown_model_key_is_named(liver):
    with pytest.raises(tissue.TissueError, match="cg_iteratons"):
        tissue.Model("fem-corotational", liver, {"young_modulus": 1e3, "poisson_ratio": 0.3}, {"cg_iteratons": 5})


def test_bad_material_is_refused(liver):
    with pytest.raises(tissue.TissueError, match="poisson"):
        tissue.Model("fem-static", liver, {"young_modulus": 1e3, "poisson_ratio": 0.7})


def test_bad_arrays_are_refused(liver):
    with pytest.raises(tissue.TissueError, match=r"\(n, 3\)"):
        tissue.Mesh(np.zeros((4, 2)))
    with pytest.raises(tissue.TissueError, match="not finite"):
        tissue.Mesh(np.array([[0.0, 0.0, np.nan]]))
    with pytest.raises(tissue.TissueError, match="vertex 7"):
        tissue.Mesh(np.zeros((4, 3)), tets=np.array([[0, 1, 2, 7]]))
    m = tissue.Model("fem-static", liver, {"young_modulus": 1e3, "poisson_ratio": 0.3})
    with pytest.raises(tissue.TissueError, match="positions"):
        m.set_constraints(prescribed=[1, 2], positions=np.zeros((1, 3)))


def test_a_failed_step_keeps_the_last_good_state(liver):
    m = tissue.Model("fem-explicit", liver, {"young_modulus": 3e3, "poisson_ratio": 0.3, "density": 1000.0})
    m.set_constraints(fixed=[3, 39, 64])
    with pytest.raises(tissue.TissueError):
        m.step(float("nan"))
    pos, _ = m.surface()
    np.testing.assert_array_equal(pos, m.rest_surface())


def test_bad_scene_names_the_key_and_line(tmp_path):
    text = tissue.Scene.demo_text().replace("dt = ", "dtt = ", 1)
    with pytest.raises(tissue.TissueError, match="dtt"):
        tissue.Scene.from_toml(text, tmp_path)
