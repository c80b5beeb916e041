//! Lumped (diagonal) nodal masses of a linear tetrahedral mesh, shared by the dynamic FEM
//! variants: each tetrahedron gives a quarter of its mass ρ·V to each corner.

use crate::material::ElementMaterials;
use crate::math::Real;
use crate::mesh::TetMesh;

/// Mass per node, in kg. Nodes used by no tetrahedron get zero.
pub fn lumped_masses(mesh: &TetMesh, density: Real) -> Vec<Real> {
    lumped_masses_by(mesh, |_| density)
}

/// Mass per node with each tetrahedron's own density (per-region materials), in kg.
pub fn lumped_masses_of(mesh: &TetMesh, materials: &ElementMaterials) -> Vec<Real> {
    match materials.uniform() {
        Some(m) => lumped_masses(mesh, m.density),
        None => lumped_masses_by(mesh, |t| materials.of(t).density),
    }
}

fn lumped_masses_by(mesh: &TetMesh, density: impl Fn(usize) -> Real) -> Vec<Real> {
    let mut m = vec![0.0; mesh.vertices.len()];
    for (t, tet) in mesh.tets.iter().enumerate() {
        let quarter = 0.25 * density(t) * mesh.tet_volume(t).abs();
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

    #[test]
    fn per_element_densities_add_up_to_each_regions_mass() {
        use crate::material::{Material, RegionMaterial};
        let mesh = box_tets(Vec3::ZERO, Vec3::ONE, [1, 1, 1], BoxSplit::Five);
        let tags: Vec<i32> = (0..mesh.tets.len() as i32)
            .map(|t| 1 + (t == 0) as i32)
            .collect();
        let light = Material::new(1e3, 0.3).unwrap();
        let heavy = RegionMaterial {
            name: "2".into(),
            tag: 2,
            material: light.with_density(3000.0).unwrap(),
        };
        let materials = ElementMaterials::new(light, &[heavy], &tags, tags.len()).unwrap();
        let total: Real = lumped_masses_of(&mesh, &materials).iter().sum();
        let v0 = mesh.tet_volume(0).abs();
        assert!(
            (total - (1000.0 * (1.0 - v0) + 3000.0 * v0)).abs() < 1e-9,
            "{total}"
        );
    }
}
