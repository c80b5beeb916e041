//! The mechanical system both kinds integrate: tetrahedra with their tensors, lumped
//! masses, damping and external loads, seen as particles with forces.
//!
//! Forces, all per node: elastic −K u (linear tensors), plus the St Venant–Kirchhoff
//! terms of the tetrahedra in the non-linear set, plus the volume penalty, minus damping
//! α m v + β K v (Rayleigh, with the linear K), plus loads. Removing a tetrahedron (cut)
//! updates every tensor it contributed to, and its lumped mass, in O(1).

use crate::error::SimError;
use crate::integrate::ParticleSystem;
use crate::integrate::split_damping::SplitDamping;
use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::mesh::TetMesh;

use crate::model::fem::mass::lumped_masses;

use super::elasticity::{Elasticity, TetRest};
use super::element;
use super::kernel::ElementKernel;
use super::stvk::NonlinearTensors;
use super::tensors::{LinearTensors, Topology, tet_blocks};

/// How the non-linear set's forces are computed: per element from the deformation gradient
/// (the default: a packed, vectorised kernel, about 3× faster) or Picinbono's tensors (on
/// vertices, edges, triangles, tetrahedra). Same forces and energy to rounding.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum NonlinearForm {
    Tensors,
    #[default]
    Elements,
}

/// The element form's non-linear set: its isotropic tetrahedra packed for the fast kernel,
/// its fibre ones (rarer, more terms) through the plain per-element code.
#[derive(Clone, Debug, Default)]
pub struct ElementSet {
    in_set: Vec<bool>,
    /// In the packed kernel (which then also computes the volume penalty).
    packed: Vec<bool>,
    kernel: ElementKernel,
    fibre: Vec<u32>,
    dirty: bool,
    /// Counts the repacks (the penalty pass follows them).
    generation: u64,
}

/// The volume penalty of the tetrahedra the element kernel does not cover, packed the same
/// way, and what it was packed for.
#[derive(Clone, Debug, Default)]
struct PenaltyPass {
    kernel: ElementKernel,
    built_for: Option<(usize, u64)>,
}

impl ElementSet {
    /// Repacks after the set changed (hybrid switch, removal): one pass over the set.
    fn refresh(&mut self, tets: &[[u32; 4]], rest: &[TetRest], el: &[Elasticity], kappa: Real) {
        if !self.dirty {
            return;
        }
        let (fibre, iso): (Vec<u32>, Vec<u32>) = (0..self.in_set.len() as u32)
            .filter(|&t| self.in_set[t as usize])
            .partition(|&t| el[t as usize].has_fibre());
        self.packed.clear();
        self.packed.resize(self.in_set.len(), false);
        for &t in &iso {
            self.packed[t as usize] = true;
        }
        self.kernel = ElementKernel::new(tets, rest, el, &iso, kappa);
        self.fibre = fibre;
        self.dirty = false;
        self.generation += 1;
    }

    fn len(&self) -> usize {
        self.kernel.len() + self.fibre.len()
    }
}

/// The tensors, masses and loads of a tensor-mass model.
#[derive(Clone, Debug)]
pub struct TensorSystem {
    pub(super) tets: Vec<[u32; 4]>,
    pub(super) rest_tets: Vec<TetRest>,
    pub(super) elasticity: Vec<Elasticity>,
    pub(super) alive: Vec<bool>,
    pub(super) alive_count: usize,
    pub(super) topo: Topology,
    pub(super) linear: LinearTensors,
    pub(super) nonlinear: Option<NonlinearTensors>,
    /// The element form of the non-linear set: its tetrahedra leave the linear tensors and
    /// get the per-element St Venant–Kirchhoff force instead.
    pub(super) elements: Option<ElementSet>,
    /// Tetrahedra left at each node (attachment; the linear tensors may count fewer).
    node_tets: Vec<u32>,
    pub(super) rest: Vec<Vec3>,
    pub(super) masses: Vec<Real>,
    pub(super) density: Real,
    pub(super) damping: Real,
    pub(super) stiffness_damping: Real,
    pub(super) volume_penalty: Real,
    /// Gravity share and point loads per node, in N.
    pub(super) external: Vec<Vec3>,
    pub(super) gravity: Vec3,
    /// Displacements x − rest of the last elastic force pass.
    u: Vec<Vec3>,
    kv: Vec<Vec3>,
    /// Elastic + penalty energy of the last `add_forces`, at the displacements `u`.
    energy: Option<Real>,
    /// Displacements at which `prepare_jacobians` linearised.
    jacobian_u: Vec<Vec3>,
    penalty_pass: PenaltyPass,
    /// Explicit schemes with β > 0: the stiffness damping, out of `add_forces`, applied once
    /// per step implicitly (`integrate::split_damping`); K₀ reassembled after a removal.
    split: Option<Box<SplitDamping>>,
    split_dirty: bool,
}

impl TensorSystem {
    /// Builds the tensors of every tetrahedron of a validated mesh whose tets have positive
    /// volume; `nonlinear` adds the St Venant–Kirchhoff tensors of all of them.
    pub fn new(
        mesh: &TetMesh,
        rest_tets: Vec<TetRest>,
        elasticity: Vec<Elasticity>,
        material: &Material,
        volume_penalty: Real,
        nonlinear: Option<NonlinearForm>,
    ) -> Self {
        let n = mesh.vertices.len();
        let topo = Topology::new(&mesh.tets);
        let mut linear = LinearTensors::empty(n, &topo);
        let mut nl = (nonlinear == Some(NonlinearForm::Tensors))
            .then(|| NonlinearTensors::empty(n, &mesh.tets, &topo));
        let mut node_tets = vec![0u32; n];
        for &v in mesh.tets.iter().flatten() {
            node_tets[v as usize] += 1;
        }
        let masses = lumped_masses(mesh, material.density);
        for (t, tet) in mesh.tets.iter().enumerate() {
            linear.update_tet(
                &topo,
                t,
                tet,
                &tet_blocks(&rest_tets[t], &elasticity[t]),
                true,
            );
            if let Some(nl) = nl.as_mut() {
                nl.update_tet(&topo, t, tet, &rest_tets[t], &elasticity[t], true);
            }
        }
        let mut system = Self {
            alive: vec![true; mesh.tets.len()],
            alive_count: mesh.tets.len(),
            tets: mesh.tets.clone(),
            rest_tets,
            elasticity,
            topo,
            linear,
            nonlinear: nl,
            elements: None,
            node_tets,
            rest: mesh.vertices.clone(),
            masses,
            density: material.density,
            damping: material.damping,
            stiffness_damping: material.stiffness_damping,
            volume_penalty,
            external: vec![Vec3::ZERO; n],
            gravity: Vec3::ZERO,
            u: vec![Vec3::ZERO; n],
            kv: vec![Vec3::ZERO; n],
            energy: None,
            jacobian_u: vec![Vec3::ZERO; n],
            penalty_pass: PenaltyPass::default(),
            split: None,
            split_dirty: false,
        };
        if nonlinear == Some(NonlinearForm::Elements) {
            system.elements = Some(ElementSet {
                in_set: vec![false; system.tets.len()],
                dirty: true,
                ..Default::default()
            });
            for t in 0..system.tets.len() {
                system.set_membership(t, true);
            }
        }
        system
    }

    /// Is tetrahedron `t` in the non-linear set (either form)?
    pub fn in_nonlinear_set(&self, t: usize) -> bool {
        self.nonlinear.as_ref().is_some_and(|nl| nl.contains(t))
            || self
                .elements
                .as_ref()
                .is_some_and(|e| e.in_set.get(t).copied().unwrap_or(false))
    }

    /// Moves tetrahedron `t` into (`want`) or out of the non-linear set: O(1).
    fn set_membership(&mut self, t: usize, want: bool) {
        let tet = self.tets[t];
        let (r, el) = (self.rest_tets[t], self.elasticity[t]);
        if let Some(nl) = self.nonlinear.as_mut() {
            nl.update_tet(&self.topo, t, &tet, &r, &el, want);
        } else if let Some(es) = self.elements.as_mut()
            && es.in_set[t] != want
        {
            es.in_set[t] = want;
            es.dirty = true;
            self.linear
                .update_tet(&self.topo, t, &tet, &tet_blocks(&r, &el), !want);
        }
        self.energy = None;
    }

    /// The tangent stiffness a common translation of the `held` nodes meets from the
    /// tetrahedra around them at positions `x`, everything else held: Σ_{a,b held} K_ab
    /// (3×3, N/m; K = −∂f/∂x of the elastic forces: the St Venant–Kirchhoff tangent on the
    /// non-linear set, the linear one elsewhere, the volume penalty's g gᵀ part as in the
    /// implicit Jacobian). For the `hybrid` model's haptic stiffness.
    pub fn translation_stiffness(&self, x: &[Vec3], held: &[bool]) -> crate::math::Mat3 {
        let is_held = |v: u32| held.get(v as usize).copied().unwrap_or(false);
        let mut k = crate::math::Mat3::ZERO;
        for (t, tet) in self.tets.iter().enumerate() {
            if !self.alive[t] || !tet.iter().any(|&v| is_held(v)) {
                continue;
            }
            let (r, el) = (&self.rest_tets[t], &self.elasticity[t]);
            let xs = self.corners(t, x);
            let rest = self.corners(t, &self.rest);
            let u = if self.in_nonlinear_set(t) {
                std::array::from_fn(|a| xs[a] - rest[a])
            } else {
                [Vec3::ZERO; 4]
            };
            for c in 0..3 {
                let e = Vec3::AXES[c];
                let d = tet.map(|v| if is_held(v) { e } else { Vec3::ZERO });
                let mut add = element::stvk_tangent_product(r, el, &u, &d);
                if self.volume_penalty > 0.0 {
                    let g = element::volume_gradient(&xs);
                    let s = self.volume_penalty / r.volume
                        * (0..4).map(|a| g[a].dot(d[a])).sum::<Real>();
                    for a in 0..4 {
                        add[a] += g[a] * s;
                    }
                }
                for (a, &v) in tet.iter().enumerate() {
                    if is_held(v) {
                        *k.col_mut(c) += add[a];
                    }
                }
            }
        }
        k
    }

    /// Takes the stiffness damping β K₀ v out of the forces and applies it once per step
    /// implicitly (`on`: what explicit schemes need, see `integrate::split_damping`), or puts
    /// it back (implicit Euler, which integrates it in its own solve). No-op when β = 0.
    pub fn set_split_damping(&mut self, on: bool) {
        if on && self.stiffness_damping > 0.0 {
            if self.split.is_none() {
                self.split = Some(Box::new(
                    SplitDamping::new(self.rest.len(), &self.tets, self.stiffness_damping)
                        .with_positions(&self.rest),
                ));
                self.split_dirty = true;
            }
        } else {
            self.split = None;
        }
    }

    /// Whether the stiffness damping is split off (see `set_split_damping`).
    pub fn split_damping(&self) -> bool {
        self.split.is_some()
    }

    pub fn node_count(&self) -> usize {
        self.rest.len()
    }

    /// Tetrahedra still in the mesh.
    pub fn alive_count(&self) -> usize {
        self.alive_count
    }

    pub fn is_alive(&self, t: usize) -> bool {
        self.alive.get(t).copied().unwrap_or(false)
    }

    /// True when node `n` still belongs to a tetrahedron.
    pub fn is_attached(&self, n: usize) -> bool {
        self.node_tets.get(n).is_some_and(|&c| c > 0)
    }

    /// Tetrahedra in the non-linear set (0 for the linear kind).
    pub fn nonlinear_count(&self) -> usize {
        self.nonlinear.as_ref().map_or(0, |nl| nl.count())
            + self
                .elements
                .as_ref()
                .map_or(0, |e| e.in_set.iter().filter(|&&b| b).count())
    }

    fn corners<T: Copy>(&self, t: usize, x: &[T]) -> [T; 4] {
        self.tets[t].map(|v| x[v as usize])
    }

    /// Elastic (and volume-penalty) forces at positions `x`, added to `f`; returns the
    /// elastic + penalty energy, got on the way: ½uᵀKu = −½ u·f_linear, and the
    /// non-linear terms sum their own.
    pub fn add_elastic_forces(&mut self, x: &[Vec3], f: &mut [Vec3]) -> Real {
        // `u` changes: the energy kept for the old one no longer applies.
        self.energy = None;
        for ((u, x), r) in self.u.iter_mut().zip(x).zip(&self.rest) {
            *u = *x - *r;
        }
        let mut w = 0.0;
        // With every tetrahedron in the element form's non-linear set the linear tensors are
        // all exactly zero (counts reset them): skip their pass and the energy dot products.
        if self.linear.tet_count() > 0 {
            let dot =
                |u: &[Vec3], f: &[Vec3]| u.iter().zip(f).map(|(a, b)| a.dot(*b)).sum::<Real>();
            let before = dot(&self.u, f);
            self.linear.add_forces(&self.topo, &self.u, f);
            w -= 0.5 * (dot(&self.u, f) - before);
        }
        if let Some(nl) = self.nonlinear.as_mut() {
            w += nl.add_forces(&self.topo, &self.u, f);
        }
        if let Some(es) = self.elements.as_mut() {
            es.refresh(
                &self.tets,
                &self.rest_tets,
                &self.elasticity,
                self.volume_penalty,
            );
            w += es.kernel.add_forces(&self.u, f);
            for &t in &es.fibre {
                let t = t as usize;
                let tet = self.tets[t];
                let u = tet.map(|v| self.u[v as usize]);
                let (fe, we) =
                    element::stvk_forces_energy(&self.rest_tets[t], &self.elasticity[t], &u);
                w += we;
                for (k, &v) in tet.iter().enumerate() {
                    f[v as usize] += fe[k];
                }
            }
        }
        if self.volume_penalty > 0.0 {
            // The tetrahedra the element kernel did not cover (linear, fibre; all of them for
            // the linear kind and the tensor form), repacked when a removal or a hybrid switch
            // changed which they are.
            let key = (
                self.alive_count,
                self.elements.as_ref().map_or(0, |e| e.generation),
            );
            if self.penalty_pass.built_for != Some(key) {
                let packed = self.elements.as_ref().map(|e| &e.packed[..]);
                let list: Vec<u32> = (0..self.tets.len())
                    .filter(|&t| {
                        self.alive[t] && !packed.is_some_and(|p| p.get(t).copied().unwrap_or(false))
                    })
                    .map(|t| t as u32)
                    .collect();
                self.penalty_pass.kernel = ElementKernel::penalty_only(
                    &self.tets,
                    &self.rest_tets,
                    &list,
                    self.volume_penalty,
                );
                self.penalty_pass.built_for = Some(key);
            }
            w += self.penalty_pass.kernel.add_forces(&self.u, f);
        }
        w
    }

    /// All forces at (x, v): elastic, penalty, damping and loads, added to `f`.
    pub fn add_forces(&mut self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        let w = self.add_elastic_forces(x, f);
        self.energy = Some(w);
        for ((fi, vi), (m, e)) in f
            .iter_mut()
            .zip(v)
            .zip(self.masses.iter().zip(&self.external))
        {
            *fi += *e - *vi * (self.damping * m);
        }
        if self.stiffness_damping > 0.0 && self.split.is_none() {
            self.kv.iter_mut().for_each(|k| *k = Vec3::ZERO);
            self.linear.add_forces(&self.topo, v, &mut self.kv);
            for (fi, k) in f.iter_mut().zip(&self.kv) {
                *fi += *k * self.stiffness_damping;
            }
        }
    }

    /// Elastic + penalty energy at `x` minus the work of the loads: what the blow-up guard
    /// watches. The value from the last force evaluation when `x` gives the displacements it
    /// was done at (the integrators ask right after evaluating), else per element.
    pub fn potential_energy(&self, x: &[Vec3]) -> Real {
        let load: Real = self
            .external
            .iter()
            .zip(x)
            .zip(&self.rest)
            .map(|((e, x), r)| e.dot(*x - *r))
            .sum();
        // The force pass sees x only through u = x − rest, so u is the key of its energy, and
        // it keeps u anyway: no copy of x per force evaluation.
        let at_u = || {
            x.len() == self.u.len()
                && x.iter()
                    .zip(&self.rest)
                    .zip(&self.u)
                    .all(|((x, r), u)| *x - *r == *u)
        };
        match self.energy {
            Some(w) if at_u() => w - load,
            _ => self.element_energy(x) - load,
        }
    }

    /// Elastic + penalty energy at `x`, element by element.
    pub fn element_energy(&self, x: &[Vec3]) -> Real {
        let mut w = 0.0;
        for t in 0..self.tets.len() {
            if !self.alive[t] {
                continue;
            }
            let xs = self.corners(t, x);
            let rs = self.corners(t, &self.rest);
            let u = [xs[0] - rs[0], xs[1] - rs[1], xs[2] - rs[2], xs[3] - rs[3]];
            let (r, el) = (&self.rest_tets[t], &self.elasticity[t]);
            let in_nl = self.in_nonlinear_set(t);
            w += if in_nl {
                element::stvk_energy(r, el, &u)
            } else {
                element::linear_energy(r, el, &u)
            };
            if self.volume_penalty > 0.0 {
                w += element::volume_energy(&xs, r.volume, self.volume_penalty);
            }
        }
        w
    }

    /// The hybrid switch: tetrahedra whose displacement gradient norm (`gradient_norm`:
    /// strain and rotation) exceeds `threshold` join the
    /// non-linear set, those below half of it leave (the gap stops flickering). Returns how
    /// many switched.
    pub fn switch_hybrid(&mut self, x: &[Vec3], threshold: Real) -> usize {
        if self.nonlinear.is_none() && self.elements.is_none() {
            return 0;
        }
        let mut switched = 0;
        for t in 0..self.tets.len() {
            if !self.alive[t] {
                continue;
            }
            let u = self.tets[t].map(|v| x[v as usize] - self.rest[v as usize]);
            let s = element::gradient_norm(&self.rest_tets[t], &u);
            let inside = self.in_nonlinear_set(t);
            let want = if inside {
                s >= 0.5 * threshold
            } else {
                s > threshold
            };
            if want != inside {
                self.set_membership(t, want);
                switched += 1;
            }
        }
        switched
    }

    /// Removes tetrahedron `t`: its tensors leave its vertices, edges and triangles, its
    /// mass (ρV/4 per corner) leaves its corners. O(1).
    pub fn remove_tet(&mut self, t: usize) -> bool {
        if !self.is_alive(t) {
            return false;
        }
        // Out of the non-linear set first (the element form puts it back into the linear
        // tensors), then out of the linear tensors.
        self.set_membership(t, false);
        let tet = self.tets[t];
        let (r, el) = (self.rest_tets[t], self.elasticity[t]);
        self.linear
            .update_tet(&self.topo, t, &tet, &tet_blocks(&r, &el), false);
        for &v in &tet {
            self.node_tets[v as usize] = self.node_tets[v as usize].saturating_sub(1);
        }
        // Mass is conserved: each node keeps exactly its surviving tetrahedra's quarters. A
        // node left with none gets no mass and no gravity share (the model holds it); the
        // time step a light node on slivers would need is the sliver guard's business.
        let quarter = 0.25 * self.density * r.volume;
        for &v in &tet {
            let v = v as usize;
            let old = self.masses[v];
            self.masses[v] = if self.is_attached(v) {
                (old - quarter).max(0.0)
            } else {
                0.0
            };
            self.external[v] -= self.gravity * (old - self.masses[v]);
            if !self.is_attached(v) {
                self.external[v] = Vec3::ZERO;
            }
        }
        self.alive[t] = false;
        self.alive_count -= 1;
        self.energy = None;
        self.split_dirty = true;
        true
    }

    /// Estimated bytes one explicit step moves to and from memory: every tensor read once
    /// (vertex and edge tensors; the non-linear set's tensors and scratch) plus about 36
    /// passes over per-node 3-vectors (state copies, forces, displacements, the shared
    /// integrator's bookkeeping) and 4 over per-node scalars. A model, not a measurement.
    pub fn step_traffic_bytes(&self) -> usize {
        let n = self.node_count();
        let linear = n * 72 + self.topo.edges.len() * (72 + 8);
        let nonlinear = self
            .nonlinear
            .as_ref()
            .map_or(0, |nl| nl.step_traffic_bytes())
            + self.elements.as_ref().map_or(0, |e| {
                e.kernel.bytes() + e.fibre.len() * (4 + 16 + 104 + 72) + e.len() * 4 * 24 * 2
            });
        linear + nonlinear + n * (36 * 24 + 4 * 8)
    }

    /// Adds mass at node `n` (a coupled model's share at shared nodes); its weight follows at
    /// the next `set_node_loads`.
    pub fn add_node_mass(&mut self, n: usize, m: Real) {
        if let Some(x) = self.masses.get_mut(n) {
            *x += m;
        }
    }

    /// Sets the loads: gravity as the lumped share m g, plus point forces per node.
    pub fn set_node_loads(&mut self, gravity: Vec3, forces: &[(usize, Vec3)]) {
        self.gravity = gravity;
        self.energy = None;
        for (n, e) in self.external.iter_mut().enumerate() {
            *e = if self.node_tets[n] > 0 {
                gravity * self.masses[n]
            } else {
                Vec3::ZERO
            };
        }
        for &(n, f) in forces {
            if let Some(e) = self.external.get_mut(n) {
                *e += f;
            }
        }
    }
}

impl ParticleSystem for TensorSystem {
    fn masses(&self) -> &[Real] {
        &self.masses
    }

    fn forces(&mut self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        self.add_forces(x, v, f);
    }

    fn potential_energy(&self, x: &[Vec3]) -> Option<Real> {
        Some(TensorSystem::potential_energy(self, x))
    }

    fn prepare_jacobians(&mut self, x: &[Vec3], _v: &[Vec3]) -> Result<(), SimError> {
        for ((u, x), r) in self.jacobian_u.iter_mut().zip(x).zip(&self.rest) {
            *u = *x - *r;
        }
        Ok(())
    }

    /// K dx: the linear tensors, corrected to the St Venant–Kirchhoff tangent on the
    /// tetrahedra of the non-linear set, plus the Gauss–Newton part of the volume penalty.
    fn stiffness_product(&self, dx: &[Vec3], out: &mut [Vec3]) {
        out.fill(Vec3::ZERO);
        self.linear.add_forces(&self.topo, dx, out);
        out.iter_mut().for_each(|o| *o = -*o);
        for t in 0..self.tets.len() {
            if !self.alive[t] {
                continue;
            }
            let (r, el) = (&self.rest_tets[t], &self.elasticity[t]);
            let d = self.corners(t, dx);
            let mut add = [Vec3::ZERO; 4];
            let mut any = false;
            if self.in_nonlinear_set(t) {
                let u = self.corners(t, &self.jacobian_u);
                let k = element::stvk_tangent_product(r, el, &u, &d);
                let k0 = element::stvk_tangent_product(r, el, &[Vec3::ZERO; 4], &d);
                for a in 0..4 {
                    add[a] += k[a] - k0[a];
                }
                any = true;
            }
            if self.volume_penalty > 0.0 {
                let x = self.corners(t, &self.rest);
                let u = self.corners(t, &self.jacobian_u);
                let g =
                    element::volume_gradient(&[x[0] + u[0], x[1] + u[1], x[2] + u[2], x[3] + u[3]]);
                let s =
                    self.volume_penalty / r.volume * (0..4).map(|a| g[a].dot(d[a])).sum::<Real>();
                for a in 0..4 {
                    add[a] += g[a] * s;
                }
                any = true;
            }
            if any {
                for (a, &v) in self.tets[t].iter().enumerate() {
                    out[v as usize] += add[a];
                }
            }
        }
    }

    fn damping_product(&self, dv: &[Vec3], out: &mut [Vec3]) {
        out.fill(Vec3::ZERO);
        if self.stiffness_damping > 0.0 {
            self.linear.add_forces(&self.topo, dv, out);
            out.iter_mut().for_each(|o| *o *= -self.stiffness_damping);
        }
        for ((o, d), m) in out.iter_mut().zip(dv).zip(&self.masses) {
            *o += *d * (self.damping * m);
        }
    }

    fn prepare_velocity_split(&mut self, dt: Real, held: &[bool]) -> Result<bool, SimError> {
        let Some(split) = self.split.as_mut() else {
            return Ok(false);
        };
        if self.split_dirty {
            let (tets, rest, el, alive) =
                (&self.tets, &self.rest_tets, &self.elasticity, &self.alive);
            split.assemble(
                (0..tets.len())
                    .filter(|&t| alive[t])
                    .map(|t| (tets[t], tet_blocks(&rest[t], &el[t]))),
            );
            self.split_dirty = false;
        }
        split.prepare(dt, &self.masses, held)?;
        Ok(true)
    }

    fn apply_velocity_split(&mut self, v: &mut [Vec3], force: &mut [Vec3]) -> bool {
        match self.split.as_mut() {
            Some(split) => split.apply(&self.masses, v, force),
            None => false,
        }
    }

    fn jacobian_diagonal(&self, stiffness: &mut [Vec3], damping: &mut [Vec3]) {
        for (((s, d), k), m) in stiffness
            .iter_mut()
            .zip(damping.iter_mut())
            .zip(self.linear.diagonal())
            .zip(&self.masses)
        {
            *s = k;
            *d = k * self.stiffness_damping + Vec3::splat(self.damping * m);
        }
    }
}
