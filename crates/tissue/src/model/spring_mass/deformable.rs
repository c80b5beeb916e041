//! `Deformable` for `SpringModel`: surface-vertex constraints and loads turned into held
//! particles and particle forces, and the integrator's held forces handed back per constraint.
//!
//! A surface vertex follows one particle (surface and volumetric kinds) or the k T2 nodes
//! around it (simplex kind, weight 1/k each). A fixed vertex holds its particles at rest; a
//! prescribed one holds its particle at the target, or translates its ring from where it is
//! now by the vertex's gap to the target (targets averaged when two prescribed vertices share
//! a particle); fixed wins. A particle's held force is shared equally among the constraints
//! that hold it, so the sum over an instrument's vertices is the total force it feels.

use crate::error::SimError;
use crate::integrate::{Hold, PointHold};
use crate::interact::{Constraints, Loads, PointContact};
use crate::math::{Real, Vec3, is_finite_vec};
use crate::model::{
    CutInfo, CutPath, Deformable, ModelInfo, Reactions, StepInfo, SurfaceView, VolumeView,
};

use super::{Kind, SpringModel, SurfaceLink};

/// For each hold, the constraints its force is reported to: (fixed?, index in its list).
#[derive(Clone, Debug, Default)]
pub(crate) struct HeldConstraints {
    claims: Vec<Vec<(bool, u32)>>,
}

impl SpringModel {
    /// The particles a surface vertex follows, with weights.
    fn support(&self, vertex: u32) -> Result<Vec<(usize, Real)>, SimError> {
        let count = self.surface_rest.len();
        let bad = SimError::BadConstraint {
            vertex: vertex as usize,
            count,
        };
        match &self.link {
            SurfaceLink::Nodes(nodes) => nodes
                .get(vertex as usize)
                .map(|&n| vec![(n as usize, 1.0)])
                .ok_or(bad),
            SurfaceLink::Dual(s) => {
                let ring = s.ring(vertex as usize).ok_or(bad)?;
                let w = 1.0 / ring.len().max(1) as Real;
                Ok(ring.iter().map(|&t| (t as usize, w)).collect())
            }
        }
    }

    pub(crate) fn distribute_reactions(&mut self) {
        self.fixed_reactions
            .iter_mut()
            .for_each(|r| *r = Vec3::ZERO);
        self.prescribed_reactions
            .iter_mut()
            .for_each(|r| *r = Vec3::ZERO);
        let forces = self.integrator.held_forces();
        for (claims, f) in self.constraints.claims.iter().zip(forces) {
            let share = *f / claims.len().max(1) as Real;
            for &(fixed, k) in claims {
                let list = if fixed {
                    &mut self.fixed_reactions
                } else {
                    &mut self.prescribed_reactions
                };
                if let Some(r) = list.get_mut(k as usize) {
                    *r += share;
                }
            }
        }
    }
}

impl Deformable for SpringModel {
    fn kind(&self) -> &'static str {
        self.kind.name()
    }

    fn surface(&self) -> SurfaceView<'_> {
        SurfaceView {
            positions: &self.surface_positions,
            triangles: &self.triangles,
        }
    }

    fn rest_surface(&self) -> &[Vec3] {
        &self.surface_rest
    }

    fn volume(&self) -> Option<VolumeView<'_>> {
        (!self.tets.is_empty()).then_some(VolumeView {
            positions: &self.state.x,
            rest_positions: &self.rest,
            tets: &self.tets,
        })
    }

    fn set_constraints(&mut self, c: &Constraints) -> Result<(), SimError> {
        let n = self.rest.len();
        // Per particle: fixed claims, prescribed claims and the summed displacement.
        let mut fixed: Vec<Vec<u32>> = vec![Vec::new(); n];
        let mut prescribed: Vec<(Vec<u32>, Vec3)> = vec![(Vec::new(), Vec3::ZERO); n];
        for (k, &v) in c.fixed.iter().enumerate() {
            for (p, _) in self.support(v)? {
                fixed[p].push(k as u32);
            }
        }
        for (k, pr) in c.prescribed.iter().enumerate() {
            let support = self.support(pr.vertex)?;
            if !is_finite_vec(pr.position) {
                return Err(SimError::BadParameter {
                    name: "prescribed",
                    value: format!("surface vertex {} -> {}", pr.vertex, pr.position),
                    reason: "the target position is not finite".into(),
                });
            }
            // Where each supporting particle must go for the vertex to reach its target.
            // A node-linked vertex is its particle: the target itself. A simplex vertex is
            // rebuilt from its ring, and the rebuild commutes with translation, so the ring
            // moves by the vertex's remaining gap from where it is now and keeps its current
            // shape. (Moving it to its rest shape instead snapped a stretched or crumpled
            // membrane back under the probe, with reactions of several newtons.)
            let v = pr.vertex as usize;
            let gap = pr.position - self.surface_positions[v];
            for (p, _) in support {
                prescribed[p].0.push(k as u32);
                prescribed[p].1 += match self.link {
                    SurfaceLink::Nodes(_) => pr.position,
                    SurfaceLink::Dual(_) => self.state.x[p] + gap,
                };
            }
        }
        let mut holds = Vec::new();
        let mut claims = Vec::new();
        for p in 0..n {
            if !fixed[p].is_empty() {
                holds.push(Hold::new(p, self.rest[p]));
                claims.push(fixed[p].iter().map(|&k| (true, k)).collect());
            } else if !prescribed[p].0.is_empty() {
                let (ks, sum) = &prescribed[p];
                holds.push(Hold::new(p, *sum / ks.len() as Real));
                claims.push(ks.iter().map(|&k| (false, k)).collect());
            }
        }
        self.holds = holds;
        self.integrator.set_points(Vec::new());
        self.constraints = HeldConstraints { claims };
        self.fixed_reactions = vec![Vec3::ZERO; c.fixed.len()];
        self.prescribed_reactions = vec![Vec3::ZERO; c.prescribed.len()];
        Ok(())
    }

    /// Frictionless contacts held by the integrator's push-only projection
    /// (`integrate::Hold::contact`). A particle claimed by contacts only (a simplex vertex's
    /// ring shares its particles with the neighbouring vertices, each with its own normal)
    /// is held along their mean normal n̄, as far along it as the most demanding claim asks
    /// (moved by s along n̄ it meets claim i's plane when s·(n̄·nᵢ) ≥ nᵢ·gᵢ, gᵢ the claim's
    /// target less the particle), as `linked-volumes` holds its elements. Any fixed or
    /// full claim, or normals that cancel, hold it in full. (Particles with claims of
    /// differing normals used to be held in full both ways, and with the vertices near the
    /// instrument handed over too they were pulled onto it: the viewer's frictionless probe
    /// blew `simplex-spring-mass` up on the coarse liver.)
    fn set_constraints_along(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<bool, SimError> {
        self.set_constraints(c)?;
        let (x, surface, link) = (&self.state.x, &self.surface_positions, &self.link);
        for (hold, claims) in self.holds.iter_mut().zip(&self.constraints.claims) {
            let p = hold.particle;
            let planes: Option<Vec<(Vec3, Vec3)>> = claims
                .iter()
                .map(|&(fixed, k)| {
                    let n = normals.get(k as usize).copied().flatten()?;
                    let n = n.normalize_or_zero();
                    let pr = c.prescribed.get(k as usize)?;
                    let target = match link {
                        SurfaceLink::Nodes(_) => pr.position,
                        SurfaceLink::Dual(_) => {
                            x[p] + (pr.position - *surface.get(pr.vertex as usize)?)
                        }
                    };
                    (!fixed && n != Vec3::ZERO && is_finite_vec(n)).then_some((n, target - x[p]))
                })
                .collect();
            let Some(planes) = planes.filter(|p| !p.is_empty()) else {
                continue;
            };
            let sum: Vec3 = planes.iter().map(|(n, _)| *n).sum();
            if sum.length() <= 1e-3 * planes.len() as Real {
                continue;
            }
            let n = sum.normalize();
            let s = planes
                .iter()
                .filter(|(ni, _)| ni.dot(n) > 1e-6)
                .map(|(ni, g)| ni.dot(*g) / ni.dot(n))
                .fold(Real::NEG_INFINITY, Real::max);
            *hold = Hold::contact(p, x[p] + n * s, n);
        }
        Ok(true)
    }

    /// The kinds whose surface vertices are particles, under an explicit scheme: the holds
    /// of `set_constraints_along` made two-sided (`integrate::Hold` with `unilateral` false:
    /// the projection after every substep puts the particle on its plane from either side).
    /// A simplex vertex is rebuilt from its ring (its particles shared by several vertices'
    /// planes) and implicit Euler holds only push-only contacts in its solve: there every
    /// entry is held in full and the answer is false.
    fn set_constraints_two_sided(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<bool, SimError> {
        if !self.holds_point_contacts() {
            return self.set_constraints(c).map(|()| false);
        }
        self.set_constraints_along(c, normals)?;
        self.holds.iter_mut().for_each(|h| h.unilateral = false);
        Ok(true)
    }

    fn contacts_push_only(&self) -> bool {
        true
    }

    /// The kinds whose surface vertices are particles (`spring-mass`,
    /// `volumetric-spring-mass`), under an explicit scheme (`Integrator::holds_points`): a
    /// point is then tied to three particles. A simplex
    /// vertex is rebuilt from its ring (not a fixed weighting of particles) and keeps the
    /// coarse vertices' planes.
    fn holds_point_contacts(&self) -> bool {
        matches!(self.link, SurfaceLink::Nodes(_)) && self.integrator.holds_points()
    }

    /// Each point a push-only contact on its three particles, projected after every
    /// (sub)step by the integrator (`integrate::PointHold`).
    fn set_point_contacts(&mut self, points: &[PointContact]) -> Result<bool, SimError> {
        let SurfaceLink::Nodes(nodes) = &self.link else {
            return Ok(points.is_empty());
        };
        let holds = PointHold::from_contacts(points, nodes, &self.surface_rest)?;
        self.integrator.set_points(holds);
        Ok(true)
    }

    fn point_reactions(&self) -> &[Real] {
        self.integrator.point_pushes()
    }

    fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        if !is_finite_vec(loads.gravity) {
            return Err(SimError::BadParameter {
                name: "gravity",
                value: loads.gravity.to_string(),
                reason: "must be finite".into(),
            });
        }
        let mut external: Vec<Vec3> = self
            .body
            .masses
            .iter()
            .map(|m| loads.gravity * *m)
            .collect();
        for &(v, f) in &loads.point_loads {
            if !is_finite_vec(f) {
                return Err(SimError::BadParameter {
                    name: "point_loads",
                    value: format!("surface vertex {v} -> {f}"),
                    reason: "the force is not finite".into(),
                });
            }
            for (p, w) in self.support(v)? {
                external[p] += w * f;
            }
        }
        self.body.external = external;
        self.loads = loads.clone();
        self.integrator.invalidate();
        Ok(())
    }

    fn step(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        self.advance(dt)
    }

    fn reactions(&self) -> Reactions<'_> {
        Reactions {
            fixed: &self.fixed_reactions,
            prescribed: &self.prescribed_reactions,
        }
    }

    fn cut(&mut self, blade: &CutPath) -> Result<CutInfo, SimError> {
        if self.kind != Kind::Surface {
            return Err(SimError::Unsupported {
                model: self.kind(),
                operation: "cutting",
                reason: "only the surface kind `spring-mass` cuts (its springs are the surface)"
                    .into(),
            });
        }
        super::cut::cut_model(self, blade)
    }

    fn kinetic_energy(&self) -> Option<Real> {
        use crate::integrate::ParticleSystem;
        Some(self.state.kinetic_energy(self.body.masses()))
    }

    /// The particles' velocities zeroed (`Integrator::motion_stopped`).
    fn stop_motion(&mut self) -> bool {
        self.state.stop();
        self.integrator.motion_stopped();
        true
    }

    fn reset(&mut self) {
        self.state.x.clone_from(&self.rest);
        self.state.v.iter_mut().for_each(|v| *v = Vec3::ZERO);
        self.integrator.invalidate();
        self.update_surface();
    }

    fn info(&self) -> ModelInfo {
        let n = self.rest.len();
        let mut details = vec![
            ("integrator".into(), self.integrator.scheme.name().into()),
            ("stiffness".into(), format!("{:?}", self.params.stiffness)),
            ("springs".into(), self.body.network.len().to_string()),
            ("pressure".into(), self.body.pressure.is_some().to_string()),
            (
                "split_spring_damping".into(),
                self.body.split_damping().to_string(),
            ),
            ("steps".into(), self.integrator.steps().to_string()),
            (
                "last_cg_iterations".into(),
                self.last_info.iterations.to_string(),
            ),
        ];
        if self.kind != Kind::Volumetric {
            details.push(("thickness_m".into(), self.params.thickness.to_string()));
        }
        if let Some(dt) = self.explicit_time_step_estimate() {
            details.push(("explicit_dt_estimate_s".into(), format!("{dt:.3e}")));
        }
        details.extend(self.integrator.details());
        ModelInfo {
            kind: self.kind(),
            nodes: n,
            dofs: 3 * n,
            elements: self.body.network.len(),
            surface_vertices: self.surface_rest.len(),
            memory_bytes: self.body.network.memory_bytes() + n * (8 + 4 * 24),
            precompute_seconds: self.precompute_seconds,
            is_static: false,
            details,
        }
    }
}

impl SpringModel {
    /// 2/ω with ω² ≤ max_i 2 Σ_{springs at i} k / m_i (Gershgorin bound of M⁻¹K): a time
    /// step below which symplectic Euler is stable on the springs alone (pressure excluded).
    pub fn explicit_time_step_estimate(&self) -> Option<Real> {
        let m = &self.body.masses;
        let mut row = vec![0.0; m.len()];
        for s in &self.body.network.springs {
            row[s.a as usize] += 2.0 * s.stiffness;
            row[s.b as usize] += 2.0 * s.stiffness;
        }
        let w2 = row
            .iter()
            .zip(m)
            .filter(|(_, m)| **m > 0.0)
            .map(|(r, m)| r / m)
            .fold(0.0, Real::max);
        (w2 > 0.0).then(|| 2.0 / w2.sqrt())
    }
}
