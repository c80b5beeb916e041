//! `Mesh`: any supported mesh file read, written, inspected or made from arrays; generators.

use std::path::PathBuf;

use numpy::PyArray2;
use pyo3::prelude::*;

use tissue::mesh::generate::{BoxSplit, MAX_SUBDIVISIONS, box_tets, icosphere, tube};
use tissue::mesh::{MeshData, inspect, split_tets};
use tissue::{Vec3, io};

use crate::convert::{err, index_rows, json_to_py, point, points, points_array, rows_u32};

/// A mesh as a file holds it: vertices (m), triangles and/or tetrahedra, tags, fixed vertices.
#[pyclass(module = "tissue._native")]
#[derive(Clone)]
pub struct Mesh {
    pub data: MeshData,
    /// Where it came from, for messages.
    pub source: String,
}

#[pymethods]
impl Mesh {
    /// A mesh from arrays: `vertices` (n, 3) in m; `triangles` (m, 3) and/or `tets` (k, 4)
    /// vertex indices.
    #[new]
    #[pyo3(signature = (vertices, triangles=None, tets=None))]
    fn new(
        vertices: &Bound<'_, PyAny>,
        triangles: Option<&Bound<'_, PyAny>>,
        tets: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let data = MeshData {
            vertices: points(vertices, "vertices")?,
            triangles: match triangles {
                Some(t) => index_rows::<3>(t, "triangles")?,
                None => Vec::new(),
            },
            tets: match tets {
                Some(t) => index_rows::<4>(t, "tets")?,
                None => Vec::new(),
            },
            ..MeshData::default()
        };
        let n = data.vertices.len();
        let bad = data
            .triangles
            .iter()
            .flatten()
            .chain(data.tets.iter().flatten())
            .find(|&&i| i as usize >= n);
        if let Some(i) = bad {
            return Err(err(format!(
                "an element names vertex {i}, but there are {n} vertices"
            )));
        }
        Ok(Self {
            data,
            source: "mesh from arrays".into(),
        })
    }

    /// Reads any supported format, chosen by the extension.
    #[staticmethod]
    fn read(path: PathBuf) -> PyResult<Self> {
        let data = io::read(&path).map_err(err)?;
        Ok(Self {
            data,
            source: path.display().to_string(),
        })
    }

    /// Writes any writable format, chosen by the extension.
    fn write(&self, path: PathBuf) -> PyResult<()> {
        io::write(&path, &self.data).map_err(err)
    }

    /// Counts, bounds, volume, quality and problems, as `tissue mesh inspect --json` gives.
    fn inspect<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let report = serde_json::to_value(inspect(&self.data)).map_err(err)?;
        json_to_py(py, &report)
    }

    #[getter]
    fn vertices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        points_array(py, &self.data.vertices)
    }

    #[getter]
    fn triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u32>>> {
        rows_u32(py, &self.data.triangles)
    }

    /// Linear tetrahedra (the corners of 10-node ones included).
    #[getter]
    fn tets<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u32>>> {
        let mut tets = self.data.tets.clone();
        tets.extend(self.data.tets10.iter().map(|t| [t[0], t[1], t[2], t[3]]));
        rows_u32(py, &tets)
    }

    /// Vertices the file marks as fixed.
    #[getter]
    fn fixed_vertices(&self) -> Vec<u32> {
        self.data.fixed_vertices.clone()
    }

    /// The surface a user sees: the boundary of the tetrahedra, else the triangles.
    fn surface(&self) -> PyResult<Self> {
        let s = self.data.surface_mesh().map_err(err)?;
        Ok(Self {
            data: MeshData::from_surface(&s),
            source: format!("surface of {}", self.source),
        })
    }

    /// Every tetrahedron split into eight (edge midpoints): the same body, h halved.
    fn refined(&self) -> PyResult<Self> {
        let tets = self.data.tet_mesh(&self.source).map_err(err)?;
        let fine = split_tets(&tets).map_err(err)?;
        Ok(Self {
            data: MeshData::from_tets(&fine),
            source: format!("{} refined", self.source),
        })
    }

    /// A copy with every coordinate multiplied by `factor` (e.g. 0.01 for centimetres).
    fn scaled(&self, factor: f64) -> PyResult<Self> {
        if !(factor.is_finite() && factor > 0.0) {
            return Err(err(format!("scale: {factor} is not a positive number")));
        }
        let mut out = self.clone();
        for v in &mut out.data.vertices {
            *v *= factor;
        }
        Ok(out)
    }

    /// A box of tetrahedra from `min` to `max` with `cells` cells per axis (6 per cell).
    #[staticmethod]
    #[pyo3(signature = (min, max, cells, split = "six"))]
    fn box_tets(min: [f64; 3], max: [f64; 3], cells: [usize; 3], split: &str) -> PyResult<Self> {
        let (lo, hi) = (point(min, "min")?, point(max, "max")?);
        if !(hi - lo).cmpgt(Vec3::ZERO).all() {
            return Err(err(format!(
                "box: max {hi} must exceed min {lo} on every axis"
            )));
        }
        if cells.iter().any(|&c| c == 0 || c > 1000) {
            return Err(err(format!("box: cells {cells:?} must be in 1..=1000")));
        }
        let split = match split {
            "five" => BoxSplit::Five,
            "six" => BoxSplit::Six,
            other => {
                return Err(err(format!(
                    "box: split {other:?} is not \"five\" or \"six\""
                )));
            }
        };
        Ok(Self {
            data: MeshData::from_tets(&box_tets(lo, hi, cells, split)),
            source: "box".into(),
        })
    }

    /// A triangulated sphere (icosahedron subdivided `subdivisions` times).
    #[staticmethod]
    fn sphere(center: [f64; 3], radius: f64, subdivisions: u32) -> PyResult<Self> {
        if !(radius.is_finite() && radius > 0.0) || subdivisions > MAX_SUBDIVISIONS {
            return Err(err(format!(
                "sphere: radius {radius} must be positive and subdivisions {subdivisions} at most {MAX_SUBDIVISIONS}"
            )));
        }
        let s = icosphere(point(center, "center")?, radius, subdivisions);
        Ok(Self {
            data: MeshData::from_surface(&s),
            source: "sphere".into(),
        })
    }

    /// An open tube along z (a vessel or bowel segment): `segments` around, `rings` along.
    #[staticmethod]
    fn tube(radius: f64, length: f64, segments: usize, rings: usize) -> PyResult<Self> {
        let ok = |x: f64| x.is_finite() && x > 0.0;
        if !ok(radius)
            || !ok(length)
            || !(3..=4096).contains(&segments)
            || !(1..=4096).contains(&rings)
        {
            return Err(err(format!(
                "tube: radius {radius} and length {length} must be positive, segments {segments} \
                 in 3..=4096 and rings {rings} in 1..=4096"
            )));
        }
        Ok(Self {
            data: MeshData::from_surface(&tube(radius, length, segments, rings)),
            source: "tube".into(),
        })
    }

    fn __repr__(&self) -> String {
        let d = &self.data;
        format!(
            "Mesh({} vertices, {} triangles, {} tetrahedra, from {})",
            d.vertices.len(),
            d.triangles.len(),
            d.tets.len() + d.tets10.len(),
            self.source
        )
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Mesh>()
}
