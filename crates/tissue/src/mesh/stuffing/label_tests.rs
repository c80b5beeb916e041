//! Several labels of one image meshed as conforming regions: the checks of every mesh
//! (conforming faces, no tetrahedron across an interface, interfaces near the voxels'),
//! nested balls, random two-label blobs, and a layered cube under compression whose
//! stiffness is the two layers' in series only when the interface is conforming.

use rustc_hash::FxHashMap;

use super::interfaces::interface_samples;
use super::*;
use crate::image::{ByteOrder, SourceType, VoxelImage};

/// An image of `dims` voxels of 1 mm whose value at voxel (i, j, k) is `label(i, j, k)`.
fn image(dims: [usize; 3], label: impl Fn(usize, usize, usize) -> f32) -> VoxelImage {
    let mut values = vec![0f32; dims[0] * dims[1] * dims[2]];
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                values[i + dims[0] * (j + dims[1] * k)] = label(i, j, k);
            }
        }
    }
    VoxelImage {
        dims,
        spacing: Vec3::splat(0.001),
        origin: Vec3::ZERO,
        values,
        source_type: SourceType::U8,
        byte_order: ByteOrder::Little,
        segments: Vec::new(),
    }
}

/// What `check` found on a labelled mesh.
#[derive(Debug)]
struct Found {
    /// Faces shared by two tetrahedra of different tags.
    interface_faces: usize,
    /// Edges of those faces not in exactly two of them (0: the interfaces are closed).
    interface_rim_edges: usize,
    /// The farthest a tetrahedron's corner or centroid lies on the wrong side of the
    /// voxel interface of its label, in h (0 when none is on the wrong side), for points
    /// farther than h from the outer boundary and for those nearer (where junction
    /// tetrahedra are: no bound is claimed there).
    straddle: Real,
    straddle_near_boundary: Real,
    /// The farthest interface point of the mesh (corners, centroids and edge midpoints of
    /// interface faces) from the voxel interface, in h, away from the outer boundary and
    /// near it.
    interface: Real,
    interface_near_boundary: Real,
}

/// Checks a labelled mesh: every face is on one tetrahedron (the boundary) or two with
/// opposite orientations (conforming), and every tetrahedron's corners and centroid lie in
/// its label's voxels or within h/2 of their interface (none straddles it). The distance
/// to the voxel interface is the first-order estimate bounded by the nearest interface
/// sample (crossings of lines h/4 apart).
fn check(s: &Stuffed, d: &ImageDomain, h: Real) -> Found {
    let mut faces: FxHashMap<[u32; 3], Vec<(bool, i32)>> = FxHashMap::default();
    for (t, tet) in s.mesh.tets.iter().enumerate() {
        for (a, b, c) in [(1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1)] {
            let tri = [tet[a], tet[b], tet[c]];
            let mut key = tri;
            key.sort_unstable();
            let rot = (0..3).any(|i| [tri[i], tri[(i + 1) % 3], tri[(i + 2) % 3]] == key);
            faces.entry(key).or_default().push((rot, s.tags[t]));
        }
    }
    let mut edges: FxHashMap<[u32; 2], usize> = FxHashMap::default();
    let mut interface_faces = 0;
    let mut probes: Vec<(Vec3, usize, usize)> = Vec::new();
    let tags = d.material_tags();
    let index_of = |tag: i32| tags.iter().position(|&x| x == tag).unwrap_or(0);
    for (key, sides) in &faces {
        match sides.as_slice() {
            [_] => {}
            [x, y] => {
                assert_ne!(x.0, y.0, "face {key:?} has the same side twice");
                if x.1 != y.1 {
                    interface_faces += 1;
                    let [p, q, r] = key.map(|v| s.mesh.vertices[v as usize]);
                    for x_ in [
                        p,
                        q,
                        r,
                        (p + q + r) / 3.0,
                        0.5 * (p + q),
                        0.5 * (q + r),
                        0.5 * (r + p),
                    ] {
                        probes.push((x_, index_of(x.1), index_of(y.1)));
                    }
                    for (a, b) in [(0, 1), (1, 2), (0, 2)] {
                        *edges.entry([key[a], key[b]]).or_default() += 1;
                    }
                }
            }
            more => panic!("face {key:?} shared by {} tetrahedra", more.len()),
        }
    }
    let samples = interface_samples(d, h / 4.0);
    let points: Vec<[u32; 3]> = (0..samples.len() as u32).map(|i| [i, i, i]).collect();
    let near = TriangleIndex::new(&samples, &points);
    let outer = d.boundary_samples(h / 4.0);
    let outer_points: Vec<[u32; 3]> = (0..outer.len() as u32).map(|i| [i, i, i]).collect();
    let outer = TriangleIndex::new(&outer, &outer_points);
    let step = 1e-3 * h;
    let distance = |p: Vec3, k: usize, m: usize| {
        let f = d.interface_value(p, k, m);
        let g = Vec3::new(
            d.interface_value(p + step * Vec3::X, k, m)
                - d.interface_value(p - step * Vec3::X, k, m),
            d.interface_value(p + step * Vec3::Y, k, m)
                - d.interface_value(p - step * Vec3::Y, k, m),
            d.interface_value(p + step * Vec3::Z, k, m)
                - d.interface_value(p - step * Vec3::Z, k, m),
        ) / (2.0 * step);
        let first_order = if g.length() > 0.0 {
            f.abs() / g.length()
        } else {
            Real::INFINITY
        };
        first_order.min(near.distance(p)) / h
    };
    let (mut interface, mut interface_near_boundary): (Real, Real) = (0.0, 0.0);
    for &(p, k, m) in &probes {
        if outer.distance(p) > h {
            interface = interface.max(distance(p, k, m));
        } else {
            interface_near_boundary = interface_near_boundary.max(distance(p, k, m));
        }
    }
    let (mut straddle, mut straddle_near_boundary): (Real, Real) = (0.0, 0.0);
    for (t, &tag) in s.tags.iter().enumerate() {
        let k = tags
            .iter()
            .position(|&x| x == tag)
            .unwrap_or_else(|| panic!("tet {t} tagged {tag}, not a label"));
        let c = s.mesh.corners(t);
        for p in [c[0], c[1], c[2], c[3], (c[0] + c[1] + c[2] + c[3]) / 4.0] {
            if d.value(p) >= 0.0 {
                continue; // the outer boundary: the report measures it
            }
            let m = d.material_at(p);
            if m == k {
                continue;
            }
            if outer.distance(p) > h {
                straddle = straddle.max(distance(p, k, m));
            } else {
                straddle_near_boundary = straddle_near_boundary.max(distance(p, k, m));
            }
        }
    }
    Found {
        interface_faces,
        interface_rim_edges: edges.values().filter(|&&n| n != 2).count(),
        straddle,
        straddle_near_boundary,
        interface,
        interface_near_boundary,
    }
}

/// The ball of label 2 (radius 7 voxels) inside the ball of label 1 (radius 16): at
/// h = 2 and 1.5 voxels the mesh conforms, no tetrahedron straddles the interface, the
/// interface is a closed surface of faces within h/2 of the voxels', each label's volume
/// is near its voxels' and every angle keeps 10° (no junction: the inner ball touches
/// nothing else). Both labels keep their volume within 1 % (the inner ball −0.96 % at h = 2
/// voxels, −0.97 % at 1.5): the voxel interface itself, the level where the two labels'
/// interpolated indicators are equal, encloses 0.79 % less than the 1472 voxels counted
/// (sampled every 1/4 voxel), and the interface vertices moved off their chords
/// (`interface_volume`) bring the mesh within 0.2 % of it (as chords, −2.7 % and −3.7 %).
#[test]
fn nested_balls_give_a_conforming_closed_interface() {
    let d = ImageDomain::from_labels(&super::tests::nested_balls(40, 7.0, 16.0), &[1.0, 2.0])
        .unwrap_or_else(|e| panic!("{e}"));
    for h in [0.002, 0.0015] {
        let s = stuff(&d, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
        let r = &s.report;
        println!("h = {h}:\n{r}");
        let found = check(&s, &d, h);
        println!("{found:?}");
        assert_eq!((r.inverted, r.degenerate), (0, 0), "{r}");
        assert!(r.min_dihedral_deg >= report::MIN_DIHEDRAL_DEG, "{r}");
        assert!(
            found.interface_faces > 100 && found.interface_rim_edges == 0,
            "{found:?}"
        );
        assert!(found.straddle <= 0.5, "{found:?}");
        let labels = r.labels.as_ref().unwrap_or_else(|| panic!("labels"));
        assert_eq!(labels.interface.nonconforming_faces, 0);
        assert!(labels.interface.mesh_to_input <= 0.5 * h, "{r}");
        assert!(labels.interface.input_to_mesh <= 0.5 * h, "{r}");
        let err = |tag: i32| {
            labels
                .volumes
                .iter()
                .find(|l| l.tag == tag)
                .and_then(|l| l.volume_error)
                .unwrap_or(Real::INFINITY)
        };
        assert!(err(1).abs() <= report::MAX_LABEL_VOLUME_ERROR, "{r}");
        assert!(err(2).abs() <= report::MAX_LABEL_VOLUME_ERROR, "{r}");
        assert_eq!(r.junctions.map(|j| j.tets), Some(0), "{r}");
        assert!(r.hausdorff <= 0.5 * h, "{r}");
    }
}

/// The nested balls at h = 1 voxel (244,272 tetrahedra; 0.26 s to mesh, 2.4 min with the checks): the row of the table in
/// docs/meshing.md that the normal test leaves out. `cargo test --release -p tissue --lib
/// nested_balls_at_one_voxel_study -- --ignored --nocapture`.
#[test]
#[ignore = "minutes (the conformity checks): the 1 mm row of docs/meshing.md's nested-ball table"]
fn nested_balls_at_one_voxel_study() {
    let d = ImageDomain::from_labels(&super::tests::nested_balls(40, 7.0, 16.0), &[1.0, 2.0])
        .unwrap_or_else(|e| panic!("{e}"));
    let h = 0.001;
    let s = stuff(&d, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
    println!("h = {h}:\n{}", s.report);
    println!("{:?}", check(&s, &d, h));
}

/// A small deterministic generator (64-bit LCG) for the random images.
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> Real {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as Real / (1u64 << 53) as Real
    }
    fn range(&mut self, lo: Real, hi: Real) -> Real {
        lo + (hi - lo) * self.next()
    }
}

/// Random two-label blobs: the union is a sum of Gaussian bumps, label 2 the voxels of it
/// where a second sum is above 1/2, so label 2 sometimes reaches the outer boundary (a
/// junction line where the interface meets it). Six seeds: no inverted or degenerate
/// tetrahedron, conforming faces; farther than h from the outer boundary, no tetrahedron
/// across the interface by more than h/2 and the mesh's interface within h/2 of the
/// voxels'. Nearer (the junction tetrahedra, where the interface is coned to one point per
/// tetrahedron and cut points are held α·length from unwarped vertices) no bound is
/// claimed: measured up to 0.53 h on these seeds, printed.
/// Every two-material stencil tetrahedron keeps 10° (the stencils' sampled bound is
/// 10.7°, `stencil_bounds`); the junction tetrahedra have no proven bound and are printed.
#[test]
fn random_two_label_blobs_conform() {
    random_two_label_blobs(1..=6);
}

/// `random_two_label_blobs_conform` on more seeds (`SEEDS=n`, default 60): the smallest
/// angle of the two-material stencils and of the junction tetrahedra found.
/// `cargo test --release -p tissue --lib random_two_label_blobs_study -- --ignored --nocapture`
#[test]
#[ignore]
fn random_two_label_blobs_study() {
    let n: u64 = std::env::var("SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(60);
    random_two_label_blobs(1..=n);
}

fn random_two_label_blobs(seeds: std::ops::RangeInclusive<u64>) {
    let mut worst_junction: Real = 180.0;
    let mut worst_stencil: Real = 180.0;
    let (mut near_straddle, mut near_interface): (Real, Real) = (0.0, 0.0);
    for seed in seeds {
        let mut rng = Lcg(seed);
        let n = 32;
        let bumps = |rng: &mut Lcg, count: usize, scale: Real| -> Vec<(Vec3, Real)> {
            (0..count)
                .map(|_| {
                    (
                        Vec3::new(
                            rng.range(11.0, 21.0),
                            rng.range(11.0, 21.0),
                            rng.range(11.0, 21.0),
                        ),
                        rng.range(4.5, 7.0) * scale,
                    )
                })
                .collect()
        };
        let outer = bumps(&mut rng, 3, 1.2);
        let inner = bumps(&mut rng, 2, 1.0);
        let field = |b: &[(Vec3, Real)], p: Vec3| -> Real {
            b.iter()
                .map(|&(c, r)| (-(p - c).length_squared() / (r * r)).exp())
                .sum()
        };
        let img = image([n; 3], |i, j, k| {
            let p = Vec3::new(i as Real, j as Real, k as Real);
            if field(&outer, p) <= 0.5 {
                0.0
            } else if field(&inner, p) > 0.5 {
                2.0
            } else {
                1.0
            }
        });
        let d = ImageDomain::from_labels(&img, &[1.0, 2.0])
            .and_then(|d| d.cleaned(crate::image::Cleaning::default()))
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        let h = 0.001 * [1.5, 2.0, 2.0][seed as usize % 3];
        let s = stuff(&d, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
        let r = &s.report;
        let found = check(&s, &d, h);
        println!("seed {seed} h = {h}: {found:?}\n{r}");
        assert_eq!((r.inverted, r.degenerate), (0, 0), "seed {seed}: {r}");
        assert!(r.min_dihedral_deg > 0.0, "seed {seed}: {r}");
        assert!(found.straddle <= 0.5, "seed {seed}: {found:?}");
        near_straddle = near_straddle.max(found.straddle_near_boundary);
        near_interface = near_interface.max(found.interface_near_boundary);
        let labels = r.labels.as_ref().unwrap_or_else(|| panic!("labels"));
        assert_eq!(labels.interface.nonconforming_faces, 0, "seed {seed}");
        if labels.volumes.iter().all(|l| l.tets > 0) {
            assert!(found.interface_faces > 0, "seed {seed}: {found:?}");
            // Away from the outer boundary the mesh's interface is within h/2 of the
            // voxels'; near it (junctions) it is printed, as is voxel interface → mesh.
            assert!(found.interface <= 0.5, "seed {seed}: {found:?}");
        }
        if let Some(j) = r.junctions.and_then(|j| j.min_dihedral_deg) {
            worst_junction = worst_junction.min(j);
        }
        let stencil = r
            .junctions
            .and_then(|j| j.stencil_min_dihedral_deg)
            .unwrap_or(r.min_dihedral_deg);
        assert!(
            stencil >= 10.0,
            "seed {seed}: stencils at {stencil:.2}°: {r}"
        );
        worst_stencil = worst_stencil.min(stencil);
        s.mesh
            .validate_for_simulation()
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
    }
    println!(
        "over the seeds: smallest two-material stencil angle {worst_stencil:.2}°, smallest \
         junction angle {worst_junction:.2}°, near the outer \
         boundary tetrahedra across the interface by up to {near_straddle:.3} h, interface up \
         to {near_interface:.3} h from the voxels'"
    );
}

/// The reaction of a layered block under uniaxial compression, by linear FEM with one
/// material per tag (`materials(tag)`), ν = 0: nodes on the bottom face (z at its
/// smallest) held, nodes on the top face moved down by `delta` (x and y held on both), the
/// rest free. Solved by conjugate gradients (Jacobi) on the assembled element matrices.
fn compression_reaction(
    mesh: &TetMesh,
    tags: &[i32],
    material: impl Fn(i32) -> crate::material::Material,
    delta: Real,
) -> Real {
    let planes = mesh
        .vertices
        .iter()
        .fold((Real::INFINITY, Real::NEG_INFINITY), |(a, b), p| {
            (a.min(p.z), b.max(p.z))
        });
    compression_reaction_between(mesh, tags, material, delta, planes)
}

/// `compression_reaction` with the platens at `planes` (z below, z above): every vertex at
/// or past a plane is held by it.
fn compression_reaction_between(
    mesh: &TetMesh,
    tags: &[i32],
    material: impl Fn(i32) -> crate::material::Material,
    delta: Real,
    (zmin, zmax): (Real, Real),
) -> Real {
    use crate::model::fem::element_linear::stiffness;
    let n = mesh.vertices.len();
    let tol = 1e-9;
    let mut fixed = vec![None; 3 * n];
    for (v, p) in mesh.vertices.iter().enumerate() {
        if p.z <= zmin + tol {
            fixed[3 * v..3 * v + 3].copy_from_slice(&[Some(0.0); 3]);
        } else if p.z >= zmax - tol {
            fixed[3 * v..3 * v + 3].copy_from_slice(&[Some(0.0), Some(0.0), Some(-delta)]);
        }
    }
    let ke: Vec<[[Real; 12]; 12]> = mesh
        .tets
        .iter()
        .enumerate()
        .map(|(t, _)| {
            stiffness(&mesh.corners(t), &material(tags[t]))
                .unwrap_or_else(|| panic!("flat tet {t}"))
        })
        .collect();
    let apply = |u: &[Real], out: &mut [Real]| {
        out.iter_mut().for_each(|x| *x = 0.0);
        for (t, tet) in mesh.tets.iter().enumerate() {
            let dofs: Vec<usize> = tet
                .iter()
                .flat_map(|&v| (0..3).map(move |c| 3 * v as usize + c))
                .collect();
            for (i, &di) in dofs.iter().enumerate() {
                out[di] += (0..12).map(|j| ke[t][i][j] * u[dofs[j]]).sum::<Real>();
            }
        }
    };
    let mut diag = vec![0.0; 3 * n];
    for (t, tet) in mesh.tets.iter().enumerate() {
        for (a, &v) in tet.iter().enumerate() {
            for c in 0..3 {
                diag[3 * v as usize + c] += ke[t][3 * a + c][3 * a + c];
            }
        }
    }
    // u = u_prescribed + w, w zero on held dofs: K_ff w = −K_fp u_p.
    let mut u: Vec<Real> = fixed.iter().map(|f| f.unwrap_or(0.0)).collect();
    let mut ku = vec![0.0; 3 * n];
    apply(&u, &mut ku);
    let free = |i: usize| fixed[i].is_none();
    let mut r: Vec<Real> = (0..3 * n)
        .map(|i| if free(i) { -ku[i] } else { 0.0 })
        .collect();
    let mut z: Vec<Real> = (0..3 * n).map(|i| r[i] / diag[i].max(1e-300)).collect();
    let mut p = z.clone();
    let mut rz: Real = r.iter().zip(&z).map(|(a, b)| a * b).sum();
    let r0 = r.iter().map(|x| x * x).sum::<Real>().sqrt();
    let mut kp = vec![0.0; 3 * n];
    for _ in 0..20 * n {
        apply(&p, &mut kp);
        for (i, k) in kp.iter_mut().enumerate() {
            if !free(i) {
                *k = 0.0;
            }
        }
        let alpha = rz / p.iter().zip(&kp).map(|(a, b)| a * b).sum::<Real>();
        for ((ui, ri), (pi, ki)) in u.iter_mut().zip(r.iter_mut()).zip(p.iter().zip(&kp)) {
            *ui += alpha * pi;
            *ri -= alpha * ki;
        }
        if r.iter().map(|x| x * x).sum::<Real>().sqrt() <= 1e-12 * r0 {
            break;
        }
        for ((zi, ri), di) in z.iter_mut().zip(&r).zip(&diag) {
            *zi = ri / di.max(1e-300);
        }
        let rz_new: Real = r.iter().zip(&z).map(|(a, b)| a * b).sum();
        let beta = rz_new / rz;
        rz = rz_new;
        for (pi, zi) in p.iter_mut().zip(&z) {
            *pi = zi + beta * *pi;
        }
    }
    apply(&u, &mut ku);
    // The force the top nodes need to be held down: the reaction, positive in compression.
    -(0..n)
        .filter(|&v| mesh.vertices[v].z >= zmax - tol)
        .map(|v| ku[3 * v + 2])
        .sum::<Real>()
}

/// A block of 12 × 12 × 24 voxels of 1 mm, its lower half label 1 (E = 10 kPa), its upper
/// half label 2 (E = 1 kPa), the interface the plane between them, compressed along z by
/// 1 % of its height. With ν = 0 the layers do not pull on each other sideways, so the
/// stiffness is two springs in series, k = A / (L₁/E₁ + L₂/E₂), and the displacement is
/// linear in z within each layer: linear tetrahedra represent it exactly when the
/// interface is made of their faces (A: the mesh's mean cross-section, the block's edges
/// being rounded by the voxels' interpolation). Measured at h = 3 mm: the conforming mesh
/// −1.3 % from the series value; the same union mesh tagged by the nearest voxel (what the
/// mesher did before: tetrahedra straddling the plane) too stiff, +1.8 %.
#[test]
fn a_layered_block_under_compression_is_two_springs_in_series() {
    let (e1, e2) = (1.0e4, 1.0e3);
    let dims = [16, 16, 28];
    let img = image(dims, |i, j, k| {
        let inside = (2..14).contains(&i) && (2..14).contains(&j) && (2..26).contains(&k);
        match (inside, k < 14) {
            (false, _) => 0.0,
            (true, true) => 1.0,
            (true, false) => 2.0,
        }
    });
    let material = |tag: i32| {
        crate::material::Material::new(if tag == 1 { e1 } else { e2 }, 0.0)
            .unwrap_or_else(|e| panic!("{e}"))
    };
    let h = 0.003;
    let delta = 0.01 * 0.024;
    let labelled = ImageDomain::from_labels(&img, &[1.0, 2.0]).unwrap_or_else(|e| panic!("{e}"));
    let s = stuff(&labelled, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
    println!("{}", s.report);
    let found = check(&s, &labelled, h);
    assert!(found.straddle <= 0.5, "{found:?}");
    let (zmin, zmax) = s
        .mesh
        .vertices
        .iter()
        .fold((Real::INFINITY, Real::NEG_INFINITY), |(a, b), p| {
            (a.min(p.z), b.max(p.z))
        });
    let length = zmax - zmin;
    let area = s.report.volume / length;
    // The interface plane z = 13.5 mm (half way between voxel rows 13 and 14).
    let (l1, l2) = (0.0135 - zmin, zmax - 0.0135);
    let series = area / (l1 / e1 + l2 / e2);
    let conforming = compression_reaction(&s.mesh, &s.tags, material, delta) / delta;
    // The old way: the union meshed as one region, each tetrahedron tagged by the label of
    // the voxel nearest its centroid.
    let union = ImageDomain::from_threshold(&img, 0.5, 2.5).unwrap_or_else(|e| panic!("{e}"));
    let u = stuff(&union, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
    let nearest: Vec<i32> = (0..u.mesh.tets.len())
        .map(|t| labelled.tag_at(u.mesh.corners(t).iter().sum::<Vec3>() / 4.0))
        .collect();
    // Held at the conforming mesh's end planes (the block's): since session 17 the union's
    // boundary moves off its chords, and vertices of its rounded rims lie up to 0.08 h past
    // those planes, which the platens hold too.
    let straddling =
        compression_reaction_between(&u.mesh, &nearest, material, delta, (zmin, zmax)) / delta;
    println!(
        "series {series:.6e} N/m (A = {area:.4e} m², L1 = {l1:.4e} m, L2 = {l2:.4e} m); \
         conforming {conforming:.6e} N/m ({:+.3} %); nearest-voxel tags {straddling:.6e} N/m \
         ({:+.3} %)",
        100.0 * (conforming / series - 1.0),
        100.0 * (straddling / series - 1.0)
    );
    // Measured at h = 3 mm: conforming −1.29 %, nearest-voxel tags +1.77 % (the block's
    // rounded edges and its junction ring weigh on both; `exact_layers_…` has exact planes).
    assert!((conforming / series - 1.0).abs() < 0.02);
    assert!(straddling > conforming);
}

/// A box of two layers as an implicit domain: x and y in [0, `side`], z in [0, `height`],
/// material 0 (tag 1) below the plane z = `plane`, material 1 (tag 2) above. Its faces and
/// interface are exact planes, so the mesh's are too.
struct Layers {
    side: Real,
    height: Real,
    plane: Real,
}

impl Domain for Layers {
    fn value(&self, p: Vec3) -> Real {
        let c = Vec3::new(0.5 * self.side, 0.5 * self.side, 0.5 * self.height);
        let half = Vec3::new(0.5 * self.side, 0.5 * self.side, 0.5 * self.height);
        ((p - c).abs() - half).max_element()
    }
    fn bounds(&self) -> (Vec3, Vec3) {
        (Vec3::ZERO, Vec3::new(self.side, self.side, self.height))
    }
    fn reference_volume(&self) -> Option<Real> {
        Some(self.side * self.side * self.height)
    }
    fn material_tags(&self) -> &[i32] {
        &[1, 2]
    }
    fn material_at(&self, p: Vec3) -> usize {
        usize::from(p.z >= self.plane)
    }
    fn interface_value(&self, p: Vec3, a: usize, _b: usize) -> Real {
        if a == 0 {
            p.z - self.plane
        } else {
            self.plane - p.z
        }
    }
    fn material_volumes(&self) -> Vec<Real> {
        let a = self.side * self.side;
        vec![a * self.plane, a * (self.height - self.plane)]
    }
}

/// The layered block with exact planes (`Layers`: 12 × 12 × 24 mm, the interface at
/// z = 12.5 mm; h = 3 and 1.5 mm, lattice vertices 0.5 mm below it warped onto it),
/// E = 10 kPa below and 1 kPa above, ν = 0, compressed by 1 % of its height: the
/// conforming mesh gives the series stiffness A / (L₁/E₁ + L₂/E₂); the same box meshed as
/// one region and tagged by the material at each centroid (tetrahedra across the plane)
/// does not.
#[test]
fn exact_layers_under_compression_give_the_series_stiffness() {
    let (e1, e2) = (1.0e4, 1.0e3);
    let d = Layers {
        side: 0.012,
        height: 0.024,
        plane: 0.0125,
    };
    let material = |tag: i32| {
        crate::material::Material::new(if tag == 1 { e1 } else { e2 }, 0.0)
            .unwrap_or_else(|e| panic!("{e}"))
    };
    let delta = 0.01 * 0.024;
    let mut errors = Vec::new();
    for h in [0.003, 0.0015] {
        let s = stuff(&d, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
        println!("{}", s.report);
        let area = d.side * d.side;
        let series = area / (d.plane / e1 + (d.height - d.plane) / e2);
        let conforming = compression_reaction(&s.mesh, &s.tags, material, delta) / delta;
        let union = Implicit {
            f: |p: Vec3| d.value(p),
            lo: Vec3::ZERO,
            hi: Vec3::new(d.side, d.side, d.height),
            volume: d.reference_volume(),
        };
        let u = stuff(&union, h, &Progress::silent()).unwrap_or_else(|e| panic!("{e}"));
        let by_centroid: Vec<i32> = (0..u.mesh.tets.len())
            .map(|t| 1 + d.material_at(u.mesh.corners(t).iter().sum::<Vec3>() / 4.0) as i32)
            .collect();
        let straddling = compression_reaction(&u.mesh, &by_centroid, material, delta) / delta;
        println!(
            "h = {h}: exact layers: series {series:.6e} N/m; conforming {conforming:.6e} N/m ({:+.4} %); \
             tagged by centroid {straddling:.6e} N/m ({:+.4} %)",
            100.0 * (conforming / series - 1.0),
            100.0 * (straddling / series - 1.0)
        );
        errors.push((conforming / series - 1.0, straddling / series - 1.0));
    }
    // Measured: conforming −3.66 % and −1.23 %, tagged by centroid +4.23 % and +1.11 %.
    // Both errors are first order in h: the conforming mesh's comes from the junction ring
    // where the interface meets the sides (cut points held α·length from the vertices that
    // could not be warped: a dent, and the interface coned inside junction tetrahedra), the
    // other's from the staircase of tetrahedra across the plane, too stiff.
    let (c, st) = (errors[1].0, errors[1].1);
    assert!(c < 0.0 && c.abs() < 0.015 && st > 0.0, "{errors:?}");
    assert!(
        errors[0].0.abs() > c.abs() && errors[0].1 > st,
        "{errors:?}"
    );
}
