//! `bem`: linear elastostatics by the boundary element method on the rendered surface
//! (survey section 3.2, eq. 11-13).
//!
//! Only the surface is discretised: linear triangles with displacement and traction unknowns
//! at the vertices (`assembly`, with Kelvin's kernels from `kelvin` and the rules of
//! `quadrature`). The system is reordered by column exchange and pre-inverted for the fixed
//! vertices; contacts enter by the Woodbury formula (`system`). Reactions are tractions times
//! tributary areas. With `alpha > 0` the static solution becomes a target approached with
//! eq. 13 (`viscous`). Gravity enters through a particular solution (`body_force`), so no
//! volume integral is needed.

mod assembly;
mod body_force;
mod border;
mod contact_rims;
mod cut;
mod deformable;
mod incision_worker;
mod kelvin;
mod model;
mod points;
mod quadrature;
mod rim_worker;
mod stroke;
mod system;
mod viscous;

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_along;
#[cfg(test)]
mod tests_background;
#[cfg(test)]
mod tests_cut;
#[cfg(test)]
mod tests_points;
#[cfg(test)]
mod tests_quadrature;
#[cfg(test)]
mod tests_stiffness;

pub use assembly::Influence;
pub use contact_rims::DEFAULT_RIM_CACHE_BYTES;
pub use cut::CutUpdate;
pub use kelvin::Kelvin;
pub use model::{Bem, BemParams};
pub use system::BemSystem;
pub use viscous::SurfaceGraph;
