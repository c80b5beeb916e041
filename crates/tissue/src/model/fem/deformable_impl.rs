//! `Deformable` for `FemStatic`: surface-vertex constraints and loads turned into a dof-level
//! problem, one direct solve per step, and reactions handed back per given constraint.

use crate::error::SimError;
use crate::interact::{Constraints, Loads, PointContact};
use crate::math::{Real, Vec3};
use crate::model::{Deformable, ModelInfo, Reactions, StepInfo, SurfaceView, VolumeView};

use super::static_model::{FemStatic, Order};
use super::surface_nodes::nodal_forces;
use super::system::{ALONG_CAP, DofProblem, PointHold, oblique_holds};

impl FemStatic {
    /// The constraints as a dof problem (see `set_constraints`), the prescribed entry k held
    /// along `normals[k]` only where given (none: every entry in full). Returns whether
    /// every entry is held as asked: more than `ALONG_CAP` entries with a direction are held
    /// in full instead (the Schur complement that holds them would be too large).
    fn hold(&mut self, c: &Constraints, normals: &[Option<Vec3>]) -> Result<bool, SimError> {
        let mut holds = c.surface_holds(&self.boundary.surface.vertices, normals)?;
        let as_asked = oblique_holds(&holds) <= ALONG_CAP;
        if !as_asked {
            holds.iter_mut().flatten().for_each(|h| h.along = None);
        }
        let mut dp = DofProblem::new(self.system.dofs());
        dp.hold_surface(&self.boundary.nodes, &self.surface_mids, &holds)?;
        dp.finish();
        dp.forces = std::mem::take(&mut self.problem.forces);
        self.problem = dp;
        self.reactions.set(c);
        Ok(as_asked)
    }

    fn update_reactions(&mut self) {
        let r = |n: usize| Vec3::new(self.r[3 * n], self.r[3 * n + 1], self.r[3 * n + 2]);
        for (s, &n) in self.boundary.nodes.iter().enumerate() {
            self.surface_reaction[s] = r(n as usize);
        }
        // A held mid-edge node hands its reaction to the two ends that hold it (a free one
        // has none: reactions are zero on free dofs).
        for &(m, a, b) in &self.surface_mids {
            let half = r(m as usize) * 0.5;
            self.surface_reaction[a as usize] += half;
            self.surface_reaction[b as usize] += half;
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
        self.hold(c, &[]).map(|_| ())
    }

    /// Held along a direction exactly: one more row nᵀu = nᵀd of the linear solve, through
    /// the Schur complement on the factorisation of the other held dofs (`System`); the
    /// reaction is λ n. A mid-edge node between two held ends is held along the mean of
    /// their directions.
    fn set_constraints_along(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<bool, SimError> {
        self.hold(c, normals)
    }

    /// Linear tetrahedra only: a quadratic surface bends between its corners, which a point
    /// tied to the corners by flat weights does not follow.
    fn holds_point_contacts(&self) -> bool {
        self.order == Order::Linear
    }

    /// Each point a unilateral row Σ wᵢ n·uᵢ ≥ n·(target − rest) over its vertices' nodes,
    /// solved with the other held dofs as one complementarity problem on the Schur
    /// complement of the factorisation (`System`, `solve::lcp`).
    fn set_point_contacts(&mut self, points: &[PointContact]) -> Result<bool, SimError> {
        if !self.holds_point_contacts() {
            return Ok(points.is_empty());
        }
        let count = self.boundary.nodes.len();
        let mut holds = Vec::with_capacity(points.len());
        for pt in points {
            pt.check(count)?;
            holds.push(PointHold {
                nodes: pt
                    .vertices
                    .map(|v| self.boundary.nodes[v as usize] as usize),
                weights: pt.weights,
                normal: pt.normal,
                value: pt.reach(),
            });
        }
        self.problem.points = holds;
        Ok(true)
    }

    fn point_reactions(&self) -> &[Real] {
        &self.point_pushes
    }

    /// Gravity becomes the consistent body load ρ g over every element; point loads act on
    /// the node of their surface vertex.
    fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        self.problem.forces = nodal_forces(loads, &self.boundary.nodes, |g| self.gravity_load(g))?;
        self.loads = loads.clone();
        Ok(())
    }

    /// Solves for equilibrium (`dt` plays no role). Factorises only when the held set changed.
    fn step(&mut self, _dt: Real) -> Result<StepInfo, SimError> {
        self.system
            .solve(&self.problem, &mut self.u_trial, &mut self.r_trial)?;
        std::mem::swap(&mut self.u, &mut self.u_trial);
        std::mem::swap(&mut self.r, &mut self.r_trial);
        self.point_pushes.clone_from(&self.system.point_pushes);
        self.update_positions();
        self.update_reactions();
        Ok(StepInfo::default())
    }

    fn reactions(&self) -> Reactions<'_> {
        self.reactions.reactions()
    }

    fn reset(&mut self) {
        self.point_pushes.iter_mut().for_each(|v| *v = 0.0);
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
