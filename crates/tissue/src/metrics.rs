//! Measurements of a model's state that every driver reports the same way: `tissue run`'s
//! summary, the Python package, comparisons, the viewer's strain colours.

use crate::math::{Mat3, Real, Vec3, tet_signed_volume};
use crate::mesh::surface::signed_volume_of;
use crate::model::{Deformable, VolumeView};

/// Enclosed volume now, in m³: the tetrahedra if the model has them, else the closed surface.
pub fn volume(model: &dyn Deformable) -> Real {
    match model.volume() {
        Some(v) => v
            .tets
            .iter()
            .filter_map(|t| {
                let [a, b, c, d] = t.map(|i| v.positions.get(i as usize).copied());
                Some(tet_signed_volume(a?, b?, c?, d?))
            })
            .sum(),
        None => {
            let s = model.surface();
            signed_volume_of(s.positions, s.triangles)
        }
    }
}

/// Largest displacement from rest now, in m, over the volume's nodes if the model has a
/// volume mesh, else over the surface.
pub fn max_displacement(model: &dyn Deformable) -> Real {
    let (now, rest) = match model.volume() {
        Some(v) => (v.positions, v.rest_positions),
        None => (model.surface().positions, model.rest_surface()),
    };
    now.iter()
        .zip(rest)
        .map(|(p, q)| p.distance(*q))
        .fold(0.0, Real::max)
}

/// Which node of the model's tetrahedra each surface vertex is (matched by rest position,
/// bit for bit: the tetrahedral kinds copy their surface from their nodes), for models with a
/// volume mesh; `None` for a vertex no node sits on. Built once per topology: after a cut the
/// surface changes. Where a cut split a node, the vertex takes the first node at its place.
pub fn surface_nodes(model: &dyn Deformable) -> Option<Vec<Option<u32>>> {
    let volume = model.volume()?;
    let key = |p: Vec3| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
    let mut at = std::collections::HashMap::with_capacity(volume.rest_positions.len());
    for (i, &p) in volume.rest_positions.iter().enumerate() {
        at.entry(key(p)).or_insert(i as u32);
    }
    Some(
        model
            .rest_surface()
            .iter()
            .map(|&p| at.get(&key(p)).copied())
            .collect(),
    )
}

/// Equivalent strain per node of a volume mesh: over the tetrahedra around the node, the
/// volume-weighted mean of the von Mises measure of the Green-Lagrange strain,
/// ε_eq = √(2/3 dev(E) : dev(E)) with E = (FᵀF − I)/2 and F the tetrahedron's deformation
/// gradient. Green-Lagrange strain is zero under any rigid motion, so a rotated organ shows
/// no strain; under a uniaxial stretch s with no lateral strain, ε_eq = (s² − 1)/3.
/// Dimensionless; 0 at a node no live tetrahedron touches.
pub fn node_strain(volume: &VolumeView<'_>) -> Vec<Real> {
    let n = volume.positions.len().min(volume.rest_positions.len());
    let mut sum = vec![0.0; n];
    let mut weight = vec![0.0; n];
    for tet in volume.tets {
        let idx = tet.map(|i| i as usize);
        if idx.iter().any(|&i| i >= n) {
            continue;
        }
        let [a, b, c, d] = idx.map(|i| volume.rest_positions[i]);
        let dm = Mat3::from_cols(b - a, c - a, d - a);
        let rest_volume = dm.determinant().abs() / 6.0;
        // Degenerate (or NaN) at rest: no deformation gradient.
        if rest_volume.is_nan() || rest_volume <= 0.0 {
            continue;
        }
        let [p, q, r, s] = idx.map(|i| volume.positions[i]);
        let f = Mat3::from_cols(q - p, r - p, s - p) * dm.inverse();
        let e = (f.transpose() * f - Mat3::IDENTITY) * 0.5;
        let mean = (e.x_axis.x + e.y_axis.y + e.z_axis.z) / 3.0;
        let dev = e - Mat3::IDENTITY * mean;
        let dd =
            dev.x_axis.length_squared() + dev.y_axis.length_squared() + dev.z_axis.length_squared();
        let eq = (2.0 / 3.0 * dd).sqrt();
        if !eq.is_finite() {
            continue;
        }
        for i in idx {
            sum[i] += rest_volume * eq;
            weight[i] += rest_volume;
        }
    }
    sum.iter()
        .zip(&weight)
        .map(|(s, w)| if *w > 0.0 { s / w } else { 0.0 })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::generate::{BoxSplit, box_tets};

    fn strain_of(positions: &[Vec3], rest: &[Vec3], tets: &[[u32; 4]]) -> Vec<Real> {
        node_strain(&VolumeView {
            positions,
            rest_positions: rest,
            tets,
        })
    }

    /// A rigid motion strains nothing; a uniaxial stretch s (no lateral strain) gives
    /// ε_eq = (s² − 1)/3 at every node; a volume-preserving shear of amount γ gives
    /// √(2/3 dev(E):dev(E)) with E = [[0, γ/2, 0], [γ/2, γ²/2, 0], [0, 0, 0]].
    #[test]
    fn equivalent_strain_is_zero_for_rigid_motions_and_exact_for_homogeneous_ones() {
        let mesh = box_tets(
            Vec3::ZERO,
            Vec3::new(0.1, 0.05, 0.03),
            [4, 3, 2],
            BoxSplit::Six,
        );
        let rest = &mesh.vertices;
        let rot = glam::DQuat::from_axis_angle(Vec3::new(1.0, 2.0, 0.5).normalize(), 1.3);
        let moved: Vec<Vec3> = rest
            .iter()
            .map(|&p| rot * p + Vec3::new(0.3, -0.1, 2.0))
            .collect();
        for e in strain_of(&moved, rest, &mesh.tets) {
            assert!(e.abs() < 1e-12, "{e}");
        }
        let s = 1.2;
        let stretched: Vec<Vec3> = rest.iter().map(|&p| Vec3::new(s * p.x, p.y, p.z)).collect();
        for e in strain_of(&stretched, rest, &mesh.tets) {
            assert!((e - (s * s - 1.0) / 3.0).abs() < 1e-12, "{e}");
        }
        let g = 0.3;
        let sheared: Vec<Vec3> = rest
            .iter()
            .map(|&p| Vec3::new(p.x + g * p.y, p.y, p.z))
            .collect();
        let e = Mat3::from_cols(
            Vec3::new(0.0, g / 2.0, 0.0),
            Vec3::new(g / 2.0, g * g / 2.0, 0.0),
            Vec3::ZERO,
        );
        let mean = g * g / 6.0;
        let dev = e - Mat3::IDENTITY * mean;
        let dd =
            dev.x_axis.length_squared() + dev.y_axis.length_squared() + dev.z_axis.length_squared();
        let want = (2.0 / 3.0 * dd).sqrt();
        for got in strain_of(&sheared, rest, &mesh.tets) {
            assert!((got - want).abs() < 1e-12, "{got} against {want}");
        }
    }
}
