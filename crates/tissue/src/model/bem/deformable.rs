//! `Deformable` for `Bem`: constraints become a fixed set (re-factorised when it changes)
//! and a contact set (a Woodbury update); each step is one O(n·contacts) solve, optionally
//! relaxed by eq. 13; reactions are tractions times tributary areas.

use crate::error::SimError;
use crate::interact::{Constraints, Loads, PointContact};
use crate::math::{Mat3, Real, Vec3, is_finite_vec};
use crate::model::{
    CutInfo, CutPath, Deformable, ModelInfo, Progress, Reactions, StepInfo, SurfaceView,
};

use super::model::Bem;
use super::system::BemSystem;
use super::viscous::relax;

impl Bem {
    /// Re-computes u_L = W P_load after a change of loads or of the factorisation.
    pub(super) fn refresh_load_response(&mut self) -> Result<(), SimError> {
        if self.system.is_factored() {
            self.system
                .load_response(&self.load_traction, &mut self.u_load)?;
            self.gravity_response()?;
            if let Some(body) = &self.body {
                for (u, g) in self.u_load.iter_mut().zip(&body.x) {
                    *u += g;
                }
            }
        }
        Ok(())
    }

    fn update_distances(&mut self) {
        if self.params.alpha > 0.0 {
            let contacts = self.system.contacts();
            let sources: Vec<usize> = if contacts.is_empty() {
                let f = self.system.fixed();
                (0..f.len()).filter(|&v| f[v]).collect()
            } else {
                contacts.to_vec()
            };
            self.distance = self.graph.distances(&sources);
        }
    }

    /// Checks `c` (as `Constraints::surface_displacements` does: a vertex that does not
    /// exist or a non-finite target is an error naming it) into the reused masks: the fixed
    /// set, each vertex's held displacement and direction (`normals`, as
    /// `set_constraints_along` takes them; fixed wins, the last prescribed entry counts) and
    /// the contacts (held, not fixed), ascending. Nothing of the model changes.
    fn stage_constraints(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<(), SimError> {
        let rest = &self.surface.vertices;
        let n = rest.len();
        let bad = |v: u32| SimError::BadConstraint {
            vertex: v as usize,
            count: n,
        };
        if let Some(&v) = c.fixed.iter().find(|&&v| v as usize >= n) {
            return Err(bad(v));
        }
        for p in &c.prescribed {
            if p.vertex as usize >= n {
                return Err(bad(p.vertex));
            }
            if !is_finite_vec(p.position) {
                return Err(SimError::BadParameter {
                    name: "prescribed",
                    value: format!("surface vertex {} -> {}", p.vertex, p.position),
                    reason: "the target position is not finite".into(),
                });
            }
        }
        let s = &mut self.scratch;
        s.fixed.clear();
        s.fixed.resize(n, false);
        for &v in &c.fixed {
            s.fixed[v as usize] = true;
        }
        s.held.clear();
        s.held.resize(n, None);
        s.along.clear();
        s.along.resize(n, Vec3::ZERO);
        for (entry, p) in c.prescribed.iter().enumerate() {
            let v = p.vertex as usize;
            if !s.fixed[v] {
                s.held[v] = Some(p.position - rest[v]);
                s.along[v] = normals
                    .get(entry)
                    .copied()
                    .flatten()
                    .map_or(Vec3::ZERO, |n| n.normalize_or_zero());
            }
        }
        s.contacts.clear();
        s.contacts.extend((0..n).filter(|&v| s.held[v].is_some()));
        Ok(())
    }

    /// Static solution from the current constraints and loads: targets, tractions, reactions.
    fn solve_static(&mut self) -> Result<(), SimError> {
        let m = 3 * self.contact_targets.len();
        self.p_contact.resize(m, 0.0);
        // Gravity: the homogeneous problem holds the contacts at u* − u_p.
        self.homogeneous_targets.clear();
        for (k, &v) in self.system.contacts().iter().enumerate() {
            let shift = self.body.as_ref().map_or(Vec3::ZERO, |b| {
                b.force.displacement(self.surface.vertices[v])
            });
            self.homogeneous_targets
                .push(self.contact_targets.get(k).copied().unwrap_or(Vec3::ZERO) - shift);
        }
        // Contacts held along their normals (a direction each) have the held directions'
        // block solved per step; else the kept capacitance inverse answers.
        let along = self.contact_normals.len() == self.system.contacts().len()
            && self.contact_normals.iter().any(|n| *n != Vec3::ZERO);
        // Points pushed by instruments are solved with the contacts (`points`); without
        // them, the contacts' own solves: the haptic path is unchanged.
        let points = !self.points.is_empty();
        if points {
            self.solve_points()?;
        } else if along {
            self.system.solve_along(
                &self.homogeneous_targets,
                &self.contact_normals,
                &self.u_load,
                (&mut self.x, &mut self.p_contact),
                &mut self.held,
            )?;
        } else {
            self.system.solve(
                &self.homogeneous_targets,
                &self.u_load,
                &mut self.x,
                &mut self.p_contact,
            )?;
        }
        let body = self.body.as_ref();
        let particular = |x: Vec3| body.map_or(Vec3::ZERO, |b| b.force.displacement(x));
        let fixed = self.system.fixed();
        let at = |x: &[Real], v: usize| Vec3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
        // The points' pushes act as loads (a known traction over the vertex's hat).
        let load = |v: usize| {
            at(&self.load_traction, v)
                + if points {
                    at(&self.point_traction, v)
                } else {
                    Vec3::ZERO
                }
        };
        let area = |v: usize| traction_area(&self.system, &self.areas, v);
        for (v, &is_fixed) in fixed.iter().enumerate() {
            let rest = self.surface.vertices[v];
            if is_fixed {
                self.target[v] = rest;
                // The particular field's traction over the support, as a mean traction.
                let extra = body.map_or(Vec3::ZERO, |b| b.support[v] / area(v));
                self.traction[v] = at(&self.x, v) + extra;
            } else {
                self.target[v] = rest + at(&self.x, v) + particular(rest);
                self.traction[v] = load(v);
            }
        }
        for (k, &v) in self.system.contacts().iter().enumerate() {
            // A contact held along its normal stays where the solve slid it (as a free
            // vertex, above); one held in full is at its target.
            if !(along && self.contact_normals[k] != Vec3::ZERO) {
                self.target[v] = self.surface.vertices[v] + self.contact_targets[k];
            }
            self.traction[v] += at(&self.p_contact, k);
        }
        // The tissue pushes on its support with the load on that vertex minus the traction
        // the support applies over the area it acts on. A load on a contact acts over the
        // vertex's whole hat (it is known traction, on either side of a contact rim), so
        // the contact's reaction is its unknown traction over its support alone.
        let reaction = |v: usize| {
            if fixed[v] {
                self.point_forces[v] - self.traction[v] * area(v)
            } else {
                -(self.traction[v] - load(v)) * area(v)
            }
        };
        self.reactions.distribute(|v| reaction(v as usize));
        Ok(())
    }
}

impl Deformable for Bem {
    fn kind(&self) -> &'static str {
        "bem"
    }

    fn surface(&self) -> SurfaceView<'_> {
        SurfaceView {
            positions: &self.positions,
            triangles: &self.surface.triangles,
        }
    }

    fn rest_surface(&self) -> &[Vec3] {
        &self.surface.vertices
    }

    /// A new fixed set re-factorises (O(n³)); a new contact set costs a Woodbury update.
    /// Reactions go to the first fixed entry of a vertex, else its last prescribed entry.
    /// With the same vertices as the last call (targets may move) nothing is allocated.
    fn set_constraints(&mut self, c: &Constraints) -> Result<(), SimError> {
        self.set_constraints_along(c, &[]).map(|_| ())
    }

    /// `set_constraints`; an entry with a direction n is held along n only, solved exactly
    /// with the pre-inverted response (`BemSystem::solve_along`).
    fn set_constraints_along(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<bool, SimError> {
        self.stage_constraints(c, normals)?;
        self.assemble_pending();
        if self.scratch.fixed.as_slice() != self.system.fixed() || !self.system.is_factored() {
            let stage = "bem: factorising A0 and W = A0^-1 G";
            self.progress.report(stage, 0.0);
            self.system.factor(&self.scratch.fixed)?;
            self.progress.report(stage, 1.0);
            self.refresh_load_response()?;
        }
        let changed = self.scratch.contacts.as_slice() != self.system.contacts();
        self.system.set_contacts(&self.scratch.contacts)?;
        if changed {
            self.update_distances();
        }
        self.contact_targets.clear();
        let held = &self.scratch.held;
        self.contact_targets.extend(
            self.scratch
                .contacts
                .iter()
                .map(|&v| held[v].unwrap_or(Vec3::ZERO)),
        );
        self.contact_normals.clear();
        let along = &self.scratch.along;
        self.contact_normals
            .extend(self.scratch.contacts.iter().map(|&v| along[v]));
        self.reactions.set(c);
        self.points.clear();
        self.point_lambda.clear();
        Ok(true)
    }

    fn holds_point_contacts(&self) -> bool {
        true
    }

    /// Checked (a vertex that does not exist, a non-finite number: an error naming the
    /// point), then solved with the held contacts from the next step on (`points`). A
    /// point whose vertices are all fixed is held by the support: it is not pushed.
    fn set_point_contacts(&mut self, points: &[PointContact]) -> Result<bool, SimError> {
        self.stage_points(points)?;
        Ok(true)
    }

    fn point_reactions(&self) -> &[Real] {
        &self.point_lambda
    }

    /// Point loads become tractions over their vertex's tributary area; gravity (times the
    /// density) acts through a particular solution (`body_force`), computed once per gravity
    /// and fixed set, O(n²).
    fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        if !is_finite_vec(loads.gravity) {
            return Err(SimError::BadParameter {
                name: "gravity",
                value: loads.gravity.to_string(),
                reason: "must be finite".into(),
            });
        }
        let n = self.surface.vertices.len();
        let mut forces = vec![Vec3::ZERO; n];
        for &(v, f) in &loads.point_loads {
            let slot = forces.get_mut(v as usize).ok_or(SimError::BadConstraint {
                vertex: v as usize,
                count: n,
            })?;
            if !is_finite_vec(f) {
                return Err(SimError::BadParameter {
                    name: "point_loads",
                    value: format!("surface vertex {v} -> {f}"),
                    reason: "the force is not finite".into(),
                });
            }
            *slot += f;
        }
        // Nothing changes on error (a non-finite gravity response).
        let before = (
            self.load_traction.clone(),
            std::mem::replace(&mut self.point_forces, forces),
            std::mem::replace(&mut self.gravity, loads.gravity),
            self.u_load.clone(),
        );
        for (v, f) in self.point_forces.iter().enumerate() {
            let p = *f / self.areas[v];
            self.load_traction[3 * v..3 * v + 3].copy_from_slice(&[p.x, p.y, p.z]);
        }
        let refreshed = self.refresh_load_response();
        if refreshed.is_err() {
            (
                self.load_traction,
                self.point_forces,
                self.gravity,
                self.u_load,
            ) = before;
            self.body = None;
        }
        refreshed
    }

    /// The static solution; with `alpha > 0`, one step of eq. 13 toward it.
    fn step(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        if self.params.alpha > 0.0 && !(dt.is_finite() && dt > 0.0) {
            return Err(SimError::BadTimeStep { dt });
        }
        // Contacts waiting on background rim solves switch over when these land.
        self.system.collect_rim_solves()?;
        self.solve_static()?;
        if self.params.alpha > 0.0 {
            relax(
                &mut self.positions,
                &self.target,
                &self.distance,
                self.params.alpha,
                dt,
            );
        } else {
            self.positions.copy_from_slice(&self.target);
        }
        // With points, the pivoting rounds of their complementarity solve.
        let (iterations, capped) = if self.points.is_empty() {
            (0, false)
        } else {
            (self.point_rows.rounds, self.point_rows.capped)
        };
        Ok(StepInfo {
            iterations,
            capped,
            ..StepInfo::default()
        })
    }

    /// The reactions are −P_c · area_c with P_C = W̃_CC⁻¹ (targets − u_L): linear in the
    /// targets, so the stiffness is exact and the same whatever the targets are.
    /// A contact held along its normal only has a stiffness along it alone: not in this
    /// closed form (`None`; the haptic loop then estimates it from successive updates).
    fn prescribed_stiffness(&self, entries: std::ops::Range<usize>) -> Option<Mat3> {
        if self.contact_normals.iter().any(|n| *n != Vec3::ZERO) || !self.points.is_empty() {
            return None;
        }
        let vertices: Vec<usize> = (self.reactions.owned_prescribed(entries)?.iter())
            .map(|&v| v as usize)
            .collect();
        Some(
            -self.system.held_traction_stiffness(&vertices, |v| {
                traction_area(&self.system, &self.areas, v)
            })?,
        )
    }

    fn reactions(&self) -> Reactions<'_> {
        self.reactions.reactions()
    }

    /// Opens the incision as a narrow groove (`cut`) and extends the pre-inverted system by
    /// bordering (`border`): no re-factorisation. Consecutive sweeps form one stroke whose
    /// groove opens when the blade leaves the tissue (`stroke`).
    fn cut(&mut self, blade: &CutPath) -> Result<CutInfo, SimError> {
        self.cut_stroke(blade)
    }

    /// A stroke still held (the blade was inside when the scalpel went away) opens now.
    fn end_cut(&mut self) -> Result<CutInfo, SimError> {
        match self.pending_cut.take() {
            Some((start, end)) => self.incise_when_ready(&CutPath { start, end }),
            None => Ok(self.no_cut()),
        }
    }

    /// An incision computed in the background (real time) lands here.
    fn finish_background(&mut self) -> Result<Option<CutInfo>, SimError> {
        self.finish_incision()
    }

    fn background(&self) -> Option<String> {
        self.incisions.describe(self.system.last_cut_seconds)
    }

    fn set_progress(&mut self, progress: Progress) {
        self.progress = progress;
    }

    /// Incisions (always) and rim solves (unless the scene chose, `background_rim_solves`)
    /// go to the background in real time.
    fn set_real_time(&mut self, on: bool) {
        self.real_time = on;
        if self.params.background_rim_solves.is_none() {
            self.system.set_rim_background(on);
        }
    }

    fn reset(&mut self) {
        self.pending_cut = None;
        self.positions.copy_from_slice(&self.surface.vertices);
        self.target.copy_from_slice(&self.surface.vertices);
        self.traction.iter_mut().for_each(|t| *t = Vec3::ZERO);
        self.point_lambda.iter_mut().for_each(|l| *l = 0.0);
        self.reactions.distribute(|_| Vec3::ZERO);
    }

    fn info(&self) -> ModelInfo {
        let dofs = self.system.dofs();
        let s = &self.system;
        ModelInfo {
            kind: self.kind(),
            nodes: self.surface.vertices.len(),
            dofs,
            elements: self.surface.triangles.len(),
            surface_vertices: self.surface.vertices.len(),
            // H, G, W, the LU of A₀ and the contact-rim cache.
            memory_bytes: 4 * dofs * dofs * 8 + s.rim_cache_usage().0,
            precompute_seconds: self.assembly_seconds + s.last_factor_seconds,
            is_static: self.params.alpha == 0.0,
            details: vec![
                ("assembly_s".into(), format!("{:.3}", self.assembly_seconds)),
                ("factor_s".into(), format!("{:.3}", s.last_factor_seconds)),
                ("factorizations".into(), s.factorizations.to_string()),
                ("woodbury_updates".into(), s.woodbury_updates.to_string()),
                ("cuts".into(), self.cuts.to_string()),
                ("borderings".into(), s.borderings().to_string()),
                ("last_cut_s".into(), format!("{:.3}", s.last_cut_seconds)),
                ("contacts".into(), s.contacts().len().to_string()),
                ("rim_cache_pairs".into(), s.rim_cache_usage().1.to_string()),
                (
                    "rim_pairs_solved".into(),
                    s.rim_cache_counts().0.to_string(),
                ),
                ("alpha".into(), self.params.alpha.to_string()),
            ],
        }
    }
}

/// The area vertex v's unknown traction acts on: a fixed vertex's acts only on the fixed side
/// of the rim, and so may a contact's (`BemSystem::support_area`); else its tributary area
/// (`areas`).
fn traction_area(system: &BemSystem, areas: &[Real], v: usize) -> Real {
    system.support_area(v).unwrap_or(areas[v])
}
