//! `Deformable` for `LinkedVolumes`: surface constraints become held elements, surface
//! loads become element forces, and held-element reactions are shared back to the vertices.

use std::collections::HashMap;

use crate::error::SimError;
use crate::integrate::Hold;
use crate::interact::{Constraints, Loads};
use crate::math::{Real, Vec3, is_finite_vec};
use crate::model::{CutInfo, CutPath, Deformable, ModelInfo, Reactions, StepInfo, SurfaceView};

use super::LinkedVolumes;

/// The frictionless contacts of the surface vertices an element carries: (unit normal, the
/// vertex's gap to its target, its weight on the element).
#[derive(Default)]
struct Touch {
    claims: Vec<(Vec3, Vec3, Real)>,
}

impl Touch {
    /// The element's plane, as its offset from where the element starts the step, and its
    /// normal. An element carries several surface vertices, each with its own plane; it is
    /// held along their weighted mean normal n̄ (as `fem-static` holds a mid-edge node
    /// between two contacts), as far as the most demanding of them asks: moved by s along
    /// n̄, the element meets vertex i's plane when s·(n̄·nᵢ) ≥ nᵢ·gᵢ. The largest such s
    /// keeps the touching vertex (the one deepest in) out of the instrument: a mean of the
    /// gaps would let the vertices near the instrument but not touching it (handed over as
    /// contacts too, `sim::CONTACT_MARGIN`) draw the plane back into it.
    fn plane(&self) -> (Vec3, Option<Vec3>) {
        let sum: Vec3 = self.claims.iter().map(|(n, _, w)| *n * *w).sum();
        let total: Real = self.claims.iter().map(|c| c.2).sum();
        // Normals that cancel (two sides of a thin part under one instrument): no plane
        // to hold it on; the element is held in full at the mean target.
        if sum.length() <= 1e-3 * total || !sum.is_finite() {
            let mean: Vec3 = self.claims.iter().map(|(_, g, w)| *g * *w).sum();
            return (mean / total, None);
        }
        let n = sum.normalize();
        let s = self
            .claims
            .iter()
            .filter(|(ni, _, _)| ni.dot(n) > 1e-6)
            .map(|(ni, g, _)| ni.dot(*g) / ni.dot(n))
            .fold(Real::NEG_INFINITY, Real::max);
        (n * s, Some(n))
    }
}

impl LinkedVolumes {
    /// The elements (with weights) a surface vertex follows.
    fn corners(&self, v: usize) -> impl Iterator<Item = (u32, Real)> + '_ {
        let (ids, w) = (&self.embedding.nodes[v], &self.embedding.weights[v]);
        (0..8)
            .filter(move |&k| w[k] != 0.0)
            .map(move |k| (ids[k], w[k]))
    }

    /// Shares the held elements' forces among the vertices holding them, by weight.
    fn share_reactions(&mut self) {
        let held: HashMap<u32, Vec3> = self
            .holds
            .iter()
            .zip(self.integrator.held_forces())
            .map(|(h, f)| (h.particle as u32, *f))
            .collect();
        let mut fixed_w: HashMap<u32, Real> = HashMap::new();
        let mut pres_w: HashMap<u32, Real> = HashMap::new();
        for &v in &self.constraints.fixed {
            for (e, w) in self.corners(v as usize) {
                *fixed_w.entry(e).or_insert(0.0) += w;
            }
        }
        for p in &self.constraints.prescribed {
            if !self.fixed_vertex[p.vertex as usize] {
                for (e, w) in self.corners(p.vertex as usize) {
                    if !self.fixed_elements.contains(&e) {
                        *pres_w.entry(e).or_insert(0.0) += w;
                    }
                }
            }
        }
        let share = |v: usize, weights: &HashMap<u32, Real>, this: &Self| -> Vec3 {
            this.corners(v)
                .filter_map(|(e, w)| {
                    let total = *weights.get(&e)?;
                    Some(*held.get(&e)? * (w / total))
                })
                .sum()
        };
        // A vertex listed twice gets its share once (the first entry).
        let mut seen = vec![false; self.surface.len()];
        let fixed: Vec<Vec3> = self
            .constraints
            .fixed
            .iter()
            .map(|&v| {
                if std::mem::replace(&mut seen[v as usize], true) {
                    Vec3::ZERO
                } else {
                    share(v as usize, &fixed_w, self)
                }
            })
            .collect();
        let prescribed: Vec<Vec3> = self
            .constraints
            .prescribed
            .iter()
            .map(|p| {
                let v = p.vertex as usize;
                if std::mem::replace(&mut seen[v], true) {
                    Vec3::ZERO
                } else {
                    share(v, &pres_w, self)
                }
            })
            .collect();
        self.fixed_reactions = fixed;
        self.prescribed_reactions = prescribed;
    }

    /// The fixed elements and the bookkeeping of a new constraint set.
    fn hold_elements(&mut self, c: &Constraints) -> Result<(), SimError> {
        c.surface_displacements(&self.embedding.rest)?;
        let mut is_fixed = vec![false; self.surface.len()];
        for &v in &c.fixed {
            is_fixed[v as usize] = true;
        }
        let mut fixed: Vec<u32> = c
            .fixed
            .iter()
            .flat_map(|&v| self.corners(v as usize).map(|(e, _)| e))
            .collect();
        fixed.sort_unstable();
        fixed.dedup();
        self.fixed_elements = fixed;
        self.fixed_vertex = is_fixed;
        self.fixed_reactions = vec![Vec3::ZERO; c.fixed.len()];
        self.prescribed_reactions = vec![Vec3::ZERO; c.prescribed.len()];
        self.constraints = c.clone();
        Ok(())
    }
}

impl Deformable for LinkedVolumes {
    fn kind(&self) -> &'static str {
        "linked-volumes"
    }

    fn surface(&self) -> SurfaceView<'_> {
        SurfaceView {
            positions: &self.surface,
            triangles: &self.triangles,
        }
    }

    fn rest_surface(&self) -> &[Vec3] {
        &self.embedding.rest
    }

    fn set_constraints(&mut self, c: &Constraints) -> Result<(), SimError> {
        self.normals.clear();
        self.hold_elements(c)
    }

    /// Entries with a direction are frictionless contacts that only push: each element a
    /// contact vertex follows is held by the integrator's projection
    /// (`integrate::Hold::contact`) on the plane `Touch::plane` gives it.
    fn set_constraints_along(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<bool, SimError> {
        self.hold_elements(c)?;
        self.normals = (0..c.prescribed.len())
            .map(|k| {
                normals
                    .get(k)
                    .copied()
                    .flatten()
                    .map(Vec3::normalize_or_zero)
                    .filter(|n| *n != Vec3::ZERO && is_finite_vec(*n))
            })
            .collect();
        Ok(true)
    }

    fn contacts_push_only(&self) -> bool {
        true
    }

    /// Gravity acts on every element mass; point loads reach the elements of their cell.
    fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        let n = self.surface.len();
        let mut surface_forces = vec![Vec3::ZERO; n];
        for &(v, f) in &loads.point_loads {
            if !is_finite_vec(f) {
                return Err(SimError::BadParameter {
                    name: "point load",
                    value: format!("surface vertex {v}: {f}"),
                    reason: "the force is not finite".into(),
                });
            }
            *surface_forces
                .get_mut(v as usize)
                .ok_or(SimError::BadConstraint {
                    vertex: v as usize,
                    count: n,
                })? += f;
        }
        if !is_finite_vec(loads.gravity) {
            return Err(SimError::BadParameter {
                name: "gravity",
                value: loads.gravity.to_string(),
                reason: "not finite".into(),
            });
        }
        let mut ext: Vec<Vec3> = self
            .system
            .masses
            .iter()
            .map(|m| *m * loads.gravity)
            .collect();
        self.embedding.apply_transpose(&surface_forces, &mut ext);
        self.system.external = ext;
        self.gravity = loads.gravity;
        self.point_loads = loads.point_loads.clone();
        self.integrator.invalidate();
        Ok(())
    }

    fn step(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(SimError::BadTimeStep { dt });
        }
        // (element, target, the normal of a contact that only pushes).
        let mut targets: Vec<(u32, Vec3, Option<Vec3>)> = self
            .fixed_elements
            .iter()
            .map(|&e| (e, self.rest[e as usize], None))
            .collect();
        let mut wanted: HashMap<u32, (Vec3, Real)> = HashMap::new();
        let mut touching: HashMap<u32, Touch> = HashMap::new();
        for (k, p) in self.constraints.prescribed.iter().enumerate() {
            let v = p.vertex as usize;
            if self.fixed_vertex[v] {
                continue;
            }
            let missing = p.position - self.surface[v];
            let normal = self.normals.get(k).copied().flatten();
            for (e, w) in self.corners(v) {
                if self.fixed_elements.binary_search(&e).is_ok() {
                    continue;
                }
                match normal {
                    None => {
                        let s = wanted.entry(e).or_insert((Vec3::ZERO, 0.0));
                        s.0 += w * missing;
                        s.1 += w;
                    }
                    Some(n) => touching.entry(e).or_default().claims.push((n, missing, w)),
                }
            }
        }
        let x0 = &self.state.x;
        targets.extend(
            wanted
                .iter()
                .map(|(&e, &(d, w))| (e, x0[e as usize] + d / w, None)),
        );
        // An element held in full by another entry stays held in full.
        targets.extend(touching.iter().filter_map(|(&e, t)| {
            if wanted.contains_key(&e) {
                return None;
            }
            let (plane, n) = t.plane();
            Some((e, x0[e as usize] + plane, n))
        }));
        targets.sort_unstable_by_key(|t| t.0);
        let start: Vec<Vec3> = targets.iter().map(|t| self.state.x[t.0 as usize]).collect();
        let n = match self.params.substeps {
            crate::integrate::Substeps::Fixed(n) => n as usize,
            crate::integrate::Substeps::Auto => 1,
        };
        let h = dt / n as Real;
        let saved = self.state.clone();
        let mut info = StepInfo::default();
        for s in 0..n {
            let f = (s + 1) as Real / n as Real;
            self.holds = targets
                .iter()
                .zip(&start)
                .map(|(t, x0)| match t.2 {
                    // A contact's plane stays at its end-of-step place (`Hold::contact`).
                    Some(n) => Hold::contact(t.0 as usize, t.1, n),
                    None => Hold::new(t.0 as usize, *x0 + (t.1 - *x0) * f),
                })
                .collect();
            match self
                .integrator
                .step(&mut self.system, &mut self.state, &self.holds, h)
            {
                Ok(i) => {
                    info.iterations += i.iterations;
                    info.residual = info.residual.max(i.residual);
                    info.capped |= i.capped;
                    info.substeps += i.substeps;
                }
                Err(e) => {
                    self.state = saved;
                    self.integrator.invalidate();
                    self.refresh_surface();
                    return Err(match e {
                        SimError::Diverged { node, reason, .. } => SimError::Diverged {
                            step: self.steps + 1,
                            node,
                            reason,
                        },
                        other => other,
                    });
                }
            }
        }
        self.refresh_surface();
        self.share_reactions();
        self.steps += 1;
        Ok(info)
    }

    fn reactions(&self) -> Reactions<'_> {
        Reactions {
            fixed: &self.fixed_reactions,
            prescribed: &self.prescribed_reactions,
        }
    }

    /// Removes the springs crossing the blade (see `topology`).
    fn cut(&mut self, blade: &CutPath) -> Result<CutInfo, SimError> {
        self.cut_links(blade)
    }

    fn kinetic_energy(&self) -> Option<Real> {
        use crate::integrate::ParticleSystem;
        Some(self.state.kinetic_energy(self.system.masses()))
    }

    /// The particles' velocities zeroed (implicit Euler's next step starts from rest;
    /// `Integrator::motion_stopped`).
    fn stop_motion(&mut self) -> bool {
        self.state.stop();
        self.integrator.motion_stopped();
        true
    }

    fn reset(&mut self) {
        self.state = crate::integrate::ParticleState::at_rest(self.rest.clone());
        self.integrator.invalidate();
        self.refresh_surface();
    }

    fn info(&self) -> ModelInfo {
        let n = self.rest.len();
        ModelInfo {
            kind: self.kind(),
            nodes: n,
            dofs: 3 * n,
            elements: self.system.springs.len(),
            surface_vertices: self.surface.len(),
            memory_bytes: n * (24 * 6 + 8) + self.system.springs.len() * (40 + 40),
            precompute_seconds: self.precompute_seconds,
            is_static: false,
            details: vec![
                ("neighbours".into(), self.params.neighbours.to_string()),
                ("voxel_size".into(), format!("{:.4e}", self.spacing.x)),
                ("integrator".into(), self.params.integrator.to_string()),
                (
                    "preconditioner".into(),
                    self.params.preconditioner.name().to_string(),
                ),
                (
                    "factorizations".into(),
                    self.integrator.implicit_factorizations().to_string(),
                ),
                ("substeps_setting".into(), self.params.substeps.describe()),
                (
                    "substeps".into(),
                    match self.params.substeps {
                        crate::integrate::Substeps::Fixed(n) => n,
                        crate::integrate::Substeps::Auto => self.integrator.last_substeps(),
                    }
                    .to_string(),
                ),
                (
                    "stable_dt".into(),
                    self.integrator
                        .stable_dt()
                        .map_or("not measured".into(), |h| format!("{h:.6e}")),
                ),
                (
                    "effective_poisson_ratio".into(),
                    super::lattice_moduli(&self.material, self.params.neighbours)
                        .map_or(0.25, |m| m.poisson_ratio)
                        .to_string(),
                ),
                (
                    "material_poisson_ratio".into(),
                    self.material.poisson_ratio.to_string(),
                ),
                ("links".into(), self.topology.link_count().to_string()),
                ("topology_version".into(), self.topology_version.to_string()),
                ("steps".into(), self.steps.to_string()),
            ],
        }
    }
}
