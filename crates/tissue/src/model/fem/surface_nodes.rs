//! Constraints and loads name surface vertices; the models work on tet-mesh nodes. What
//! `fem-static`, the dynamic models, the surface-condensed models and `fem-corotational`
//! share in that mapping.

use crate::error::SimError;
use crate::interact::Loads;
use crate::math::{Real, Vec3, is_finite_vec};

/// The node of surface vertex `vertex`, given the node of each surface vertex.
pub(super) fn node_of(nodes: &[u32], vertex: u32) -> Result<usize, SimError> {
    nodes
        .get(vertex as usize)
        .map(|&n| n as usize)
        .ok_or(SimError::BadConstraint {
            vertex: vertex as usize,
            count: nodes.len(),
        })
}

/// The nodal forces (3 per node) of `loads`: `gravity_load(g)` for a finite gravity g, plus
/// each point load on the node of its surface vertex. Checked before anything is returned.
pub(super) fn nodal_forces(
    loads: &Loads,
    nodes: &[u32],
    gravity_load: impl FnOnce(Vec3) -> Vec<Real>,
) -> Result<Vec<Real>, SimError> {
    if !is_finite_vec(loads.gravity) {
        return Err(SimError::BadParameter {
            name: "gravity",
            value: loads.gravity.to_string(),
            reason: "must be finite".into(),
        });
    }
    let mut f = gravity_load(loads.gravity);
    for &(v, force) in &loads.point_loads {
        let n = node_of(nodes, v)?;
        if !is_finite_vec(force) {
            return Err(SimError::BadParameter {
                name: "point_loads",
                value: format!("surface vertex {v} -> {force}"),
                reason: "the force is not finite".into(),
            });
        }
        for k in 0..3 {
            f[3 * n + k] += force[k];
        }
    }
    Ok(f)
}
