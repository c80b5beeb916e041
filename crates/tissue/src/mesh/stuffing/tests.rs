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

fn liver() -> crate::mesh::SurfaceMesh {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/meshes/liver-smooth.obj"
    );
    let data = crate::io::read(path).unwrap_or_else(|e| panic!("{e}"));
    let mut s = data.surface_mesh().unwrap_or_else(|e| panic!("{e}"));
    // The file is in decimetre-like units; 2 cm per unit makes an organ of ~13 cm.
    for v in &mut s.vertices {
        *v *= 0.02;
    }
    s
}

#[test]
fn liver_surface_keeps_every_guarantee_and_the_tags() {
    let d = SurfaceDomain::new(&liver()).unwrap_or_else(|e| panic!("{e}"));
    let s = stuff(&d, 0.005, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
    let r = &s.report;
    assert!(r.violations().is_empty(), "{r}");
    assert_eq!(r.distance_method, "exact");
    assert!(s.tags.iter().all(|&t| t == 1));
    s.mesh
        .validate_for_simulation()
        .unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn an_open_surface_is_refused_naming_an_edge() {
    let mut s = liver();
    s.triangles.pop();
    let e = SurfaceDomain::new(&s).err().map(|e| e.to_string());
    assert!(e.is_some_and(|e| e.contains("not closed") && e.contains("border edges")));
}

/// A ball of label 2 (voxels closer than `r_in` voxels to the centre) inside a ball of
/// label 1 (`r_out`), in an image of n³ voxels of 1 mm.
pub(super) fn nested_balls(n: usize, r_in: Real, r_out: Real) -> crate::image::VoxelImage {
    use crate::image::{ByteOrder, SourceType, VoxelImage};
    let mut values = vec![0f32; n * n * n];
    let c = Vec3::splat((n as Real - 1.0) / 2.0);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let r = (Vec3::new(i as Real, j as Real, k as Real) - c).length();
                values[i + n * (j + n * k)] = if r < r_in {
                    2.0
                } else if r < r_out {
                    1.0
                } else {
                    0.0
                };
            }
        }
    }
    VoxelImage {
        dims: [n; 3],
        spacing: Vec3::splat(0.001),
        origin: Vec3::ZERO,
        values,
        source_type: SourceType::U8,
        byte_order: ByteOrder::Little,
        segments: Vec::new(),
    }
}

/// Two labels of one image (a ball of label 2 inside a ball of label 1) give one conforming
/// mesh whose tetrahedra carry the label they lie in, and whose volume is the voxel volume.
/// At h = 2 voxels the inner ball (radius 3.5 h) keeps its volume within the 1 % promised
/// (−0.96 %; its voxels' interpolated interface encloses 0.79 % less than they count): its
/// interface vertices are moved off their chords (`interface_volume`; as the chordal
/// polyhedron of a coarse sphere it lost 2.7 %, and broke that promise). Every guarantee
/// holds.
#[test]
fn image_labels_become_tags_and_the_voxel_volume_is_kept() {
    use crate::image::{ByteOrder, SourceType, VoxelImage};
    let n = 40;
    let sp = 0.001;
    let mut values = vec![0f32; n * n * n];
    let c = Vec3::splat((n as Real - 1.0) / 2.0);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let r = (Vec3::new(i as Real, j as Real, k as Real) - c).length();
                values[i + n * (j + n * k)] = if r < 7.0 {
                    2.0
                } else if r < 16.0 {
                    1.0
                } else {
                    0.0
                };
            }
        }
    }
    let image = VoxelImage {
        dims: [n; 3],
        spacing: Vec3::splat(sp),
        origin: Vec3::ZERO,
        values,
        source_type: SourceType::U8,
        byte_order: ByteOrder::Little,
        segments: Vec::new(),
    };
    let d = ImageDomain::from_labels(&image, &[1.0, 2.0]).unwrap_or_else(|e| panic!("{e}"));
    let s = stuff(&d, 0.002, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
    let r = &s.report;
    assert!(r.violations().is_empty(), "{r}");
    let centre = c * sp;
    for (t, &tag) in s.tags.iter().enumerate() {
        let m = s.mesh.corners(t).iter().sum::<Vec3>() / 4.0;
        let dist = (m - centre).length() / sp;
        if dist < 5.0 {
            assert_eq!(tag, 2, "tet {t} at {dist} voxels");
        } else if dist > 9.0 {
            assert_eq!(tag, 1, "tet {t} at {dist} voxels");
        }
    }
    // A blur of σ = 1 voxel shrinks the convex ball at level 1/2 (measured −1.7 %): every
    // other guarantee holds.
    let d = d.smoothed(0.001);
    let s = stuff(&d, 0.002, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
    let r = &s.report;
    assert_eq!((r.inverted, r.degenerate), (0, 0), "{r}");
    assert!(
        r.min_dihedral_deg >= 10.0 && r.hausdorff <= 0.5 * r.size,
        "{r}"
    );
    assert!(r.volume_error.is_some_and(|e| e.abs() < 0.02), "{r}");
}

/// A ball of voxels cut by the image's border and split by a crack 1 voxel wide from its
/// surface to its centre: the lattice (h = 3 voxels) cannot follow the crack, and the report
/// says so (input→mesh over h/2 on the whole input, a share of the input boundary beyond
/// h/2, the farthest sample in the crack) while the guarantee, checked against the input at
/// resolution h (the crack closed), holds; where the ball meets the border the mesh closes
/// it half a voxel beyond, within h/2.
#[test]
fn a_crack_thinner_than_h_is_reported_and_the_border_closes_the_mesh() {
    use crate::image::{ByteOrder, SourceType, VoxelImage};
    let (n, sp, h) = ([36, 36, 24], 0.001, 0.003);
    // Centre on the last z slice: the top half of the ball is beyond the image.
    let c = Vec3::new(17.5, 17.5, 23.0);
    let mut values = vec![0f32; n[0] * n[1] * n[2]];
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                let p = Vec3::new(i as Real, j as Real, k as Real);
                let in_ball = (p - c).length() < 15.0;
                let in_crack = j == 17 && p.x > c.x;
                values[i + n[0] * (j + n[1] * k)] = if in_ball && !in_crack { 1.0 } else { 0.0 };
            }
        }
    }
    let image = VoxelImage {
        dims: n,
        spacing: Vec3::splat(sp),
        origin: Vec3::ZERO,
        values,
        source_type: SourceType::U8,
        byte_order: ByteOrder::Little,
        segments: Vec::new(),
    };
    let d = ImageDomain::from_threshold(&image, 0.5, 1.5).unwrap_or_else(|e| panic!("{e}"));
    let s = stuff(&d, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
    let r = &s.report;
    assert_eq!((r.inverted, r.degenerate), (0, 0), "{r}");
    assert!(r.min_dihedral_deg >= 10.0, "{r}");
    // The crack's walls are up to its depth (measured 2.0 h) from the mesh's boundary.
    assert!(r.input_to_mesh > 1.5 * h, "{r}");
    assert!(r.input_beyond_half_size > 0.01, "{r}");
    let far = Vec3::from_array(r.farthest_input_sample) / sp;
    assert!(
        (16.0..19.0).contains(&far.y) && far.x >= c.x,
        "farthest at {far} voxels: {r}"
    );
    let resolved = r.resolved_input_to_mesh.unwrap_or(Real::INFINITY);
    assert!(resolved <= 0.5 * h, "{r}");
    assert!(
        r.hausdorff <= 0.5 * h && r.violations().iter().all(|v| !v.contains("boundary")),
        "{r}"
    );
    // The cut face: boundary vertices reach z = 23.5 voxels (half a voxel past the last
    // slice) and none goes farther, but for the rim's vertices moved off their chords since
    // session 17 (`follow::off_chords`: a vertex with no face on the cut plane, measured
    // 23.53 voxels = 0.01 h past it).
    let top = s
        .mesh
        .vertices
        .iter()
        .map(|v| v.z / sp)
        .fold(0.0, Real::max);
    assert!((23.0..=23.55).contains(&top), "top at {top} voxels");
    assert!(r.to_string().contains("thinner than h"), "{r}");
}

/// A ball with a smaller one joined to it by a strand 2 voxels thick, h = 4 voxels (issue
/// 25, the pelvis's loose pieces): the input is one piece, so the mesh keeps its largest
/// piece; the ball of radius h/2 cuts the strand, and the input at resolution h keeps only
/// its largest part too, so the small ball is not held against the mesh that dropped it.
/// The whole input's distance still reports it (the small ball is far from the mesh).
#[test]
fn a_part_cut_off_at_resolution_h_is_reported_not_held_against_the_mesh() {
    use crate::image::{ByteOrder, Cleaning, SourceType, VoxelImage};
    let (n, sp, h) = ([44, 24, 24], 0.001, 0.004);
    let (big, small) = (Vec3::new(12.0, 11.5, 11.5), Vec3::new(33.0, 11.5, 11.5));
    let mut values = vec![0f32; n[0] * n[1] * n[2]];
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                let p = Vec3::new(i as Real, j as Real, k as Real);
                let strand = (11..13).contains(&j) && (11..13).contains(&k) && p.x > big.x;
                if (p - big).length() < 9.0 || (p - small).length() < 4.0 || strand && p.x < small.x
                {
                    values[i + n[0] * (j + n[1] * k)] = 1.0;
                }
            }
        }
    }
    let image = VoxelImage {
        dims: n,
        spacing: Vec3::splat(sp),
        origin: Vec3::ZERO,
        values,
        source_type: SourceType::U8,
        byte_order: ByteOrder::Little,
        segments: Vec::new(),
    };
    let one_piece = Cleaning {
        open: 0.0,
        close: 0.0,
        open_close: 0,
        largest_component: true,
        fill_holes: false,
    };
    let d = ImageDomain::from_threshold(&image, 0.5, 1.5)
        .and_then(|d| d.cleaned(one_piece))
        .unwrap_or_else(|e| panic!("{e}"));
    let near_small = |samples: &[Vec3]| {
        samples
            .iter()
            .filter(|p| (**p / sp - small).length() < 6.0)
            .count()
    };
    // The filtered input without the one-piece rule keeps the small ball; with it, not.
    let all_parts = ImageDomain::from_threshold(&image, 0.5, 1.5).unwrap_or_else(|e| panic!("{e}"));
    assert!(near_small(&all_parts.at_resolution(h).boundary_samples(0.25 * h)) > 0);
    assert_eq!(
        near_small(&d.at_resolution(h).boundary_samples(0.25 * h)),
        0
    );
    let s = stuff(&d, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
    let r = &s.report;
    assert_eq!((r.inverted, r.degenerate), (0, 0), "{r}");
    let resolved = r.resolved_input_to_mesh.unwrap_or(Real::INFINITY);
    assert!(resolved <= 0.5 * h, "{r}");
    // The small ball (radius 4 voxels = h) is not in the mesh: the whole input's distance
    // says so, at its far side.
    assert!(r.input_to_mesh > h, "{r}");
    let far = Vec3::from_array(r.farthest_input_sample) / sp;
    assert!(
        (far - small).length() < 6.0,
        "farthest at {far} voxels: {r}"
    );
    // What went is in the volume, which is checked against the whole input's voxels.
    let v = r.violations();
    assert!(
        v.iter().any(|v| v.contains("volume")) && !v.iter().any(|v| v.contains("boundary")),
        "{r}"
    );
}

/// A scene's declared ball filters (`Cleaning::close`, `open`; issue 25, the pelvis's
/// bundles of muscle parted by cracks of fat): a block of four bundles parted by cracks one
/// voxel wide, anisotropic voxels (1 × 1 × 2 mm), with a strand one voxel thick sticking out.
/// Without the filters the largest bundle alone is meshed (3 parts dropped); closed by a
/// ball of radius 1.5 mm then opened by one, the cracks (3 × 20 × 12 voxels) are filled
/// and the strand (3 voxels) goes, the block is one part, the report says both, and every
/// guarantee is measured against the filtered voxels: the reference volume is theirs, the
/// boundary is within h/2 of them both ways, and the volume before the filter is beside it.
#[test]
fn declared_ball_filters_join_bundles_and_the_guarantees_use_the_filtered_voxels() {
    use crate::image::{ByteOrder, Cleaning, SourceType, VoxelImage};
    let (n, h) = ([28, 28, 16], 0.004);
    let spacing = Vec3::new(0.001, 0.001, 0.002);
    let mut values = vec![0f32; n[0] * n[1] * n[2]];
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                let block = (4..24).contains(&i) && (4..24).contains(&j) && (2..14).contains(&k);
                let crack = [9, 14, 19].contains(&j);
                let strand = (24..27).contains(&i) && j == 12 && k == 8;
                if block && !crack || strand {
                    values[i + n[0] * (j + n[1] * k)] = 1.0;
                }
            }
        }
    }
    let image = VoxelImage {
        dims: n,
        spacing,
        origin: Vec3::ZERO,
        values,
        source_type: SourceType::U8,
        byte_order: ByteOrder::Little,
        segments: Vec::new(),
    };
    let plain = Cleaning {
        open_close: 0,
        ..Cleaning::default()
    };
    let domain = |c: Cleaning| {
        ImageDomain::from_threshold(&image, 0.5, 1.5)
            .and_then(|d| d.cleaned(c))
            .unwrap_or_else(|e| panic!("{e}"))
    };
    let bundle = domain(plain);
    let c = bundle
        .cleaning()
        .unwrap_or_else(|| panic!("a cleaning report"))
        .0;
    assert_eq!((c.parts_dropped, c.voxels_after), (3, 1200), "{c:?}");
    let filtered = domain(Cleaning {
        close: 0.0015,
        open: 0.0015,
        ..plain
    });
    let c = filtered
        .cleaning()
        .unwrap_or_else(|| panic!("a cleaning report"))
        .0;
    assert_eq!(
        (
            c.voxels_before,
            c.closed_voxels,
            c.opened_voxels,
            c.parts_dropped,
            c.voxels_after
        ),
        (4083, 720, 3, 0, 4800),
        "{c:?}"
    );
    assert_eq!((c.close, c.open), (0.0015, 0.0015));
    let s = stuff(&filtered, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
    let r = &s.report;
    let voxel = spacing.x * spacing.y * spacing.z;
    let reference = r.reference_volume.unwrap_or(0.0);
    assert!((reference - 4800.0 * voxel).abs() < 1e-12, "{r}");
    let before = r.uncleaned_volume.unwrap_or(0.0);
    assert!((before - 4083.0 * voxel).abs() < 1e-12, "{r}");
    assert!(
        r.mesh_to_input <= 0.5 * h && r.resolved_input_to_mesh.unwrap_or(Real::INFINITY) <= 0.5 * h,
        "{r}"
    );
    // The box's edges are rounded by the voxels' trilinear level set and cut by the chords
    // at a lattice of 4 voxels (measured −3.55 %); the volume guarantee itself is held on
    // the pelvis scene (`voxel_image_scenes`).
    assert!(r.volume_error.unwrap_or(1.0).abs() < 0.05, "{r}");
    assert_eq!((r.inverted, r.degenerate), (0, 0), "{r}");
    let text = r.to_string();
    assert!(
        text.contains("closed by a ball of radius 1.500e-3 m (720 voxels")
            && text.contains("opened by a ball of radius 1.500e-3 m (3 voxels"),
        "{text}"
    );
}

/// Speed and accuracy at about 100k and 1M tetrahedra, printed (run on one core with
/// `RAYON_NUM_THREADS=1 cargo test --release -p tissue --lib stuffing_speed -- --ignored
/// --nocapture`).
#[test]
#[ignore]
fn stuffing_speed() {
    let d = SurfaceDomain::new(&liver()).unwrap_or_else(|e| panic!("{e}"));
    for h in [0.003, 0.0014] {
        let s = stuff(&d, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
        println!("liver h = {h}: {}", s.report);
    }
    let sphere = sphere(0.05);
    let s = stuff(&sphere, 0.0022, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
    println!("sphere r = 0.05, h = 0.0022: {}", s.report);
}

mod blobs {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(8))]
        /// Random blobby shapes (sums of up to five Gaussian bumps): no inverted or degenerate
        /// tetrahedron, every dihedral angle at least 10° (the stencils keep 10.7° sampled).
        #[test]
        fn random_blobs_give_valid_meshes(
            centres in proptest::collection::vec((-0.5f64..0.5, -0.5f64..0.5, -0.5f64..0.5, 0.15f64..0.35), 1..6),
            h in 0.08f64..0.14,
        ) {
            let bumps: Vec<(Vec3, Real)> = centres.iter().map(|&(x, y, z, r)| (Vec3::new(x, y, z), r)).collect();
            let d = Implicit {
                f: move |p: Vec3| {
                    0.5 - bumps.iter().map(|&(c, r)| (-(p - c).length_squared() / (r * r)).exp()).sum::<Real>()
                },
                lo: Vec3::splat(-1.0),
                hi: Vec3::splat(1.0),
                volume: None,
            };
            let s = stuff(&d, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
            let r = &s.report;
            prop_assert!(r.tets > 0);
            prop_assert_eq!((r.inverted, r.degenerate), (0, 0), "{}", r);
            prop_assert!(r.min_dihedral_deg >= 10.0, "{}", r);
            s.mesh.validate_for_simulation().unwrap_or_else(|e| panic!("{e}"));
        }
    }

    /// `random_blobs_give_valid_meshes` on many more shapes (`SEEDS=n`, default 200), drawn
    /// by a fixed generator: the smallest and largest dihedral angle found, printed.
    /// `cargo test --release -p tissue --lib random_blobs_study -- --ignored --nocapture`
    #[test]
    #[ignore]
    fn random_blobs_study() {
        use crate::mesh::stuffing::stencil_bounds::Rng;
        let n: u64 = std::env::var("SEEDS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(200);
        let (mut lo, mut hi, mut tets): (Real, Real, usize) = (180.0, 0.0, 0);
        for seed in 1..=n {
            let mut rng = Rng(seed);
            let count = 1 + rng.below(5);
            let bumps: Vec<(Vec3, Real)> = (0..count)
                .map(|_| {
                    let c = Vec3::new(rng.unit(), rng.unit(), rng.unit()) - Vec3::splat(0.5);
                    (c, 0.15 + 0.2 * rng.unit())
                })
                .collect();
            let h = 0.08 + 0.06 * rng.unit();
            let d = Implicit {
                f: move |p: Vec3| {
                    0.5 - bumps
                        .iter()
                        .map(|&(c, r)| (-(p - c).length_squared() / (r * r)).exp())
                        .sum::<Real>()
                },
                lo: Vec3::splat(-1.0),
                hi: Vec3::splat(1.0),
                volume: None,
            };
            let s = stuff(&d, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
            let r = &s.report;
            assert_eq!((r.inverted, r.degenerate), (0, 0), "seed {seed}: {r}");
            assert!(r.min_dihedral_deg >= 10.0, "seed {seed}: {r}");
            lo = lo.min(r.min_dihedral_deg);
            hi = hi.max(r.max_dihedral_deg);
            tets += r.tets;
        }
        println!("{n} blobs, {tets} tetrahedra: dihedral angles {lo:.2}° .. {hi:.2}°");
    }
}

/// Both BCC tetrahedra sharing a lattice face split its quadrilateral the same way: the
/// mesh is conforming. Every triangle is a face of one tetrahedron (then all three corners
/// are on the boundary) or of two with opposite orientations, and the boundary is closed.
#[test]
fn neighbouring_stencils_agree_so_the_mesh_is_conforming() {
    let bumps = [
        (Vec3::new(0.1, 0.0, 0.05), 0.3),
        (Vec3::new(-0.25, 0.15, -0.1), 0.22),
        (Vec3::new(0.2, -0.3, 0.2), 0.18),
    ];
    let f = move |p: Vec3| {
        0.5 - bumps
            .iter()
            .map(|&(c, r)| (-(p - c).length_squared() / (r * r)).exp())
            .sum::<Real>()
    };
    let d = Implicit {
        f,
        lo: Vec3::splat(-1.0),
        hi: Vec3::splat(1.0),
        volume: None,
    };
    for h in [0.05, 0.037] {
        let s = stuff(&d, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
        let mut faces: FxHashMap<[u32; 3], Vec<bool>> = FxHashMap::default();
        for t in &s.mesh.tets {
            for (a, b, c) in [(1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1)] {
                let tri = [t[a], t[b], t[c]];
                let mut key = tri;
                key.sort_unstable();
                // Orientation parity of the permutation that sorts the triangle.
                let rot = (0..3).any(|i| [tri[i], tri[(i + 1) % 3], tri[(i + 2) % 3]] == key);
                faces.entry(key).or_default().push(rot);
            }
        }
        let mut boundary_edges: FxHashMap<[u32; 2], usize> = FxHashMap::default();
        for (key, sides) in &faces {
            match sides.as_slice() {
                [_] => {
                    for &v in key {
                        let fv = (d.f)(s.mesh.vertices[v as usize]);
                        assert!(
                            fv.abs() < 1e-9,
                            "boundary face {key:?} off the surface: {fv}"
                        );
                    }
                    for (a, b) in [(0, 1), (1, 2), (0, 2)] {
                        *boundary_edges.entry([key[a], key[b]]).or_default() += 1;
                    }
                }
                [x, y] => assert_ne!(x, y, "face {key:?} has the same side twice"),
                more => panic!("face {key:?} shared by {} tetrahedra", more.len()),
            }
        }
        assert!(boundary_edges.values().all(|&n| n == 2));
    }
}

/// The quality table of docs/meshing.md: the shipped livers in file units at several sizes
/// (`cargo test --release --workspace --lib quality_table -- --ignored --nocapture`).
/// Asserts what the table says: the smooth liver keeps every guarantee at h = 0.3, 0.2 and
/// 0.15 (0.15 was refused at 9.88° before the lattice split rule), and no size gives an
/// inverted or degenerate tetrahedron.
#[test]
#[ignore]
fn quality_table() {
    for (file, sizes) in [
        ("liver-smooth.obj", &[0.5, 0.3, 0.2, 0.15, 0.07][..]),
        ("liver.obj", &[1.0, 0.5, 0.3][..]),
    ] {
        let path = format!("{}/../../assets/meshes/{file}", env!("CARGO_MANIFEST_DIR"));
        let data = crate::io::read(&path).unwrap_or_else(|e| panic!("{e}"));
        let surface = data.surface_mesh().unwrap_or_else(|e| panic!("{e}"));
        let d = SurfaceDomain::new(&surface).unwrap_or_else(|e| panic!("{e}"));
        for &h in sizes {
            let s = stuff(&d, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
            println!("{file} h = {h}:\n{}", s.report);
            assert_eq!(
                (s.report.inverted, s.report.degenerate),
                (0, 0),
                "{file} h = {h}"
            );
            if file == "liver-smooth.obj" && [0.3, 0.2, 0.15].contains(&h) {
                assert!(
                    s.report.violations().is_empty(),
                    "{file} h = {h}: {}",
                    s.report
                );
            }
        }
    }
}

/// The studies' image mesh: the voxels in `window`, cleaned, blurred by `sigma`, stuffed at `h`.
fn stuff_window(
    image: &crate::image::VoxelImage,
    window: (f32, f32),
    cleaning: crate::image::Cleaning,
    sigma: Real,
    h: Real,
) -> Stuffed {
    let d = ImageDomain::from_threshold(image, window.0, window.1)
        .and_then(|d| d.cleaned(cleaning))
        .unwrap_or_else(|e| panic!("{e}"))
        .smoothed(sigma);
    stuff(&d, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"))
}

/// Image → tetrahedra settings for the brain scene, printed
/// (`cargo test --release --workspace --lib brain_image_study -- --ignored --nocapture`).
#[test]
#[ignore]
fn brain_image_study() {
    use crate::image::{Cleaning, read_image};
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/images/anatomical.nii"
    );
    let image = read_image(std::path::Path::new(path), 0.001).unwrap_or_else(|e| panic!("{e}"));
    for cleaning in [Cleaning::NONE, Cleaning::default()] {
        for h in [0.004, 0.005, 0.006] {
            for smooth in [0.0, 0.5, 1.0] {
                let s = stuff_window(&image, (6000.0, 40000.0), cleaning, smooth * h, h);
                let r = &s.report;
                println!(
                    "clean {} h {h} smooth {smooth}h: {} tets, dihedral {:.2}..{:.2}, volume {:+.2} % (uncleaned {:+.2} %), Hausdorff {:.3} h; {:?}",
                    cleaning != Cleaning::NONE,
                    r.tets,
                    r.min_dihedral_deg,
                    r.max_dihedral_deg,
                    100.0 * r.volume_error.unwrap_or(0.0),
                    100.0 * r.uncleaned_volume_error.unwrap_or(0.0),
                    r.hausdorff / h,
                    r.violations()
                );
            }
        }
    }
}

/// Where the input→mesh distance comes from on the shipped images: the farthest input
/// boundary samples with the voxel they lie in, whether it is on the image's border, and the
/// run of selected voxels through it along x, y and z (thin parts show as short runs).
/// `STUDY_FACTOR` is the ball radius of the resolution filter in h (default 0.5).
#[test]
#[ignore]
fn image_far_samples_study() {
    use crate::image::{Cleaning, read_image};
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/images/");
    let factor: Real = std::env::var("STUDY_FACTOR")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.5);
    for (file, scale, lo, hi, h, smooth, premesh) in [
        ("pelvis_f.mhd", 0.1, 20.0, 75.0, 0.009935, 0.0, false),
        ("pelvis_f.mhd", 0.1, 20.0, 75.0, 0.006, 0.003, false),
        ("pelvis_f.mhd", 0.1, 20.0, 75.0, 0.006, 0.0, true),
        (
            "anatomical.nii",
            0.001,
            6000.0,
            40000.0,
            0.005,
            0.0025,
            false,
        ),
        ("anatomical.nii", 0.001, 6000.0, 40000.0, 0.005, 0.0, true),
        ("anatomical.nii", 0.001, 6000.0, 40000.0, 0.004, 0.0, true),
    ] {
        let image = read_image(std::path::Path::new(&format!("{root}{file}")), scale)
            .unwrap_or_else(|e| panic!("{e}"));
        let raw = ImageDomain::from_threshold(&image, lo, hi)
            .and_then(|d| d.cleaned(Cleaning::default()))
            .unwrap_or_else(|e| panic!("{e}"))
            .smoothed(smooth);
        let clock = std::time::Instant::now();
        let resolved = raw.at_resolution(2.0 * factor * h);
        println!("at_resolution: {:.2} s", clock.elapsed().as_secs_f64());
        let d = if premesh { &resolved } else { &raw };
        let s = stuff(d, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
        let boundary = crate::mesh::boundary::boundary_surface(&s.mesh).surface;
        let index = TriangleIndex::new(&boundary.vertices, &boundary.triangles);
        let far_of = |dom: &ImageDomain| {
            let mut far: Vec<(Real, Vec3)> = dom
                .boundary_samples(0.25 * h)
                .iter()
                .map(|&p| (index.distance(p), p))
                .collect();
            far.sort_by(|a, b| b.0.total_cmp(&a.0));
            far
        };
        let far = far_of(&raw);
        let far_r = far_of(&resolved);
        let beyond = far.iter().filter(|f| f.0 > 0.5 * h).count();
        println!(
            "{file} h {h} σ {smooth} meshed at resolution {premesh}: {} tets, min {:.2}°, volume vs cleaned {:+.2} %, mesh→input {:.3} h, input→mesh raw {:.3} h ({:.2} % beyond h/2), resolved (r = {factor} h) {:.3} h",
            s.report.tets,
            s.report.min_dihedral_deg,
            100.0 * (s.report.volume / raw.reference_volume().unwrap_or(1.0) - 1.0),
            s.report.mesh_to_input / h,
            far[0].0 / h,
            100.0 * beyond as Real / far.len() as Real,
            far_r[0].0 / h,
        );
        if std::env::var("STUDY_VERBOSE").is_err() {
            continue;
        }
        for &(dist, p) in far_r.iter().take(6) {
            let u = ((p - image.origin) / image.spacing).round();
            println!(
                "  at resolution h: {:.2} h at {:.4?} voxel {:?}; raw value {:.3}, resolved {:.3}",
                dist / h,
                p.to_array(),
                u.to_array(),
                raw.value(p),
                resolved.value(p)
            );
        }
        let [nx, ny, nz] = image.dims;
        let inside = |i: i64, j: i64, k: i64| {
            i >= 0
                && j >= 0
                && k >= 0
                && (i as usize) < nx
                && (j as usize) < ny
                && (k as usize) < nz
                && raw.value(image.position(i as usize, j as usize, k as usize)) < 0.0
        };
        for &(dist, p) in far.iter().take(12) {
            let u = ((p - image.origin) / image.spacing).round();
            let (i, j, k) = (u.x as i64, u.y as i64, u.z as i64);
            let border = i <= 0
                || j <= 0
                || k <= 0
                || i + 1 >= nx as i64
                || j + 1 >= ny as i64
                || k + 1 >= nz as i64;
            // Runs of voxels of the same side as this one through it, along x, y, z.
            let side = inside(i, j, k);
            let run = |di: i64, dj: i64, dk: i64| {
                let mut n = 1;
                for s in [-1i64, 1] {
                    let mut t = 1;
                    while inside(i + s * t * di, j + s * t * dj, k + s * t * dk) == side && t < 400
                    {
                        n += 1;
                        t += 1;
                    }
                }
                n
            };
            println!(
                "  {:.2} h at {:.4?} voxel ({i},{j},{k}) {} border {border}: runs x {} y {} z {} voxels",
                dist / h,
                p.to_array(),
                if side { "selected" } else { "unselected" },
                run(1, 0, 0),
                run(0, 1, 0),
                run(0, 0, 1),
            );
        }
    }
}

/// Settings for the image → tetrahedra scenes: size, blur and opening on the shipped pelvis
/// and brain, with what each keeps
/// (`cargo test --release -p tissue --lib image_settings_study -- --ignored --nocapture`).
#[test]
#[ignore]
fn image_settings_study() {
    use crate::image::{Cleaning, read_image};
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/images/");
    for (file, scale, lo, hi, sizes) in [
        ("anatomical.nii", 0.001, 6000.0, 40000.0, [0.004, 0.005]),
        ("pelvis_f.mhd", 0.1, 20.0, 75.0, [0.006, 0.008]),
    ] {
        let image = read_image(std::path::Path::new(&format!("{root}{file}")), scale)
            .unwrap_or_else(|e| panic!("{e}"));
        for h in sizes {
            for open_close in [1, 2] {
                for smooth in [0.5, 0.75] {
                    let c = Cleaning {
                        open_close,
                        ..Cleaning::default()
                    };
                    let s = stuff_window(&image, (lo, hi), c, smooth * h, h);
                    let r = &s.report;
                    println!(
                        "{file} h {h} open {open_close} σ {smooth}h: {} tets, min {:.1}°, volume {:+.2} %, mesh→input {:.3} h, input→mesh {:.3} h ({:.2} % beyond h/2), resolved {:.3} h, {:.1} s; {:?}",
                        r.tets,
                        r.min_dihedral_deg,
                        100.0 * r.volume_error.unwrap_or(0.0),
                        r.mesh_to_input / h,
                        r.input_to_mesh / h,
                        100.0 * r.input_beyond_half_size,
                        r.resolved_input_to_mesh.unwrap_or(0.0) / h,
                        r.seconds,
                        r.violations()
                    );
                }
            }
        }
    }
}

/// `fem-static` on stuffed spheres of radius 5 cm sagging under gravity, the bottom cap
/// (z < −4 cm) held: the work of gravity W = Σ m_i g·u_i (twice the strain energy at
/// equilibrium), which fixes the whole displacement field in one number.
fn sphere_sag_work(h: Real, order: crate::model::fem::Order) -> (usize, Real) {
    use crate::interact::{Constraints, Loads};
    use crate::model::Deformable;
    use crate::model::fem::FemStatic;
    let s = stuff(&sphere(0.05), h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
    let material = crate::material::Material::new(3000.0, 0.3).unwrap();
    let mut fem = FemStatic::new(&s.mesh, material, order).unwrap_or_else(|e| panic!("{e}"));
    let mut c = Constraints::default();
    for (v, p) in fem.rest_surface().iter().enumerate() {
        if p.z < -0.04 {
            c.fixed.push(v as u32);
        }
    }
    fem.set_constraints(&c).unwrap_or_else(|e| panic!("{e}"));
    let g = Vec3::new(0.0, 0.0, -9.81);
    fem.set_loads(&Loads {
        gravity: g,
        ..Default::default()
    })
    .unwrap_or_else(|e| panic!("{e}"));
    fem.step(1.0).unwrap_or_else(|e| panic!("{e}"));
    let volume = fem.volume().unwrap_or_else(|| panic!("a volume view"));
    // W = ∫ ρ g·u dV over the tetrahedra (the mean of the corners' displacements).
    let mut work = 0.0;
    for t in &s.mesh.tets {
        let p = t.map(|v| s.mesh.vertices[v as usize]);
        let u: Vec3 = t
            .iter()
            .map(|&v| volume.positions[v as usize] - s.mesh.vertices[v as usize])
            .sum::<Vec3>()
            / 4.0;
        work += 1000.0 * crate::math::tet_signed_volume(p[0], p[1], p[2], p[3]).abs() * g.dot(u);
    }
    (s.mesh.tets.len(), work)
}

#[test]
fn fem_static_sag_converges_on_stuffed_spheres() {
    use crate::model::fem::Order;
    let sizes = [0.02, 0.01, 0.006];
    let p1: Vec<(usize, Real)> = sizes
        .iter()
        .map(|&h| sphere_sag_work(h, Order::Linear))
        .collect();
    let (_, reference) = sphere_sag_work(0.01, Order::Quadratic);
    for (h, (tets, w)) in sizes.iter().zip(&p1) {
        println!(
            "h = {h}: {tets} tetrahedra, P1 work of gravity {w:.6e} J, {:+.3} % from P2 at h = 0.01",
            100.0 * (w / reference - 1.0)
        );
    }
    println!("P2 at h = 0.01: {reference:.6e} J");
    // Displacement-based elements are too stiff: every P1 answer lies below the P2 one,
    // and the gap closes as the lattice refines (measured −19.4 %, −9.1 %, −8.0 %).
    let gaps: Vec<Real> = p1.iter().map(|&(_, w)| w / reference - 1.0).collect();
    assert!(gaps.iter().all(|&g| g < 0.0), "{gaps:?}");
    assert!(gaps[1] > gaps[0] && gaps[2] > gaps[1], "{gaps:?}");
}

/// Which direction and which points break the h/2 boundary promise on the shipped image
/// scenes' settings (issue 25): for each size, the farthest mesh boundary points (direction
/// a: the first-order estimate, the nearest raw sample, and both against the input at
/// resolution h) and the farthest samples of the input at resolution h (direction b), with
/// the voxel there, the raw and resolved values (negative inside), and the size of the
/// resolved input's 6-connected part of voxels nearest to it (a part the opening cut off
/// shows as a small one)
/// (`cargo test --release -p tissue --lib image_boundary_direction_study -- --ignored --nocapture`).
#[test]
#[ignore]
fn image_boundary_direction_study() {
    use crate::image::{Cleaning, read_image};
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/images/");
    let brain = Cleaning {
        open_close: 2,
        ..Cleaning::default()
    };
    let cases: Vec<(&str, Real, f32, f32, Cleaning, Real, Real)> = vec![
        ("anatomical.nii", 0.001, 6000.0, 40000.0, brain, 0.0, 0.007),
        ("anatomical.nii", 0.001, 6000.0, 40000.0, brain, 0.0, 0.006),
        ("anatomical.nii", 0.001, 6000.0, 40000.0, brain, 0.0, 0.005),
        ("anatomical.nii", 0.001, 6000.0, 40000.0, brain, 0.0, 0.004),
        (
            "pelvis_f.mhd",
            0.1,
            20.0,
            75.0,
            Cleaning::default(),
            0.5,
            0.012,
        ),
        (
            "pelvis_f.mhd",
            0.1,
            20.0,
            75.0,
            Cleaning::default(),
            0.5,
            0.010,
        ),
        (
            "pelvis_f.mhd",
            0.1,
            20.0,
            75.0,
            Cleaning::default(),
            0.5,
            0.008,
        ),
    ];
    let only = std::env::var("STUDY_ONLY").unwrap_or_default();
    for (file, scale, lo, hi, cleaning, smooth, h) in cases {
        if !file.contains(only.as_str()) {
            continue;
        }
        let image = read_image(std::path::Path::new(&format!("{root}{file}")), scale)
            .unwrap_or_else(|e| panic!("{e}"));
        let raw = ImageDomain::from_threshold(&image, lo, hi)
            .and_then(|d| d.cleaned(cleaning))
            .unwrap_or_else(|e| panic!("{e}"))
            .smoothed(smooth * h);
        let resolved = raw.at_resolution(h);
        let s = stuff(&raw, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
        let r = &s.report;
        println!(
            "\n{file} h {h}: {} tets, a (mesh→input) {:.3} h, b raw {:.3} h, b resolved {:.3} h, split {}, bare moved {} ({} partly) left {}, \
             volume {:+.2} %, manifold removed {} ({:.2e} m³), pieces dropped {} ({} tets, {:.2e} m³)",
            r.tets,
            r.mesh_to_input / h,
            r.input_to_mesh / h,
            r.resolved_input_to_mesh.unwrap_or(0.0) / h,
            r.manifold.split,
            r.manifold.bare_moved,
            r.manifold.bare_partly,
            r.manifold.bare_left,
            100.0 * r.volume_error.unwrap_or(0.0),
            r.manifold.removed,
            r.manifold.removed_volume,
            r.pieces.dropped,
            r.pieces.dropped_tets,
            r.pieces.dropped_volume
        );
        let boundary = crate::mesh::boundary::boundary_surface(&s.mesh).surface;
        let index = TriangleIndex::new(&boundary.vertices, &boundary.triangles);
        let point_index = |pts: &[Vec3]| {
            let tris: Vec<[u32; 3]> = (0..pts.len() as u32).map(|i| [i, i, i]).collect();
            TriangleIndex::new(pts, &tris)
        };
        let raw_samples = raw.boundary_samples(0.25 * h);
        let res_samples = resolved.boundary_samples(0.25 * h);
        let (near_raw, near_res) = (point_index(&raw_samples), point_index(&res_samples));
        // The resolved input's voxels in 6-connected parts, by voxel count.
        let [nx, ny, nz] = image.dims;
        let id = |i: usize, j: usize, k: usize| i + nx * (j + ny * k);
        let inside: Vec<bool> = (0..nx * ny * nz)
            .map(|n| resolved.value(image.position(n % nx, (n / nx) % ny, n / (nx * ny))) < 0.0)
            .collect();
        let mut part = vec![usize::MAX; inside.len()];
        let mut part_size = Vec::new();
        for start in 0..inside.len() {
            if !inside[start] || part[start] != usize::MAX {
                continue;
            }
            let label = part_size.len();
            let mut stack = vec![start];
            part[start] = label;
            let mut count = 0usize;
            while let Some(n) = stack.pop() {
                count += 1;
                let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
                let mut push = |m: usize| {
                    if inside[m] && part[m] == usize::MAX {
                        part[m] = label;
                        stack.push(m);
                    }
                };
                if i > 0 {
                    push(n - 1);
                }
                if i + 1 < nx {
                    push(n + 1);
                }
                if j > 0 {
                    push(n - nx);
                }
                if j + 1 < ny {
                    push(n + nx);
                }
                if k > 0 {
                    push(n - nx * ny);
                }
                if k + 1 < nz {
                    push(n + nx * ny);
                }
            }
            part_size.push(count);
        }
        let mut sizes = part_size.clone();
        sizes.sort_unstable_by(|a, b| b.cmp(a));
        println!(
            "  input at resolution h: {} parts, largest {:?} voxels",
            sizes.len(),
            &sizes[..sizes.len().min(5)]
        );
        // The part of the resolved voxel nearest to p (within 3 voxels), if any.
        let part_near = |p: Vec3| {
            let u = ((p - image.origin) / image.spacing).round();
            let mut best: Option<(Real, usize)> = None;
            for dk in -3i64..=3 {
                for dj in -3i64..=3 {
                    for di in -3i64..=3 {
                        let (i, j, k) = (u.x as i64 + di, u.y as i64 + dj, u.z as i64 + dk);
                        if i < 0
                            || j < 0
                            || k < 0
                            || i >= nx as i64
                            || j >= ny as i64
                            || k >= nz as i64
                        {
                            continue;
                        }
                        let n = id(i as usize, j as usize, k as usize);
                        if !inside[n] {
                            continue;
                        }
                        let d = (image.position(i as usize, j as usize, k as usize) - p).length();
                        if best.is_none_or(|b| d < b.0) {
                            best = Some((d, part_size[part[n]]));
                        }
                    }
                }
            }
            best.map(|b| b.1)
        };
        // Farthest points, at most one per ball of radius h.
        let distinct = |mut v: Vec<(Real, Vec3)>, n: usize| {
            v.sort_by(|a, b| b.0.total_cmp(&a.0));
            let mut out: Vec<(Real, Vec3)> = Vec::new();
            for x in v {
                if out.iter().all(|o| (o.1 - x.1).length() > h) {
                    out.push(x);
                }
                if out.len() == n {
                    break;
                }
            }
            out
        };
        let step = 1e-3 * h;
        let mut probes = boundary.vertices.clone();
        for t in 0..boundary.triangles.len() {
            let [a, b, c] = boundary.corners(t);
            probes.extend([
                (a + b + c) / 3.0,
                0.5 * (a + b),
                0.5 * (b + c),
                0.5 * (c + a),
            ]);
        }
        let a: Vec<(Real, Vec3)> = probes
            .iter()
            .map(|&p| (raw.boundary_distance(p, step).min(near_raw.distance(p)), p))
            .collect();
        let a_res = probes
            .iter()
            .map(|&p| {
                resolved
                    .boundary_distance(p, step)
                    .min(near_res.distance(p))
            })
            .fold(0.0, Real::max);
        let a_exactish = probes
            .iter()
            .map(|&p| near_raw.distance(p))
            .fold(0.0, Real::max);
        println!(
            "  a against the input at resolution h {:.3} h; nearest raw sample alone {:.3} h",
            a_res / h,
            a_exactish / h
        );
        // Boundary faces whose corners all lie inside the input (value < −0.25: a mask
        // over 3/4): faces left where tetrahedra were removed (manifold repair, dropped
        // pieces), not made on the surface.
        let exposed = |t: usize| boundary.corners(t).iter().all(|&c| raw.value(c) < -0.25);
        println!(
            "  boundary faces with every corner inside the input: {} of {}",
            (0..boundary.triangles.len())
                .filter(|&t| exposed(t))
                .count(),
            boundary.triangles.len()
        );
        for (d, p) in distinct(a.clone(), 4) {
            let t = (0..boundary.triangles.len())
                .min_by(|&x, &y| {
                    let c = |t: usize| {
                        let [a, b, c] = boundary.corners(t);
                        ((a + b + c) / 3.0 - p).length()
                    };
                    c(x).total_cmp(&c(y))
                })
                .unwrap_or(0);
            let corners = boundary.corners(t).map(|c| raw.value(c));
            let u = ((p - image.origin) / image.spacing).round();
            println!(
                "  a {:.3} h at {:.4?} voxel {:?}: |f|/|∇f| {:.3} h, nearest raw sample {:.3} h, \
                 resolved {:.3} h; raw value {:.3}, resolved {:.3}",
                d / h,
                p.to_array(),
                u.to_array(),
                raw.boundary_distance(p, step) / h,
                near_raw.distance(p) / h,
                resolved
                    .boundary_distance(p, step)
                    .min(near_res.distance(p))
                    / h,
                raw.value(p),
                resolved.value(p)
            );
            println!("    its face's corners' raw values {corners:.3?}");
        }
        let b: Vec<(Real, Vec3)> = res_samples
            .iter()
            .map(|&p| (index.distance(p), p))
            .collect();
        for (d, p) in distinct(b, 6) {
            let u = ((p - image.origin) / image.spacing).round();
            println!(
                "  b {:.3} h at {:.4?} voxel {:?}: raw value {:.3}, resolved {:.3}, part of {:?} voxels",
                d / h,
                p.to_array(),
                u.to_array(),
                raw.value(p),
                resolved.value(p),
                part_near(p)
            );
        }
    }
}
