//! `fem-condensed`: fast finite elements (Bro-Nielsen; eq. 4-5 of the survey).
//!
//! Linear elastostatics condensed onto the free surface dofs and pre-inverted: W = C⁻¹ (see
//! `surface_response`). At run time the contact set may change every step: with contact
//! dofs p and condensed surface loads f̃, the contact forces solve the small SPD system
//! W_pp λ = u_p − (W f̃)_p (dense LLT, |p| ≤ 3·contacts), and every surface displacement is
//! u_s = W f̃ + W_{:,p} λ, read from the pre-inverted columns. A change of the *fixed* set
//! needs a new condensation (one sparse solve per surface dof plus a dense inversion): its
//! cost is reported in `info()` ("rebuilds", "last_rebuild_s"). The interior is computed
//! only on demand (`interior_displacements`). Same answers as `fem-static` (linear order).

use faer::{Mat, MatMut};
use serde::Deserialize;

use crate::error::{Error, SimError};
use crate::material::Material;
use crate::math::{Mat3, Real, Vec3};
use crate::mesh::TetMesh;
use crate::model::BuildInput;
use crate::model::registry::parse_params;
use crate::solve::{ContactResponse, block3};

use super::static_model::{FemStatic, Order};
use super::surface_response::{SurfaceCore, SurfaceResponse};

#[cfg(test)]
pub(crate) mod tests;
#[cfg(test)]
mod tests_along;
#[cfg(test)]
mod tests_points;

/// The `[model]` settings of `fem-condensed` (none yet).
#[derive(Clone, Copy, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {}

/// Condensed, pre-inverted linear FEM on the surface.
pub struct FemCondensed {
    core: SurfaceCore,
    /// The surface compliance W = C⁻¹ over the free surface dofs.
    w: Mat<Real>,
    /// W f̃: the surface displacements under the loads alone.
    u0: Vec<Real>,
}

impl std::fmt::Debug for FemCondensed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FemCondensed")
            .field("surface_dofs", &self.w.nrows())
            .finish()
    }
}

impl FemCondensed {
    /// Builds from the registry's input; the condensation waits for the first fixed set.
    pub fn from_input(input: &BuildInput<'_>) -> Result<Self, Error> {
        let _: Params = parse_params("fem-condensed", input.params)?;
        let mesh = input.mesh.tet_mesh(input.source)?;
        let materials = input.element_materials(mesh.tets.len())?;
        Self::from_static(
            FemStatic::with_materials(&mesh, materials, Order::Linear)?,
            &[],
            &|_| {},
        )
    }

    /// Builds the model with `fixed` surface vertices (condensed now unless empty).
    pub fn new(mesh: &TetMesh, material: Material, fixed: &[u32]) -> Result<Self, Error> {
        Self::new_with_progress(mesh, material, fixed, &|_| {})
    }

    /// Like `new`; `progress` receives the fraction of the condensation done (0..1).
    pub fn new_with_progress(
        mesh: &TetMesh,
        material: Material,
        fixed: &[u32],
        progress: &dyn Fn(f64),
    ) -> Result<Self, Error> {
        Self::from_static(
            FemStatic::new(mesh, material, Order::Linear)?,
            fixed,
            progress,
        )
    }

    /// Around a built `fem-static` (its elements' materials, per region or one): the
    /// surface response is condensed from its stiffness, gravity from its body load.
    fn from_static(fem: FemStatic, fixed: &[u32], progress: &dyn Fn(f64)) -> Result<Self, Error> {
        let mut model = Self {
            core: SurfaceCore::new(fem),
            w: Mat::zeros(0, 0),
            u0: Vec::new(),
        };
        model.install_fixed(fixed, progress)?;
        Ok(model)
    }

    /// The surface compliance W (3n × 3n over the free surface vertices, in m/N).
    pub fn compliance(&self) -> &Mat<Real> {
        &self.w
    }

    /// Free (not fixed) surface vertices, in the order of W's 3×3 blocks.
    pub fn free_vertices(&self) -> &[u32] {
        &self.core.set.free
    }

    /// Displacements of every mechanical node (surface from the last step, interior from
    /// K_ii⁻¹ (f_i − K_is u_s): one sparse solve), in m.
    pub fn interior_displacements(&mut self) -> Result<Vec<Vec3>, SimError> {
        self.core.node_displacements()
    }

    /// Sizes the step buffers for `contacts` contact vertices (they also grow on demand).
    pub fn reserve_contacts(&mut self, contacts: usize) {
        self.core.small.reserve(3 * contacts);
    }
}

impl SurfaceResponse for FemCondensed {
    const KIND: &'static str = "fem-condensed";
    const REBUILD_STAGE: &'static str = "condensing the stiffness to the surface";
    const NO_CUT_REASON: &'static str = "its surface compliance is pre-computed for a fixed \
        topology; a cut would need a new condensation and inversion";

    fn core(&self) -> &SurfaceCore {
        &self.core
    }

    fn core_mut(&mut self) -> &mut SurfaceCore {
        &mut self.core
    }

    fn adopt_compliance(&mut self, w: Mat<Real>) -> Result<(), SimError> {
        self.w = w;
        Ok(())
    }

    fn update_u0(&mut self) {
        let n = self.w.nrows();
        self.u0.clear();
        self.u0.resize(n, 0.0);
        for (j, &f) in self.core.f_cond.iter().enumerate() {
            if f != 0.0 {
                for (u, &w) in self.u0.iter_mut().zip(self.w.col_as_slice(j)) {
                    *u += w * f;
                }
            }
        }
    }

    /// W_pp λ = u_p − (W f̃)_p, then u_s = W f̃ + W_{:,p} λ.
    fn solve_contacts(&mut self) -> Result<(), SimError> {
        if self.core.holds_along() {
            return self.solve_contacts_along();
        }
        let m = self.core.targets.len();
        let contacts = &self.core.contacts;
        let dof = |r: usize| 3 * contacts[r / 3] as usize + r % 3;
        let (block, rhs) = self.core.small.block_and_rhs(m);
        fill_compliance_block(&self.w, contacts, block, true);
        for (r, x) in rhs.iter_mut().enumerate() {
            *x = self.core.targets[r] - self.u0[dof(r)];
        }
        let rhs = self.core.small.solve_spd_rhs(m)?;
        self.core.lambda.copy_from_slice(rhs);
        self.superpose_lambda();
        Ok(())
    }

    fn contact_block(&self) -> Mat<Real> {
        let m = 3 * self.core.contacts.len();
        let mut a = Mat::zeros(m, m);
        fill_compliance_block(&self.w, &self.core.contacts, a.as_mut(), false);
        a
    }

    /// λ is the unknown itself.
    fn contact_force_map(&self, _k: usize) -> Mat3 {
        Mat3::IDENTITY
    }

    fn compliance_between(&self, a: usize, b: usize) -> Mat3 {
        block3(self.w.as_ref(), 3 * a, 3 * b)
    }

    fn free_displacement(&self, a: usize) -> Vec3 {
        Vec3::from_slice(&self.u0[3 * a..3 * a + 3])
    }

    /// u_s = u₀ + Σ_b W_{:,b} f_b, from the pre-inverted columns.
    fn superpose_forces(&mut self) {
        let core = &mut self.core;
        core.us_trial.copy_from_slice(&self.u0);
        for &(b, f) in &core.point_forces {
            for (i, &fi) in f.to_array().iter().enumerate() {
                if fi != 0.0 {
                    let column = self.w.col_as_slice(3 * b + i);
                    for (u, &w) in core.us_trial.iter_mut().zip(column) {
                        *u += w * fi;
                    }
                }
            }
        }
    }

    fn own_memory_bytes(&self) -> usize {
        let n = self.w.nrows();
        n * n * 8
    }

    fn details(&self) -> Vec<(String, String)> {
        let n = self.w.nrows();
        vec![
            ("surface_dofs".into(), n.to_string()),
            ("compliance_bytes".into(), (n * n * 8).to_string()),
            (
                "contact_capacity".into(),
                (self.core.small.a.nrows() / 3).to_string(),
            ),
        ]
    }
}

/// W_CC, the compliance between the contacts (indices into the free surface vertices), into
/// `a`; only its lower triangle when `lower` (what a Cholesky factorisation reads).
fn fill_compliance_block(w: &Mat<Real>, contacts: &[u32], mut a: MatMut<'_, Real>, lower: bool) {
    let m = 3 * contacts.len();
    let dof = |r: usize| 3 * contacts[r / 3] as usize + r % 3;
    for c in 0..m {
        for r in if lower { c } else { 0 }..m {
            a[(r, c)] = w[(dof(r), dof(c))];
        }
    }
}

impl FemCondensed {
    /// The contact problem with some contacts held along their normal only, solved exactly
    /// with the compliance (`solve::along`: Bᵀ W_CC B μ = Bᵀ(t − u₀), symmetric positive
    /// definite as W_CC is, one row per held direction), then u_s = u₀ + W_{:,C} λ.
    fn solve_contacts_along(&mut self) -> Result<(), SimError> {
        let core = &mut self.core;
        let response = Compliance {
            w: &self.w,
            contacts: &core.contacts,
            targets: &core.targets,
            u0: &self.u0,
        };
        core.held
            .solve(&response, &core.normals, &mut core.lambda)?;
        self.superpose_lambda();
        Ok(())
    }

    /// u_s = u₀ + W_{:,C} λ into the trial surface displacements.
    fn superpose_lambda(&mut self) {
        let core = &mut self.core;
        core.us_trial.copy_from_slice(&self.u0);
        for (k, &a) in core.contacts.iter().enumerate() {
            for i in 0..3 {
                let l = core.lambda[3 * k + i];
                if l != 0.0 {
                    let column = self.w.col_as_slice(3 * a as usize + i);
                    for (u, &w) in core.us_trial.iter_mut().zip(column) {
                        *u += w * l;
                    }
                }
            }
        }
    }
}

/// The compliance between the contacts: the unknowns are the contact forces (F = I).
struct Compliance<'a> {
    w: &'a Mat<Real>,
    contacts: &'a [u32],
    targets: &'a [Real],
    u0: &'a [Real],
}

impl ContactResponse for Compliance<'_> {
    const SYMMETRIC: bool = true;

    fn block(&self, j: usize, k: usize) -> Mat3 {
        let (a, b) = (self.contacts[j] as usize, self.contacts[k] as usize);
        block3(self.w.as_ref(), 3 * a, 3 * b)
    }

    fn unknown_per_force(&self, _k: usize) -> Mat3 {
        Mat3::IDENTITY
    }

    fn gap(&self, k: usize) -> Vec3 {
        let d = 3 * self.contacts[k] as usize;
        let t = &self.targets[3 * k..3 * k + 3];
        Vec3::new(
            t[0] - self.u0[d],
            t[1] - self.u0[d + 1],
            t[2] - self.u0[d + 2],
        )
    }
}
