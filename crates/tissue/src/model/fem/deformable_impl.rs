//! `Deformable` for `FemStatic`: surface-vertex constraints and loads turned into a dof-level
//! problem, one direct solve per step, and reactions handed back per given constraint.

use crate::error::SimError;
use crate::interact::{Constraints, Loads};
use crate::math::{Real, Vec3};
use crate::model::{Deformable, ModelInfo, Reactions, StepInfo, SurfaceView, VolumeView};

use super::static_model::{FemStatic, Order};
use super::surface_nodes::nodal_forces;
use super::system::DofProblem;

impl FemStatic {
    /// Surface vertex → held displacement, from constraints (fixed wins over prescribed).
    fn surface_targets(&self, c: &Constraints) -> Result<Vec<Option<Vec3>>, SimError> {
        c.surface_displacements(&self.boundary.surface.vertices)
    }

    fn update_reactions(&mut self) {
        let r = |n: usize| Vec3::new(self.r[3 * n], self.r[3 * n + 1], self.r[3 * n + 2]);
        for (s, &n) in self.boundary.nodes.iter().enumerate() {
            self.surface_reaction[s] = r(n as usize);
        }
        // A held mid-edge node hands its reaction to the two ends that hold it.
        for &(m, a, b) in &self.surface_mids {
            if self.problem.constrained[3 * m as usize] {
                let half = r(m as usize) * 0.5;
                self.surface_reaction[a as usize] += half;
                self.surface_reaction[b as usize] += half;
            }
        }
        let surface_reaction = &self.surface_reaction;
        self.reactions.distribute(|v| surface_reaction[v as usize]);
    }

    fn update_positions(&mut self) {
        for (i, (p, x)) in self.positions.iter_mut().zip(&self.rest).enumerate() {
            *p = *x + Vec3::new(self.u[3 * i], self.u[3 * i + 1], self.u[3 * i + 2]);
        }
        for (s, &n) in self.boundary.nodes.iter().enumerate() {
            self.surface_positions[s] = self.positions[n as usize];
        }
    }
}

impl Deformable for FemStatic {
    fn kind(&self) -> &'static str {
        "fem-static"
    }

    fn surface(&self) -> SurfaceView<'_> {
        SurfaceView {
            positions: &self.surface_positions,
            triangles: &self.boundary.surface.triangles,
        }
    }

    fn rest_surface(&self) -> &[Vec3] {
        &self.boundary.surface.vertices
    }

    fn volume(&self) -> Option<VolumeView<'_>> {
        let n = self.mesh.vertices.len();
        Some(VolumeView {
            positions: &self.positions[..n],
            rest_positions: &self.rest[..n],
            tets: &self.mesh.tets,
        })
    }

    /// Fixed vertices are held at rest, prescribed ones at their target; on quadratic meshes
    /// the mid-edge node of a boundary edge whose ends are both held follows the mean of their
    /// displacements. A vertex listed several times gets its reaction in its first fixed entry
    /// (else its last prescribed entry, whose target is used); the other entries get zero.
    fn set_constraints(&mut self, c: &Constraints) -> Result<(), SimError> {
        let disp = self.surface_targets(c)?;
        let mut dp = DofProblem::new(self.system.dofs());
        for (s, d) in disp.iter().enumerate() {
            if let Some(d) = d {
                dp.hold_node(self.boundary.nodes[s] as usize, *d)?;
            }
        }
        for &(m, a, b) in &self.surface_mids {
            if let (Some(da), Some(db)) = (disp[a as usize], disp[b as usize]) {
                dp.hold_node(m as usize, (da + db) * 0.5)?;
            }
        }
        dp.finish();
        dp.forces = std::mem::take(&mut self.problem.forces);
        self.problem = dp;
        self.reactions.set(c);
        Ok(())
    }

    /// Gravity becomes the consistent body load ρ g over every element; point loads act on
    /// the node of their surface vertex.
    fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        let density = self.material.density;
        self.problem.forces =
            nodal_forces(loads, &self.boundary.nodes, |g| self.body_load(g * density))?;
        self.loads = loads.clone();
        Ok(())
    }

    /// Solves for equilibrium (`dt` plays no role). Factorises only when the held set changed.
    fn step(&mut self, _dt: Real) -> Result<StepInfo, SimError> {
        self.system
            .solve(&self.problem, &mut self.u_trial, &mut self.r_trial)?;
        std::mem::swap(&mut self.u, &mut self.u_trial);
        std::mem::swap(&mut self.r, &mut self.r_trial);
        self.update_positions();
        self.update_reactions();
        Ok(StepInfo::default())
    }

    fn reactions(&self) -> Reactions<'_> {
        self.reactions.reactions()
    }

    fn reset(&mut self) {
        self.u.iter_mut().for_each(|v| *v = 0.0);
        self.r.iter_mut().for_each(|v| *v = 0.0);
        self.update_positions();
        self.update_reactions();
    }

    fn info(&self) -> ModelInfo {
        let (pattern, _) = self.stiffness_parts();
        let nnz = pattern.nnz();
        let dofs = self.system.dofs();
        let m = self.system.assembler.nodes_per_element;
        let elements = self.mesh.tets.len();
        let memory_bytes = nnz * (8 + 8 + 8)
            + self.system.factor_nnz() * 16
            + elements * m * (m + 1) * 4
            + dofs * 8 * 8
            + self.rest.len() * 24 * 2;
        ModelInfo {
            kind: self.kind(),
            nodes: self.rest.len(),
            dofs,
            elements,
            surface_vertices: self.boundary.nodes.len(),
            memory_bytes,
            precompute_seconds: self.precompute_seconds,
            is_static: true,
            details: vec![
                (
                    "order".into(),
                    match self.order {
                        Order::Linear => "linear",
                        Order::Quadratic => "quadratic",
                    }
                    .into(),
                ),
                ("nnz".into(), nnz.to_string()),
                ("factor_nnz".into(), self.system.factor_nnz().to_string()),
                (
                    "refactorizations".into(),
                    self.system.refactorizations.to_string(),
                ),
                (
                    "schur_columns".into(),
                    self.system.schur_columns.to_string(),
                ),
                ("solves".into(), self.system.solves.to_string()),
            ],
        }
    }
}
