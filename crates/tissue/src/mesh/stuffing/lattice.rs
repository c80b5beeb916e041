//! The body-centred cubic (BCC) lattice isosurface stuffing fills space with.
//!
//! Black vertices sit at the corners of cubes of side `h`, red vertices at their centres.
//! Points are named by doubled integer coordinates (black: all even, red: all odd), so that
//! every lattice point has an exact integer name and the edge between two of them a key.
//! Every BCC tetrahedron joins two red vertices of neighbouring cubes (its *red* edge, length
//! h) to the two ends of one edge of the square face the cubes share (its *black* edge, length
//! h); its four other edges join a black to a red vertex (length h·√3/2). All BCC
//! tetrahedra are congruent, with dihedral angles of 60° and 90°.

use crate::math::{Real, Vec3};

/// The lattice over a box: `n` cubes of side `h` along each axis, starting at `origin`.
#[derive(Clone, Debug)]
pub(crate) struct Lattice {
    pub origin: Vec3,
    pub h: Real,
    pub n: [usize; 3],
}

impl Lattice {
    pub fn black_count(&self) -> usize {
        (self.n[0] + 1) * (self.n[1] + 1) * (self.n[2] + 1)
    }

    pub fn red_count(&self) -> usize {
        self.n[0] * self.n[1] * self.n[2]
    }

    pub fn vertex_count(&self) -> usize {
        self.black_count() + self.red_count()
    }

    /// Vertex id of the point with doubled coordinates `d`, or `None` outside the box.
    #[inline]
    pub fn id(&self, d: [i64; 3]) -> Option<u32> {
        let [nx, ny, nz] = self.n.map(|v| v as i64);
        let odd = d[0] & 1;
        if d[1] & 1 != odd || d[2] & 1 != odd {
            return None;
        }
        if odd == 0 {
            let [i, j, k] = d.map(|v| v / 2);
            if d.iter().any(|&v| v < 0) || i > nx || j > ny || k > nz {
                return None;
            }
            Some((i + (nx + 1) * (j + (ny + 1) * k)) as u32)
        } else {
            let [i, j, k] = d.map(|v| (v - 1) / 2);
            if d.iter().any(|&v| v < 0) || i >= nx || j >= ny || k >= nz {
                return None;
            }
            Some((self.black_count() as i64 + i + nx * (j + ny * k)) as u32)
        }
    }

    /// Doubled coordinates of vertex `id` (inverse of `id`).
    #[inline]
    pub fn coords(&self, id: u32) -> [i64; 3] {
        let id = id as usize;
        let nb = self.black_count();
        if id < nb {
            let (nx, ny) = (self.n[0] + 1, self.n[1] + 1);
            let (i, j, k) = (id % nx, (id / nx) % ny, id / (nx * ny));
            [2 * i as i64, 2 * j as i64, 2 * k as i64]
        } else {
            let r = id - nb;
            let (nx, ny) = (self.n[0], self.n[1]);
            let (i, j, k) = (r % nx, (r / nx) % ny, r / (nx * ny));
            [2 * i as i64 + 1, 2 * j as i64 + 1, 2 * k as i64 + 1]
        }
    }

    #[inline]
    pub fn position(&self, id: u32) -> Vec3 {
        let d = self.coords(id);
        self.origin + 0.5 * self.h * Vec3::new(d[0] as Real, d[1] as Real, d[2] as Real)
    }

    /// True for an edge between two black or two red vertices (length h), false for a
    /// black–red edge (length h·√3/2).
    #[inline]
    pub fn is_long(&self, a: u32, b: u32) -> bool {
        let nb = self.black_count() as u32;
        (a < nb) == (b < nb)
    }

    /// Calls `f(u)` for each lattice neighbour of `v` (joined to it by an edge): up to six
    /// along the axes at distance h and eight across the cube diagonals at h·√3/2.
    pub fn for_each_neighbour(&self, v: u32, mut f: impl FnMut(u32)) {
        let d = self.coords(v);
        for axis in 0..3 {
            for s in [-2, 2] {
                let mut e = d;
                e[axis] += s;
                if let Some(u) = self.id(e) {
                    f(u);
                }
            }
        }
        for c in 0..8 {
            let o = [c & 1, (c >> 1) & 1, (c >> 2) & 1].map(|b| 2 * b as i64 - 1);
            if let Some(u) = self.id([d[0] + o[0], d[1] + o[1], d[2] + o[2]]) {
                f(u);
            }
        }
    }

    /// Calls `f(a, b)` once for every lattice edge: long edges along +x, +y, +z from every
    /// vertex, and the eight black–red edges of every red vertex.
    pub fn for_each_edge(&self, mut f: impl FnMut(u32, u32)) {
        const AXES: [[i64; 3]; 3] = [[2, 0, 0], [0, 2, 0], [0, 0, 2]];
        for a in 0..self.vertex_count() as u32 {
            let d = self.coords(a);
            for s in AXES {
                if let Some(b) = self.id([d[0] + s[0], d[1] + s[1], d[2] + s[2]]) {
                    f(a, b);
                }
            }
            if d[0] & 1 == 1 {
                for c in 0..8 {
                    let o = [c & 1, (c >> 1) & 1, (c >> 2) & 1].map(|b| 2 * b as i64 - 1);
                    if let Some(b) = self.id([d[0] + o[0], d[1] + o[1], d[2] + o[2]]) {
                        f(a, b);
                    }
                }
            }
        }
    }

    /// Calls `f([r1, r2, b1, b2])` for every BCC tetrahedron inside the box: for every pair
    /// of red vertices of neighbouring cubes, the four edges of the square face they share.
    pub fn for_each_tet(&self, mut f: impl FnMut([u32; 4])) {
        let nb = self.black_count() as u32;
        for r1 in nb..self.vertex_count() as u32 {
            let c = self.coords(r1);
            for axis in 0..3 {
                let mut d2 = c;
                d2[axis] += 2;
                let Some(r2) = self.id(d2) else { continue };
                let mut centre = c;
                centre[axis] += 1;
                let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
                // The face's corners in cyclic order.
                let corner = |su: i64, sw: i64| {
                    let mut p = centre;
                    p[u] += su;
                    p[w] += sw;
                    p
                };
                let ring = [corner(-1, -1), corner(1, -1), corner(1, 1), corner(-1, 1)];
                for e in 0..4 {
                    // Corners of a face between two cubes inside the box are inside it.
                    if let (Some(b1), Some(b2)) = (self.id(ring[e]), self.id(ring[(e + 1) % 4])) {
                        f([r1, r2, b1, b2]);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::tet_signed_volume;

    #[test]
    fn ids_and_coordinates_round_trip() {
        let l = Lattice {
            origin: Vec3::new(0.1, -0.2, 0.3),
            h: 0.5,
            n: [3, 4, 2],
        };
        for id in 0..l.vertex_count() as u32 {
            assert_eq!(l.id(l.coords(id)), Some(id));
        }
        assert_eq!(l.id([1, 2, 1]), None);
        assert_eq!(l.id([-2, 0, 0]), None);
        assert_eq!(l.id([7, 1, 1]), None);
    }

    #[test]
    fn tetrahedra_tile_the_inner_cubes_with_equal_volume_and_lattice_edge_lengths() {
        let h = 0.25;
        let l = Lattice {
            origin: Vec3::ZERO,
            h,
            n: [4, 4, 4],
        };
        let mut count = 0;
        let mut volume = 0.0;
        l.for_each_tet(|t| {
            let p = t.map(|v| l.position(v));
            let v = tet_signed_volume(p[0], p[1], p[2], p[3]).abs();
            assert!((v - h * h * h / 12.0).abs() < 1e-15);
            assert!(((p[0] - p[1]).length() - h).abs() < 1e-12);
            assert!(((p[2] - p[3]).length() - h).abs() < 1e-12);
            for (a, b) in [(0, 2), (0, 3), (1, 2), (1, 3)] {
                assert!(((p[a] - p[b]).length() - h * 0.75f64.sqrt()).abs() < 1e-12);
            }
            count += 1;
            volume += v;
        });
        // One face shared per pair of neighbouring cubes: 3·n²(n-1) faces, 4 tets each.
        assert_eq!(count, 4 * 3 * 16 * 3);
        assert!((volume - count as Real * h * h * h / 12.0).abs() < 1e-12);
        let mut edges = 0;
        l.for_each_edge(|a, b| {
            let long = l.is_long(a, b);
            let len = (l.position(a) - l.position(b)).length();
            let want = if long { h } else { h * 0.75f64.sqrt() };
            assert!((len - want).abs() < 1e-12);
            edges += 1;
        });
        // Black: 3·5·5·4 axis edges; red: 3·4·4·3; black–red: 8 per red vertex.
        assert_eq!(edges, 300 + 144 + 8 * 64);
    }
}
