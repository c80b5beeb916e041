//! Mesh checks: everything that makes a mesh unfit for simulation or drawing, each problem
//! naming the element, edge or vertex at fault.
//!
//! Checks never panic, whatever the input (out-of-range indices are reported and the
//! elements left out of the other checks). A broken mesh with a million bad elements gives a
//! bounded report: at most `MAX_PER_KIND` entries per kind, then one `MoreOfKind` entry with
//! the total.

use crate::math::{Real, Vec3, is_finite_vec, tet_signed_volume, triangle_area_vector};
use crate::mesh::quality::{tet_quality, triangle_quality};
use crate::mesh::topology::{coincident_map, components, edge_faces};
use crate::mesh::{MeshData, SurfaceMesh, TET_FACES, TetMesh, boundary_surface};

mod problem;

use problem::Collector;
pub use problem::Problem;

/// Individual entries reported per kind of problem before summarising.
pub const MAX_PER_KIND: usize = 20;
/// Examples carried by a summary problem (border edges, duplicate and unused vertices).
pub const EXAMPLES: usize = 5;
/// A tetrahedron with |quality| below this is degenerate (flat, a sliver or a needle).
pub const DEGENERATE_TET_QUALITY: Real = 1e-3;
/// A triangle with quality below this is degenerate (its corners are nearly collinear).
pub const DEGENERATE_TRIANGLE_QUALITY: Real = 1e-6;
/// Coordinates larger than this in magnitude are reported (`FarVertex`) and left out of the
/// scale of the mesh: a product of three such (a volume) still fits in an f64.
pub const MAX_COORDINATE: Real = 1e100;

/// Whether a vertex is finite and within `MAX_COORDINATE` of the origin on every axis.
pub fn is_usable_vertex(p: Vec3) -> bool {
    is_finite_vec(p) && p.abs().max_element() <= MAX_COORDINATE
}

/// Vertices closer than this fraction of the bounding-box diagonal coincide.
pub const COINCIDENT_TOLERANCE: Real = 1e-9;

/// Problems of a triangle surface, expected closed and outward.
pub fn check_surface(mesh: &SurfaceMesh) -> Vec<Problem> {
    check_parts(&mesh.vertices, &mesh.triangles, &[], &[])
}

/// Problems of a tetrahedral mesh: its elements, then its boundary surface.
pub fn check_tets(mesh: &TetMesh) -> Vec<Problem> {
    check_parts(&mesh.vertices, &[], &mesh.tets, &[])
}

/// Problems of a loaded mesh. With a volume, the triangles (if any) are a patch of skin and
/// need not be closed; without one, the triangles are the surface and must be.
pub fn check(mesh: &MeshData) -> Vec<Problem> {
    check_parts(&mesh.vertices, &mesh.triangles, &mesh.tets, &mesh.tets10)
}

fn check_parts(
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    tets: &[[u32; 4]],
    tets10: &[[u32; 10]],
) -> Vec<Problem> {
    let mut c = Collector::default();
    for (v, p) in vertices.iter().enumerate() {
        if !is_finite_vec(*p) {
            c.push(Problem::NonFiniteVertex { vertex: v });
        } else if !is_usable_vertex(*p) {
            c.push(Problem::FarVertex {
                vertex: v,
                coordinate: p
                    .to_array()
                    .into_iter()
                    .fold(0.0, |m: Real, x| if x.abs() > m.abs() { x } else { m }),
            });
        }
    }
    let n = vertices.len();
    let tris = valid_elements("triangle", triangles, n, 0, &mut c);
    let mut all_tets = valid_elements("tetrahedron", tets, n, 0, &mut c);
    let quadratic = valid_elements("10-node tetrahedron", tets10, n, tets.len(), &mut c);
    all_tets.extend(
        quadratic
            .iter()
            .map(|&(i, t)| (i, [t[0], t[1], t[2], t[3]])),
    );
    let volume = !tets.is_empty() || !tets10.is_empty();
    if volume {
        tet_problems(vertices, &all_tets, &mut c);
    }
    if !tris.is_empty() || !volume {
        triangle_problems(vertices, &tris, !volume, &mut c);
    }
    duplicate_vertex_problems(vertices, &mut c);
    let mut used = vec![false; n];
    let mark =
        |used: &mut Vec<bool>, ids: &[u32]| ids.iter().for_each(|&i| used[i as usize] = true);
    tris.iter().for_each(|(_, t)| mark(&mut used, t));
    all_tets.iter().for_each(|(_, t)| mark(&mut used, t));
    quadratic.iter().for_each(|(_, t)| mark(&mut used, t));
    let unused: Vec<u32> = (0..n as u32).filter(|&v| !used[v as usize]).collect();
    if !unused.is_empty() {
        c.push(Problem::UnusedVertices {
            count: unused.len(),
            examples: unused.iter().take(EXAMPLES).copied().collect(),
        });
    }
    c.finish()
}

/// Elements whose indices all name a vertex, with their index (`offset` added); the others
/// are reported and left out of every further check.
fn valid_elements<const N: usize>(
    kind: &'static str,
    elements: &[[u32; N]],
    vertex_count: usize,
    offset: usize,
    c: &mut Collector,
) -> Vec<(usize, [u32; N])> {
    let mut out = Vec::with_capacity(elements.len());
    for (e, el) in elements.iter().enumerate() {
        match el.iter().find(|&&i| i as usize >= vertex_count) {
            Some(&i) => c.push(Problem::IndexOutOfRange {
                element_kind: kind,
                element: e + offset,
                index: i as usize,
                vertex_count,
            }),
            None => out.push((e + offset, *el)),
        }
    }
    out
}

fn has_repeat<const N: usize>(el: &[u32; N]) -> bool {
    (1..N).any(|k| el[..k].contains(&el[k]))
}

fn tet_problems(vertices: &[Vec3], tets: &[(usize, [u32; 4])], c: &mut Collector) {
    let p = |i: u32| vertices[i as usize];
    for &(t, el @ [a, b, cc, d]) in tets {
        let (a, b, cc, d) = (p(a), p(b), p(cc), p(d));
        if ![a, b, cc, d].into_iter().all(is_usable_vertex) {
            continue; // its vertex is the problem, already reported
        }
        let volume = tet_signed_volume(a, b, cc, d);
        let quality = tet_quality(a, b, cc, d);
        if has_repeat(&el) || volume == 0.0 || quality.abs() < DEGENERATE_TET_QUALITY {
            c.push(Problem::DegenerateTet {
                tet: t,
                volume,
                quality,
            });
        } else if volume < 0.0 {
            c.push(Problem::InvertedTet { tet: t, volume });
        }
    }
    duplicate_problems("tetrahedron", tets, c);

    let mut faces: Vec<[u32; 3]> = tets
        .iter()
        .flat_map(|(_, t)| TET_FACES.map(|f| sorted3([t[f[0]], t[f[1]], t[f[2]]])))
        .collect();
    faces.sort_unstable();
    for group in faces.chunk_by(|x, y| x == y).filter(|g| g.len() > 2) {
        c.push(Problem::NonManifoldFace {
            face: group[0],
            tets: group.len(),
        });
    }

    let plain: Vec<[u32; 4]> = tets.iter().map(|&(_, t)| t).collect();
    let comps = components(&plain);
    if comps.count > 1 {
        c.push(Problem::MultipleComponents { count: comps.count });
    }
    // The boundary, in the mesh's own vertex numbers. It is outward by construction, so only
    // its manifoldness and closedness say something about the volume.
    let b = boundary_surface(&TetMesh::new(vertices.to_vec(), plain));
    let surface: Vec<[u32; 3]> = b
        .surface
        .triangles
        .iter()
        .map(|t| t.map(|v| b.nodes[v as usize]))
        .collect();
    edge_problems(&surface, false, c);
}

fn triangle_problems(
    vertices: &[Vec3],
    tris: &[(usize, [u32; 3])],
    standalone: bool,
    c: &mut Collector,
) {
    let p = |i: u32| vertices[i as usize];
    let mut proper = Vec::with_capacity(tris.len());
    let mut ids = Vec::with_capacity(tris.len());
    for &(t, el @ [a, b, cc]) in tris {
        let (a, b, cc) = (p(a), p(b), p(cc));
        let usable = [a, b, cc].into_iter().all(is_usable_vertex);
        if usable && (has_repeat(&el) || triangle_quality(a, b, cc) < DEGENERATE_TRIANGLE_QUALITY) {
            let area = triangle_area_vector(a, b, cc).length();
            c.push(Problem::DegenerateTriangle { triangle: t, area });
        }
        // Collapsed triangles have no proper edges to judge the surface by.
        if !has_repeat(&el) {
            proper.push(el);
            ids.push(t);
        }
    }
    duplicate_problems("triangle", tris, c);
    let orientation = edge_problems(&proper, standalone, c);
    for (&(a, b), &edge) in orientation
        .inconsistent
        .iter()
        .zip(&orientation.inconsistent_edges)
    {
        c.push(Problem::InconsistentOrientation {
            triangle_a: ids[a as usize],
            triangle_b: ids[b as usize],
            edge,
        });
    }
    if !standalone {
        return;
    }
    let comps = components(&proper);
    if comps.count > 1 {
        c.push(Problem::MultipleComponents { count: comps.count });
    }
    // A component is judged inward only when it is closed, manifold and consistent:
    // otherwise its signed volume means nothing.
    let mut usable = vec![true; comps.count];
    for &f in &orientation.bad_faces {
        usable[comps.of_element[f as usize] as usize] = false;
    }
    let mut volume = vec![0.0; comps.count];
    for (f, &[a, b, cc]) in proper.iter().enumerate() {
        volume[comps.of_element[f] as usize] += p(a).dot(p(b).cross(p(cc))) / 6.0;
    }
    for (k, (&ok, &v)) in usable.iter().zip(&volume).enumerate() {
        if ok && v < 0.0 {
            c.push(Problem::InwardOrientation {
                component: k,
                volume: v,
            });
        }
    }
}

/// Edge-based findings the caller turns into problems.
#[derive(Default)]
struct EdgeFindings {
    /// Pairs of faces (indices into the given triangles) with the same direction on an edge.
    inconsistent: Vec<(u32, u32)>,
    inconsistent_edges: Vec<[u32; 2]>,
    /// Faces touching a border, non-manifold or inconsistent edge.
    bad_faces: Vec<u32>,
}

/// Non-manifold edges and (when `closed` is expected) border edges are reported here; the
/// orientation findings are returned.
fn edge_problems(triangles: &[[u32; 3]], closed: bool, c: &mut Collector) -> EdgeFindings {
    let ef = edge_faces(triangles);
    let mut out = EdgeFindings::default();
    let mut border = 0usize;
    let mut examples = Vec::new();
    for (e, faces) in ef.with_face_count(|_| true) {
        match faces {
            [f] => {
                border += 1;
                if examples.len() < EXAMPLES {
                    examples.push(e);
                }
                out.bad_faces.push(*f);
            }
            [f, g] => {
                let tf = triangles[*f as usize];
                let tg = triangles[*g as usize];
                if traverses(tf, e) == traverses(tg, e) {
                    out.inconsistent.push((*f, *g));
                    out.inconsistent_edges.push(e);
                    out.bad_faces.extend([*f, *g]);
                }
            }
            _ => {
                c.push(Problem::NonManifoldEdge {
                    a: e[0] as usize,
                    b: e[1] as usize,
                    faces: faces.len(),
                });
                out.bad_faces.extend_from_slice(faces);
            }
        }
    }
    if closed && border > 0 {
        c.push(Problem::BorderEdges {
            count: border,
            examples,
        });
    }
    out
}

/// True when the triangle goes from `e[0]` to `e[1]` (rather than back).
pub(crate) fn traverses([a, b, c]: [u32; 3], e: [u32; 2]) -> bool {
    (a, b) == (e[0], e[1]) || (b, c) == (e[0], e[1]) || (c, a) == (e[0], e[1])
}

fn duplicate_problems<const N: usize>(
    kind: &'static str,
    elements: &[(usize, [u32; N])],
    c: &mut Collector,
) {
    let mut keys: Vec<([u32; N], usize)> = elements
        .iter()
        .map(|&(i, mut e)| {
            e.sort_unstable();
            (e, i)
        })
        .collect();
    keys.sort_unstable();
    for group in keys.chunk_by(|x, y| x.0 == y.0) {
        for &(_, e) in &group[1..] {
            c.push(Problem::DuplicateElement {
                element_kind: kind,
                element: e,
                first: group[0].1,
            });
        }
    }
}

fn duplicate_vertex_problems(vertices: &[Vec3], c: &mut Collector) {
    let map = coincident_map(vertices, COINCIDENT_TOLERANCE * finite_diagonal(vertices));
    let pairs: Vec<[u32; 2]> = map
        .iter()
        .enumerate()
        .filter(|&(v, &r)| v as u32 != r)
        .map(|(v, &r)| [v as u32, r])
        .collect();
    if !pairs.is_empty() {
        c.push(Problem::DuplicateVertices {
            count: pairs.len(),
            examples: pairs.iter().take(EXAMPLES).copied().collect(),
        });
    }
}

/// Bounding-box diagonal over the usable vertices (finite, within `MAX_COORDINATE`; 0 if
/// none): one vertex at 1e308 would otherwise make every other vertex "coincide".
pub(crate) fn finite_diagonal(vertices: &[Vec3]) -> Real {
    let mut it = vertices.iter().copied().filter(|p| is_usable_vertex(*p));
    let Some(first) = it.next() else { return 0.0 };
    let (lo, hi) = it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p)));
    let d = (hi - lo).length();
    if d.is_finite() { d } else { Real::MAX }
}

pub(crate) fn sorted3(mut f: [u32; 3]) -> [u32; 3] {
    f.sort_unstable();
    f
}

#[cfg(test)]
mod tests;
