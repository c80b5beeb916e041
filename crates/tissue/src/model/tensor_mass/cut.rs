//! Cutting by removing tetrahedra (electrocautery style, survey §2.4): the tetrahedra the
//! blade's swept surface touches leave the mesh, their tensors leave the vertices, edges
//! and triangles they shared (`TensorSystem::remove_tet`, O(1) each), and the boundary
//! surface is patched locally (`cut_surface`).
//!
//! A cut costs about the size of the region it touches, not of the mesh: the candidates
//! come from a grid of the tetrahedra (`spatial`), the sliver guard (`stability`) looks at
//! the corners of what was removed, and the pieces the cut separated are found by searches
//! from the removed tetrahedra's neighbours (`pieces`). The only pass over the whole mesh
//! is the grid's check of which nodes moved, a few flops per node.
//!
//! Order within one cut: the blade's tetrahedra, then the slivers the guard removes, then
//! the fragments: every piece split off from its piece but the largest (the main body stays
//! the main body), reported once, then removed or kept as the `fragments` setting says.

use crate::math::{Real, Vec3, segment_triangle};
use crate::mesh::TET_FACES;
use crate::model::CutPath;

use super::cut_surface::CutSurface;
use super::pieces::Pieces;
use super::spatial::TetLocator;
use super::stability::StabilityGuard;
use super::system::TensorSystem;

/// What one cut removed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CutReport {
    /// Tetrahedra the blade touched.
    pub cut_tets: usize,
    /// Tetrahedra the sliver guard removed (see `stability`).
    pub sliver_tets: usize,
    /// Pieces separated by this cut, with their tetrahedron counts.
    pub fragments: Vec<usize>,
    /// Tetrahedra removed as fragments (0 when fragments are kept).
    pub fragment_tets: usize,
    pub added_vertices: usize,
    /// Every tetrahedron removed, in order.
    pub removed: Vec<usize>,
    /// Nodes this cut left without any tetrahedron.
    pub detached: Vec<usize>,
    /// Tetrahedra tested against the blade (the grid's candidates).
    pub examined: usize,
    /// Tetrahedra the piece search visited.
    pub searched: usize,
    /// Nodes the grid re-filed because they had moved.
    pub refiled_nodes: usize,
}

impl CutReport {
    /// All tetrahedra this cut removed.
    pub fn removed_tets(&self) -> usize {
        self.removed.len()
    }
}

/// What cutting keeps between cuts: the grid of tetrahedra, the piece labels, the guard.
#[derive(Clone, Debug)]
pub struct Cutter {
    locator: TetLocator,
    pieces: Pieces,
    guard: StabilityGuard,
}

/// Removes tetrahedron `t` from everything that knows it.
fn remove(
    t: usize,
    system: &mut TensorSystem,
    surface: &mut CutSurface,
    locator: &mut TetLocator,
    x: &[Vec3],
    report: &mut CutReport,
) -> bool {
    if !system.remove_tet(t) {
        return false;
    }
    surface.on_removed(t, system, x);
    locator.remove(t);
    report.removed.push(t);
    true
}

impl Cutter {
    /// Files the tetrahedra of `system` at positions `x` (all alive: before any cut).
    pub fn new(system: &TensorSystem, x: &[Vec3]) -> Self {
        let locator = TetLocator::new(&system.tets, x);
        let guard = StabilityGuard::new(system, &locator);
        Self {
            pieces: Pieces::new(system.tets.len()),
            locator,
            guard,
        }
    }

    pub fn guard(&self) -> &StabilityGuard {
        &self.guard
    }

    /// Changes the sliver guard's limit (infinity turns it off; to measure what it does).
    pub fn set_guard_limit(&mut self, limit: Real) {
        self.guard.set_limit(limit);
    }

    pub fn locator(&self) -> &TetLocator {
        &self.locator
    }

    /// Removes the tetrahedra touched by the blade's sweep, the slivers it leaves and
    /// (when `remove_fragments`) the fragments, and patches the surface.
    pub fn cut(
        &mut self,
        system: &mut TensorSystem,
        surface: &mut CutSurface,
        x: &[Vec3],
        blade: &CutPath,
        remove_fragments: bool,
    ) -> CutReport {
        let mut report = CutReport {
            refiled_nodes: self.locator.refresh(&system.tets, &system.alive, x),
            ..CutReport::default()
        };
        let [a, b] = blade.start;
        let [c, d] = blade.end;
        let quads = blade.triangles();
        let (lo, hi) = (a.min(b).min(c).min(d), a.max(b).max(c).max(d));
        let candidates = self.locator.candidates(&quads);
        report.examined = candidates.len();
        let mut touched: Vec<usize> = candidates
            .iter()
            .map(|&t| t as usize)
            .filter(|&t| {
                let p = system.tets[t].map(|v| x[v as usize]);
                let (pl, ph) = (
                    p[0].min(p[1]).min(p[2]).min(p[3]),
                    p[0].max(p[1]).max(p[2]).max(p[3]),
                );
                system.is_alive(t)
                    && pl.cmple(hi).all()
                    && ph.cmpge(lo).all()
                    && quads.iter().any(|q| tet_meets_triangle(&p, q))
            })
            .collect();
        touched.sort_unstable();
        self.remove_tets(system, surface, x, &touched, remove_fragments, report)
    }

    /// Removes the tetrahedra `touched` as if a blade had touched them (then the slivers
    /// and fragments, as `cut` does); `report` carries what the search found.
    pub fn remove_tets(
        &mut self,
        system: &mut TensorSystem,
        surface: &mut CutSurface,
        x: &[Vec3],
        touched: &[usize],
        remove_fragments: bool,
        mut report: CutReport,
    ) -> CutReport {
        let vertices_before = surface.nodes.len();
        let loc = &mut self.locator;
        for &t in touched {
            remove(t, system, surface, loc, x, &mut report);
        }
        report.cut_tets = report.removed.len();
        // The guard: corners of what left, until none is above the limit.
        let mut work: Vec<usize> = report
            .removed
            .iter()
            .flat_map(|&t| system.tets[t].map(|v| v as usize))
            .collect();
        while let Some(n) = work.pop() {
            if let Some(t) = self.guard.offender(system, loc, n)
                && remove(t, system, surface, loc, x, &mut report)
            {
                report.sliver_tets += 1;
                work.push(n);
                work.extend(system.tets[t].map(|v| v as usize));
            }
        }
        if !report.removed.is_empty() {
            let nb = &surface.neighbours;
            let seeds: Vec<usize> = report
                .removed
                .iter()
                .flat_map(|&t| nb[t].iter().flatten().map(|&m| m as usize))
                .filter(|&m| system.is_alive(m))
                .collect();
            let split = self.pieces.split(&seeds, &system.alive, nb);
            report.searched = split.visited;
            for piece in &split.fragments {
                report.fragments.push(piece.len());
                if remove_fragments {
                    for &t in piece {
                        remove(t, system, surface, loc, x, &mut report);
                    }
                    report.fragment_tets += piece.len();
                }
            }
        }
        let mut detached: Vec<usize> = report
            .removed
            .iter()
            .flat_map(|&t| system.tets[t].map(|v| v as usize))
            .filter(|&n| !system.is_attached(n))
            .collect();
        detached.sort_unstable();
        detached.dedup();
        report.detached = detached;
        report.added_vertices = surface.nodes.len() - vertices_before;
        report
    }
}

fn inside_tet(p: Vec3, x: &[Vec3; 4]) -> bool {
    let vol = |a: Vec3, b: Vec3, c: Vec3, d: Vec3| (b - a).dot((c - a).cross(d - a));
    let total = vol(x[0], x[1], x[2], x[3]);
    let parts = [
        vol(p, x[1], x[2], x[3]),
        vol(x[0], p, x[2], x[3]),
        vol(x[0], x[1], p, x[3]),
        vol(x[0], x[1], x[2], p),
    ];
    parts.iter().all(|&v| v * total >= 0.0)
}

/// Does the (solid) tetrahedron meet the triangle? An edge of one crosses a face of the
/// other, or the triangle lies inside.
pub fn tet_meets_triangle(x: &[Vec3; 4], tri: &[Vec3; 3]) -> bool {
    const EDGES: [[usize; 2]; 6] = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]];
    if EDGES
        .iter()
        .any(|[i, j]| segment_triangle(x[*i], x[*j], *tri).is_some())
    {
        return true;
    }
    for f in TET_FACES {
        let face = [x[f[0]], x[f[1]], x[f[2]]];
        if (0..3).any(|k| segment_triangle(tri[k], tri[(k + 1) % 3], face).is_some()) {
            return true;
        }
    }
    inside_tet(tri[0], x)
}

/// Volume enclosed by the surface (outward triangles give the solid's volume).
pub fn enclosed_volume(positions: &[Vec3], triangles: &[[u32; 3]]) -> Real {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}
