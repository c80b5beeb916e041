//! Fine-surface points pushed by a plane (`Deformable::set_point_contacts`) on
//! `fem-condensed` and `fem-precomputed-tensors`: the two agree, `fem-static` loaded with the
//! pushes they found reproduces their surface (an independent forward solve), the points are
//! complementary on that surface, the supports balance the pushes, and a point on a coarse
//! vertex is that vertex held along the plane's normal.

use super::tests::Rng;
use super::*;
use crate::interact::{Constraints, Loads, PointContact, Prescribed};
use crate::mesh::generate::{BoxSplit, box_tets};
use crate::model::Deformable;
use crate::model::fem::FemPrecomputedTensors;

/// A 4 × 4 × 2 cm block of 4 × 4 × 2 cells, its material, its linear `fem-static` and the
/// surface vertices at z = 0 (the support).
fn block() -> (TetMesh, Material, FemStatic, Vec<u32>) {
    let mesh = box_tets(
        Vec3::ZERO,
        Vec3::new(0.04, 0.04, 0.02),
        [4, 4, 2],
        BoxSplit::Six,
    );
    let material = Material::new(5000.0, 0.45).unwrap();
    let fem = FemStatic::new(&mesh, material, Order::Linear).unwrap();
    let rest = fem.rest_surface();
    let fixed = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].z < 1e-9)
        .collect();
    (mesh, material, fem, fixed)
}

/// `count` points at random barycentric places on the block's top triangles (many per
/// triangle: more points than the vertices have directions), against the plane through
/// `target` with normal `normal` (pointing down into the block, tilted: part of the top is
/// pushed, part is not).
fn top_points(model: &dyn Deformable, count: usize, rng: &mut Rng) -> Vec<PointContact> {
    let rest = model.rest_surface();
    let top: Vec<[u32; 3]> = model
        .surface()
        .triangles
        .iter()
        .copied()
        .filter(|t| t.iter().all(|&v| rest[v as usize].z > 0.02 - 1e-9))
        .collect();
    let normal = Vec3::new(0.05, 0.02, -1.0).normalize();
    let target = Vec3::new(0.02, 0.02, 0.02 - 4e-4);
    (0..count)
        .map(|_| {
            let t = top[(rng.next() * top.len() as Real) as usize % top.len()];
            let (a, b) = (rng.next(), rng.next());
            let (a, b) = if a + b > 1.0 {
                (1.0 - a, 1.0 - b)
            } else {
                (a, b)
            };
            let weights = [1.0 - a - b, a, b];
            let rest = (0..3).map(|i| rest[t[i] as usize] * weights[i]).sum();
            PointContact {
                vertices: t,
                weights,
                rest,
                normal,
                target,
            }
        })
        .collect()
}

fn gravity() -> Loads {
    Loads {
        gravity: Vec3::new(0.0, 0.0, -9.81),
        point_loads: Vec::new(),
    }
}

/// The point's position on `surface` (x = rest + Σ wᵢ (xᵢ − Xᵢ)).
fn at(p: &PointContact, surface: &[Vec3], rest: &[Vec3]) -> Vec3 {
    p.rest
        + (0..3)
            .map(|i| {
                (surface[p.vertices[i] as usize] - rest[p.vertices[i] as usize]) * p.weights[i]
            })
            .sum::<Vec3>()
}

fn max_gap(a: &[Vec3], b: &[Vec3]) -> Real {
    a.iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length())
        .fold(0.0, Real::max)
}

/// Steps `model` with the block's support, gravity and `points` (and `held`, one vertex held
/// in full: a bilateral row beside the points); returns the pushes, surface and reactions.
fn press(
    model: &mut dyn Deformable,
    fixed: &[u32],
    held: &[Prescribed],
    points: &[PointContact],
) -> (Vec<Real>, Vec<Vec3>, Vec<Vec3>) {
    model.set_loads(&gravity()).unwrap();
    let c = Constraints {
        fixed: fixed.to_vec(),
        prescribed: held.to_vec(),
    };
    model.set_constraints(&c).unwrap();
    assert!(model.holds_point_contacts());
    assert!(model.set_point_contacts(points).unwrap());
    model.step(0.01).unwrap();
    let r = model.reactions();
    let reactions = r.fixed.iter().chain(r.prescribed).copied().collect();
    (
        model.point_reactions().to_vec(),
        model.surface().positions.to_vec(),
        reactions,
    )
}

#[test]
fn points_pressed_by_a_plane_agree_across_kinds_and_with_fem_static_loaded_by_their_pushes() {
    let (mesh, material, mut reference, fixed) = block();
    let mut condensed = FemCondensed::new(&mesh, material, &fixed).unwrap();
    let mut tensors = FemPrecomputedTensors::new(&mesh, material, &fixed).unwrap();
    let points = top_points(&condensed, 60, &mut Rng::new(3));
    let rest = condensed.rest_surface().to_vec();
    // A side vertex held in full, pushed inward: a bilateral row beside the points.
    let side = (0..rest.len() as u32)
        .find(|&v| rest[v as usize].x < 1e-9 && rest[v as usize].z > 0.009)
        .unwrap();
    let held = [Prescribed {
        vertex: side,
        position: rest[side as usize] + Vec3::new(5e-4, 0.0, 0.0),
    }];
    let (lc, xc, rc) = press(&mut condensed, &fixed, &held, &points);
    let (lt, xt, rt) = press(&mut tensors, &fixed, &held, &points);
    let pushed = lc.iter().filter(|&&l| l > 0.0).count();
    assert!(pushed > 5 && pushed < points.len() - 5, "{pushed} pushed");
    let (sc, st): (Real, Real) = (lc.iter().sum(), lt.iter().sum());
    let sag = max_gap(&xc, &rest);
    let scale_r = rc.iter().map(|r| r.length()).fold(0.0, Real::max);
    let (d_sum, d_x, d_r) = (
        (sc - st).abs() / sc,
        max_gap(&xc, &xt) / sag,
        max_gap(&rc, &rt) / scale_r,
    );
    eprintln!(
        "60 points, {pushed} pushed, Σλ {sc:.6e} N: tensors vs condensed Σλ {d_sum:.1e}, \
         surface {d_x:.1e}, reactions {d_r:.1e} (relative)"
    );
    assert!(d_sum < 1e-8 && d_x < 1e-8 && d_r < 1e-8);

    // fem-static, loaded with the pushes (each point's λ n spread on its vertices by its
    // weights) and the held vertex's reaction, reaches the same surface.
    let mut loads = gravity();
    for (p, &l) in points.iter().zip(&lc) {
        for i in 0..3 {
            loads
                .point_loads
                .push((p.vertices[i], p.normal * (l * p.weights[i])));
        }
    }
    let held_force = -condensed.reactions().prescribed[0];
    loads.point_loads.push((side, held_force));
    reference.set_loads(&loads).unwrap();
    reference
        .set_constraints(&Constraints::fixed(fixed.clone()))
        .unwrap();
    reference.step(0.0).unwrap();
    let xs = reference.surface().positions.to_vec();
    let d_static = max_gap(&xs, &xc) / sag;
    // Complementarity on fem-static's surface: no point below its plane, none pulled, a
    // pushed one on it.
    let (mut below, mut off_pushed): (Real, Real) = (0.0, 0.0);
    for (p, &l) in points.iter().zip(&lc) {
        assert!(l >= 0.0);
        let g = p.normal.dot(at(p, &xs, &rest) - p.target);
        below = below.max(-g);
        if l > 0.0 {
            off_pushed = off_pushed.max(g.abs());
        }
    }
    // Equilibrium: the supports take gravity and the pushes.
    let weight = applied_load_of(&reference, &gravity());
    let pushes: Vec3 = points.iter().zip(&lc).map(|(p, &l)| p.normal * l).sum();
    let supports: Vec3 = condensed.reactions().fixed.iter().sum();
    let balance = (supports - weight - pushes - held_force).length() / scale_r;
    eprintln!(
        "fem-static under the pushes: surface {d_static:.1e} relative; below a plane \
         {below:.1e} m, a pushed point off it {off_pushed:.1e} m (sag {sag:.1e} m); \
         balance {balance:.1e}"
    );
    assert!(d_static < 1e-8, "{d_static:e}");
    assert!(below < 1e-8 * sag && off_pushed < 1e-8 * sag);
    assert!(balance < 1e-9, "{balance:e}");
}

fn applied_load_of(fem: &FemStatic, l: &Loads) -> Vec3 {
    super::tests::applied_load(fem, l)
}

/// A point on a coarse vertex (weights 1, 0, 0) pushed by a plane is that vertex held along
/// the plane's normal at the plane (`set_constraints_along`): same push, same surface.
#[test]
fn a_point_on_a_vertex_is_the_vertex_held_along_the_normal() {
    let (mesh, material, _, fixed) = block();
    let mut models: [Box<dyn Deformable>; 2] = [
        Box::new(FemCondensed::new(&mesh, material, &fixed).unwrap()),
        Box::new(FemPrecomputedTensors::new(&mesh, material, &fixed).unwrap()),
    ];
    for model in &mut models {
        let rest = model.rest_surface().to_vec();
        let v = (0..rest.len() as u32)
            .find(|&v| (rest[v as usize] - Vec3::new(0.02, 0.02, 0.02)).length() < 1e-9)
            .unwrap();
        let other = (0..rest.len() as u32)
            .find(|&v| (rest[v as usize] - Vec3::new(0.01, 0.03, 0.02)).length() < 1e-9)
            .unwrap();
        let normal = Vec3::new(0.3, -0.2, -1.0).normalize();
        let target = rest[v as usize] + Vec3::new(1e-4, 0.0, -8e-4);
        // The other vertex is held in full in both: the bilateral rows beside the point.
        let full = Prescribed {
            vertex: other,
            position: rest[other as usize] + Vec3::new(0.0, 2e-4, -3e-4),
        };
        let point = PointContact {
            vertices: [v, other, fixed[0]],
            weights: [1.0, 0.0, 0.0],
            rest: rest[v as usize],
            normal,
            target,
        };
        let (l, x, _) = press(model.as_mut(), &fixed, &[full], &[point]);
        let r_full = model.reactions().prescribed[0];
        let c = Constraints {
            fixed: fixed.clone(),
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
        model.step(0.01).unwrap();
        let along = model.reactions().prescribed.to_vec();
        let d_push = (along[1] + normal * l[0]).length() / along[1].length();
        let d_full = (along[0] - r_full).length() / r_full.length();
        let d_x = max_gap(&x, model.surface().positions) / max_gap(&x, &rest);
        eprintln!(
            "{}: point on a vertex vs held along n: push {d_push:.1e}, other contact \
             {d_full:.1e}, surface {d_x:.1e} (relative; λ {:.4e} N)",
            model.kind(),
            l[0]
        );
        assert!(l[0] > 0.0);
        // Not to roundoff: the complementarity solve raises the points' diagonal by 1e-9
        // of the largest (`solve::lcp::REGULARISATION`), a relative change of that order.
        assert!(d_push < 1e-8 && d_full < 1e-8 && d_x < 1e-8);
        // A point clear of its plane is not pushed, and the surface is the loads' alone.
        let clear = PointContact {
            target: target - normal * 1e-2,
            ..point
        };
        let (l, _, _) = press(model.as_mut(), &fixed, &[], &[clear]);
        assert_eq!(l[0], 0.0);
        // Setting constraints again clears the points; a bad point is an error, no panic.
        model
            .set_constraints(&Constraints::fixed(fixed.clone()))
            .unwrap();
        assert!(model.point_reactions().is_empty());
        let bad = PointContact {
            vertices: [v, other, rest.len() as u32],
            ..point
        };
        assert!(model.set_point_contacts(&[bad]).is_err());
        let bad = PointContact {
            normal: Vec3::new(Real::NAN, 0.0, 1.0),
            ..point
        };
        assert!(model.set_point_contacts(&[bad]).is_err());
    }
}

/// The cost of point contacts on the liver (137 free surface vertices) against today's
/// vertex path (`model::testing::point_contact_study`).
#[test]
#[ignore = "study, seconds: cargo test --release -p tissue --lib fem_point_contact_study -- --ignored --nocapture"]
fn fem_point_contact_study() {
    let (mesh, _, fixed) = super::tests::liver_static();
    let material = super::tests::liver_material();
    let counts = [25, 100, 400];
    let mut condensed = FemCondensed::new(&mesh, material, &fixed).unwrap();
    let mut tensors = FemPrecomputedTensors::new(&mesh, material, &fixed).unwrap();
    for bulge in [0.0, 0.005] {
        crate::model::testing::point_contact_study(&mut condensed, &fixed, &counts, bulge);
        crate::model::testing::point_contact_study(&mut tensors, &fixed, &counts, bulge);
    }
}
