//! `Deformable` for `FemCorotational`: surface-vertex constraints and loads mapped to nodes,
//! reactions handed back per given constraint (as `fem-static` does).

use crate::error::SimError;
use crate::integrate::PointHold;
use crate::interact::{Constraints, Loads, PointContact, SurfaceHold};
use crate::math::{Real, Vec3};
use crate::model::{Deformable, ModelInfo, Reactions, StepInfo, SurfaceView, VolumeView};

use super::super::surface_nodes::node_of;
use super::FemCorotational;
use super::contact::PushContact;

impl FemCorotational {
    fn node_of(&self, vertex: u32) -> Result<usize, SimError> {
        node_of(&self.boundary.nodes, vertex)
    }

    /// Each vertex's reaction goes to its first fixed entry, else its last prescribed one.
    pub(super) fn distribute_reactions(&mut self) {
        let nodes = &self.boundary.nodes;
        let r = |v: u32| {
            nodes
                .get(v as usize)
                .and_then(|&n| self.node_reactions.get(n as usize))
                .copied()
                .unwrap_or(Vec3::ZERO)
        };
        self.reactions.distribute(r);
    }
}

impl FemCorotational {
    /// The solver in use, with its factorisation counts, for `info`.
    fn solver_description(&self) -> String {
        match (self.resolved, &self.warp) {
            (Some(super::Resolved::Warp), Some(w)) => format!(
                "warp-pcg (factor {} values, {} factorisations in {:.3} s)",
                w.factor_nnz(),
                w.factorizations,
                w.factor_seconds
            ),
            (Some(super::Resolved::Jacobi), _) => match &self.fallback_reason {
                Some(why) => format!("jacobi-pcg ({why})"),
                None => "jacobi-pcg".into(),
            },
            _ => "chosen at the next step".into(),
        }
    }
}

impl Deformable for FemCorotational {
    fn kind(&self) -> &'static str {
        "fem-corotational"
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
        Some(VolumeView {
            positions: &self.x,
            rest_positions: &self.rest,
            tets: &self.mesh.tets,
        })
    }

    /// Fixed vertices keep zero velocity, prescribed ones reach their target within each step
    /// (the last entry wins for a vertex prescribed twice; fixed wins over prescribed).
    fn set_constraints(&mut self, c: &Constraints) -> Result<(), SimError> {
        self.set_constraints_along(c, &[]).map(|_| ())
    }

    /// An entry with a direction is a frictionless contact that only pushes (`contact`):
    /// held along its normal by the CG's filter while it pushes, free otherwise, decided
    /// within each step. Every entry is held as asked (the filter costs nothing per contact
    /// beyond its node, so there is no cap).
    fn set_constraints_along(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<bool, SimError> {
        let holds = c.surface_holds(&self.boundary.surface.vertices, normals)?;
        let fixed = c
            .fixed
            .iter()
            .map(|&v| self.node_of(v))
            .collect::<Result<Vec<_>, _>>()?;
        // Entries held in full keep their given position (fixed wins in
        // `set_node_constraints`); a vertex held along a direction takes its last entry's.
        let prescribed = c
            .prescribed
            .iter()
            .filter(|p| {
                let h = holds.get(p.vertex as usize).copied().flatten();
                h.is_some_and(|h| h.along.is_none())
            })
            .map(|p| Ok((self.node_of(p.vertex)?, p.position)))
            .collect::<Result<Vec<_>, SimError>>()?;
        let rest = &self.boundary.surface.vertices;
        let mut contacts = Vec::new();
        for (v, h) in holds.iter().enumerate() {
            if let Some(SurfaceHold {
                displacement,
                along: Some(normal),
            }) = *h
            {
                contacts.push(PushContact {
                    node: self.node_of(v as u32)?,
                    normal,
                    target: rest[v] + displacement,
                    push: 0.0,
                });
            }
        }
        self.set_node_constraints(&fixed, &prescribed)?;
        self.contacts = contacts;
        self.points.clear();
        self.point_push.clear();
        self.reactions.set(c);
        Ok(true)
    }

    fn contacts_push_only(&self) -> bool {
        true
    }

    fn holds_point_contacts(&self) -> bool {
        true
    }

    /// Each point held in the implicit step by the contact problem of the points on the
    /// step's matrix (`contact::points`).
    fn set_point_contacts(&mut self, points: &[PointContact]) -> Result<bool, SimError> {
        self.points = PointHold::from_contacts(
            points,
            &self.boundary.nodes,
            &self.boundary.surface.vertices,
        )?;
        self.point_push = vec![0.0; points.len()];
        Ok(true)
    }

    fn point_reactions(&self) -> &[Real] {
        &self.point_push
    }

    /// Gravity acts as the lumped share m_i g on each node; point loads on their vertex's node.
    fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        let forces = loads
            .point_loads
            .iter()
            .map(|&(v, f)| Ok((self.node_of(v)?, f)))
            .collect::<Result<Vec<_>, SimError>>()?;
        self.set_node_loads(loads.gravity, &forces)?;
        self.loads = loads.clone();
        Ok(())
    }

    fn step(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        self.advance(dt)
    }

    fn reactions(&self) -> Reactions<'_> {
        self.reactions.reactions()
    }

    fn kinetic_energy(&self) -> Option<Real> {
        Some(
            self.velocities()
                .iter()
                .zip(self.masses())
                .map(|(v, m)| 0.5 * m * v.length_squared())
                .sum(),
        )
    }

    fn stop_motion(&mut self) -> bool {
        self.stop_nodes();
        true
    }

    fn reset(&mut self) {
        self.reset_state();
    }

    fn info(&self) -> ModelInfo {
        let n = self.rest.len();
        let ne = self.elements.len();
        let memory_bytes = ne * (std::mem::size_of::<super::ElementRest>() + 2 * 72)
            + n * (8 + 24 * 8 + 8 * 3 * 10)
            + self.ws.stiffness.memory_bytes()
            + self.warp.as_ref().map_or(0, |w| 8 * w.factor_nnz());
        ModelInfo {
            kind: self.kind(),
            nodes: n,
            dofs: 3 * n,
            elements: ne,
            surface_vertices: self.boundary.nodes.len(),
            memory_bytes,
            precompute_seconds: self.precompute_seconds,
            is_static: false,
            details: vec![
                ("solver".into(), self.solver_description()),
                (
                    "cg_iterations".into(),
                    self.params.cg_iterations.to_string(),
                ),
                ("cg_tolerance".into(), self.params.cg_tolerance.to_string()),
                ("steps".into(), self.steps.to_string()),
                (
                    "last_cg_iterations".into(),
                    self.last_cg.iterations.to_string(),
                ),
                (
                    "last_cg_residual".into(),
                    format!("{:.3e}", self.last_cg.relative_residual),
                ),
                (
                    "contact_solves".into(),
                    format!(
                        "{} (last step; {} steps stopped unsettled at {})",
                        self.contact_solves,
                        self.contact_caps,
                        super::contact::MAX_CONTACT_SOLVES
                    ),
                ),
            ],
        }
    }
}
