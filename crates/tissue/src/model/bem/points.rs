//! Fine-surface points pushed by instruments (`Deformable::set_point_contacts`) on the BEM:
//! the held contacts and the points solved together on the pre-inverted response
//! (`solve::points`), then superposed on the loads' response like the contacts' tractions.
//!
//! A held contact's multiplier is the force of its unknown traction (traction times the
//! area it acts on: `traction_area`, the rim-corrected support with discontinuous contacts,
//! whose response is W̃); a point's push on a vertex is a load, a traction over the vertex's
//! tributary area whose response is W (as `set_loads`' point loads). Both per newton, so
//! that M is nearly symmetric (Betti's reciprocity, up to the collocation's error): its
//! symmetric part guesses the pushing points and M itself answers (`PointRows::refine`).
//! Displacements are the homogeneous problem's (gravity's particular field is added after),
//! so each row's target is shifted by that field, as the held contacts' are.

use crate::error::SimError;
use crate::interact::PointContact;
use crate::math::{Mat3, Real, Vec3};
use crate::solve::{Source, VertexResponse, block3};

use super::model::Bem;
use super::system::BemSystem;

/// The BEM's response per newton (see the module notes).
struct PerForce<'a> {
    system: &'a BemSystem,
    areas: &'a [Real],
    u_load: &'a [Real],
}

impl VertexResponse for PerForce<'_> {
    const SYMMETRIC: bool = false;

    fn response(&self, j: usize, source: Source) -> Mat3 {
        let k = source.vertex;
        let contact = source
            .held
            .then(|| self.system.contacts.binary_search(&k).ok())
            .flatten();
        match (contact, &self.system.rims) {
            (Some(c), Some(rims)) => {
                let area = rims.area.get(c).copied().unwrap_or(self.areas[k]);
                block3(rims.wt.as_ref(), 3 * j, 3 * c) / area
            }
            _ => block3((*self.system.w).as_ref(), 3 * j, 3 * k) / self.areas[k],
        }
    }

    fn free(&self, j: usize) -> Vec3 {
        Vec3::from_slice(&self.u_load[3 * j..3 * j + 3])
    }
}

impl Bem {
    /// Checks and keeps `points` for the next steps (see `Deformable::set_point_contacts`).
    pub(super) fn stage_points(&mut self, points: &[PointContact]) -> Result<(), SimError> {
        let n = self.surface.vertices.len();
        for p in points {
            p.check(n)?;
        }
        self.points.clear();
        self.points.extend_from_slice(points);
        self.point_lambda.clear();
        self.point_lambda.resize(points.len(), 0.0);
        Ok(())
    }

    /// The held contacts and the points together: `x` gets u_L + W̃_{:,C} P_C + W P_points,
    /// `p_contact` the contacts' tractions (their held part), `point_traction` the points'
    /// pushes over their vertices' tributary areas and `point_lambda` each point's push.
    pub(super) fn solve_points(&mut self) -> Result<(), SimError> {
        const AXES: [Vec3; 3] = [Vec3::X, Vec3::Y, Vec3::Z];
        let mut rows = std::mem::take(&mut self.point_rows);
        rows.clear();
        let contacts = self.system.contacts();
        let normal = |k: usize| self.contact_normals.get(k).copied().unwrap_or(Vec3::ZERO);
        for (k, &v) in contacts.iter().enumerate() {
            let t = self.homogeneous_targets[k];
            match normal(k) {
                n if n == Vec3::ZERO => AXES.iter().for_each(|&e| rows.push_held(v, e, e.dot(t))),
                n => rows.push_held(v, n, n.dot(t)),
            }
        }
        let fixed = self.system.fixed();
        let rest = &self.surface.vertices;
        let body = self.body.as_ref();
        let particular = |x: Vec3| body.map_or(Vec3::ZERO, |b| b.force.displacement(x));
        self.point_row.clear();
        for p in &self.points {
            let free = p
                .vertices
                .map(|v| (!fixed[v as usize]).then_some(v as usize));
            let shift: Real = (0..3)
                .filter_map(|i| free[i].map(|v| p.weights[i] * p.normal.dot(particular(rest[v]))))
                .sum();
            let added = rows.push_point(free, p.weights, p.normal, p.reach() - shift);
            self.point_row.push(added.then(|| rows.len() - 1));
        }
        let response = PerForce {
            system: &self.system,
            areas: &self.areas,
            u_load: &self.u_load,
        };
        let solved = rows.solve(&response).map(|l| l.to_vec());
        let lambda = match solved {
            Ok(l) => l,
            Err(e) => {
                self.point_rows = rows;
                return Err(e);
            }
        };
        self.p_contact.iter_mut().for_each(|p| *p = 0.0);
        let mut r = 0;
        for (k, &v) in self.system.contacts().iter().enumerate() {
            let n = normal(k);
            let dirs = if n == Vec3::ZERO { &AXES[..] } else { &[n][..] };
            let mut f = Vec3::ZERO;
            for &e in dirs {
                f += e * lambda[r];
                r += 1;
            }
            let p = f / self.system.support_area(v).unwrap_or(self.areas[v]);
            self.p_contact[3 * k..3 * k + 3].copy_from_slice(&p.to_array());
        }
        self.point_lambda.clear();
        self.point_lambda
            .extend(self.point_row.iter().map(|r| r.map_or(0.0, |r| lambda[r])));
        self.point_traction.iter_mut().for_each(|p| *p = 0.0);
        let (traction, areas) = (&mut self.point_traction, &self.areas);
        rows.forces(|s, f| {
            if !s.held {
                let p = f / areas[s.vertex];
                for i in 0..3 {
                    traction[3 * s.vertex + i] += p[i];
                }
            }
        });
        self.point_rows = rows;
        self.x.copy_from_slice(&self.u_load);
        self.system
            .add_response(&self.p_contact, &self.point_traction, &mut self.x);
        Ok(())
    }
}
