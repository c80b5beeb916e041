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
    let median = near[near.len() / 2];
    (2.0 * radius < SLIP_RATIO * median).then(|| {
        format!(
            "instrument {index} (\"{}\"): a frictionless {} of radius {radius:.3e} m on surface \
             edges of {median:.3e} m near its path (median of {}) can slip between the \
             vertices; give the scene a finer contact surface ([mesh] visual), a finer mesh, \
             or contact = \"sticking\" (docs/contact.md)",
            inst.name,
            if matches!(inst.shape(), Some(Shape::Capsule { .. })) {
                "capsule"
            } else {
                "probe"
            },
            near.len()
        )
    })
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
}
