//! A closed triangle surface as a domain: inside by the parity of crossings of a ray along
//! +x, cut points where lattice edges cross the triangles.

use rustc_hash::FxHashMap;

use crate::error::MeshError;
use crate::math::{Real, Vec3};
use crate::mesh::SurfaceMesh;

use super::domain::{Domain, bisect};
use super::triangle_index::TriangleIndex;

/// The inside of a closed surface (orientation does not matter; parity decides).
#[derive(Clone, Debug)]
pub struct SurfaceDomain {
    index: TriangleIndex,
    lo: Vec3,
    hi: Vec3,
    volume: Real,
    /// Triangles by the cell of the (y, z) plane their projection's box overlaps.
    bins: [usize; 2],
    bin: [Real; 2],
    start: Vec<u32>,
    items: Vec<u32>,
}

impl SurfaceDomain {
    /// Refuses an empty or open surface (a border or non-manifold edge makes inside and
    /// outside meaningless), naming an edge at fault.
    pub fn new(surface: &SurfaceMesh) -> Result<Self, MeshError> {
        surface.validate_indices()?;
        if surface.triangles.is_empty() {
            return Err(MeshError::Empty { what: "triangles" });
        }
        let mut uses: FxHashMap<(u32, u32), u32> = FxHashMap::default();
        for t in &surface.triangles {
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                *uses.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        let mut odd: Vec<(u32, u32)> = uses
            .iter()
            .filter(|&(_, &n)| n % 2 == 1)
            .map(|(&e, _)| e)
            .collect();
        if !odd.is_empty() {
            odd.sort_unstable();
            return Err(MeshError::NotClosed {
                border_edges: odd.len(),
                a: odd[0].0 as usize,
                b: odd[0].1 as usize,
            });
        }
        let index = TriangleIndex::new(&surface.vertices, &surface.triangles);
        let (mut lo, mut hi) = (Vec3::splat(Real::INFINITY), Vec3::splat(-Real::INFINITY));
        for &v in surface.triangles.iter().flatten() {
            lo = lo.min(surface.vertices[v as usize]);
            hi = hi.max(surface.vertices[v as usize]);
        }
        let side = ((surface.triangles.len() as Real).sqrt() * 0.5).clamp(1.0, 512.0) as usize;
        let bins = [side, side];
        let bin = [
            ((hi.y - lo.y) / side as Real).max(1e-300),
            ((hi.z - lo.z) / side as Real).max(1e-300),
        ];
        let mut domain = Self {
            index,
            lo,
            hi,
            volume: surface.signed_volume().abs(),
            bins,
            bin,
            start: Vec::new(),
            items: Vec::new(),
        };
        let mut count = vec![0u32; bins[0] * bins[1] + 1];
        for t in 0..surface.triangles.len() {
            domain.for_bins_of(t as u32, |b| count[b] += 1);
        }
        let mut acc = 0;
        for c in count.iter_mut() {
            let k = *c;
            *c = acc;
            acc += k;
        }
        let mut fill = count.clone();
        let mut items = vec![0u32; acc as usize];
        for t in 0..surface.triangles.len() {
            domain.for_bins_of(t as u32, |b| {
                items[fill[b] as usize] = t as u32;
                fill[b] += 1;
            });
        }
        domain.start = count;
        domain.items = items;
        Ok(domain)
    }

    fn bin_of(&self, y: Real, z: Real) -> (usize, usize) {
        let i = (((y - self.lo.y) / self.bin[0]).max(0.0) as usize).min(self.bins[0] - 1);
        let j = (((z - self.lo.z) / self.bin[1]).max(0.0) as usize).min(self.bins[1] - 1);
        (i, j)
    }

    fn for_bins_of(&self, t: u32, mut f: impl FnMut(usize)) {
        let p = self.index.corners(t);
        let (i0, j0) = self.bin_of(
            p[0].y.min(p[1].y).min(p[2].y),
            p[0].z.min(p[1].z).min(p[2].z),
        );
        let (i1, j1) = self.bin_of(
            p[0].y.max(p[1].y).max(p[2].y),
            p[0].z.max(p[1].z).max(p[2].z),
        );
        for j in j0..=j1 {
            for i in i0..=i1 {
                f(i + self.bins[0] * j);
            }
        }
    }

    /// The surface, indexed for distances.
    pub fn index(&self) -> &TriangleIndex {
        &self.index
    }
}

/// Twice the signed area of (a, b, p) in the (y, z) plane; swapping a and b negates it
/// exactly, so two triangles sharing an edge agree on which side a point is.
#[inline]
fn orient(a: Vec3, b: Vec3, p: Vec3) -> Real {
    (a.y - p.y) * (b.z - p.z) - (a.z - p.z) * (b.y - p.y)
}

/// Tie rule for a point exactly on a projected edge a→b of a counter-clockwise triangle:
/// exactly one of the two directions of an edge owns it.
#[inline]
fn owns(a: Vec3, b: Vec3) -> bool {
    let (dy, dz) = (b.y - a.y, b.z - a.z);
    dz > 0.0 || (dz == 0.0 && dy > 0.0)
}

impl Domain for SurfaceDomain {
    fn value(&self, p: Vec3) -> Real {
        if p.cmplt(self.lo).any() || p.cmpgt(self.hi).any() {
            return 1.0;
        }
        let (i, j) = self.bin_of(p.y, p.z);
        let b = i + self.bins[0] * j;
        let mut crossings = 0u32;
        for &t in &self.items[self.start[b] as usize..self.start[b + 1] as usize] {
            let [a, mut bb, mut c] = self.index.corners(t);
            let area = orient(a, bb, c);
            if area == 0.0 {
                continue;
            }
            if area < 0.0 {
                std::mem::swap(&mut bb, &mut c);
            }
            let w = [orient(bb, c, p), orient(c, a, p), orient(a, bb, p)];
            let edges = [(bb, c), (c, a), (a, bb)];
            let inside = w
                .iter()
                .zip(edges)
                .all(|(&w, (e0, e1))| w > 0.0 || (w == 0.0 && owns(e0, e1)));
            if !inside {
                continue;
            }
            let x = (w[0] * a.x + w[1] * bb.x + w[2] * c.x) / (w[0] + w[1] + w[2]);
            if x == p.x {
                return 0.0;
            }
            if x > p.x {
                crossings += 1;
            }
        }
        if crossings % 2 == 1 { -1.0 } else { 1.0 }
    }

    fn cut(&self, inside: Vec3, outside: Vec3) -> Vec3 {
        match self.index.first_hit(inside, outside) {
            Some(t) => inside + t * (outside - inside),
            None => bisect(|p| self.value(p), inside, outside),
        }
    }

    fn bounds(&self) -> (Vec3, Vec3) {
        (self.lo, self.hi)
    }

    fn boundary_distance(&self, p: Vec3, _step: Real) -> Real {
        self.index.distance(p)
    }

    /// The surface's vertices, edge midpoints and face centroids.
    fn boundary_samples(&self, _spacing: Real) -> Vec<Vec3> {
        let mut out = self.index.vertices.clone();
        for t in 0..self.index.triangles.len() {
            let [a, b, c] = self.index.corners(t as u32);
            out.extend([
                (a + b + c) / 3.0,
                0.5 * (a + b),
                0.5 * (b + c),
                0.5 * (c + a),
            ]);
        }
        out
    }

    fn reference_volume(&self) -> Option<Real> {
        Some(self.volume)
    }

    fn surface_index(&self) -> Option<&TriangleIndex> {
        Some(&self.index)
    }
}
