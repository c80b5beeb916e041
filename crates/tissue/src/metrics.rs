//! Measurements of a model's state that every driver reports the same way: `tissue run`'s
//! summary, the Python package, comparisons.

use crate::math::{Real, tet_signed_volume};
use crate::mesh::surface::signed_volume_of;
use crate::model::Deformable;

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
