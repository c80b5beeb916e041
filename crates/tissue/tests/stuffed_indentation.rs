//! `fem-static` indentation on meshes that `tissue` stuffs itself (issue 25: "indentation on
//! those meshes converges under refinement"). Two set-ups:
//! - the shipped scene `scenes/liver-fem-stuffed.toml` (the smooth liver surface meshed at
//!   `tet_size` when the scene is built, a 5 mm probe pressed 1 cm into its top, the surface
//!   below 8 mm held): successive sizes differ by 6–9 % without converging, because the held
//!   patch's rim moves by O(h) with the lattice (session 19's studies below);
//! - the same surface held by a rigid core the mesh follows (`Anchored`: a ball taken out,
//!   its wall fixed), where the force converges (`anchored_liver_indentation_converges_under_
//!   refinement`, docs/meshing.md).

use tissue::math::{Real, Vec3};
use tissue::mesh::stuffing::Domain;

fn root() -> String {
    format!("{}/../..", env!("CARGO_MANIFEST_DIR"))
}

/// `liver-fem-stuffed.toml` with `tet_size = h` (m), its paths made absolute.
fn stuffed_scene_text(h: Real) -> String {
    let root = root();
    std::fs::read_to_string(format!("{root}/scenes/liver-fem-stuffed.toml"))
        .unwrap()
        .replace("../assets", &format!("{root}/assets"))
        .replace("tet_size = 0.003 ", &format!("tet_size = {h} "))
}

/// `text` written to a file of its own (`tag`, h) and loaded.
fn load(text: &str, tag: &str, h: Real) -> tissue::scene::Scene {
    let dir = std::env::temp_dir().join(format!("tissue-{tag}-{}-{h}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    tissue::scene::Scene::load(&path).unwrap()
}

/// The scene's steps, asserting each contact loop converged and the first instrument is
/// never pulled in (it goes down, −y); the force after each step, in mN, as one line.
fn run_checked(sim: &mut tissue::sim::Simulation, scene: &tissue::scene::Scene, h: Real) -> String {
    let mut line = String::new();
    for _ in 0..scene.run.step_count() {
        let r = sim.step(scene.run.dt).unwrap();
        assert!(
            r.contact_converged,
            "h = {h}, t = {}: the contact loop capped",
            r.time
        );
        assert!(r.forces[0].y >= 0.0, "h = {h}, t = {}: pulls", r.time);
        line += &format!(
            " {:.2}:{:.4}[{}]",
            r.time,
            1e3 * r.forces[0].length(),
            r.contact_iterations
        );
    }
    line
}

/// Sizes from `SIZES` (comma-separated, m), or these.
fn sizes_or(default: &[Real]) -> Vec<Real> {
    std::env::var("SIZES").map_or(default.to_vec(), |s| {
        s.split(',').map(|x| x.parse().unwrap()).collect()
    })
}

/// A study's number from the environment, or `default`.
fn var_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name).map_or(default, |s| s.parse().ok().unwrap())
}

/// The probe force at the end of `liver-fem-stuffed.toml` with `tet_size = h` (m), and the
/// number of tetrahedra.
fn press(h: Real) -> (Vec3, usize) {
    let scene = load(&stuffed_scene_text(h), "stuffed-press", h);
    let mut sim = scene.build().unwrap();
    run_checked(&mut sim, &scene, h);
    let f = sim.instruments()[0].force();
    let tets = sim.model().info().elements;
    eprintln!(
        "tet_size {:.1} mm: {tets} tetrahedra, F = {f:.5} N, |F| = {:.5} N",
        h * 1e3,
        f.length()
    );
    (f, tets)
}

/// The successive relative differences |F(hᵢ₊₁) − F(hᵢ)| / |F(hᵢ₊₁)| and the angles
/// between successive forces, printed.
fn differences(sizes: &[Real]) -> Vec<Real> {
    let forces: Vec<Vec3> = sizes.iter().map(|&h| press(h).0).collect();
    forces
        .windows(2)
        .zip(sizes.windows(2))
        .map(|(f, h)| {
            let d = (f[1] - f[0]).length() / f[1].length();
            eprintln!(
                "{:.1} → {:.1} mm: difference {:.2} % of the force, directions {:.2}° apart",
                h[0] * 1e3,
                h[1] * 1e3,
                100.0 * d,
                f[0].angle_between(f[1]).to_degrees()
            );
            d
        })
        .collect()
}

/// Quick: the two coarsest sizes the mesher accepts for this surface agree within 8 %
/// (measured 6.1 %); the whole ladder is the ignored study below.
#[test]
fn stuffed_liver_indentation_agrees_between_two_sizes() {
    let d = differences(&[0.003, 0.0025]);
    assert!(d[0] < 0.08, "{d:?}");
}

/// The ladder 3, 2.5, 2 and 1.5 mm (19k to 147k tetrahedra, a few minutes of CPU), every
/// step's contact loop settled: successive sizes differ by 6.1, 9.4 and 6.5 % (measured), so
/// the force does **not** converge under refinement here. With the contact loop capped at 8
/// solves (before session 15) the same ladder read 6.1, 4.2 and 2.8 %, an artefact of steps
/// stopped before their contact settled. What the study asserts: every size within 10 % of
/// every other (a 5 mm probe on 1.5–3 mm vertices: the patch is a handful of vertices whose
/// places change with the lattice; docs/meshing.md).
#[test]
#[ignore = "four meshes up to 147k tetrahedra, a few minutes: cargo test --release -p tissue --test stuffed_indentation -- --ignored --nocapture"]
fn stuffed_liver_indentation_under_refinement() {
    let d = differences(&[0.003, 0.0025, 0.002, 0.0015]);
    assert!(d.iter().all(|&x| x < 0.10), "{d:?}");
}

/// Session 19's studies (docs/meshing.md, "Why it does not converge here"): the force at
/// several sizes with the contact, the elements and the support changed one at a time.
///
/// The scene's probe pressed `PRESS` m (default its 1 cm) in steps of `DT` s, its contact
/// loop capped at `ITER`, touching the stuffed mesh's own boundary cut flat into n² triangles
/// per face (n so that the fine edges are at most a quarter of the probe's radius), or with
/// `VISUAL = k` the input surface itself cut into k² per triangle.
#[test]
#[ignore = "study: cargo test --release -p tissue --test stuffed_indentation on_faces -- --ignored --nocapture"]
fn stuffed_liver_indentation_on_faces_study() {
    use tissue::interact::fine_surface::MappedSurface;
    let (dt, press, iterations): (Real, Real, usize) = (
        var_or("DT", 0.1),
        var_or("PRESS", 0.01),
        var_or("ITER", 400),
    );
    for h in sizes_or(&[0.003, 0.0025, 0.002]) {
        let text = stuffed_scene_text(h)
            .replace("dt = 0.1 ", &format!("dt = {dt} "))
            .replace(
                "position = [-0.005, 0.0455, 0.0067]",
                &format!("position = [-0.005, {}, 0.0067]", 0.0555 - press),
            )
            .replace(
                "max_iterations = 30",
                &format!("max_iterations = {iterations}"),
            );
        let scene = load(&text, "faces-press", h);
        let mut sim = scene.build().unwrap();
        let (rest, triangles) = (
            sim.model().rest_surface().to_vec(),
            sim.model().surface().triangles.to_vec(),
        );
        let mut edges: Vec<Real> = triangles
            .iter()
            .flat_map(|t| (0..3).map(move |i| (t[i], t[(i + 1) % 3])))
            .map(|(a, b)| rest[a as usize].distance(rest[b as usize]))
            .collect();
        edges.sort_by(Real::total_cmp);
        let n = (edges[edges.len() * 9 / 10] / (0.25 * 0.005)).ceil() as usize;
        let fine = match std::env::var("VISUAL") {
            Ok(k) => {
                let root = root();
                let mut input =
                    tissue::io::read(format!("{root}/assets/meshes/liver-smooth.obj")).unwrap();
                input.vertices.iter_mut().for_each(|v| *v *= 0.01);
                let cut = MappedSurface::subdivided(
                    &input.vertices,
                    &input.triangles,
                    k.parse().unwrap(),
                )
                .unwrap();
                MappedSurface::new(cut.rest, cut.triangles, &rest, &triangles).unwrap()
            }
            Err(_) => MappedSurface::subdivided(&rest, &triangles, n).unwrap(),
        };
        sim.set_fine_surface(fine).unwrap();
        let line = run_checked(&mut sim, &scene, h);
        let f = sim.instruments()[0].force();
        eprintln!(
            "tet_size {:.2} mm (boundary cut in {n}), {} tets: |F| = {:.5} N, F = {f:.5}\n  mN [solves] by t:{line}",
            h * 1e3,
            sim.model().info().elements,
            f.length()
        );
    }
}

/// The same liver pressed from above by a flat frictionless plate (`kind = "plane"`)
/// lowered `PRESS` m (default 4 mm) from the mesh's own highest point in `STEPS` steps,
/// `ORDER` linear or quadratic tetrahedra.
#[test]
#[ignore = "study: cargo test --release -p tissue --test stuffed_indentation plate_study -- --ignored --nocapture"]
fn stuffed_liver_plate_study() {
    let (press, steps): (Real, usize) = (var_or("PRESS", 0.004), var_or("STEPS", 4));
    let order: String = var_or("ORDER", "linear".to_string());
    for h in sizes_or(&[0.003, 0.0025, 0.002]) {
        let text = stuffed_scene_text(h).replace(
            "kind = \"fem-static\"",
            &format!("kind = \"fem-static\"\norder = \"{order}\""),
        );
        let top = load(&text, "plate-top", h)
            .build()
            .unwrap()
            .model()
            .rest_surface()
            .iter()
            .fold(Real::MIN, |a, p| a.max(p.y));
        let (head, tail) = text.split_once("[[instrument]]").unwrap();
        let (_, tail) = tail.split_once("[run]").unwrap();
        let text = format!(
            "{head}[[instrument]]\nkind = \"plane\"\nnormal = [0.0, -1.0, 0.0]\ncontact = \"sliding\"\n\
             path = [ {{ t = 0.0, position = [0.0, {top}, 0.0] }}, {{ t = 1.0, position = [0.0, {}, 0.0] }} ]\n\n[run]{}",
            top - press,
            tail.replace("dt = 0.1 ", &format!("dt = {} ", 1.0 / steps as Real))
        );
        let scene = load(&text, "plate-press", h);
        let mut sim = scene.build().unwrap();
        let line = run_checked(&mut sim, &scene, h);
        eprintln!(
            "plate, {order}, tet_size {:.2} mm, {} tets, top {:.4} mm below the input's: |F| = {:.6} N\n  mN [solves] by t:{line}",
            h * 1e3,
            sim.model().info().elements,
            (0.0517195 - top) * 1e3,
            sim.instruments()[0].force().length()
        );
    }
}

/// The held patch (the surface triangles whose corners `box y < 8 mm` holds) at each size.
#[test]
#[ignore = "study: cargo test --release -p tissue --test stuffed_indentation held_patch -- --ignored --nocapture"]
fn stuffed_liver_held_patch_study() {
    for h in sizes_or(&[0.003, 0.0025, 0.002, 0.0015]) {
        let sim = load(&stuffed_scene_text(h), "held", h).build().unwrap();
        let rest = sim.model().rest_surface();
        let held: std::collections::HashSet<u32> = sim.fixed().iter().copied().collect();
        let area: Real = sim
            .model()
            .surface()
            .triangles
            .iter()
            .filter(|t| t.iter().all(|v| held.contains(v)))
            .map(|t| {
                let [a, b, c] = t.map(|v| rest[v as usize]);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum();
        let top = held
            .iter()
            .map(|&v| rest[v as usize].y)
            .fold(Real::MIN, Real::max);
        eprintln!(
            "h {:.1} mm: {} held, held area {:.3} cm², highest held {:.3} mm",
            h * 1e3,
            held.len(),
            area * 1e4,
            top * 1e3
        );
    }
}

/// The liver's input surface cut flat at y = 8 mm (the domain: inside the surface and above
/// the plane), stuffed at each size, held on its flat underside (every vertex the cut put on
/// the plane), pressed from above by a plate lowered 4 mm from the mesh's top in 4 steps:
/// the held face is a mesh face at every size.
#[test]
#[ignore = "study: cargo test --release -p tissue --test stuffed_indentation cut_liver -- --ignored --nocapture"]
fn stuffed_cut_liver_plate_study() {
    use tissue::mesh::stuffing::{Implicit, SurfaceDomain, stuff};
    let root = root();
    let order: String = var_or("ORDER", "linear".to_string());
    let mut input = tissue::io::read(format!("{root}/assets/meshes/liver-smooth.obj")).unwrap();
    input.vertices.iter_mut().for_each(|v| *v *= 0.01);
    let surface = tissue::mesh::SurfaceMesh::new(input.vertices.clone(), input.triangles.clone());
    let liver = SurfaceDomain::new(&surface).unwrap();
    let floor = 0.008;
    let (lo, hi) = liver.bounds();
    let cut = Implicit {
        f: |p: Vec3| liver.value(p).max(floor - p.y),
        lo: Vec3::new(lo.x, floor - 1e-3, lo.z),
        hi,
        volume: None,
    };
    for h in sizes_or(&[0.003, 0.0025, 0.002]) {
        let stuffed = stuff(&cut, h, &tissue::model::Progress::silent()).unwrap();
        let mesh = stuffed.to_mesh_data();
        let top = mesh.vertices.iter().fold(Real::MIN, |a, p| a.max(p.y));
        let text = format!(
            "[mesh]\nfile = \"{root}/assets/meshes/liver-smooth.obj\"\n\n[material]\n\
             young_modulus = 3000.0\npoisson_ratio = 0.3\ndensity = 1000.0\n\n[model]\n\
             kind = \"fem-static\"\norder = \"{order}\"\n\n[[fixed]]\nname = \"floor\"\n\
             box = {{ min = [-1.0, -1.0, -1.0], max = [1.0, {}, 1.0] }}\n\n[[instrument]]\n\
             kind = \"plane\"\nnormal = [0.0, -1.0, 0.0]\ncontact = \"sliding\"\n\
             path = [ {{ t = 0.0, position = [0.0, {top}, 0.0] }}, {{ t = 1.0, position = [0.0, {}, 0.0] }} ]\n\n\
             [run]\nduration = 1.0\ndt = 0.25\n\n[contact]\nmax_iterations = 30\n",
            floor + 1e-9,
            top - 0.004,
        );
        let scene = load(&text, "cut-liver", h);
        let mut sim = scene.build_with_mesh(mesh, "the cut liver").unwrap();
        let line = run_checked(&mut sim, &scene, h);
        eprintln!(
            "cut liver, {order}, tet_size {:.2} mm: {} tets, {} held, min dihedral {:.1}°: \
             |F| = {:.6} N\n  mN [solves] by t:{line}",
            h * 1e3,
            sim.model().info().elements,
            sim.fixed().len(),
            stuffed.report.min_dihedral_deg,
            sim.instruments()[0].force().length()
        );
    }
}

/// A closed surface held by a rigid core: the inside of `outer` with a ball of radius `core`
/// about `centre` taken out, the cavity's wall fixed. The stuffing puts its vertices on the
/// cavity's sphere (chords O(h²) off it), so the held region is the same at every size, where
/// the shipped scene's support (a box through the underside) has a rim that moves by O(h),
/// which session 19 found to dominate the force's change under refinement.
struct Anchored<'a> {
    outer: &'a dyn Domain,
    core: Real,
    centre: Vec3,
}

impl tissue::mesh::stuffing::Domain for Anchored<'_> {
    fn value(&self, p: Vec3) -> Real {
        if self.outer.value(p) > 0.0 {
            1.0
        } else {
            self.core - p.distance(self.centre)
        }
    }
    fn cut(&self, inside: Vec3, outside: Vec3) -> Vec3 {
        if self.outer.value(outside) > 0.0 {
            return self.outer.cut(inside, outside);
        }
        // The segment enters the ball: the root of |inside + t d − c| = core in [0, 1].
        let (d, m) = (outside - inside, inside - self.centre);
        let (a, b, c) = (d.dot(d), 2.0 * d.dot(m), m.dot(m) - self.core * self.core);
        let t = (-b - (b * b - 4.0 * a * c).max(0.0).sqrt()) / (2.0 * a);
        inside + t.clamp(0.0, 1.0) * d
    }
    fn bounds(&self) -> (Vec3, Vec3) {
        self.outer.bounds()
    }
    fn boundary_distance(&self, p: Vec3, step: Real) -> Real {
        self.outer
            .boundary_distance(p, step)
            .min((p.distance(self.centre) - self.core).abs())
    }
    fn boundary_samples(&self, spacing: Real) -> Vec<Vec3> {
        let mut out = self.outer.boundary_samples(spacing);
        // The sphere on a latitude-longitude net about `spacing` apart.
        let rings = (std::f64::consts::PI * self.core / spacing).ceil() as usize;
        for i in 0..=rings {
            let theta = std::f64::consts::PI * i as Real / rings as Real;
            let around = ((2.0 * rings as Real * theta.sin()).ceil() as usize).max(1);
            for j in 0..around {
                let phi = 2.0 * std::f64::consts::PI * j as Real / around as Real;
                out.push(
                    self.centre
                        + self.core
                            * Vec3::new(
                                theta.sin() * phi.cos(),
                                theta.cos(),
                                theta.sin() * phi.sin(),
                            ),
                );
            }
        }
        out
    }
    fn reference_volume(&self) -> Option<Real> {
        self.outer
            .reference_volume()
            .map(|v| v - 4.0 / 3.0 * std::f64::consts::PI * self.core.powi(3))
    }
}

impl Anchored<'_> {
    /// Stuffed at `h`, every guarantee of the mesher kept (asserted).
    fn stuffed(&self, h: Real) -> tissue::mesh::stuffing::Stuffed {
        let stuffed =
            tissue::mesh::stuffing::stuff(self, h, &tissue::model::Progress::silent()).unwrap();
        let bad = stuffed.report.violations();
        assert!(bad.is_empty(), "h = {h}: {bad:?}");
        stuffed
    }

    /// The fixed region: every boundary vertex within a tenth of a millimetre of the core.
    fn fixed(&self) -> String {
        let c = self.centre;
        format!(
            "[[fixed]]\nname = \"core\"\nsphere = {{ center = [{}, {}, {}], radius = {} }}\n",
            c.x,
            c.y,
            c.z,
            self.core + 1e-4
        )
    }
}

/// Builds a fine contact surface from a model's rest surface (vertices, triangles).
type FineSurface<'a> =
    dyn Fn(&[Vec3], &[[u32; 3]]) -> tissue::interact::fine_surface::MappedSurface + 'a;

/// The probe force (N) pressing `press` m into `mesh` at (x, z), in `steps` static steps, its
/// contact on `fine` (built from the model's own rest surface; its rest points
/// `contact_rest` place the probe's start), with the fixed region `fixed`. Prints the force
/// after every step.
#[allow(clippy::too_many_arguments)]
fn anchored_press(
    mesh: tissue::mesh::MeshData,
    fixed: &str,
    (x, z): (Real, Real),
    press: Real,
    steps: usize,
    label: &str,
    h: Real,
    contact_rest: &[Vec3],
    fine: Option<&FineSurface<'_>>,
) -> Vec3 {
    // A 5 mm probe, or (no fine surface) a flat plate, which touches the vertices exactly.
    let radius: Real = if fine.is_some() { 0.005 } else { 0.0 };
    // It starts touching the contact surface's highest point near its centre line (the
    // input's, the same at every size).
    let top = contact_rest
        .iter()
        .filter(|p| (p.x - x).hypot(p.z - z) < 0.5 * radius.max(1e-3))
        .fold(Real::MIN, |a, p| a.max(p.y));
    let instrument = if fine.is_some() {
        format!("kind = \"probe\"\nradius = {radius}")
    } else {
        "kind = \"plane\"\nnormal = [0.0, -1.0, 0.0]\ncontact = \"sliding\"".to_string()
    };
    let root = root();
    let order: String = var_or("ORDER", "linear".to_string());
    let text = format!(
        "[mesh]\nfile = \"{root}/assets/meshes/liver-smooth.obj\"\n\n[material]\n\
         young_modulus = 3000.0\npoisson_ratio = 0.3\ndensity = 1000.0\n\n[model]\n\
         kind = \"fem-static\"\norder = \"{order}\"\n\n{fixed}\n[[instrument]]\n{instrument}\n\
         path = [ {{ t = 0.0, position = [{x}, {}, {z}] }}, {{ t = 1.0, position = [{x}, {}, {z}] }} ]\n\n\
         [run]\nduration = 1.0\ndt = {}\n\n[contact]\nmax_iterations = 400\n",
        top + radius,
        top + radius - press,
        1.0 / steps as Real,
    );
    let scene = load(&text, label, h);
    let mut sim = scene.build_with_mesh(mesh, label).unwrap();
    let (rest, triangles) = (
        sim.model().rest_surface().to_vec(),
        sim.model().surface().triangles.to_vec(),
    );
    if let Some(fine) = fine {
        sim.set_fine_surface(fine(&rest, &triangles)).unwrap();
    }
    let held = sim.fixed().len();
    let line = run_checked(&mut sim, &scene, h);
    let f = sim.instruments()[0].force();
    eprintln!(
        "{label}, {order}, tet_size {:.2} mm: {} tets, {held} held: |F| = {:.6} N, F = {f:.6}\n  mN [solves] by t:{line}",
        h * 1e3,
        sim.model().info().elements,
        f.length()
    );
    f
}

/// Successive sizes' forces: their relative differences, and the order p and limit that
/// three successive sizes give (Richardson: F(h) = F∞ + C hᵖ).
fn ladder_report(sizes: &[Real], forces: &[Real]) -> Vec<Real> {
    let d: Vec<Real> = forces
        .windows(2)
        .map(|f| (f[1] - f[0]).abs() / f[1])
        .collect();
    for (i, w) in forces.windows(3).enumerate() {
        let (h0, h1, h2) = (sizes[i], sizes[i + 1], sizes[i + 2]);
        // Solve (F0 − F1)/(F1 − F2) = (h0ᵖ − h1ᵖ)/(h1ᵖ − h2ᵖ) for p by bisection.
        let ratio = (w[0] - w[1]) / (w[1] - w[2]);
        let g = |p: Real| (h0.powf(p) - h1.powf(p)) / (h1.powf(p) - h2.powf(p)) - ratio;
        let (mut a, mut b) = (0.05, 6.0);
        if g(a) * g(b) < 0.0 {
            for _ in 0..60 {
                let m = 0.5 * (a + b);
                if g(a) * g(m) <= 0.0 { b = m } else { a = m }
            }
            let p = 0.5 * (a + b);
            let c = (w[1] - w[2]) / (h1.powf(p) - h2.powf(p));
            eprintln!(
                "sizes {:.1}/{:.1}/{:.1} mm: order {p:.2}, limit {:.6} N ({:+.2} % from the finest)",
                h0 * 1e3,
                h1 * 1e3,
                h2 * 1e3,
                w[2] - c * h2.powf(p),
                100.0 * (w[2] - c * h2.powf(p) - w[2]) / w[2]
            );
        } else {
            eprintln!(
                "sizes {:.1}/{:.1}/{:.1} mm: no order fits",
                h0 * 1e3,
                h1 * 1e3,
                h2 * 1e3
            );
        }
    }
    for (s, x) in sizes.windows(2).zip(&d) {
        eprintln!(
            "{:.1} → {:.1} mm: {:.2} %",
            s[0] * 1e3,
            s[1] * 1e3,
            100.0 * x
        );
    }
    d
}

/// The shipped liver surface held by a rigid core (a 4 mm ball at its thickest, the
/// cavity's wall fixed), a 5 mm probe pressed `PRESS` m (default 2 mm) into the top above
/// it, on the input surface cut in 16 per triangle. Sizes from `SIZES`.
fn anchored_liver_forces(sizes: &[Real]) -> Vec<Real> {
    use tissue::interact::fine_surface::MappedSurface;
    use tissue::mesh::stuffing::SurfaceDomain;
    let root = root();
    let mut input = tissue::io::read(format!("{root}/assets/meshes/liver-smooth.obj")).unwrap();
    input.vertices.iter_mut().for_each(|v| *v *= 0.01);
    let surface = tissue::mesh::SurfaceMesh::new(input.vertices.clone(), input.triangles.clone());
    let liver = SurfaceDomain::new(&surface).unwrap();
    let anchor = Anchored {
        outer: &liver,
        core: 0.004,
        centre: Vec3::new(-0.026, 0.0392, 0.004),
    };
    let wall = liver.boundary_distance(anchor.centre, 1e-6) - anchor.core;
    eprintln!(
        "the core's wall is {:.2} mm from the liver's surface",
        wall * 1e3
    );
    assert!(wall > 0.005, "the core must lie well inside");
    let press: Real = var_or("PRESS", 0.002);
    let cut = MappedSurface::subdivided(&input.vertices, &input.triangles, 4).unwrap();
    sizes
        .iter()
        .map(|&h| {
            let stuffed = anchor.stuffed(h);
            anchored_press(
                stuffed.to_mesh_data(),
                &anchor.fixed(),
                (-0.026, 0.004),
                press,
                var_or("STEPS", 6),
                "anchored liver",
                h,
                &cut.rest,
                Some(&|rest, triangles| {
                    MappedSurface::new(cut.rest.clone(), cut.triangles.clone(), rest, triangles)
                        .unwrap()
                }),
            )
            .length()
        })
        .collect()
}

/// Issue 25's "indentation converges under refinement", on a support the mesh keeps at every
/// size: the anchored liver (`anchored_liver_forces`, a 2 mm press) at 3, 2.5 and 2 mm. The
/// force falls at each refinement and by less each time (measured 25.857, 23.870, 22.183 mN:
/// steps of 1.987 and 1.687 mN for equal steps in h, so the error falls faster than h). The
/// ignored ladder goes on to 1.5 and 1.25 mm (21.059, 20.662 mN: steps 1.124 and 0.397 mN).
#[test]
fn anchored_liver_indentation_converges_under_refinement() {
    let sizes = [0.003, 0.0025, 0.002];
    let f = anchored_liver_forces(&sizes);
    ladder_report(&sizes, &f);
    assert!(f[0] > f[1] && f[1] > f[2], "not monotone: {f:?}");
    assert!(
        f[1] - f[2] < 0.95 * (f[0] - f[1]),
        "the steps do not shrink: {f:?}"
    );
}

/// The study: the anchored liver at 3, 2.5, 2 and 1.5 mm (or `SIZES`).
#[test]
#[ignore = "study: cargo test --release -p tissue --test stuffed_indentation anchored_liver_ladder -- --ignored --nocapture"]
fn anchored_liver_ladder() {
    let sizes = sizes_or(&[0.003, 0.0025, 0.002, 0.0015]);
    let forces = anchored_liver_forces(&sizes);
    ladder_report(&sizes, &forces);
}

/// A sphere of radius 2 cm on a rigid core of 1 cm (the same centre), a 5 mm probe pressed
/// `PRESS` m (default 1 mm) into its top in `STEPS` steps, on the stuffed mesh's own boundary
/// cut flat in n² per face (fine edges at most a sixteenth of the probe's radius); with
/// `PLATE=1` a flat plate instead. Printed beside Hertz's force, F = 4/3 · E/(1 − ν²) · √R* ·
/// δ^{3/2} with 1/R* = 1/R + 1/r (R* = R for the plate): the contact's radius √(R*δ) is
/// small against the 1 cm shell, which still stiffens it somewhat.
fn anchored_sphere_forces(sizes: &[Real]) -> Vec<Real> {
    use tissue::interact::fine_surface::MappedSurface;
    use tissue::mesh::stuffing::Implicit;
    let (big, core, probe) = (0.02, 0.01, 0.005);
    let sphere = Implicit {
        f: |p: Vec3| p.length() - big,
        lo: Vec3::splat(-big - 1e-3),
        hi: Vec3::splat(big + 1e-3),
        volume: Some(4.0 / 3.0 * std::f64::consts::PI * big.powi(3)),
    };
    let anchor = Anchored {
        outer: &sphere,
        core,
        centre: Vec3::ZERO,
    };
    let press: Real = var_or("PRESS", 0.001);
    let plate = var_or("PLATE", 0) == 1;
    let (e, nu) = (3000.0, 0.3);
    let r_star = if plate {
        big
    } else {
        1.0 / (1.0 / big + 1.0 / probe)
    };
    let hertz = 4.0 / 3.0 * e / (1.0 - nu * nu) * r_star.sqrt() * press.powf(1.5);
    eprintln!("Hertz: {:.6} N at {:.2} mm", hertz, press * 1e3);
    sizes
        .iter()
        .map(|&h| {
            let stuffed = anchor.stuffed(h);
            let mesh = stuffed.to_mesh_data();
            // The top's rest points: the input sphere's pole (the cut faces' points lie on
            // chords, below it by O(h²)).
            let pole = [Vec3::new(0.0, big, 0.0)];
            let n = (h / (probe / 16.0)).ceil() as usize;
            let f = anchored_press(
                mesh,
                &anchor.fixed(),
                (0.0, 0.0),
                press,
                var_or("STEPS", 4),
                "anchored sphere",
                h,
                &pole,
                (!plate).then_some(&|rest: &[Vec3], triangles: &[[u32; 3]]| {
                    MappedSurface::subdivided(rest, triangles, n).unwrap()
                }),
            )
            .length();
            eprintln!("  against Hertz: {:+.2} %", 100.0 * (f / hertz - 1.0));
            f
        })
        .collect()
}

/// The study: the anchored sphere at 3, 2.5, 2 and 1.5 mm (or `SIZES`).
#[test]
#[ignore = "study: cargo test --release -p tissue --test stuffed_indentation anchored_sphere_ladder -- --ignored --nocapture"]
fn anchored_sphere_ladder() {
    let sizes = sizes_or(&[0.003, 0.0025, 0.002, 0.0015]);
    let forces = anchored_sphere_forces(&sizes);
    ladder_report(&sizes, &forces);
}
