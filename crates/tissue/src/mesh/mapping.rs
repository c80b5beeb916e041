//! The map between a model's mechanical nodes and the surface the user sees and touches.
//!
//! One object does both directions: `apply` moves positions out (for drawing and contact),
//! `apply_transpose` brings surface forces back to the nodes (instrument forces).

use crate::math::{Real, Vec3};

#[derive(Clone, Debug, PartialEq)]
pub enum SurfaceMapping {
    /// Surface vertex i is mechanical node `nodes[i]` (the surface is the mesh boundary).
    Nodes(Vec<u32>),
    /// Surface vertex i is Σ_k weights[i][k] · x[nodes[i][k]] (barycentric in a tetrahedron,
    /// or any other four-node interpolation). Weights sum to 1.
    Embedded {
        nodes: Vec<[u32; 4]>,
        weights: Vec<[Real; 4]>,
    },
}

impl SurfaceMapping {
    /// Number of surface vertices.
    pub fn len(&self) -> usize {
        match self {
            SurfaceMapping::Nodes(n) => n.len(),
            SurfaceMapping::Embedded { nodes, .. } => nodes.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Writes surface positions (or displacements, velocities) from node values.
    pub fn apply(&self, node_values: &[Vec3], surface: &mut [Vec3]) {
        match self {
            SurfaceMapping::Nodes(n) => {
                for (s, &i) in surface.iter_mut().zip(n) {
                    *s = node_values[i as usize];
                }
            }
            SurfaceMapping::Embedded { nodes, weights } => {
                for ((s, ids), w) in surface.iter_mut().zip(nodes).zip(weights) {
                    *s = (0..4).map(|k| w[k] * node_values[ids[k] as usize]).sum();
                }
            }
        }
    }

    /// Adds surface vertex forces to node forces (the transpose of `apply`).
    pub fn apply_transpose(&self, surface_forces: &[Vec3], node_forces: &mut [Vec3]) {
        match self {
            SurfaceMapping::Nodes(n) => {
                for (f, &i) in surface_forces.iter().zip(n) {
                    node_forces[i as usize] += *f;
                }
            }
            SurfaceMapping::Embedded { nodes, weights } => {
                for ((f, ids), w) in surface_forces.iter().zip(nodes).zip(weights) {
                    for k in 0..4 {
                        node_forces[ids[k] as usize] += w[k] * *f;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transpose_preserves_virtual_work() {
        // <apply(x), f> = <x, apply_transpose(f)> for any x and f.
        let m = SurfaceMapping::Embedded {
            nodes: vec![[0, 1, 2, 3], [1, 2, 3, 4]],
            weights: vec![[0.1, 0.2, 0.3, 0.4], [0.25, 0.25, 0.25, 0.25]],
        };
        let x: Vec<Vec3> = (0..5)
            .map(|i| Vec3::new(i as f64, 1.0 - i as f64, 0.5 * i as f64))
            .collect();
        let f = vec![Vec3::new(1.0, -2.0, 0.5), Vec3::new(0.3, 0.7, -1.1)];
        let mut s = vec![Vec3::ZERO; 2];
        m.apply(&x, &mut s);
        let mut g = vec![Vec3::ZERO; 5];
        m.apply_transpose(&f, &mut g);
        let lhs: f64 = s.iter().zip(&f).map(|(a, b)| a.dot(*b)).sum();
        let rhs: f64 = x.iter().zip(&g).map(|(a, b)| a.dot(*b)).sum();
        assert!((lhs - rhs).abs() < 1e-12);
    }
}
