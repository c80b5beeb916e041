//! Tests of the dynamic model: damping, honest reactions, refusals, the registry.

use super::*;
use crate::integrate::Scheme;
use crate::interact::{Constraints, Loads, Prescribed};
use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::mesh::MeshData;
use crate::model::{BuildInput, Deformable};

fn tube_model(scheme: Scheme, damping: Real) -> SplineModel {
    let mut material = Material::new(2e4, 0.4).unwrap();
    material.damping = damping;
    let params = SplineParams {
        integrator: scheme,
        thickness: 1e-3,
        ..SplineParams::default()
    };
    SplineModel::new(
        SplineSurface::tube(0.01, 0.04, 12, 8).unwrap(),
        material,
        params,
    )
    .unwrap()
}

#[test]
fn energy_decreases_under_damping_with_every_scheme() {
    for (scheme, dt) in [
        (Scheme::ImplicitEuler, 2e-3),
        (Scheme::SymplecticEuler, 1e-4),
        (Scheme::VelocityVerlet, 1e-4),
        (Scheme::Rk4, 1e-4),
    ] {
        let mut m = tube_model(scheme, 50.0);
        // Start squeezed into an ellipse, at rest.
        let x: Vec<Vec3> = m
            .rest_shape()
            .control
            .iter()
            .map(|p| Vec3::new(p.x * 1.1, p.y * 0.9, p.z))
            .collect();
        let v = vec![Vec3::ZERO; x.len()];
        m.set_state(&x, &v).unwrap();
        let total = |m: &SplineModel| m.elastic_energy() + m.kinetic_energy();
        let e0 = total(&m);
        assert!(e0 > 0.0);
        let mut last = e0;
        let steps = if scheme == Scheme::ImplicitEuler {
            50
        } else {
            1000
        };
        for s in 0..steps {
            m.step(dt).unwrap();
            let e = total(&m);
            assert!(e <= last * (1.0 + 1e-9), "{scheme} step {s}: {e} > {last}");
            last = e;
        }
        // Damped to well below the start (α = 50/s over 0.1 s).
        assert!(last < 0.05 * e0, "{scheme}: {last} vs {e0}");
    }
}

#[test]
fn fixed_reactions_balance_the_weight_of_a_hanging_sheet() {
    let mut material = Material::new(1e4, 0.3).unwrap();
    material.damping = 100.0;
    let params = SplineParams {
        integrator: Scheme::ImplicitEuler,
        thickness: 2e-3,
        subdivisions: 2,
        cg_iterations: Some(200),
        cg_tolerance: Some(1e-10),
        ..SplineParams::default()
    };
    let sheet = SplineSurface::flat_patch(0.05, 0.05, 7, 7).unwrap();
    let mut m = SplineModel::new(sheet, material, params).unwrap();
    // Hold the row of surface vertices at y = 0 (a clamped edge held by springs).
    let fixed: Vec<u32> = (0..m.rest_surface().len() as u32)
        .filter(|&v| m.rest_surface()[v as usize].y == 0.0)
        .collect();
    assert_eq!(fixed.len(), 2 * 4 + 1);
    m.set_constraints(&Constraints::fixed(fixed.clone()))
        .unwrap();
    // Gravity pulls the sheet away from its held edge (in its plane: a membrane in tension).
    let g = Vec3::new(0.0, 9.81, 0.0);
    m.set_loads(&Loads {
        gravity: g,
        point_loads: vec![],
    })
    .unwrap();
    for _ in 0..400 {
        m.step(5e-3).unwrap();
    }
    let weight = m.net().total_mass() * g;
    // ρ h A g exactly: the lumped masses sum to the area times ρ h.
    assert!((m.net().total_mass() - 1000.0 * 2e-3 * 0.05 * 0.05).abs() < 1e-12);
    let total: Vec3 = m.reactions().fixed.iter().copied().sum();
    // The tissue pulls its supports along g by its weight.
    assert!(
        total.distance(weight) < 1e-3 * weight.length(),
        "{total} vs {weight}"
    );
    assert!(m.kinetic_energy() < 1e-12);
    // The held vertices stay within |f|/k of their targets.
    let k = m.net().stiffness;
    for (&v, r) in fixed.iter().zip(m.reactions().fixed) {
        let gap = m.surface().positions[v as usize].distance(m.rest_surface()[v as usize]);
        assert!((gap - r.length() / k).abs() < 1e-12 + 1e-9 * gap, "{v}");
    }
}

#[test]
fn a_prescribed_vertex_pushes_back_and_duplicates_share_one_reaction() {
    let mut m = tube_model(Scheme::ImplicitEuler, 20.0);
    let v = (m.rest_surface().len() / 2) as u32;
    let target = m.rest_surface()[v as usize] * Vec3::new(0.8, 0.8, 1.0);
    let c = Constraints {
        fixed: vec![0],
        prescribed: vec![
            Prescribed {
                vertex: v,
                position: target,
            },
            Prescribed {
                vertex: v,
                position: target,
            },
        ],
    };
    m.set_constraints(&c).unwrap();
    for _ in 0..20 {
        m.step(2e-3).unwrap();
    }
    let r = m.reactions();
    assert_eq!(r.prescribed[0], Vec3::ZERO);
    let inward = -(m.rest_surface()[v as usize] * Vec3::new(1.0, 1.0, 0.0)).normalize();
    // Pushed in, the tube pushes the instrument outward.
    assert!(r.prescribed[1].dot(inward) < 0.0, "{}", r.prescribed[1]);
    let bad = Constraints::fixed(vec![u32::MAX]);
    assert!(m.set_constraints(&bad).is_err());
}

#[test]
fn cut_closed_organs_and_bad_settings_are_refused_by_name() {
    let mut m = tube_model(Scheme::SymplecticEuler, 0.0);
    let blade = crate::model::CutPath {
        start: [Vec3::ZERO, Vec3::X],
        end: [Vec3::Y, Vec3::ONE],
    };
    let e = m.cut(&blade).unwrap_err().to_string();
    assert!(e.contains("spline") && e.contains("cutting"), "{e}");

    let liver = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/meshes/liver.obj");
    let mesh = crate::io::read(liver).unwrap();
    let material = Material::new(3000.0, 0.3).unwrap();
    let params = toml::Table::new();
    let input = BuildInput {
        mesh: &mesh,
        source: "liver.obj",
        material,
        params: &params,
        regions: &[],
    };
    let e = crate::model::build("spline", &input)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("liver.obj") && e.contains("genus 0"), "{e}");

    let tube = crate::mesh::generate::tube(0.01, 0.05, 24, 10);
    let mesh = MeshData::from_surface(&tube);
    let params: toml::Table =
        toml::from_str("control = [12, 8]\nintegrator = \"rk4\"\nthickness = 5e-4").unwrap();
    let input = BuildInput {
        mesh: &mesh,
        source: "tube",
        material,
        params: &params,
        regions: &[],
    };
    let m = crate::model::build("spline", &input).unwrap();
    let info = m.info();
    assert_eq!((info.kind, info.nodes), ("spline", 96));
    assert_eq!(info.surface_vertices, 36 * 16);
    for (text, key) in [
        ("control = [100000, 100000]", "control"),
        ("control = [3, 8]", "control"),
        ("thickness = -1.0", "thickness"),
        ("subdivisions = 0", "subdivisions"),
        ("integrator = \"leapfrog\"", "leapfrog"),
    ] {
        let bad: toml::Table = toml::from_str(text).unwrap();
        let input = BuildInput {
            mesh: &mesh,
            source: "tube",
            material,
            params: &bad,
            regions: &[],
        };
        let e = crate::model::build("spline", &input)
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains(key), "{text}: {e}");
    }
    let bad: toml::Table = toml::from_str("thicknes = 1.0").unwrap();
    let input = BuildInput {
        mesh: &mesh,
        source: "tube",
        material,
        params: &bad,
        regions: &[],
    };
    let e = crate::model::build("spline", &input)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("thicknes"), "{e}");
}
