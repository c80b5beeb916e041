//! Speed of the hybrid against whole-organ `tensor-mass-nonlinear` on the refined liver
//! (`split_tets` of the shipped one): cost per step, build time and memory at cut regions of
//! about 10, 25 and 50 % of the volume, the surface gap between the two after the same
//! loading, and the time of one automatic region growth. Ignored (long); run with
//! `cargo test --release -p tissue --lib hybrid::tests_speed -- --ignored --nocapture`.

use std::time::Instant;

use super::*;
use crate::integrate::Scheme;
use crate::interact::{Constraints, Prescribed};
use crate::material::Material;
use crate::mesh::{MeshData, TetMesh};
use crate::model::tensor_mass::TensorMass;
use crate::model::{CutPath, Deformable};

fn refined_liver() -> TetMesh {
    let m = crate::io::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/meshes/liver.msh"
    ))
    .unwrap()
    .tet_mesh("liver.msh")
    .unwrap();
    let m = TetMesh::new(m.vertices.iter().map(|v| *v * 0.01).collect(), m.tets);
    crate::mesh::split_tets(&m).unwrap()
}

fn material() -> Material {
    let mut m = Material::new(3000.0, 0.3).unwrap();
    m.damping = 20.0;
    m
}

/// Ligament nodes 3, 39, 64 fixed, the surface vertices within 8 mm of the top of the
/// right lobe pressed 5 mm down: as surface vertices of a model whose surface vertex → node
/// map is `node_of`.
fn constraints(rest: &[Vec3], node_of: impl Fn(usize) -> u32) -> Constraints {
    let mut c = Constraints::default();
    let press = Vec3::new(0.0, 0.045, 0.005);
    for (v, p) in rest.iter().enumerate() {
        if [3, 39, 64].contains(&node_of(v)) {
            c.fixed.push(v as u32);
        } else if p.distance(press) < 0.008 {
            c.prescribed.push(Prescribed {
                vertex: v as u32,
                position: *p + Vec3::new(0.0, -0.005, 0.0),
            });
        }
    }
    c
}

fn sphere_for_fraction(mesh: &TetMesh, centre: Vec3, fraction: Real) -> Real {
    let cents = split::centroids(mesh);
    let total = mesh.volume();
    let (mut lo, mut hi) = (0.0, 0.2);
    for _ in 0..40 {
        let r = 0.5 * (lo + hi);
        let v: Real = (0..mesh.tets.len())
            .filter(|&t| cents[t].distance(centre) <= r)
            .map(|t| mesh.tet_volume(t))
            .sum();
        if v / total < fraction {
            lo = r;
        } else {
            hi = r;
        }
    }
    hi
}

#[test]
#[ignore = "speed study: prints a table"]
fn hybrid_speed_against_whole_organ_tensor_mass() {
    let mesh = refined_liver();
    let data = MeshData::from_tets(&mesh);
    let (dt, steps) = (5e-5, 300);
    println!(
        "refined liver: {} tetrahedra, {} nodes",
        mesh.tets.len(),
        mesh.vertices.len()
    );
    let t0 = Instant::now();
    let mut whole = TensorMass::new(
        &mesh,
        material(),
        Default::default(),
        true,
        Scheme::SymplecticEuler,
    )
    .unwrap();
    let whole_build = t0.elapsed().as_secs_f64();
    let nodes = whole.surface_nodes().to_vec();
    whole
        .set_constraints(&constraints(whole.rest_surface(), |v| nodes[v]))
        .unwrap();
    let t0 = Instant::now();
    for _ in 0..steps {
        whole.step(dt).unwrap();
    }
    let whole_step = t0.elapsed().as_secs_f64() / steps as Real;
    let whole_pos: Vec<(u32, Vec3)> = nodes
        .iter()
        .zip(whole.surface().positions)
        .map(|(&n, &p)| (n, p))
        .collect();
    println!(
        "tensor-mass-nonlinear, whole organ: {:.1} us/step, build {:.3} s, {:.1} MB",
        whole_step * 1e6,
        whole_build,
        whole.info().memory_bytes as Real / 1e6
    );
    println!(
        "fraction | region tets | interface | us/step | speed-up | build s | MB | surface gap"
    );
    let centre = Vec3::new(0.005, 0.04, 0.005);
    for fraction in [0.1, 0.25, 0.5, 0.75] {
        let r = sphere_for_fraction(&mesh, centre, fraction);
        let params: toml::Table = toml::from_str(&format!(
            "cut_region = {{ sphere = {{ center = [{}, {}, {}], radius = {r} }} }}",
            centre.x, centre.y, centre.z
        ))
        .unwrap();
        let mut h = Hybrid::from_input(&BuildInput {
            mesh: &data,
            source: "refined liver",
            material: material(),
            params: &params,
        })
        .unwrap();
        let surf = h.surf_nodes.clone();
        h.set_constraints(&constraints(h.rest_surface(), |v| surf[v]))
            .unwrap();
        let t0 = Instant::now();
        for _ in 0..steps {
            h.step(dt).unwrap();
        }
        let step = t0.elapsed().as_secs_f64() / steps as Real;
        // Surface gap to the whole-organ model after the same loading, relative to the
        // largest displacement.
        let pos = h.surface().positions;
        let mut gap: Real = 0.0;
        let mut size: Real = 0.0;
        for &(n, p) in &whole_pos {
            let v = h.surf_of_node_for_tests(n);
            gap = gap.max(pos[v].distance(p));
            size = size.max(p.distance(mesh.vertices[n as usize]));
        }
        let info = h.info();
        println!(
            "{:.2} | {} | {} | {:.1} | {:.2} | {:.3} | {:.1} | {:.1e}",
            h.region_fraction(),
            h.region_tets(),
            h.interface_nodes(),
            step * 1e6,
            whole_step / step,
            info.precompute_seconds,
            info.memory_bytes as Real / 1e6,
            gap / size
        );
    }
    // One automatic growth: a blade 2 cm from the starting region.
    let params: toml::Table = toml::from_str(
        "cut_region = \"auto\"\nauto_radius = 0.012\nauto_seeds = [[0.01, 0.04, 0.005]]",
    )
    .unwrap();
    let mut h = Hybrid::from_input(&BuildInput {
        mesh: &data,
        source: "refined liver",
        material: material(),
        params: &params,
    })
    .unwrap();
    let before = h.region_tets();
    let x = -0.01;
    h.cut(&CutPath {
        start: [Vec3::new(x, 0.06, 0.005), Vec3::new(x, 0.05, 0.005)],
        end: [
            Vec3::new(x - 0.002, 0.06, 0.005),
            Vec3::new(x - 0.002, 0.05, 0.005),
        ],
    })
    .unwrap();
    let g = h.growths();
    println!(
        "automatic growth: {before} -> {} region tetrahedra in {:.3} s ({} growths)",
        h.region_tets(),
        g.iter().map(|g| g.seconds).sum::<Real>(),
        g.len()
    );
}
