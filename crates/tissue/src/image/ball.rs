//! Morphology by a ball of a physical radius (metres, whatever the voxel spacing along each
//! axis), through exact Euclidean distance transforms: what "the selected voxels at
//! resolution h" means. An opening by a ball of radius r removes every part of the mask no
//! ball of radius r fits in (sheets and strands thinner than 2r); a closing fills every gap
//! of the background no such ball fits in (cracks and channels narrower than 2r). A lattice
//! of spacing h cannot follow either when 2r ≈ h, so the mesher's boundary guarantee is
//! checked against the mask opened and closed at r = h/2 (`mesh::stuffing::report`).

use crate::math::{Real, Vec3};

/// Squared distance used for "no seed on this line yet".
const FAR: Real = 1e30;

/// `mask` (x fastest, then y, then z, over `dims`, voxel `spacing` in m) opened then closed
/// by a ball of radius `radius` (m). Beyond the image the mask is unselected, as the mesher
/// reads it, so a part cut by the image's border is opened from there too. 0 or a radius
/// smaller than every half voxel leaves the mask as it is.
pub fn open_close_ball(mask: &[bool], dims: [usize; 3], spacing: Vec3, radius: Real) -> Vec<bool> {
    padded_apply(mask, dims, spacing, radius, |padded, big| {
        let opened = open(padded, big, spacing, radius);
        close(&opened, big, spacing, radius)
    })
}

/// `mask` closed by a ball of radius `radius` (m): every crack, channel or pocket of the
/// background that no such ball fits in (narrower than 2·radius) is selected, and nothing
/// selected is removed. Beyond the image the mask is unselected, so a gap open to the
/// image's border is closed as one inside it would be, never from the outside in. 0 leaves
/// the mask as it is.
pub fn close_ball(mask: &[bool], dims: [usize; 3], spacing: Vec3, radius: Real) -> Vec<bool> {
    padded_apply(mask, dims, spacing, radius, |padded, big| {
        close(padded, big, spacing, radius)
    })
}

/// `mask` opened by a ball of radius `radius` (m): every sheet or strand of it that no such
/// ball fits in (thinner than 2·radius) is unselected, and nothing is added. 0 leaves the
/// mask as it is.
pub fn open_ball(mask: &[bool], dims: [usize; 3], spacing: Vec3, radius: Real) -> Vec<bool> {
    padded_apply(mask, dims, spacing, radius, |padded, big| {
        open(padded, big, spacing, radius)
    })
}

/// `filter` applied to `mask` padded by the radius and one voxel on every side, so that the
/// background beyond the image takes part as it would in an infinite image.
fn padded_apply(
    mask: &[bool],
    dims: [usize; 3],
    spacing: Vec3,
    radius: Real,
    filter: impl Fn(&[bool], [usize; 3]) -> Vec<bool>,
) -> Vec<bool> {
    if !(radius.is_finite() && radius > 0.0) || mask.len() != dims[0] * dims[1] * dims[2] {
        return mask.to_vec();
    }
    let pad = [0, 1, 2].map(|a| (radius / spacing[a]).ceil() as usize + 1);
    let big = [0, 1, 2].map(|a| dims[a] + 2 * pad[a]);
    let mut padded = vec![false; big[0] * big[1] * big[2]];
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            let src = dims[0] * (j + dims[1] * k);
            let dst = pad[0] + big[0] * ((j + pad[1]) + big[1] * (k + pad[2]));
            padded[dst..dst + dims[0]].copy_from_slice(&mask[src..src + dims[0]]);
        }
    }
    let filtered = filter(&padded, big);
    let mut out = vec![false; mask.len()];
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            let dst = dims[0] * (j + dims[1] * k);
            let src = pad[0] + big[0] * ((j + pad[1]) + big[1] * (k + pad[2]));
            out[dst..dst + dims[0]].copy_from_slice(&filtered[src..src + dims[0]]);
        }
    }
    out
}

/// The closing: the complement of the opening of the complement.
fn close(mask: &[bool], dims: [usize; 3], spacing: Vec3, r: Real) -> Vec<bool> {
    let inverted: Vec<bool> = mask.iter().map(|m| !m).collect();
    open(&inverted, dims, spacing, r)
        .iter()
        .map(|m| !m)
        .collect()
}

/// The union of the balls of radius `r` that fit in `mask`: centres farther than r from
/// every unselected voxel, then every voxel within r of a centre.
fn open(mask: &[bool], dims: [usize; 3], spacing: Vec3, r: Real) -> Vec<bool> {
    let r2 = r * r;
    let to_outside = squared_distance_to(mask, dims, spacing, false);
    let centres: Vec<bool> = to_outside.iter().map(|&d| d > r2).collect();
    squared_distance_to(&centres, dims, spacing, true)
        .iter()
        .map(|&d| d <= r2)
        .collect()
}

/// Squared Euclidean distance (m²) from every voxel centre to the nearest voxel whose mask
/// value is `target`; `FAR` or more when there is none.
fn squared_distance_to(mask: &[bool], dims: [usize; 3], spacing: Vec3, target: bool) -> Vec<Real> {
    let mut d: Vec<Real> = mask
        .iter()
        .map(|&m| if m == target { 0.0 } else { FAR })
        .collect();
    let strides = [1, dims[0], dims[0] * dims[1]];
    let mut line = Vec::new();
    let mut out = Vec::new();
    for axis in 0..3 {
        let (n, stride) = (dims[axis], strides[axis]);
        let w = spacing[axis] * spacing[axis];
        for start in 0..d.len() {
            // Each line along `axis` once, from its first voxel.
            if (start / stride) % n != 0 {
                continue;
            }
            line.clear();
            line.extend((0..n).map(|i| d[start + i * stride]));
            lower_envelope(&line, w, &mut out);
            for (i, v) in out.iter().enumerate() {
                d[start + i * stride] = *v;
            }
        }
    }
    d
}

/// One-dimensional squared distance transform (Felzenszwalb & Huttenlocher 2012): out[i] =
/// min over j of w·(i − j)² + f[j], by the lower envelope of the parabolas rooted at every j.
fn lower_envelope(f: &[Real], w: Real, out: &mut Vec<Real>) {
    let n = f.len();
    out.clear();
    out.resize(n, FAR);
    let finite: Vec<usize> = (0..n).filter(|&j| f[j] < FAR).collect();
    if finite.is_empty() {
        return;
    }
    // Vertices of the envelope's parabolas and where each starts to be the lowest.
    let mut v: Vec<usize> = Vec::with_capacity(finite.len());
    let mut z: Vec<Real> = Vec::with_capacity(finite.len() + 1);
    let meet = |q: usize, p: usize| -> Real {
        let (qf, pf) = (q as Real, p as Real);
        ((f[q] / w + qf * qf) - (f[p] / w + pf * pf)) / (2.0 * (qf - pf))
    };
    for &q in &finite {
        while let Some(&p) = v.last() {
            let s = meet(q, p);
            if z.last().is_some_and(|&zl| s <= zl) {
                v.pop();
                z.pop();
            } else {
                z.push(s);
                break;
            }
        }
        if v.is_empty() {
            z.clear();
            z.push(-Real::INFINITY);
        }
        v.push(q);
    }
    z.push(Real::INFINITY);
    let mut k = 0;
    for (i, o) in out.iter_mut().enumerate() {
        while z[k + 1] < i as Real {
            k += 1;
        }
        let dq = i as Real - v[k] as Real;
        *o = w * dq * dq + f[v[k]];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force over every pair, against the separable transform, anisotropic spacing.
    #[test]
    fn distance_transform_is_exact() {
        let dims = [7, 5, 4];
        let spacing = Vec3::new(1.0, 0.7, 2.3);
        let mask: Vec<bool> = (0..140)
            .map(|n: usize| (n * 37 + n / 3).is_multiple_of(11))
            .collect();
        let d = squared_distance_to(&mask, dims, spacing, true);
        let at = |n: usize| {
            Vec3::new((n % 7) as Real, ((n / 7) % 5) as Real, (n / 35) as Real) * spacing
        };
        for (n, got) in d.iter().enumerate() {
            let want = (0..140)
                .filter(|&m| mask[m])
                .map(|m| (at(n) - at(m)).length_squared())
                .fold(FAR, Real::min);
            assert!((got - want).abs() < 1e-9, "voxel {n}: {got} vs {want}");
        }
    }

    /// A slab 3 voxels thick survives an opening of radius 1 voxel and goes at radius 2; a
    /// crack 3 voxels wide in a block is filled by a closing of radius 2, not of radius 1;
    /// the block's thick plates keep their middle either way.
    #[test]
    fn thin_sheets_and_cracks_go_at_the_ball_radius() {
        let dims = [20, 20, 20];
        let s = Vec3::splat(0.001);
        let idx = |i: usize, j: usize, k: usize| i + 20 * (j + 20 * k);
        let mut slab = vec![false; 8000];
        let mut block = vec![false; 8000];
        for k in 0..20 {
            for j in 0..20 {
                for i in 0..20 {
                    slab[idx(i, j, k)] = (9..12).contains(&k);
                    block[idx(i, j, k)] = !(9..12).contains(&k) || i < 2;
                }
            }
        }
        assert!(open_close_ball(&slab, dims, s, 0.0011)[idx(10, 10, 10)]);
        assert!(!open_close_ball(&slab, dims, s, 0.0021).contains(&true));
        for (r, filled) in [(0.0011, false), (0.0021, true)] {
            let m = open_close_ball(&block, dims, s, r);
            assert_eq!(m[idx(10, 10, 10)], filled, "radius {r}");
            assert!(m[idx(10, 10, 4)] && m[idx(10, 10, 15)], "radius {r}");
        }
    }

    /// A closing alone, anisotropic voxels (0.78 × 0.78 × 2.5 mm, as the pelvis image's): a
    /// crack 2 voxels (1.56 mm) wide across x is filled at a radius of 1 mm, not at 0.7 mm;
    /// a sheet one voxel thick (which an opening of that radius would remove) stays, and no
    /// selected voxel is ever removed.
    #[test]
    fn a_closing_fills_cracks_narrower_than_its_diameter_and_removes_nothing() {
        let dims = [24, 12, 8];
        let s = Vec3::new(0.00078, 0.00078, 0.0025);
        let idx = |i: usize, j: usize, k: usize| i + 24 * (j + 12 * k);
        let mut m = vec![false; 24 * 12 * 8];
        for k in 1..7 {
            for j in 1..11 {
                for i in 1..23 {
                    // A block with a crack at x = 11, 12 open to its +y side, and a sheet
                    // one voxel thick at x = 22 beyond a gap of 3 voxels.
                    let crack = (11..13).contains(&i) && j > 3;
                    let gap = (19..22).contains(&i);
                    m[idx(i, j, k)] = !(crack || gap);
                }
            }
        }
        for (r, filled) in [(0.0007, false), (0.001, true)] {
            let c = close_ball(&m, dims, s, r);
            assert_eq!(c[idx(11, 6, 4)], filled, "radius {r}");
            assert!(
                m.iter().zip(&c).all(|(a, b)| !a || *b),
                "radius {r} removed voxels"
            );
            assert!(c[idx(22, 6, 4)], "radius {r}: the sheet went");
            assert!(
                !c[idx(20, 6, 4)],
                "radius {r}: the 3-voxel gap (2.34 mm) filled"
            );
        }
    }
}
