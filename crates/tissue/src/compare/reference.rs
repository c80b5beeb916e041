//! The reference: quadratic `fem-static` (10-node tetrahedra) on the organ and on meshes
//! refined by splitting every tetrahedron into eight, with the convergence of the probe force
//! reported; the finest level gives the reference values. The dynamics reference is
//! `fem-explicit` (central differences add no numerical damping) on the organ itself.

use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::error::Error;
use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::mesh::{MeshData, split_tets};

use super::drive::{Stepping, indent, prescribe, volume};
use super::measure::{bar_on, settling, stable_step, step_response};
use super::record::{Curve, Measure, ReferenceLevel, ReferenceRecord};
use super::setup::{Organ, Scenario, build_on, nearest};
use super::{Settings, bar_mesh};

/// The reference values the measurements are compared with.
#[derive(Clone, Debug, Default)]
pub struct Reference {
    pub force_shallow: Real,
    pub force_deep: Real,
    /// Relative volume change under the plate at ν = 0.45.
    pub compression_volume: Real,
    pub bar_force: Real,
    pub bar_nu: Real,
    pub frequency: Option<Real>,
    pub delay: Option<Real>,
    /// The shallow indentation's surface: rest positions and displacements.
    pub rest: Vec<Vec3>,
    pub displacement: Vec<Vec3>,
    pub record: ReferenceRecord,
}

impl Reference {
    /// RMS of the difference between a model's surface displacements and the reference's
    /// (at the nearest reference surface vertex), over the RMS of the reference's.
    pub fn displacement_error(&self, field: &[(Vec3, Vec3)]) -> Real {
        let (mut num, mut den) = (0.0, 0.0);
        for (p, u) in field {
            if let Some(i) = nearest(&self.rest, *p) {
                let r = self.displacement[i as usize];
                num += (*u - r).length_squared();
                den += r.length_squared();
            }
        }
        (num / den.max(1e-300)).sqrt()
    }
}

/// `Reference` as stored in the comparison's cache (vectors as arrays).
#[derive(Serialize, Deserialize)]
struct Stored {
    force_shallow: Real,
    force_deep: Real,
    compression_volume: Real,
    bar_force: Real,
    bar_nu: Real,
    frequency: Option<Real>,
    delay: Option<Real>,
    rest: Vec<[Real; 3]>,
    displacement: Vec<[Real; 3]>,
    record: ReferenceRecord,
}

impl Reference {
    /// The reference as JSON, for a cache: computing it is the longest part of a run.
    pub fn to_json(&self) -> serde_json::Result<String> {
        serde_json::to_string(&Stored {
            force_shallow: self.force_shallow,
            force_deep: self.force_deep,
            compression_volume: self.compression_volume,
            bar_force: self.bar_force,
            bar_nu: self.bar_nu,
            frequency: self.frequency,
            delay: self.delay,
            rest: self.rest.iter().map(|v| v.to_array()).collect(),
            displacement: self.displacement.iter().map(|v| v.to_array()).collect(),
            record: self.record.clone(),
        })
    }

    /// The reference `to_json` wrote.
    pub fn from_json(text: &str) -> serde_json::Result<Self> {
        let s: Stored = serde_json::from_str(text)?;
        Ok(Self {
            force_shallow: s.force_shallow,
            force_deep: s.force_deep,
            compression_volume: s.compression_volume,
            bar_force: s.bar_force,
            bar_nu: s.bar_nu,
            frequency: s.frequency,
            delay: s.delay,
            rest: s.rest.into_iter().map(Vec3::from).collect(),
            displacement: s.displacement.into_iter().map(Vec3::from).collect(),
            record: s.record,
        })
    }
}

fn quadratic() -> toml::Table {
    let mut t = toml::Table::new();
    t.insert("order".into(), toml::Value::String("quadratic".into()));
    t
}

/// Computes the reference on `organ` (it must have tetrahedra).
pub fn reference(
    organ: &Organ,
    sc: &Scenario,
    s: &Settings,
    progress: &dyn Fn(&str),
) -> Result<Reference, Error> {
    let mat = settling(organ.material, sc);
    let st = Stepping::new(true, 1.0, s);
    let mut meshes = vec![organ.tets().clone()];
    let mut tets = organ.tets().tet_mesh(&organ.name)?;
    for _ in 0..s.reference_refinements {
        tets = split_tets(&tets)?;
        meshes.push(MeshData::from_tets(&tets));
    }
    let model = match &organ.stuffed {
        None => "fem-static, order = quadratic".to_string(),
        Some(st) => format!(
            "fem-static, order = quadratic, on {} tetrahedra stuffed from the surface \
             (h = {:.2e} m{})",
            st.mesh.tets.len(),
            st.size,
            st.misses()
        ),
    };
    let mut rec = ReferenceRecord {
        model,
        ..ReferenceRecord::default()
    };
    let mut out = Reference::default();
    for (level, mesh) in meshes.iter().enumerate() {
        progress(&format!("reference level {level}"));
        let t = Instant::now();
        let model = build_on("fem-static", mesh, &organ.name, mat, &quadratic())?;
        let build = t.elapsed().as_secs_f64();
        let info = model.info();
        let fixed = sc.fixed(model.rest_surface());
        let (settled, sim) = indent(model, fixed, sc.probe(), sc.probe_radius, sc.shallow, &st)?;
        rec.levels.push(ReferenceLevel {
            tets: mesh.tets.len(),
            nodes: info.nodes,
            probe_force: settled.value,
            build_seconds: build,
        });
        if level + 1 == meshes.len() {
            let m = sim.model();
            out.rest = m.rest_surface().to_vec();
            out.displacement = m
                .surface()
                .positions
                .iter()
                .zip(&out.rest)
                .map(|(p, r)| *p - *r)
                .collect();
            out.force_shallow = settled.value;
            rec.curves.insert(
                "indentation".into(),
                Curve {
                    x_unit: "m".into(),
                    y_unit: "N".into(),
                    points: settled
                        .curve
                        .iter()
                        .map(|p| [p[0] * sc.shallow, p[1]])
                        .collect(),
                },
            );
        }
    }
    let n = rec.levels.len();
    rec.convergence = if n >= 2 {
        let (a, b) = (rec.levels[n - 2].probe_force, rec.levels[n - 1].probe_force);
        (a - b).abs() / b.abs().max(1e-300)
    } else {
        Real::NAN
    };
    let finest = meshes.last().cloned().unwrap_or_default();
    progress("reference deep");
    let model = build_on("fem-static", &finest, &organ.name, mat, &quadratic())?;
    let fixed = sc.fixed(model.rest_surface());
    let (deep, _) = indent(model, fixed, sc.probe(), sc.probe_radius, sc.deep, &st)?;
    out.force_deep = deep.value;
    progress("reference compression");
    let incompressible = Material {
        poisson_ratio: 0.45,
        ..mat
    };
    let mut model = build_on(
        "fem-static",
        &finest,
        &organ.name,
        incompressible,
        &quadratic(),
    )?;
    let rest = model.rest_surface().to_vec();
    let v0 = volume(model.as_ref());
    let travel = sc.compression;
    let comp = prescribe(
        model.as_mut(),
        &sc.fixed(&rest),
        &sc.plate(&rest),
        |p, s| p - Vec3::Y * (s * travel),
        &st,
        |m| (volume(m) - v0) / v0,
    )?;
    out.compression_volume = comp.value;
    rec.curves.insert(
        "compression".into(),
        Curve {
            x_unit: "m".into(),
            y_unit: "relative volume change".into(),
            points: comp.curve.iter().map(|p| [p[0] * travel, p[1]]).collect(),
        },
    );
    progress("reference bar");
    let bar = split_tets(&bar_mesh(s).tet_mesh("bar")?)?;
    let (f, nu) = bar_on(
        "fem-static",
        &MeshData::from_tets(&bar),
        mat,
        &st,
        &quadratic(),
    )?;
    out.bar_force = f;
    out.bar_nu = nu;
    progress("reference dynamics");
    let dyn_kind = "fem-explicit";
    if let Ok(dt) = stable_step(dyn_kind, organ, sc, mat, s)
        && let Ok((freq, delay)) =
            step_response(dyn_kind, organ, sc, organ.material, 0.25 * dt, &out, s)
    {
        out.frequency = freq.value;
        out.delay = delay.value;
    }
    let m = &mut rec.measures;
    m.insert("force_shallow".into(), Measure::of(out.force_shallow, "N"));
    m.insert("force_deep".into(), Measure::of(out.force_deep, "N"));
    m.insert(
        "compression_volume".into(),
        Measure::of(out.compression_volume, "relative"),
    );
    m.insert("bar_force".into(), Measure::of(out.bar_force, "N"));
    m.insert("bar_nu".into(), Measure::of(out.bar_nu, ""));
    m.insert(
        "frequency".into(),
        match out.frequency {
            Some(f) => Measure::of(f, "Hz").noted("fem-explicit on the organ mesh"),
            None => Measure::failed("Hz", "fem-explicit gave no oscillation"),
        },
    );
    m.insert(
        "delay".into(),
        match out.delay {
            Some(d) => Measure::of(d, "s").noted("fem-explicit on the organ mesh"),
            None => Measure::failed("s", "fem-explicit's far side did not move"),
        },
    );
    m.insert(
        "convergence".into(),
        Measure::of(rec.convergence, "relative"),
    );
    out.record = rec;
    Ok(out)
}
