//! How the dynamic kinds settle in the comparison's probe indentation (issue 20).

use super::Settings;
use super::drive::{
    ContactLaw, Settled, Stepping, indent, probe_instrument, probe_simulation, touching_probe,
};
use super::measure::{relaxing, settling, stable_step};
use super::setup::{Organ, Scenario};
use crate::material::Material;
use crate::math::{Real, Vec3};

fn liver() -> (Organ, Scenario) {
    let mut mesh = crate::io::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/meshes/liver.msh"
    ))
    .unwrap();
    for v in &mut mesh.vertices {
        *v *= 0.01;
    }
    let material = Material::new(3000.0, 0.3).unwrap();
    let organ = Organ::new(mesh, "liver".into(), material, 0.0, 800).unwrap();
    let sc = Scenario::of(&organ.mesh).unwrap();
    (organ, sc)
}

fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The shallow (or `DEPTH`=deep) indentation of `KINDS` (default fem-explicit, tensor-mass)
/// with the probe's ramp of `--quick` and `T_END` s of hold, mass damping `DAMPING` times the
/// comparison's settling damping: the probe force and the surface's kinetic energy (each
/// surface vertex given an equal share of the organ's mass) over time, beside `fem-static`'s.
#[test]
#[ignore = "study: prints the force and kinetic energy over time"]
fn settling_study() {
    let (organ, sc) = liver();
    let s = Settings::quick();
    let kinds: String = env_or("KINDS", "fem-explicit,tensor-mass".to_string());
    let factor: Real = env_or("DAMPING", 1.0);
    let t_end: Real = env_or("T_END", 3.0);
    let deep = std::env::var("DEPTH").is_ok_and(|d| d == "deep");
    let depth = if deep { sc.deep } else { sc.shallow };
    let base = settling(organ.material, &sc);
    println!(
        "settling damping 2ω = {:.2} /s, height {:.4} m, depth {depth:.4e} m",
        base.damping, sc.height
    );
    let st_static = Stepping {
        contact: ContactLaw::FineSurface,
        ..Stepping::new(true, 1.0, &s)
    };
    let model = organ.build("fem-static", base).unwrap();
    let fixed = sc.fixed(model.rest_surface());
    let (st, _) = indent(model, fixed, sc.probe(), sc.probe_radius, depth, &st_static).unwrap();
    println!("fem-static: {:.5e} N", st.value);
    let mass = organ.material.density * sc.volume;
    for kind in kinds.split(',') {
        let mat = Material {
            damping: factor * base.damping,
            ..base
        };
        let stable = stable_step(kind, &organ, &sc, base, ContactLaw::FineSurface, &s).unwrap();
        let dt = (0.5 * stable).min(s.run_dt_max);
        let model = organ.build(kind, mat).unwrap();
        let fixed = sc.fixed(model.rest_surface());
        let mut sim =
            probe_simulation(model, fixed, sc.probe_radius, ContactLaw::FineSurface).unwrap();
        sim.add_instrument(
            probe_instrument(
                sc.probe(),
                sc.probe_radius,
                depth,
                s.ramp,
                ContactLaw::FineSurface,
            )
            .unwrap(),
        );
        let n = sim.model().surface().positions.len();
        let m_v = mass / n as Real;
        let mut prev: Vec<Vec3> = sim.model().surface().positions.to_vec();
        let steps = (t_end / dt).ceil() as usize;
        let every = ((0.025 / dt).round() as usize).max(1);
        println!(
            "{kind}: stable {stable:.3e} s, dt {dt:.3e} s, damping {:.2} /s",
            mat.damping
        );
        let relax = std::env::var("KINETIC").is_ok();
        let mut last = 0.0;
        for k in 1..=steps {
            sim.step(dt).unwrap();
            if relax {
                let e = sim.model().kinetic_energy().unwrap();
                if e < last {
                    sim.model_mut().stop_motion();
                    last = 0.0;
                } else {
                    last = e;
                }
            }
            let now = sim.model().surface().positions;
            if k % every == 0 {
                let ke: Real = now
                    .iter()
                    .zip(&prev)
                    .map(|(a, b)| 0.5 * m_v * (*a - *b).length_squared() / (dt * dt))
                    .sum();
                let f = sim.instrument_forces()[0].y;
                println!(
                    "  t {:.3} s  F {f:.5e} N  F/F_static {:.3}  KE {ke:.3e} J",
                    k as Real * dt,
                    f / st.value
                );
            }
            prev.copy_from_slice(now);
        }
    }
}

/// One kind's settled shallow or deep indentation as the comparison runs it (`--quick`'s
/// ramp, time limit and step; kinetic damping where the kind has velocities), and its
/// surface displacement field.
fn settle(
    kind: &str,
    organ: &Organ,
    sc: &Scenario,
    depth: Real,
) -> Result<(Settled, Vec<Vec3>), crate::error::Error> {
    let q = Settings::quick();
    let s = Settings {
        settle_time: env_or("SETTLE_TIME", q.settle_time),
        settle_dt_max: env_or("SETTLE_DT_MAX", q.settle_dt_max),
        ..q
    };
    let base = settling(organ.material, sc);
    let probe = organ.build(kind, base).unwrap();
    let info = probe.info();
    let has_motion = !info.is_static && probe.kinetic_energy().is_some();
    let dt = if info.is_static {
        1.0
    } else {
        let stable = stable_step(kind, organ, sc, base, ContactLaw::FineSurface, &s).unwrap();
        (0.5 * stable).min(s.settle_dt_max)
    };
    let st = Stepping {
        contact: ContactLaw::FineSurface,
        kinetic_damping: has_motion,
        ..Stepping::new(info.is_static, dt, &s)
    };
    let st = Stepping {
        window: env_or("WINDOW", st.window),
        rest_energy: env_or("REST_ENERGY", st.rest_energy),
        ..st
    };
    let model = organ.build(kind, relaxing(base, &st)).unwrap();
    let fixed = sc.fixed(model.rest_surface());
    let (settled, sim) = indent(model, fixed, sc.probe(), sc.probe_radius, depth, &st)?;
    let m = sim.model();
    let field = m
        .surface()
        .positions
        .iter()
        .zip(m.rest_surface())
        .map(|(p, r)| *p - *r)
        .collect();
    Ok((settled, field))
}

/// RMS of a − b over the RMS of b (fields on the same surface vertices).
fn field_error(a: &[Vec3], b: &[Vec3]) -> Real {
    assert_eq!(a.len(), b.len());
    let d: Real = a
        .iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length_squared())
        .sum();
    let n: Real = b.iter().map(|y| y.length_squared()).sum();
    (d / n.max(1e-300)).sqrt()
}

/// The settled indentations of `KINDS` (default every dynamic kind) shallow and deep, with
/// the comparison's kinetic damping: force, whether settled, steps, motion stops, and the
/// force and displacement field against `fem-static` (linear, same mesh, same fine points).
#[test]
#[ignore = "study: every dynamic kind's settled indentation against fem-static"]
fn kinetic_damping_study() {
    let (organ, sc) = liver();
    let kinds: String = env_or(
        "KINDS",
        "fem-explicit,fem-semi-implicit,fem-corotational,tensor-mass,tensor-mass-nonlinear,\
         hybrid,spring-mass,simplex-spring-mass,volumetric-spring-mass,linked-volumes"
            .to_string(),
    );
    for (name, depth) in [("shallow", sc.shallow), ("deep", sc.deep)] {
        let (st, field_static) = settle("fem-static", &organ, &sc, depth).unwrap();
        println!("{name}: fem-static {:.5e} N", st.value);
        for kind in kinds.split(',') {
            let t = std::time::Instant::now();
            let (d, field) = match settle(kind, &organ, &sc, depth) {
                Ok(r) => r,
                Err(e) => {
                    println!("  {kind}: {e}");
                    continue;
                }
            };
            println!(
                "  {kind}: {:.5e} N ({:+.3} % of fem-static's), field {:.3} % off, settled \
                 {} after {} steps, {} motion stops, {:.2} s",
                d.value,
                100.0 * (d.value / st.value - 1.0),
                100.0 * field_error(&field, &field_static),
                d.settled,
                d.steps,
                d.motion_stops,
                t.elapsed().as_secs_f64()
            );
        }
    }
}

/// Settling methods side by side on `KINDS` (default fem-explicit, tensor-mass), shallow and
/// deep: `METHODS` is a list of `kinetic:damping_factor:ramp_shape:ramp_s` (kinetic 0/1; the
/// mass damping as a multiple of `settling`'s 2ω; ramp shape `lin` or `smooth`, the
/// smoothstep 3s² − 2s³). Prints, per method, when the probe force comes and stays within
/// 1 % and 0.2 % of `fem-static`'s, and its value at 0.6 s and at `T_END`.
#[test]
#[ignore = "study: settling methods compared"]
fn settling_methods_study() {
    let (organ, sc) = liver();
    let s = Settings::quick();
    let kinds: String = env_or("KINDS", "fem-explicit,tensor-mass".to_string());
    let methods: String = env_or(
        "METHODS",
        "0:1:lin:0.15,0:0.3:lin:0.15,1:0:lin:0.15,1:0:smooth:0.15,0:0.3:smooth:0.15,1:0.3:smooth:0.15"
            .to_string(),
    );
    let t_end: Real = env_or("T_END", 1.5);
    let base = settling(organ.material, &sc);
    for (name, depth) in [("shallow", sc.shallow), ("deep", sc.deep)] {
        let st_static = Stepping {
            contact: ContactLaw::FineSurface,
            ..Stepping::new(true, 1.0, &s)
        };
        let model = organ.build("fem-static", base).unwrap();
        let fixed = sc.fixed(model.rest_surface());
        let (fs, _) = indent(model, fixed, sc.probe(), sc.probe_radius, depth, &st_static).unwrap();
        println!("{name}: fem-static {:.5e} N", fs.value);
        for kind in kinds.split(',') {
            let stable = stable_step(kind, &organ, &sc, base, ContactLaw::FineSurface, &s).unwrap();
            let dt = (0.5 * stable).min(s.run_dt_max);
            for method in methods.split(',') {
                let p: Vec<&str> = method.split(':').collect();
                let kinetic = p[0] == "1";
                let factor: Real = p[1].parse().unwrap();
                let smooth = p[2] == "smooth";
                let ramp: Real = p[3].parse().unwrap();
                let mat = Material {
                    damping: factor * base.damping,
                    ..base
                };
                let model = organ.build(kind, mat).unwrap();
                let mut sim = touching_probe(model, &sc, ContactLaw::FineSurface).unwrap();
                let top = sc.probe() + Vec3::Y * sc.probe_radius;
                let steps = (t_end / dt).ceil() as usize;
                let mut last = 0.0;
                let mut stops = 0;
                let mut hist: Vec<(Real, Real)> = Vec::new();
                for k in 1..=steps {
                    let t = k as Real * dt;
                    let x = (t / ramp).min(1.0);
                    let f = if smooth { x * x * (3.0 - 2.0 * x) } else { x };
                    sim.set_instrument_position(0, Some(top - Vec3::Y * (f * depth)))
                        .unwrap();
                    sim.step(dt).unwrap();
                    if kinetic {
                        let e = sim.model().kinetic_energy().unwrap();
                        if e < last {
                            sim.model_mut().stop_motion();
                            stops += 1;
                            last = 0.0;
                        } else {
                            last = e;
                        }
                    }
                    hist.push((t, sim.instrument_forces()[0].y / fs.value));
                }
                let stays = |tol: Real| {
                    hist.iter()
                        .rposition(|(_, r)| (r - 1.0).abs() > tol)
                        .map_or(0.0, |i| hist.get(i + 1).map_or(Real::INFINITY, |h| h.0))
                };
                let at = |t: Real| {
                    hist.iter()
                        .find(|(u, _)| *u >= t - 1e-9)
                        .map_or(Real::NAN, |h| h.1)
                };
                println!(
                    "  {kind} dt {dt:.1e} [{method}]: within 1 % from {:.3} s, 0.2 % from {:.3} s; \
                     F/F_static at 0.6 s {:.4}, at {t_end} s {:.4}; {stops} stops",
                    stays(0.01),
                    stays(0.002),
                    at(0.6),
                    at(t_end)
                );
            }
        }
    }
}

/// The comparison's settling on the built-in liver (`--quick`'s ramp, step and time limit;
/// kinetic damping, `drive::run`; the fine contact surface of `drive::fine_levels`, k = 3
/// here), checked against physics. Linear `fem-explicit`, `fem-semi-implicit` and
/// `tensor-mass` with the fine points solve the same frictionless problem on the same mesh
/// as linear `fem-static` (a convex problem: one equilibrium), by a different route
/// (dynamics to rest against a static solve): each settles, and its probe force and surface
/// displacement field agree with `fem-static`'s within 1 % (measured at k = 3, session 19:
/// shallow at most 0.06 % and 0.05 %; at k = 1, 0.053 % and 0.015 %; session 20, the points
/// projected exactly, deep at most 0.011 % and 0.004 %). At k = 3 the deep press of
/// `fem-explicit` and `tensor-mass` settles only with the points projected exactly
/// (`integrate::PointProjection`; the Gauss-Seidel sweeps stopped at their cap on every
/// substep and the pushed set flickered). At the shallow depth the
/// nonlinear kinds settle within 25 % of their linear twins' force (measured at k = 3:
/// `fem-corotational` 19.4 % below `fem-explicit`, `tensor-mass-nonlinear` 21.3 % below
/// `tensor-mass`; at k = 1 12.0 % and 13.6 %): the shallow press pushes two fine points
/// within 3 mm of the liver's highest vertex, a cone point, a near point load whose strains
/// next to it are large, and the finer surface resolves it better. The shallow and the deep
/// press are two tests, so that they run side by side.
fn dynamic_kinds_settle_to_the_static_equilibrium(deep: bool) {
    let (organ, sc) = liver();
    let (name, depth) = if deep {
        ("deep", sc.deep)
    } else {
        ("shallow", sc.shallow)
    };
    let (st, field_static) = settle("fem-static", &organ, &sc, depth).unwrap();
    let mut linear = Vec::new();
    for kind in ["fem-explicit", "fem-semi-implicit", "tensor-mass"] {
        let (d, field) = settle(kind, &organ, &sc, depth).unwrap();
        let force = d.value / st.value - 1.0;
        let field = field_error(&field, &field_static);
        println!(
            "{name} {kind}: {:.5e} N against {:.5e} N ({:+.3} %), field {:.3} % off, \
             {} steps, {} motion stops",
            d.value,
            st.value,
            100.0 * force,
            100.0 * field,
            d.steps,
            d.motion_stops
        );
        assert!(d.settled && d.motion_stops > 0, "{kind} {name}: {d:?}");
        assert!(force.abs() < 0.01 && field < 0.01, "{kind} {name}");
        linear.push(d.value);
    }
    if !deep {
        for (kind, twin) in [("fem-corotational", 0), ("tensor-mass-nonlinear", 2)] {
            let (d, _) = settle(kind, &organ, &sc, depth).unwrap();
            let off = d.value / linear[twin] - 1.0;
            println!(
                "{name} {kind}: {:.5e} N, {:+.2} % of its linear twin, settled {}",
                d.value,
                100.0 * off,
                d.settled
            );
            assert!(off.abs() < 0.25, "{kind}: {d:?}");
            assert!(d.settled, "{kind}: {d:?}");
        }
    }
}

#[test]
fn the_dynamic_kinds_settle_to_the_static_equilibrium() {
    dynamic_kinds_settle_to_the_static_equilibrium(false);
}

/// Deep at k = 3 `fem-explicit` and `tensor-mass` did not settle with the projection's
/// Gauss-Seidel sweeps (capped on every substep: 0.96 % and 0.02 % off `fem-static`, moving,
/// at 1.5 s); projected exactly they settle (session 20: +0.011 % and +0.009 %, 1846 and
/// 1933 steps), the energy ledger counting the projection's own work (docs/compare.md,
/// "Session 20").
#[test]
fn the_dynamic_kinds_settle_to_the_static_equilibrium_deep() {
    dynamic_kinds_settle_to_the_static_equilibrium(true);
}

/// `Deformable::stop_motion` on every kind that reports a kinetic energy: after a few steps
/// under gravity (the bottom held) the energy is positive; stopped, it is zero, the surface
/// has not moved, and the next step goes on from rest (its kinetic energy is that of one
/// step's acceleration, below the moving state's). Kinds without velocities say so (false).
#[test]
fn stop_motion_zeroes_the_kinetic_energy_and_keeps_the_positions() {
    use crate::interact::{Constraints, Loads};
    let (organ, sc) = liver();
    let mat = settling(organ.material, &sc);
    for info in crate::model::KINDS {
        let Ok(mut m) = organ.build(info.name, mat) else {
            continue;
        };
        let fixed = sc.fixed(m.rest_surface());
        m.set_constraints(&Constraints::fixed(fixed)).unwrap();
        m.set_loads(&Loads {
            gravity: Vec3::new(0.0, -9.81, 0.0),
            point_loads: Vec::new(),
        })
        .unwrap();
        let dt = 1e-3;
        for _ in 0..5 {
            m.step(dt).unwrap();
        }
        let Some(moving) = m.kinetic_energy() else {
            assert!(!m.stop_motion(), "{}", info.name);
            continue;
        };
        let before: Vec<Vec3> = m.surface().positions.to_vec();
        assert!(moving > 0.0, "{}: {moving}", info.name);
        assert!(m.stop_motion(), "{}", info.name);
        assert_eq!(m.kinetic_energy(), Some(0.0), "{}", info.name);
        assert_eq!(m.surface().positions, &before[..], "{}", info.name);
        m.step(dt).unwrap();
        let restarted = m.kinetic_energy().unwrap();
        println!(
            "{}: {moving:.3e} J moving, {restarted:.3e} J one step after the stop",
            info.name
        );
        assert!(restarted > 0.0 && restarted < moving, "{}", info.name);
    }
}

/// One kind's plate compression at ν = 0.45 as the comparison runs it (`--quick`'s ramp,
/// time limit and step; kinetic damping where the kind has velocities): the relative volume
/// change, whether it settled, and how the plate held the vertices.
fn plate(
    kind: &str,
    organ: &Organ,
    sc: &Scenario,
) -> Result<(Real, bool, super::drive::PlateHold), crate::error::Error> {
    let q = Settings::quick();
    let s = Settings {
        settle_dt_max: env_or("SETTLE_DT_MAX", q.settle_dt_max),
        ..q
    };
    let base = settling(organ.material, sc);
    let probe = organ.build(kind, base)?;
    let info = probe.info();
    let has_motion = !info.is_static && probe.kinetic_energy().is_some();
    let dt = if info.is_static {
        1.0
    } else {
        let stable = stable_step(kind, organ, sc, base, ContactLaw::FineSurface, &s).unwrap();
        (0.5 * stable).min(s.settle_dt_max)
    };
    let st = Stepping {
        contact: ContactLaw::FineSurface,
        kinetic_damping: has_motion,
        ..Stepping::new(info.is_static, dt, &s)
    };
    let mat = Material {
        poisson_ratio: 0.45,
        ..relaxing(base, &st)
    };
    let (dv, _, settled, how) = super::measure::compression(kind, organ, sc, mat, &st)?;
    Ok((dv, settled, how))
}

/// The plate is one boundary condition for every kind that can hold it so (issue 20): its
/// vertices held along y both ways, free across, as the reference holds them. Linear
/// `fem-explicit`, `fem-semi-implicit` and `tensor-mass` then solve the same linear problem
/// on the same mesh as linear `fem-static`, by dynamics to rest: each settles, holds the
/// plate two-sided, and its volume change agrees with `fem-static`'s (measured: +1.2299 %,
/// +1.2298 %, +1.2299 % against +1.2298 %, within 0.009 % of it; asserted 0.5 %). With the
/// push-only plate they held before, they swelled by 8.8 % where `fem-static` gives 1.23 %.
#[test]
fn the_plate_is_the_same_problem_for_a_static_and_a_dynamic_linear_kind() {
    use super::drive::PlateHold;
    let (organ, sc) = liver();
    let (dv_static, settled, how) = plate("fem-static", &organ, &sc).unwrap();
    println!(
        "fem-static: volume change {:+.4} %, {how:?}",
        100.0 * dv_static
    );
    assert!(settled && how == PlateHold::TwoSided);
    assert!(dv_static.abs() > 1e-3, "{dv_static}");
    for kind in ["fem-explicit", "fem-semi-implicit", "tensor-mass"] {
        let (dv, settled, how) = plate(kind, &organ, &sc).unwrap();
        let off = dv / dv_static - 1.0;
        println!(
            "{kind}: volume change {:+.4} % ({:+.3} % of fem-static's), settled {settled}, {how:?}",
            100.0 * dv,
            100.0 * off
        );
        assert_eq!(how, PlateHold::TwoSided, "{kind}");
        assert!(settled, "{kind}");
        assert!(off.abs() < 0.005, "{kind}: {dv} against {dv_static}");
    }
}

/// The comparison's quasi-static run of `KINDS` traced (`--quick`'s step, smooth ramp and
/// time limit, kinetic damping, no mass damping): every `EVERY` s (0.05) the watched
/// quantity, the model's kinetic energy over its peak so far, the motion stops, the
/// surface vertex that moved most over the interval (its rest height and its move), and
/// for the probe the pressed vertex's fall. `RUN=shallow|deep|plate|plate-push` (the
/// plate at ν = 0.45: two-sided, or with push-only contacts as before); `SETTLE_DT_MAX`.
#[test]
#[ignore = "study: traces the settling of the comparison's runs"]
fn settling_trace_study() {
    use super::drive::smooth_ramp;
    use super::setup::nearest;
    use crate::interact::{Constraints, Prescribed};
    let (organ, sc) = liver();
    let q = Settings::quick();
    let s = Settings {
        settle_dt_max: env_or("SETTLE_DT_MAX", q.settle_dt_max),
        ..q
    };
    let kinds: String = env_or("KINDS", "fem-explicit".to_string());
    let run: String = env_or("RUN", "shallow".to_string());
    let every: Real = env_or("EVERY", 0.05);
    let t_end: Real = env_or("T_END", s.settle_time);
    let base = settling(organ.material, &sc);
    let plate = run.starts_with("plate");
    let depth = if run == "deep" { sc.deep } else { sc.shallow };
    for kind in kinds.split(',') {
        let stable = stable_step(kind, &organ, &sc, base, ContactLaw::FineSurface, &s).unwrap();
        let dt = (0.5 * stable).min(s.settle_dt_max);
        let mat = Material {
            damping: 0.0,
            poisson_ratio: if plate { 0.45 } else { base.poisson_ratio },
            ..base
        };
        let model = organ.build(kind, mat).unwrap();
        let rest: Vec<Vec3> = model.rest_surface().to_vec();
        let fixed = sc.fixed(&rest);
        let moved = sc.plate(&rest);
        let pressed = nearest(&rest, sc.probe()).unwrap() as usize;
        let v0 = super::drive::volume(model.as_ref());
        let mut sim = probe_simulation(
            model,
            fixed.clone(),
            sc.probe_radius,
            ContactLaw::FineSurface,
        )
        .unwrap();
        let top = sc.probe() + Vec3::Y * sc.probe_radius;
        if !plate {
            sim.add_instrument(
                probe_instrument(
                    sc.probe(),
                    sc.probe_radius,
                    0.0,
                    1.0,
                    ContactLaw::FineSurface,
                )
                .unwrap(),
            );
        }
        println!("{kind} {run}: dt {dt:.1e} s");
        let steps = (t_end / dt).ceil() as usize;
        let print = ((every / dt).round() as usize).max(1);
        let (mut last, mut peak, mut stops) = (0.0, 0.0 as Real, 0);
        let mut prev: Vec<Vec3> = rest.clone();
        for k in 1..=steps {
            let t = k as Real * dt;
            let f = smooth_ramp(t / s.ramp);
            if plate {
                let c = Constraints {
                    fixed: fixed.clone(),
                    prescribed: moved
                        .iter()
                        .map(|&v| Prescribed {
                            vertex: v,
                            position: rest[v as usize] - Vec3::Y * (f * sc.compression),
                        })
                        .collect(),
                };
                let normals = vec![Some(-Vec3::Y); moved.len()];
                let m = sim.model_mut();
                if run == "plate-push" {
                    m.set_constraints_along(&c, &normals).unwrap();
                } else {
                    m.set_constraints_two_sided(&c, &normals).unwrap();
                }
                m.step(dt).unwrap();
            } else {
                sim.set_instrument_position(0, Some(top - Vec3::Y * (f * depth)))
                    .unwrap();
                sim.step(dt).unwrap();
            }
            let e = sim.model().kinetic_energy().unwrap_or(0.0);
            peak = peak.max(e);
            if e < last && sim.model_mut().stop_motion() {
                stops += 1;
                last = 0.0;
            } else {
                last = e;
            }
            if k % print == 0 {
                let m = sim.model();
                let now = m.surface().positions;
                let (v, d) = now
                    .iter()
                    .zip(&prev)
                    .map(|(a, b)| (*a - *b).length())
                    .enumerate()
                    .fold((0, 0.0), |b, (i, d)| if d > b.1 { (i, d) } else { b });
                let q = if plate {
                    format!(
                        "dV/V {:+.4} %",
                        100.0 * (super::drive::volume(m) / v0 - 1.0)
                    )
                } else {
                    format!(
                        "F {:.5e} N, pressed vertex dy {:+.3} mm",
                        sim.instrument_forces()[0].y,
                        1e3 * (now[pressed].y - rest[pressed].y)
                    )
                };
                println!(
                    "  t {t:.3}  {q}  KE/peak {:.2e}  stops {stops}  most moved: vertex {v} \
                     (rest y {:.1} mm) by {:.2e} mm",
                    e / peak.max(1e-300),
                    1e3 * rest[v].y,
                    1e3 * d
                );
                prev.copy_from_slice(now);
            }
        }
    }
}

/// A membrane that gives way is the model's honest answer, and its cell says "probe passed
/// through", not "not settled" (`measure::passed_through`): `spring-mass` (a surface of
/// springs, nothing behind it) lets the shallow probe push its pressed vertex through to
/// its mirror image, below the probe, and holds no force; `fem-explicit` (a volume) holds
/// the probe and is not called through.
#[test]
fn a_membrane_that_gives_way_is_said_to_let_the_probe_through() {
    let (organ, sc) = liver();
    let s = Settings::quick();
    let base = settling(organ.material, &sc);
    for (kind, through) in [("spring-mass", true), ("fem-explicit", false)] {
        let stable = stable_step(kind, &organ, &sc, base, ContactLaw::FineSurface, &s).unwrap();
        let st = Stepping {
            contact: ContactLaw::FineSurface,
            kinetic_damping: true,
            ..Stepping::new(false, (0.5 * stable).min(s.settle_dt_max), &s)
        };
        let ind =
            super::measure::indentation(kind, &organ, &sc, relaxing(base, &st), &st, sc.shallow)
                .unwrap();
        println!("{kind}: {:.3e} N, {:?}", ind.force, ind.unsettled_note());
        assert_eq!(ind.through.is_some(), through, "{kind}: {:?}", ind.through);
        if through {
            assert!(ind.force.abs() < 1e-6, "{kind}: {}", ind.force);
            assert!(
                ind.unsettled_note()
                    .unwrap()
                    .starts_with("probe passed through")
            );
        } else {
            assert!(ind.settled && ind.unsettled_note().is_none(), "{kind}");
        }
    }
}

/// The contact set per step of one kind's probe press on the liver, with the comparison's
/// fine surface (`KIND`, default linked-volumes; `RUN=deep`; `DT`; printed from `FROM` to
/// `TO` s; `KINETIC=0` and `MDAMP` (mass damping, /s) for a plain damped run; `ALLC=1` each
/// contact): the probe force, the contacts that pushed of those handed over, how far the
/// pressed vertex and the nearest fine point are outside the probe, the kinetic energy, the
/// motion stops, and whether the step was capped.
#[test]
#[ignore = "study: the probe's contact set per step"]
fn contact_trace_study() {
    use super::drive::smooth_ramp;
    use super::setup::nearest;
    let (organ, sc) = liver();
    let s = Settings::quick();
    let kind: String = env_or("KIND", "linked-volumes".to_string());
    let deep = std::env::var("RUN").is_ok_and(|d| d == "deep");
    let depth = if deep { sc.deep } else { sc.shallow };
    let from: Real = env_or("FROM", 0.0);
    let to: Real = env_or("TO", 1.5);
    let kinetic = env_or("KINETIC", 1) == 1;
    let base = settling(organ.material, &sc);
    let dt = env_or("DT", s.settle_dt_max);
    let mat = Material {
        damping: env_or("MDAMP", 0.0),
        ..base
    };
    let model = organ.build(kind.as_str(), mat).unwrap();
    let rest: Vec<Vec3> = model.rest_surface().to_vec();
    let pressed = nearest(&rest, sc.probe()).unwrap() as usize;
    let mut sim = touching_probe(model, &sc, ContactLaw::FineSurface).unwrap();
    let top = sc.probe() + Vec3::Y * sc.probe_radius;
    println!(
        "{kind}: dt {dt}, pressed {pressed} rest {:?} probe {:?} R {}",
        rest[pressed],
        sc.probe(),
        sc.probe_radius
    );
    let steps = (to / dt).ceil() as usize;
    let (mut last, mut stops) = (0.0, 0);
    for k in 1..=steps {
        let t = k as Real * dt;
        let f = smooth_ramp(t / s.ramp);
        let c = top - Vec3::Y * (f * depth);
        sim.set_instrument_position(0, Some(c)).unwrap();
        let r = sim.step(dt).unwrap();
        let e = sim.model().kinetic_energy().unwrap_or(0.0);
        let mut stopped = false;
        if kinetic && e < last && sim.model_mut().stop_motion() {
            stops += 1;
            last = 0.0;
            stopped = true;
        } else {
            last = e;
        }
        if t + 1e-12 < from {
            continue;
        }
        let now = sim.model().surface().positions;
        let p = now[pressed];
        let vd = p.distance(c) - sc.probe_radius;
        let fine_min = sim
            .fine_surface()
            .map(|(_, q)| {
                q.iter()
                    .map(|x| x.distance(c) - sc.probe_radius)
                    .fold(Real::INFINITY, Real::min)
            })
            .unwrap_or(Real::NAN);
        let inst = &sim.instruments()[0];
        let active = inst
            .contact_reactions()
            .iter()
            .filter(|f| **f != Vec3::ZERO)
            .count();
        let pc = inst
            .contacts()
            .iter()
            .position(|k| k.vertex as usize == pressed);
        let pinfo = pc.map(|j| {
            let k = inst.contacts()[j];
            let n = k.face.unwrap_or(Vec3::ZERO);
            format!(
                "plane gap {:+.4} mm R {:.2e}",
                1e3 * n.dot(p - k.target),
                inst.contact_reactions()[j].y
            )
        });
        if std::env::var("ALLC").is_ok() {
            let pos0 = sim.model().surface().positions;
            for (k, f) in inst.contacts().iter().zip(inst.contact_reactions()) {
                let n = k.face.unwrap_or(Vec3::ZERO);
                println!(
                    "   c v {} gap {:+.4} mm n {:.3?} R {:.3e} vdepth {:+.4} mm",
                    k.vertex,
                    1e3 * n.dot(pos0[k.vertex as usize] - k.target),
                    n,
                    f.length(),
                    1e3 * (pos0[k.vertex as usize].distance(c) - sc.probe_radius)
                );
            }
        }
        println!(
            "t {t:.3} F {:.4e} contacts {}/{} pressed depth {:+.4} mm ({:?}) fine min {:+.4} mm KE {e:.3e} {} cap {} it {}",
            sim.instrument_forces()[0].y,
            active,
            inst.contacts().len(),
            1e3 * vd,
            pinfo,
            1e3 * fine_min,
            if stopped { "STOP" } else { "" },
            r.info.capped,
            r.info.iterations,
        );
    }
    println!("stops {stops}");
}

/// `linked-volumes` (implicit Euler, the fine surface's per-vertex planes) pressed shallow
/// settles holding a push, and the same push two independent ways: the comparison's kinetic
/// damping (no mass damping, velocities zeroed at each peak of the kinetic energy) and a
/// plain run with mass damping (α = 8 /s, about critical for its slowest mode here, no
/// stops) stepped to rest (2.5 s and 4.2 s at 1 ms; each steady to 2 % over its last 0.2 s,
/// within 10 % of the other). Before the handed-over planes of vertices a fine point does not
/// follow were dropped, the kinetic run read 0 N from 0.4 s on: planes through vertices
/// 7 mm from the probe held the liver off it (`contact::hold_points`).
#[test]
fn linked_volumes_shallow_press_holds_its_equilibrium_push() {
    use super::drive::smooth_ramp;
    let (organ, sc) = liver();
    let s = Settings::quick();
    let base = settling(organ.material, &sc);
    let press = |damping: Real, kinetic: bool, t_end: Real| {
        let model = organ
            .build("linked-volumes", Material { damping, ..base })
            .unwrap();
        let mut sim = touching_probe(model, &sc, ContactLaw::FineSurface).unwrap();
        let top = sc.probe() + Vec3::Y * sc.probe_radius;
        let dt = s.settle_dt_max;
        let steps = (t_end / dt).round() as usize;
        let (mut last, mut forces) = (0.0, Vec::new());
        for k in 1..=steps {
            let f = smooth_ramp(k as Real * dt / s.ramp);
            sim.set_instrument_position(0, Some(top - Vec3::Y * (f * sc.shallow)))
                .unwrap();
            let r = sim.step(dt).unwrap();
            assert!(!r.info.capped, "step {k} capped");
            let e = sim.model().kinetic_energy().unwrap();
            if kinetic && e < last && sim.model_mut().stop_motion() {
                last = 0.0;
            } else {
                last = e;
            }
            forces.push(sim.instrument_forces()[0].y);
        }
        forces
    };
    let kinetic = press(0.0, true, 2.5);
    let damped = press(8.0, false, 4.2);
    // Held: the last 0.2 s of each move by less than 2 % of its end value.
    let end = |f: &[Real]| {
        let tail = &f[f.len() - 200..];
        let last = tail[tail.len() - 1];
        let spread = tail.iter().map(|x| (x - last).abs()).fold(0.0, Real::max);
        (last, spread / last)
    };
    let (fk, sk) = end(&kinetic);
    let (fd, sd) = end(&damped);
    println!("kinetic {fk:.5e} N (spread {sk:.1e}), damped {fd:.5e} N (spread {sd:.1e})");
    assert!(fk > 0.0 && fd > 0.0);
    assert!(sk < 2e-2 && sd < 2e-2, "{sk} {sd}");
    assert!((fk / fd - 1.0).abs() < 0.1, "{fk} {fd}");
}

/// `volumetric-spring-mass` pressed deep through the comparison's fine surface (k = 3,
/// issue 20): its spring lattice lets the tetrahedra under the probe invert (tetrahedron 65
/// from 2.5 mm in, at 0.051 s), which folds the surface there, and the fine points 0.1 mm
/// inside the probe on the fold were sent out through the ball's far side (45 mm away):
/// at 0.067 s one substep moved a particle 163 mm, the probe read −1.38 N (pulled down)
/// and the run diverged. A probe only pushes: over the ramp (to 0.12 s, 1 ms steps, no
/// damping) every step's probe force points up, out of the liver (its horizontal part
/// under half the vertical), and no surface vertex moves faster than the probe could
/// push it (under 1 mm in a step; the probe moves 0.1 mm at most).
#[test]
fn volumetric_spring_mass_deep_press_pushes_its_folded_surface_the_nearest_way() {
    use super::drive::smooth_ramp;
    let (organ, sc) = liver();
    let s = Settings::quick();
    let dt = s.settle_dt_max;
    let base = settling(organ.material, &sc);
    let mat = Material {
        damping: 0.0,
        ..base
    };
    let model = organ.build("volumetric-spring-mass", mat).unwrap();
    let rest: Vec<Vec3> = model.rest_surface().to_vec();
    let mut sim = touching_probe(model, &sc, ContactLaw::FineSurface).unwrap();
    let top = sc.probe() + Vec3::Y * sc.probe_radius;
    let mut prev = rest.clone();
    let (mut peak, mut fastest, mut probe_step, mut tilt): (Real, Real, Real, Real) =
        (0.0, 0.0, 0.0, 0.0);
    let mut last_probe = top;
    for k in 1..=120 {
        let t = k as Real * dt;
        let c = top - Vec3::Y * (smooth_ramp(t / s.ramp) * sc.deep);
        sim.set_instrument_position(0, Some(c)).unwrap();
        sim.step(dt).unwrap_or_else(|e| panic!("step {k}: {e}"));
        let f = sim.instrument_forces()[0];
        assert!(f.y >= -1e-12, "step {k}: the probe is pulled down: {f}");
        let across = Vec3::new(f.x, 0.0, f.z).length();
        if f.y > 0.0 {
            tilt = tilt.max(across / f.y);
        } else {
            assert!(across < 1e-12, "step {k}: {f}");
        }
        peak = peak.max(f.y);
        let now = sim.model().surface().positions;
        let moved = now
            .iter()
            .zip(&prev)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, Real::max);
        fastest = fastest.max(moved);
        prev.copy_from_slice(now);
        probe_step = probe_step.max(c.distance(last_probe));
        last_probe = c;
    }
    println!(
        "peak push {peak:.4e} N, largest horizontal/vertical {tilt:.3}, fastest surface \
         vertex {:.3} mm per step, probe {:.3} mm per step",
        1e3 * fastest,
        1e3 * probe_step
    );
    assert!(peak > 0.0);
    assert!(tilt < 0.5, "{tilt}");
    assert!(fastest < 1e-3, "{fastest}");
}
