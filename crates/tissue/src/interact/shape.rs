//! The solid shapes of pushing instruments: a sphere (probe tip), a capsule (a tool shaft), a
//! half-space (a retractor blade or a table) and an axis-aligned box. Each answers, for a
//! point, how deep it is inside, the outward normal there and the nearest point of its
//! surface: everything contact needs, written once for every shape.

use crate::math::{Real, Vec3};

/// A shape placed at an instrument's position (`at`, the path point).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A ball of `radius` centred at the path point.
    Sphere { radius: Real },
    /// The points within `radius` of the segment from the path point (the tip) `length` m
    /// along `axis` (unit): the shaft of a laparoscopic tool.
    Capsule {
        radius: Real,
        axis: Vec3,
        length: Real,
    },
    /// The half-space behind the plane through the path point: the instrument fills
    /// `normal · (x − at) ≤ 0`, `normal` (unit) pointing toward the tissue.
    Plane { normal: Vec3 },
    /// An axis-aligned box centred at the path point with half extents `half`.
    Box { half: Vec3 },
}

/// Where a point is relative to a shape.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Closest {
    /// Signed distance to the surface, negative inside, in m.
    pub depth: Real,
    /// Outward unit normal of the surface at `point` (toward the tissue).
    pub normal: Vec3,
    /// The nearest point of the surface.
    pub point: Vec3,
}

impl Shape {
    /// A length that sets the shape's scale (tolerances are relative to it), in m.
    pub fn size(&self) -> Real {
        match *self {
            Shape::Sphere { radius } | Shape::Capsule { radius, .. } => radius,
            // A half-space has no size: a millimetre, the scale of surgical tissue meshes.
            Shape::Plane { .. } => 1e-3,
            Shape::Box { half } => half.min_element(),
        }
    }

    /// A ball holding every point of the shape that can be inside it, for the BVH query;
    /// `None` for the unbounded half-space.
    pub fn bounds(&self, at: Vec3) -> Option<(Vec3, Real)> {
        match *self {
            Shape::Sphere { radius } => Some((at, radius)),
            Shape::Capsule {
                radius,
                axis,
                length,
            } => Some((at + 0.5 * length * axis, radius + 0.5 * length)),
            Shape::Plane { .. } => None,
            Shape::Box { half } => Some((at, half.length())),
        }
    }

    /// For the round shapes (sphere, capsule): the point of their core (the centre, the
    /// axis segment) nearest `p`, and their radius; `None` for the flat ones, whose deepest
    /// point in a flat face is always one of its vertices.
    pub fn core(&self, at: Vec3, p: Vec3) -> Option<(Vec3, Real)> {
        match *self {
            Shape::Sphere { radius } => Some((at, radius)),
            Shape::Capsule {
                radius,
                axis,
                length,
            } => Some((at + (p - at).dot(axis).clamp(0.0, length) * axis, radius)),
            Shape::Plane { .. } | Shape::Box { .. } => None,
        }
    }

    /// Depth, normal and nearest surface point of `p`, the shape placed at `at`. A point on
    /// a sphere's centre or a capsule's axis goes along `fallback` (its surface normal, or
    /// +z when that is zero too).
    pub fn closest(&self, at: Vec3, p: Vec3, fallback: Vec3) -> Closest {
        match *self {
            Shape::Sphere { radius } => ball(at, radius, p, fallback),
            Shape::Capsule {
                radius,
                axis,
                length,
            } => {
                let s = (p - at).dot(axis).clamp(0.0, length);
                ball(at + s * axis, radius, p, fallback)
            }
            Shape::Plane { normal } => {
                let depth = (p - at).dot(normal);
                Closest {
                    depth,
                    normal,
                    point: p - depth * normal,
                }
            }
            Shape::Box { half } => {
                let d = p - at;
                let outside = d.abs() - half;
                if outside.max_element() > 0.0 {
                    // The gap from the clamped offset, not from the clamped point: along an
                    // axis where p is within the box's extent it is then exactly zero. From
                    // p − (at + clamp) it was round-off (1e-19 m) there, which outweighed a
                    // point resting on a face to round-off and gave it a side face's normal.
                    let c = d.clamp(-half, half);
                    let gap = d - c;
                    let q = at + c;
                    return Closest {
                        depth: gap.length(),
                        normal: gap.normalize_or_zero(),
                        point: q,
                    };
                }
                // Inside: out through the nearest face.
                let axis = if outside.x >= outside.y && outside.x >= outside.z {
                    0
                } else if outside.y >= outside.z {
                    1
                } else {
                    2
                };
                let mut normal = Vec3::ZERO;
                normal[axis] = if d[axis] >= 0.0 { 1.0 } else { -1.0 };
                let mut point = p;
                point[axis] = at[axis] + normal[axis] * half[axis];
                Closest {
                    depth: outside[axis],
                    normal,
                    point,
                }
            }
        }
    }
}

fn ball(center: Vec3, radius: Real, p: Vec3, fallback: Vec3) -> Closest {
    let d = p - center;
    let len = d.length();
    let normal = if len > 1e-300 {
        d / len
    } else if fallback.length() > 0.0 {
        fallback.normalize()
    } else {
        Vec3::Z
    };
    Closest {
        depth: len - radius,
        normal,
        point: center + radius * normal,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(shape: Shape, at: Vec3, p: Vec3, depth: Real, normal: Vec3) {
        let c = shape.closest(at, p, Vec3::ZERO);
        assert!((c.depth - depth).abs() < 1e-12, "{shape:?} {p}: {c:?}");
        assert!(c.normal.distance(normal) < 1e-12, "{shape:?} {p}: {c:?}");
        // The nearest point is on the surface, `depth` along the normal from p.
        assert!(
            (c.point + c.depth * c.normal).distance(p) < 1e-12,
            "{shape:?} {p}: {c:?}"
        );
        let again = shape.closest(at, c.point, Vec3::ZERO);
        assert!(again.depth.abs() < 1e-12, "{shape:?}: {again:?}");
    }

    #[test]
    fn every_shape_gives_depth_normal_and_surface_point() {
        let at = Vec3::new(1.0, 2.0, 3.0);
        let sphere = Shape::Sphere { radius: 0.5 };
        check(sphere, at, at + Vec3::new(0.0, 0.0, 0.2), -0.3, Vec3::Z);
        check(sphere, at, at + Vec3::new(0.6, 0.0, 0.0), 0.1, Vec3::X);
        let capsule = Shape::Capsule {
            radius: 0.1,
            axis: Vec3::X,
            length: 2.0,
        };
        // Beside the shaft, past its far end, behind its tip.
        check(capsule, at, at + Vec3::new(1.0, 0.05, 0.0), -0.05, Vec3::Y);
        check(capsule, at, at + Vec3::new(2.3, 0.0, 0.0), 0.2, Vec3::X);
        check(
            capsule,
            at,
            at + Vec3::new(-0.05, 0.0, 0.0),
            -0.05,
            -Vec3::X,
        );
        let plane = Shape::Plane { normal: Vec3::Y };
        check(plane, at, at + Vec3::new(5.0, -0.25, 1.0), -0.25, Vec3::Y);
        check(plane, at, at + Vec3::new(-5.0, 0.25, 1.0), 0.25, Vec3::Y);
        let cube = Shape::Box {
            half: Vec3::new(1.0, 0.5, 0.25),
        };
        check(cube, at, at + Vec3::new(0.1, -0.4, 0.0), -0.1, -Vec3::Y);
        check(cube, at, at + Vec3::new(0.2, 0.1, 0.2), -0.05, Vec3::Z);
        check(cube, at, at + Vec3::new(1.3, 0.1, 0.0), 0.3, Vec3::X);
    }

    #[test]
    fn bounds_hold_the_shape() {
        let at = Vec3::new(0.0, 1.0, 0.0);
        let capsule = Shape::Capsule {
            radius: 0.1,
            axis: Vec3::Z,
            length: 1.0,
        };
        let (c, r) = capsule.bounds(at).unwrap();
        for p in [at + Vec3::new(0.1, 0.0, 0.0), at + Vec3::new(0.0, 0.0, 1.1)] {
            assert!(p.distance(c) <= r + 1e-12);
        }
        assert!(Shape::Plane { normal: Vec3::Z }.bounds(at).is_none());
    }
}
