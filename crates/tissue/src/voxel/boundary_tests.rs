//! The voxel boundary surface: closed and oriented after cuts, carves and random link
//! removals, exact volumes, Euler characteristics per piece.

use super::*;
use crate::mesh::SurfaceMesh;
use crate::model::CutPath;
use crate::voxel::VoxelGrid;

fn pieces(links: &VoxelLinks, smoothing: usize) -> (Vec<i64>, Real) {
    let b = boundary_surface(links, smoothing);
    let x = &b.embedding.rest;
    let chi = closed_pieces(&b.triangles, x, 1e-3).unwrap();
    let volume = SurfaceMesh::new(x.clone(), b.triangles.clone()).signed_volume();
    (chi, volume)
}

fn rest_cut(links: &mut VoxelLinks, blade: &CutPath) -> usize {
    let x: Vec<Vec3> = (0..links.len()).map(|v| links.centre_of(v)).collect();
    links.cut(|v| x[v], blade).len()
}

fn blade_x(x: Real, y_top: Real) -> CutPath {
    CutPath {
        start: [Vec3::new(x, -1.0, -1.0), Vec3::new(x, y_top, -1.0)],
        end: [Vec3::new(x, -1.0, 9.0), Vec3::new(x, y_top, 9.0)],
    }
}

#[test]
fn a_block_is_one_closed_box_of_exact_volume() {
    let links = VoxelLinks::new(&VoxelGrid::filled([4, 3, 5], 1.0), 6);
    let (chi, v) = pieces(&links, 0);
    assert_eq!(chi, vec![2]);
    assert!((v - 60.0).abs() < 1e-12, "{v}");
    // 2·(4·3 + 3·5 + 4·5) faces, two triangles each.
    assert_eq!(boundary_surface(&links, 0).triangles.len(), 4 * 47);
    let (chi, v) = pieces(&links, SMOOTHING);
    assert_eq!(chi, vec![2]);
    // Rounded, inside the voxels, losing little volume.
    assert!(v > 0.85 * 60.0 && v < 60.0, "{v}");
}

#[test]
fn a_full_cut_gives_two_closed_boxes_and_a_partial_cut_one() {
    let g = VoxelGrid::filled([6, 6, 6], 1.0);
    let mut links = VoxelLinks::new(&g, 6);
    assert_eq!(rest_cut(&mut links, &blade_x(2.5, 9.0)), 36);
    let (chi, v) = pieces(&links, 0);
    assert_eq!(chi, vec![2, 2]);
    assert!((v - 216.0).abs() < 1e-12);
    // The lips: 36 faces on each side of the cut, twice the 36 · 2 triangles.
    let b = boundary_surface(&links, 0);
    assert_eq!(b.triangles.len(), 2 * (6 * 36 + 2 * 36));
    assert_eq!(pieces(&links, SMOOTHING).0, vec![2, 2]);

    // A blade stopping at y = 2.5 cuts the links of rows y = 0..2: a slit, one piece.
    let mut links = VoxelLinks::new(&g, 6);
    assert_eq!(rest_cut(&mut links, &blade_x(2.5, 2.5)), 18);
    let (chi, v) = pieces(&links, 0);
    assert_eq!(chi, vec![2]);
    assert!((v - 216.0).abs() < 1e-12);
    assert_eq!(pieces(&links, SMOOTHING).0, vec![2]);
}

#[test]
fn voxels_touching_along_an_edge_or_a_corner_stay_apart() {
    // Two voxels sharing an edge only, and a third sharing a corner only.
    let mut g = VoxelGrid::new([3, 3, 3], Vec3::ONE, Vec3::ZERO);
    for v in [g.index(0, 0, 0), g.index(1, 1, 0), g.index(2, 2, 1)] {
        g.labels[v.unwrap()] = 1;
    }
    let (chi, v) = pieces(&VoxelLinks::new(&g, 6), 0);
    assert_eq!(chi, vec![2, 2, 2]);
    assert!((v - 3.0).abs() < 1e-12);
    // A ring of eight voxels around an empty centre: a torus (χ = 0), and a 2x2x3
    // block whose middle layer keeps two voxels touching along an edge only.
    let mut g = VoxelGrid::new([3, 3, 1], Vec3::ONE, Vec3::ZERO);
    g.labels.fill(1);
    g.labels[4] = 0;
    assert_eq!(pieces(&VoxelLinks::new(&g, 6), 0).0, vec![0]);
    let mut g = VoxelGrid::new([2, 2, 3], Vec3::ONE, Vec3::ZERO);
    g.labels.fill(1);
    for (i, j) in [(1, 0), (0, 1)] {
        let v = g.index(i, j, 1).unwrap();
        g.labels[v] = 0;
    }
    // Two columns joining the end layers: a torus.
    let (chi, v) = pieces(&VoxelLinks::new(&g, 6), 0);
    assert_eq!(chi, vec![0]);
    assert!((v - 10.0).abs() < 1e-12);
}

#[test]
fn a_carved_cavity_is_a_second_closed_sheet() {
    let mut links = VoxelLinks::new(&VoxelGrid::filled([5, 5, 5], 1.0), 6);
    let x: Vec<Vec3> = (0..links.len()).map(|v| links.centre_of(v)).collect();
    let (gone, _) = links.carve(|v| x[v], Vec3::splat(2.0), 0.5);
    assert_eq!(gone.len(), 1);
    // The outer box and the inner cube's inward sheet, both genus 0.
    let (chi, v) = pieces(&links, 0);
    assert_eq!(chi, vec![2, 2]);
    assert!((v - 124.0).abs() < 1e-12);
}

#[test]
fn random_voxels_with_random_cut_links_are_always_closed() {
    // Random occupancy (about 60%) and a random third of the face links cut: every
    // configuration of edge and corner contacts, slits and crack tips shows up.
    let mut seed: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    let mut midpoints = 0;
    let corners_used = |b: &BoundarySurface| {
        b.embedding
            .rest
            .iter()
            .filter(|p| p.to_array().iter().all(|c| c.fract().abs() == 0.5))
            .count()
    };
    for _ in 0..200 {
        let mut g = VoxelGrid::new([5, 5, 5], Vec3::ONE, Vec3::ZERO);
        for l in &mut g.labels {
            *l = (next() % 10 < 6) as u8;
        }
        let mut links = VoxelLinks::new(&g, 6);
        for v in 0..links.len() {
            for d in [1, 3, 5] {
                if next() % 3 == 0 {
                    links.unlink(v, d);
                }
            }
        }
        for (split, smoothing) in [(0, 0), (0, SMOOTHING), (SUBDIVISIONS, SMOOTHING)] {
            let b = boundary_surface_with(&links, split, smoothing);
            closed_pieces(&b.triangles, &b.embedding.rest, 1e-6).unwrap();
        }
        let b = boundary_surface(&links, 0);
        let v = SurfaceMesh::new(b.embedding.rest.clone(), b.triangles.clone()).signed_volume();
        assert!((v - g.occupied() as Real).abs() < 1e-9, "{v}");
        midpoints += b.embedding.len() - corners_used(&b);
    }
    // The fix for edge contacts was exercised.
    assert!(midpoints > 0);
}
