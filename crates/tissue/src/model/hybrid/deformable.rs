//! `Deformable` for `Hybrid`.

use crate::error::SimError;
use crate::interact::{Constraints, Loads, PointContact};
use crate::math::{Mat3, Real, Vec3};
use crate::model::{
    ContactSurface, CutInfo, CutPath, Deformable, ModelInfo, Progress, Reactions, StepInfo,
    SurfaceView, VolumeView,
};

use super::CutRegion;
use super::model::{Hybrid, WHOLE_ORGAN_NOTICE};

impl Deformable for Hybrid {
    fn kind(&self) -> &'static str {
        "hybrid"
    }

    /// Both parts' outer surface (the interface is inside), with the cut surfaces.
    fn surface(&self) -> SurfaceView<'_> {
        SurfaceView {
            positions: self.surface_positions(),
            triangles: &self.triangles,
        }
    }

    fn set_contact_reach(&mut self, reach: Option<&[(Vec3, Real)]>) {
        self.set_reach(reach);
    }

    /// The region's vertices and, of the pre-computed rest, only those a search within the
    /// reach can touch (see `Hybrid::contact_positions`).
    fn contact_surface(&self) -> ContactSurface<'_> {
        let (positions, slack) = self.contact_positions();
        ContactSurface {
            positions,
            triangles: &self.triangles,
            slack,
        }
    }

    fn rest_surface(&self) -> &[Vec3] {
        &self.surf_rest
    }

    /// Every node of the organ (the rest's interior from its condensed state: one sparse
    /// solve on the first read after a step) and the tetrahedra no cut removed.
    fn volume(&self) -> Option<VolumeView<'_>> {
        Some(self.volume_view())
    }

    /// The instantaneous stiffness, everything else held: the region's tangent at the
    /// instrument's region nodes, the rest's condensed stiffness at the interface and its
    /// contacts (see `Hybrid::held_stiffness`).
    fn prescribed_stiffness(&self, entries: std::ops::Range<usize>) -> Option<Mat3> {
        self.held_stiffness(entries)
    }

    /// 0 the pre-computed rest, 1 the cut region's border, 2 the cuttable region.
    fn vertex_labels(&self) -> Option<Vec<u8>> {
        Some(self.region_labels())
    }

    /// Contacts and supports on either part; on the rest they are contacts of its
    /// condensed response (a new node costs three sparse solves, once).
    fn set_constraints(&mut self, c: &Constraints) -> Result<(), SimError> {
        self.clear_points();
        self.apply_constraints(c, &[])
    }

    /// Entries with a direction are frictionless contacts that only push: on the region
    /// the tensor-mass integrator's projection (`integrate::Hold::contact`), on the rest a
    /// row of its condensed response held along the normal, in an active set settled
    /// within the step (`Hybrid::advance`).
    fn set_constraints_along(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<bool, SimError> {
        self.clear_points();
        self.apply_constraints(c, normals).map(|()| true)
    }

    fn contacts_push_only(&self) -> bool {
        true
    }

    /// With `exact_fine_points` only (see `Hybrid::exact_points`).
    fn holds_point_contacts(&self) -> bool {
        self.exact_points
    }

    /// Each point goes to the part that owns the vertices it follows: on the region, the
    /// tensor-mass integrator's projection (`integrate::PointHold`); on the rest, or across
    /// the interface, a push-only contact of the rest's condensed response on the nodes it
    /// follows (its interface nodes' share through the coupling), settled with the rest's
    /// other contacts within the step (`Hybrid::route_points`).
    fn set_point_contacts(&mut self, points: &[PointContact]) -> Result<bool, SimError> {
        if !self.exact_points {
            return Ok(points.is_empty());
        }
        self.apply_points(points).map(|()| true)
    }

    fn point_reactions(&self) -> &[Real] {
        self.point_pushes()
    }

    fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        self.set_loads_checked(loads)
    }

    fn step(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        self.advance(dt)
    }

    fn reactions(&self) -> Reactions<'_> {
        self.reactions.reactions()
    }

    fn cut(&mut self, blade: &CutPath) -> Result<CutInfo, SimError> {
        self.cut_along(blade)
    }

    /// The region's nodes: the pre-computed rest is static (no inertia).
    fn kinetic_energy(&self) -> Option<Real> {
        Some(self.tm.node_kinetic_energy())
    }

    /// The region's velocities zeroed; the rest holds no velocity.
    fn stop_motion(&mut self) -> bool {
        self.tm.stop_nodes();
        true
    }

    fn reset(&mut self) {
        self.reset_state();
    }

    /// The one notice this model gives goes here: that the cut region has come to cover
    /// the whole organ (given now if it already does).
    fn set_progress(&mut self, progress: Progress) {
        self.progress = progress;
        self.notice_whole();
    }

    /// In real time a region growth is built on its own thread while the old region
    /// answers; otherwise each growth completes before the cut that asked for it.
    fn set_real_time(&mut self, on: bool) {
        self.real_time = on;
        if !on {
            let _ = self.finish_growth();
        }
    }

    fn info(&self) -> ModelInfo {
        let tm = self.tm.info();
        let alive = self.alive.iter().filter(|&&a| a).count();
        let mut details = vec![
            (
                "cut_region".to_string(),
                match &self.mode {
                    CutRegion::Auto => "auto".to_string(),
                    given => given.describe(),
                },
            ),
            (
                "auto_radius".into(),
                match self.mode {
                    CutRegion::Auto => format!("{:.4}", self.auto_radius),
                    CutRegion::Given(_) => "-".into(),
                },
            ),
            ("region_tets".into(), self.region_tets().to_string()),
            (
                "region_volume_fraction".into(),
                format!("{:.3}", self.region_fraction()),
            ),
            ("interface_nodes".into(), self.interface_nodes().to_string()),
            ("rest_outer_nodes".into(), self.rest.outer.len().to_string()),
            ("region_model".into(), tm.kind.to_string()),
            (
                "removed_tets".into(),
                (self.alive.len() - alive).to_string(),
            ),
            ("growths".into(), self.growths.len().to_string()),
            ("growth_pending".into(), self.growth_pending().to_string()),
            (
                "rest_build_s".into(),
                format!("{:.4}", self.rest.build_seconds),
            ),
            (
                "rest_column_solves".into(),
                self.rest.column_solves.to_string(),
            ),
            ("border_removals".into(), self.border_removals.to_string()),
            (
                "rest_contact_solves".into(),
                format!(
                    "{} last step, {} at most",
                    self.contact_stats.last_solves, self.contact_stats.max_solves
                ),
            ),
            (
                "rest_contact_capped_steps".into(),
                self.contact_stats.capped_steps.to_string(),
            ),
            (
                "region_refused_steps".into(),
                self.tm.integrator().refused_steps().to_string(),
            ),
        ];
        if self.is_whole_organ() {
            details.push(("whole_organ".into(), WHOLE_ORGAN_NOTICE.into()));
        }
        if let Some(p) = self.default_seed {
            details.push((
                "default_region".into(),
                format!(
                    "auto, seeded at the topmost point ({:.4}, {:.4}, {:.4}): no cut_region \
                     and no scalpel given",
                    p.x, p.y, p.z
                ),
            ));
        }
        if let Some(g) = self.growths.last() {
            details.push(("last_growth_s".into(), format!("{:.4}", g.seconds)));
            details.push((
                "last_growth_steps_waited".into(),
                g.steps_waited.to_string(),
            ));
        }
        details.extend(
            tm.details
                .into_iter()
                .filter(|(k, _)| k == "integrator" || k == "nonlinear_tets" || k == "steps"),
        );
        ModelInfo {
            kind: "hybrid",
            nodes: self.mesh.vertices.len(),
            dofs: tm.dofs + 3 * self.rest.outer.len(),
            elements: alive,
            surface_vertices: self.surf_nodes.len(),
            memory_bytes: self.memory_bytes(),
            precompute_seconds: self.precompute_seconds,
            is_static: false,
            details,
        }
    }
}
