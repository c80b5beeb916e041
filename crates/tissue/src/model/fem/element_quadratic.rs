//! The 10-node (quadratic) tetrahedron with straight edges, in VTK node order: corners 0..3,
//! then the mid-edge nodes of edges (0,1), (1,2), (0,2), (0,3), (1,3), (2,3).
//!
//! With barycentric coordinates L_i, the shape functions are L_i (2 L_i − 1) at corners and
//! 4 L_i L_j at mid-edge nodes. For straight edges ∇L_i is constant, so shape-function
//! gradients are linear and the stiffness integrand (products of two gradients) has degree 2:
//! the symmetric 4-point rule, exact for degree 2, integrates it exactly (checked in tests
//! against the closed-form integrals ∫ L_i L_j = V (1 + δ_ij) / 20).

use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::model::fem::element_linear::{add_block, shape_gradients};

/// The corners of each mid-edge node 4..9, in VTK order.
pub const EDGES: [[usize; 2]; 6] = [[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]];

/// The 4-point rule on a tetrahedron: barycentric points (a, b, b, b) and permutations, with
/// equal weights V/4; exact for polynomials of degree 2.
pub fn quadrature_points() -> [[Real; 4]; 4] {
    let a = (5.0 + 3.0 * 5.0_f64.sqrt()) / 20.0;
    let b = (5.0 - 5.0_f64.sqrt()) / 20.0;
    [[a, b, b, b], [b, a, b, b], [b, b, a, b], [b, b, b, a]]
}

/// Shape function values at barycentric point `l`.
pub fn shape_values(l: &[Real; 4]) -> [Real; 10] {
    let mut n = [0.0; 10];
    for i in 0..4 {
        n[i] = l[i] * (2.0 * l[i] - 1.0);
    }
    for (e, [i, j]) in EDGES.iter().enumerate() {
        n[4 + e] = 4.0 * l[*i] * l[*j];
    }
    n
}

/// Shape function gradients at barycentric point `l`, given the corner gradients ∇L_i.
pub fn shape_gradients_at(l: &[Real; 4], gl: &[Vec3; 4]) -> [Vec3; 10] {
    let mut g = [Vec3::ZERO; 10];
    for i in 0..4 {
        g[i] = gl[i] * (4.0 * l[i] - 1.0);
    }
    for (e, [i, j]) in EDGES.iter().enumerate() {
        g[4 + e] = (gl[*i] * l[*j] + gl[*j] * l[*i]) * 4.0;
    }
    g
}

/// The 30×30 element stiffness, row-major, dofs ordered node after node. Only the corner
/// positions matter (edges are straight, mid-edge nodes at the midpoints).
pub fn stiffness(corners: &[Vec3; 4], material: &Material) -> Option<Vec<[Real; 30]>> {
    let (gl, v) = shape_gradients(corners)?;
    let (lambda, mu) = (material.lambda(), material.mu());
    let mut k = vec![[0.0; 30]; 30];
    for l in quadrature_points() {
        let g = shape_gradients_at(&l, &gl);
        let w = v.abs() / 4.0;
        for a in 0..10 {
            for b in a..10 {
                let mut blk = [[0.0; 3]; 3];
                add_block(&mut blk, g[a], g[b], lambda, mu, w);
                for i in 0..3 {
                    for j in 0..3 {
                        k[3 * a + i][3 * b + j] += blk[i][j];
                    }
                }
            }
        }
    }
    // The (b, a) blocks are the transposes of the (a, b) ones.
    for a in 0..10 {
        for b in 0..a {
            for i in 0..3 {
                for j in 0..3 {
                    k[3 * a + i][3 * b + j] = k[3 * b + j][3 * a + i];
                }
            }
        }
    }
    Some(k)
}

/// Nodal forces of a uniform body force density `b` (N/m³): ∫ N_i b dV, which is −V/20 at
/// each corner and V/5 at each mid-edge node (the total is b·V).
pub fn body_load(volume: Real, b: Vec3) -> [Vec3; 10] {
    let v = volume.abs();
    let mut f = [b * (-v / 20.0); 10];
    for fi in f.iter_mut().skip(4) {
        *fi = b * (v / 5.0);
    }
    f
}
