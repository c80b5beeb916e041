//! `fem-corotational`: linear elasticity in a frame that rotates with each element, integrated
//! by implicit Euler: large rotations at the cost of linear FEM, the method of SOFA's
//! `TetrahedronFEMForceField` (method "polar"), Vega and PhysX.
//!
//! Method (Müller & Gross 2004, "Interactive virtual materials"): each tetrahedron's
//! deformation gradient F = R S is split by polar decomposition (`rotation`); the element
//! force is the linear one computed in the rotated frame, f_e = −R K_e (Rᵀx − X), so a rigid
//! motion produces no force (linear FEM produces forces growing with the rotation angle, and
//! its equilibrium inflates rotated parts). The stiffness is R K_e Rᵀ, the derivative of R
//! being dropped (`force`).
//!
//! Time integration (Baraff & Witkin 1998), one linear solve per step:
//! (M + h D + h² K) Δv = h (f − h K v), v ← v + Δv, x ← x + h v, with lumped masses M,
//! Rayleigh damping D = α M + β K (α = `material.damping`, β = `material.stiffness_damping`),
//! f the elastic, damping and external forces at the start of the step and K the stiffness
//! corotated at the start of the step. The system is solved by conjugate gradients
//! (`solve::cg`) on the assembled block-sparse K, warm-started from the last Δv, to the
//! relative residual `cg_tolerance` (default 1e-6, which settles within 1e-4 of the converged
//! answer on the issue-24 beam) or at most `cg_iterations` (default 200; a step that stops
//! there says `capped` in its `StepInfo`). The preconditioner (`solver`):
//! - `warp-pcg` (`warp`): the rest matrix c_m M + c_k K₀ factorised once by sparse Cholesky,
//!   rotated per node each step; 3 to 4 iterations per step on the stiff beam where Jacobi
//!   needs ~300;
//! - `jacobi-pcg`: the diagonal, nothing to factorise;
//! - `auto` (default): warp unless its factor would exceed `MAX_FACTOR_NNZ` values.
//!
//! Constrained dofs are projected out: fixed nodes get zero velocity, prescribed
//! ones the velocity that reaches their target in this step. A frictionless instrument
//! contact (`set_constraints_along`) is a contact that only pushes, held along its normal by
//! the CG's filter S = I − n nᵀ with an active set settled within the step (`contact`).
//!
//! Reactions are the forces the tissue exerts on the constrained nodes: elastic + damping +
//! the node's share of the external loads, evaluated after the step; at rest they balance the
//! loads as in `fem-static`.
//!
//! What it cannot do: cut (the element list and masses are fixed when built); a capped CG
//! (or a large step) trades accuracy for speed, so fast transients are damped numerically.
//! A change of the held nodes (an instrument grasping more or fewer vertices) refactorises
//! the rest matrix on the stepping thread (e.g. ~30 ms at 20k tetrahedra).
//!
//! - `rotation`: polar decomposition by scaled Newton, with inverted elements handled
//! - `force`: element rest data, forces, stiffness products and diagonal, energy
//! - `bsr`: the step's stiffness assembled into 3×3 block-sparse rows for the CG products
//! - `warp`: the warp-canceling preconditioner (rest factor, node rotations)
//! - `step`: the implicit Euler step; `deformable`: the `Deformable` interface
//! - `contact`: frictionless contacts that only push (the filter, the active set's data),
//!   and a fine contact surface's points (`contact::points`, held in the step by their
//!   contact problem on the step's matrix)

mod bsr;
mod contact;
mod deformable;
pub mod force;
pub mod rotation;
mod step;
mod warp;

use std::time::Instant;

use serde::Deserialize;

use crate::error::{Error, SimError};
use crate::integrate::contact::HeldContacts;
use crate::interact::Loads;
use crate::material::{ElementMaterials, Material};
use crate::math::{Mat3, Real, Vec3, is_finite_vec};
use crate::mesh::{Boundary, TetMesh, boundary_surface};
use crate::model::registry::parse_params;
use crate::model::{BuildInput, ConstraintReactions};
use crate::solve::CgWorkspace;

use super::mass::lumped_masses_of;
use force::{ElementRest, Lames};

/// How `fem-corotational` solves (M + hD + h²K) Δv = b each step (`[model] solver`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CorotationalSolver {
    /// `warp-pcg` unless the rest matrix's Cholesky factor would be too large
    /// (`MAX_FACTOR_NNZ`), then `jacobi-pcg`.
    #[default]
    Auto,
    /// CG preconditioned by the factorised rest matrix, rotated per node (`warp`).
    WarpPcg,
    /// CG preconditioned by the diagonal: no factorisation, many more iterations on stiff
    /// materials.
    JacobiPcg,
}

/// Above this many stored values of the rest matrix's Cholesky factor (8 bytes each, so
/// 400 MB), `auto` uses Jacobi-PCG instead of the warp preconditioner.
pub const MAX_FACTOR_NNZ: usize = 50_000_000;

/// The `[model]` settings of `fem-corotational`.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CorotationalParams {
    /// The linear solver (default `auto`).
    #[serde(default)]
    pub solver: CorotationalSolver,
    /// Maximum conjugate-gradient iterations per step (default 200); a step that stops
    /// there before `cg_tolerance` reports `capped`.
    #[serde(default = "default_iterations")]
    pub cg_iterations: usize,
    /// Relative residual ‖b − A Δv‖ / ‖b‖ at which CG stops (default 1e-6).
    #[serde(default = "default_tolerance")]
    pub cg_tolerance: Real,
}

fn default_iterations() -> usize {
    200
}
fn default_tolerance() -> Real {
    1e-6
}

impl Default for CorotationalParams {
    fn default() -> Self {
        Self {
            solver: CorotationalSolver::Auto,
            cg_iterations: default_iterations(),
            cg_tolerance: default_tolerance(),
        }
    }
}

/// The solver a model settled on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Resolved {
    Warp,
    Jacobi,
}

/// How a node is held during a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Hold {
    Free,
    /// Zero velocity.
    Fixed,
    /// Reaches this position at the end of the step.
    Target(Vec3),
}

/// Scratch buffers sized at build, so that a step allocates nothing.
#[derive(Debug)]
struct Workspace {
    cg: CgWorkspace,
    /// The step's corotated stiffness, assembled once per step.
    stiffness: bsr::BlockStiffness,
    rhs: Vec<Real>,
    inv_diag: Vec<Real>,
    dv: Vec<Real>,
    kv: Vec<Real>,
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    rotations: Vec<Mat3>,
    elastic: Vec<Real>,
    /// Per-element node forces of the parallel force loop.
    element_forces: Vec<[Vec3; 4]>,
    /// The CG's filter (held dofs, contacts held along their normals).
    filter: contact::Filter,
    /// Per contact, within the step: held along its normal; let go for pulling; its push.
    held: HeldContacts,
    pushes: Vec<Real>,
    /// The fine surface's points within the step (`contact::PointWork`).
    points: contact::PointWork,
}

/// The corotational implicit model (see the module doc).
#[derive(Debug)]
pub struct FemCorotational {
    /// The default material (damping, and everything without per-region materials).
    material: Material,
    /// Each element's Lamé parameters (one pair without per-region materials).
    lame: Lames,
    params: CorotationalParams,
    mesh: TetMesh,
    rest: Vec<Vec3>,
    elements: Vec<ElementRest>,
    masses: Vec<Real>,
    boundary: Boundary,
    surface_positions: Vec<Vec3>,
    // State.
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    rotations: Vec<Mat3>,
    /// Elastic forces at `x` (flat), valid when `elastic_valid`.
    elastic: Vec<Real>,
    elastic_valid: bool,
    /// Last Δv (flat): the CG warm start.
    last_dv: Vec<Real>,
    steps: u64,
    // Constraints and loads, per node.
    holds: Vec<Hold>,
    /// Frictionless contacts that only push (`contact`), on free nodes.
    contacts: Vec<contact::PushContact>,
    /// Per node: a contact on it pushed in the last step (the next step starts it held).
    pushed: Vec<bool>,
    /// A fine surface's points (`Deformable::set_point_contacts`) on the nodes, held in the
    /// step (`contact::points`), and the push on each over the last step, N.
    points: Vec<crate::integrate::PointHold>,
    point_push: Vec<Real>,
    /// Solves the last step's active set took, and steps that stopped at the bound.
    contact_solves: usize,
    contact_caps: u64,
    /// The mesh's size (bounding-box diagonal), m: the scale of roundoff in positions.
    length: Real,
    external: Vec<Vec3>,
    node_reactions: Vec<Vec3>,
    loads: Loads,
    reactions: ConstraintReactions,
    ws: Workspace,
    precompute_seconds: Real,
    last_cg: crate::solve::CgResult,
    /// The solver in use (`None`: to be chosen at the next step).
    resolved: Option<Resolved>,
    /// Why `auto` chose Jacobi-PCG, if it did.
    fallback_reason: Option<String>,
    warp: Option<warp::WarpPreconditioner>,
}

impl FemCorotational {
    /// Builds the model from the registry's input (`[model] cg_iterations`, `cg_tolerance`).
    pub fn from_input(input: &BuildInput<'_>) -> Result<Self, Error> {
        let params: CorotationalParams = parse_params("fem-corotational", input.params)?;
        let mesh = input.mesh.tet_mesh(input.source)?;
        let materials = input.element_materials(mesh.tets.len())?;
        Self::with_materials(&mesh, &materials, params)
    }

    /// Validates mesh, material and settings; computes rest data and lumped masses.
    pub fn new(
        mesh: &TetMesh,
        material: Material,
        params: CorotationalParams,
    ) -> Result<Self, Error> {
        Self::with_materials(mesh, &ElementMaterials::Uniform(material), params)
    }

    /// Like `new`, each element with its own material (e in the order of `mesh.tets`):
    /// its Lamé parameters and its share of the lumped masses.
    pub fn with_materials(
        mesh: &TetMesh,
        materials: &ElementMaterials,
        params: CorotationalParams,
    ) -> Result<Self, Error> {
        let material = materials.default_material().validated()?;
        if !(params.cg_tolerance.is_finite() && params.cg_tolerance >= 0.0) {
            return Err(SimError::BadParameter {
                name: "cg_tolerance",
                value: params.cg_tolerance.to_string(),
                reason: "must be a finite value >= 0".into(),
            }
            .into());
        }
        mesh.validate_for_simulation()?;
        let start = Instant::now();
        let mesh = mesh.compacted();
        let mut elements = Vec::with_capacity(mesh.tets.len());
        for (t, tet) in mesh.tets.iter().enumerate() {
            let e = ElementRest::new(*tet, &mesh.corners(t)).ok_or(
                crate::error::MeshError::DegenerateTet {
                    tet: t,
                    volume: mesh.tet_volume(t),
                    quality: 0.0,
                },
            )?;
            elements.push(e);
        }
        let masses = lumped_masses_of(&mesh, materials);
        let boundary = boundary_surface(&mesh);
        let rest = mesh.vertices.clone();
        let (n, ne) = (rest.len(), elements.len());
        let length = mesh.bounds().map_or(0.0, |(lo, hi)| (hi - lo).length());
        let mut model = Self {
            lame: Lames::of_materials(materials, ne),
            material,
            params,
            surface_positions: boundary.surface.vertices.clone(),
            x: rest.clone(),
            v: vec![Vec3::ZERO; n],
            rotations: vec![Mat3::IDENTITY; ne],
            elastic: vec![0.0; 3 * n],
            elastic_valid: true,
            last_dv: vec![0.0; 3 * n],
            steps: 0,
            holds: vec![Hold::Free; n],
            contacts: Vec::new(),
            pushed: vec![false; n],
            points: Vec::new(),
            point_push: Vec::new(),
            contact_solves: 0,
            contact_caps: 0,
            length,
            external: vec![Vec3::ZERO; n],
            node_reactions: vec![Vec3::ZERO; n],
            loads: Loads::default(),
            reactions: ConstraintReactions::default(),
            ws: Workspace {
                cg: CgWorkspace::new(3 * n),
                stiffness: bsr::BlockStiffness::new(&elements, n),
                rhs: vec![0.0; 3 * n],
                inv_diag: vec![0.0; 3 * n],
                dv: vec![0.0; 3 * n],
                kv: vec![0.0; 3 * n],
                x: rest.clone(),
                v: vec![Vec3::ZERO; n],
                rotations: vec![Mat3::IDENTITY; ne],
                elastic: vec![0.0; 3 * n],
                element_forces: Vec::new(),
                filter: contact::Filter::default(),
                held: HeldContacts::default(),
                pushes: Vec::new(),
                points: contact::PointWork::default(),
            },
            precompute_seconds: start.elapsed().as_secs_f64(),
            last_cg: Default::default(),
            resolved: None,
            fallback_reason: None,
            warp: None,
            boundary,
            rest,
            elements,
            masses,
            mesh,
        };
        model.resolve_solver()?;
        model.precompute_seconds = start.elapsed().as_secs_f64();
        Ok(model)
    }

    /// Chooses the solver for `params.solver`, building the warp preconditioner's symbolic
    /// factorisation if it is needed and not built yet.
    fn resolve_solver(&mut self) -> Result<(), SimError> {
        self.fallback_reason = None;
        let want_warp = match self.params.solver {
            CorotationalSolver::JacobiPcg => false,
            CorotationalSolver::WarpPcg | CorotationalSolver::Auto => true,
        };
        if want_warp && self.warp.is_none() {
            match warp::WarpPreconditioner::new(&self.elements, &self.lame, &self.rest) {
                Ok(w) => self.warp = Some(w),
                Err(e) if self.params.solver == CorotationalSolver::Auto => {
                    self.fallback_reason = Some(e.to_string());
                }
                Err(e) => return Err(e),
            }
        }
        let nnz = self.warp.as_ref().map_or(0, |w| w.factor_nnz());
        self.resolved = Some(match self.params.solver {
            CorotationalSolver::JacobiPcg => Resolved::Jacobi,
            CorotationalSolver::WarpPcg => Resolved::Warp,
            CorotationalSolver::Auto if self.warp.is_some() && nnz <= MAX_FACTOR_NNZ => {
                Resolved::Warp
            }
            CorotationalSolver::Auto => {
                if self.fallback_reason.is_none() {
                    self.fallback_reason = Some(format!(
                        "the rest matrix's factor would hold {nnz} values (> {MAX_FACTOR_NNZ})"
                    ));
                }
                self.warp = None;
                Resolved::Jacobi
            }
        });
        Ok(())
    }

    pub fn params(&self) -> CorotationalParams {
        self.params
    }
    /// Changes the solver, CG cap and tolerance (a new solver is set up at the next step).
    pub fn set_params(&mut self, params: CorotationalParams) {
        if params.solver != self.params.solver {
            self.resolved = None;
        }
        self.params = params;
    }
    pub fn material(&self) -> &Material {
        &self.material
    }
    /// Rest positions of the nodes (the compacted mesh's vertices).
    pub fn rest_nodes(&self) -> &[Vec3] {
        &self.rest
    }
    pub fn positions(&self) -> &[Vec3] {
        &self.x
    }
    pub fn velocities(&self) -> &[Vec3] {
        &self.v
    }
    /// Every node's velocity zeroed, the positions kept (`Deformable::stop_motion`); the
    /// CG's warm start (the last Δv) is dropped with them.
    pub fn stop_nodes(&mut self) {
        self.v.iter_mut().for_each(|v| *v = Vec3::ZERO);
        self.last_dv.iter_mut().for_each(|d| *d = 0.0);
    }
    pub fn masses(&self) -> &[Real] {
        &self.masses
    }
    pub fn elements(&self) -> &[ElementRest] {
        &self.elements
    }
    pub fn lame(&self) -> &Lames {
        &self.lame
    }
    /// The mechanical node of each surface vertex.
    pub fn surface_nodes(&self) -> &[u32] {
        &self.boundary.nodes
    }
    /// Force the tissue exerts on each constrained node after the last step (zero elsewhere).
    pub fn node_reactions(&self) -> &[Vec3] {
        &self.node_reactions
    }

    /// Elastic forces at the current positions, per node.
    pub fn elastic_forces(&mut self) -> Vec<Vec3> {
        self.ensure_elastic();
        self.elastic
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect()
    }

    /// Replaces positions and velocities (e.g. a pre-stretched start); lengths must match.
    pub fn set_state(&mut self, x: &[Vec3], v: &[Vec3]) -> Result<(), SimError> {
        let n = self.rest.len();
        if x.len() != n || v.len() != n || !x.iter().chain(v).all(|p| is_finite_vec(*p)) {
            return Err(SimError::BadParameter {
                name: "state",
                value: format!("{} positions, {} velocities", x.len(), v.len()),
                reason: format!("needs {n} finite positions and velocities"),
            });
        }
        self.x.copy_from_slice(x);
        self.v.copy_from_slice(v);
        self.elastic_valid = false;
        self.update_surface();
        Ok(())
    }

    /// Holds nodes: `fixed` get zero velocity, `prescribed` reach their target in each step
    /// (fixed wins); no contacts. Node ids must exist and targets be finite.
    pub fn set_node_constraints(
        &mut self,
        fixed: &[usize],
        prescribed: &[(usize, Vec3)],
    ) -> Result<(), SimError> {
        let n = self.rest.len();
        let bad = |what: String| SimError::BadParameter {
            name: "constraints",
            value: what,
            reason: format!("needs a node < {n} and a finite target"),
        };
        for &(node, p) in prescribed {
            if node >= n || !is_finite_vec(p) {
                return Err(bad(format!("node {node} -> {p}")));
            }
        }
        if let Some(&node) = fixed.iter().find(|&&node| node >= n) {
            return Err(bad(format!("fixed node {node}")));
        }
        self.holds.iter_mut().for_each(|h| *h = Hold::Free);
        for &(node, p) in prescribed {
            self.holds[node] = Hold::Target(p);
        }
        for &node in fixed {
            self.holds[node] = Hold::Fixed;
        }
        self.contacts.clear();
        self.node_reactions.iter_mut().for_each(|r| *r = Vec3::ZERO);
        Ok(())
    }

    /// External loads per node: gravity (m/s², as the lumped share m_i g) plus point forces.
    pub fn set_node_loads(
        &mut self,
        gravity: Vec3,
        forces: &[(usize, Vec3)],
    ) -> Result<(), SimError> {
        let n = self.rest.len();
        if !is_finite_vec(gravity) {
            return Err(SimError::BadParameter {
                name: "gravity",
                value: gravity.to_string(),
                reason: "must be finite".into(),
            });
        }
        if let Some(&(node, f)) = forces
            .iter()
            .find(|(node, f)| *node >= n || !is_finite_vec(*f))
        {
            return Err(SimError::BadParameter {
                name: "point_loads",
                value: format!("node {node} -> {f}"),
                reason: format!("needs a node < {n} and a finite force"),
            });
        }
        for (e, m) in self.external.iter_mut().zip(&self.masses) {
            *e = gravity * *m;
        }
        for &(node, f) in forces {
            self.external[node] += f;
        }
        Ok(())
    }

    fn update_surface(&mut self) {
        for (s, &node) in self.boundary.nodes.iter().enumerate() {
            self.surface_positions[s] = self.x[node as usize];
        }
    }

    /// Recomputes rotations and elastic forces at `x` if a state change invalidated them.
    fn ensure_elastic(&mut self) {
        if !self.elastic_valid {
            self.elastic.iter_mut().for_each(|f| *f = 0.0);
            force::elastic_forces(
                &self.elements,
                &self.lame,
                crate::math::flatten(&self.x),
                &mut self.rotations,
                &mut self.elastic,
                &mut self.ws.element_forces,
            );
            self.elastic_valid = true;
        }
    }
}

#[cfg(test)]
mod tests;
