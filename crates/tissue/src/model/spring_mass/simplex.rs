//! `simplex-spring-mass`: the T2 (2-simplex) mesh, dual of a closed triangulation (Fig. 2b-c).
//!
//! Node t sits at the centre of triangle t and is linked to the 3 nodes of the triangles
//! across its edges; each vertex v of the triangulation becomes a face of the simplex mesh,
//! the cycle of nodes around v. Counts: nodes = F, links = E, faces = V of the triangulation.
//!
//! Back to triangles (for drawing and for instruments): a vertex is rebuilt from the cycle
//! around it as centre + a t₁ + b t₂ + c n in the cycle's own frame (n its Newell normal,
//! t₁ towards its first node), with (a, b, c) recorded at rest. The round trip is exact at
//! rest and under any rigid motion, and cheap (one pass over the cycles).
//!
//! Springs: a link crossing the primal edge e gets k = k_e (l_e / l_link)², with k_e the
//! membrane stiffness of e (see `stiffness`): the two networks then store the same energy
//! under a uniform dilation. The ratio is capped (`MAX_LENGTH_RATIO_SQUARED`) where a sliver
//! pair of triangles would make a link far stiffer than its neighbours. Masses: ρ t A_T at the node of triangle T.

use std::collections::HashMap;

use crate::error::{Error, MeshError};
use crate::material::Material;
use crate::math::{Real, Vec3, triangle_area_vector};
use crate::mesh::SurfaceMesh;
use crate::mesh::topology::triangle_edges;

use super::body::SpringBody;
use super::pressure::Pressure;
use super::springs::{Spring, SpringNetwork};
use super::stiffness::{edge_index, membrane_stiffness};
use super::surface::checked_compact;
use super::{Kind, SpringModel, SpringParams, SurfaceLink};

/// The largest (l_e / l_link)² a link's stiffness is scaled by: four times its value on
/// equilateral triangles (3). Two near-degenerate triangles sharing a long edge put their
/// centres close together, and the uncapped ratio made that link up to 98 times stiffer than
/// its edge on the shipped liver: it set the stable step, and a probe holding a node next to
/// it read 7-11 N where `fem-static` reads 0.1 N. Capping loses the dilation match of those
/// few links only.
const MAX_LENGTH_RATIO_SQUARED: Real = 12.0;

/// A T2 simplex mesh with its link to the triangulation it is dual to.
#[derive(Clone, Debug, PartialEq)]
pub struct SimplexMesh {
    /// The triangulation: node t is the centre of triangle t.
    triangles: Vec<[u32; 3]>,
    /// Node across edge k of triangle t, edges (t0,t1), (t1,t2), (t2,t0).
    neighbours: Vec<[u32; 3]>,
    /// Per triangulation vertex, the nodes around it, counter-clockwise seen from outside.
    ring_offsets: Vec<usize>,
    ring_nodes: Vec<u32>,
    /// Per vertex, its coordinates in the frame of its ring at rest.
    coefficients: Vec<Vec3>,
}

impl SimplexMesh {
    /// The dual of a closed, oriented, manifold triangulation (every vertex used).
    pub fn from_triangles(s: &SurfaceMesh) -> Result<Self, MeshError> {
        s.validate_indices()?;
        let nv = s.vertices.len();
        let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(3 * s.triangles.len());
        for (t, &[a, b, c]) in s.triangles.iter().enumerate() {
            for (p, q) in [(a, b), (b, c), (c, a)] {
                if directed.insert((p, q), t as u32).is_some() {
                    return Err(MeshError::NonManifoldEdge {
                        a: p as usize,
                        b: q as usize,
                        faces: 3,
                    });
                }
            }
        }
        let mut neighbours = Vec::with_capacity(s.triangles.len());
        for &[a, b, c] in &s.triangles {
            let mut n = [0u32; 3];
            for (k, (p, q)) in [(a, b), (b, c), (c, a)].into_iter().enumerate() {
                n[k] = *directed.get(&(q, p)).ok_or_else(|| MeshError::NotClosed {
                    // Every edge without its reverse, so the message counts them all.
                    border_edges: directed
                        .keys()
                        .filter(|&&(p, q)| !directed.contains_key(&(q, p)))
                        .count(),
                    a: p as usize,
                    b: q as usize,
                })?;
            }
            neighbours.push(n);
        }
        // Rings: from triangle (v, a, b) the next one around v holds the directed edge v→b.
        let mut incident = vec![0usize; nv];
        let mut first = vec![u32::MAX; nv];
        for (t, tri) in s.triangles.iter().enumerate() {
            for &v in tri {
                incident[v as usize] += 1;
                if first[v as usize] == u32::MAX {
                    first[v as usize] = t as u32;
                }
            }
        }
        let mut ring_offsets = vec![0usize];
        let mut ring_nodes = Vec::with_capacity(3 * s.triangles.len());
        for v in 0..nv {
            let start = first[v];
            if start == u32::MAX {
                return Err(MeshError::Invalid(format!("vertex {v} is in no triangle")));
            }
            let mut t = start;
            loop {
                ring_nodes.push(t);
                let tri = s.triangles[t as usize];
                let k = tri.iter().position(|&w| w as usize == v).unwrap_or(0);
                let b = tri[(k + 2) % 3];
                t = directed.get(&(v as u32, b)).copied().unwrap_or(start);
                if t == start || ring_nodes.len() - ring_offsets[v] > incident[v] {
                    break;
                }
            }
            if ring_nodes.len() - ring_offsets[v] != incident[v] {
                return Err(MeshError::Invalid(format!(
                    "vertex {v} is not manifold: its triangles form more than one fan"
                )));
            }
            ring_offsets.push(ring_nodes.len());
        }
        let mut mesh = Self {
            triangles: s.triangles.clone(),
            neighbours,
            ring_offsets,
            ring_nodes,
            coefficients: vec![Vec3::ZERO; nv],
        };
        let centres = mesh.centres(&s.vertices);
        for v in 0..nv {
            if let Some((c, frame)) = mesh.frame(v, &centres) {
                let d = s.vertices[v] - c;
                mesh.coefficients[v] = Vec3::new(d.dot(frame[0]), d.dot(frame[1]), d.dot(frame[2]));
            }
        }
        Ok(mesh)
    }

    pub fn node_count(&self) -> usize {
        self.triangles.len()
    }
    /// Faces of the simplex mesh = vertices of the triangulation.
    pub fn vertex_count(&self) -> usize {
        self.ring_offsets.len() - 1
    }
    /// The triangulation (node t ↔ triangle t), for drawing.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }
    /// The 3 neighbours of each node.
    pub fn neighbours(&self) -> &[[u32; 3]] {
        &self.neighbours
    }
    /// Each link once, (smaller, larger), sorted.
    pub fn links(&self) -> Vec<[u32; 2]> {
        let mut e: Vec<[u32; 2]> = self
            .neighbours
            .iter()
            .enumerate()
            .flat_map(|(t, n)| n.map(|u| [t as u32, u]))
            .filter(|[a, b]| a < b)
            .collect();
        e.sort_unstable();
        e
    }
    /// The nodes around triangulation vertex `v`, counter-clockwise seen from outside.
    pub fn ring(&self, v: usize) -> Option<&[u32]> {
        let (s, e) = (*self.ring_offsets.get(v)?, *self.ring_offsets.get(v + 1)?);
        self.ring_nodes.get(s..e)
    }

    /// Triangle → simplex: the node positions, the centres of the triangles.
    pub fn centres(&self, vertices: &[Vec3]) -> Vec<Vec3> {
        self.triangles
            .iter()
            .map(|t| t.iter().map(|&v| vertices[v as usize]).sum::<Vec3>() / 3.0)
            .collect()
    }

    /// Simplex → triangle: the vertex positions rebuilt from node positions.
    pub fn vertices_into(&self, nodes: &[Vec3], out: &mut [Vec3]) {
        for (v, o) in out.iter_mut().enumerate().take(self.vertex_count()) {
            *o = match self.frame(v, nodes) {
                Some((c, f)) => {
                    let k = self.coefficients[v];
                    c + k.x * f[0] + k.y * f[1] + k.z * f[2]
                }
                None => self.ring(v).map_or(Vec3::ZERO, |r| mean(r, nodes)),
            };
        }
    }

    /// The dual triangle mesh of the current nodes.
    pub fn to_triangle_mesh(&self, nodes: &[Vec3]) -> SurfaceMesh {
        let mut vertices = vec![Vec3::ZERO; self.vertex_count()];
        self.vertices_into(nodes, &mut vertices);
        SurfaceMesh::new(vertices, self.triangles.clone())
    }

    /// Each face (cycle) as a fan of outward triangles over nodes, for volume and pressure.
    pub fn face_fans(&self) -> Vec<[u32; 3]> {
        let mut out = Vec::new();
        for v in 0..self.vertex_count() {
            if let Some(r) = self.ring(v) {
                for i in 1..r.len().saturating_sub(1) {
                    out.push([r[0], r[i], r[i + 1]]);
                }
            }
        }
        out
    }

    /// Centre and orthonormal frame (t₁, t₂, n) of the cycle around `v`.
    fn frame(&self, v: usize, nodes: &[Vec3]) -> Option<(Vec3, [Vec3; 3])> {
        let r = self.ring(v)?;
        let c = mean(r, nodes);
        let mut normal = Vec3::ZERO;
        for i in 0..r.len() {
            let (p, q) = (
                nodes[r[i] as usize] - c,
                nodes[r[(i + 1) % r.len()] as usize] - c,
            );
            normal += p.cross(q);
        }
        let n = normal.try_normalize()?;
        let d = nodes[*r.first()? as usize] - c;
        let t1 = (d - d.dot(n) * n).try_normalize()?;
        Some((c, [t1, n.cross(t1), n]))
    }
}

fn mean(ring: &[u32], nodes: &[Vec3]) -> Vec3 {
    ring.iter().map(|&t| nodes[t as usize]).sum::<Vec3>() / ring.len().max(1) as Real
}

pub(crate) fn build(
    surface: &SurfaceMesh,
    material: Material,
    params: SpringParams,
) -> Result<SpringModel, Error> {
    let s = checked_compact(surface)?;
    let simplex = SimplexMesh::from_triangles(&s)?;
    let nodes = simplex.centres(&s.vertices);
    let edges = triangle_edges(&s.triangles);
    let kp = membrane_stiffness(
        &s.vertices,
        &s.triangles,
        &edges,
        material.young_modulus,
        material.poisson_ratio,
        params.thickness,
        params.stiffness,
    );
    let mut springs = Vec::with_capacity(edges.len());
    for (t, tri) in s.triangles.iter().enumerate() {
        for (k, u) in simplex.neighbours[t].iter().enumerate() {
            if (t as u32) > *u {
                continue;
            }
            let (p, q) = (tri[k], tri[(k + 1) % 3]);
            let Some(e) = edge_index(&edges, p, q) else {
                continue;
            };
            let lp2 = (s.vertices[q as usize] - s.vertices[p as usize]).length_squared();
            let ld = (nodes[*u as usize] - nodes[t]).length();
            let stiffness = if ld > 0.0 {
                kp[e] * (lp2 / (ld * ld)).min(MAX_LENGTH_RATIO_SQUARED)
            } else {
                kp[e]
            };
            springs.push(Spring {
                a: t as u32,
                b: *u,
                rest_length: ld,
                stiffness,
                damping: material.stiffness_damping * stiffness,
            });
        }
    }
    let masses = s
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| s.vertices[i as usize]);
            material.density * params.thickness * triangle_area_vector(a, b, c).length()
        })
        .collect();
    let mut body = SpringBody::new(SpringNetwork::new(springs), masses, material.damping);
    // The simplex kind needs a closed surface, so its pressure is on unless turned off.
    if params.pressure != Some(false) {
        body.pressure = Some(
            Pressure::new(simplex.face_fans(), &nodes, material.bulk_modulus()).ok_or_else(
                || MeshError::Invalid("the simplex mesh encloses no positive volume".into()),
            )?,
        );
    }
    let triangles = s.triangles.clone();
    let mut model = SpringModel::assemble(
        Kind::Simplex,
        material,
        params,
        body,
        nodes,
        SurfaceLink::Dual(simplex),
        triangles,
        Vec::new(),
    );
    // The rebuilt vertices equal the file's at rest only to rounding; scenes find file
    // vertices on the surface by exact position, and displacements are measured from here.
    model.surface_rest.clone_from(&s.vertices);
    Ok(model)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::icosphere;

    #[test]
    fn dual_counts_and_degree_three() {
        let s = icosphere(Vec3::ZERO, 1.0, 2);
        let m = SimplexMesh::from_triangles(&s).unwrap();
        let (v, f) = (s.vertices.len(), s.triangles.len());
        let e = triangle_edges(&s.triangles).len();
        assert_eq!(m.node_count(), f);
        assert_eq!(m.links().len(), e);
        assert_eq!(m.vertex_count(), v);
        // Euler characteristic of the dual equals the primal one (2 for a sphere).
        assert_eq!(f as i64 - e as i64 + v as i64, 2);
        for (t, n) in m.neighbours().iter().enumerate() {
            assert!(n[0] != n[1] && n[1] != n[2] && n[0] != n[2]);
            for u in n {
                assert!(m.neighbours()[*u as usize].contains(&(t as u32)));
            }
        }
        let ring_total: usize = (0..v).map(|i| m.ring(i).unwrap().len()).sum();
        assert_eq!(ring_total, 3 * f);
    }

    #[test]
    fn round_trip_is_exact_at_rest_and_under_rigid_motion() {
        let s = icosphere(Vec3::new(0.1, 0.2, 0.3), 0.5, 2);
        let m = SimplexMesh::from_triangles(&s).unwrap();
        let nodes = m.centres(&s.vertices);
        let back = m.to_triangle_mesh(&nodes);
        assert_eq!(back.triangles, s.triangles);
        for (a, b) in back.vertices.iter().zip(&s.vertices) {
            assert!((*a - *b).length() < 1e-12);
        }
        let r = crate::math::Mat3::from_axis_angle(Vec3::new(0.2, 1.0, -0.4).normalize(), 2.0);
        let moved: Vec<Vec3> = nodes.iter().map(|p| r * *p + Vec3::X).collect();
        let back = m.to_triangle_mesh(&moved);
        for (a, b) in back.vertices.iter().zip(&s.vertices) {
            assert!((*a - (r * *b + Vec3::X)).length() < 1e-12);
        }
        // The face fans enclose a positive volume a little below the sphere's.
        let vol = Pressure::new(m.face_fans(), &nodes, 1.0)
            .unwrap()
            .rest_volume;
        assert!(vol > 0.0 && vol < s.signed_volume());
    }

    #[test]
    fn open_surface_is_refused_with_the_edge() {
        let s = SurfaceMesh::new(
            vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2]],
        );
        let e = SimplexMesh::from_triangles(&s).unwrap_err();
        assert!(matches!(e, MeshError::NotClosed { .. }), "{e}");
    }
}
