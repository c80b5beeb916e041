//! Checks of scene entries that serde cannot express, region selection on the built
//! model's surface, and instruments from their entries. Messages are completed with the
//! table and line by the caller.

use std::collections::HashMap;

use crate::interact::{Instrument, InstrumentKind, Region, Trajectory};
use crate::math::{Real, Vec3};
use crate::mesh::MeshData;
use crate::model::{Deformable, KINDS};

use super::spec::{InstrumentSpec, RegionSpec, RunSpec};

pub(super) fn known_kinds() -> String {
    KINDS.iter().map(|k| k.name).collect::<Vec<_>>().join(", ")
}

/// Steps a scene may ask for (`duration / dt`), exclusive.
pub const MAX_STEPS: Real = 1e9;

pub(super) fn check_run(run: &RunSpec) -> Result<(), String> {
    if !(run.duration.is_finite() && run.duration > 0.0) {
        return Err(format!(
            "duration = {}: must be finite and > 0 s",
            run.duration
        ));
    }
    if !(run.dt.is_finite() && run.dt > 0.0) {
        return Err(format!("dt = {}: must be finite and > 0 s", run.dt));
    }
    if run.dt > run.duration {
        return Err(format!(
            "dt = {} s is longer than duration = {} s",
            run.dt, run.duration
        ));
    }
    // Compared as a float: the step count of dt = 1e-300 overflows an integer. 1e9 steps
    // or more is days of computing for any model: a typo, not a plan.
    let steps = (run.duration / run.dt).ceil();
    if steps.is_nan() || steps >= MAX_STEPS {
        return Err(format!(
            "dt = {} s gives {steps:e} steps over duration = {} s, and {MAX_STEPS:e} or more \
             would run for days: raise dt or shorten duration",
            run.dt, run.duration
        ));
    }
    Ok(())
}

pub(super) fn region_label(table: &str, k: usize, r: &RegionSpec) -> String {
    match &r.name {
        Some(n) => format!("[[{table}]] {} (`{n}`)", k + 1),
        None => format!("[[{table}]] {}", k + 1),
    }
}

/// `image_body`: the body is an `[image]`, which has no file vertices to name.
pub(super) fn check_region(r: &RegionSpec, is_load: bool, image_body: bool) -> Result<(), String> {
    let set = [
        ("box", r.aabb.is_some()),
        ("sphere", r.sphere.is_some()),
        ("plane", r.plane.is_some()),
        ("indices", r.indices.is_some()),
        ("file_vertices", r.file_vertices.is_some()),
        ("file", r.file == Some(true)),
    ];
    let given: Vec<&str> = set.iter().filter(|s| s.1).map(|s| s.0).collect();
    if given.len() != 1 {
        return Err(format!(
            "needs exactly one of box, sphere, plane, indices, file_vertices, file = true; found {}",
            if given.is_empty() {
                "none".to_string()
            } else {
                given.join(", ")
            }
        ));
    }
    if image_body && (r.file_vertices.is_some() || r.file.is_some()) {
        return Err(format!(
            "`{}` names vertices of a mesh file, and an [image] body has none; select by box, \
             sphere, plane or surface indices",
            if r.file.is_some() {
                "file"
            } else {
                "file_vertices"
            }
        ));
    }
    let finite = |v: &[Real]| v.iter().all(|x| x.is_finite());
    if let Some(b) = &r.aabb
        && !(finite(&b.min) && finite(&b.max))
    {
        return Err("box bounds must be finite".into());
    }
    if let Some(s) = &r.sphere
        && !(finite(&s.center) && s.radius.is_finite() && s.radius >= 0.0)
    {
        return Err("sphere center and radius must be finite, radius >= 0".into());
    }
    if let Some(p) = &r.plane
        && !(finite(&p.point) && finite(&p.normal) && p.tolerance.is_finite())
    {
        return Err("plane point, normal and tolerance must be finite".into());
    }
    match (is_load, r.force) {
        (true, None) => Err("a load needs `force` (total, in N)".into()),
        (true, Some(f)) if !finite(&f) => Err("force must be finite".into()),
        (false, Some(_)) => Err("`force` belongs in a [[load]], not a [[fixed]] region".into()),
        _ => Ok(()),
    }
}

/// Surface vertices a region selects; errors name indices that do not exist or are interior.
pub(super) fn select(
    model: &dyn Deformable,
    mesh: &MeshData,
    r: &RegionSpec,
) -> Result<Vec<u32>, String> {
    let rest = model.rest_surface();
    if let Some(b) = &r.aabb {
        return Ok(Region::Box {
            min: b.min,
            max: b.max,
        }
        .select(rest));
    }
    if let Some(s) = &r.sphere {
        return Ok(Region::Sphere {
            center: s.center,
            radius: s.radius,
        }
        .select(rest));
    }
    if let Some(p) = &r.plane {
        return Ok(Region::Plane {
            point: p.point,
            normal: p.normal,
            tolerance: p.tolerance,
        }
        .select(rest));
    }
    if let Some(ids) = &r.indices {
        let region = Region::Indices(ids.clone());
        if let Some(bad) = region.out_of_range(rest.len()).first() {
            return Err(format!(
                "surface vertex {bad} does not exist: the surface has {} vertices",
                rest.len()
            ));
        }
        return Ok(region.select(rest));
    }
    let (ids, what) = match (&r.file_vertices, r.file) {
        (Some(ids), _) => (ids.clone(), "file vertex"),
        (None, Some(true)) => (
            mesh.fixed_vertices.clone(),
            "vertex marked fixed in the file,",
        ),
        _ => return Ok(Vec::new()),
    };
    // The surface is built from the file's vertices without moving them, so an exact
    // position match finds a file vertex on the surface.
    let key = |p: Vec3| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
    let on_surface: HashMap<[u64; 3], u32> = rest
        .iter()
        .enumerate()
        .map(|(i, &p)| (key(p), i as u32))
        .collect();
    let mut out = Vec::with_capacity(ids.len());
    for i in ids {
        let p = mesh.vertices.get(i as usize).ok_or_else(|| {
            format!(
                "{what} {i} does not exist: the file has {} vertices",
                mesh.vertices.len()
            )
        })?;
        let s = on_surface
            .get(&key(*p))
            .ok_or_else(|| format!("{what} {i} is not on the surface (it is interior)"))?;
        out.push(*s);
    }
    out.sort_unstable();
    out.dedup();
    Ok(out)
}

/// The instrument an `[[instrument]]` entry describes, or why it is not one.
pub(super) fn make_instrument(i: &InstrumentSpec, k: usize) -> Result<Instrument, String> {
    let trajectory = Trajectory::new(i.path.clone()).map_err(|e| format!("path: {e}"))?;
    let forbid = |key: &str, present: bool, kind: &str| {
        if present {
            Err(format!("`{key}` does not apply to a {kind}"))
        } else {
            Ok(())
        }
    };
    let need_radius = || {
        i.radius
            .ok_or_else(|| format!("a {} needs `radius` (m)", i.kind))
    };
    let only = |allowed: &[&str]| -> Result<(), String> {
        let present = [
            ("grasp_at", i.grasp_at.is_some()),
            ("release_at", i.release_at.is_some()),
            ("direction", i.direction.is_some()),
            ("length", i.length.is_some()),
            ("friction", i.friction.is_some()),
            ("contact", i.contact.is_some()),
            ("axis", i.axis.is_some()),
            ("normal", i.normal.is_some()),
            ("size", i.size.is_some()),
        ];
        for (key, here) in present {
            if !allowed.contains(&key) {
                forbid(key, here, &i.kind)?;
            }
        }
        Ok(())
    };
    let (kind, radius) = match i.kind.as_str() {
        "probe" => {
            only(&["friction", "contact"])?;
            (InstrumentKind::Probe, need_radius()?)
        }
        "capsule" => {
            only(&["friction", "contact", "axis", "length"])?;
            let axis = i
                .axis
                .ok_or("a capsule needs `axis` (its shaft direction)")?;
            let length = i.length.ok_or("a capsule needs `length` (m)")?;
            (
                InstrumentKind::Capsule {
                    axis: Vec3::from(axis),
                    length,
                },
                need_radius()?,
            )
        }
        "plane" => {
            only(&["friction", "contact", "normal"])?;
            let normal = i
                .normal
                .ok_or("a plane needs `normal` (out of the instrument, toward the tissue)")?;
            // No size: the radius only sets the viewer's marker and the contact tolerance.
            (
                InstrumentKind::Plane {
                    normal: Vec3::from(normal),
                },
                i.radius.unwrap_or(0.01),
            )
        }
        "box" => {
            only(&["friction", "contact", "size"])?;
            let size = Vec3::from(i.size.ok_or("a box needs `size` (edge lengths, m)")?);
            (
                InstrumentKind::Box { half: 0.5 * size },
                i.radius.unwrap_or(0.5 * size.min_element().abs()),
            )
        }
        "grasper" => {
            only(&["grasp_at", "release_at"])?;
            let grasp_at = i.grasp_at.ok_or("a grasper needs `grasp_at` (s)")?;
            (
                InstrumentKind::Grasper {
                    grasp_at,
                    release_at: i.release_at,
                },
                need_radius()?,
            )
        }
        "scalpel" => {
            only(&["direction", "length"])?;
            let direction = i.direction.ok_or("a scalpel needs `direction`")?;
            let length = i.length.ok_or("a scalpel needs `length` (m)")?;
            (
                InstrumentKind::Scalpel {
                    direction: Vec3::from(direction),
                    length,
                },
                i.radius.unwrap_or(length),
            )
        }
        other => {
            return Err(format!(
                "unknown instrument kind `{other}`; known: probe, capsule, plane, box, grasper, \
                 scalpel"
            ));
        }
    };
    let name = i
        .name
        .clone()
        .unwrap_or_else(|| format!("{}{}", i.kind, k + 1));
    let inst = Instrument::new(name, kind, radius, trajectory).map_err(|e| e.to_string())?;
    // A pushing instrument slides, frictionless unless `friction` is given (the default,
    // docs/contact.md); `contact = "sticking"` opts into sticking contact. A grasper or
    // scalpel takes neither key (`only` above).
    match (i.contact.as_deref(), i.friction) {
        (None, None) => Ok(inst),
        (Some("sticking"), None) => Ok(inst.sticking()),
        (None | Some("sliding"), mu) => inst
            .with_friction(mu.unwrap_or(0.0))
            .map_err(|e| e.to_string()),
        (Some("sticking"), Some(_)) => Err(
            "`friction` is for sliding contact: give `contact = \"sliding\"` or no `contact`"
                .into(),
        ),
        (Some(other), _) => Err(format!(
            "unknown contact `{other}`; known: sliding (the default), sticking"
        )),
    }
}

#[cfg(test)]
mod run_tests {
    use super::*;

    #[test]
    fn a_billion_steps_is_refused_at_load() {
        let run = |duration, dt| check_run(&RunSpec { duration, dt });
        assert!(run(1.0, 1e-3).is_ok());
        for (duration, dt) in [(1.0, 1e-9), (10.0, 1e-9), (1.0, 1e-300), (1e300, 1.0)] {
            let e = run(duration, dt).err().unwrap_or_default();
            assert!(
                e.contains("steps over duration") && e.contains("raise dt"),
                "{e}"
            );
        }
        assert!(run(0.999, 1e-9).is_ok());
    }

    /// Frictionless sliding is the default; `friction` gives Coulomb friction and
    /// `contact = "sticking"` sticking contact; a contradiction, an unknown mode or a contact
    /// mode on a grasper is refused by name, and a grasper still holds (no friction).
    #[test]
    fn contact_mode_keys() {
        let spec = |extra: &str| -> InstrumentSpec {
            toml::from_str(&format!(
                "kind = \"probe\"\nradius = 0.005\n{extra}\npath = [ {{ t = 0.0, position = [0.0, 0.0, 0.0] }} ]"
            ))
            .unwrap()
        };
        let friction = |extra: &str| make_instrument(&spec(extra), 0).map(|i| i.friction());
        assert_eq!(friction(""), Ok(Some(0.0)));
        assert_eq!(friction("contact = \"sticking\""), Ok(None));
        assert_eq!(friction("contact = \"sliding\""), Ok(Some(0.0)));
        assert_eq!(friction("friction = 0.3"), Ok(Some(0.3)));
        assert_eq!(
            friction("contact = \"sliding\"\nfriction = 0.2"),
            Ok(Some(0.2))
        );
        let e = friction("contact = \"sticking\"\nfriction = 0.2").unwrap_err();
        assert!(e.contains("`friction` is for sliding contact"), "{e}");
        let e = friction("contact = \"glued\"").unwrap_err();
        assert!(e.contains("unknown contact `glued`"), "{e}");
        let e = friction("friction = -1.0").unwrap_err();
        assert!(e.contains("friction"), "{e}");
        let grasper = |extra: &str| -> Result<Option<Real>, String> {
            let spec: InstrumentSpec = toml::from_str(&format!(
                "kind = \"grasper\"\nradius = 0.005\ngrasp_at = 0.1\n{extra}\npath = [ {{ t = 0.0, position = [0.0, 0.0, 0.0] }} ]"
            ))
            .unwrap();
            make_instrument(&spec, 0).map(|i| i.friction())
        };
        assert_eq!(grasper(""), Ok(None));
        let e = grasper("contact = \"sticking\"").unwrap_err();
        assert!(e.contains("contact"), "{e}");
    }
}
