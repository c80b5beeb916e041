//! The report of a mesh of several labels: each label's tetrahedra and volume against its
//! voxels, and how far the interfaces between labels (the faces shared by two tetrahedra
//! of different tags) are from the input's interfaces, both ways, as the outer boundary is
//! measured (`report::measure`).

use rustc_hash::FxHashMap;
use serde::Serialize;

use crate::math::{Real, Vec3, tet_signed_volume};
use crate::mesh::TetMesh;

use super::domain::{Domain, walk_grid_lines};
use super::triangle_index::TriangleIndex;

/// One label's share of the mesh.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LabelVolume {
    pub tag: i32,
    pub tets: usize,
    /// Volume of its tetrahedra, m³.
    pub volume: Real,
    /// Its voxels' volume (m³) and the relative error against it.
    pub voxel_volume: Option<Real>,
    pub volume_error: Option<Real>,
}

/// The interfaces between labels in the mesh against those of the input.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct InterfaceReport {
    /// Faces shared by two tetrahedra of different tags.
    pub triangles: usize,
    /// Faces with tetrahedra of two different tags on the same side, or shared by more
    /// than two tetrahedra: 0 in a conforming mesh.
    pub nonconforming_faces: usize,
    /// Interface edges not in exactly two interface triangles: where an interface meets
    /// the outer boundary (0 for a label enclosed by another).
    pub rim_edges: usize,
    /// Largest distance from an interface point of the mesh (vertex, face centroid, edge
    /// midpoint) to the input's interface between the same labels (m): the first-order
    /// estimate |f|/|∇f| on `Domain::interface_value`, bounded above by the distance to
    /// the nearest input interface sample.
    pub mesh_to_input: Real,
    /// Largest distance from an input interface sample (crossings of lines h/4 apart) to
    /// the mesh's interface triangles (m), and the number of samples.
    pub input_to_mesh: Real,
    pub samples: usize,
}

/// Per-label counts and volumes, and the interfaces.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Labels {
    pub volumes: Vec<LabelVolume>,
    pub interface: InterfaceReport,
}

/// Measures the labels of `mesh` (`tags`, one per tetrahedron) against `domain`.
pub fn measure_labels(mesh: &TetMesh, tags: &[i32], domain: &dyn Domain, size: Real) -> Labels {
    let material_tags = domain.material_tags();
    let voxel_volumes = domain.material_volumes();
    let mut volumes: Vec<LabelVolume> = material_tags
        .iter()
        .enumerate()
        .map(|(k, &tag)| LabelVolume {
            tag,
            tets: 0,
            volume: 0.0,
            voxel_volume: voxel_volumes.get(k).copied(),
            volume_error: None,
        })
        .collect();
    for (t, &tag) in tags.iter().enumerate().take(mesh.tets.len()) {
        let p = mesh.corners(t);
        if let Some(l) = volumes.iter_mut().find(|l| l.tag == tag) {
            l.tets += 1;
            l.volume += tet_signed_volume(p[0], p[1], p[2], p[3]);
        }
    }
    for l in &mut volumes {
        l.volume_error = l
            .voxel_volume
            .filter(|&v| v > 0.0)
            .map(|v| (l.volume - v) / v);
    }
    Labels {
        volumes,
        interface: measure_interface(mesh, tags, domain, size),
    }
}

fn measure_interface(
    mesh: &TetMesh,
    tags: &[i32],
    domain: &dyn Domain,
    size: Real,
) -> InterfaceReport {
    let material_tags = domain.material_tags();
    let index_of = |tag: i32| material_tags.iter().position(|&t| t == tag);
    // Every face with the tags of the tetrahedra on it.
    let mut faces: FxHashMap<[u32; 3], Vec<i32>> = FxHashMap::default();
    for (t, tet) in mesh.tets.iter().enumerate() {
        for skip in 0..4 {
            let mut f = [0u32; 3];
            let mut n = 0;
            for (i, &v) in tet.iter().enumerate() {
                if i != skip {
                    f[n] = v;
                    n += 1;
                }
            }
            f.sort_unstable();
            faces
                .entry(f)
                .or_default()
                .push(tags.get(t).copied().unwrap_or(0));
        }
    }
    let mut report = InterfaceReport::default();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut pairs: Vec<(usize, usize)> = Vec::new();
    let mut edges: FxHashMap<[u32; 2], u32> = FxHashMap::default();
    for (f, sides) in &faces {
        match sides.as_slice() {
            [_] => {}
            [a, b] if a == b => {}
            [a, b] => {
                triangles.push(*f);
                pairs.push((index_of(*a).unwrap_or(0), index_of(*b).unwrap_or(0)));
                for (x, y) in [(f[0], f[1]), (f[1], f[2]), (f[0], f[2])] {
                    *edges.entry([x, y]).or_insert(0) += 1;
                }
            }
            _ => report.nonconforming_faces += 1,
        }
    }
    report.triangles = triangles.len();
    report.rim_edges = edges.values().filter(|&&n| n != 2).count();

    // Input interface samples: where the label changes between neighbouring inside points
    // of lines along x, y and z, h/4 apart.
    let samples = interface_samples(domain, 0.25 * size);
    report.samples = samples.len();
    let index = TriangleIndex::new(&mesh.vertices, &triangles);
    if !triangles.is_empty() {
        report.input_to_mesh = samples
            .iter()
            .map(|&p| index.distance(p))
            .fold(0.0, Real::max);
    } else if !samples.is_empty() {
        report.input_to_mesh = Real::INFINITY;
    }
    let nearest = (!samples.is_empty()).then(|| {
        let points: Vec<[u32; 3]> = (0..samples.len() as u32).map(|i| [i, i, i]).collect();
        TriangleIndex::new(&samples, &points)
    });
    let step = 1e-3 * size;
    let first_order = |p: Vec3, a: usize, b: usize| {
        let f = domain.interface_value(p, a, b);
        let g = Vec3::new(
            domain.interface_value(p + step * Vec3::X, a, b)
                - domain.interface_value(p - step * Vec3::X, a, b),
            domain.interface_value(p + step * Vec3::Y, a, b)
                - domain.interface_value(p - step * Vec3::Y, a, b),
            domain.interface_value(p + step * Vec3::Z, a, b)
                - domain.interface_value(p - step * Vec3::Z, a, b),
        ) / (2.0 * step);
        let n = g.length();
        if n > 0.0 { f.abs() / n } else { Real::INFINITY }
    };
    for (f, &(a, b)) in triangles.iter().zip(&pairs) {
        let [p, q, r] = f.map(|v| mesh.vertices[v as usize]);
        for x in [
            p,
            q,
            r,
            (p + q + r) / 3.0,
            0.5 * (p + q),
            0.5 * (q + r),
            0.5 * (r + p),
        ] {
            let d = match &nearest {
                Some(near) => first_order(x, a, b).min(near.distance(x)),
                None => first_order(x, a, b),
            };
            report.mesh_to_input = report.mesh_to_input.max(d);
        }
    }
    report
}

/// Points of the input's label interfaces about `spacing` apart: between neighbouring
/// samples of lines along x, y and z, both inside and of different labels, the crossing
/// found by `Domain::interface_cut`.
pub fn interface_samples(domain: &dyn Domain, spacing: Real) -> Vec<Vec3> {
    let (lo, hi) = domain.bounds();
    let material = |p: Vec3| (domain.value(p) < 0.0).then(|| domain.material_at(p));
    let mut out = Vec::new();
    let mut prev: Option<(Vec3, Option<usize>)> = None;
    walk_grid_lines(lo, hi, spacing, |p, starts_line| {
        let m = material(p);
        if let Some((q, Some(mq))) = prev.filter(|_| !starts_line)
            && let Some(mp) = m
            && mp != mq
        {
            out.push(domain.interface_cut(q, mq, p, mp));
        }
        prev = Some((p, m));
    });
    out
}
