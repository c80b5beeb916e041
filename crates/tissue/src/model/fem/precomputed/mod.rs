//! `fem-precomputed-tensors`: pre-computed displacement and force tensors (Cotin 1996).
//!
//! For every free surface node k, the elementary solution "node k displaced by ū, every
//! other surface node free, fixed ones fixed" is stored as 3×3 tensors: the displacement of
//! every surface node i, u_i = T^U_{i,k} ū, and the force at k, P_k = T^F_k ū. Instead of n
//! separate solves they are derived from the condensed compliance W (`surface_response`):
//! the elementary solution is u = W_{:,k} λ with W_kk λ = ū, so T^F_k = W_kk⁻¹ and
//! T^U_{i,k} = W_ik W_kk⁻¹. W itself is then dropped; the tensors take n²·9 doubles (the
//! liver's 137 free surface nodes: 1.35 MB; a 2194-node surface would take 347 MB).
//!
//! Several simultaneous contacts by superposition: the "virtual" displacements a_k of the
//! contact nodes solve Σ_k T^U_{j,k} a_k = ū_j − u0_j (a small non-symmetric system, dense
//! LU), then u_i = u0_i + Σ_k T^U_{i,k} a_k and P_k = T^F_k a_k, where u0 is the response to
//! the loads alone. Same answers as `fem-static` (linear order) and `fem-condensed`.

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
mod tests;

/// The `[model]` settings of `fem-precomputed-tensors` (none yet).
#[derive(Clone, Copy, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {}

/// Linear FEM answered from pre-computed elementary tensors.
pub struct FemPrecomputedTensors {
    core: SurfaceCore,
    /// Free surface nodes.
    n: usize,
    /// T^U_{i,k} at `k * n + i`.
    t_u: Vec<Mat3>,
    /// T^F_k.
    t_f: Vec<Mat3>,
    /// W_kk, to turn condensed loads into displacements (u0).
    w_diag: Vec<Mat3>,
    u0: Vec<Vec3>,
}

impl std::fmt::Debug for FemPrecomputedTensors {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FemPrecomputedTensors")
            .field("surface_nodes", &self.n)
            .finish()
    }
}

fn block(w: &faer::Mat<Real>, i: usize, k: usize) -> Mat3 {
    block3(w.as_ref(), 3 * i, 3 * k)
}

impl FemPrecomputedTensors {
    /// Builds from the registry's input; the tensors wait for the first fixed set.
    pub fn from_input(input: &BuildInput<'_>) -> Result<Self, Error> {
        let _: Params = parse_params("fem-precomputed-tensors", input.params)?;
        let mesh = input.mesh.tet_mesh(input.source)?;
        let materials = input.element_materials(mesh.tets.len())?;
        Self::from_static(
            FemStatic::with_materials(&mesh, materials, Order::Linear)?,
            &[],
            &|_| {},
        )
    }

    /// Builds the model with `fixed` surface vertices (pre-computed now unless empty).
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
            n: 0,
            t_u: Vec::new(),
            t_f: Vec::new(),
            w_diag: Vec::new(),
            u0: Vec::new(),
        };
        model.install_fixed(fixed, progress)?;
        Ok(model)
    }

    /// Free (not fixed) surface vertices, in tensor index order.
    pub fn free_vertices(&self) -> &[u32] {
        &self.core.set.free
    }

    /// T^U_{i,k}: displacement of free node i per unit displacement of free node k alone.
    pub fn displacement_tensor(&self, i: usize, k: usize) -> Option<Mat3> {
        (i < self.n && k < self.n).then(|| self.t_u[k * self.n + i])
    }

    /// T^F_k: force at free node k per unit displacement of k alone.
    pub fn force_tensor(&self, k: usize) -> Option<Mat3> {
        self.t_f.get(k).copied()
    }

    /// Displacements of every mechanical node (the interior by one sparse solve), in m.
    pub fn interior_displacements(&mut self) -> Result<Vec<Vec3>, SimError> {
        self.core.node_displacements()
    }

    /// Sizes the step buffers for `contacts` contact vertices (they also grow on demand).
    pub fn reserve_contacts(&mut self, contacts: usize) {
        self.core.small.reserve(3 * contacts);
    }

    /// Bytes held by the tensors (n²·9 + 2n·9 doubles).
    pub fn tensor_bytes(&self) -> usize {
        (self.t_u.len() + self.t_f.len() + self.w_diag.len()) * 72
    }
}

impl SurfaceResponse for FemPrecomputedTensors {
    const KIND: &'static str = "fem-precomputed-tensors";
    const REBUILD_STAGE: &'static str = "pre-computing the surface tensors";
    const NO_CUT_REASON: &'static str = "its tensors are pre-computed for a fixed topology; \
        a cut would need all n² tensors again";

    fn core(&self) -> &SurfaceCore {
        &self.core
    }

    fn core_mut(&mut self) -> &mut SurfaceCore {
        &mut self.core
    }

    /// The tensors from W (see the module notes); W itself is dropped.
    fn adopt_compliance(&mut self, w: faer::Mat<Real>) -> Result<(), SimError> {
        let n = w.nrows() / 3;
        let w_diag: Vec<Mat3> = (0..n).map(|k| block(&w, k, k)).collect();
        let t_f: Vec<Mat3> = w_diag.iter().map(|b| b.inverse()).collect();
        if let Some(k) = t_f.iter().position(|t| !t.is_finite()) {
            return Err(SimError::NotPositiveDefinite {
                row: 3 * k,
                hint: "a diagonal block of the surface compliance is singular".into(),
            });
        }
        let mut t_u = Vec::with_capacity(n * n);
        for (k, tf) in t_f.iter().enumerate() {
            t_u.extend((0..n).map(|i| block(&w, i, k) * *tf));
        }
        (self.n, self.t_u, self.t_f, self.w_diag) = (n, t_u, t_f, w_diag);
        Ok(())
    }

    /// u0_i = Σ_k W_ik f̃_k = Σ_k T^U_{i,k} (W_kk f̃_k).
    fn update_u0(&mut self) {
        let f = &self.core.f_cond;
        self.u0.clear();
        self.u0.resize(self.n, Vec3::ZERO);
        for k in 0..self.n {
            let fk = Vec3::new(f[3 * k], f[3 * k + 1], f[3 * k + 2]);
            if fk == Vec3::ZERO {
                continue;
            }
            let a = self.w_diag[k] * fk;
            for (u, t) in self
                .u0
                .iter_mut()
                .zip(&self.t_u[k * self.n..(k + 1) * self.n])
            {
                *u += *t * a;
            }
        }
    }

    /// Σ_k T^U_jk a_k = target_j − u0_j for the virtual displacements a, then superposition.
    /// With contacts held along their normals, the same system in the contact forces
    /// (`solve::along`: a_k = W_kk n_k μ_k, one row per held direction).
    fn solve_contacts(&mut self) -> Result<(), SimError> {
        if self.core.holds_along() {
            let core = &mut self.core;
            let response = Tensors {
                n: self.n,
                t_u: &self.t_u,
                w_diag: &self.w_diag,
                u0: &self.u0,
                contacts: &core.contacts,
                targets: &core.targets,
            };
            core.held
                .solve(&response, &core.normals, &mut core.unknowns)?;
            self.superpose();
            return Ok(());
        }
        let m = self.core.targets.len();
        let (n, contacts) = (self.n, &self.core.contacts);
        let (a, rhs) = self.core.small.block_and_rhs(m);
        fill_tensor_block(&self.t_u, n, contacts, a);
        for (jb, &j) in contacts.iter().enumerate() {
            for r in 0..3 {
                rhs[3 * jb + r] = self.core.targets[3 * jb + r] - self.u0[j as usize][r];
            }
        }
        let rhs = self.core.small.solve_general_rhs(m)?;
        self.core.unknowns.copy_from_slice(rhs);
        self.superpose();
        Ok(())
    }

    fn contact_block(&self) -> Mat<Real> {
        let m = 3 * self.core.contacts.len();
        let mut a = Mat::zeros(m, m);
        fill_tensor_block(&self.t_u, self.n, &self.core.contacts, a.as_mut());
        a
    }

    /// λ_k = T_f[k] a_k.
    fn contact_force_map(&self, k: usize) -> Mat3 {
        self.t_f[self.core.contacts[k] as usize]
    }

    /// W_ab = T^U_{a,b} W_bb (T^U_{a,b} = W_ab W_bb⁻¹, module notes): W is not kept, but
    /// the tensors give back any of its blocks.
    fn compliance_between(&self, a: usize, b: usize) -> Mat3 {
        self.t_u[b * self.n + a] * self.w_diag[b]
    }

    fn free_displacement(&self, a: usize) -> Vec3 {
        self.u0[a]
    }

    /// u_i = u0_i + Σ_b T^U_{i,b} (W_bb f_b): the virtual displacement of a force f_b is
    /// W_bb f_b.
    fn superpose_forces(&mut self) {
        let n = self.n;
        let core = &mut self.core;
        let us = &mut core.us_trial;
        for (i, u) in self.u0.iter().enumerate() {
            us[3 * i..3 * i + 3].copy_from_slice(&u.to_array());
        }
        for &(b, f) in &core.point_forces {
            let a = self.w_diag[b] * f;
            for (i, t) in self.t_u[b * n..(b + 1) * n].iter().enumerate() {
                let d = *t * a;
                us[3 * i] += d.x;
                us[3 * i + 1] += d.y;
                us[3 * i + 2] += d.z;
            }
        }
    }

    fn own_memory_bytes(&self) -> usize {
        self.tensor_bytes()
    }

    fn details(&self) -> Vec<(String, String)> {
        vec![
            ("surface_nodes".into(), self.n.to_string()),
            ("tensor_bytes".into(), self.tensor_bytes().to_string()),
        ]
    }
}

impl FemPrecomputedTensors {
    /// u_i = u0_i + Σ_k T^U_{i,k} a_k into the trial surface displacements and
    /// λ_k = T^F_k a_k, for the contacts' virtual displacements a (`core.unknowns`).
    fn superpose(&mut self) {
        let n = self.n;
        let core = &mut self.core;
        let us = &mut core.us_trial;
        for (i, u) in self.u0.iter().enumerate() {
            us[3 * i..3 * i + 3].copy_from_slice(&u.to_array());
        }
        for (kb, &k) in core.contacts.iter().enumerate() {
            let a = &core.unknowns[3 * kb..3 * kb + 3];
            let ak = Vec3::new(a[0], a[1], a[2]);
            let tk = &self.t_u[k as usize * n..(k as usize + 1) * n];
            for (i, t) in tk.iter().enumerate() {
                let d = *t * ak;
                us[3 * i] += d.x;
                us[3 * i + 1] += d.y;
                us[3 * i + 2] += d.z;
            }
            let p = self.t_f[k as usize] * ak;
            core.lambda[3 * kb..3 * kb + 3].copy_from_slice(&p.to_array());
        }
    }
}

/// The tensors between the contacts: the unknowns are virtual displacements a_k, A_jk =
/// T^U_{j,k} and F_k = T^F_k = W_kk⁻¹, so A F⁻¹ = W_CC only up to roundoff (an LU).
struct Tensors<'a> {
    n: usize,
    t_u: &'a [Mat3],
    w_diag: &'a [Mat3],
    u0: &'a [Vec3],
    contacts: &'a [u32],
    targets: &'a [Real],
}

impl ContactResponse for Tensors<'_> {
    const SYMMETRIC: bool = false;

    fn block(&self, j: usize, k: usize) -> Mat3 {
        self.t_u[self.contacts[k] as usize * self.n + self.contacts[j] as usize]
    }

    fn unknown_per_force(&self, k: usize) -> Mat3 {
        self.w_diag[self.contacts[k] as usize]
    }

    fn gap(&self, k: usize) -> Vec3 {
        let t = &self.targets[3 * k..3 * k + 3];
        Vec3::new(t[0], t[1], t[2]) - self.u0[self.contacts[k] as usize]
    }
}

/// The contacts' superposition system into `a`: block (j, k) is T_u[k][j], the
/// displacement of contact j per unit virtual displacement a_k of contact k.
fn fill_tensor_block(t_u: &[Mat3], n: usize, contacts: &[u32], mut a: MatMut<'_, Real>) {
    for (kb, &k) in contacts.iter().enumerate() {
        for (jb, &j) in contacts.iter().enumerate() {
            let t = t_u[k as usize * n + j as usize];
            for c in 0..3 {
                for r in 0..3 {
                    a[(3 * jb + r, 3 * kb + c)] = t.col(c)[r];
                }
            }
        }
    }
}
