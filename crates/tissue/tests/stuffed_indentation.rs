//! `fem-static` indentation on meshes that `tissue` stuffs itself (issue 25: "indentation on
//! those meshes converges under refinement"): the shipped smooth liver surface meshed at
//! several `tet_size`s when the scene is built (`scenes/liver-fem-stuffed.toml`), a 5 mm
//! frictionless probe pressed 1 cm into its top, the bottom held. The force at full depth is
//! compared between sizes: the differences between successive sizes shrink.

use tissue::math::{Real, Vec3};

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
    use tissue::mesh::stuffing::{Domain, Implicit, SurfaceDomain, stuff};
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
