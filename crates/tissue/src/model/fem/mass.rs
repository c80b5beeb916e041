//! Lumped (diagonal) nodal masses of a linear tetrahedral mesh, shared by the dynamic FEM
//! variants: each tetrahedron gives a quarter of its mass ρ·V to each corner.

use crate::math::Real;
use crate::mesh::TetMesh;

/// Mass per node, in kg. Nodes used by no tetrahedron get zero.
pub fn lumped_masses(mesh: &TetMesh, density: Real) -> Vec<Real> {
    let mut m = vec![0.0; mesh.vertices.len()];
    for (t, tet) in mesh.tets.iter().enumerate() {
        let quarter = 0.25 * density * mesh.tet_volume(t).abs();
        for &n in tet {
            m[n as usize] += quarter;
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;
    use crate::mesh::generate::{BoxSplit, box_tets};

    #[test]
    fn masses_add_up_to_the_body_mass() {
        let mesh = box_tets(
            Vec3::ZERO,
            Vec3::new(0.3, 0.2, 0.1),
            [3, 2, 2],
            BoxSplit::Five,
        );
        let m = lumped_masses(&mesh, 1000.0);
        assert!((m.iter().sum::<Real>() - 1000.0 * 0.006).abs() < 1e-12);
        assert!(m.iter().all(|&x| x > 0.0));
    }
}
