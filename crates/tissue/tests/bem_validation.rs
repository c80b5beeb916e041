//! The BEM against the quadratic-tetrahedron `fem-static` reference on the same body, and its
//! speed on the 2194-vertex liver. The slow parts are `#[ignore]`d and print their numbers:
//! `cargo test --release --offline -p tissue --test bem_validation -- --ignored --nocapture`.

use std::time::Instant;

use tissue::Material;
use tissue::interact::{Constraints, Prescribed};
use tissue::math::{Real, Vec3};
use tissue::mesh::generate::{BoxSplit, box_tets};
use tissue::mesh::{MeshData, TetMesh};
use tissue::model::Deformable;
use tissue::model::bem::{Bem, BemParams};
use tissue::model::fem::{FemStatic, Order};

const LIVER_MSH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/meshes/liver.msh");
const LIVER_SMOOTH: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../assets/meshes/liver-smooth.obj"
);

fn material() -> Material {
    Material::new(3000.0, 0.3).unwrap()
}

/// What an indentation gives: the probe force and the surface displacements.
struct Indent {
    force: Vec3,
    displacements: Vec<Vec3>,
}

fn run(model: &mut dyn Deformable, c: &Constraints) -> Indent {
    model.set_constraints(c).unwrap();
    model.step(0.01).unwrap();
    let s = model.surface();
    let rest = model.rest_surface();
    Indent {
        force: model.reactions().prescribed.iter().copied().sum(),
        displacements: s.positions.iter().zip(rest).map(|(p, r)| *p - *r).collect(),
    }
}

/// Both models on the same tetrahedral body; the BEM on its boundary (same numbering).
/// Returns (BEM, FEM, surface vertices).
fn compare(mesh: &TetMesh, c: &Constraints) -> (Indent, Indent, usize) {
    let surface = MeshData::from_tets(mesh).surface_mesh().unwrap();
    let mut bem = Bem::new(&surface, material(), BemParams::default()).unwrap();
    let mut fem = FemStatic::new(mesh, material(), Order::Quadratic).unwrap();
    assert_eq!(
        bem.rest_surface(),
        fem.rest_surface(),
        "the same surface numbering"
    );
    let n = bem.rest_surface().len();
    (run(&mut bem, c), run(&mut fem, c), n)
}

/// Largest displacement difference over the surface relative to the largest FEM one.
fn displacement_gap(a: &Indent, b: &Indent) -> Real {
    let gap = a
        .displacements
        .iter()
        .zip(&b.displacements)
        .map(|(x, y)| (*x - *y).length())
        .fold(0.0, Real::max);
    gap / b
        .displacements
        .iter()
        .map(|d| d.length())
        .fold(0.0, Real::max)
}

/// A 4 × 4 × 2 cm block on a fixed floor, a 2 cm square punch in the middle of the top
/// pushed 1 mm down (its edges lie on grid lines for every even `cells`).
fn block(cells: usize) -> (TetMesh, Constraints) {
    let (lo, hi) = (Vec3::new(-0.02, -0.02, 0.0), Vec3::new(0.02, 0.02, 0.02));
    let mesh = box_tets(lo, hi, [2 * cells, 2 * cells, cells], BoxSplit::Six);
    let surface = MeshData::from_tets(&mesh).surface_mesh().unwrap();
    let mut c = Constraints::default();
    for (v, p) in surface.vertices.iter().enumerate() {
        if p.z < 1e-9 {
            c.fixed.push(v as u32);
        } else if p.z > 0.02 - 1e-9 && p.x.abs() < 0.01 + 1e-9 && p.y.abs() < 0.01 + 1e-9 {
            c.prescribed.push(Prescribed {
                vertex: v as u32,
                position: *p - Vec3::Z * 0.001,
            });
        }
    }
    (mesh, c)
}

#[test]
fn block_indentation_approaches_quadratic_fem_under_refinement() {
    // Not within 5% on meshes this coarse (see `block_convergence_table`): the BEM is
    // stiffer on a given mesh and the gap shrinks about like h.
    let mut gaps = Vec::new();
    for cells in [2, 4] {
        let (mesh, c) = block(cells);
        let (b, f, n) = compare(&mesh, &c);
        let force_gap = (b.force.z - f.force.z) / f.force.z;
        let disp_gap = displacement_gap(&b, &f);
        eprintln!(
            "block, {n} surface vertices: force BEM {:.4e} N, FEM-P2 {:.4e} N ({:.1}%), displacement gap {:.1}%",
            b.force.z,
            f.force.z,
            100.0 * force_gap,
            100.0 * disp_gap
        );
        assert!(
            b.force.z > 0.0 && f.force.z > 0.0,
            "the tissue pushes the probe up"
        );
        gaps.push((force_gap, disp_gap));
    }
    assert!(gaps[1].0 > 0.0 && gaps[1].0 < 0.6 * gaps[0].0, "{gaps:?}");
    assert!(gaps[1].1 < 0.6 * gaps[0].1, "{gaps:?}");
    assert!(gaps[1].0 < 0.25 && gaps[1].1 < 0.2, "{gaps:?}");
}

#[test]
#[ignore = "slow: a refinement study, prints a table"]
fn block_convergence_table() {
    eprintln!(
        "cells(z) | surface vertices | BEM force (N) | FEM-P2 force (N) | force gap | displacement gap | BEM s"
    );
    for cells in [2, 4, 6, 8] {
        let (mesh, c) = block(cells);
        let start = Instant::now();
        let (b, f, n) = compare(&mesh, &c);
        let gap = (b.force.z - f.force.z).abs() / f.force.z.abs();
        eprintln!(
            "{cells} | {n} | {:.5e} | {:.5e} | {:.2}% | {:.2}% | {:.1}",
            b.force.z,
            f.force.z,
            100.0 * gap,
            100.0 * displacement_gap(&b, &f),
            start.elapsed().as_secs_f64()
        );
    }
}

#[test]
#[ignore = "slow: the liver against quadratic FEM, prints numbers"]
fn liver_indentation_against_quadratic_fem() {
    let data = tissue::io::read(LIVER_MSH).unwrap();
    let mut tets = data.tet_mesh(LIVER_MSH).unwrap();
    tets.vertices.iter_mut().for_each(|p| *p *= 0.01);
    let surface = MeshData::from_tets(&tets).surface_mesh().unwrap();
    // Supports are patches (every surface vertex within 1.2 cm of ligament nodes 3, 39
    // and 64): a single held vertex is a point support whose compliance depends on the mesh
    // (infinite in the continuum), not on the model.
    let mut c = Constraints::default();
    for file_vertex in [3usize, 39, 64] {
        let centre = tets.vertices[file_vertex];
        for (v, p) in surface.vertices.iter().enumerate() {
            if (*p - centre).length() < 0.012 {
                c.fixed.push(v as u32);
            }
        }
    }
    let probe = Vec3::new(-0.005, 0.0555, 0.0067);
    let near: Vec<usize> = (0..surface.vertices.len())
        .filter(|&v| (surface.vertices[v] - probe).length() < 0.012)
        .collect();
    for v in near {
        let p = surface.vertices[v];
        c.prescribed.push(Prescribed {
            vertex: v as u32,
            position: p - Vec3::Y * 0.003,
        });
    }
    assert!(!c.prescribed.is_empty());
    let (b, f, n) = compare(&tets, &c);
    eprintln!(
        "liver.msh, {n} surface vertices, {} held, {} pushed 3 mm: force BEM {:.4e} N, FEM-P2 {:.4e} N ({:.1}%), displacement gap {:.1}%",
        c.fixed.len(),
        c.prescribed.len(),
        b.force.y,
        f.force.y,
        100.0 * (b.force.y - f.force.y).abs() / f.force.y.abs(),
        100.0 * displacement_gap(&b, &f)
    );
}

#[test]
#[ignore = "slow: pre-computation on the 2194-vertex liver (about a minute)"]
fn liver_smooth_speed() {
    let data = tissue::io::read(LIVER_SMOOTH).unwrap();
    let mut surface = data.surface_mesh().unwrap();
    surface.vertices.iter_mut().for_each(|p| *p *= 0.01);
    let start = Instant::now();
    let mut bem = Bem::new(&surface, material(), BemParams::default()).unwrap();
    let assembly = start.elapsed().as_secs_f64();
    let rest = bem.rest_surface().to_vec();
    let n = rest.len();
    // Three supports far apart (lowest x, highest x, lowest z).
    let by = |f: &dyn Fn(&Vec3) -> Real| {
        (0..n)
            .min_by(|&a, &b| f(&rest[a]).total_cmp(&f(&rest[b])))
            .unwrap() as u32
    };
    let fixed = vec![by(&|p| p.x), by(&|p| -p.x), by(&|p| p.z)];
    let start = Instant::now();
    bem.set_constraints(&Constraints::fixed(fixed.clone()))
        .unwrap();
    let factor = start.elapsed().as_secs_f64();
    eprintln!("liver-smooth: {n} vertices, {} dofs", 3 * n);
    eprintln!(
        "assembly of H and G: {assembly:.2} s; LU of A0 and W = A0^-1 G: {factor:.2} s; total {:.2} s",
        assembly + factor
    );
    // 20 contacts around the top-most vertex, then 10 of them replaced.
    let top = by(&|p| -p.y) as usize;
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| {
        (rest[a] - rest[top])
            .length()
            .total_cmp(&(rest[b] - rest[top]).length())
    });
    let set = |vs: &[usize]| Constraints {
        fixed: fixed.clone(),
        prescribed: vs
            .iter()
            .map(|&v| Prescribed {
                vertex: v as u32,
                position: rest[v] - Vec3::Y * 0.002,
            })
            .collect(),
    };
    let first: Vec<usize> = order[..20].to_vec();
    let second: Vec<usize> = order[..10].iter().chain(&order[20..30]).copied().collect();
    bem.set_constraints(&set(&first)).unwrap();
    bem.step(0.01).unwrap();
    let reps = 200;
    let start = Instant::now();
    for _ in 0..reps {
        bem.step(0.01).unwrap();
    }
    let step = start.elapsed().as_secs_f64() / reps as f64;
    let start = Instant::now();
    for k in 0..reps {
        bem.set_constraints(&set(if k % 2 == 0 { &second } else { &first }))
            .unwrap();
    }
    let woodbury = start.elapsed().as_secs_f64() / reps as f64;
    bem.step(0.01).unwrap();
    eprintln!("static update, 20 contacts: {:.3} ms", 1e3 * step);
    eprintln!(
        "contact change of 10 vertices (Woodbury, set_constraints): {:.3} ms",
        1e3 * woodbury
    );
    eprintln!(
        "probe force {:?} N",
        bem.reactions().prescribed.iter().copied().sum::<Vec3>()
    );
}
