//! (being written)
use crate::error::Error;
use crate::model::BuildInput;
pub struct FemStatic;
impl FemStatic {
    pub fn from_input(_i: &BuildInput<'_>) -> Result<Self, Error> {
        todo!()
    }
}
impl crate::model::Deformable for FemStatic {
    fn kind(&self) -> &'static str {
        "fem-static"
    }
    fn surface(&self) -> crate::model::SurfaceView<'_> {
        todo!()
    }
    fn rest_surface(&self) -> &[crate::Vec3] {
        todo!()
    }
    fn set_constraints(&mut self, _: &crate::interact::Constraints) -> Result<(), crate::SimError> {
        todo!()
    }
    fn set_loads(&mut self, _: &crate::interact::Loads) -> Result<(), crate::SimError> {
        todo!()
    }
    fn step(&mut self, _: f64) -> Result<crate::model::StepInfo, crate::SimError> {
        todo!()
    }
    fn reactions(&self) -> crate::model::Reactions<'_> {
        todo!()
    }
    fn reset(&mut self) {}
    fn info(&self) -> crate::model::ModelInfo {
        todo!()
    }
}
