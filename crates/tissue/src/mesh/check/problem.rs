//! The problems `check` reports, their messages, and the collector that bounds how many
//! of each kind are kept.

use std::fmt;

use serde::Serialize;

use super::MAX_PER_KIND;
use crate::math::Real;

/// One thing wrong with a mesh. Element indices are 0-based; in a `MeshData` with both kinds
/// of tetrahedra the linear ones are numbered first, then the 10-node ones.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Problem {
    NonFiniteVertex {
        vertex: usize,
    },
    /// A coordinate so large (beyond `MAX_COORDINATE`) that areas, volumes and distances
    /// through the vertex overflow: a corrupt file, not an organ.
    FarVertex {
        vertex: usize,
        coordinate: Real,
    },
    IndexOutOfRange {
        element_kind: &'static str,
        element: usize,
        index: usize,
        vertex_count: usize,
    },
    InvertedTet {
        tet: usize,
        volume: Real,
    },
    /// Flat or nearly flat (|quality| < 1e-3), or repeating a corner.
    DegenerateTet {
        tet: usize,
        volume: Real,
        quality: Real,
    },
    /// Zero or nearly zero area, or repeating a corner.
    DegenerateTriangle {
        triangle: usize,
        area: Real,
    },
    /// Same vertex set as an earlier element (whatever the order).
    DuplicateElement {
        element_kind: &'static str,
        element: usize,
        first: usize,
    },
    /// A surface edge used by three or more triangles.
    NonManifoldEdge {
        a: usize,
        b: usize,
        faces: usize,
    },
    /// A triangular face shared by three or more tetrahedra (overlapping elements).
    NonManifoldFace {
        face: [u32; 3],
        tets: usize,
    },
    /// Edges used by one triangle only: the surface has holes.
    BorderEdges {
        count: usize,
        examples: Vec<[u32; 2]>,
    },
    /// Vertices that coincide with an earlier one, as pairs (later, earlier).
    DuplicateVertices {
        count: usize,
        examples: Vec<[u32; 2]>,
    },
    UnusedVertices {
        count: usize,
        examples: Vec<u32>,
    },
    /// Two triangles traverse their shared edge in the same direction.
    InconsistentOrientation {
        triangle_a: usize,
        triangle_b: usize,
        edge: [u32; 2],
    },
    /// A closed, consistently oriented component with negative enclosed volume.
    InwardOrientation {
        component: usize,
        volume: Real,
    },
    MultipleComponents {
        count: usize,
    },
    /// Summary of the entries of one kind left out of the report.
    MoreOfKind {
        problem_kind: &'static str,
        total: usize,
        shown: usize,
    },
}

impl Problem {
    /// The kind's name, as in the JSON `kind` tag.
    pub fn kind(&self) -> &'static str {
        match self {
            Problem::NonFiniteVertex { .. } => "non_finite_vertex",
            Problem::FarVertex { .. } => "far_vertex",
            Problem::IndexOutOfRange { .. } => "index_out_of_range",
            Problem::InvertedTet { .. } => "inverted_tet",
            Problem::DegenerateTet { .. } => "degenerate_tet",
            Problem::DegenerateTriangle { .. } => "degenerate_triangle",
            Problem::DuplicateElement { .. } => "duplicate_element",
            Problem::NonManifoldEdge { .. } => "non_manifold_edge",
            Problem::NonManifoldFace { .. } => "non_manifold_face",
            Problem::BorderEdges { .. } => "border_edges",
            Problem::DuplicateVertices { .. } => "duplicate_vertices",
            Problem::UnusedVertices { .. } => "unused_vertices",
            Problem::InconsistentOrientation { .. } => "inconsistent_orientation",
            Problem::InwardOrientation { .. } => "inward_orientation",
            Problem::MultipleComponents { .. } => "multiple_components",
            Problem::MoreOfKind { .. } => "more_of_kind",
        }
    }
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Problem::NonFiniteVertex { vertex } => {
                write!(f, "vertex {vertex} has a non-finite coordinate")
            }
            Problem::FarVertex { vertex, coordinate } => write!(
                f,
                "vertex {vertex} has the coordinate {coordinate:e}, beyond ±{:e}: \
                 areas and volumes through it overflow",
                super::MAX_COORDINATE
            ),
            Problem::IndexOutOfRange {
                element_kind,
                element,
                index,
                vertex_count,
            } => write!(
                f,
                "{element_kind} {element} refers to vertex {index}, but the mesh has {vertex_count} vertices"
            ),
            Problem::InvertedTet { tet, volume } => {
                write!(
                    f,
                    "tetrahedron {tet} is inverted (signed volume {volume:.3e})"
                )
            }
            Problem::DegenerateTet {
                tet,
                volume,
                quality,
            } => write!(
                f,
                "tetrahedron {tet} is degenerate (volume {volume:.3e}, quality {quality:.2e})"
            ),
            Problem::DegenerateTriangle { triangle, area } => {
                write!(f, "triangle {triangle} is degenerate (area {area:.3e})")
            }
            Problem::DuplicateElement {
                element_kind,
                element,
                first,
            } => write!(
                f,
                "{element_kind} {element} has the same vertices as {element_kind} {first}"
            ),
            Problem::NonManifoldEdge { a, b, faces } => {
                write!(
                    f,
                    "edge ({a}, {b}) is shared by {faces} triangles (non-manifold)"
                )
            }
            Problem::NonManifoldFace { face, tets } => write!(
                f,
                "face ({}, {}, {}) is shared by {tets} tetrahedra (overlapping elements)",
                face[0], face[1], face[2]
            ),
            Problem::BorderEdges { count, examples } => {
                write!(f, "the surface has holes: {count} border edges")?;
                write_examples(f, examples.iter().map(|[a, b]| format!("({a}, {b})")))
            }
            Problem::DuplicateVertices { count, examples } => {
                write!(f, "{count} vertices coincide with an earlier vertex")?;
                write_examples(f, examples.iter().map(|[a, b]| format!("{a} = {b}")))
            }
            Problem::UnusedVertices { count, examples } => {
                write!(f, "{count} vertices are used by no element")?;
                write_examples(f, examples.iter().map(|v| v.to_string()))
            }
            Problem::InconsistentOrientation {
                triangle_a,
                triangle_b,
                edge,
            } => write!(
                f,
                "triangles {triangle_a} and {triangle_b} traverse their shared edge ({}, {}) in the same direction (inconsistent orientation)",
                edge[0], edge[1]
            ),
            Problem::InwardOrientation { component, volume } => write!(
                f,
                "closed component {component} is oriented inward (signed volume {volume:.3e})"
            ),
            Problem::MultipleComponents { count } => {
                write!(f, "the mesh has {count} connected components")
            }
            Problem::MoreOfKind {
                problem_kind,
                total,
                shown,
            } => write!(
                f,
                "... and {} more {problem_kind} problems ({total} in all)",
                total.saturating_sub(*shown)
            ),
        }
    }
}

fn write_examples(
    f: &mut fmt::Formatter<'_>,
    examples: impl Iterator<Item = String>,
) -> fmt::Result {
    let list: Vec<String> = examples.collect();
    if list.is_empty() {
        Ok(())
    } else {
        write!(f, ", e.g. {}", list.join(", "))
    }
}

/// Gathers problems, keeping at most `MAX_PER_KIND` of each kind.
#[derive(Default)]
pub(super) struct Collector {
    out: Vec<Problem>,
    totals: Vec<(&'static str, usize)>,
}

impl Collector {
    pub(super) fn push(&mut self, p: Problem) {
        let kind = p.kind();
        if self.count_only(kind, 1) <= MAX_PER_KIND {
            self.out.push(p);
        }
    }

    /// Counts `n` problems of a kind; returns the new total.
    fn count_only(&mut self, kind: &'static str, n: usize) -> usize {
        match self.totals.iter_mut().find(|(k, _)| *k == kind) {
            Some((_, total)) => {
                *total += n;
                *total
            }
            None => {
                self.totals.push((kind, n));
                n
            }
        }
    }

    /// The problems, each truncated kind followed (after its last entry) by its summary.
    pub(super) fn finish(self) -> Vec<Problem> {
        let mut result = Vec::with_capacity(self.out.len() + 1);
        for (i, p) in self.out.iter().enumerate() {
            let kind = p.kind();
            result.push(p.clone());
            let last_of_kind = !self.out[i + 1..].iter().any(|q| q.kind() == kind);
            let total = self.totals.iter().find(|(k, _)| *k == kind).map(|x| x.1);
            if let Some(total) = total.filter(|&t| last_of_kind && t > MAX_PER_KIND) {
                result.push(Problem::MoreOfKind {
                    problem_kind: kind,
                    total,
                    shown: MAX_PER_KIND,
                });
            }
        }
        result
    }
}
