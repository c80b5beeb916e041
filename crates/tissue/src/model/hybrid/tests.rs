//! The hybrid against physics: its static equilibrium equals `fem-static`'s on the same mesh
//! (linear region, probe on either part and on the interface), rigid rotations of the
//! region give no elastic force (St Venant–Kirchhoff region), the rest is in equilibrium
//! across the interface at every step (forces and moments), cuts inside the region leave a
//! closed oriented surface and a stable model, cuts outside are refused or grow the region.

use std::collections::HashMap;

use super::*;
use crate::integrate::coupling::NodeCoupling;
use crate::interact::{Constraints, Loads, Prescribed};
use crate::material::Material;
use crate::math::Mat3;
use crate::mesh::generate::{BoxSplit, box_tets};
use crate::mesh::{MeshData, TetMesh};
use crate::model::fem::{FemStatic, Order};
use crate::model::tensor_mass::cut::enclosed_volume;
use crate::model::{CutPath, Deformable, build};

fn material(damping: Real) -> Material {
    let mut m = Material::new(5000.0, 0.4).unwrap();
    m.damping = damping;
    m
}

/// A 12 × 3 × 3-cell beam of 12 × 3 × 3 cm.
fn beam() -> TetMesh {
    box_tets(
        Vec3::ZERO,
        Vec3::new(0.12, 0.03, 0.03),
        [12, 3, 3],
        BoxSplit::Six,
    )
}

fn hybrid(mesh: &TetMesh, m: Material, params: &str) -> Hybrid {
    let data = MeshData::from_tets(mesh);
    let params: toml::Table = toml::from_str(params).unwrap();
    Hybrid::from_input(&BuildInput {
        mesh: &data,
        source: "test",
        material: m,
        params: &params,
        regions: &[],
    })
    .unwrap()
}

/// Surface vertex of `b` at each rest position of `a`'s surface (same mesh, exact copies).
fn vertex_map(a: &[Vec3], b: &[Vec3]) -> Vec<u32> {
    let key = |p: &Vec3| p.to_array().map(|c| c.to_bits());
    let index: HashMap<[u64; 3], u32> = b
        .iter()
        .enumerate()
        .map(|(i, p)| (key(p), i as u32))
        .collect();
    a.iter().map(|p| index[&key(p)]).collect()
}

fn map_constraints(c: &Constraints, map: &[u32]) -> Constraints {
    Constraints {
        fixed: c.fixed.iter().map(|&v| map[v as usize]).collect(),
        prescribed: c
            .prescribed
            .iter()
            .map(|p| Prescribed {
                vertex: map[p.vertex as usize],
                position: p.position,
            })
            .collect(),
    }
}

fn max_abs(v: impl Iterator<Item = Real>) -> Real {
    v.fold(0.0, |m, x| m.max(x.abs()))
}

/// Steps (implicit Euler, long steps) until the state stops moving: the static equilibrium.
fn settle(m: &mut Hybrid) {
    m.tm.set_scheme(crate::integrate::Scheme::ImplicitEuler);
    let mut last = m.surface().positions.to_vec();
    for _ in 0..400 {
        m.step(10.0).unwrap();
        let now = m.surface().positions;
        let change = max_abs(
            now.iter()
                .zip(&last)
                .flat_map(|(a, b)| (*a - *b).to_array()),
        );
        let size = max_abs(
            now.iter()
                .zip(m.rest_surface())
                .flat_map(|(a, b)| (*a - *b).to_array()),
        );
        last.copy_from_slice(now);
        if change < 1e-13 * size {
            return;
        }
    }
    panic!("no equilibrium after 400 implicit steps");
}

/// The beam clamped at x = 0, a probe pushing one surface vertex, gravity and a point load:
/// the hybrid (linear region in the middle, the rest in two pieces on either side) at
/// equilibrium against `fem-static`, with the probe on the region, on the rest and on the
/// interface.
#[test]
fn static_equilibrium_matches_fem_static_wherever_the_probe_is() {
    let mesh = beam();
    let params = r#"
        nonlinear = false
        cut_region = { box = { min = [0.04, -1.0, -1.0], max = [0.08, 1.0, 1.0] } }
    "#;
    let mut h = hybrid(&mesh, material(5.0), params);
    assert!(h.interface_nodes() > 0 && h.region_fraction() > 0.3 && h.region_fraction() < 0.36);
    let mut reference = FemStatic::new(&mesh, material(5.0), Order::Linear).unwrap();
    let map = vertex_map(h.rest_surface(), reference.rest_surface());
    let rest = h.rest_surface().to_vec();
    let fixed: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].x < 1e-9)
        .collect();
    let at = |p: Vec3| -> u32 {
        (0..rest.len() as u32)
            .min_by(|&a, &b| {
                rest[a as usize]
                    .distance(p)
                    .total_cmp(&rest[b as usize].distance(p))
            })
            .unwrap()
    };
    let region_v = at(Vec3::new(0.06, 0.03, 0.01));
    let rest_v = at(Vec3::new(0.12, 0.02, 0.03));
    let iface_v = at(Vec3::new(0.04, 0.01, 0.03));
    let load_v = at(Vec3::new(0.10, 0.0, 0.0));
    let loads = Loads {
        gravity: Vec3::new(0.0, 0.0, -9.81),
        point_loads: vec![(load_v, Vec3::new(0.01, -0.02, 0.005))],
    };
    for (name, v, d) in [
        ("region", region_v, Vec3::new(0.0, -2e-3, 1e-3)),
        ("rest", rest_v, Vec3::new(1e-3, -2e-3, -1e-3)),
        ("interface", iface_v, Vec3::new(-1e-3, 0.0, -2e-3)),
    ] {
        let c = Constraints {
            fixed: fixed.clone(),
            prescribed: vec![Prescribed {
                vertex: v,
                position: rest[v as usize] + d,
            }],
        };
        h.reset();
        h.set_loads(&loads).unwrap();
        h.set_constraints(&c).unwrap();
        settle(&mut h);
        let ref_loads = Loads {
            gravity: loads.gravity,
            point_loads: vec![(map[load_v as usize], loads.point_loads[0].1)],
        };
        reference.set_loads(&ref_loads).unwrap();
        reference
            .set_constraints(&map_constraints(&c, &map))
            .unwrap();
        reference.step(0.0).unwrap();
        let (ph, pr) = (h.surface().positions, reference.surface().positions);
        let rr = reference.rest_surface();
        let mut du: Real = 0.0;
        let mut scale: Real = 0.0;
        for (a, &b) in map.iter().enumerate().take(rest.len()) {
            du = du.max(max_abs((ph[a] - pr[b as usize]).to_array().into_iter()));
            scale = scale.max(max_abs(
                (pr[b as usize] - rr[b as usize]).to_array().into_iter(),
            ));
        }
        let (rh, rf) = (h.reactions(), reference.reactions());
        let flat = |r: crate::model::Reactions<'_>| -> Vec<Real> {
            r.fixed
                .iter()
                .chain(r.prescribed)
                .flat_map(|v| v.to_array())
                .collect()
        };
        let (fa, fb) = (flat(rh), flat(rf));
        let dr = max_abs(fa.iter().zip(&fb).map(|(x, y)| x - y)) / max_abs(fb.iter().copied());
        eprintln!(
            "probe on the {name}: surface {:.1e}, reactions {dr:.1e} (relative)",
            du / scale
        );
        assert!(du < 1e-8 * scale, "{name}: displacements {:e}", du / scale);
        assert!(dr < 1e-8, "{name}: reactions {dr:e}");
        // The volume view: every node, the rest's interior included, where fem-static
        // has it.
        let (vh, vr) = (h.volume().unwrap(), reference.volume().unwrap());
        assert_eq!(vh.positions.len(), vr.positions.len());
        assert_eq!(vh.tets.len(), mesh.tets.len());
        let dv = max_abs(
            vh.positions
                .iter()
                .zip(vr.positions)
                .flat_map(|(a, b)| (*a - *b).to_array()),
        );
        assert!(
            dv < 1e-8 * scale,
            "{name}: volume positions {:e}",
            dv / scale
        );
        // Σ reactions = the applied loads (weight + point load).
        let total: Vec3 = rh.fixed.iter().chain(rh.prescribed).copied().sum();
        let weight = loads.gravity * 1000.0 * mesh.volume() + loads.point_loads[0].1;
        assert!(
            (total - weight).length() < 1e-9 * weight.length(),
            "{total} vs {weight}"
        );
    }
}

/// Newton's third law at the interface: after every step of a dynamic run with contacts on
/// both parts, the rest is in equilibrium under its loads, its contacts and the region's
/// forces on it (minus the forces it exerts on the interface): forces and moments to 1e-9.
#[test]
fn the_rest_is_in_equilibrium_across_the_interface_every_step() {
    let mesh = beam();
    let params = r#"
        cut_region = { box = { min = [0.04, -1.0, -1.0], max = [0.08, 1.0, 1.0] } }
        volume_penalty = 500.0
    "#;
    let mut h = hybrid(&mesh, material(10.0), params);
    let rest = h.rest_surface().to_vec();
    let fixed: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].x < 1e-9)
        .collect();
    let tip: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].x > 0.12 - 1e-9 && rest[v as usize].z > 0.03 - 1e-9)
        .collect();
    let mid = (0..rest.len() as u32)
        .find(|&v| (rest[v as usize] - Vec3::new(0.06, 0.01, 0.03)).length() < 1e-9)
        .unwrap();
    h.set_loads(&Loads {
        gravity: Vec3::new(0.0, 0.0, -9.81),
        point_loads: vec![],
    })
    .unwrap();
    for step in 0..300 {
        let s = (step as Real / 300.0).min(1.0);
        let mut c = Constraints::fixed(fixed.clone());
        for &v in &tip {
            c.prescribed.push(Prescribed {
                vertex: v,
                position: rest[v as usize] + Vec3::new(0.0, 0.0, -0.01 * s),
            });
        }
        c.prescribed.push(Prescribed {
            vertex: mid,
            position: rest[mid as usize] + Vec3::new(0.0, 0.0, -0.004 * s),
        });
        h.set_constraints(&c).unwrap();
        h.step(2e-4).unwrap();
        let (iface, contacts) = h.interface_balance();
        // Forces on the rest: its load, the contacts' λ, and −F_I from the region.
        let slots: Vec<Vec3> = contacts;
        let mut force = h.rest_load();
        let mut moment = Vec3::ZERO;
        for f in &slots {
            force += *f;
        }
        let mut scale: Real = h.rest_load().length();
        for &(g, f) in &iface {
            force -= f;
            moment -= h.mesh.vertices[g as usize].cross(f);
            scale = scale.max(f.length());
        }
        // The contacts' and loads' moments, from the rest's own data.
        moment += h.rest_moment_of_loads_and_contacts();
        assert!(
            force.length() < 1e-9 * scale,
            "step {step}: force imbalance {force}"
        );
        assert!(
            moment.length() < 1e-9 * scale * 0.12,
            "step {step}: moment imbalance {moment}"
        );
    }
    // The clamp and the tip are on the rest: its contacts.
    assert_eq!(h.rest_contacts(), tip.len() + fixed.len());
}

/// A rigid rotation of the region's nodes by 90° (the rest given the rotated interface):
/// the St Venant–Kirchhoff region exerts no elastic force on its nodes (those away from
/// the interface feel nothing else), where a linear region inflates.
#[test]
fn a_rotated_region_feels_no_spurious_force() {
    let mesh = beam();
    let params = |nl: bool| {
        format!(
            "nonlinear = {nl}\ncut_region = {{ box = {{ min = [0.06, -1.0, -1.0], max = \
             [0.13, 1.0, 1.0] }} }}"
        )
    };
    let mut out = Vec::new();
    for nl in [true, false] {
        let h = hybrid(&mesh, material(0.0), &params(nl));
        let tm = h.region_model();
        let rest = tm.rest_nodes().to_vec();
        let c = rest.iter().copied().sum::<Vec3>() / rest.len() as Real;
        let q = glam::DQuat::from_axis_angle(Vec3::X, std::f64::consts::FRAC_PI_2);
        let x: Vec<Vec3> = rest.iter().map(|p| c + q * (*p - c)).collect();
        let v = vec![Vec3::ZERO; x.len()];
        let mut system = tm.system().clone();
        let mut f = vec![Vec3::ZERO; x.len()];
        system.add_forces(&x, &v, &mut f);
        // The rest's forces on the interface nodes, for the same positions.
        let iface = h.region_iface_nodes();
        let coupling = h.rest.coupling(&iface, &h.split.region.mesh.vertices);
        let mut fc = vec![Vec3::ZERO; x.len()];
        coupling.add_forces(&x, &mut fc);
        let interior: Vec<usize> = (0..x.len())
            .filter(|&n| !h.split.border[h.split.region.global[n] as usize])
            .collect();
        assert!(interior.len() > 20);
        let stretch: Vec<Vec3> = rest.iter().map(|p| *p * 1.01).collect();
        let mut fs = vec![Vec3::ZERO; x.len()];
        system.add_forces(&stretch, &v, &mut fs);
        let scale = fs.iter().fold(0.0 as Real, |m, f| m.max(f.length()));
        let worst = interior
            .iter()
            .fold(0.0 as Real, |m, &n| m.max((f[n] + fc[n]).length()));
        out.push(worst / scale);
    }
    eprintln!(
        "90° rotation of the region, |f| / |f of a 1% stretch| away from the interface: \
         StVK {:.1e}, linear {:.2}",
        out[0], out[1]
    );
    assert!(out[0] < 1e-9, "{}", out[0]);
    assert!(out[1] > 1.0, "{}", out[1]);
}

/// Checks the drawn surface: every edge in exactly two triangles, in opposite directions,
/// and the enclosed volume equal to the surviving tetrahedra's.
fn assert_closed_oriented(h: &Hybrid) {
    let s = h.surface();
    let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
    for t in s.triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *edges.entry((a, b)).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &edges {
        assert_eq!(n, 1, "edge {a}-{b} used {n} times one way");
        assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}-{b} has no twin");
    }
    let alive: Real = (0..h.mesh.tets.len())
        .filter(|&t| h.alive[t])
        .map(|t| h.mesh.tet_volume(t))
        .sum();
    let enclosed = enclosed_volume(h.rest_surface(), s.triangles);
    assert!(
        (enclosed - alive).abs() < 1e-9 * alive,
        "{enclosed} vs {alive}"
    );
}

/// A vertical slice of blade sweeping across z at x, from y0 to y1.
fn slice(x: Real, y0: Real, y1: Real) -> CutPath {
    CutPath {
        start: [Vec3::new(x, y0, 0.045), Vec3::new(x, y0, 0.012)],
        end: [Vec3::new(x, y1, 0.045), Vec3::new(x, y1, 0.012)],
    }
}

#[test]
fn cuts_inside_the_region_close_the_surface_and_stay_stable_outside_are_refused() {
    let mesh = box_tets(
        Vec3::ZERO,
        Vec3::new(0.12, 0.06, 0.03),
        [12, 6, 3],
        BoxSplit::Six,
    );
    let params = r#"
        cut_region = { box = { min = [0.02, -1.0, -1.0], max = [0.10, 1.0, 1.0] } }
        volume_penalty = 500.0
    "#;
    let mut stiff = material(50.0);
    stiff.young_modulus = 50e3;
    let mut h = hybrid(&mesh, stiff, params);
    let rest = h.rest_surface().to_vec();
    let fixed: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].x < 1e-9)
        .collect();
    h.set_constraints(&Constraints::fixed(fixed)).unwrap();
    h.set_loads(&Loads {
        gravity: Vec3::new(0.0, 0.0, -9.81),
        point_loads: vec![],
    })
    .unwrap();
    assert_closed_oriented(&h);
    let mut removed = 0;
    for (k, x) in [0.055, 0.065, 0.0605].into_iter().enumerate() {
        // Sweep across in 10 small strokes, stepping between them.
        for i in 0..10 {
            let y0 = 0.015 + 0.003 * i as Real;
            let info = h.cut(&slice(x, y0, y0 + 0.003)).unwrap();
            removed += info.removed_elements;
            for _ in 0..5 {
                h.step(2e-4).unwrap();
            }
        }
        assert_closed_oriented(&h);
        eprintln!("cut {k}: {removed} tetrahedra removed");
    }
    assert!(removed > 20, "{removed}");
    assert_eq!(h.border_removals, 0);
    for _ in 0..2000 {
        h.step(2e-4).unwrap();
    }
    let speed = h
        .region_model()
        .velocities()
        .iter()
        .fold(0.0 as Real, |m, v| m.max(v.length()));
    let moved = h
        .surface()
        .positions
        .iter()
        .zip(h.rest_surface())
        .fold(0.0 as Real, |m, (x, r)| m.max(x.distance(*r)));
    eprintln!("after the cuts: speed {speed:.1e} m/s, displacement {moved:.1e} m");
    assert!(speed < 1e-3 && moved < 0.05, "{speed} m/s, {moved} m");
    // Near the region's border, and outside it: refused, naming the region.
    let before = h.info().elements;
    for x in [0.025, 0.11] {
        let e = h.cut(&slice(x, 0.02, 0.04)).unwrap_err().to_string();
        assert!(e.contains("cut_region") && e.contains("Box"), "{e}");
    }
    assert_eq!(h.info().elements, before);
    // Reset: uncut, closed.
    h.reset();
    assert_eq!(h.info().elements, mesh.tets.len());
    assert_closed_oriented(&h);
}

/// Automatic mode: the region starts around the seed and grows ahead of a blade that
/// travels along the beam, so every stroke cuts; each growth keeps the cuts made so far.
/// A 24 × 6 × 3 cm beam clamped at x = 0, hybrid in automatic mode seeded at its far top.
fn auto_beam(auto_radius: Real) -> (TetMesh, Hybrid) {
    let mesh = box_tets(
        Vec3::ZERO,
        Vec3::new(0.24, 0.06, 0.03),
        [24, 6, 3],
        BoxSplit::Six,
    );
    let params = format!(
        r#"
        cut_region = "auto"
        auto_radius = {auto_radius}
        auto_seeds = [[0.2, 0.03, 0.03]]
        volume_penalty = 500.0
    "#
    );
    let mut h = hybrid(&mesh, material(20.0), &params);
    let rest = h.rest_surface().to_vec();
    let fixed: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].x < 1e-9)
        .collect();
    h.set_constraints(&Constraints::fixed(fixed)).unwrap();
    (mesh, h)
}

#[test]
fn the_automatic_region_follows_the_blade() {
    let (mesh, mut h) = auto_beam(0.02);
    let start = h.region_tets();
    let mut removed = 0;
    // Along the beam at y = 0.03 from x = 0.2 to x = 0.13.
    for i in 0..14 {
        let x0 = 0.2 - 0.005 * i as Real;
        let blade = CutPath {
            start: [Vec3::new(x0, 0.03, 0.045), Vec3::new(x0, 0.03, 0.015)],
            end: [
                Vec3::new(x0 - 0.005, 0.03, 0.045),
                Vec3::new(x0 - 0.005, 0.03, 0.015),
            ],
        };
        removed += h.cut(&blade).unwrap().removed_elements;
        for _ in 0..5 {
            h.step(2e-4).unwrap();
        }
        assert_closed_oriented(&h);
    }
    let growths = h.growths().to_vec();
    eprintln!(
        "region {start} -> {} tetrahedra in {} growths ({:?} s), {removed} removed",
        h.region_tets(),
        growths.len(),
        growths.iter().map(|g| g.seconds).collect::<Vec<_>>()
    );
    assert!(!growths.is_empty() && h.region_tets() > start);
    assert!(removed > 20);
    assert_eq!(h.border_removals, 0);
    let removed_now = h.info().elements;
    assert_eq!(removed_now, mesh.tets.len() - removed);
}

/// Automatic mode, one fast stroke: the blade sweeps a quad 10 cm long and deeper than the
/// beam in a single step. The middle of that quad is farther than the growth radius from all
/// of the blade's edges and from its tip's path, so the region must grow around the swept
/// surface itself, or the stroke is refused (the soak found this with random jumps).
#[test]
fn a_fast_stroke_grows_the_automatic_region_around_all_it_sweeps() {
    let (mesh, mut h) = auto_beam(0.01);
    let blade = CutPath {
        start: [Vec3::new(0.2, 0.03, 0.045), Vec3::new(0.2, 0.03, -0.015)],
        end: [Vec3::new(0.1, 0.03, 0.045), Vec3::new(0.1, 0.03, -0.015)],
    };
    let removed = h.cut(&blade).unwrap().removed_elements;
    h.step(2e-4).unwrap();
    assert_closed_oriented(&h);
    assert!(removed >= 10, "{removed}");
    assert_eq!(h.border_removals, 0);
    assert_eq!(h.info().elements, mesh.tets.len() - removed);
}

#[test]
fn bad_settings_are_refused_with_the_key() {
    let mesh = beam();
    let data = MeshData::from_tets(&mesh);
    for (params, key) in [
        ("cut_region = \"everywhere\"", "cut_region"),
        (
            "cut_region = { sphere = { center = [5.0, 5.0, 5.0], radius = 0.01 } }",
            "no tetrahedron",
        ),
        (
            "cut_region = { box = { min = [0.0, 0.0, 0.0], max = [0.05, 1.0, 1.0] } }\n\
             fragments = \"remove\"",
            "fragments",
        ),
    ] {
        let table: toml::Table = toml::from_str(params).unwrap();
        let input = BuildInput {
            mesh: &data,
            source: "test",
            material: material(0.0),
            params: &table,
            regions: &[],
        };
        let e = build("hybrid", &input).err().unwrap().to_string();
        assert!(e.contains(key), "{params}: {e}");
    }
}

/// `prescribed_stiffness` is the derivative of the instrument's force: central differences
/// of the reactions over a 1e-7 s step after the targets moved by ±h (the free nodes move by
/// O(dt²) meanwhile), in a deformed state of a St Venant–Kirchhoff region (its tangent, not
/// the rest one), with the instrument on the region, on the rest, and on both.
#[test]
fn prescribed_stiffness_is_the_derivative_of_the_reactions() {
    let mesh = beam();
    let params = r#"
        cut_region = { box = { min = [0.04, -1.0, -1.0], max = [0.08, 1.0, 1.0] } }
        integrator = "symplectic-euler"
    "#;
    let probe = hybrid(&mesh, material(0.0), params);
    let rest = probe.rest_surface().to_vec();
    let at = |p: Vec3| -> u32 {
        (0..rest.len() as u32)
            .min_by(|&a, &b| {
                rest[a as usize]
                    .distance(p)
                    .total_cmp(&rest[b as usize].distance(p))
            })
            .unwrap()
    };
    let fixed: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].x < 1e-9)
        .collect();
    let region = [
        at(Vec3::new(0.06, 0.03, 0.01)),
        at(Vec3::new(0.05, 0.03, 0.02)),
    ];
    let on_rest = [
        at(Vec3::new(0.11, 0.03, 0.01)),
        at(Vec3::new(0.10, 0.03, 0.02)),
    ];
    let iface = at(Vec3::new(0.04, 0.03, 0.01));
    // The instrument's vertices come after a support entry that is not the instrument's.
    let other = at(Vec3::new(0.12, 0.0, 0.0));
    for (name, verts) in [
        ("region", region.to_vec()),
        ("rest", on_rest.to_vec()),
        (
            "region, interface and rest",
            vec![region[0], iface, on_rest[0]],
        ),
    ] {
        let press = Vec3::new(0.0, -4e-3, 1e-3);
        let constraints = |shift: Vec3| Constraints {
            fixed: fixed.clone(),
            prescribed: std::iter::once(Prescribed {
                vertex: other,
                position: rest[other as usize],
            })
            .chain(verts.iter().map(|&v| Prescribed {
                vertex: v,
                position: rest[v as usize] + press + shift,
            }))
            .collect(),
        };
        // The same deformed, moving state for every model: pressed in over 300 steps.
        let prepared = || {
            let mut h = hybrid(&mesh, material(0.0), params);
            for k in 1..=300 {
                let mut c = constraints(Vec3::ZERO);
                for p in &mut c.prescribed[1..] {
                    let r = rest[p.vertex as usize];
                    p.position = r + press * (k.min(200) as Real / 200.0);
                }
                h.set_constraints(&c).unwrap();
                h.step(2e-5).unwrap();
            }
            h
        };
        let mut base = prepared();
        base.set_constraints(&constraints(Vec3::ZERO)).unwrap();
        let k = base.prescribed_stiffness(1..1 + verts.len()).unwrap();
        let h = 1e-7;
        let mut fd = Mat3::ZERO;
        for c in 0..3 {
            let force = |sign: Real| -> Vec3 {
                let mut m = prepared();
                m.set_constraints(&constraints(Vec3::AXES[c] * (sign * h)))
                    .unwrap();
                m.step(1e-7).unwrap();
                m.reactions().prescribed[1..].iter().copied().sum()
            };
            *fd.col_mut(c) = (force(1.0) - force(-1.0)) / (2.0 * h);
        }
        let err = (k - fd)
            .to_cols_array()
            .iter()
            .fold(0.0 as Real, |m, x| m.max(x.abs()));
        let size = fd
            .to_cols_array()
            .iter()
            .fold(0.0 as Real, |m, x| m.max(x.abs()));
        eprintln!(
            "instrument on the {name}: |K| {size:.3e} N/m, K vs differences {:.1e}",
            err / size
        );
        assert!(err < 1e-4 * size, "{name}: {k:?} vs {fd:?}");
        // Pushing in meets resistance: −K is positive definite on its symmetric part.
        let sym = (k + k.transpose()) * 0.5;
        assert!(
            sym.determinant() < 0.0 && sym.x_axis.x < 0.0,
            "{name}: {k:?}"
        );
    }
}

/// The automatic substeps see the rest's interface stiffness from the first step. On a
/// stiff rest — a region one cell thick, every node of it on the interface, held on both
/// sides by the rest — the stability limit measured with the coupling is well below the
/// one of the region alone (its nodes carry the rest's mass share but would be free), and
/// stepping at 20× the coupled limit under `substeps = "auto"` stays bounded and settles.
#[test]
fn automatic_substeps_count_the_interface_stiffness() {
    let mesh = beam();
    let params = r#"
        cut_region = { box = { min = [0.04, -1.0, -1.0], max = [0.05, 1.0, 1.0] } }
        integrator = "symplectic-euler"
    "#;
    let mut h = hybrid(&mesh, material(20.0), params);
    let coupled = h.tm.integrator().stable_dt().unwrap();
    h.tm.measure_stability(None);
    let alone = h.tm.integrator().stable_dt().unwrap();
    h.measure_stability();
    let again = h.tm.integrator().stable_dt().unwrap();
    // (Power iterations warm-started from the last vector: the same limit to 1 %.)
    assert!(
        (again - coupled).abs() < 0.01 * coupled,
        "{again} vs {coupled}"
    );
    eprintln!("stable dt: region with the rest's stiffness {coupled:.3e} s, alone {alone:.3e} s");
    assert!(coupled < 0.9 * alone, "{coupled} vs {alone}");
    let rest = h.rest_surface().to_vec();
    let fixed: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].x < 1e-9)
        .collect();
    h.set_constraints(&Constraints {
        fixed,
        prescribed: Vec::new(),
    })
    .unwrap();
    h.set_loads(&Loads {
        gravity: Vec3::new(0.0, -9.81, 0.0),
        point_loads: Vec::new(),
    })
    .unwrap();
    let dt = 20.0 * coupled;
    let mut substeps = 0;
    let mut last = Vec::new();
    for _ in 0..400 {
        let info = h.step(dt).unwrap();
        substeps = substeps.max(info.substeps);
        last = h.surface().positions.to_vec();
    }
    assert!(substeps >= 20, "{substeps} substeps");
    let before = last.clone();
    h.step(dt).unwrap();
    let speed = max_abs(
        h.surface()
            .positions
            .iter()
            .zip(&before)
            .flat_map(|(a, b)| (*a - *b).to_array()),
    ) / dt;
    let sag = max_abs(before.iter().zip(&rest).map(|(a, b)| a.y - b.y));
    eprintln!(
        "{substeps} substeps per step; after {:.3} s: sag {sag:.3e} m, speed {speed:.1e} m/s",
        400.0 * dt
    );
    // Bounded and at rest: the soft beam (E = 5 kPa) hangs at its static sag (0.21 m here;
    // it is that soft), no longer moving.
    assert!(
        sag.is_finite() && sag > 0.0 && speed < 1e-9,
        "sag {sag}, speed {speed}"
    );
}

/// With only a mesh and a material (a live switch of kind, `tissue compare`, the Python
/// `Model("hybrid", mesh, material)`), the region is the automatic one around the organ's
/// topmost point, said in the model's details; the labels mark rest, border and cuttable
/// region; a cut elsewhere grows the region.
#[test]
fn a_bare_mesh_and_material_get_the_automatic_region_at_the_top() {
    let mesh = box_tets(
        Vec3::ZERO,
        Vec3::new(0.12, 0.03, 0.03),
        [12, 3, 3],
        BoxSplit::Six,
    );
    let data = MeshData::from_tets(&mesh);
    let mut m = build(
        "hybrid",
        &BuildInput {
            mesh: &data,
            source: "test",
            material: material(5.0),
            params: &toml::Table::new(),
            regions: &[],
        },
    )
    .unwrap();
    let info = m.info();
    let detail = |k: &str| {
        info.details
            .iter()
            .find(|(n, _)| n == k)
            .map(|(_, v)| v.clone())
            .unwrap_or_default()
    };
    assert_eq!(detail("cut_region"), "auto");
    assert!(
        detail("default_region").contains("topmost"),
        "{:?}",
        info.details
    );
    let fraction: Real = detail("region_volume_fraction").parse().unwrap();
    assert!(fraction > 0.0 && fraction < 0.5, "{fraction}");
    let labels = m.vertex_labels().unwrap();
    let rest = m.rest_surface().to_vec();
    assert_eq!(labels.len(), rest.len());
    for l in 0..3 {
        assert!(labels.contains(&l), "no label {l}");
    }
    // The top (y = 0.03) is where the region starts: the highest vertex is labelled region.
    let top = (0..rest.len())
        .max_by(|&a, &b| rest[a].y.total_cmp(&rest[b].y))
        .unwrap();
    assert!(labels[top] >= 1);
    m.step(1e-4).unwrap();
    // A blade at the other end grows the region.
    let far = if rest[top].x > 0.06 { 0.02 } else { 0.10 };
    m.cut(&CutPath {
        start: [Vec3::new(far, 0.035, 0.015), Vec3::new(far, 0.02, 0.015)],
        end: [
            Vec3::new(far + 0.004, 0.035, 0.015),
            Vec3::new(far + 0.004, 0.02, 0.015),
        ],
    })
    .unwrap();
    let grown: Real = m
        .info()
        .details
        .iter()
        .find(|(n, _)| n == "region_volume_fraction")
        .unwrap()
        .1
        .parse()
        .unwrap();
    assert!(grown > fraction, "{grown} vs {fraction}");
}

/// Sweeps that take the automatic region over every tetrahedron (as `tissue compare`'s
/// scalpel passes across the whole top do): the rest becomes empty and the hybrid is
/// whole-organ tensor-mass, said once as a notice and in the details; it keeps cutting
/// anywhere (closed oriented surface, volume accounted) and, with a linear region, its
/// static equilibrium under gravity and a probe still equals `fem-static` on the surviving
/// tetrahedra.
#[test]
fn a_region_grown_over_every_tetrahedron_is_whole_organ_tensor_mass() {
    let mesh = beam();
    let params = r#"
        nonlinear = false
        cut_region = "auto"
        auto_radius = 0.03
        auto_seeds = [[0.0, 0.015, 0.03]]
    "#;
    let mut h = hybrid(&mesh, material(5.0), params);
    let notices = std::sync::Arc::new(std::sync::Mutex::new(Vec::<String>::new()));
    let sink = notices.clone();
    h.set_progress(crate::model::Progress::new(move |stage, _| {
        sink.lock().unwrap().push(stage.to_string())
    }));
    assert!(!h.is_whole_organ());
    assert_eq!(h.info().notices().count(), 0);
    // Blades sweeping along the beam just above its top: they cut nothing, but each one
    // near the border grows the region.
    for k in 0..12 {
        let x0 = 0.01 * k as Real;
        let blade = CutPath {
            start: [Vec3::new(x0, 0.015, 0.05), Vec3::new(x0, 0.015, 0.035)],
            end: [
                Vec3::new(x0 + 0.01, 0.015, 0.05),
                Vec3::new(x0 + 0.01, 0.015, 0.035),
            ],
        };
        assert_eq!(h.cut(&blade).unwrap().removed_elements, 0);
        h.step(1e-4).unwrap();
    }
    assert!(h.is_whole_organ(), "region {}", h.region_tets());
    assert_eq!(h.region_tets(), mesh.tets.len());
    assert_eq!(h.interface_nodes(), 0);
    let growths = h.growths().len();
    assert!(growths >= 1);
    let said: Vec<String> = notices.lock().unwrap().clone();
    assert_eq!(said.iter().filter(|n| n.contains("whole-organ")).count(), 1);
    let details = h.info().details;
    assert!(
        details
            .iter()
            .any(|(k, v)| k == "whole_organ" && v.contains("tensor-mass")),
        "{details:?}"
    );
    // The notice `tissue run` lists and the viewer says once.
    let info = h.info();
    let notices: Vec<&str> = info.notices().collect();
    assert!(
        notices.len() == 1 && notices[0].contains("tensor-mass"),
        "{notices:?}"
    );
    // Cutting continues, everywhere, and shrinks nothing.
    let before = h.info().elements;
    let removed = h.cut(&slice(0.065, 0.005, 0.025)).unwrap().removed_elements;
    assert!(removed > 0);
    assert_eq!(h.info().elements, before - removed);
    assert_eq!(h.region_tets(), mesh.tets.len());
    assert_eq!(h.growths().len(), growths);
    assert_closed_oriented(&h);
    // The static equilibrium of the cut organ against fem-static on its surviving tetrahedra.
    let alive = TetMesh::new(
        mesh.vertices.clone(),
        (0..mesh.tets.len())
            .filter(|&t| h.alive[t])
            .map(|t| mesh.tets[t])
            .collect(),
    )
    .compacted();
    let mut reference = FemStatic::new(&alive, material(5.0), Order::Linear).unwrap();
    let rest = h.rest_surface().to_vec();
    let key = |p: &Vec3| p.to_array().map(|c| c.to_bits());
    let index: HashMap<[u64; 3], u32> = reference
        .rest_surface()
        .iter()
        .enumerate()
        .map(|(i, p)| (key(p), i as u32))
        .collect();
    // Vertices the hybrid still numbers but no surviving triangle uses may be missing.
    let map: Vec<Option<u32>> = rest.iter().map(|p| index.get(&key(p)).copied()).collect();
    let fixed: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].x < 1e-9)
        .collect();
    let probe = (0..rest.len() as u32)
        .find(|&v| rest[v as usize].distance(Vec3::new(0.11, 0.03, 0.03)) < 1e-9)
        .unwrap();
    let c = Constraints {
        fixed: fixed.clone(),
        prescribed: vec![Prescribed {
            vertex: probe,
            position: rest[probe as usize] + Vec3::new(0.0, -1e-3, -2e-3),
        }],
    };
    let gravity = Loads {
        gravity: Vec3::new(0.0, 0.0, -9.81),
        point_loads: vec![],
    };
    h.set_loads(&gravity).unwrap();
    h.set_constraints(&c).unwrap();
    settle(&mut h);
    let full: Vec<u32> = map.iter().map(|m| m.unwrap_or(0)).collect();
    reference.set_loads(&gravity).unwrap();
    reference
        .set_constraints(&map_constraints(&c, &full))
        .unwrap();
    reference.step(0.0).unwrap();
    let (ph, pr, rr) = (
        h.surface().positions,
        reference.surface().positions,
        reference.rest_surface(),
    );
    let (mut du, mut scale): (Real, Real) = (0.0, 0.0);
    for (a, b) in map.iter().enumerate() {
        if let Some(b) = *b {
            du = du.max(max_abs((ph[a] - pr[b as usize]).to_array().into_iter()));
            scale = scale.max(max_abs(
                (pr[b as usize] - rr[b as usize]).to_array().into_iter(),
            ));
        }
    }
    let fh: Vec3 = h.reactions().prescribed.iter().copied().sum();
    let fr: Vec3 = reference.reactions().prescribed.iter().copied().sum();
    let dr = (fh - fr).length() / fr.length();
    eprintln!(
        "whole-organ hybrid after {growths} growths and a cut of {removed} tetrahedra: \
         surface {:.1e}, probe force {dr:.1e} from fem-static (relative)",
        du / scale
    );
    assert!(du < 1e-8 * scale, "surface {:e}", du / scale);
    assert!(dr < 1e-8, "probe force {dr:e}");
}

/// In real time a growth is built on its own thread: the old parts answer every step until
/// the new ones land, the steps waited and the build time are recorded.
#[test]
fn a_growth_in_real_time_is_built_off_the_stepping_thread_and_timed() {
    let mesh = beam();
    let params = r#"
        cut_region = "auto"
        auto_radius = 0.03
        auto_seeds = [[0.0, 0.015, 0.03]]
    "#;
    let mut h = hybrid(&mesh, material(5.0), params);
    h.set_real_time(true);
    let before = h.region_tets();
    // A blade just above the top near the region's border: it cuts nothing, but asks for a
    // growth.
    let blade = CutPath {
        start: [Vec3::new(0.04, 0.015, 0.05), Vec3::new(0.04, 0.015, 0.035)],
        end: [Vec3::new(0.05, 0.015, 0.05), Vec3::new(0.05, 0.015, 0.035)],
    };
    assert_eq!(h.cut(&blade).unwrap().removed_elements, 0);
    assert!(h.growth_pending() || !h.growths().is_empty());
    let start = std::time::Instant::now();
    let mut pending_steps = 0;
    while h.growth_pending() {
        assert!(start.elapsed().as_secs() < 120, "the growth never landed");
        assert_eq!(h.region_tets(), before, "the old region answers meanwhile");
        pending_steps += 1;
        h.step(1e-4).unwrap();
    }
    let g = h.growths().to_vec();
    assert_eq!(g.len(), 1);
    assert!(g[0].region_tets > before && g[0].region_tets == h.region_tets());
    assert!(g[0].seconds > 0.0);
    // The step that installed the growth did not wait.
    assert_eq!(g[0].steps_waited, (pending_steps as u64).saturating_sub(1));
    let info = h.info();
    let last: Real = info
        .details
        .iter()
        .find(|(k, _)| k == "last_growth_s")
        .unwrap()
        .1
        .parse()
        .unwrap();
    assert!((last - g[0].seconds).abs() < 1e-4);
    eprintln!(
        "real-time growth {before} -> {} tetrahedra in {:.3} s, {} steps answered by the old \
         region meanwhile",
        g[0].region_tets, g[0].seconds, g[0].steps_waited
    );
    h.step(1e-4).unwrap();
    assert_closed_oriented(&h);
}

/// A free beam (no support, no gravity, no damping), region in the middle, released from a
/// deformed state at rest: the rest's interface forces are internal (S annihilates
/// translations, and is symmetric), so the total momentum of the region's nodes (which carry
/// the rest's mass share at the interface) stays zero while the body vibrates.
#[test]
fn a_free_hybrid_conserves_momentum_across_the_interface() {
    use crate::integrate::ParticleSystem;
    let mesh = beam();
    let params = r#"
        cut_region = { box = { min = [0.04, -1.0, -1.0], max = [0.08, 1.0, 1.0] } }
        integrator = "symplectic-euler"
    "#;
    let mut h = hybrid(&mesh, material(0.0), params);
    let rest = h.region_model().rest_nodes().to_vec();
    let x: Vec<Vec3> = rest
        .iter()
        .map(|p| {
            *p + Vec3::new(
                2e-3 * (60.0 * p.y).sin(),
                1e-3 * (40.0 * p.x).cos(),
                1.5e-3 * (50.0 * p.x + 30.0 * p.z).sin(),
            )
        })
        .collect();
    h.tm.set_state(&x, &vec![Vec3::ZERO; x.len()]).unwrap();
    h.update_state().unwrap();
    let masses = h.tm.system().masses().to_vec();
    let (mut worst, mut scale): (Real, Real) = (0.0, 0.0);
    for _ in 0..300 {
        h.step(1e-4).unwrap();
        let v = h.region_model().velocities();
        let p: Vec3 = v.iter().zip(&masses).map(|(v, &m)| *v * m).sum();
        let s: Real = v.iter().zip(&masses).map(|(v, &m)| v.length() * m).sum();
        worst = worst.max(p.length());
        scale = scale.max(s);
    }
    eprintln!("free hybrid: |Σ m v| / Σ m |v| = {:.1e}", worst / scale);
    assert!(scale > 1e-6, "it did not move: {scale}");
    assert!(worst < 1e-9 * scale, "momentum {worst:e} of {scale:e}");
}
