//! The drawn boundary redrawn near each edit equals a rebuild of the whole boundary: the
//! same triangles (by vertex keys, orientation kept), the same rest positions and the same
//! followed voxels, after every edit of a sequence of cuts, a carve and a join.

use std::collections::BTreeMap;

use super::*;
use crate::model::CutPath;
use crate::voxel::VoxelGrid;
use crate::voxel::boundary::closed_pieces;

/// A model's surface made only of the drawn boundary.
struct Model {
    links: VoxelLinks,
    drawn: DrawnBoundary,
    embedding: TrilinearEmbedding,
    triangles: Vec<[u32; 3]>,
    element_of: Option<Vec<u32>>,
}

impl Model {
    /// Nothing drawn yet.
    fn blank(links: VoxelLinks, element_of: Option<Vec<u32>>, drawn: DrawnBoundary) -> Self {
        Model {
            links,
            drawn,
            embedding: TrilinearEmbedding {
                rest: Vec::new(),
                nodes: Vec::new(),
                weights: Vec::new(),
            },
            triangles: Vec::new(),
            element_of,
        }
    }

    /// The whole boundary drawn.
    fn new(links: VoxelLinks, element_of: Option<Vec<u32>>) -> Self {
        let mut m = Model::blank(links, element_of, DrawnBoundary::new());
        let surface = DrawnSurface {
            embedding: &mut m.embedding,
            original: 0,
            triangles: &mut m.triangles,
            element_of: m.element_of.as_deref(),
        };
        m.drawn.redraw_all(surface, &m.links);
        m
    }

    fn redraw(&mut self, edited: &[Link], removed: &[usize]) {
        let surface = DrawnSurface {
            embedding: &mut self.embedding,
            original: 0,
            triangles: &mut self.triangles,
            element_of: self.element_of.as_deref(),
        };
        self.drawn.redraw(surface, &self.links, edited, removed);
    }

    fn rest_centres(&self) -> Vec<Vec3> {
        (0..self.links.len())
            .map(|v| self.links.centre_of(v))
            .collect()
    }

    fn cut(&mut self, blade: &CutPath) -> usize {
        let x = self.rest_centres();
        let cut = self.links.cut(|v| x[v], blade);
        self.redraw(&cut, &[]);
        cut.len()
    }

    fn carve(&mut self, centre: Vec3, radius: Real) -> usize {
        let x = self.rest_centres();
        let (gone, links) = self.links.carve(|v| x[v], centre, radius);
        self.redraw(&links, &gone);
        gone.len()
    }

    fn join_all(&mut self) -> usize {
        let added = self.links.join(|_, _, _| true);
        self.redraw(&added, &[]);
        added.len()
    }

    /// Checks the drawn surface against a full rebuild; returns the vertices the last
    /// redraw built.
    fn check(&self, what: &str) -> usize {
        let mut full = Model::blank(
            self.links.clone(),
            self.element_of.clone(),
            DrawnBoundary::new(),
        );
        let full_surface = DrawnSurface {
            embedding: &mut full.embedding,
            original: 0,
            triangles: &mut full.triangles,
            element_of: self.element_of.as_deref(),
        };
        full.drawn.redraw_all(full_surface, &self.links);
        assert_eq!(
            keyed_triangles(&self.drawn, &self.triangles),
            keyed_triangles(&full.drawn, &full.triangles),
            "{what}: triangles"
        );
        let spacing = self.links.spacing.max_element();
        for (v, &key) in self.drawn.keys.iter().enumerate() {
            if self.drawn.uses[v] == 0 {
                continue;
            }
            let w = full.drawn.index[&key] as usize;
            let (a, b) = (self.embedding.rest[v], full.embedding.rest[w]);
            assert!(
                (a - b).length() <= 1e-12 * spacing,
                "{what}: vertex {v} at {a}, rebuilt at {b}"
            );
            assert_eq!(
                follows(&self.embedding, v),
                follows(&full.embedding, w),
                "{what}: vertex {v} follows"
            );
        }
        closed_pieces(&self.triangles, &self.embedding.rest, 0.0)
            .unwrap_or_else(|e| panic!("{what}: {e}"));
        self.drawn.last_window_vertices()
    }
}

/// Triangles as key triples starting at their smallest key (orientation kept), sorted.
fn keyed_triangles(drawn: &DrawnBoundary, triangles: &[[u32; 3]]) -> Vec<[VertexKey; 3]> {
    let mut out: Vec<[VertexKey; 3]> = triangles
        .iter()
        .map(|t| {
            let k = t.map(|v| drawn.keys[v as usize]);
            let first = (0..3).min_by_key(|&i| k[i]).unwrap_or(0);
            [k[first], k[(first + 1) % 3], k[(first + 2) % 3]]
        })
        .collect();
    out.sort_unstable();
    out
}

/// A vertex's followed voxels with their weights (rounded to 1e-12).
fn follows(e: &TrilinearEmbedding, v: usize) -> BTreeMap<u32, i64> {
    (0..8)
        .filter(|&k| e.weights[v][k] != 0.0)
        .map(|k| (e.nodes[v][k], (e.weights[v][k] * 1e12).round() as i64))
        .collect()
}

/// A vertical blade in the plane x = `x`, from y0 to y1, through the top `depth` layers.
fn blade(x: Real, y0: Real, y1: Real, top: Real, depth: Real) -> CutPath {
    CutPath {
        start: [Vec3::new(x, y0, top + 1.0), Vec3::new(x, y0, top - depth)],
        end: [Vec3::new(x, y1, top + 1.0), Vec3::new(x, y1, top - depth)],
    }
}

#[test]
fn edits_redrawn_near_themselves_equal_a_full_rebuild() {
    // 100 × 100 × 40 voxels of 1 m: the window of a small edit is well under half the
    // grid (it reaches 24 voxels beyond the edit).
    let grid = VoxelGrid::filled([100, 100, 40], 1.0);
    let mut m = Model::new(VoxelLinks::new(&grid, 6), None);
    let all = m.drawn.keys.len();
    let top = 39.0;
    let mut windows = Vec::new();
    // A short cut, then one that meets it at a right angle, then its continuation.
    assert!(m.cut(&blade(10.5, 5.2, 12.8, top, 4.0)) > 0);
    windows.push(m.check("first cut"));
    let across = CutPath {
        start: [
            Vec3::new(8.2, 9.5, top + 1.0),
            Vec3::new(8.2, 9.5, top - 2.0),
        ],
        end: [
            Vec3::new(14.8, 9.5, top + 1.0),
            Vec3::new(14.8, 9.5, top - 2.0),
        ],
    };
    assert!(m.cut(&across) > 0);
    windows.push(m.check("crossing cut"));
    assert!(m.cut(&blade(10.5, 12.8, 16.2, top, 4.0)) > 0);
    windows.push(m.check("continued cut"));
    // A cavity under the surface, then one that opens it.
    assert!(m.carve(Vec3::new(70.0, 70.0, 34.0), 2.5) > 0);
    windows.push(m.check("buried carve"));
    assert!(m.carve(Vec3::new(70.0, 70.0, 37.5), 2.0) > 0);
    windows.push(m.check("opening carve"));
    // A cut through a corner of the grid, where the window is clipped.
    assert!(m.cut(&blade(2.5, -1.0, 3.3, top, 40.0)) > 0);
    windows.push(m.check("corner cut"));
    // Joining every touching pair closes the cuts again (a large edit: a full rebuild).
    assert!(m.join_all() > 0);
    m.check("join");
    eprintln!("vertices built per edit: {windows:?} (whole boundary: {all})");
    for (k, w) in windows.iter().enumerate() {
        assert!(*w < all / 2, "edit {k} rebuilt {w} of {all} vertices");
    }
}

#[test]
fn a_boundary_prepared_ahead_makes_the_first_edit_local_too() {
    let grid = VoxelGrid::filled([100, 100, 40], 1.0);
    let links = VoxelLinks::new(&grid, 6);
    let mut drawn = DrawnBoundary::new();
    drawn.prepare(&links, None);
    let all = drawn.keys.len();
    // A model drawing its given surface (here: none) until the first edit.
    let mut m = Model::blank(links, None, drawn);
    assert!(m.cut(&blade(50.5, 40.2, 47.8, 39.0, 4.0)) > 0);
    let w = m.check("first cut after prepare");
    assert!(w < all / 2, "{w} of {all}");
}

#[test]
fn drawn_vertices_keep_their_numbers_across_an_edit_elsewhere() {
    let grid = VoxelGrid::filled([100, 100, 40], 1.0);
    let mut m = Model::new(VoxelLinks::new(&grid, 6), None);
    assert!(m.cut(&blade(10.5, 5.2, 12.8, 39.0, 4.0)) > 0);
    // A vertex on the far side of the block.
    let far = (0..m.embedding.len())
        .max_by(|&a, &b| m.embedding.rest[a].x.total_cmp(&m.embedding.rest[b].x))
        .unwrap();
    let (key, rest) = (m.drawn.keys[far], m.embedding.rest[far]);
    assert!(m.cut(&blade(12.5, 30.2, 36.8, 39.0, 4.0)) > 0);
    assert_eq!(m.drawn.keys[far], key);
    assert_eq!(m.embedding.rest[far], rest);
    m.check("second cut");
}

#[test]
fn element_numbers_follow_the_model_map() {
    // Linked volumes number their elements apart from the grid: every voxel id drawn is
    // renamed through the map, in the window as in the full rebuild.
    let grid = VoxelGrid::filled([100, 100, 40], 1.0);
    let links = VoxelLinks::new(&grid, 26);
    let map: Vec<u32> = (0..links.len() as u32).rev().collect();
    let mut m = Model::new(links, Some(map));
    assert!(m.cut(&blade(20.5, 20.2, 27.8, 39.0, 5.0)) > 0);
    let w = m.check("cut with 26 neighbours");
    assert!(w < m.drawn.keys.len() / 2);
}
