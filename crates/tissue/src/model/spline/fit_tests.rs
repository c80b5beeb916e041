//! Tests of the fit: close fits of tubes and sheets, refusals naming the reason.

use super::*;
use crate::mesh::generate::{icosphere, tube};

#[test]
fn generated_tube_is_fitted_closely() {
    let m = tube(0.01, 0.05, 48, 20);
    let fit = fit_mesh(&m.vertices, &m.triangles, 16, 10, 1e-6).unwrap();
    assert_eq!(fit.topology, Topology::Tube);
    // The mesh is a 48-gon prism; a 16-point periodic cubic fits it within 0.2% of R.
    assert!(
        fit.max_error < 2e-5,
        "max {} rms {}",
        fit.max_error,
        fit.rms_error
    );
    let p = fit.surface.point(0.3, 0.5);
    assert!(((p.x * p.x + p.y * p.y).sqrt() - 0.01).abs() < 2e-5);
    assert!((p.z - 0.025).abs() < 1e-6);
}

#[test]
fn height_field_sheet_is_fitted() {
    let k = 20;
    let f = |x: Real, y: Real| 0.01 * (x * 3.0).sin() * (y * 2.0).cos();
    let vertices: Vec<Vec3> = (0..=k)
        .flat_map(|j| (0..=k).map(move |i| (i as Real / k as Real, j as Real / k as Real)))
        .map(|(x, y)| Vec3::new(x * 0.1, y * 0.08, f(x, y)))
        .collect();
    let id = |i: u32, j: u32| i + (k as u32 + 1) * j;
    let triangles: Vec<[u32; 3]> = (0..k as u32)
        .flat_map(|j| {
            (0..k as u32).flat_map(move |i| {
                [
                    [id(i, j), id(i + 1, j), id(i + 1, j + 1)],
                    [id(i, j), id(i + 1, j + 1), id(i, j + 1)],
                ]
            })
        })
        .collect();
    let fit = fit_mesh(&vertices, &triangles, 10, 10, 1e-8).unwrap();
    assert_eq!(fit.topology, Topology::Sheet);
    assert!(
        fit.max_error < 2e-5,
        "max {} rms {}",
        fit.max_error,
        fit.rms_error
    );
}

#[test]
fn square_sheet_patch_has_the_sheet_s_corners() {
    // Isotropic covariance: the principal axes are arbitrary, the border edges are not.
    let k = 6u32;
    let vertices: Vec<Vec3> = (0..=k)
        .flat_map(|j| (0..=k).map(move |i| Vec3::new(0.01 * i as Real, 0.01 * j as Real, 0.0)))
        .collect();
    let id = |i: u32, j: u32| i + (k + 1) * j;
    let triangles: Vec<[u32; 3]> = (0..k)
        .flat_map(|j| {
            (0..k).flat_map(move |i| {
                [
                    [id(i, j), id(i + 1, j), id(i + 1, j + 1)],
                    [id(i, j), id(i + 1, j + 1), id(i, j + 1)],
                ]
            })
        })
        .collect();
    let fit = fit_mesh(&vertices, &triangles, 6, 6, 1e-6).unwrap();
    let corners = [
        Vec3::ZERO,
        Vec3::new(0.06, 0.0, 0.0),
        Vec3::new(0.0, 0.06, 0.0),
        Vec3::new(0.06, 0.06, 0.0),
    ];
    for (s, t) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
        let p = fit.surface.point(s, t);
        assert!(corners.iter().any(|c| c.distance(p) < 1e-7), "{p}");
    }
}

#[test]
fn closed_organ_and_two_pieces_are_refused_with_the_reason() {
    let s = icosphere(Vec3::ZERO, 1.0, 2);
    let e = fit_mesh(&s.vertices, &s.triangles, 8, 8, 1e-6)
        .unwrap_err()
        .to_string();
    assert!(e.contains("closed surface of genus 0"), "{e}");
    let a = tube(1.0, 1.0, 8, 2);
    let mut tris = a.triangles.clone();
    let off = a.vertices.len() as u32;
    tris.extend(a.triangles.iter().map(|t| t.map(|v| v + off)));
    let mut verts = a.vertices.clone();
    verts.extend(a.vertices.iter().map(|p| *p + Vec3::X * 5.0));
    let e = classify(&verts, &tris).unwrap_err().to_string();
    assert!(e.contains("2 separate components"), "{e}");
    let e = classify(&verts, &[[0, 1, 999]]).unwrap_err().to_string();
    assert!(e.contains("999"), "{e}");
}
