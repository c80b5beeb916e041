//! What is meshed: a region of space given by a function negative inside, positive outside
//! (an implicit shape, the signed side of a closed surface, an image's thresholded field).
//! Stuffing reads only its sign at lattice points and where it changes along lattice edges.

use crate::math::{Real, Vec3};

use super::triangle_index::TriangleIndex;

/// A region to mesh. Implementations: `Implicit`, `SurfaceDomain`, `ImageDomain`.
pub trait Domain: Sync {
    /// Negative inside, positive outside, zero on the boundary. Only the sign is used for
    /// meshing; its magnitude helps the report's distance estimate.
    fn value(&self, p: Vec3) -> Real;

    /// A point of the boundary on the segment from `inside` (value < 0) to `outside`
    /// (value > 0). Default: bisection on the sign, then a secant step in the last bracket.
    fn cut(&self, inside: Vec3, outside: Vec3) -> Vec3 {
        bisect(|p| self.value(p), inside, outside)
    }

    /// A box holding the whole inside (min, max).
    fn bounds(&self) -> (Vec3, Vec3);

    /// Distance from `p` to the boundary, for the report. Default: the first-order estimate
    /// |f| / |∇f| with a central-difference gradient of step `step`.
    fn boundary_distance(&self, p: Vec3, step: Real) -> Real {
        let f = self.value(p);
        let g = Vec3::new(
            self.value(p + step * Vec3::X) - self.value(p - step * Vec3::X),
            self.value(p + step * Vec3::Y) - self.value(p - step * Vec3::Y),
            self.value(p + step * Vec3::Z) - self.value(p - step * Vec3::Z),
        ) / (2.0 * step);
        let n = g.length();
        if n > 0.0 { f.abs() / n } else { Real::INFINITY }
    }

    /// Points on the boundary, about `spacing` apart, for the distance from the input to the
    /// mesh. Default: where the sign changes along lines parallel to x, y and z through a
    /// grid of that spacing.
    fn boundary_samples(&self, spacing: Real) -> Vec<Vec3> {
        line_crossings(self, spacing)
    }

    /// The inside's volume (m³) when the input states it: a closed surface's enclosed
    /// volume, an image's voxel volume. `None` for a shape given only by its function.
    fn reference_volume(&self) -> Option<Real> {
        None
    }

    /// What cleaning an image's selected voxels changed, and their volume (m³) before it.
    fn cleaning(&self) -> Option<(crate::image::CleanReport, Real)> {
        None
    }

    /// The input as a lattice of spacing `size` can follow it, when it has features thinner
    /// than that to drop (an image: `ImageDomain::at_resolution`); `None` when the domain
    /// is its own best description (a surface, a function).
    fn at_resolution(&self, _size: Real) -> Option<Box<dyn Domain>> {
        None
    }

    /// The physical tag of the region holding `p` (several labels of one image); 1 by
    /// default.
    fn tag_at(&self, _p: Vec3) -> i32 {
        1
    }

    /// Whether the input is one piece (an image whose largest part was kept): a mesh in
    /// several pieces then keeps its largest (`pieces`).
    fn one_piece(&self) -> bool {
        false
    }

    /// The input surface, indexed, when the domain is one (exact boundary distances).
    fn surface_index(&self) -> Option<&TriangleIndex> {
        None
    }

    /// The tags of the regions meshed as separate materials, whose interfaces the mesh
    /// follows with its faces (several labels of one image). Empty (the default): the
    /// inside is one region, each tetrahedron tagged by `tag_at`.
    fn material_tags(&self) -> &[i32] {
        &[]
    }

    /// The material (an index into `material_tags`) holding `p`, a point inside.
    fn material_at(&self, _p: Vec3) -> usize {
        0
    }

    /// Negative on material `a`'s side of its interface with material `b`, positive on
    /// `b`'s, zero on it (only its sign matters for meshing; its magnitude helps the
    /// report's distance estimate).
    fn interface_value(&self, _p: Vec3, _a: usize, _b: usize) -> Real {
        0.0
    }

    /// A point of the interface between material `a` (at `pa`) and `b` (at `pb`) on the
    /// segment between them. Default: bisection on `interface_value`.
    fn interface_cut(&self, pa: Vec3, a: usize, pb: Vec3, b: usize) -> Vec3 {
        bisect(|p| self.interface_value(p, a, b), pa, pb)
    }

    /// Each material's volume (m³) as the input states it (an image's voxels of that
    /// label), in the order of `material_tags`; empty when unknown.
    fn material_volumes(&self) -> Vec<Real> {
        Vec::new()
    }
}

/// A shape given by a function (negative inside) and a box that holds it.
pub struct Implicit<F> {
    pub f: F,
    pub lo: Vec3,
    pub hi: Vec3,
    /// The exact volume, when known (a sphere's 4πr³/3), for the report.
    pub volume: Option<Real>,
}

impl<F: Fn(Vec3) -> Real + Sync> Domain for Implicit<F> {
    fn value(&self, p: Vec3) -> Real {
        (self.f)(p)
    }
    fn bounds(&self) -> (Vec3, Vec3) {
        (self.lo, self.hi)
    }
    fn reference_volume(&self) -> Option<Real> {
        self.volume
    }
}

/// Bisection on the sign of `f` from `a` (negative) to `b` (positive), 40 halvings (a
/// bracket 1e-12 of the segment), then the secant point inside the last bracket.
pub(crate) fn bisect(f: impl Fn(Vec3) -> Real, mut a: Vec3, mut b: Vec3) -> Vec3 {
    let (mut fa, mut fb) = (f(a), f(b));
    // An end exactly on the boundary is the crossing (a lattice vertex half way between
    // voxel centres, where the image's value is exactly 1/2).
    if fa == 0.0 {
        return a;
    }
    if fb == 0.0 {
        return b;
    }
    if !(fa < 0.0 && fb > 0.0) {
        return 0.5 * (a + b);
    }
    for _ in 0..40 {
        let m = 0.5 * (a + b);
        let fm = f(m);
        if fm == 0.0 {
            return m;
        }
        if fm < 0.0 {
            (a, fa) = (m, fm);
        } else {
            (b, fb) = (m, fm);
        }
    }
    let t = (fa / (fa - fb)).clamp(0.0, 1.0);
    a + t * (b - a)
}

/// Every point of a grid of `spacing` over the box `lo`..`hi`, line after line along x,
/// then along y, then along z: `f(p, starts_line)`, for walks that compare neighbouring
/// samples of a line.
pub(crate) fn walk_grid_lines(lo: Vec3, hi: Vec3, spacing: Real, mut f: impl FnMut(Vec3, bool)) {
    let n = ((hi - lo) / spacing).ceil().max(Vec3::ONE);
    let n = [n.x as usize + 1, n.y as usize + 1, n.z as usize + 1];
    for axis in 0..3 {
        let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
        for a in 0..n[u] {
            for b in 0..n[w] {
                for s in 0..n[axis] {
                    let mut idx = [0; 3];
                    idx[axis] = s;
                    idx[u] = a;
                    idx[w] = b;
                    let step = Vec3::new(idx[0] as Real, idx[1] as Real, idx[2] as Real);
                    f(lo + spacing * step, s == 0);
                }
            }
        }
    }
}

/// Boundary points where the sign of `d.value` changes between neighbouring samples of
/// lines along x, y and z through a grid of `spacing` over the domain's box.
pub(crate) fn line_crossings<D: Domain + ?Sized>(d: &D, spacing: Real) -> Vec<Vec3> {
    let (lo, hi) = d.bounds();
    crossings_in_box(d, lo, hi, spacing)
}

/// Boundary points where the sign of `d.value` changes along lines along x, y and z through
/// a grid of `spacing` over the box `lo`..`hi`.
pub(crate) fn crossings_in_box<D: Domain + ?Sized>(
    d: &D,
    lo: Vec3,
    hi: Vec3,
    spacing: Real,
) -> Vec<Vec3> {
    let mut out = Vec::new();
    let mut prev: Option<(Vec3, Real)> = None;
    walk_grid_lines(lo, hi, spacing, |p, starts_line| {
        let f = d.value(p);
        if let Some((q, g)) = prev.filter(|_| !starts_line) {
            if g < 0.0 && f > 0.0 {
                out.push(d.cut(q, p));
            } else if g > 0.0 && f < 0.0 {
                out.push(d.cut(p, q));
            } else if f == 0.0 {
                out.push(p);
            }
        }
        prev = Some((p, f));
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bisection_finds_the_sphere_and_samples_lie_on_it() {
        let sphere = Implicit {
            f: |p: Vec3| p.length() - 1.0,
            lo: Vec3::splat(-1.2),
            hi: Vec3::splat(1.2),
            volume: None,
        };
        let c = sphere.cut(Vec3::ZERO, Vec3::new(2.0, 1.0, 0.0));
        assert!((c.length() - 1.0).abs() < 1e-12);
        let s = sphere.boundary_samples(0.1);
        assert!(s.len() > 500);
        assert!(s.iter().all(|p| (p.length() - 1.0).abs() < 1e-10));
        let d = sphere.boundary_distance(Vec3::new(1.1, 0.0, 0.0), 1e-4);
        assert!((d - 0.1).abs() < 1e-8);
    }
}
