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
        // Not to roundoff: the points' diagonal is raised by 1e-9 of the largest
        // (`solve::lcp::REGULARISATION`).
        assert!(d_push < 1e-8 && d_full < 1e-8 && d_x < 1e-8);
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
