//! Spring stiffnesses from Young's modulus and Poisson's ratio, so that users give material
//! constants, not spring constants.
//!
//! - `VanGelder` (van Gelder 1998): an edge c gets k_c = E t Σ_T A_T / |c|² over the triangles
//!   T around it (membrane of thickness t), or k_c = E Σ_T V_T / |c|² over the tetrahedra.
//!   It ignores ν: a spring network has a fixed Poisson ratio (1/3 in the plane, 1/4 in space
//!   for regular lattices), the limit van Gelder proves cannot be lifted in general.
//! - `Fitted` (the approach of Lloyd, Székely & Harders 2007): per element, the spring
//!   constants whose stiffness matrix is closest, in the Frobenius norm, to the linear finite
//!   element stiffness matrix of the same element (plane stress for a membrane); edge
//!   stiffnesses are the sums over their elements. A constant the fit makes negative is set to
//!   zero in that element (a spring cannot push when stretched); an edge whose total is not
//!   positive keeps 1 % of the van Gelder value so that no spring is slack.

use serde::Deserialize;

use crate::math::{Real, Vec3, tet_signed_volume, triangle_area_vector};

/// How spring constants are derived from E and ν.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StiffnessRule {
    #[default]
    VanGelder,
    Fitted,
}

/// Index of edge (a, b) in a sorted list of unique sorted edges.
pub(crate) fn edge_index(edges: &[[u32; 2]], a: u32, b: u32) -> Option<usize> {
    let key = if a < b { [a, b] } else { [b, a] };
    edges.binary_search(&key).ok()
}

/// Stiffness of each edge of a membrane of thickness `t` (m), in N/m. `edges` is the sorted
/// list of unique edges of `triangles` (as `mesh::topology::triangle_edges` returns).
pub fn membrane_stiffness(
    x: &[Vec3],
    triangles: &[[u32; 3]],
    edges: &[[u32; 2]],
    young: Real,
    poisson: Real,
    thickness: Real,
    rule: StiffnessRule,
) -> Vec<Real> {
    let mut gelder = vec![0.0; edges.len()];
    let mut fitted = vec![0.0; edges.len()];
    for tri in triangles {
        let p = tri.map(|i| x[i as usize]);
        let area = triangle_area_vector(p[0], p[1], p[2]).length();
        for (i, j) in [(0, 1), (1, 2), (2, 0)] {
            if let Some(e) = edge_index(edges, tri[i], tri[j]) {
                let l2 = (p[j] - p[i]).length_squared();
                if l2 > 0.0 {
                    gelder[e] += young * thickness * area / l2;
                }
            }
        }
        if rule == StiffnessRule::Fitted {
            let k = triangle_fem_stiffness(&p, young, poisson, thickness);
            let pairs = [(0, 1), (1, 2), (0, 2)];
            let fit = fit_springs::<9, 3>(&p, &pairs, &k);
            for (&(i, j), kf) in pairs.iter().zip(fit) {
                if let Some(e) = edge_index(edges, tri[i], tri[j]) {
                    fitted[e] += kf;
                }
            }
        }
    }
    finish(rule, gelder, fitted)
}

/// Stiffness of each edge of a tetrahedral mesh, in N/m (`edges` as `tet_edges` returns).
pub fn tet_stiffness(
    x: &[Vec3],
    tets: &[[u32; 4]],
    edges: &[[u32; 2]],
    young: Real,
    poisson: Real,
    rule: StiffnessRule,
) -> Vec<Real> {
    let mut gelder = vec![0.0; edges.len()];
    let mut fitted = vec![0.0; edges.len()];
    let pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];
    for tet in tets {
        let p = tet.map(|i| x[i as usize]);
        let volume = tet_signed_volume(p[0], p[1], p[2], p[3]).abs();
        for &(i, j) in &pairs {
            if let Some(e) = edge_index(edges, tet[i], tet[j]) {
                let l2 = (p[j] - p[i]).length_squared();
                if l2 > 0.0 {
                    gelder[e] += young * volume / l2;
                }
            }
        }
        if rule == StiffnessRule::Fitted {
            let k = tet_fem_stiffness(&p, young, poisson);
            let fit = fit_springs::<12, 4>(&p, &pairs, &k);
            for (&(i, j), kf) in pairs.iter().zip(fit) {
                if let Some(e) = edge_index(edges, tet[i], tet[j]) {
                    fitted[e] += kf;
                }
            }
        }
    }
    finish(rule, gelder, fitted)
}

fn finish(rule: StiffnessRule, gelder: Vec<Real>, fitted: Vec<Real>) -> Vec<Real> {
    match rule {
        StiffnessRule::VanGelder => gelder,
        StiffnessRule::Fitted => fitted
            .into_iter()
            .zip(gelder)
            .map(|(f, g)| if f > 0.01 * g { f } else { 0.01 * g })
            .collect(),
    }
}

/// Gradients of the barycentric coordinates of a tetrahedron (zero if it is flat).
fn tet_gradients(p: &[Vec3; 4]) -> ([Vec3; 4], Real) {
    let (e1, e2, e3) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let det = e1.dot(e2.cross(e3));
    if det.abs() <= Real::MIN_POSITIVE {
        return ([Vec3::ZERO; 4], 0.0);
    }
    let g1 = e2.cross(e3) / det;
    let g2 = e3.cross(e1) / det;
    let g3 = e1.cross(e2) / det;
    ([-(g1 + g2 + g3), g1, g2, g3], det.abs() / 6.0)
}

/// Linear elastic stiffness K_ab = V [λ g_a g_bᵀ + μ g_b g_aᵀ + μ (g_a·g_b) I], dense 12×12.
pub(crate) fn tet_fem_stiffness(p: &[Vec3; 4], young: Real, poisson: Real) -> [[Real; 12]; 12] {
    let (g, volume) = tet_gradients(p);
    let lambda = young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
    let mu = young / (2.0 * (1.0 + poisson));
    element_stiffness::<12, 4>(&g, volume, lambda, mu, None)
}

/// Plane-stress membrane stiffness of a triangle of thickness t, dense 9×9, in space.
pub(crate) fn triangle_fem_stiffness(
    p: &[Vec3; 3],
    young: Real,
    poisson: Real,
    thickness: Real,
) -> [[Real; 9]; 9] {
    let av = triangle_area_vector(p[0], p[1], p[2]);
    let area = av.length();
    if area <= Real::MIN_POSITIVE {
        return [[0.0; 9]; 9];
    }
    let n = av / area;
    // Gradient of the barycentric coordinate of a corner: n × (opposite edge) / 2A.
    let g = [0, 1, 2].map(|a| n.cross(p[(a + 2) % 3] - p[(a + 1) % 3]) / (2.0 * area));
    let lambda = young * poisson / (1.0 - poisson * poisson);
    let mu = young / (2.0 * (1.0 + poisson));
    element_stiffness::<9, 3>(&g, area * thickness, lambda, mu, Some(n))
}

/// K_ab = w [λ g_a g_bᵀ + μ g_b g_aᵀ + μ (g_a·g_b) P], P the identity (or in-plane projector).
fn element_stiffness<const D: usize, const N: usize>(
    g: &[Vec3; N],
    w: Real,
    lambda: Real,
    mu: Real,
    normal: Option<Vec3>,
) -> [[Real; D]; D] {
    let mut k = [[0.0; D]; D];
    for a in 0..N {
        for b in 0..N {
            let dot = g[a].dot(g[b]);
            for i in 0..3 {
                for j in 0..3 {
                    let identity = match normal {
                        None => Real::from(u8::from(i == j)),
                        Some(n) => Real::from(u8::from(i == j)) - n[i] * n[j],
                    };
                    k[3 * a + i][3 * b + j] = w
                        * (lambda * g[a][i] * g[b][j]
                            + mu * g[b][i] * g[a][j]
                            + mu * dot * identity);
                }
            }
        }
    }
    k
}

/// The spring constants (one per corner pair) whose summed stiffness matrix is closest to `k`
/// in the Frobenius norm: the normal equations of a small least-squares problem.
fn fit_springs<const D: usize, const N: usize>(
    p: &[Vec3; N],
    pairs: &[(usize, usize)],
    k: &[[Real; D]; D],
) -> Vec<Real> {
    let m = pairs.len();
    // Each spring's unit-stiffness matrix, dense.
    let basis: Vec<[[Real; D]; D]> = pairs
        .iter()
        .map(|&(a, b)| {
            let mut s = [[0.0; D]; D];
            let u = (p[b] - p[a]).normalize_or_zero();
            for i in 0..3 {
                for j in 0..3 {
                    let uu = u[i] * u[j];
                    s[3 * a + i][3 * a + j] = uu;
                    s[3 * b + i][3 * b + j] = uu;
                    s[3 * a + i][3 * b + j] = -uu;
                    s[3 * b + i][3 * a + j] = -uu;
                }
            }
            s
        })
        .collect();
    let inner = |x: &[[Real; D]; D], y: &[[Real; D]; D]| -> Real {
        x.iter()
            .zip(y)
            .map(|(r, s)| r.iter().zip(s).map(|(a, b)| a * b).sum::<Real>())
            .sum()
    };
    let mut gram = vec![vec![0.0; m + 1]; m];
    for e in 0..m {
        for f in 0..m {
            gram[e][f] = inner(&basis[e], &basis[f]);
        }
        gram[e][m] = inner(&basis[e], k);
    }
    solve_dense(gram)
        .unwrap_or_else(|| vec![0.0; m])
        .into_iter()
        .map(|c| c.max(0.0))
        .collect()
}

/// Gaussian elimination with partial pivoting on an augmented matrix; `None` if singular.
fn solve_dense(mut a: Vec<Vec<Real>>) -> Option<Vec<Real>> {
    let n = a.len();
    let scale = a.iter().flatten().fold(0.0, |s: Real, v| s.max(v.abs()));
    for c in 0..n {
        let pivot = (c..n).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[pivot][c].abs() <= 1e-12 * scale {
            return None;
        }
        a.swap(c, pivot);
        let (top, rest) = a.split_at_mut(c + 1);
        let pivot_row = &top[c];
        for row in rest.iter_mut() {
            let f = row[c] / pivot_row[c];
            for (x, p) in row[c..].iter_mut().zip(&pivot_row[c..]) {
                *x -= f * p;
            }
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: Real = (r + 1..n).map(|k| a[r][k] * x[k]).sum();
        x[r] = (a[r][n] - s) / a[r][r];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::topology::{tet_edges, triangle_edges};

    fn equilateral() -> Vec<Vec3> {
        vec![Vec3::ZERO, Vec3::X, Vec3::new(0.5, 0.75_f64.sqrt(), 0.0)]
    }

    #[test]
    fn van_gelder_on_an_equilateral_triangle() {
        // One triangle: k = E t A / a² = E t √3/4 for every edge.
        let x = equilateral();
        let tris = [[0, 1, 2]];
        let edges = triangle_edges(&tris);
        let k = membrane_stiffness(
            &x,
            &tris,
            &edges,
            1000.0,
            0.3,
            0.01,
            StiffnessRule::VanGelder,
        );
        for kc in k {
            assert!(
                (kc - 1000.0 * 0.01 * 3f64.sqrt() / 4.0).abs() < 1e-12,
                "{kc}"
            );
        }
    }

    #[test]
    fn fit_agrees_with_van_gelder_where_springs_are_exact() {
        // Lloyd et al.: for ν = 1/3 an equilateral triangle of springs k = √3/4 E t reproduces
        // the plane-stress element exactly; the fit must find it.
        let x = equilateral();
        let tris = [[0, 1, 2]];
        let edges = triangle_edges(&tris);
        let f = membrane_stiffness(
            &x,
            &tris,
            &edges,
            1000.0,
            1.0 / 3.0,
            0.01,
            StiffnessRule::Fitted,
        );
        let g = membrane_stiffness(
            &x,
            &tris,
            &edges,
            1000.0,
            1.0 / 3.0,
            0.01,
            StiffnessRule::VanGelder,
        );
        for (a, b) in f.iter().zip(&g) {
            assert!((a - b).abs() < 1e-9 * b, "{a} vs {b}");
        }
        // And the spring matrix then equals the FEM matrix.
        let p = [x[0], x[1], x[2]];
        let kf = triangle_fem_stiffness(&p, 1000.0, 1.0 / 3.0, 0.01);
        let pairs = [(0, 1), (1, 2), (0, 2)];
        let c = fit_springs::<9, 3>(&p, &pairs, &kf);
        let residual = residual_norm::<9, 3>(&p, &pairs, &c, &kf);
        assert!(residual < 1e-9, "{residual}");
    }

    fn residual_norm<const D: usize, const N: usize>(
        p: &[Vec3; N],
        pairs: &[(usize, usize)],
        c: &[Real],
        k: &[[Real; D]; D],
    ) -> Real {
        let mut r = *k;
        for (&(a, b), kc) in pairs.iter().zip(c) {
            let u = (p[b] - p[a]).normalize();
            for i in 0..3 {
                for j in 0..3 {
                    let v = kc * u[i] * u[j];
                    r[3 * a + i][3 * a + j] -= v;
                    r[3 * b + i][3 * b + j] -= v;
                    r[3 * a + i][3 * b + j] += v;
                    r[3 * b + i][3 * a + j] += v;
                }
            }
        }
        let norm = |m: &[[Real; D]; D]| m.iter().flatten().map(|v| v * v).sum::<Real>().sqrt();
        norm(&r) / norm(k)
    }

    #[test]
    fn fem_stiffness_has_rigid_null_space() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(0.2, 0.3, 1.0)];
        let k = tet_fem_stiffness(&p, 5000.0, 0.45);
        let w = Vec3::new(0.3, -0.5, 0.8);
        let rot: Vec<Real> = p.iter().flat_map(|q| w.cross(*q).to_array()).collect();
        for row in &k {
            let kr: Real = row.iter().zip(&rot).map(|(a, b)| a * b).sum();
            assert!(kr.abs() < 1e-9, "{kr}");
        }
    }

    #[test]
    fn tet_rules_give_positive_constants_on_a_box() {
        use crate::mesh::generate::{BoxSplit, box_tets};
        let m = box_tets(Vec3::ZERO, Vec3::ONE, [2, 2, 2], BoxSplit::Six);
        let edges = tet_edges(&m.tets);
        for rule in [StiffnessRule::VanGelder, StiffnessRule::Fitted] {
            let k = tet_stiffness(&m.vertices, &m.tets, &edges, 1000.0, 0.3, rule);
            assert_eq!(k.len(), edges.len());
            assert!(k.iter().all(|&c| c > 0.0 && c.is_finite()), "{rule:?}");
        }
        // Van Gelder sums V/l² over the tets around each edge: total = E Σ_T Σ_edges V_T/l².
        let k = tet_stiffness(
            &m.vertices,
            &m.tets,
            &edges,
            1000.0,
            0.3,
            StiffnessRule::VanGelder,
        );
        let total: Real = k.iter().sum();
        let expected: Real = (0..m.tets.len())
            .map(|t| {
                let p = m.corners(t);
                let v = m.tet_volume(t).abs();
                [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
                    .iter()
                    .map(|&(i, j)| 1000.0 * v / (p[j] - p[i]).length_squared())
                    .sum::<Real>()
            })
            .sum();
        assert!((total - expected).abs() < 1e-9 * expected);
    }
}
