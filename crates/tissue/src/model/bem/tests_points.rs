//! Fine-surface points pushed by a plane (`Deformable::set_point_contacts`) on the BEM:
//! complementary on the surface the model reports, and a point on a vertex is that vertex
//! held along the plane's normal (`set_constraints_along`).

use super::tests::{material, sphere, top};
use super::*;
use crate::interact::{Constraints, Loads, PointContact, Prescribed};
use crate::math::{Real, Vec3};
use crate::model::Deformable;

fn gravity() -> Loads {
    Loads {
        gravity: Vec3::new(0.0, 0.0, -9.81),
        point_loads: Vec::new(),
    }
}

/// The sphere's vertices below z = −0.03 m (the support).
fn support(rest: &[Vec3]) -> Vec<u32> {
    (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].z < -0.03)
        .collect()
}

/// Steps with the support, gravity, `held` and `points`: the pushes and the surface.
fn press(model: &mut Bem, held: &[Prescribed], points: &[PointContact]) -> (Vec<Real>, Vec<Vec3>) {
    let rest = model.rest_surface().to_vec();
    model.set_loads(&gravity()).unwrap();
    let c = Constraints {
        fixed: support(&rest),
        prescribed: held.to_vec(),
    };
    model.set_constraints(&c).unwrap();
    assert!(model.holds_point_contacts());
    assert!(model.set_point_contacts(points).unwrap());
    model.step(0.01).unwrap();
    (
        model.point_reactions().to_vec(),
        model.surface().positions.to_vec(),
    )
}

/// Sixty points at seeded barycentric places on the cap's triangles (several per triangle:
/// more points than directions), pressed by a tilted plane: none pulled, none through its
/// plane, every pushed one on it, on the surface the model reports; with the contacts'
/// tractions continuous and discontinuous at their rim (a held patch beside the points).
#[test]
fn points_pressed_by_a_plane_are_complementary() {
    for params in [BemParams::continuous(), BemParams::default()] {
        let mut model = Bem::new(&sphere(2), material(), params).unwrap();
        let rest = model.rest_surface().to_vec();
        let cap: Vec<[u32; 3]> = model
            .surface()
            .triangles
            .iter()
            .copied()
            .filter(|t| t.iter().all(|&v| rest[v as usize].z > 0.035))
            .collect();
        // The plane 5 mm below the top as gravity alone leaves it (it sags ~1 cm).
        let sag = press(&mut model, &[], &[]).1;
        let top_z = sag.iter().map(|x| x.z).fold(Real::MIN, Real::max);
        let normal = Vec3::new(0.1, 0.05, -1.0).normalize();
        let target = Vec3::new(0.0, 0.0, top_z - 5e-3);
        let mut state = 17u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as Real / (1u64 << 53) as Real
        };
        let points: Vec<PointContact> = (0..60)
            .map(|_| {
                let t = cap[(next() * cap.len() as Real) as usize % cap.len()];
                let (a, b) = (next(), next());
                let (a, b) = if a + b > 1.0 {
                    (1.0 - a, 1.0 - b)
                } else {
                    (a, b)
                };
                let weights = [1.0 - a - b, a, b];
                PointContact {
                    vertices: t,
                    weights,
                    rest: (0..3).map(|i| rest[t[i] as usize] * weights[i]).sum(),
                    normal,
                    target,
                }
            })
            .collect();
        // A patch of side vertices held in full, pushed inward (with discontinuous
        // contacts, its inner triangles carry the rim-corrected tractions W̃).
        let mut side: Vec<u32> = (0..rest.len() as u32).collect();
        side.sort_by(|&a, &b| rest[b as usize].x.total_cmp(&rest[a as usize].x));
        let held: Vec<Prescribed> = side[..6]
            .iter()
            .map(|&v| Prescribed {
                vertex: v,
                position: rest[v as usize] * 0.99,
            })
            .collect();
        let (l, x) = press(&mut model, &held, &points);
        let scale = x
            .iter()
            .zip(&rest)
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, Real::max);
        let (mut below, mut off_pushed): (Real, Real) = (0.0, 0.0);
        for (p, &l) in points.iter().zip(&l) {
            assert!(l >= 0.0, "a point pulls: {l}");
            let moved: Vec3 = (0..3)
                .map(|i| (x[p.vertices[i] as usize] - rest[p.vertices[i] as usize]) * p.weights[i])
                .sum();
            let g = p.normal.dot(p.rest + moved - p.target);
            below = below.max(-g);
            if l > 0.0 {
                off_pushed = off_pushed.max(g.abs());
            }
        }
        let pushed = l.iter().filter(|&&l| l > 0.0).count();
        // The supports take the pushes, the held vertex's force and the weight, to the
        // BIE's discretisation error (it does not impose global equilibrium exactly).
        let r = model.reactions();
        let pushes: Vec3 = points.iter().zip(&l).map(|(p, &l)| p.normal * l).sum();
        let total: Vec3 = r.fixed.iter().chain(r.prescribed).copied().sum();
        let volume = 4.0 / 3.0 * std::f64::consts::PI * 0.05f64.powi(3);
        let weight = gravity().gravity * material().density * volume;
        let imbalance = (total - pushes - weight).length() / (pushes.length() + weight.length());
        eprintln!(
            "bem {}: 60 points, {pushed} pushed, Σλ {:.4e} N; below a plane {below:.1e} m, \
             a pushed point off it {off_pushed:.1e} m (largest displacement {scale:.1e} m); \
             imbalance {imbalance:.1e}",
            if params.discontinuous_contacts {
                "discontinuous"
            } else {
                "continuous"
            },
            l.iter().sum::<Real>()
        );
        assert!(pushed > 5 && pushed < 55, "{pushed}");
        assert!(below < 1e-8 * scale && off_pushed < 1e-8 * scale);
        assert!(imbalance < 0.05, "{imbalance}");
    }
}

/// A point on a vertex (weights 1, 0, 0) is that vertex held along the plane's normal at
/// the plane: same push, same surface, beside another vertex held in full; with the
/// contacts' tractions continuous and discontinuous at their rim (a lone contact vertex has
/// no triangle inside the contact set, so its traction acts over its hat either way, as a
/// point's push does).
#[test]
fn a_point_on_a_vertex_is_the_vertex_held_along_the_normal() {
    for params in [BemParams::continuous(), BemParams::default()] {
        let mut model = Bem::new(&sphere(2), material(), params).unwrap();
        let rest = model.rest_surface().to_vec();
        let cap = top(&rest);
        let (v, other) = (cap[0], cap[4]);
        let normal = Vec3::new(0.2, 0.1, -1.0).normalize();
        // 1 mm below where gravity alone leaves the vertex (it sags ~1 cm).
        let sag = press(&mut model, &[], &[]).1;
        let target = sag[v as usize] + Vec3::new(0.0, 0.0, -1e-3);
        let full = Prescribed {
            vertex: other,
            position: rest[other as usize] * 0.995,
        };
        let point = PointContact {
            vertices: [v, other, cap[1]],
            weights: [1.0, 0.0, 0.0],
            rest: rest[v as usize],
            normal,
            target,
        };
        let (l, x) = press(&mut model, &[full], &[point]);
        let r_full = model.reactions().prescribed[0];
        let c = Constraints {
            fixed: support(&rest),
            prescribed: vec![
                full,
                Prescribed {
                    vertex: v,
                    position: target,
                },
            ],
        };
        assert!(
            model
                .set_constraints_along(&c, &[None, Some(normal)])
                .unwrap()
        );
        assert!(model.point_reactions().is_empty());
        model.step(0.01).unwrap();
        let along = model.reactions().prescribed.to_vec();
        let gap = |a: &[Vec3], b: &[Vec3]| {
            a.iter()
                .zip(b)
                .map(|(a, b)| (*a - *b).length())
                .fold(0.0, Real::max)
        };
        let d_push = (along[1] + normal * l[0]).length() / along[1].length();
        let d_full = (along[0] - r_full).length() / r_full.length();
        let d_x = gap(&x, model.surface().positions) / gap(&x, &rest);
        eprintln!(
            "bem {}: point on a vertex vs held along n: push {d_push:.1e}, other contact \
             {d_full:.1e}, surface {d_x:.1e} (relative; λ {:.4e} N)",
            if params.discontinuous_contacts {
                "discontinuous"
            } else {
                "continuous"
            },
            l[0]
        );
        assert!(l[0] > 0.0);
        // To roundoff: the rows are solved with M itself, unregularised (7e-16 measured).
        assert!(d_push < 1e-12 && d_full < 1e-12 && d_x < 1e-12);
        // A bad point is an error, not a panic.
        let bad = PointContact {
            vertices: [rest.len() as u32, v, v],
            ..point
        };
        assert!(model.set_point_contacts(&[bad]).is_err());
    }
}

/// The cost of point contacts on a 642-vertex sphere against today's vertex path
/// (`model::testing::point_contact_study`).
#[test]
#[ignore = "study, seconds: cargo test --release -p tissue --lib bem_point_contact_study -- --ignored --nocapture"]
fn bem_point_contact_study() {
    let mut model = Bem::new(&sphere(3), material(), BemParams::default()).unwrap();
    let rest = model.rest_surface().to_vec();
    for bulge in [0.0, 0.005] {
        let fixed = support(&rest);
        crate::model::testing::point_contact_study(&mut model, &fixed, &[25, 100, 400], bulge);
    }
}

/// The exact fine points' cost on the built-in liver (the comparison's organ and probe,
/// `compare --quick`'s settings): for k = 1 to `FINE_LEVELS` (default 3) subdivisions,
/// the probe pressed to the deep indentation through the fine surface, timed, and its
/// largest contact problem solved again cold by the splitting (`PointRows::split`) and by
/// the pivoting it replaced: rows, rounds, ms, the gaps' agreement and the splitting's
/// contraction ρ (`solve::points::contraction`). `cargo test --release -p tissue --lib
/// exact_points_cost_study -- --ignored --nocapture`.
#[test]
#[ignore = "study, a minute: prints the exact fine points' cost by both solvers"]
fn exact_points_cost_study() {
    use std::time::Instant;

    use crate::compare::Settings;
    use crate::compare::drive::{ContactLaw, Stepping, indent_sim};
    use crate::compare::measure::settling;
    use crate::compare::setup::{Organ, Scenario};
    use crate::interact::MappedSurface;
    use crate::material::Material;
    use crate::sim::Simulation;
    use crate::solve::points::{PointRows, capture, contraction};

    let mut mesh = crate::io::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/meshes/liver.msh"
    ))
    .unwrap();
    for v in &mut mesh.vertices {
        *v *= 0.01;
    }
    let s = Settings::quick();
    let material = Material::new(3000.0, 0.3).unwrap();
    let organ = Organ::new(mesh, "liver".into(), material, 0.0, s.surface_tets).unwrap();
    let sc = Scenario::of(&organ.mesh).unwrap();
    let mat = settling(material, &sc);
    let st = Stepping {
        contact: ContactLaw::FineSurface,
        ..Stepping::new(true, 1.0, &s)
    };
    let top: u32 = std::env::var("FINE_LEVELS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    for k in 1..=top {
        let model = organ.build("bem", mat).unwrap();
        let fixed = sc.fixed(model.rest_surface());
        let fine =
            MappedSurface::subdivided(model.rest_surface(), model.surface().triangles, 1 << k)
                .unwrap();
        let mut sim = Simulation::new(model, fixed, Loads::default()).unwrap();
        sim.set_fine_surface(fine).unwrap();
        capture::start();
        let t = Instant::now();
        let run = indent_sim(sim, sc.probe(), sc.probe_radius, 0.0, sc.deep, &st);
        let wall = t.elapsed().as_secs_f64();
        let problem = capture::take().unwrap();
        match run {
            Ok((settled, done)) => println!(
                "k = {k}: deep indentation in {wall:.2} s, F = {:.5e} N, {} points pushed, \
                 converged {}; {} solves, {} rows in all",
                done.instrument_forces()[0].length(),
                settled.contacts,
                settled.contact_converged,
                problem.solves,
                problem.rows
            ),
            Err(e) => println!("k = {k}: failed after {wall:.2} s: {e}"),
        }
        let (m, b, bilateral) = (&problem.m, &problem.b, problem.bilateral);
        let n = b.len();
        let t = Instant::now();
        let (new, new_rounds) = PointRows::solve_matrix(m, b, bilateral).unwrap();
        let new_ms = 1e3 * t.elapsed().as_secs_f64();
        let t = Instant::now();
        let (old, old_rounds) = PointRows::solve_by_pivoting(m, b, bilateral).unwrap();
        let old_ms = 1e3 * t.elapsed().as_secs_f64();
        let gaps = |l: &[Real]| -> Vec<Real> {
            (0..n)
                .map(|i| b[i] + (0..n).map(|j| m[(i, j)] * l[j]).sum::<Real>())
                .collect()
        };
        let scale = b.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
        let worst = |l: &[Real]| {
            let w = gaps(l);
            (bilateral..n).fold(0.0, |a: Real, i| {
                a.max(-w[i]).max(if l[i] > 0.0 { w[i].abs() } else { 0.0 })
            }) / scale
        };
        let (lo, hi, rho, leak) = contraction(m);
        println!(
            "  largest problem: {n} rows ({bilateral} held); H's eigenvalues {lo:.2e} .. \
             {hi:.2e}, ρ = {rho:.3}, K on H's null space {leak:.1e}"
        );
        println!(
            "  splitting: {new_rounds} rounds, {new_ms:.1} ms, {}",
            new.as_ref().map_or("capped".into(), |l| format!(
                "{} pushing, complementarity {:.1e}",
                l.iter().filter(|&&x| x > 0.0).count(),
                worst(l)
            ))
        );
        println!(
            "  pivoting: {old_rounds} rounds, {old_ms:.1} ms, {}",
            old.as_ref().map_or("capped".into(), |l| format!(
                "{} pushing, complementarity {:.1e}",
                l.iter().filter(|&&x| x > 0.0).count(),
                worst(l)
            ))
        );
        if let (Some(a), Some(c)) = (&new, &old) {
            let (wa, wc) = (gaps(a), gaps(c));
            let off = wa
                .iter()
                .zip(&wc)
                .fold(0.0, |x: Real, (p, q)| x.max((p - q).abs()));
            println!("  gaps differ by {:.1e} of the largest |b|", off / scale);
        }
    }
}
