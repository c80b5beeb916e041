//! A fine contact surface's points held exactly against an instrument, by the models that
//! solve point contacts with their own response (`Deformable::set_point_contacts`).
//!
//! Each fine point near the instrument becomes a unilateral row on the instrument's tangent
//! plane at the point's nearest surface point; the model solves all of them with its
//! stiffness as one complementarity problem, so a point either rests on its plane and is
//! pushed, or is off it and free, and none pulls. The planes are those of the current
//! positions only, nothing is carried from one step to the next: a static model's loop
//! solves, moves each plane to where its point now is nearest the instrument, and solves
//! again until the planes stop moving, so the answer is the equilibrium of the position the
//! instrument is at, whatever the path and the step that brought it there.

use crate::interact::PointContact;
use crate::interact::contact::{exit_along, on_far_side, passed_to_far_side};
use crate::interact::fine_surface::MappedSurface;
use crate::interact::shape::Shape;
use crate::math::{Real, Vec3};

/// One fine point's contact: which fine vertex, and its row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FinePoint {
    pub fine: u32,
    pub contact: PointContact,
}

/// The fine points inside `shape` placed at `at` or outside it by less than `margin` m, in
/// fine-vertex order, each on the shape's tangent plane at its nearest surface point, for
/// the coarse surface at `coarse` (rest `coarse_rest`). Only the fine vertices near the
/// shape's bounding ball are placed (`MappedSurface::near`; every one for a half-space):
/// a step's cost does not grow with the whole fine surface.
///
/// `stepped`: for a dynamic model's step, which gives a plane's offset to its particles as
/// velocity within the step: a point a curved instrument has only just reached is never
/// sent out through its far side (`contact::passed_to_far_side`), where a fold of the
/// surface (normals turned inward) threw `volumetric-spring-mass`'s particles 163 mm in one
/// substep. A static solve (false) keeps `contact::on_far_side` at any depth: it puts its
/// points in equilibrium on their planes, and there the nearest way out for the shallow
/// points of a probe that came through the liver made the comparison's random paths fail
/// more often (`fem-static` 3/4 → 2/4).
pub fn gather(
    fine: &MappedSurface,
    coarse_rest: &[Vec3],
    coarse: &[Vec3],
    shape: &Shape,
    at: Vec3,
    margin: Real,
    stepped: bool,
) -> Vec<FinePoint> {
    // A cheap test first: a point farther than the shape's bounding ball plus the margin
    // cannot be near it (the half-space has no ball and is tested point by point).
    let ball = shape.bounds(at);
    let mut candidates = Vec::new();
    match ball {
        Some((c, r)) => fine.near(coarse, c, r + margin, &mut candidates),
        None => candidates.extend(0..fine.len() as u32),
    }
    let position = |v: u32| fine.position(v as usize, coarse_rest, coarse);
    let mut out = Vec::new();
    for j in candidates {
        let p = position(j);
        if let Some((c, r)) = ball
            && p.distance_squared(c) > (r + margin) * (r + margin)
        {
            continue;
        }
        let Some((vertices, weights)) = fine.tie(j as usize) else {
            continue;
        };
        let Some(&rest) = fine.rest.get(j as usize) else {
            continue;
        };
        let mut near = shape.closest(at, p, Vec3::ZERO);
        if near.depth >= margin {
            continue;
        }
        // A point the instrument's nearest surface would push out of the tissue (the
        // instrument arrived past its centre in one move, as the viewer's probe does) leaves
        // along the tissue's inward normal instead (`contact::exit_along`).
        if near.depth < 0.0 {
            let outward = fine.outward_normal(j as usize, &position);
            let far = if stepped {
                passed_to_far_side(shape, &near, outward)
            } else {
                on_far_side(shape, near.normal, outward)
            };
            if far {
                near = exit_along(shape, at, p, -outward);
            }
        }
        // A point on an edge of a box (outside it by round-off) has no direction out: it
        // touches without pushing, and the next gather finds it on one side
        // (`PointContact::check` refuses a normal that is not a unit vector).
        if (near.normal.length() - 1.0).abs() > 1e-6 {
            continue;
        }
        out.push(FinePoint {
            fine: j,
            contact: PointContact {
                vertices,
                weights,
                rest,
                normal: near.normal,
                target: near.point,
            },
        });
    }
    out
}

/// How far the planes of `new` moved from those of `old` for the same fine points, along
/// their normals (m), and whether `new` holds a penetrating point `old` did not have (fine
/// vertex `v` being at `position(v)`).
pub fn change(
    old: &[FinePoint],
    new: &[FinePoint],
    position: &dyn Fn(u32) -> Vec3,
) -> (Real, bool) {
    let mut moved: Real = 0.0;
    let mut entered = false;
    let mut i = 0;
    for q in new {
        while i < old.len() && old[i].fine < q.fine {
            i += 1;
        }
        match old.get(i).filter(|o| o.fine == q.fine) {
            Some(o) => {
                // The planes' offset at the point: how much the row's value changes.
                let a = o.contact.normal.dot(o.contact.target - o.contact.rest);
                let b = q.contact.normal.dot(q.contact.target - q.contact.rest);
                moved = moved.max((a - b).abs()).max(
                    (o.contact.normal - q.contact.normal).length()
                        * (q.contact.target - q.contact.rest).length(),
                );
            }
            None => {
                let p = position(q.fine);
                entered |= q.contact.normal.dot(p - q.contact.target) < 0.0;
            }
        }
    }
    (moved, entered)
}

/// Aitken's acceleration of a static loop's planes (Irons and Tuck's vector form, as used
/// for partitioned fluid–structure coupling). The loop is a fixed-point iteration: each
/// solve leaves the points where the planes let them slide, and each plane moves to the
/// instrument's surface nearest its point again. On a curved instrument every round takes
/// back only part of the last move (about 0.6 of it on the stuffed liver under a 5 mm
/// probe), so the loop converges linearly and a press took 20 to 130 solves per step. The
/// relaxation moves each target by ω times what the round asked, ω estimated from the
/// last two rounds' moves (a secant on the whole set), then puts it back on the instrument.
/// It changes the path to the fixed point, not the fixed point: the loop still stops only
/// when a round moves no plane by more than its tolerance.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlaneRelaxation {
    /// The last round's asked moves, point by point (empty: no round yet this set).
    last: Vec<Vec3>,
    /// The last round's ids, to know the set is the same.
    ids: Vec<u32>,
    omega: Real,
}

/// ω's bounds: no step backwards or smaller than a tenth of the asked one, and no more than
/// five times it (a rate of 0.8); beyond, the secant is trusted less than the plain round.
const OMEGA_RANGE: (Real, Real) = (0.1, 5.0);

impl PlaneRelaxation {
    /// Forgets the rounds: a new step, or a point set that changed.
    pub fn reset(&mut self) {
        self.last.clear();
        self.ids.clear();
        self.omega = 1.0;
    }

    /// `new` are the planes a round asks for, `old` those of the solve just taken, for the
    /// same instrument (`shape` at `at`). When both hold the same points as the last round,
    /// each target of `new` is moved to old + ω (new − old) and put back on the instrument
    /// (its nearest surface point, with that point's normal); otherwise the round is taken
    /// as asked and the relaxation starts again from it.
    pub fn relax(&mut self, old: &[FinePoint], new: &mut [FinePoint], shape: &Shape, at: Vec3) {
        let same =
            old.len() == new.len() && old.iter().zip(new.iter()).all(|(o, n)| o.fine == n.fine);
        if !same {
            self.reset();
            return;
        }
        let asked: Vec<Vec3> = old
            .iter()
            .zip(new.iter())
            .map(|(o, n)| n.contact.target - o.contact.target)
            .collect();
        let continues = self.ids.len() == new.len()
            && self.ids.iter().zip(new.iter()).all(|(&i, n)| i == n.fine);
        if continues {
            let (mut num, mut den) = (0.0, 0.0);
            for (r, l) in asked.iter().zip(&self.last) {
                let d = *r - *l;
                num += l.dot(d);
                den += d.dot(d);
            }
            if den > 0.0 {
                self.omega = (-self.omega * num / den).clamp(OMEGA_RANGE.0, OMEGA_RANGE.1);
            }
        } else {
            self.omega = 1.0;
        }
        self.ids = new.iter().map(|n| n.fine).collect();
        self.last = asked;
        if self.omega == 1.0 {
            return;
        }
        for ((n, o), r) in new.iter_mut().zip(old).zip(&self.last) {
            let near = shape.closest(at, o.contact.target + self.omega * *r, n.contact.normal);
            if (near.normal.length() - 1.0).abs() <= 1e-6 {
                n.contact.target = near.point;
                n.contact.normal = near.normal;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_near_a_ball_are_gathered_on_its_tangent_planes() {
        // Three fine points on one coarse triangle: one inside the ball, one just outside
        // within the margin, one far.
        let coarse = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        let fine = vec![
            Vec3::new(0.2, 0.2, 0.0),
            Vec3::new(0.3, 0.1, 0.0),
            Vec3::new(0.1, 0.8, 0.0),
        ];
        let m = MappedSurface::new(fine.clone(), vec![[0, 1, 2]], &coarse, &[[0, 1, 2]]).unwrap();
        let ball = Shape::Sphere { radius: 0.1 };
        let at = Vec3::new(0.2, 0.2, 0.09);
        let got = gather(&m, &coarse, &coarse, &ball, at, 0.02, false);
        let ids: Vec<u32> = got.iter().map(|p| p.fine).collect();
        assert_eq!(ids, vec![0]);
        let k = got[0].contact;
        assert!((k.normal + Vec3::Z).length() < 1e-12, "{}", k.normal);
        assert!((k.target - Vec3::new(0.2, 0.2, -0.01)).length() < 1e-12);
        // The point must move 1 cm down to reach the plane.
        assert!((k.reach() - 0.01).abs() < 1e-12);
        let wider = gather(&m, &coarse, &coarse, &ball, at, 0.2, false);
        assert_eq!(wider.len(), 2);
        let (moved, entered) = change(&got, &wider, &|v| fine[v as usize]);
        assert_eq!(moved, 0.0);
        // The added point is outside the ball: nothing new penetrates.
        assert!(!entered);
    }
}
