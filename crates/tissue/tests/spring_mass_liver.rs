//! The spring-mass kinds on the liver: accuracy against `fem-static` on the same indentation,
//! and the largest stable time step of each integrator (measured by bisection).
//!
//! `cargo test --release --offline -p tissue --test spring_mass_liver -- --ignored --nocapture`
//! prints both tables.

use tissue::interact::{Constraints, Loads, Prescribed};
use tissue::io;
use tissue::material::Material;
use tissue::math::{Real, Vec3};
use tissue::mesh::MeshData;
use tissue::model::{BuildInput, Deformable, build};

const LIVER: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/meshes/liver.msh");
const LIVER_SMOOTH: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../assets/meshes/liver-smooth.obj"
);

fn scaled(path: &str) -> MeshData {
    let mut m = io::read(path).expect("mesh loads");
    m.vertices.iter_mut().for_each(|v| *v *= 0.01);
    m
}

fn model(kind: &str, mesh: &MeshData, e: Real, table: &str) -> Box<dyn Deformable> {
    model_damped(kind, mesh, e, 0.0, table)
}

fn model_damped(
    kind: &str,
    mesh: &MeshData,
    e: Real,
    friction: Real,
    table: &str,
) -> Box<dyn Deformable> {
    let params: toml::Table = toml::from_str(table).expect("toml");
    let mut material = Material::new(e, 0.3).expect("material");
    material.damping = friction;
    let input = BuildInput {
        mesh,
        source: "liver",
        material,
        params: &params,
        regions: &[],
    };
    build(kind, &input).expect("model builds")
}

/// Ligament vertices (liver.msh nodes 3, 39, 64 found on the surface) and the indentation:
/// the surface vertices within 8 mm of the top point under the probe, pushed 5 mm down.
fn indentation(surface: &[Vec3], mesh: &MeshData) -> Constraints {
    let nearest = |p: Vec3| {
        (0..surface.len())
            .min_by(|&a, &b| {
                (surface[a] - p)
                    .length()
                    .total_cmp(&(surface[b] - p).length())
            })
            .unwrap_or(0) as u32
    };
    let fixed = [3usize, 39, 64]
        .iter()
        .map(|&i| nearest(mesh.vertices[i]))
        .collect();
    let top = nearest(Vec3::new(-0.005, 0.06, 0.0067));
    let centre = surface[top as usize];
    let prescribed = (0..surface.len() as u32)
        .filter(|&v| (surface[v as usize] - centre).length() < 0.008)
        .map(|v| Prescribed {
            vertex: v,
            position: surface[v as usize] + Vec3::new(0.0, -0.005, 0.0),
        })
        .collect();
    Constraints { fixed, prescribed }
}

/// (relative L2 error of surface displacements, relative error of the probe force, force).
fn compare(kind: &str, table: &str) -> (Real, Real, Real) {
    let mesh = scaled(LIVER);
    let mut fem = model("fem-static", &mesh, 3000.0, "");
    let rest = fem.rest_surface().to_vec();
    let c = indentation(&rest, &mesh);
    fem.set_constraints(&c).expect("constraints");
    fem.step(1.0).expect("fem solve");
    let uf: Vec<Vec3> = fem
        .surface()
        .positions
        .iter()
        .zip(&rest)
        .map(|(p, r)| *p - *r)
        .collect();
    let ff: Vec3 = fem.reactions().prescribed.iter().copied().sum();

    let mut springs = model_damped(kind, &mesh, 3000.0, 10.0, table);
    assert_eq!(
        springs.rest_surface().len(),
        rest.len(),
        "{kind}: same surface"
    );
    springs.set_constraints(&c).expect("constraints");
    // Implicit Euler with a long step relaxes to equilibrium in a few dozen steps; a membrane
    // (no transverse stiffness at rest) needs shorter ones: halve on refusal, run 20 s.
    let (mut dt, mut t, mut steps) = (1.0, 0.0, 0);
    while t < 20.0 && steps < 4000 {
        match springs.step(dt) {
            Ok(_) => {
                t += dt;
                steps += 1;
            }
            Err(e) if dt > 1e-4 => {
                let _ = e;
                dt *= 0.5;
            }
            Err(e) => panic!("{kind}: {e}"),
        }
    }
    let us: Vec<Vec3> = springs
        .surface()
        .positions
        .iter()
        .zip(springs.rest_surface())
        .map(|(p, r)| *p - *r)
        .collect();
    let fs: Vec3 = springs.reactions().prescribed.iter().copied().sum();
    let num: Real = us
        .iter()
        .zip(&uf)
        .map(|(a, b)| (*a - *b).length_squared())
        .sum();
    let den: Real = uf.iter().map(|a| a.length_squared()).sum();
    (
        (num / den).sqrt(),
        (fs - ff).length() / ff.length(),
        fs.length(),
    )
}

const IMPLICIT: &str =
    "integrator = \"implicit-euler\"\ncg_iterations = 400\ncg_tolerance = 1e-9\n";

#[test]
fn volumetric_springs_are_within_the_measured_error_of_fem_static() {
    let (du, df, _) = compare("volumetric-spring-mass", IMPLICIT);
    eprintln!("volumetric van Gelder: displacement {du:.3}, force {df:.3}");
    // Measured: 0.691 and 0.447 (see the ignored table for the other kinds).
    assert!(du < 0.75, "{du}");
    assert!(df < 0.5, "{df}");
}

#[test]
#[ignore]
fn table_springs_vs_fem_static() {
    println!("| kind | settings | displacement error | force error | force (N) |");
    println!("|---|---|---|---|---|");
    for (kind, extra) in [
        ("volumetric-spring-mass", ""),
        ("volumetric-spring-mass", "stiffness = \"fitted\""),
        ("volumetric-spring-mass", "pressure = true"),
        ("spring-mass", "pressure = true"),
        ("spring-mass", "pressure = true\nstiffness = \"fitted\""),
        ("spring-mass", ""),
        ("simplex-spring-mass", "pressure = true"),
    ] {
        let (du, df, f) = compare(kind, &format!("{IMPLICIT}{extra}"));
        println!(
            "| {kind} | {} | {du:.3} | {df:.3} | {f:.4} |",
            extra.replace('\n', ", ")
        );
    }
}

/// True when `steps` steps of `dt` with gravity and the ligaments fixed all succeed and no
/// vertex ends more than 10 cm from rest (a slow blow-up the per-step guard lets through).
fn stable(kind: &str, mesh: &MeshData, e: Real, scheme: &str, dt: Real, steps: usize) -> bool {
    let table = format!("integrator = \"{scheme}\"\npressure = true\n");
    let mut m = model(kind, mesh, e, &table);
    let rest = m.rest_surface().to_vec();
    let c = indentation(&rest, mesh);
    if m.set_constraints(&Constraints::fixed(c.fixed)).is_err() {
        return false;
    }
    let g = Loads {
        gravity: Vec3::new(0.0, -9.81, 0.0),
        point_loads: vec![],
    };
    if m.set_loads(&g).is_err() {
        return false;
    }
    (0..steps).all(|_| m.step(dt).is_ok()) && m.surface().positions.iter().all(|p| p.is_finite())
}

/// Bisection in log dt between 1e-7 s and 0.1 s.
fn largest_stable_dt(kind: &str, mesh: &MeshData, e: Real, scheme: &str) -> Real {
    let steps = 500;
    let (mut lo, mut hi) = (1e-7_f64.ln(), 0.1_f64.ln());
    if stable(kind, mesh, e, scheme, hi.exp(), steps) {
        return hi.exp();
    }
    for _ in 0..14 {
        let mid = 0.5 * (lo + hi);
        if stable(kind, mesh, e, scheme, mid.exp(), steps) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo.exp()
}

#[test]
#[ignore]
fn table_largest_stable_time_step() {
    println!("| model | E (Pa) | integrator | largest stable dt (s) |");
    println!("|---|---|---|---|");
    let cases = [
        ("volumetric-spring-mass", LIVER),
        ("spring-mass", LIVER_SMOOTH),
    ];
    for (kind, path) in cases {
        let mesh = scaled(path);
        for e in [3.0e3, 3.0e5] {
            for scheme in [
                "explicit-euler",
                "symplectic-euler",
                "velocity-verlet",
                "rk4",
                "implicit-euler",
            ] {
                let dt = largest_stable_dt(kind, &mesh, e, scheme);
                println!(
                    "| {kind} ({}) | {e:.0} | {scheme} | {dt:.3e} |",
                    path.rsplit('/').next().unwrap_or("")
                );
            }
        }
    }
}

/// Time this thread has spent on a CPU, in s (Linux schedstat), so that the rate is not
/// skewed by other processes sharing the machine; `None` elsewhere.
fn thread_cpu_seconds() -> Option<Real> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: Real = s.split_whitespace().next()?.parse().ok()?;
    Some(ns * 1e-9)
}

#[test]
#[ignore]
fn table_steps_per_cpu_second() {
    use tissue::model::spring_mass::{Kind, SpringModel};
    let mesh = scaled(LIVER_SMOOTH);
    println!("| model | integrator | steps per CPU second | resets after a refused step |");
    println!("|---|---|---|---|");
    for scheme in [
        "explicit-euler",
        "symplectic-euler",
        "velocity-verlet",
        "rk4",
        "implicit-euler",
    ] {
        let table: toml::Table = toml::from_str(&format!(
            "integrator = \"{scheme}\"\npressure = true\ncg_iterations = 20\n"
        ))
        .expect("toml");
        let input = BuildInput {
            mesh: &mesh,
            source: "liver-smooth",
            material: Material {
                damping: 20.0,
                ..Material::new(3000.0, 0.3).expect("material")
            },
            params: &table,
            regions: &[],
        };
        let mut m = SpringModel::from_input(Kind::Surface, &input).expect("model");
        m.set_constraints(&Constraints::fixed(vec![0, 700, 1400]))
            .expect("fixed");
        m.set_loads(&Loads {
            gravity: Vec3::new(0.0, -9.81, 0.0),
            point_loads: vec![],
        })
        .expect("gravity");
        let steps = if scheme == "implicit-euler" {
            500
        } else {
            3000
        };
        let t0 = thread_cpu_seconds().unwrap_or(0.0);
        let mut resets = 0;
        for _ in 0..steps {
            // Explicit Euler drifts even when damped: start over if the guard refuses a step.
            if m.step(1e-5).is_err() {
                m.reset();
                resets += 1;
            }
        }
        let t1 = thread_cpu_seconds().unwrap_or(1.0);
        println!(
            "| spring-mass liver-smooth.obj | {scheme} | {:.0} | {resets} |",
            steps as Real / (t1 - t0)
        );
    }
}
