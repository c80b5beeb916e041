//! `Model`: any kind built by name from a mesh, a material and the scene's `[model]` keys;
//! constraints, loads, steps, cuts, reactions and the surface and volume as arrays.

use std::sync::{Mutex, MutexGuard};

use numpy::PyArray2;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use serde::de::Deserialize as _;

use tissue::interact::{Constraints, Loads, Prescribed};
use tissue::model::{BuildInput, CutPath, Deformable, StepInfo, build};
use tissue::{Material, Vec3};

use crate::convert::{Points, Rows, err, indices, point, points, points_array, rows_u32, table};
use crate::mesh::Mesh;

/// A deformable model of one kind (see `tissue.kinds()`).
#[pyclass(module = "tissue._native")]
pub struct Model {
    /// Stepping happens without the GIL; the lock keeps other Python threads out meanwhile.
    inner: Mutex<Box<dyn Deformable>>,
}

impl Model {
    pub fn lock(&self) -> PyResult<MutexGuard<'_, Box<dyn Deformable>>> {
        self.inner
            .lock()
            .map_err(|_| err("the model was poisoned by a panic in another thread"))
    }
}

/// A material from a dict with the scene's `[material]` keys (young_modulus, poisson_ratio,
/// density, damping, stiffness_damping).
pub fn material(dict: Option<&Bound<'_, PyDict>>) -> PyResult<Material> {
    let t = table(dict, "material")?;
    let m = Material::deserialize(toml::Value::Table(t))
        .map_err(|e| err(format!("material: {}", e.to_string().trim())))?;
    m.validated().map_err(err)
}

fn step_dict<'py>(py: Python<'py>, info: &StepInfo) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("iterations", info.iterations)?;
    d.set_item("residual", info.residual)?;
    d.set_item("capped", info.capped)?;
    d.set_item("substeps", info.substeps)?;
    Ok(d)
}

pub fn info_dict<'py>(py: Python<'py>, model: &dyn Deformable) -> PyResult<Bound<'py, PyDict>> {
    let i = model.info();
    let d = PyDict::new(py);
    d.set_item("kind", i.kind)?;
    d.set_item("nodes", i.nodes)?;
    d.set_item("dofs", i.dofs)?;
    d.set_item("elements", i.elements)?;
    d.set_item("surface_vertices", i.surface_vertices)?;
    d.set_item("memory_bytes", i.memory_bytes)?;
    d.set_item("precompute_seconds", i.precompute_seconds)?;
    d.set_item("is_static", i.is_static)?;
    let details = PyDict::new(py);
    for (k, v) in &i.details {
        details.set_item(k, v)?;
    }
    d.set_item("details", details)?;
    Ok(d)
}

#[pymethods]
impl Model {
    /// Builds `kind` from `mesh` with `material` (dict of `[material]` keys; E and ν at
    /// least) and `params` (the scene's `[model]` keys without `kind`). Long builds (bem,
    /// the condensed kinds) run without the GIL.
    #[new]
    #[pyo3(signature = (kind, mesh, material, params=None))]
    fn new(
        py: Python<'_>,
        kind: &str,
        mesh: &Mesh,
        material: Option<&Bound<'_, PyDict>>,
        params: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let material = self::material(material)?;
        let params = table(params, "params")?;
        let model = py
            .detach(|| {
                build(
                    kind,
                    &BuildInput {
                        mesh: &mesh.data,
                        source: &mesh.source,
                        material,
                        params: &params,
                        regions: &[],
                    },
                )
            })
            .map_err(err)?;
        Ok(Self {
            inner: Mutex::new(model),
        })
    }

    #[getter]
    fn kind(&self) -> PyResult<&'static str> {
        Ok(self.lock()?.kind())
    }

    /// Replaces the constraints: `fixed` surface vertices held at rest, and `prescribed`
    /// vertices moved to `positions` (one row each, in m). Fixed wins where both name one.
    #[pyo3(signature = (fixed=None, prescribed=None, positions=None))]
    fn set_constraints(
        &self,
        fixed: Option<&Bound<'_, PyAny>>,
        prescribed: Option<&Bound<'_, PyAny>>,
        positions: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let fixed = match fixed {
            Some(f) => indices(f, "fixed")?,
            None => Vec::new(),
        };
        let vertices = match prescribed {
            Some(p) => indices(p, "prescribed")?,
            None => Vec::new(),
        };
        let targets = match positions {
            Some(p) => points(p, "positions")?,
            None => Vec::new(),
        };
        if vertices.len() != targets.len() {
            return Err(err(format!(
                "set_constraints: {} prescribed vertices but {} positions",
                vertices.len(),
                targets.len()
            )));
        }
        let c = Constraints {
            fixed,
            prescribed: vertices
                .into_iter()
                .zip(targets)
                .map(|(vertex, position)| Prescribed { vertex, position })
                .collect(),
        };
        self.lock()?.set_constraints(&c).map_err(err)
    }

    /// Replaces the loads: `gravity` (m/s²) and point loads on surface vertices (N).
    #[pyo3(signature = (gravity=None, vertices=None, forces=None))]
    fn set_loads(
        &self,
        gravity: Option<[f64; 3]>,
        vertices: Option<&Bound<'_, PyAny>>,
        forces: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let gravity = match gravity {
            Some(g) => point(g, "gravity")?,
            None => Vec3::ZERO,
        };
        let vertices = match vertices {
            Some(v) => indices(v, "vertices")?,
            None => Vec::new(),
        };
        let forces = match forces {
            Some(f) => points(f, "forces")?,
            None => Vec::new(),
        };
        if vertices.len() != forces.len() {
            return Err(err(format!(
                "set_loads: {} vertices but {} forces",
                vertices.len(),
                forces.len()
            )));
        }
        let loads = Loads {
            gravity,
            point_loads: vertices.into_iter().zip(forces).collect(),
        };
        self.lock()?.set_loads(&loads).map_err(err)
    }

    /// Advances by `dt` s (dynamic kinds) or solves for equilibrium (static kinds), without
    /// the GIL. Returns the step's iterations, residual, capped flag and substeps. On failure
    /// the model keeps its last good state and a TissueError says why.
    fn step<'py>(&self, py: Python<'py>, dt: f64) -> PyResult<Bound<'py, PyDict>> {
        // The lock is taken without the GIL, so a thread holding it can finish.
        let info = py.detach(|| self.lock()?.step(dt).map_err(err))?;
        step_dict(py, &info)
    }

    /// Cuts along a scalpel sweep: the blade (tip, heel) at the start and at the end.
    fn cut<'py>(
        &self,
        py: Python<'py>,
        start: [[f64; 3]; 2],
        end: [[f64; 3]; 2],
    ) -> PyResult<Bound<'py, PyDict>> {
        let blade = CutPath {
            start: start.map(Vec3::from_array),
            end: end.map(Vec3::from_array),
        };
        let info = py.detach(|| self.lock()?.cut(&blade).map_err(err))?;
        let d = PyDict::new(py);
        d.set_item("removed_elements", info.removed_elements)?;
        d.set_item("added_vertices", info.added_vertices)?;
        d.set_item("topology_version", info.topology_version)?;
        Ok(d)
    }

    /// Forces the tissue exerts on its constraints (N): (fixed, prescribed), one row per
    /// constrained vertex in the order given.
    fn reactions<'py>(&self, py: Python<'py>) -> PyResult<(Points<'py>, Points<'py>)> {
        let model = self.lock()?;
        let r = model.reactions();
        Ok((points_array(py, r.fixed)?, points_array(py, r.prescribed)?))
    }

    /// The surface now: (positions (n, 3), triangles (m, 3)).
    fn surface<'py>(&self, py: Python<'py>) -> PyResult<(Points<'py>, Rows<'py>)> {
        let model = self.lock()?;
        let s = model.surface();
        Ok((points_array(py, s.positions)?, rows_u32(py, s.triangles)?))
    }

    /// The surface's rest positions (n, 3).
    fn rest_surface<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        points_array(py, self.lock()?.rest_surface())
    }

    /// The volume mesh now, for kinds with tetrahedra: (positions, rest positions, tets), or
    /// None.
    #[allow(clippy::type_complexity)]
    fn volume<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<
        Option<(
            Bound<'py, PyArray2<f64>>,
            Bound<'py, PyArray2<f64>>,
            Bound<'py, PyArray2<u32>>,
        )>,
    > {
        let model = self.lock()?;
        model
            .volume()
            .map(|v| {
                Ok((
                    points_array(py, v.positions)?,
                    points_array(py, v.rest_positions)?,
                    rows_u32(py, v.tets)?,
                ))
            })
            .transpose()
    }

    /// Back to the rest state, keeping constraints and loads.
    fn reset(&self) -> PyResult<()> {
        self.lock()?.reset();
        Ok(())
    }

    /// What the model is: kind, nodes, dofs, elements, memory, build time, details.
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        info_dict(py, self.lock()?.as_ref())
    }

    fn __repr__(&self) -> String {
        match self.lock() {
            Ok(m) => {
                let i = m.info();
                format!(
                    "Model({}, {} nodes, {} elements)",
                    i.kind, i.nodes, i.elements
                )
            }
            Err(_) => "Model(<poisoned>)".into(),
        }
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Model>()
}
