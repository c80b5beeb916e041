//! Fitting a spline surface to a triangle mesh (or to points with known parameters) by
//! least squares, so a scene can start from an organ mesh of sheet or tube topology.
//!
//! A single tensor-product patch is a rectangle whose u edges may be glued (periodic): it can
//! only be a disc (a sheet: one boundary loop) or an annulus (a tube: two boundary loops). The
//! mesh's topology is classified first (components, non-manifold edges, boundary loops,
//! Euler characteristic) and anything else is refused with the reason, e.g. a closed genus-0
//! organ (a liver) would need several patches or degenerate poles.
//!
//! Parameterisation (simple on purpose, and said so in the errors):
//! - tube: the axis runs from the centroid of one boundary loop to the other's; v is the
//!   projection on the axis, u the angle around it. Suits straight-ish vessels and ducts.
//! - sheet: projection on the mean plane (area-weighted normal), axes along the principal
//!   directions in that plane, scaled to the bounding rectangle. The sheet must not fold over
//!   that plane (checked per triangle).
//!
//! The control points solve (NᵀN + λR) P = Nᵀp with N the basis at the data parameters and R
//! the squared second differences of the control net along u and v: the smoothing term fills
//! control points that no data touches (e.g. the corners of a round sheet) and damps
//! wiggles; λ = `smoothing` × trace(NᵀN) / count.

use std::f64::consts::TAU;

use crate::error::{MeshError, SimError};
use crate::math::{Real, Vec3, is_finite_vec};
use crate::mesh::topology::{UnionFind, components, edge_faces, euler_characteristic};
use crate::solve::{BlockPattern, SparseCholesky};

use super::basis::{Basis, KnotKind};
use super::surface::{Deriv, SplineSurface, check_net_size};

/// What a single spline patch can represent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Topology {
    /// A disc: one boundary loop (clamped in u and v).
    Sheet,
    /// An annulus: two boundary loops (periodic in u, clamped in v).
    Tube,
}

/// A fitted surface and how well it matches the data.
#[derive(Clone, Debug)]
pub struct Fit {
    pub surface: SplineSurface,
    pub topology: Topology,
    /// Root-mean-square and largest distance from a data point to S(its parameters), in m.
    pub rms_error: Real,
    pub max_error: Real,
}

fn refuse(reason: String) -> SimError {
    SimError::Unsupported {
        model: "spline",
        operation: "fitting this mesh",
        reason,
    }
}

/// Sheet or tube, or the reason the mesh is neither.
pub fn classify(vertices: &[Vec3], triangles: &[[u32; 3]]) -> Result<Topology, SimError> {
    if triangles.is_empty() {
        return Err(MeshError::Empty { what: "triangles" }.into());
    }
    for (t, tri) in triangles.iter().enumerate() {
        for &v in tri {
            if v as usize >= vertices.len() {
                return Err(MeshError::IndexOutOfRange {
                    element_kind: "triangle",
                    element: t,
                    index: v as usize,
                    vertex_count: vertices.len(),
                }
                .into());
            }
        }
    }
    if let Some((v, p)) = vertices
        .iter()
        .enumerate()
        .find(|(_, p)| !is_finite_vec(**p))
    {
        return Err(MeshError::NonFiniteVertex {
            vertex: v,
            x: p.x,
            y: p.y,
            z: p.z,
        }
        .into());
    }
    let parts = components(triangles).count;
    if parts != 1 {
        return Err(refuse(format!(
            "it has {parts} separate components; one spline patch is one connected surface"
        )));
    }
    let ef = edge_faces(triangles);
    if let Some((e, f)) = ef.non_manifold_edges().next() {
        return Err(MeshError::NonManifoldEdge {
            a: e[0] as usize,
            b: e[1] as usize,
            faces: f.len(),
        }
        .into());
    }
    let loops = border_loops(&ef.border_edges().collect::<Vec<_>>()).len() as i64;
    let chi = euler_characteristic(triangles);
    let genus = (2 - chi - loops) / 2;
    match (loops, genus) {
        (1, 0) => Ok(Topology::Sheet),
        (2, 0) => Ok(Topology::Tube),
        (0, 0) => Err(refuse(
            "it is a closed surface of genus 0 (a whole organ, no boundary); a tensor-product \
             spline patch covers only a sheet (one boundary loop) or a tube (two, periodic \
             around); use a volumetric model or open the surface"
                .into(),
        )),
        (0, g) => Err(refuse(format!(
            "it is a closed surface of genus {g} (no boundary); one patch covers only a sheet or a tube"
        ))),
        (b, g) => Err(refuse(format!(
            "it has {b} boundary loops and genus {g}; one patch covers only a sheet (1 loop, genus 0) \
             or a tube (2 loops, genus 0)"
        ))),
    }
}

/// The vertex sets of the boundary loops (connected components of the border edges).
fn border_loops(edges: &[[u32; 2]]) -> Vec<Vec<u32>> {
    let mut ids: Vec<u32> = edges.iter().flatten().copied().collect();
    ids.sort_unstable();
    ids.dedup();
    let slot = |v: u32| ids.binary_search(&v).unwrap_or(0);
    let mut uf = UnionFind::new(ids.len());
    for e in edges {
        uf.union(slot(e[0]), slot(e[1]));
    }
    let mut groups: Vec<(usize, u32)> = ids.iter().map(|&v| (uf.find(slot(v)), v)).collect();
    groups.sort_unstable();
    groups
        .chunk_by(|a, b| a.0 == b.0)
        .map(|g| g.iter().map(|x| x.1).collect())
        .collect()
}

/// Fits a `nu` × `nv` control net to a sheet or tube mesh (unused vertices are ignored).
pub fn fit_mesh(
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    nu: usize,
    nv: usize,
    smoothing: Real,
) -> Result<Fit, SimError> {
    check_net_size(nu, nv)?;
    let topology = classify(vertices, triangles)?;
    let mut used = vec![false; vertices.len()];
    triangles
        .iter()
        .flatten()
        .for_each(|&v| used[v as usize] = true);
    let params = match topology {
        Topology::Tube => tube_parameters(vertices, triangles)?,
        Topology::Sheet => sheet_parameters(vertices, triangles, &used)?,
    };
    let (points, params): (Vec<Vec3>, Vec<(Real, Real)>) = vertices
        .iter()
        .zip(params)
        .zip(&used)
        .filter(|(_, u)| **u)
        .map(|(pp, _)| (*pp.0, pp.1))
        .unzip();
    let kind = match topology {
        Topology::Tube => KnotKind::Periodic,
        Topology::Sheet => KnotKind::Clamped,
    };
    let (bu, bv) = (Basis::new(kind, nu)?, Basis::clamped(nv)?);
    let surface = fit_points(&points, &params, bu, bv, smoothing)?;
    let errors: Vec<Real> = points
        .iter()
        .zip(&params)
        .map(|(p, &(s, t))| surface.point(s, t).distance(*p))
        .collect();
    let rms_error =
        (errors.iter().map(|e| e * e).sum::<Real>() / errors.len().max(1) as Real).sqrt();
    let max_error = errors.iter().copied().fold(0.0, Real::max);
    Ok(Fit {
        surface,
        topology,
        rms_error,
        max_error,
    })
}

fn tube_parameters(
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
) -> Result<Vec<(Real, Real)>, SimError> {
    let ef = edge_faces(triangles);
    let loops = border_loops(&ef.border_edges().collect::<Vec<_>>());
    let centroid =
        |l: &[u32]| l.iter().map(|&v| vertices[v as usize]).sum::<Vec3>() / l.len().max(1) as Real;
    let (c0, c1) = match loops.as_slice() {
        [a, b] => (centroid(a), centroid(b)),
        _ => return Err(refuse("a tube needs exactly two boundary loops".into())),
    };
    let axis = c1 - c0;
    let length = axis.length();
    let first = loops
        .first()
        .and_then(|l| l.first())
        .map(|&v| vertices[v as usize])
        .unwrap_or(c0);
    let d = if length > 0.0 {
        axis / length
    } else {
        Vec3::ZERO
    };
    let e1 = (first - c0) - (first - c0).dot(d) * d;
    if length <= 0.0 || e1.length() <= 1e-9 * length {
        return Err(refuse(
            "its two boundary loops have the same centroid or lie on the axis; the tube \
             parameterisation needs the ends apart along a straight-ish axis"
                .into(),
        ));
    }
    let e1 = e1.normalize();
    let e2 = d.cross(e1);
    Ok(vertices
        .iter()
        .map(|p| {
            let r = *p - c0;
            let v = (r.dot(d) / length).clamp(0.0, 1.0);
            let u = (r.dot(e2).atan2(r.dot(e1)) / TAU).rem_euclid(1.0);
            (u, v)
        })
        .collect())
}

fn sheet_parameters(
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    used: &[bool],
) -> Result<Vec<(Real, Real)>, SimError> {
    let corner = |t: &[u32; 3], k: usize| vertices[t[k] as usize];
    let normal: Vec3 = triangles
        .iter()
        .map(|t| (corner(t, 1) - corner(t, 0)).cross(corner(t, 2) - corner(t, 0)))
        .sum();
    if normal.length() <= 0.0 {
        return Err(refuse(
            "the sheet has no mean plane (its area vectors cancel)".into(),
        ));
    }
    let n = normal.normalize();
    let count = used.iter().filter(|u| **u).count().max(1) as Real;
    let c = vertices
        .iter()
        .zip(used)
        .filter(|(_, u)| **u)
        .map(|(p, _)| *p)
        .sum::<Vec3>()
        / count;
    // Principal directions within the plane: eigenvectors of the 2 × 2 covariance.
    let a = n.any_orthonormal_vector();
    let b = n.cross(a);
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for (p, _) in vertices.iter().zip(used).filter(|(_, u)| **u) {
        let (x, y) = ((*p - c).dot(a), (*p - c).dot(b));
        sxx += x * x;
        syy += y * y;
        sxy += x * y;
    }
    // The patch covers the bounding rectangle of the projection: orient it to the smallest
    // rectangle among the principal axes and the directions of (up to 256) border edges, so
    // that a square sheet (isotropic covariance, arbitrary principal axes) gets its own edges.
    let mut angles = vec![0.5 * (2.0 * sxy).atan2(sxx - syy)];
    let border: Vec<[u32; 2]> = edge_faces(triangles).border_edges().collect();
    let stride = border.len().div_ceil(256).max(1);
    for e in border.iter().step_by(stride) {
        let d = vertices[e[1] as usize] - vertices[e[0] as usize];
        angles.push(d.dot(b).atan2(d.dot(a)));
    }
    let area_at = |angle: Real| {
        let (e1, e2) = (
            angle.cos() * a + angle.sin() * b,
            angle.sin() * -a + angle.cos() * b,
        );
        let (mut lo, mut hi) = ([Real::INFINITY; 2], [Real::NEG_INFINITY; 2]);
        for (p, _) in vertices.iter().zip(used).filter(|(_, u)| **u) {
            let q = [(*p - c).dot(e1), (*p - c).dot(e2)];
            for k in 0..2 {
                lo[k] = lo[k].min(q[k]);
                hi[k] = hi[k].max(q[k]);
            }
        }
        (hi[0] - lo[0]) * (hi[1] - lo[1])
    };
    let mut angle = angles[0];
    let mut best = area_at(angle);
    for &t in &angles[1..] {
        let area = area_at(t);
        // Prefer the principal axes unless an edge direction is clearly tighter.
        if area < best * (1.0 - 1e-9) {
            (angle, best) = (t, area);
        }
    }
    let e1 = angle.cos() * a + angle.sin() * b;
    let e2 = n.cross(e1);
    let proj: Vec<(Real, Real)> = vertices
        .iter()
        .map(|p| ((*p - c).dot(e1), (*p - c).dot(e2)))
        .collect();
    for (t, tri) in triangles.iter().enumerate() {
        let [p, q, r] = tri.map(|v| proj[v as usize]);
        let area = (q.0 - p.0) * (r.1 - p.1) - (q.1 - p.1) * (r.0 - p.0);
        if area <= 0.0 {
            return Err(refuse(format!(
                "the sheet folds over its mean plane at triangle {t}; the fit needs a sheet that \
                 is a height field over that plane"
            )));
        }
    }
    let (mut lo, mut hi) = (
        (Real::INFINITY, Real::INFINITY),
        (Real::NEG_INFINITY, Real::NEG_INFINITY),
    );
    for (p, _) in proj.iter().zip(used).filter(|(_, u)| **u) {
        lo = (lo.0.min(p.0), lo.1.min(p.1));
        hi = (hi.0.max(p.0), hi.1.max(p.1));
    }
    let (wx, wy) = (
        (hi.0 - lo.0).max(Real::MIN_POSITIVE),
        (hi.1 - lo.1).max(Real::MIN_POSITIVE),
    );
    Ok(proj
        .iter()
        .map(|p| ((p.0 - lo.0) / wx, (p.1 - lo.1) / wy))
        .collect())
}

/// Least-squares control net for points with known parameters (see the module doc).
pub fn fit_points(
    points: &[Vec3],
    params: &[(Real, Real)],
    u: Basis,
    v: Basis,
    smoothing: Real,
) -> Result<SplineSurface, SimError> {
    if !(smoothing.is_finite() && smoothing > 0.0) {
        return Err(SimError::BadParameter {
            name: "smoothing",
            value: smoothing.to_string(),
            reason: "must be a finite value > 0 (it keeps control points without data defined)"
                .into(),
        });
    }
    if points.len() != params.len() || points.is_empty() {
        return Err(SimError::BadParameter {
            name: "points",
            value: format!("{} points, {} parameters", points.len(), params.len()),
            reason: "needs one (u, v) per point and at least one point".into(),
        });
    }
    let (nu, nv) = (u.count(), v.count());
    check_net_size(nu, nv)?;
    let n = nu * nv;
    let shape = SplineSurface::new(u, v, vec![Vec3::ZERO; n])?;
    let stencils: Vec<_> = params.iter().map(|&(s, t)| shape.stencil(s, t)).collect();
    // Second-difference triples along u (wrapping when periodic) and along v.
    let periodic = shape.u.kind() == KnotKind::Periodic;
    let mut triples: Vec<[usize; 3]> = Vec::new();
    for j in 0..nv {
        for i in 0..nu {
            let id = |i: usize, j: usize| i + nu * j;
            if periodic || (i >= 1 && i + 1 < nu) {
                triples.push([id((i + nu - 1) % nu, j), id(i, j), id((i + 1) % nu, j)]);
            }
            if j >= 1 && j + 1 < nv {
                triples.push([id(i, j - 1), id(i, j), id(i, j + 1)]);
            }
        }
    }
    let mut elements: Vec<u32> = Vec::with_capacity(16 * (stencils.len() + triples.len()));
    for st in &stencils {
        elements.extend((0..16).map(|k| st.node(k) as u32));
    }
    for t in &triples {
        elements.extend((0..16).map(|k| t[k.min(2)] as u32));
    }
    let pattern = BlockPattern::from_elements(n, 1, &elements, 16);
    let mut values = vec![0.0; pattern.nnz()];
    let mut rhs = vec![Vec3::ZERO; n];
    let add = |values: &mut [Real], a: usize, b: usize, x: Real| {
        if let Some(s) = pattern.slot(a, b) {
            values[s] += x;
        }
    };
    let mut trace = 0.0;
    for (st, p) in stencils.iter().zip(points) {
        let w = st.weights(Deriv::Value);
        for a in 0..16 {
            rhs[st.node(a)] += w[a] * *p;
            trace += w[a] * w[a];
            for b in 0..16 {
                add(&mut values, st.node(a), st.node(b), w[a] * w[b]);
            }
        }
    }
    let lambda = smoothing * trace / n as Real;
    for t in &triples {
        let c = [1.0, -2.0, 1.0];
        for a in 0..3 {
            for b in 0..3 {
                add(&mut values, t[a], t[b], lambda * c[a] * c[b]);
            }
        }
    }
    let mut chol = SparseCholesky::new(&pattern)?;
    chol.factorize(
        &pattern,
        &values,
        "the fit's normal equations are singular (too few data points?)",
    )?;
    let mut control = vec![Vec3::ZERO; n];
    for axis in 0..3 {
        let mut b: Vec<Real> = rhs.iter().map(|r| r[axis]).collect();
        chol.solve_in_place(&mut b)?;
        for (c, x) in control.iter_mut().zip(b) {
            c[axis] = x;
        }
    }
    SplineSurface::new(shape.u, shape.v, control)
}

#[cfg(test)]
#[path = "fit_tests.rs"]
mod tests;
