//! `tissue._native`: the library's models, meshes and scenes for Python.
//!
//! Arrays cross as numpy arrays (f64 positions and forces in m and N, u32 indices), settings
//! as dicts with the scene files' key names, failures as `tissue.TissueError` (a
//! `ValueError`) carrying the library's message, which names the file, line, key or element.
//! Stepping releases the GIL, so a Python thread can drive a device or a viewer meanwhile.
//! The Python package `tissue` (python/tissue/) wraps this module; users import that.

mod convert;
mod mesh;
mod model;
mod scene;

use pyo3::prelude::*;

pyo3::create_exception!(
    _native,
    TissueError,
    pyo3::exceptions::PyValueError,
    "A tissue error: bad input (file, mesh, scene, parameter) or a failed step."
);

/// The model kinds built in, as (name, summary) pairs.
#[pyfunction]
fn kinds() -> Vec<(&'static str, &'static str)> {
    tissue::model::KINDS
        .iter()
        .map(|k| (k.name, k.summary))
        .collect()
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("TissueError", m.py().get_type::<TissueError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(kinds, m)?)?;
    mesh::register(m)?;
    model::register(m)?;
    scene::register(m)?;
    Ok(())
}
