//! `volumetric-spring-mass`: springs on the edges of tetrahedra, masses ρ V / 4 per corner.
//!
//! Two sources of tetrahedra:
//! - a tetrahedral mesh (`build`), drawn through its boundary surface;
//! - a closed surface with `parents = true` (`build_parents`): the survey's internal parent
//!   nodes. Each surface vertex gets a parent on the segment to the centroid, at
//!   `parent_depth` of the way, and one node sits at the centroid. The prisms between a
//!   surface triangle and its parent triangle are split into three tetrahedra (each quad
//!   side cut along the diagonal that starts at the smaller vertex index, so neighbouring
//!   prisms agree) and each parent triangle makes a tetrahedron with the centre. Springs and
//!   masses then follow as for a tetrahedral mesh, so the parents tie opposite sides together
//!   and give the object a volume. The construction assumes a surface star-shaped around its
//!   centroid (true of the liver); elsewhere parents may lie outside, which the springs
//!   tolerate but which is no longer a faithful volume.

use crate::error::{Error, MeshError};
use crate::material::Material;
use crate::math::{Real, Vec3, tet_signed_volume};
use crate::mesh::topology::tet_edges;
use crate::mesh::{SurfaceMesh, TetMesh, boundary_surface};

use super::body::SpringBody;
use super::pressure::Pressure;
use super::springs::SpringNetwork;
use super::stiffness::tet_stiffness;
use super::surface::{checked_compact, closed_pressure, network_on_edges};
use super::{Kind, SpringModel, SpringParams, SurfaceLink};

pub(crate) fn build(
    mesh: &TetMesh,
    material: Material,
    params: SpringParams,
) -> Result<SpringModel, Error> {
    mesh.validate_for_simulation()?;
    let mesh = mesh.compacted();
    let (network, masses) = tet_parts(&mesh.vertices, &mesh.tets, &material, &params)?;
    let boundary = boundary_surface(&mesh);
    let triangles = boundary.surface.triangles.clone();
    let mut body = SpringBody::new(network, masses, material.damping);
    if params.pressure == Some(true) {
        closed_pressure(&boundary.surface, &material)?;
        let over_nodes = triangles
            .iter()
            .map(|t| t.map(|s| boundary.nodes[s as usize]))
            .collect();
        body.pressure = Pressure::new(over_nodes, &mesh.vertices, material.bulk_modulus());
    }
    Ok(SpringModel::assemble(
        Kind::Volumetric,
        material,
        params,
        body,
        mesh.vertices,
        SurfaceLink::Nodes(boundary.nodes),
        triangles,
        mesh.tets,
    ))
}

pub(crate) fn build_parents(
    surface: &SurfaceMesh,
    material: Material,
    params: SpringParams,
) -> Result<SpringModel, Error> {
    let s = checked_compact(surface)?;
    let tets = parent_tets(&s, params.parent_depth);
    let (network, masses) = tet_parts(&tets.vertices, &tets.tets, &material, &params)?;
    let mut body = SpringBody::new(network, masses, material.damping);
    if params.pressure == Some(true) {
        body.pressure = Some(closed_pressure(&s, &material)?);
    }
    let ns = s.vertices.len() as u32;
    Ok(SpringModel::assemble(
        Kind::Volumetric,
        material,
        params,
        body,
        tets.vertices,
        SurfaceLink::Nodes((0..ns).collect()),
        s.triangles,
        tets.tets,
    ))
}

/// The shell of prisms between the surface and its parent layer plus the fan of parent
/// triangles to the centre: nodes are the surface vertices, then their parents, then the
/// centre. Every tetrahedron is positively oriented.
pub fn parent_tets(s: &SurfaceMesh, depth: Real) -> TetMesh {
    let ns = s.vertices.len();
    let centre = s.vertices.iter().copied().sum::<Vec3>() / ns.max(1) as Real;
    let mut vertices = s.vertices.clone();
    vertices.extend(
        s.vertices
            .iter()
            .map(|&x| centre + (1.0 - depth) * (x - centre)),
    );
    vertices.push(centre);
    let parent = |v: u32| v + ns as u32;
    let mut tets = Vec::with_capacity(4 * s.triangles.len());
    for tri in &s.triangles {
        let mut t = *tri;
        t.sort_unstable();
        let [a, b, c] = t;
        let (pa, pb, pc) = (parent(a), parent(b), parent(c));
        tets.push([a, b, c, pc]);
        tets.push([a, b, pb, pc]);
        tets.push([a, pa, pb, pc]);
        tets.push([pa, pb, pc, 2 * ns as u32]);
    }
    for t in &mut tets {
        let p = t.map(|i| vertices[i as usize]);
        if tet_signed_volume(p[0], p[1], p[2], p[3]) < 0.0 {
            t.swap(2, 3);
        }
    }
    TetMesh::new(vertices, tets)
}

/// Springs on tetrahedron edges and lumped masses; every node must get a positive mass.
pub(crate) fn tet_parts(
    x: &[Vec3],
    tets: &[[u32; 4]],
    material: &Material,
    params: &SpringParams,
) -> Result<(SpringNetwork, Vec<Real>), MeshError> {
    let edges = tet_edges(tets);
    let k = tet_stiffness(
        x,
        tets,
        &edges,
        material.young_modulus,
        material.poisson_ratio,
        params.stiffness,
    );
    let network = network_on_edges(x, &edges, &k, material.stiffness_damping);
    let mut masses = vec![0.0; x.len()];
    for tet in tets {
        let p = tet.map(|i| x[i as usize]);
        let m = material.density * tet_signed_volume(p[0], p[1], p[2], p[3]).abs() / 4.0;
        for &v in tet {
            masses[v as usize] += m;
        }
    }
    if let Some(v) = masses.iter().position(|m| m.is_nan() || *m <= 0.0) {
        return Err(MeshError::Invalid(format!(
            "node {v} has no mass: every tetrahedron around it is flat"
        )));
    }
    Ok((network, masses))
}
