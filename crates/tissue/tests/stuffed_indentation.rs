//! `fem-static` indentation on meshes that `tissue` stuffs itself (issue 25: "indentation on
//! those meshes converges under refinement"): the shipped smooth liver surface meshed at
//! several `tet_size`s when the scene is built (`scenes/liver-fem-stuffed.toml`), a 5 mm
//! frictionless probe pressed 1 cm into its top, the bottom held. The force at full depth is
//! compared between sizes: the differences between successive sizes shrink.

use tissue::math::{Real, Vec3};

/// The probe force at the end of `liver-fem-stuffed.toml` with `tet_size = h` (m), and the
/// number of tetrahedra.
fn press(h: Real) -> (Vec3, usize) {
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(format!("{root}/scenes/liver-fem-stuffed.toml"))
        .unwrap()
        .replace("../assets", &format!("{root}/assets"))
        .replace("tet_size = 0.003 ", &format!("tet_size = {h} "));
    let dir = std::env::temp_dir().join(format!("tissue-stuffed-press-{}-{h}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("press.toml");
    std::fs::write(&path, text).unwrap();
    let scene = tissue::scene::Scene::load(&path).unwrap();
    let mut sim = scene.build().unwrap();
    let mut pulls = 0;
    for _ in 0..scene.run.step_count() {
        let r = sim.step(scene.run.dt).unwrap();
        // The probe goes down (−y): the liver pushes it up, never pulls it in.
        pulls += usize::from(r.forces[0].y < 0.0);
        // Every step's contact loop settled (the scene's cap is set for it).
        assert!(
            r.contact_converged,
            "h = {h}, t = {}: the contact loop capped",
            r.time
        );
    }
    assert_eq!(pulls, 0, "h = {h}");
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

/// The press of `press`, the probe touching the stuffed mesh's own boundary cut flat into
/// n² triangles per face (`MappedSurface::subdivided`, n chosen so the fine edges are at most
/// a quarter of the probe's radius), printed step by step.
fn press_on_faces(h: Real, dt: Real) -> Vec3 {
    use tissue::interact::fine_surface::MappedSurface;
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(format!("{root}/scenes/liver-fem-stuffed.toml"))
        .unwrap()
        .replace("../assets", &format!("{root}/assets"))
        .replace("tet_size = 0.003 ", &format!("tet_size = {h} "))
        .replace("dt = 0.1 ", &format!("dt = {dt} "))
        .replace(
            "position = [-0.005, 0.0455, 0.0067]",
            &format!(
                "position = [-0.005, {}, 0.0067]",
                0.0555 - std::env::var("PRESS").map_or(0.01, |s| s.parse::<Real>().unwrap())
            ),
        )
        .replace(
            "max_iterations = 30",
            &format!(
                "max_iterations = {}",
                std::env::var("ITER").unwrap_or("30".into())
            ),
        );
    let dir = std::env::temp_dir().join(format!("tissue-faces-press-{}-{h}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("press.toml");
    std::fs::write(&path, text).unwrap();
    let scene = tissue::scene::Scene::load(&path).unwrap();
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
    let edge = edges[edges.len() * 9 / 10];
    let n = (edge / (0.25 * 0.005)).ceil() as usize;
    let fine = match std::env::var("VISUAL") {
        // The input surface itself, cut flat into n² per triangle, tied to the mesh.
        Ok(v) => {
            let mut input =
                tissue::io::read(format!("{root}/assets/meshes/liver-smooth.obj")).unwrap();
            input.vertices.iter_mut().for_each(|v| *v *= 0.01);
            let cut =
                MappedSurface::subdivided(&input.vertices, &input.triangles, v.parse().unwrap())
                    .unwrap();
            MappedSurface::new(cut.rest, cut.triangles, &rest, &triangles).unwrap()
        }
        Err(_) => MappedSurface::subdivided(&rest, &triangles, n).unwrap(),
    };
    sim.set_fine_surface(fine).unwrap();
    let mut line = String::new();
    for _ in 0..scene.run.step_count() {
        let r = sim.step(scene.run.dt).unwrap();
        let capped = if r.contact_converged { "" } else { "(capped)" };
        line += &format!(
            " {:.3}:{:.3}{capped}[{} it, {} held]",
            r.time,
            1e3 * r.forces[0].length(),
            r.contact_iterations,
            r.contacts[0]
        );
    }
    let f = sim.instruments()[0].force();
    eprintln!(
        "tet_size {:.2} mm, n = {n} (edge p90 {:.2} mm), {} tets: |F| = {:.5} N, F = {f:.5}\n  mN by t:{line}",
        h * 1e3,
        edge * 1e3,
        sim.model().info().elements,
        f.length()
    );
    f
}

#[test]
#[ignore = "study: cargo test --release -p tissue --test stuffed_indentation faces -- --ignored --nocapture"]
fn stuffed_liver_indentation_on_faces_study() {
    let sizes: Vec<Real> = std::env::var("SIZES")
        .map(|s| s.split(',').map(|x| x.parse().unwrap()).collect())
        .unwrap_or(vec![0.003, 0.0025, 0.002]);
    let dt: Real = std::env::var("DT")
        .map(|s| s.parse().unwrap())
        .unwrap_or(0.1);
    for h in sizes {
        press_on_faces(h, dt);
    }
}

/// The liver of `liver-fem-stuffed.toml` at `tet_size = h` pressed from above by a flat
/// frictionless plate (`kind = "plane"`) lowered `depth` m below its highest point in
/// `steps` steps: the force at full depth, printed step by step.
fn press_plate(h: Real, depth: Real, steps: usize) -> Vec3 {
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(format!("{root}/scenes/liver-fem-stuffed.toml"))
        .unwrap()
        .replace("../assets", &format!("{root}/assets"))
        .replace("tet_size = 0.003 ", &format!("tet_size = {h} "))
        .replace(
            "kind = \"fem-static\"",
            &format!(
                "kind = \"fem-static\"\norder = \"{}\"",
                std::env::var("ORDER").unwrap_or("linear".into())
            ),
        );
    let (head, tail) = text.split_once("[[instrument]]").unwrap();
    let (_, tail) = tail.split_once("[run]").unwrap();
    // The plate starts where it first touches: the highest point of this mesh (FROM_MESH),
    // or of the input surface.
    let top = if std::env::var_os("FROM_MESH").is_some() {
        let scene = {
            let path = std::env::temp_dir()
                .join(format!("tissue-plate-top-{}-{h}.toml", std::process::id()));
            std::fs::write(&path, &text).unwrap();
            tissue::scene::Scene::load(&path).unwrap()
        };
        let sim = scene.build().unwrap();
        let top = sim
            .model()
            .rest_surface()
            .iter()
            .fold(Real::MIN, |a, p| a.max(p.y));
        eprintln!(
            "mesh top {:.4} mm below the input's",
            (0.0517195 - top) * 1e3
        );
        top
    } else {
        0.0517195
    };
    let text = format!(
        "{head}[[instrument]]\nkind = \"plane\"\nnormal = [0.0, -1.0, 0.0]\ncontact = \"sliding\"\n\
         path = [ {{ t = 0.0, position = [0.0, {top}, 0.0] }}, {{ t = 1.0, position = [0.0, {}, 0.0] }} ]\n\n[run]{}",
        top - depth,
        tail.replace("dt = 0.1 ", &format!("dt = {} ", 1.0 / steps as Real))
    );
    let dir = std::env::temp_dir().join(format!("tissue-plate-press-{}-{h}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("press.toml");
    std::fs::write(&path, text).unwrap();
    let scene = tissue::scene::Scene::load(&path).unwrap();
    let mut sim = scene.build().unwrap();
    let mut line = String::new();
    for _ in 0..scene.run.step_count() {
        let r = sim.step(scene.run.dt).unwrap();
        let capped = if r.contact_converged { "" } else { "(capped)" };
        line += &format!(
            " {:.2}:{:.3}{capped}[{} it, {} held]",
            r.time,
            1e3 * r.forces[0].length(),
            r.contact_iterations,
            r.contacts[0]
        );
    }
    let f = sim.instruments()[0].force();
    eprintln!(
        "plate, tet_size {:.2} mm, {} tets: |F| = {:.6} N, F = {f:.6}\n  mN by t:{line}",
        h * 1e3,
        sim.model().info().elements,
        f.length()
    );
    f
}

#[test]
#[ignore = "study: cargo test --release -p tissue --test stuffed_indentation plate -- --ignored --nocapture"]
fn stuffed_liver_plate_study() {
    let sizes: Vec<Real> = std::env::var("SIZES")
        .map(|s| s.split(',').map(|x| x.parse().unwrap()).collect())
        .unwrap_or(vec![0.003, 0.0025, 0.002]);
    let depth: Real = std::env::var("PRESS").map_or(0.004, |s| s.parse().unwrap());
    let steps: usize = std::env::var("STEPS").map_or(4, |s| s.parse().unwrap());
    for h in sizes {
        press_plate(h, depth, steps);
    }
}

#[test]
#[ignore = "study: the held patch of the stuffed liver at several sizes"]
fn stuffed_liver_held_patch_study() {
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    for h in [0.003, 0.0025, 0.002, 0.0015] {
        let text = std::fs::read_to_string(format!("{root}/scenes/liver-fem-stuffed.toml"))
            .unwrap()
            .replace("../assets", &format!("{root}/assets"))
            .replace("tet_size = 0.003 ", &format!("tet_size = {h} "));
        let path =
            std::env::temp_dir().join(format!("tissue-held-{}-{h}.toml", std::process::id()));
        std::fs::write(&path, text).unwrap();
        let sim = tissue::scene::Scene::load(&path).unwrap().build().unwrap();
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
