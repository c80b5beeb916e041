//! Per-region materials (`material::regions`) checked against physics on every kind that
//! honours them: two layers in series, a stiff inclusion under a probe, and an inclusion of
//! the organ's own material that must change nothing.

use crate::interact::{Constraints, Prescribed};
use crate::material::{Material, RegionMaterial};
use crate::math::{Real, Vec3};
use crate::mesh::generate::{BoxSplit, box_tets};
use crate::mesh::{MeshData, TetMesh};
use crate::model::{BuildInput, Deformable, REGION_KINDS, build};

/// A box of `cells`, each tetrahedron tagged by `tag(centroid)`.
fn tagged_box(max: Vec3, cells: [usize; 3], tag: impl Fn(Vec3) -> i32) -> MeshData {
    let mesh = box_tets(Vec3::ZERO, max, cells, BoxSplit::Five);
    let tags = (0..mesh.tets.len())
        .map(|t| tag(mesh.corners(t).iter().sum::<Vec3>() / 4.0))
        .collect();
    MeshData {
        tet_tags: tags,
        ..MeshData::from_tets(&TetMesh::new(mesh.vertices, mesh.tets))
    }
}

fn model(
    kind: &str,
    mesh: &MeshData,
    material: Material,
    regions: &[RegionMaterial],
) -> Box<dyn Deformable> {
    let params = toml::Table::new();
    let input = BuildInput {
        mesh,
        source: "region test",
        material,
        params: &params,
        regions,
    };
    build(kind, &input).unwrap_or_else(|e| panic!("{kind}: {e}"))
}

/// The bottom face (z = 0) fixed, the surface vertices with `pressed(rest)` moved down by
/// `delta`. Steps `steps` times by `dt` and returns the force the pressed vertices need
/// (N, positive pushing down), and the surface positions.
fn press(
    m: &mut dyn Deformable,
    pressed: impl Fn(Vec3) -> bool,
    delta: Real,
    steps: usize,
    dt: Real,
) -> (Real, Vec<Vec3>) {
    let rest = m.rest_surface().to_vec();
    let fixed = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].z <= 1e-12)
        .collect();
    let prescribed = (0..rest.len() as u32)
        .filter(|&v| pressed(rest[v as usize]))
        .map(|v| Prescribed {
            vertex: v,
            position: rest[v as usize] - Vec3::Z * delta,
        })
        .collect();
    m.set_constraints(&Constraints { fixed, prescribed })
        .unwrap_or_else(|e| panic!("{e}"));
    for _ in 0..steps {
        m.step(dt).unwrap_or_else(|e| panic!("{e}"));
    }
    let force: Vec3 = m.reactions().prescribed.iter().copied().sum();
    (force.z.abs(), m.surface().positions.to_vec())
}

/// Steps (and step length) that settle each kind's response to a pressed face: the static
/// kinds (and the two condensed from `fem-static`) solve once; the dynamic ones, damped (α = 30/s), settle to 1e-7 of it (explicit:
/// central differences at its own stable substeps).
fn settling(kind: &str) -> (usize, Real) {
    match kind {
        "fem-static" | "fem-condensed" | "fem-precomputed-tensors" => (1, 0.01),
        "fem-explicit" => (1500, 1e-3),
        _ => (300, 0.01),
    }
}

/// A 20 × 20 × 40 mm block, its lower 15 mm E₁ = 10 kPa (tag 1, the default material), its
/// upper 25 mm E₂ = 1 kPa (tag 2, a region), ν = 0, compressed along z by 1 % of its
/// height between its bottom (fixed) and top (moved) faces. With ν = 0 the uniaxial stress
/// state needs no lateral force and the layers do not pull on each other sideways, so the
/// block is exactly two springs in series, k = A / (L₁/E₁ + L₂/E₂), and the displacement is
/// linear in z within each layer: linear tetrahedra whose faces hold the interface (a grid
/// plane) represent it exactly, so fem-static matches to round-off. The dynamic kinds reach
/// the same equilibrium after settling; corotational elements are linear ones here (a pure
/// stretch has no rotation).
#[test]
fn two_layers_under_compression_are_two_springs_in_series() {
    let (e1, e2) = (1.0e4, 1.0e3);
    let (side, height, plane) = (0.02, 0.04, 0.015);
    let mesh = tagged_box(Vec3::new(side, side, height), [4, 4, 8], |c| {
        1 + i32::from(c.z > plane)
    });
    let stiff = Material {
        damping: 30.0,
        ..Material::new(e1, 0.0).unwrap()
    };
    let soft = RegionMaterial {
        name: "soft".into(),
        tag: 2,
        material: Material {
            young_modulus: e2,
            ..stiff
        },
    };
    let delta = 0.01 * height;
    let series = side * side / (plane / e1 + (height - plane) / e2);
    let one = side * side * e1 / height;
    for kind in REGION_KINDS {
        let (steps, dt) = settling(kind);
        let mut m = model(kind, &mesh, stiff, std::slice::from_ref(&soft));
        let (f, _) = press(m.as_mut(), |p| p.z >= height - 1e-12, delta, steps, dt);
        let error = f / delta / series - 1.0;
        println!(
            "{kind}: k = {:.9e} N/m, series {series:.9e} N/m ({error:+.2e}); one material \
             would give {one:.4e}",
            f / delta
        );
        // Round-off for the direct solves (measured 2e-14 at most); the explicit kind
        // settles as e^(−αt/2) over 1.5 s (measured 3.5e-10).
        let tolerance = if *kind == "fem-explicit" { 1e-8 } else { 1e-12 };
        assert!(error.abs() < tolerance, "{kind}: {error:e}");
    }
}

/// A stiff inclusion (a 10 × 10 × 10 mm cube, 10× the organ's E) under the middle of a
/// 40 × 40 × 20 mm block: a flat punch (the top vertices within 5 mm of the middle, pressed
/// 1 mm) needs more force over it than over the plain organ, and a punch at a corner, far
/// from it, nearly the same. An inclusion of the organ's own material changes no bit.
#[test]
fn a_stiff_inclusion_stiffens_the_probe_above_it_and_a_same_material_one_changes_nothing() {
    let organ = Material {
        damping: 30.0,
        ..Material::new(3000.0, 0.45).unwrap()
    };
    let inclusion = |c: Vec3| {
        let inside = (c - Vec3::new(0.02, 0.02, 0.01)).abs().max_element() < 0.005;
        1 + i32::from(inside)
    };
    let mesh = tagged_box(Vec3::new(0.04, 0.04, 0.02), [8, 8, 4], inclusion);
    let region = |e: Real| RegionMaterial {
        name: "tumor".into(),
        tag: 2,
        material: Material {
            young_modulus: e,
            ..organ
        },
    };
    let above =
        |p: Vec3| p.z >= 0.02 - 1e-12 && (p - Vec3::new(0.02, 0.02, 0.02)).length() < 0.0051;
    let corner = |p: Vec3| p.z >= 0.02 - 1e-12 && (p - Vec3::new(0.0, 0.0, 0.02)).length() < 0.0051;
    for kind in REGION_KINDS {
        let (steps, dt) = settling(kind);
        let run = |regions: &[RegionMaterial], at: &dyn Fn(Vec3) -> bool| {
            let mut m = model(kind, &mesh, organ, regions);
            press(m.as_mut(), at, 0.001, steps, dt)
        };
        let (plain, plain_x) = run(&[], &above);
        let (same, same_x) = run(&[region(organ.young_modulus)], &above);
        assert_eq!(plain.to_bits(), same.to_bits(), "{kind}");
        assert_eq!(plain_x, same_x, "{kind}");
        let (stiff, _) = run(&[region(10.0 * organ.young_modulus)], &above);
        let (plain_far, _) = run(&[], &corner);
        let (stiff_far, _) = run(&[region(10.0 * organ.young_modulus)], &corner);
        println!(
            "{kind}: punch over the inclusion {stiff:.4e} N against {plain:.4e} N plain \
             ({:+.1} %); at a corner {stiff_far:.4e} N against {plain_far:.4e} N ({:+.2} %)",
            100.0 * (stiff / plain - 1.0),
            100.0 * (stiff_far / plain_far - 1.0)
        );
        assert!(stiff > 1.1 * plain, "{kind}");
        assert!(
            stiff_far >= plain_far && stiff_far < 1.02 * plain_far,
            "{kind}"
        );
    }
}

/// Each element's density: a block whose upper half (a region) is three times denser,
/// bottom held, under gravity: the held face carries the weight of both halves,
/// g (ρ₁ V₁ + ρ₂ V₂), on every kind once settled (the static kinds through each element's
/// body load, the dynamic ones through each element's share of the lumped masses).
#[test]
fn the_held_face_carries_each_regions_weight() {
    use crate::interact::Loads;
    let (side, height) = (0.02, 0.04);
    let mesh = tagged_box(Vec3::new(side, side, height), [2, 2, 4], |c| {
        1 + i32::from(c.z > 0.5 * height)
    });
    let light = Material {
        damping: 30.0,
        ..Material::new(3000.0, 0.3).unwrap()
    };
    let heavy = RegionMaterial {
        name: "2".into(),
        tag: 2,
        material: Material {
            density: 3000.0,
            ..light
        },
    };
    let g = 9.81;
    let weight = g * 0.5 * side * side * height * (1000.0 + 3000.0);
    for kind in REGION_KINDS {
        let (steps, dt) = settling(kind);
        let mut m = model(kind, &mesh, light, std::slice::from_ref(&heavy));
        let rest = m.rest_surface().to_vec();
        let fixed = (0..rest.len() as u32)
            .filter(|&v| rest[v as usize].z <= 1e-12)
            .collect();
        m.set_constraints(&Constraints::fixed(fixed))
            .unwrap_or_else(|e| panic!("{e}"));
        m.set_loads(&Loads {
            gravity: Vec3::new(0.0, 0.0, -g),
            point_loads: Vec::new(),
        })
        .unwrap_or_else(|e| panic!("{e}"));
        for _ in 0..steps {
            m.step(dt).unwrap_or_else(|e| panic!("{e}"));
        }
        let held: Vec3 = m.reactions().fixed.iter().copied().sum();
        let error = held.z.abs() / weight - 1.0;
        println!(
            "{kind}: held {:.9e} N, weight {weight:.9e} N ({error:+.1e})",
            held.z.abs()
        );
        let tolerance = if *kind == "fem-explicit" { 1e-8 } else { 1e-12 };
        assert!(error.abs() < tolerance, "{kind}: {error:e}");
    }
}
