//! `spring-mass`: a membrane of springs on the edges of a triangle surface (Fig. 2a), masses
//! lumped from the triangle areas: m_v = ρ t Σ A_T / 3 over the triangles around v.

use crate::error::{Error, MeshError, SimError};
use crate::material::Material;
use crate::math::{Real, Vec3, triangle_area_vector};
use crate::mesh::SurfaceMesh;
use crate::mesh::topology::{edge_faces, triangle_edges};

use super::body::SpringBody;
use super::pressure::Pressure;
use super::springs::{Spring, SpringNetwork};
use super::stiffness::membrane_stiffness;
use super::{Kind, SpringModel, SpringParams, SurfaceLink};

pub(crate) fn build(
    mesh: &SurfaceMesh,
    material: Material,
    params: SpringParams,
) -> Result<SpringModel, Error> {
    let mesh = checked_compact(mesh)?;
    let (network, masses) = membrane_parts(&mesh.vertices, &mesh.triangles, &material, &params);
    let mut body = SpringBody::new(network, masses, material.damping);
    match params.pressure {
        Some(true) => body.pressure = Some(closed_pressure(&mesh, &material)?),
        // Auto: a closed surface keeps its volume; a sheet has none to keep.
        None if edge_faces(&mesh.triangles).border_edges().next().is_none() => {
            body.pressure = Some(closed_pressure(&mesh, &material)?);
        }
        _ => {}
    }
    let n = mesh.vertices.len();
    Ok(SpringModel::assemble(
        Kind::Surface,
        material,
        params,
        body,
        mesh.vertices,
        SurfaceLink::Nodes((0..n as u32).collect()),
        mesh.triangles,
        Vec::new(),
    ))
}

/// Checks indices and triangle areas; drops vertices no triangle uses.
pub(crate) fn checked_compact(mesh: &SurfaceMesh) -> Result<SurfaceMesh, MeshError> {
    mesh.validate_indices()?;
    if mesh.triangles.is_empty() {
        return Err(MeshError::Empty { what: "triangles" });
    }
    let mut map = vec![u32::MAX; mesh.vertices.len()];
    let mut vertices = Vec::new();
    let mut triangles = Vec::with_capacity(mesh.triangles.len());
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = mesh.corners(t);
        let area = triangle_area_vector(a, b, c).length();
        let longest = (b - a).length().max((c - b).length()).max((a - c).length());
        if area <= 1e-12 * longest * longest {
            return Err(MeshError::DegenerateTriangle { triangle: t, area });
        }
        triangles.push(tri.map(|v| {
            let slot = &mut map[v as usize];
            if *slot == u32::MAX {
                *slot = vertices.len() as u32;
                vertices.push(mesh.vertices[v as usize]);
            }
            *slot
        }));
    }
    Ok(SurfaceMesh::new(vertices, triangles))
}

/// Springs on the edges (rest lengths from `x`) and lumped masses of a membrane.
pub(crate) fn membrane_parts(
    x: &[Vec3],
    triangles: &[[u32; 3]],
    material: &Material,
    params: &SpringParams,
) -> (SpringNetwork, Vec<Real>) {
    let edges = triangle_edges(triangles);
    let k = membrane_stiffness(
        x,
        triangles,
        &edges,
        material.young_modulus,
        material.poisson_ratio,
        params.thickness,
        params.stiffness,
    );
    let network = network_on_edges(x, &edges, &k, material.stiffness_damping);
    let mut masses = vec![0.0; x.len()];
    for tri in triangles {
        let [a, b, c] = tri.map(|i| x[i as usize]);
        let m = material.density * params.thickness * triangle_area_vector(a, b, c).length() / 3.0;
        for &v in tri {
            masses[v as usize] += m;
        }
    }
    (network, masses)
}

/// One spring per edge, at rest at `x`, damping c = β k.
pub(crate) fn network_on_edges(
    x: &[Vec3],
    edges: &[[u32; 2]],
    k: &[Real],
    beta: Real,
) -> SpringNetwork {
    SpringNetwork::new(
        edges
            .iter()
            .zip(k)
            .map(|(&[a, b], &k)| Spring {
                a,
                b,
                rest_length: (x[b as usize] - x[a as usize]).length(),
                stiffness: k,
                damping: beta * k,
            })
            .collect(),
    )
}

/// The pressure of a closed, outward surface with the material's bulk modulus.
pub(crate) fn closed_pressure(mesh: &SurfaceMesh, material: &Material) -> Result<Pressure, Error> {
    let ef = edge_faces(&mesh.triangles);
    if let Some([a, b]) = ef.border_edges().next() {
        return Err(MeshError::NotClosed {
            border_edges: ef.border_edges().count(),
            a: a as usize,
            b: b as usize,
        }
        .into());
    }
    Pressure::new(
        mesh.triangles.clone(),
        &mesh.vertices,
        material.bulk_modulus(),
    )
    .ok_or_else(|| {
        SimError::BadParameter {
            name: "pressure",
            value: "true".into(),
            reason: "the surface encloses no positive volume (is it oriented inward?)".into(),
        }
        .into()
    })
}
