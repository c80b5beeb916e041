//! The drawn surface of a voxel model after topology edits, redrawn where an edit reaches.
//!
//! The boundary of the linked voxels (`boundary`) is a local function of the links: a face
//! and its triangles depend on the links of the cells within one voxel of it, and a
//! smoothed position on what lies within `reach` voxels (each Taubin sweep moves data one
//! edge, at most half a voxel after one split). So after an edit only a window around the
//! changed links is rebuilt, and spliced into the kept surface by vertex keys, which name
//! a vertex the same whichever window it was built in. On a 100³ block this turns a
//! one-voxel scalpel sweep from a rebuild of the whole boundary (240,000 vertices) into one
//! of about 15,000. The result equals a full rebuild (`boundary::build` over the whole
//! grid) up to the order of floating-point sums, which `tests` checks after every edit of a
//! sequence.
//!
//! Drawn vertices keep their numbers across edits; vertices no edit uses any more stay,
//! unreferenced, until they are a quarter of the drawn ones, when a full rebuild renumbers.

use rustc_hash::FxHashMap;

use crate::math::{Real, Vec3};

use super::TrilinearEmbedding;
use super::boundary::{Region, SMOOTHING, SUBDIVISIONS, VertexKey, build, embedding_of};
use super::topology::{Link, VoxelLinks};

/// The voxel-boundary part of a model's drawn surface, with what an edit needs to redraw
/// only near itself.
#[derive(Clone, Debug, Default)]
pub struct DrawnBoundary {
    /// Per drawn vertex (numbered after the model's given surface vertices), its key.
    keys: Vec<VertexKey>,
    index: FxHashMap<VertexKey, u32>,
    /// Per drawn triangle, the key (6·voxel + direction) of the voxel face it tiles.
    face_of_triangle: Vec<u64>,
    /// Per drawn vertex, how many drawn triangles use it.
    uses: Vec<u32>,
    /// Whether the boundary is drawn (after the first edit).
    drawn: bool,
    /// The whole boundary built ahead (`prepare`), drawn at the first edit.
    pending: Option<(TrilinearEmbedding, Vec<[u32; 3]>)>,
    /// Vertices in the last redraw (to report what an edit cost).
    last_window_vertices: usize,
}

/// What a model's surface is made of, handed to `DrawnBoundary::redraw`.
pub struct DrawnSurface<'a> {
    /// The model's surface embedding: its given vertices, then the drawn boundary's.
    pub embedding: &'a mut TrilinearEmbedding,
    /// How many given vertices come first (kept, undrawn, still following their elements).
    pub original: usize,
    /// The triangles drawn (numbered in `embedding`).
    pub triangles: &'a mut Vec<[u32; 3]>,
    /// Voxel → element id (`u32::MAX`: none) when the model numbers its elements apart
    /// from the grid.
    pub element_of: Option<&'a [u32]>,
}

/// Smoothed positions depend on the lattice within this many voxels.
fn reach() -> usize {
    (2 * SMOOTHING).div_ceil(1 << SUBDIVISIONS) + 2
}

impl DrawnBoundary {
    pub fn new() -> Self {
        Self::default()
    }

    /// Builds the whole boundary now, at the model's build, so that the first edit too only
    /// redraws near itself (on a liver at 96 voxels the whole boundary takes about 90 ms).
    pub fn prepare(&mut self, links: &VoxelLinks, element_of: Option<&[u32]>) {
        let b = build(links, &Region::all(links.dims), SUBDIVISIONS, SMOOTHING);
        let mut e = embedding_of(b.rest, &b.follows);
        if let Some(map) = element_of {
            e.remap(map);
        }
        self.adopt(&b.triangles, b.keys, b.face_of_triangle);
        self.pending = Some((e, b.triangles));
        self.drawn = false;
    }

    /// Vertices built by the last redraw (the window's, or all of them).
    pub fn last_window_vertices(&self) -> usize {
        self.last_window_vertices
    }

    /// After an edit that changed the links `edited` (cut, joined or removed with a voxel)
    /// and removed the voxels `removed`: the drawn surface becomes the closed boundary of
    /// the linked voxels. The given vertices keep their numbers; so do the drawn ones an
    /// edit does not remove, unless this is the first edit or a full rebuild is due.
    pub fn redraw(
        &mut self,
        mut surface: DrawnSurface<'_>,
        links: &VoxelLinks,
        edited: &[Link],
        removed: &[usize],
    ) {
        let Some(dirty) = touched_region(links, edited, removed) else {
            return;
        };
        // Positions within `reach` of the edit may change, and each depends on the lattice
        // within `reach` of itself; the window's own sides are wrong by a voxel or so.
        let window = dirty.grown(2 * reach() + 2, links.dims);
        if !self.drawn
            && let Some((e, t)) = self.pending.take()
        {
            install(&mut surface, e, &t);
            self.drawn = true;
        }
        let unused = self.uses.iter().filter(|&&u| u == 0).count();
        let incremental = self.drawn
            && SUBDIVISIONS <= 1
            && 2 * window.voxels() < links.len()
            && 4 * unused <= self.keys.len();
        if !(incremental && self.splice(surface.reborrow(), links, &dirty, &window)) {
            self.redraw_all(surface, links);
        }
    }

    /// Rebuilds the whole boundary and renumbers its vertices.
    pub fn redraw_all(&mut self, surface: DrawnSurface<'_>, links: &VoxelLinks) {
        let b = build(links, &Region::all(links.dims), SUBDIVISIONS, SMOOTHING);
        let mut e = embedding_of(b.rest, &b.follows);
        if let Some(map) = surface.element_of {
            e.remap(map);
        }
        let mut surface = surface;
        install(&mut surface, e, &b.triangles);
        self.adopt(&b.triangles, b.keys, b.face_of_triangle);
        self.pending = None;
        self.drawn = true;
        self.last_window_vertices = self.keys.len();
    }

    /// Takes a whole boundary's keys and triangles as the drawn state.
    fn adopt(&mut self, triangles: &[[u32; 3]], keys: Vec<VertexKey>, face_of_triangle: Vec<u64>) {
        self.uses = vec![0; keys.len()];
        for t in triangles {
            for &v in t {
                self.uses[v as usize] += 1;
            }
        }
        self.index = keys
            .iter()
            .enumerate()
            .map(|(v, &k)| (k, v as u32))
            .collect();
        self.keys = keys;
        self.face_of_triangle = face_of_triangle;
    }

    /// Rebuilds `window` and replaces what the edit in `dirty` can have changed: the
    /// triangles of faces within one voxel of it, the positions within `reach`. False (and
    /// nothing changed) if the window does not cover what it must, which a full rebuild
    /// then fixes.
    fn splice(
        &mut self,
        surface: DrawnSurface<'_>,
        links: &VoxelLinks,
        dirty: &Region,
        window: &Region,
    ) -> bool {
        let b = build(links, window, SUBDIVISIONS, SMOOTHING);
        self.last_window_vertices = b.keys.len();
        let structural = dirty.grown(1, links.dims);
        let [nx, ny, _] = links.dims;
        let near = |face: u64| {
            let v = (face / 6) as usize;
            structural.contains([v % nx, (v / nx) % ny, v / (nx * ny)])
        };
        // Window vertices whose position may have changed, and their drawn numbers (new
        // ones after the last).
        let margin = reach() as Real + 0.5;
        let mut global = vec![u32::MAX; b.keys.len()];
        let mut fresh = 0u32;
        for (i, key) in b.keys.iter().enumerate() {
            if dirty.reaches(b.lattice[i], margin) {
                global[i] = match self.index.get(key) {
                    Some(&g) => g,
                    None => {
                        fresh += 1;
                        (self.keys.len() as u32) + fresh - 1
                    }
                };
            }
        }
        let new_triangles: Vec<usize> = (0..b.triangles.len())
            .filter(|&t| near(b.face_of_triangle[t]))
            .collect();
        if new_triangles.iter().any(|&t| {
            b.triangles[t]
                .iter()
                .any(|&v| global[v as usize] == u32::MAX)
        }) {
            return false;
        }

        let mut e = embedding_of(b.rest, &b.follows);
        if let Some(map) = surface.element_of {
            e.remap(map);
        }
        let (embedding, original) = (surface.embedding, surface.original);
        let offset = original as u32;
        // Old triangles near the edit go.
        let triangles = surface.triangles;
        let mut kept = 0;
        for t in 0..triangles.len() {
            if near(self.face_of_triangle[t]) {
                for &v in &triangles[t] {
                    self.uses[(v - offset) as usize] -= 1;
                }
            } else {
                triangles[kept] = triangles[t];
                self.face_of_triangle[kept] = self.face_of_triangle[t];
                kept += 1;
            }
        }
        triangles.truncate(kept);
        self.face_of_triangle.truncate(kept);
        // Positions within reach, new vertices appended.
        for (i, &g) in global.iter().enumerate() {
            if g == u32::MAX {
                continue;
            }
            let (g, at) = (g as usize, original + g as usize);
            if g == self.keys.len() {
                self.keys.push(b.keys[i]);
                self.index.insert(b.keys[i], g as u32);
                self.uses.push(0);
                embedding.rest.push(Vec3::ZERO);
                embedding.nodes.push([0; 8]);
                embedding.weights.push([0.0; 8]);
            }
            embedding.rest[at] = e.rest[i];
            embedding.nodes[at] = e.nodes[i];
            embedding.weights[at] = e.weights[i];
        }
        // The window's triangles near the edit come in.
        for t in new_triangles {
            let tri = b.triangles[t].map(|v| global[v as usize]);
            for v in tri {
                self.uses[v as usize] += 1;
            }
            triangles.push(tri.map(|v| v + offset));
            self.face_of_triangle.push(b.face_of_triangle[t]);
        }
        true
    }
}

/// Puts a whole boundary after the given vertices, in place of any drawn before.
fn install(surface: &mut DrawnSurface<'_>, e: TrilinearEmbedding, triangles: &[[u32; 3]]) {
    let (embedding, original) = (&mut *surface.embedding, surface.original);
    embedding.rest.truncate(original);
    embedding.nodes.truncate(original);
    embedding.weights.truncate(original);
    embedding.rest.extend(e.rest);
    embedding.nodes.extend(e.nodes);
    embedding.weights.extend(e.weights);
    let offset = original as u32;
    *surface.triangles = triangles.iter().map(|t| t.map(|v| v + offset)).collect();
}

impl DrawnSurface<'_> {
    fn reborrow(&mut self) -> DrawnSurface<'_> {
        DrawnSurface {
            embedding: self.embedding,
            original: self.original,
            triangles: self.triangles,
            element_of: self.element_of,
        }
    }
}

/// The box of the voxels at either end of the `edited` links and the `removed` voxels.
fn touched_region(links: &VoxelLinks, edited: &[Link], removed: &[usize]) -> Option<Region> {
    let [nx, ny, _] = links.dims;
    let ends = edited.iter().flat_map(|&(a, d)| {
        [
            Some(a as usize),
            links.lattice_neighbour(a as usize, d as usize),
        ]
    });
    let mut voxels = ends.flatten().chain(removed.iter().copied()).peekable();
    voxels.peek()?;
    let mut region = Region {
        lo: [usize::MAX; 3],
        hi: [0; 3],
    };
    for v in voxels {
        let c = [v % nx, (v / nx) % ny, v / (nx * ny)];
        for (a, &x) in c.iter().enumerate() {
            region.lo[a] = region.lo[a].min(x);
            region.hi[a] = region.hi[a].max(x);
        }
    }
    Some(region)
}

#[cfg(test)]
#[path = "drawn_tests.rs"]
mod tests;
