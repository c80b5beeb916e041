//! The `Deformable` methods that only forward to `Core`, shared by both schemes.

/// The `Deformable` methods that only forward to `Core`; the type provides `advance(dt)`
/// and `details()`. Entries given a direction are contacts that only push (`contacts`).
macro_rules! forward_deformable {
    ($ty:ty, $kind:literal) => {
        impl crate::model::Deformable for $ty {
            fn kind(&self) -> &'static str {
                $kind
            }
            fn surface(&self) -> crate::model::SurfaceView<'_> {
                crate::model::SurfaceView {
                    positions: &self.core.surface_positions,
                    triangles: &self.core.boundary.surface.triangles,
                }
            }
            fn rest_surface(&self) -> &[crate::math::Vec3] {
                &self.core.boundary.surface.vertices
            }
            fn volume(&self) -> Option<crate::model::VolumeView<'_>> {
                Some(crate::model::VolumeView {
                    positions: &self.core.positions,
                    rest_positions: &self.core.rest,
                    tets: &self.core.mesh.tets,
                })
            }
            fn set_constraints(
                &mut self,
                c: &crate::interact::Constraints,
            ) -> Result<(), crate::error::SimError> {
                self.core.set_constraints(c)
            }
            fn set_constraints_along(
                &mut self,
                c: &crate::interact::Constraints,
                normals: &[Option<crate::math::Vec3>],
            ) -> Result<bool, crate::error::SimError> {
                self.core.set_constraints_along(c, normals)
            }
            fn set_constraints_two_sided(
                &mut self,
                c: &crate::interact::Constraints,
                normals: &[Option<crate::math::Vec3>],
            ) -> Result<bool, crate::error::SimError> {
                self.core.set_constraints_two_sided(c, normals)
            }
            fn contacts_push_only(&self) -> bool {
                true
            }
            fn holds_point_contacts(&self) -> bool {
                true
            }
            /// Projected after every substep (`fem-explicit`) or held in the solve
            /// (`fem-semi-implicit`): `points`.
            fn set_point_contacts(
                &mut self,
                points: &[crate::interact::PointContact],
            ) -> Result<bool, crate::error::SimError> {
                self.core.set_points(points).map(|()| true)
            }
            fn point_reactions(&self) -> &[crate::math::Real] {
                &self.core.point_push
            }
            fn set_loads(
                &mut self,
                loads: &crate::interact::Loads,
            ) -> Result<(), crate::error::SimError> {
                self.core.set_loads(loads)
            }
            fn step(
                &mut self,
                dt: crate::math::Real,
            ) -> Result<crate::model::StepInfo, crate::error::SimError> {
                self.advance(dt)
            }
            fn reactions(&self) -> crate::model::Reactions<'_> {
                self.core.reactions()
            }
            fn kinetic_energy(&self) -> Option<crate::math::Real> {
                Some(self.core.kinetic_energy())
            }
            fn stop_motion(&mut self) -> bool {
                self.core.stop_motion();
                true
            }
            fn reset(&mut self) {
                self.core.reset();
            }
            fn info(&self) -> crate::model::ModelInfo {
                let (bytes, details) = self.details();
                self.core.info($kind, bytes, details)
            }
        }
    };
}
pub(crate) use forward_deformable;
