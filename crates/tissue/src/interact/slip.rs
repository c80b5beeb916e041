//! Whether a frictionless instrument is small against the surface it touches. Contact is
//! found on surface vertices (or on a fine surface's, `[mesh] visual`): a frictionless probe
//! whose diameter is not well above the edges near its path pushes the touched vertices round
//! its sphere and passes between them (the shipped coarse liver, 1 cm edges, under a 5 mm
//! probe: the force turned along the probe's motion, docs/contact.md "Frictionless by
//! default"). Nothing in a run shows it but the force, so the scene is told when built.

use crate::interact::instrument::Instrument;
use crate::interact::shape::Shape;
use crate::math::{Real, Vec3};

/// A frictionless sphere or capsule whose diameter is below this many times the median
/// edge near its path can slip between the vertices: measured, a 10 mm probe slipped on
/// 1 cm edges and an 8 mm one on the brain's 7 mm tetrahedra, a 40 mm one held on 1 cm edges
/// and a 10 mm one on the stuffed liver's 2–3 mm edges.
pub const SLIP_RATIO: Real = 1.5;

/// A frictionless sphere or capsule on a fine contact surface (`[mesh] visual`) whose
/// diameter is below this many times the median fine edge near its path can be held between
/// the fine points: the faces between them pass a little inside it, and the organ, which
/// cannot slide off a frictionless probe sideways without riding over them, stays put.
/// Measured on the shipped liver (fem-condensed, the probe pressed 1 cm, cap 200, the force
/// against 64 times the points; docs/contact.md "The shipped liver's fine surface resolved"):
/// at diameter / edge 3.1, 3.8 and 5.0 the organ under the probe moved 0.5–0.7 mm sideways
/// and the force was 64–66 % off; at 6.2 it moved 6.5 mm and was 5 % off, at 6.8 0.9 %, at
/// 7.5 and above at most 1.6 % (the larger probes' own floor, 0.3–0.8 % at 15–40).
pub const FINE_RATIO: Real = 8.0;

/// The warning for `inst` (number `index` in the scene) on the surface `positions`,
/// `triangles`: `None` unless it is a frictionless sphere or capsule whose path passes
/// within its reach of the surface and whose diameter is below `SLIP_RATIO` times the
/// median length of the edges there.
pub fn slip_warning(
    index: usize,
    inst: &Instrument,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
) -> Option<String> {
    let near = near_edges(inst, positions, triangles)?;
    (2.0 * near.radius < SLIP_RATIO * near.median).then(|| {
        format!(
            "instrument {index} (\"{}\"): a frictionless {} of radius {:.3e} m on surface \
             edges of {:.3e} m near its path (median of {}) can slip between the \
             vertices; give the scene a finer contact surface ([mesh] visual), a finer mesh, \
             or contact = \"sticking\" (docs/contact.md)",
            inst.name,
            shape_name(inst),
            near.radius,
            near.median,
            near.count
        )
    })
}

/// The warning for `inst` (number `index`) on a fine contact surface already cut `levels`
/// times (`[mesh] visual_levels`) with rest vertices `positions`, `triangles`: `None`
/// unless it is a frictionless sphere or capsule whose diameter is below `FINE_RATIO`
/// times the median fine edge near its path. It names the `visual_levels` that would make
/// the ratio hold (`fine_levels_needed`), or says the bound is too low for it.
pub fn fine_slip_warning(
    index: usize,
    inst: &Instrument,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    levels: u32,
) -> Option<String> {
    let near = near_edges(inst, positions, triangles)?;
    let more = fine_levels_needed(near.radius, near.median);
    (more > 0).then(|| {
        let want = levels + more;
        let fix = if want <= crate::scene::MAX_VISUAL_LEVELS {
            format!("give [mesh] visual_levels = {want}")
        } else {
            format!(
                "visual_levels = {want} would be needed, beyond its bound {}: give a finer \
                 `visual` surface",
                crate::scene::MAX_VISUAL_LEVELS
            )
        };
        format!(
            "instrument {index} (\"{}\"): a frictionless {} of radius {:.3e} m on fine \
             contact surface edges of {:.3e} m near its path (median of {}, visual_levels = \
             {levels}): its diameter is under {FINE_RATIO} edges, the fine points can hold it \
             and the organ cannot slide off it (measured: the force up to two thirds too \
             large); {fix} (docs/contact.md)",
            inst.name,
            shape_name(inst),
            near.radius,
            near.median,
            near.count
        )
    })
}

/// How many more times a fine surface whose median edge near the instrument's path is
/// `median` m must be cut in four (each level halves the edges) for a sphere or capsule of
/// radius `radius` m to span `FINE_RATIO` edges: 0 when it already does.
pub fn fine_levels_needed(radius: Real, median: Real) -> u32 {
    let mut k = 0;
    let mut edge = median;
    while 2.0 * radius < FINE_RATIO * edge && k < 32 {
        edge *= 0.5;
        k += 1;
    }
    k
}

/// The surface edges near a frictionless sphere's or capsule's path.
struct NearEdges {
    radius: Real,
    median: Real,
    count: usize,
}

/// `None` unless `inst` is a frictionless sphere or capsule and some edge's midpoint lies
/// within its reach of its path: its radius and the median length of those edges.
fn near_edges(inst: &Instrument, positions: &[Vec3], triangles: &[[u32; 3]]) -> Option<NearEdges> {
    if inst.friction() != Some(0.0) {
        return None;
    }
    let radius = match inst.shape()? {
        Shape::Sphere { radius } | Shape::Capsule { radius, .. } => radius,
        Shape::Plane { .. } | Shape::Box { .. } => return None,
    };
    let path: Vec<Vec3> = inst
        .trajectory()
        .keys()
        .iter()
        .map(|k| Vec3::from_array(k.position))
        .collect();
    // Capsules reach along their shaft too: their bounding ball's radius.
    let reach = inst.shape()?.bounds(Vec3::ZERO).map_or(radius, |(_, r)| r) + 2.0 * radius;
    let mut near: Vec<Real> = Vec::new();
    for t in triangles {
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            // Each edge once (the lower index first; an open boundary edge counted anyway).
            if a > b && triangles.len() > 1 {
                continue;
            }
            let (Some(&pa), Some(&pb)) = (positions.get(a as usize), positions.get(b as usize))
            else {
                continue;
            };
            let mid = 0.5 * (pa + pb);
            if distance_to_path(mid, &path) <= reach {
                near.push(pa.distance(pb));
            }
        }
    }
    if near.is_empty() {
        return None;
    }
    near.sort_by(Real::total_cmp);
    Some(NearEdges {
        radius,
        median: near[near.len() / 2],
        count: near.len(),
    })
}

fn shape_name(inst: &Instrument) -> &'static str {
    if matches!(inst.shape(), Some(Shape::Capsule { .. })) {
        "capsule"
    } else {
        "probe"
    }
}

/// The distance from `p` to the polyline through `path` (a point for a one-key path).
fn distance_to_path(p: Vec3, path: &[Vec3]) -> Real {
    match path {
        [] => Real::INFINITY,
        [only] => p.distance(*only),
        _ => path
            .windows(2)
            .map(|w| {
                let (a, b) = (w[0], w[1]);
                let ab = b - a;
                let s = if ab.length_squared() > 0.0 {
                    ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                p.distance(a + s * ab)
            })
            .fold(Real::INFINITY, Real::min),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::interact::{Instrument, InstrumentKind, Keyframe, Trajectory};

    fn probe(radius: Real, friction: Option<Real>) -> Instrument {
        let path = Trajectory::new(vec![
            Keyframe {
                t: 0.0,
                position: [0.5, 0.5, 0.1],
            },
            Keyframe {
                t: 1.0,
                position: [0.5, 0.5, 0.0],
            },
        ])
        .unwrap();
        let p = Instrument::new("probe", InstrumentKind::Probe, radius, path).unwrap();
        match friction {
            None => p.sticking(),
            Some(mu) => p.with_friction(mu).unwrap(),
        }
    }

    /// A flat grid of `n` × `n` cells of edge 1/n at z = 0.
    fn grid(n: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let h = 1.0 / n as Real;
        let mut p = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                p.push(Vec3::new(i as Real * h, j as Real * h, 0.0));
            }
        }
        let at = |i: u32, j: u32| j * (n + 1) + i;
        let mut t = Vec::new();
        for j in 0..n {
            for i in 0..n {
                t.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                t.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        (p, t)
    }

    #[test]
    fn a_small_frictionless_probe_on_coarse_edges_is_warned_of_and_nothing_else() {
        let (p, t) = grid(10); // edges 0.1 (and diagonals 0.141)
        let warned = slip_warning(0, &probe(0.05, Some(0.0)), &p, &t);
        assert!(
            warned.as_deref().is_some_and(|w| w.contains("slip")),
            "{warned:?}"
        );
        // A probe twice the edges, sticking, or with friction: no warning.
        assert!(slip_warning(0, &probe(0.2, Some(0.0)), &p, &t).is_none());
        assert!(slip_warning(0, &probe(0.05, None), &p, &t).is_none());
        assert!(slip_warning(0, &probe(0.05, Some(0.3)), &p, &t).is_none());
        // The same probe on a surface four times finer: no warning.
        let (p, t) = grid(40);
        assert!(slip_warning(0, &probe(0.05, Some(0.0)), &p, &t).is_none());
    }

    #[test]
    fn a_fine_surface_too_coarse_for_the_probe_is_warned_of_with_the_level_that_fixes_it() {
        let (p, t) = grid(10); // edges 0.1: a probe of radius 0.25 spans 5 of them
        let w = fine_slip_warning(0, &probe(0.25, Some(0.0)), &p, &t, 0);
        assert!(
            w.as_deref()
                .is_some_and(|w| w.contains("visual_levels = 1")),
            "{w:?}"
        );
        // Already cut twice: the fix counts from there.
        let w = fine_slip_warning(0, &probe(0.06, Some(0.0)), &p, &t, 2).unwrap();
        assert!(
            w.contains("visual_levels = 5") && w.contains("beyond"),
            "{w}"
        );
        // Spanning 8 edges, sticking or with friction: nothing.
        assert!(fine_slip_warning(0, &probe(0.4, Some(0.0)), &p, &t, 0).is_none());
        assert!(fine_slip_warning(0, &probe(0.25, None), &p, &t, 0).is_none());
        assert!(fine_slip_warning(0, &probe(0.25, Some(0.3)), &p, &t, 0).is_none());
        // One level halves the edges.
        assert_eq!(fine_levels_needed(0.25, 0.1), 1);
        assert_eq!(fine_levels_needed(0.4, 0.1), 0);
        assert_eq!(fine_levels_needed(0.06, 0.1), 3);
    }
}
