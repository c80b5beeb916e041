//! `fem-explicit` and `fem-semi-implicit`: linear elastodynamics on 4-node tetrahedra
//! (survey section 3.1.3).
//!
//! The semi-discrete equation of motion is (6)
//!
//!   M Ü + D U̇ + K U = F,
//!
//! with K the static model's stiffness (same `Assembler`, same `element_linear::stiffness`),
//! M lumped (each tetrahedron gives ρV/4 to each corner, `mass::lumped_masses`) and Rayleigh
//! damping D = αM, α = `material.damping` (1/s). Central differences
//! Ü ≈ (U⁺ − 2U + U⁻)/Δt², U̇ ≈ (U⁺ − U⁻)/(2Δt), with U⁺ = U_{t+Δt}, U⁻ = U_{t−Δt}, give
//!
//!   M (U⁺ − 2U + U⁻)/Δt² + αM (U⁺ − U⁻)/(2Δt) + K U = F.
//!
//! Solving for U⁺ and multiplying by Δt gives exactly the survey's printed form (7)
//!
//!   U⁺ = (α/2 + 1/Δt)⁻¹ { (2/Δt) U + (α/2 − 1/Δt) U⁻ − M⁻¹ Δt [K U − F] },
//!
//! every term of which has units of U/Δt (checked: the printed form is consistent).
//!
//! `explicit`: (7) as written, one sparse product K U per step. It is stable for
//! Δt < Δt_crit = 2/ω_max, ω_max² the largest eigenvalue of M⁻¹K, whatever α ≥ 0 (the
//! characteristic polynomial (1+a)z² − (2 − ω²Δt²)z + (1−a), a = αΔt/2, has both roots in
//! the unit disc iff ωΔt < 2). ω_max² is estimated at build by power iteration on
//! M^{-1/2} K M^{-1/2} (`critical_dt`) and bounded by Gershgorin (`critical_dt_bound`, a
//! guaranteed-stable step); both are in `info().details`. The constrained system's ω_max is
//! at most the free body's, so the estimate holds for every constraint set.
//!
//! `semi_implicit`: (8)-(10), the same quotients with the elastic force at t+Δt,
//!
//!   (8)  K̂ U⁺ = F̂,
//!   (9)  K̂ = K + (1/Δt² + α/(2Δt)) M,
//!   (10) F̂ = F + M [ (2/Δt²) U − (1/Δt² − α/(2Δt)) U⁻ ].
//!
//! K̂ is factorised once per (Δt, held set) with the static model's `System` (held dofs
//! eliminated keeping the pattern). For this linear system the scheme is implicit in K and
//! unconditionally stable (the roots of (1 + ω²Δt² + a)z² − 2z + (1 − a) lie in the unit
//! disc for every ωΔt); it damps high frequencies numerically. The tests run it at 100× the
//! explicit Δt_crit.
//!
//! Constraints: fixed vertices are held at U = 0; prescribed vertices reach their target at
//! the end of the step (U⁺ = target). Reactions, the forces the tissue exerts on the
//! constraints, are F − (K U⁺ + M Ü + αM U̇) on held dofs, so at rest they equal the
//! static model's F − K U. Changing Δt between steps keeps the velocity (U − U⁻)/Δt.
//! A prescribed vertex given with a direction (`set_constraints_along`: an instrument's
//! frictionless contact) is a contact that only pushes (`contacts`): free in the scheme,
//! kept out of the instrument within the step, its reaction never a pull.
//!
//! What they cannot do: the strain is linear, so large rotations are not rigid (a rotated
//! part gains volume and spurious elastic forces; use the corotational model); linear tets
//! are too stiff in bending (see the frequency table in `tests`); the topology is fixed, so
//! they cannot cut.
//!
//! - `common`: shared state (mesh, K, M, boundary, constraints, time levels, reactions,
//!   the last good state, ω_max estimates) and the forwarding `Deformable` impl
//! - `constraints`: surface constraints and loads to dofs, reactions per constraint
//! - `contacts`: frictionless contacts that only push (issue 20)
//! - `forward`: the `Deformable` methods both schemes forward to `Core`
//! - `points`: a fine contact surface's points (issue 20)
//! - `explicit`: `FemExplicit`; `semi_implicit`: `FemSemiImplicit`

mod common;
mod constraints;
mod contacts;
mod explicit;
mod forward;
mod points;
mod semi_implicit;

pub use explicit::FemExplicit;
pub use semi_implicit::FemSemiImplicit;

#[cfg(test)]
mod tests;
