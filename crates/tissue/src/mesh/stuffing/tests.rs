use super::*;

fn sphere(r: Real) -> Implicit<impl Fn(Vec3) -> Real + Sync> {
    Implicit {
        f: move |p: Vec3| p.length() - r,
        lo: Vec3::splat(-r),
        hi: Vec3::splat(r),
        volume: Some(4.0 / 3.0 * std::f64::consts::PI * r * r * r),
    }
}

#[test]
fn a_cube_aligned_with_the_lattice_is_the_bcc_tiling() {
    // A box whose faces lie half way between lattice planes: no warping needed where cut
    // points sit mid-edge; every output vertex must be inside the box.
    let b = Implicit {
        f: |p: Vec3| (p.abs() - Vec3::splat(0.5)).max_element(),
        lo: Vec3::splat(-0.5),
        hi: Vec3::splat(0.5),
        volume: Some(1.0),
    };
    let s = stuff(&b, 0.1, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
    let r = &s.report;
    assert!(r.violations().is_empty(), "{r}");
    assert!((r.volume - 1.0).abs() < 1e-9, "{r}");
    assert!(
        s.mesh
            .vertices
            .iter()
            .all(|p| p.abs().max_element() <= 0.5 + 1e-12)
    );
}

#[test]
fn sphere_keeps_every_guarantee() {
    let d = sphere(0.05);
    for h in [0.02, 0.01, 0.006] {
        let s = stuff(&d, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
        let r = &s.report;
        println!("h = {h}: {r}");
        assert_eq!((r.inverted, r.degenerate), (0, 0), "{r}");
        assert!(r.min_dihedral_deg >= PROVEN_DIHEDRAL_DEG.0 - 1e-6, "{r}");
        assert!(r.max_dihedral_deg <= PROVEN_DIHEDRAL_DEG.1 + 1e-6, "{r}");
        assert!(r.hausdorff <= 0.5 * h, "{r}");
        s.mesh
            .validate_for_simulation()
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(s.tags.len(), s.mesh.tets.len());
    }
}

#[test]
fn bad_sizes_are_refused_by_name() {
    let d = sphere(1.0);
    for h in [0.0, -1.0, Real::NAN] {
        let e = stuff(&d, h, &Progress::silent())
            .err()
            .map(|e| e.to_string());
        assert!(e.is_some_and(|e| e.contains("size")));
    }
    let e = stuff(&d, 1e-4, &Progress::silent())
        .err()
        .map(|e| e.to_string());
    assert!(e.is_some_and(|e| e.contains("use a larger size")));
}
