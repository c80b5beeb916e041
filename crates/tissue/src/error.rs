//! Typed errors. Each names the place: the file and line, the element, the vertex, the key.
//!
//! Numerical failure (`SimError`) is kept apart from bad input (`IoError`, `MeshError`,
//! `MaterialError`, `SceneError`); `Error` gathers them for callers that handle all at once.

use std::fmt;
use std::path::PathBuf;

use thiserror::Error;

use crate::math::Real;

/// Where in a file a problem was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// The file as a whole (it could not be opened, or it is empty).
    File,
    /// A 1-based line of a text file.
    Line(usize),
    /// A byte offset into a binary file or section.
    Byte(u64),
    /// A 0-based element (triangle, tetrahedron, cell) of the file.
    Element(usize),
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::File => Ok(()),
            Location::Line(l) => write!(f, ":{l}"),
            Location::Byte(b) => write!(f, ": byte {b}"),
            Location::Element(e) => write!(f, ": element {e}"),
        }
    }
}

/// A file that could not be read or written, with the place and the reason.
#[derive(Debug, Error)]
#[error("{}{location}: {message}", path.display())]
pub struct IoError {
    pub path: PathBuf,
    pub location: Location,
    pub message: String,
    #[source]
    pub source: Option<std::io::Error>,
}

impl IoError {
    pub fn new(path: impl Into<PathBuf>, location: Location, message: impl Into<String>) -> Self {
        Self {
            path: path.into(),
            location,
            message: message.into(),
            source: None,
        }
    }

    /// Wraps an operating-system error (missing file, permission, disk full).
    pub fn os(path: impl Into<PathBuf>, action: &str, source: std::io::Error) -> Self {
        let message = format!("cannot {action}: {source}");
        Self {
            path: path.into(),
            location: Location::File,
            message,
            source: Some(source),
        }
    }
}

/// A mesh that cannot be used as asked, naming the offending element or vertex.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MeshError {
    #[error("the mesh has no {what}")]
    Empty { what: &'static str },
    #[error(
        "{element_kind} {element} refers to vertex {index}, but the mesh has {vertex_count} vertices"
    )]
    IndexOutOfRange {
        element_kind: &'static str,
        element: usize,
        index: usize,
        vertex_count: usize,
    },
    #[error("vertex {vertex} has a non-finite coordinate ({x}, {y}, {z})")]
    NonFiniteVertex {
        vertex: usize,
        x: Real,
        y: Real,
        z: Real,
    },
    #[error("tetrahedron {tet} is inverted (signed volume {volume:.3e})")]
    InvertedTet { tet: usize, volume: Real },
    #[error("tetrahedron {tet} is degenerate (volume {volume:.3e}, quality {quality:.2e})")]
    DegenerateTet {
        tet: usize,
        volume: Real,
        quality: Real,
    },
    #[error("triangle {triangle} is degenerate (area {area:.3e})")]
    DegenerateTriangle { triangle: usize, area: Real },
    #[error("{element_kind} {element} repeats vertex {vertex}")]
    RepeatedVertex {
        element_kind: &'static str,
        element: usize,
        vertex: usize,
    },
    #[error("this model needs a tetrahedral volume mesh, but {source_desc} has only a surface")]
    NeedsVolume { source_desc: String },
    #[error("the surface is not closed: {border_edges} border edges, e.g. ({a}, {b})")]
    NotClosed {
        border_edges: usize,
        a: usize,
        b: usize,
    },
    #[error("edge ({a}, {b}) is shared by {faces} faces (non-manifold)")]
    NonManifoldEdge { a: usize, b: usize, faces: usize },
    #[error("{0}")]
    Invalid(String),
}

/// A material constant outside its physical range.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MaterialError {
    #[error("material {name} = {value}: {reason}")]
    OutOfRange {
        name: &'static str,
        value: Real,
        reason: &'static str,
    },
    /// A per-region material (scene `[material.regions.<name>]`) the mesh cannot carry.
    #[error("material region {region}: {reason}")]
    Region { region: String, reason: String },
}

/// A failure while building or stepping a model.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SimError {
    /// The model refuses the operation (e.g. a pre-computed model asked to cut).
    #[error("model `{model}` does not support {operation}: {reason}")]
    Unsupported {
        model: &'static str,
        operation: &'static str,
        reason: String,
    },
    /// The state became non-finite or blew up; the model kept its last good state.
    #[error("step {step} diverged at node {node}: {reason}; the last good state was kept")]
    Diverged {
        step: u64,
        node: usize,
        reason: String,
    },
    /// A step ended in a state no tissue reaches (`interact::plausibility`): it was not
    /// accepted, and time, instruments and outputs stay at the last plausible step.
    #[error(
        "step {step}: {quantity} is {value:.3e}, beyond the plausible {bound:.3e} ({reason}); \
         stopped at the last plausible step (a diverged solve: lower dt, raise damping or \
         check the material)"
    )]
    Implausible {
        step: u64,
        quantity: String,
        value: Real,
        bound: Real,
        reason: String,
    },
    /// A matrix that must be symmetric positive definite is not (e.g. a body left free to move).
    #[error("the system matrix is not positive definite near row {row}: {hint}")]
    NotPositiveDefinite { row: usize, hint: String },
    /// A constraint names a vertex that does not exist.
    #[error("constraint on surface vertex {vertex}, but the surface has {count} vertices")]
    BadConstraint { vertex: usize, count: usize },
    /// A time step that is not a finite positive number.
    #[error("time step {dt} s is not a finite positive number")]
    BadTimeStep { dt: Real },
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error(transparent)]
    Material(#[from] MaterialError),
    #[error("unknown model kind `{kind}`; built in: {known}")]
    UnknownModel { kind: String, known: String },
    #[error("invalid parameter `{name}` = {value}: {reason}")]
    BadParameter {
        name: &'static str,
        value: String,
        reason: String,
    },
}

/// A scene file that cannot be turned into a simulation.
#[derive(Debug, Error)]
pub enum SceneError {
    #[error("{}: {message}", path.display())]
    Invalid { path: PathBuf, message: String },
    #[error(transparent)]
    Io(#[from] IoError),
}

/// Any error of the library.
#[derive(Debug, Error)]
pub enum Error {
    #[error(transparent)]
    Io(#[from] IoError),
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error(transparent)]
    Material(#[from] MaterialError),
    #[error(transparent)]
    Sim(#[from] SimError),
    #[error(transparent)]
    Scene(#[from] SceneError),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn io_error_names_file_and_line() {
        let e = IoError::new(
            "liver.msh",
            Location::Line(12),
            "expected 4 node ids, found 3",
        );
        assert_eq!(e.to_string(), "liver.msh:12: expected 4 node ids, found 3");
    }
}
