//! The 4-node (linear) tetrahedron: constant strain, so one evaluation of the gradients is
//! exact.
//!
//! Shape functions are the barycentric coordinates N_a; their gradients ∇N_a are constant.
//! For an isotropic material the 3×3 block of the stiffness coupling nodes a and b is
//! K_ab = V (λ ∇N_a ∇N_bᵀ + μ ∇N_b ∇N_aᵀ + μ (∇N_a·∇N_b) I), which equals V Bᵀ D B with the
//! usual 6×12 strain-displacement matrix B (Voigt order xx, yy, zz, yz, xz, xy with
//! engineering shear strains); `b_matrix` and `elasticity_matrix` are kept to check that.

use crate::material::Material;
use crate::math::{Mat3, Real, Vec3};

/// Gradients of the four barycentric shape functions and the signed volume of the tet.
/// `None` for a flat tetrahedron (the mesh validation rejects those first).
pub fn shape_gradients(x: &[Vec3; 4]) -> Option<([Vec3; 4], Real)> {
    let j = Mat3::from_cols(x[1] - x[0], x[2] - x[0], x[3] - x[0]);
    let det = j.determinant();
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    // ∂ξ_k/∂x is row k of J⁻¹: the gradient of the barycentric coordinate of corner k+1.
    let inv = j.inverse();
    let g1 = inv.row(0);
    let g2 = inv.row(1);
    let g3 = inv.row(2);
    Some(([-(g1 + g2 + g3), g1, g2, g3], det / 6.0))
}

/// Adds `weight · (λ a bᵀ + μ b aᵀ + μ (a·b) I)` to the 3×3 block `k` (row-major), the
/// stiffness density coupling a node with gradient `a` (rows) to a node with gradient `b`.
#[inline]
pub fn add_block(k: &mut [[Real; 3]; 3], a: Vec3, b: Vec3, lambda: Real, mu: Real, weight: Real) {
    let (a, b) = (a.to_array(), b.to_array());
    let ab = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    for i in 0..3 {
        for j in 0..3 {
            k[i][j] += weight * (lambda * a[i] * b[j] + mu * a[j] * b[i]);
        }
        k[i][i] += weight * mu * ab;
    }
}

/// The 12×12 element stiffness, row-major, dofs ordered (node 0 x, y, z, node 1 x, ...).
pub fn stiffness(x: &[Vec3; 4], material: &Material) -> Option<[[Real; 12]; 12]> {
    let (g, v) = shape_gradients(x)?;
    let (lambda, mu) = (material.lambda(), material.mu());
    let mut k = [[0.0; 12]; 12];
    for a in 0..4 {
        for b in 0..4 {
            let mut blk = [[0.0; 3]; 3];
            add_block(&mut blk, g[a], g[b], lambda, mu, v.abs());
            for i in 0..3 {
                for j in 0..3 {
                    k[3 * a + i][3 * b + j] = blk[i][j];
                }
            }
        }
    }
    Some(k)
}

/// Nodal forces of a uniform body force density `b` (N/m³) over the tet: a quarter of b·V
/// on each corner. The consistent and the lumped loads agree for the linear tet, because
/// each shape function integrates to V/4.
pub fn body_load(volume: Real, b: Vec3) -> [Vec3; 4] {
    [b * (volume.abs() / 4.0); 4]
}

/// The 6×12 strain-displacement matrix B (strain = B u), Voigt order xx, yy, zz, yz, xz, xy.
pub fn b_matrix(g: &[Vec3; 4]) -> [[Real; 12]; 6] {
    let mut b = [[0.0; 12]; 6];
    for (a, ga) in g.iter().enumerate() {
        let c = 3 * a;
        b[0][c] = ga.x;
        b[1][c + 1] = ga.y;
        b[2][c + 2] = ga.z;
        b[3][c + 1] = ga.z;
        b[3][c + 2] = ga.y;
        b[4][c] = ga.z;
        b[4][c + 2] = ga.x;
        b[5][c] = ga.y;
        b[5][c + 1] = ga.x;
    }
    b
}

/// The isotropic 6×6 elasticity matrix D (stress = D strain), same Voigt order as `b_matrix`.
pub fn elasticity_matrix(material: &Material) -> [[Real; 6]; 6] {
    let (l, m) = (material.lambda(), material.mu());
    let mut d = [[0.0; 6]; 6];
    for (i, row) in d.iter_mut().enumerate().take(3) {
        for (j, v) in row.iter_mut().enumerate().take(3) {
            *v = l + if i == j { 2.0 * m } else { 0.0 };
        }
    }
    for (i, row) in d.iter_mut().enumerate().skip(3) {
        row[i] = m;
    }
    d
}
