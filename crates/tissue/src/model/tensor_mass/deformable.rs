//! `Deformable` for `TensorMass`: both kinds, surface constraints held through the
//! integrator, cutting by tetrahedron removal.

use crate::error::SimError;
use crate::integrate::PointHold;
use crate::interact::{Constraints, Loads, PointContact};
use crate::math::{Real, Vec3};
use crate::model::{
    CutInfo, CutPath, Deformable, ModelInfo, Reactions, StepInfo, SurfaceView, VolumeView,
};

use super::model::TensorMass;

impl Deformable for TensorMass {
    fn kind(&self) -> &'static str {
        if self.nonlinear {
            "tensor-mass-nonlinear"
        } else {
            "tensor-mass"
        }
    }

    fn surface(&self) -> SurfaceView<'_> {
        SurfaceView {
            positions: &self.surface.positions,
            triangles: &self.surface.triangles,
        }
    }

    fn rest_surface(&self) -> &[Vec3] {
        &self.surface.rest_positions
    }

    /// The tetrahedra that survive the cuts.
    fn volume(&self) -> Option<VolumeView<'_>> {
        Some(VolumeView {
            positions: &self.state.x,
            rest_positions: &self.mesh.vertices,
            tets: &self.alive_tets,
        })
    }

    fn set_constraints(&mut self, c: &Constraints) -> Result<(), SimError> {
        self.apply_constraints(c, &[], true)
    }

    /// Entries with a direction are frictionless contacts held by the integrator's
    /// projection (`integrate::Hold::contact`).
    fn set_constraints_along(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<bool, SimError> {
        self.apply_constraints(c, normals, true).map(|()| true)
    }

    /// Under the explicit schemes, an entry with a direction held along it both ways by the
    /// integrator's projection after every substep (`integrate::Hold` with `unilateral`
    /// false). Implicit Euler holds only the push-only contacts in its solve (a projection
    /// after it would not give the constrained equilibrium): there every entry is held in
    /// full and the answer is false.
    fn set_constraints_two_sided(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<bool, SimError> {
        if self.integrator.holds_points() {
            self.apply_constraints(c, normals, false).map(|()| true)
        } else {
            self.apply_constraints(c, &[], true).map(|()| false)
        }
    }

    fn contacts_push_only(&self) -> bool {
        true
    }

    /// Under the explicit schemes (`Integrator::holds_points`).
    fn holds_point_contacts(&self) -> bool {
        self.integrator.holds_points()
    }

    /// Each point a push-only contact on its three vertices' nodes, projected after every
    /// (sub)step by the integrator (`integrate::PointHold`).
    fn set_point_contacts(&mut self, points: &[PointContact]) -> Result<bool, SimError> {
        let holds =
            PointHold::from_contacts(points, &self.surface.nodes, &self.surface.rest_positions)?;
        self.integrator.set_points(holds);
        Ok(true)
    }

    fn point_reactions(&self) -> &[Real] {
        self.integrator.point_pushes()
    }

    /// Gravity acts as the lumped share m_i g; point loads on their vertex's node.
    fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        self.apply_loads(loads)
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
        self.cut_along(blade)
    }

    fn kinetic_energy(&self) -> Option<Real> {
        Some(self.node_kinetic_energy())
    }

    fn stop_motion(&mut self) -> bool {
        self.stop_nodes();
        true
    }

    fn reset(&mut self) {
        self.reset_state();
    }

    fn info(&self) -> ModelInfo {
        let s = &self.system;
        let n = s.node_count();
        let memory_bytes = s.linear.memory_bytes()
            + s.nonlinear.as_ref().map_or(0, |nl| nl.memory_bytes())
            + s.tets.len() * (16 + 104 + 64)
            + n * (24 * 6 + 16);
        ModelInfo {
            kind: self.kind(),
            nodes: n,
            dofs: 3 * n,
            elements: s.alive_count(),
            surface_vertices: self.surface.nodes.len(),
            memory_bytes,
            precompute_seconds: self.precompute_seconds,
            is_static: false,
            details: vec![
                ("integrator".into(), self.integrator.scheme.name().into()),
                ("edges".into(), s.topo.edges.len().to_string()),
                ("nonlinear_tets".into(), s.nonlinear_count().to_string()),
                (
                    "strain_threshold".into(),
                    self.params.strain_threshold.to_string(),
                ),
                (
                    "volume_penalty".into(),
                    self.params.volume_penalty.to_string(),
                ),
                (
                    "removed_tets".into(),
                    (s.tets.len() - s.alive_count()).to_string(),
                ),
                ("fragments".into(), self.fragments_seen.to_string()),
                ("topology_version".into(), self.topology_version.to_string()),
                ("steps".into(), self.integrator.steps().to_string()),
            ]
            .into_iter()
            .chain(self.integrator.details())
            .collect(),
        }
    }
}
