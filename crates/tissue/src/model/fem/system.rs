//! The constrained linear system K u = f with some displacement components given.
//!
//! Constrained dofs are eliminated without changing the sparsity pattern: their rows and
//! columns of K are zeroed except the diagonal, which keeps K_cc (a scaled identity keeps the
//! matrix as well conditioned as K), and the right-hand side becomes f − K_{:,c} g on free
//! rows and K_cc g_c on constrained ones. The symbolic factorisation is therefore computed
//! once; new targets and loads only need a new solve.
//!
//! A change of the held set does not always cost a numeric factorisation: when the new set
//! H contains the set H0 the factorisation was made for, the extra dofs are imposed through
//! their Schur complement on it (`solve::schur`: one sparse solve per dof when it is first
//! held, then two solves and a small dense one per problem). A contact loop whose probe
//! gains and loses vertices thus keeps one factorisation with the supports. The system
//! refactorises when H drops a dof of H0 (then with the dofs held in every problem so far,
//! typically the supports, as the new base, when the rest is cheap to add back), when the new
//! columns would cost more than a factorisation (both timed as they happen), when the extra
//! solves of the Schur path have cost a factorisation since the last one, or above
//! `SCHUR_CAP` extra dofs (memory).
//!
//! A node may also be held along one direction n only (a frictionless contact: n·u = g,
//! free across n, reaction along n). Such a row is not a unit row, so it is never part of
//! the factorisation: it is always imposed through the Schur complement, with the columns
//! of the node's three dofs (`HeldSchur::multipliers_rows`). The base factorisation is
//! then the one of the other held dofs, and a change of direction costs only the small
//! dense factorisation.
//!
//! Before factorising, each connected piece of the mesh is checked for rigid-body modes left
//! free by the constraints, so that a free body gives a clear error instead of a solution
//! made of roundoff.

use std::time::Instant;

use crate::error::SimError;
use crate::interact::SurfaceHold;
use crate::math::{Real, Vec3};
use crate::solve::schur::HeldRow;
use crate::solve::{HeldSchur, SparseCholesky, lcp};

use super::assembly::Assembler;

const FREE_BODY_HINT: &str = "is the body fixed? a free body has rigid-motion modes; \
    constrain at least three non-collinear vertices of every separate piece";

/// Most dofs the Schur complement keeps columns for: its entries take `SCHUR_CAP²` values
/// (72 MB at 3000).
const SCHUR_CAP: usize = 3000;

/// Most nodes held along an oblique direction in one problem: their three columns each stay
/// in the Schur complement, (3·n)² values (288 MB at 2000). The comparison's reference on
/// the twice-refined liver needs a few hundred for its deep indentation; a model with more
/// holds them in full instead (and the caller slides them by relaxation). Holds along a
/// coordinate axis are unit rows of the factorisation and do not count.
pub const ALONG_CAP: usize = 2000;

/// The coordinate axis a unit direction lies along, if it does (to roundoff): a hold along
/// it is a unit row, held in the factorisation, not through the Schur complement.
pub fn axis_of(n: Vec3) -> Option<usize> {
    (0..3).find(|&k| (n[k].abs() - 1.0).abs() <= 1e-14)
}

/// Nodes of `holds` held along a direction that is no coordinate axis: those take Schur
/// columns, and `ALONG_CAP` bounds them.
pub(crate) fn oblique_holds(holds: &[Option<SurfaceHold>]) -> usize {
    holds
        .iter()
        .flatten()
        .filter(|h| {
            h.along
                .is_some_and(|n| axis_of(n.normalize_or_zero()).is_none())
        })
        .count()
}

/// When `System` imposes extra held dofs through the Schur complement.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SchurRule {
    /// When the new columns cost less than a factorisation (timed as they happen).
    #[default]
    Timed,
    /// Whenever the held set contains the factorised one (under the cap): tests.
    Always,
    /// Never: every change of the held set refactorises (the reference path of tests and
    /// benches).
    Never,
}

/// One problem at the dof level: which components are held, where, and the nodal forces.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DofProblem {
    /// Per dof (3·node + axis): held or free.
    pub constrained: Vec<bool>,
    /// The held dofs, ascending.
    pub list: Vec<usize>,
    /// Displacement of each held dof (ignored on free dofs), in m.
    pub targets: Vec<Real>,
    /// Nodal forces, in N.
    pub forces: Vec<Real>,
    /// Nodes held along one direction only (none of their dofs in `list`), by node.
    pub along: Vec<AlongHold>,
    /// Points tied to three nodes that may be pushed along a normal but not pulled (a fine
    /// contact surface's vertices against an instrument).
    pub points: Vec<PointHold>,
}

/// A point following three nodes (x = rest + Σ wᵢ uᵢ) that may not pass a plane:
/// Σ wᵢ n·uᵢ ≥ `value`, pushed along n (λ ≥ 0) only where it rests on it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointHold {
    pub nodes: [usize; 3],
    pub weights: [Real; 3],
    pub normal: Vec3,
    /// The displacement along `normal` the point needs to reach the plane, in m.
    pub value: Real,
}

/// A node held along a unit direction only: `normal · u_node = value`, free across it; its
/// reaction lies along `normal`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlongHold {
    pub node: usize,
    pub normal: Vec3,
    /// The held displacement along `normal`, in m.
    pub value: Real,
}

impl DofProblem {
    pub fn new(dofs: usize) -> Self {
        Self {
            constrained: vec![false; dofs],
            list: Vec::new(),
            targets: vec![0.0; dofs],
            forces: vec![0.0; dofs],
            along: Vec::new(),
            points: Vec::new(),
        }
    }

    /// Holds dof `d` at displacement `value`; a dof out of range is an error.
    pub fn hold(&mut self, d: usize, value: Real) -> Result<(), SimError> {
        let n = self.constrained.len();
        let (Some(held), Some(target)) = (self.constrained.get_mut(d), self.targets.get_mut(d))
        else {
            return Err(SimError::BadParameter {
                name: "held",
                value: format!("dof {d}"),
                reason: format!("the model has {n} dofs"),
            });
        };
        if !*held {
            *held = true;
            self.list.push(d);
        }
        *target = value;
        Ok(())
    }

    /// Holds the three dofs of `node` at displacement `d`.
    pub(crate) fn hold_node(&mut self, node: usize, d: Vec3) -> Result<(), SimError> {
        for k in 0..3 {
            self.hold(3 * node + k, d[k])?;
        }
        Ok(())
    }

    /// Holds `node` along the unit direction `normal` only, at displacement `value` along
    /// it. A node out of range or a direction that does not normalise is an error.
    pub fn hold_along(&mut self, node: usize, normal: Vec3, value: Real) -> Result<(), SimError> {
        let nodes = self.constrained.len() / 3;
        let n = normal.normalize_or_zero();
        if node >= nodes || n == Vec3::ZERO || !value.is_finite() {
            return Err(SimError::BadParameter {
                name: "held along",
                value: format!("node {node}, direction {normal}, displacement {value}"),
                reason: format!(
                    "the model has {nodes} nodes; the direction must be non-zero and finite"
                ),
            });
        }
        // Along a coordinate axis the row is a unit row: held in the factorisation like any
        // held dof (no Schur column, no cap), e.g. a frictionless plate's vertices.
        if let Some(k) = axis_of(n) {
            return self.hold(3 * node + k, value * n[k].signum());
        }
        self.along.push(AlongHold {
            node,
            normal: n,
            value,
        });
        Ok(())
    }

    /// Holds the nodes of surface vertices (`nodes[s]` for vertex s) as `holds` says, in full
    /// or along a direction; with `mids` (quadratic meshes: mid-edge node, ends), the mid
    /// node of a boundary edge whose ends are both held follows the mean of their
    /// displacements: in full when both ends are held in full, else along the mean of
    /// their directions (the end held in full adding none).
    pub(crate) fn hold_surface(
        &mut self,
        nodes: &[u32],
        mids: &[(u32, u32, u32)],
        holds: &[Option<SurfaceHold>],
    ) -> Result<(), SimError> {
        let hold = |dp: &mut Self, node: usize, d: Vec3, along: Option<Vec3>| match along {
            Some(n) => dp.hold_along(node, n, n.dot(d)),
            None => dp.hold_node(node, d),
        };
        for (s, h) in holds.iter().enumerate() {
            if let (Some(h), Some(&node)) = (h, nodes.get(s)) {
                hold(self, node as usize, h.displacement, h.along)?;
            }
        }
        for &(m, a, b) in mids {
            if let (Some(Some(ha)), Some(Some(hb))) = (holds.get(a as usize), holds.get(b as usize))
            {
                let d = (ha.displacement + hb.displacement) * 0.5;
                let along = match (ha.along, hb.along) {
                    (None, None) => None,
                    (na, nb) => {
                        let n = (na.unwrap_or(Vec3::ZERO) + nb.unwrap_or(Vec3::ZERO))
                            .normalize_or_zero();
                        // Opposite directions: nothing to hold along, hold in full.
                        (n != Vec3::ZERO).then_some(n)
                    }
                };
                hold(self, m as usize, d, along)?;
            }
        }
        Ok(())
    }

    /// Sorts the held list and the nodes held along a direction (after a series of `hold`).
    pub fn finish(&mut self) {
        self.list.sort_unstable();
        self.along.sort_unstable_by_key(|a| a.node);
    }

    /// Every held dof: the listed ones and the three of each node held along a direction.
    pub fn held_dofs(&self) -> impl Iterator<Item = usize> + '_ {
        let along = self.along.iter().flat_map(|a| 3 * a.node..3 * a.node + 3);
        self.list.iter().copied().chain(along)
    }
}

/// K, its constrained copy, the factorisation cache and the work buffers.
pub struct System {
    pub assembler: Assembler,
    /// The assembled stiffness, pattern `assembler.pattern`.
    pub k: Vec<Real>,
    a: Vec<Real>,
    diag: Vec<usize>,
    chol: SparseCholesky,
    /// The held set H0 of the factorisation, and its list.
    factored_for: Option<Vec<bool>>,
    base_list: Vec<usize>,
    /// The dofs held in every problem so far (typically the supports).
    always_held: Option<Vec<bool>>,
    schur: HeldSchur,
    rhs: Vec<Real>,
    base_rhs: Vec<Real>,
    /// Seconds of the last factorisation, of the last plain solve, and per Schur column.
    refactor_seconds: f64,
    solve_seconds: f64,
    column_seconds: Option<f64>,
    /// Seconds of the Schur path's extra solves since the last factorisation.
    schur_overhead: f64,
    rest: Vec<Vec3>,
    component: Vec<u32>,
    components: usize,
    /// Numeric factorisations done so far.
    pub refactorizations: usize,
    /// Columns A0⁻¹ e_j computed for the Schur complement of extra held dofs so far.
    pub schur_columns: usize,
    /// Solves done so far.
    pub solves: usize,
    /// Skips the rigid-mode check: for K + cM (dynamics), definite even for a free body.
    pub allow_free_body: bool,
    pub schur_rule: SchurRule,
    /// The push λ ≥ 0 on each point of the last problem solved (0 for a point off its
    /// plane), in N.
    pub point_pushes: Vec<Real>,
    /// The points' loads on dofs the problem holds (a point tied to a fixed vertex): they
    /// go straight into those dofs' reactions.
    point_loads_held: Vec<(usize, Real)>,
    /// Pivoting rounds of the last contact problem with points (`solve::lcp`).
    pub lcp_rounds: usize,
}

impl System {
    /// Takes the assembled stiffness `k` of `assembler`'s pattern over nodes at `rest`.
    pub fn new(assembler: Assembler, k: Vec<Real>, rest: Vec<Vec3>) -> Result<Self, SimError> {
        let chol = SparseCholesky::with_positions(&assembler.pattern, &rest)?;
        let diag = assembler.pattern.diagonal_slots();
        let (component, components) = connected_components(&assembler, rest.len());
        let n = assembler.pattern.dim();
        Ok(Self {
            a: k.clone(),
            k,
            diag,
            chol,
            factored_for: None,
            base_list: Vec::new(),
            always_held: None,
            schur: HeldSchur::default(),
            rhs: vec![0.0; n],
            base_rhs: vec![0.0; n],
            refactor_seconds: 0.0,
            solve_seconds: 0.0,
            column_seconds: None,
            schur_overhead: 0.0,
            rest,
            component,
            components,
            refactorizations: 0,
            schur_columns: 0,
            solves: 0,
            allow_free_body: false,
            schur_rule: SchurRule::Timed,
            point_pushes: Vec::new(),
            point_loads_held: Vec::new(),
            lcp_rounds: 0,
            assembler,
        })
    }

    /// Replaces the matrix values (same pattern); the next solve refactorises.
    pub fn set_values(&mut self, k: &[Real]) {
        self.k.copy_from_slice(k);
        self.factored_for = None;
        self.schur.clear();
    }

    pub fn dofs(&self) -> usize {
        self.assembler.pattern.dim()
    }

    pub fn factor_nnz(&self) -> usize {
        self.chol.factor_nnz()
    }

    /// Solves `p` into `u` (length dofs) and the reactions f − K u on held dofs (zero on free
    /// ones) into `r`. On error `u` and `r` may hold partial results; callers solve into
    /// scratch buffers and keep their state.
    pub fn solve(
        &mut self,
        p: &DofProblem,
        u: &mut [Real],
        r: &mut [Real],
    ) -> Result<(), SimError> {
        let n = self.dofs();
        if p.constrained.len() != n || p.targets.len() != n || p.forces.len() != n {
            return Err(SimError::BadParameter {
                name: "problem",
                value: format!("{} dofs", p.constrained.len()),
                reason: format!("the model has {n} dofs"),
            });
        }
        // The fields are public: check that the list is exactly the held dofs, once each.
        let held = p.constrained.iter().filter(|&&h| h).count();
        if held != p.list.len()
            || p.list.windows(2).any(|w| w[0] >= w[1])
            || p.list
                .iter()
                .any(|&c| !p.constrained.get(c).copied().unwrap_or(false))
        {
            return Err(SimError::BadParameter {
                name: "problem",
                value: format!("{} held dofs listed, {held} marked", p.list.len()),
                reason: "the list must hold each marked dof once, ascending (call finish)".into(),
            });
        }
        if p.along.windows(2).any(|w| w[0].node >= w[1].node)
            || p.along.iter().any(|a| {
                (3 * a.node..3 * a.node + 3).any(|d| p.constrained.get(d).copied().unwrap_or(true))
            })
        {
            return Err(SimError::BadParameter {
                name: "problem",
                value: format!("{} nodes held along a direction", p.along.len()),
                reason: "each must be a node of the model, once, ascending (call finish), with \
                         none of its dofs held otherwise"
                    .into(),
            });
        }
        let nodes = n / 3;
        if let Some(pt) = p.points.iter().find(|pt| {
            pt.nodes.iter().any(|&v| v >= nodes)
                || !(pt.value.is_finite()
                    && pt.weights.iter().all(|w| w.is_finite())
                    && pt.normal.is_finite())
        }) {
            return Err(SimError::BadParameter {
                name: "point contact",
                value: format!("on nodes {:?}", pt.nodes),
                reason: format!("the model has {nodes} nodes; every number must be finite"),
            });
        }
        match &mut self.always_held {
            Some(a) => a.iter_mut().zip(&p.constrained).for_each(|(a, &h)| *a &= h),
            None => self.always_held = Some(p.constrained.clone()),
        }
        let extra = self.plan(p)?;
        self.point_pushes.clear();
        self.point_pushes.resize(p.points.len(), 0.0);
        self.point_loads_held.clear();
        let schur_rows = !(p.along.is_empty() && p.points.is_empty());
        if extra.is_empty() && !schur_rows {
            let t = Instant::now();
            self.solve_factored(p)?;
            self.solve_seconds = t.elapsed().as_secs_f64();
        } else if let Err(e) = self.solve_schur(p, &extra) {
            // A Schur complement that is not positive definite (roundoff on a nearly
            // dependent set): the factorisation of the whole set decides (the rows along a
            // direction stay in the Schur complement).
            if !matches!(e, SimError::NotPositiveDefinite { .. }) {
                return Err(e);
            }
            self.refactor(p.constrained.clone(), p)?;
            if !schur_rows {
                self.solve_factored(p)?;
            } else {
                self.solve_schur(p, &[])?;
            }
        }
        self.solves += 1;
        u.copy_from_slice(&self.rhs);
        for &c in &p.list {
            u[c] = p.targets[c];
        }
        if let Some(d) = u.iter().position(|v| !v.is_finite()) {
            return Err(SimError::Diverged {
                step: self.solves as u64,
                node: d / 3,
                reason: "the linear solve gave a non-finite displacement".into(),
            });
        }
        r.iter_mut().for_each(|v| *v = 0.0);
        let (cp, ri) = (
            &self.assembler.pattern.col_ptr,
            &self.assembler.pattern.row_idx,
        );
        // Row c of K is column c (K is symmetric). On the extra dofs of the Schur path this
        // is −λ: their rows of A0 u = b + E λ are rows of K u = f + λ (−λ n on a node held
        // along n).
        for c in p.held_dofs() {
            let range = cp[c]..cp[c + 1];
            let ku: Real = ri[range.clone()]
                .iter()
                .zip(&self.k[range])
                .map(|(&row, &kv)| kv * u[row])
                .sum();
            r[c] = p.forces[c] - ku;
        }
        for &(c, load) in &self.point_loads_held {
            r[c] += load;
        }
        Ok(())
    }

    /// Decides how `p` is solved, refactorising when needed; returns the held dofs to impose
    /// through the Schur complement (empty: the factorisation holds exactly `p`'s set).
    fn plan(&mut self, p: &DofProblem) -> Result<Vec<usize>, SimError> {
        if let Some(h0) = &self.factored_for
            && p.constrained.iter().zip(h0).all(|(&h, &b)| h || !b)
        {
            let extra: Vec<usize> = p.list.iter().copied().filter(|&c| !h0[c]).collect();
            let overhead_ok =
                self.schur_rule != SchurRule::Timed || self.schur_overhead <= self.refactor_seconds;
            if extra.is_empty() || (self.affordable(&extra) && overhead_ok) {
                return Ok(extra);
            }
            self.refactor(p.constrained.clone(), p)?;
            return Ok(Vec::new());
        }
        // A dof of H0 was released (or nothing is factorised): refactorise, with the dofs
        // held in every problem so far as the base when the rest is cheap to add back.
        if self.factored_for.is_some()
            && let Some(always) = &self.always_held
        {
            let base: Vec<bool> = always.clone();
            let extra: Vec<usize> = p.list.iter().copied().filter(|&c| !base[c]).collect();
            self.schur.clear();
            let cheap = !extra.is_empty() && self.affordable(&extra);
            if cheap && (self.allow_free_body || self.rigid_modes_held(&base).is_ok()) {
                let mut bp = DofProblem::new(p.constrained.len());
                bp.list = (0..base.len()).filter(|&c| base[c]).collect();
                bp.constrained = base;
                self.refactor(bp.constrained.clone(), &bp)?;
                return Ok(extra);
            }
        }
        self.refactor(p.constrained.clone(), p)?;
        Ok(Vec::new())
    }

    /// True when the missing Schur columns of `extra` cost less than a factorisation and
    /// stay under the cap.
    fn affordable(&self, extra: &[usize]) -> bool {
        let new = self.schur.missing(extra);
        let per_column = self.column_seconds.unwrap_or(self.solve_seconds);
        let cheap = match self.schur_rule {
            SchurRule::Timed => new as f64 * per_column <= self.refactor_seconds,
            SchurRule::Always => true,
            SchurRule::Never => false,
        };
        cheap && self.schur.len() + new <= SCHUR_CAP
    }

    /// Numeric factorisation with `held` (the set of `p`) eliminated.
    fn refactor(&mut self, held: Vec<bool>, p: &DofProblem) -> Result<(), SimError> {
        self.factored_for = None;
        self.schur.clear();
        if !self.allow_free_body {
            self.rigid_modes_held(&held)?;
        }
        let t = Instant::now();
        self.eliminate(&held);
        self.chol
            .factorize(&self.assembler.pattern, &self.a, FREE_BODY_HINT)?;
        self.refactor_seconds = t.elapsed().as_secs_f64();
        self.refactorizations += 1;
        self.schur_overhead = 0.0;
        self.base_list = p.list.clone();
        self.factored_for = Some(held);
        Ok(())
    }

    /// Solves `p` into `rhs` when the factorisation holds exactly `p`'s held dofs.
    fn solve_factored(&mut self, p: &DofProblem) -> Result<(), SimError> {
        build_rhs(
            &self.k,
            &self.assembler,
            &self.diag,
            p,
            &p.list,
            &mut self.rhs,
        );
        self.chol.solve_in_place(&mut self.rhs)
    }

    /// Solves `p` into `rhs` with the dofs `extra` (held by `p`, free in the factorisation)
    /// and `p`'s nodes held along a direction imposed through their Schur complement.
    fn solve_schur(&mut self, p: &DofProblem, extra: &[usize]) -> Result<(), SimError> {
        let n = self.dofs();
        let t = Instant::now();
        let mut unknowns = extra.to_vec();
        unknowns.extend(p.along.iter().flat_map(|a| 3 * a.node..3 * a.node + 3));
        // A point's row over its nodes' free dofs; its held dofs are where they are held.
        let point_rows: Vec<(HeldRow, Real)> = p.points.iter().map(|pt| point_row(pt, p)).collect();
        unknowns.extend(
            point_rows
                .iter()
                .flat_map(|(row, _)| row.iter().map(|&(c, _)| c)),
        );
        let added = self.schur.add_columns(&self.chol, n, &unknowns)?;
        if added > 0 {
            self.column_seconds = Some(t.elapsed().as_secs_f64() / added as f64);
            self.schur_columns += added;
        }
        let t = Instant::now();
        build_rhs(
            &self.k,
            &self.assembler,
            &self.diag,
            p,
            &self.base_list,
            &mut self.base_rhs,
        );
        self.rhs.copy_from_slice(&self.base_rhs);
        self.chol.solve_in_place(&mut self.rhs)?;
        let mut rows: Vec<HeldRow> = extra.iter().map(|&c| vec![(c, 1.0)]).collect();
        let mut d: Vec<Real> = extra.iter().map(|&c| p.targets[c] - self.rhs[c]).collect();
        for a in &p.along {
            let dofs = 3 * a.node..3 * a.node + 3;
            rows.push(dofs.clone().zip(a.normal.to_array()).collect());
            let now: Real = dofs
                .zip(a.normal.to_array())
                .map(|(c, k)| k * self.rhs[c])
                .sum();
            d.push(a.value - now);
        }
        let lambda = if p.points.is_empty() {
            self.schur.multipliers_rows(&rows, &d)?
        } else {
            // The held rows (w = 0) and the points (w ≥ 0, λ ≥ 0) in one complementarity
            // problem: w = (Cᵀ S C) λ + b with b = −d on held rows and the gap the loads
            // alone leave on a point's.
            let bilateral = rows.len();
            let mut b: Vec<Real> = d.iter().map(|x| -x).collect();
            let mut which = Vec::with_capacity(point_rows.len());
            for (j, (row, held_part)) in point_rows.iter().enumerate() {
                // A point on held nodes only cannot be moved: nothing to solve for it.
                if row.is_empty() {
                    continue;
                }
                let now: Real = row.iter().map(|&(c, k)| k * self.rhs[c]).sum();
                b.push(now + held_part - p.points[j].value);
                rows.push(row.clone());
                which.push(j);
            }
            let m = self.schur.rows_matrix(&rows)?;
            let solution = lcp::solve_mixed(m.as_ref(), &b, bilateral, &[])?;
            self.lcp_rounds = solution.rounds;
            for (&j, &l) in which.iter().zip(&solution.lambda[bilateral..]) {
                self.point_pushes[j] = l;
                let pt = &p.points[j];
                for (&node, &w) in pt.nodes.iter().zip(&pt.weights) {
                    for axis in 0..3 {
                        let c = 3 * node + axis;
                        if p.constrained[c] {
                            self.point_loads_held.push((c, w * pt.normal[axis] * l));
                        }
                    }
                }
            }
            solution.lambda
        };
        self.rhs.copy_from_slice(&self.base_rhs);
        for (row, l) in rows.iter().zip(lambda) {
            for &(c, k) in row {
                self.rhs[c] += k * l;
            }
        }
        self.chol.solve_in_place(&mut self.rhs)?;
        // The first solve is the extra one: the plain path would take the second only. Rows
        // along a direction need both whatever the factorisation: no refactorisation saves
        // them, so they do not count.
        if p.along.is_empty() && p.points.is_empty() {
            self.schur_overhead += 0.5 * t.elapsed().as_secs_f64();
        }
        Ok(())
    }

    /// Builds the constrained matrix in `a` from `k`, the dofs `held` eliminated.
    fn eliminate(&mut self, held: &[bool]) {
        let (cp, ri) = (
            &self.assembler.pattern.col_ptr,
            &self.assembler.pattern.row_idx,
        );
        for col in 0..self.dofs() {
            let col_held = held[col];
            let range = cp[col]..cp[col + 1];
            let rows = ri[range.clone()].iter().zip(&self.k[range.clone()]);
            for (a, (&row, &kv)) in self.a[range].iter_mut().zip(rows) {
                // Off-diagonal entries in a held row or column vanish.
                *a = if row != col && (col_held || held[row]) {
                    0.0
                } else {
                    kv
                };
            }
        }
    }

    /// Fails when the held dofs of some connected piece leave one of its six rigid motions
    /// (three translations, three rotations about its centroid) free.
    fn rigid_modes_held(&self, held: &[bool]) -> Result<(), SimError> {
        let nc = self.components;
        let mut centroid = vec![Vec3::ZERO; nc];
        let mut count = vec![0usize; nc];
        for (x, &c) in self.rest.iter().zip(&self.component) {
            centroid[c as usize] += *x;
            count[c as usize] += 1;
        }
        for (c, n) in centroid.iter_mut().zip(&count) {
            *c /= (*n).max(1) as Real;
        }
        let mut radius2 = vec![0.0; nc];
        for (x, &c) in self.rest.iter().zip(&self.component) {
            radius2[c as usize] += (*x - centroid[c as usize]).length_squared();
        }
        let mut gram = vec![[[0.0; 6]; 6]; nc];
        for d in (0..held.len()).filter(|&d| held[d]) {
            let (node, axis) = (d / 3, d % 3);
            let c = self.component[node] as usize;
            let scale = (radius2[c] / count[c].max(1) as Real)
                .sqrt()
                .max(Real::MIN_POSITIVE);
            let x = (self.rest[node] - centroid[c]) / scale;
            // Row of dof d in the rigid-mode basis: translation e_axis, rotation e_k × x.
            let mut row = [0.0; 6];
            row[axis] = 1.0;
            for k in 0..3 {
                let mut w = Vec3::ZERO;
                w[k] = 1.0;
                row[3 + k] = w.cross(x)[axis];
            }
            for i in 0..6 {
                for j in 0..6 {
                    gram[c][i][j] += row[i] * row[j];
                }
            }
        }
        for (c, g) in gram.iter().enumerate() {
            let m = faer::Mat::<Real>::from_fn(6, 6, |i, j| g[i][j]);
            let eig = m
                .self_adjoint_eigenvalues(faer::Side::Lower)
                .unwrap_or_else(|_| vec![0.0; 6]);
            let max = eig.iter().copied().fold(0.0, Real::max);
            let min = eig.iter().copied().fold(Real::INFINITY, Real::min);
            if !(max > 0.0 && min > 1e-10 * max) {
                let node = self
                    .component
                    .iter()
                    .position(|&k| k as usize == c)
                    .unwrap_or(0);
                return Err(SimError::NotPositiveDefinite {
                    row: 3 * node,
                    hint: format!(
                        "{FREE_BODY_HINT} (piece {c} of {nc}, containing node {node}, can still \
                         move rigidly)"
                    ),
                });
            }
        }
        Ok(())
    }
}

/// A point's row over the free dofs of its nodes (coefficients wᵢ nₐ, a dof named once),
/// and the part of Σ wᵢ n·uᵢ its held dofs give (their targets).
fn point_row(pt: &PointHold, p: &DofProblem) -> (HeldRow, Real) {
    let mut row: HeldRow = Vec::with_capacity(9);
    let mut held = 0.0;
    for (&node, &w) in pt.nodes.iter().zip(&pt.weights) {
        for axis in 0..3 {
            let (c, k) = (3 * node + axis, w * pt.normal[axis]);
            if k == 0.0 {
                continue;
            }
            if p.constrained[c] {
                held += k * p.targets[c];
            } else if let Some(e) = row.iter_mut().find(|e| e.0 == c) {
                e.1 += k;
            } else {
                row.push((c, k));
            }
        }
    }
    (row, held)
}

/// The right-hand side of `p` with the dofs of `list` (ascending, all held by `p`) eliminated:
/// f − K_{:,c} g_c on the other rows, K_cc g_c on held ones.
fn build_rhs(
    k: &[Real],
    assembler: &Assembler,
    diag: &[usize],
    p: &DofProblem,
    list: &[usize],
    rhs: &mut [Real],
) {
    let (cp, ri) = (&assembler.pattern.col_ptr, &assembler.pattern.row_idx);
    rhs.copy_from_slice(&p.forces);
    for &c in list {
        let g = p.targets[c];
        if g != 0.0 {
            let range = cp[c]..cp[c + 1];
            for (&row, &kv) in ri[range.clone()].iter().zip(&k[range]) {
                rhs[row] -= kv * g;
            }
        }
    }
    for &c in list {
        rhs[c] = k[diag[c]] * p.targets[c];
    }
}

/// Connected pieces of the mesh (nodes sharing an element), by union-find.
fn connected_components(assembler: &Assembler, nodes: usize) -> (Vec<u32>, usize) {
    let mut parent: Vec<u32> = (0..nodes as u32).collect();
    fn find(parent: &mut [u32], mut a: u32) -> u32 {
        while parent[a as usize] != a {
            let up = parent[parent[a as usize] as usize];
            parent[a as usize] = up;
            a = up;
        }
        a
    }
    for e in 0..assembler.element_count() {
        let el = assembler.element(e);
        let r0 = find(&mut parent, el[0]);
        for &n in &el[1..] {
            let r = find(&mut parent, n);
            if r != r0 {
                parent[r as usize] = r0;
            }
        }
    }
    let mut label = vec![u32::MAX; nodes];
    let mut component = vec![0u32; nodes];
    let mut count = 0u32;
    for (n, comp) in component.iter_mut().enumerate() {
        let r = find(&mut parent, n as u32) as usize;
        if label[r] == u32::MAX {
            label[r] = count;
            count += 1;
        }
        *comp = label[r];
    }
    (component, count as usize)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::Material;
    use crate::mesh::generate::{BoxSplit, box_tets};
    use crate::model::fem::static_model::{FemStatic, Order};

    /// The stiffness of a 6 × 2 × 2 cm bar of linear tetrahedra, as a fresh `System`.
    fn bar_system(rule: SchurRule) -> System {
        let mesh = box_tets(
            Vec3::ZERO,
            Vec3::new(0.06, 0.02, 0.02),
            [6, 2, 2],
            BoxSplit::Six,
        );
        let m = FemStatic::new(&mesh, Material::new(5000.0, 0.35).unwrap(), Order::Linear).unwrap();
        let mut s = System::new(
            m.system.assembler.clone(),
            m.system.k.clone(),
            m.rest.clone(),
        )
        .unwrap();
        s.schur_rule = rule;
        s
    }

    /// Nodes of the bar at x = 0 (the support) and on its top face (y = 0.02), by x.
    fn nodes(s: &System) -> (Vec<usize>, Vec<usize>) {
        let support = (0..s.rest.len()).filter(|&i| s.rest[i].x < 1e-9).collect();
        let mut top: Vec<usize> = (0..s.rest.len())
            .filter(|&i| s.rest[i].y > 0.02 - 1e-9 && s.rest[i].x > 1e-9)
            .collect();
        top.sort_by(|&a, &b| s.rest[a].x.total_cmp(&s.rest[b].x));
        (support, top)
    }

    /// A sequence of held sets that grows, shrinks, changes its targets, loses a support dof
    /// and grows again: the Schur path agrees with refactorising to 1e-10, reactions
    /// included, with fewer factorisations.
    #[test]
    fn schur_complement_matches_refactorising() {
        let mut fast = bar_system(SchurRule::Always);
        let mut slow = bar_system(SchurRule::Never);
        let n = fast.dofs();
        let (support, top) = nodes(&fast);
        let steps: Vec<(Vec<usize>, Real, bool)> = vec![
            (vec![], 0.0, true),
            (vec![top[9]], 1e-4, true),
            (vec![top[9], top[10], top[11]], 2e-4, true),
            (vec![top[9], top[10], top[11], top[12], top[8]], 3e-4, true),
            (vec![top[10], top[11]], 3e-4, true),
            (vec![top[10], top[11]], 5e-4, true),
            (vec![top[9], top[10], top[11], top[12]], 4e-4, true),
            // One support dof released: H no longer contains H0.
            (vec![top[9], top[10]], 4e-4, false),
            (vec![top[9], top[10], top[13], top[14]], 6e-4, false),
            (vec![top[13]], 1e-4, true),
        ];
        for (k, (pressed, depth, full_support)) in steps.iter().enumerate() {
            let mut p = DofProblem::new(n);
            for (i, &s) in support.iter().enumerate() {
                for a in 0..3 {
                    if *full_support || i != 0 || a != 1 {
                        p.hold(3 * s + a, 0.0).unwrap();
                    }
                }
            }
            for (j, &t) in pressed.iter().enumerate() {
                p.hold_node(t, Vec3::new(1e-5 * j as Real, -depth, 0.0))
                    .unwrap();
            }
            p.finish();
            // A load on a free node: the right-hand side matters too.
            p.forces[3 * top[5] + 2] = 0.3 * k as Real;
            let (mut u1, mut r1, mut u2, mut r2) =
                (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            fast.solve(&p, &mut u1, &mut r1).unwrap();
            slow.solve(&p, &mut u2, &mut r2).unwrap();
            let umax = u2.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
            let rmax = r2.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
            for d in 0..n {
                assert!(
                    (u1[d] - u2[d]).abs() <= 1e-10 * umax,
                    "step {k} dof {d}: {} vs {}",
                    u1[d],
                    u2[d]
                );
                assert!(
                    (r1[d] - r2[d]).abs() <= 1e-10 * rmax,
                    "step {k} dof {d}: reaction {} vs {}",
                    r1[d],
                    r2[d]
                );
            }
            // Equilibrium: Σ (f − K u) over all dofs is Σ f (K has the rigid translations in
            // its kernel), and it is zero on free rows.
            let sum = |r: &[Real], a: usize| (0..n).filter(|d| d % 3 == a).map(|d| r[d]).sum();
            let rz: Real = sum(&r1, 2);
            assert!(
                (rz - 0.3 * k as Real).abs() < 1e-9 * (1.0 + rmax),
                "step {k}: {rz}"
            );
        }
        // The refactorising path factorised at every change of the held set (9 sets), the
        // Schur path once, then once more when a support dof was released (the base is then
        // the dofs held every time). Its columns: 5 pressed nodes, then after the new base
        // 4 pressed nodes and the support dof held again.
        assert_eq!(slow.refactorizations, 9);
        assert_eq!(slow.schur_columns, 0);
        assert_eq!(fast.refactorizations, 2);
        assert_eq!(fast.schur_columns, 3 * 5 + 3 * 4 + 1);
    }

    /// Nodes of the top held along tilted directions only, through the Schur complement on
    /// the support's factorisation (and after a full refactorisation): each sits on its
    /// plane, its reaction is along its direction, and holding every node in full where
    /// that solution put it gives the same displacements and reactions (the same
    /// equilibrium, reached by the plain solve). Both Schur rules agree.
    #[test]
    fn nodes_held_along_a_direction_match_the_full_hold_of_their_equilibrium() {
        for rule in [SchurRule::Always, SchurRule::Never, SchurRule::Timed] {
            let mut s = bar_system(rule);
            let n = s.dofs();
            let (support, top) = nodes(&s);
            let normals = [
                Vec3::new(0.3, 1.0, 0.1).normalize(),
                Vec3::new(-0.2, 1.0, 0.4).normalize(),
                Vec3::Y,
            ];
            // A first problem with the top node held in full: the base factorisation.
            for round in 0..2 {
                let mut p = DofProblem::new(n);
                for &v in &support {
                    p.hold_node(v, Vec3::ZERO).unwrap();
                }
                if round == 0 {
                    p.hold_node(top[11], Vec3::new(0.0, -2e-4, 0.0)).unwrap();
                }
                for (k, nrm) in normals.iter().enumerate() {
                    p.hold_along(top[8 + k], *nrm, -3e-4 * (k + 1) as Real)
                        .unwrap();
                }
                p.forces[3 * top[4] + 2] = 0.05;
                p.finish();
                let (mut u, mut r) = (vec![0.0; n], vec![0.0; n]);
                s.solve(&p, &mut u, &mut r).unwrap();
                let node = |v: &[Real], i: usize| Vec3::new(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
                let rmax = r.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
                let mut slid: Real = 0.0;
                for (k, nrm) in normals.iter().enumerate() {
                    let i = top[8 + k];
                    let (ui, ri) = (node(&u, i), node(&r, i));
                    assert!((ui.dot(*nrm) + 3e-4 * (k + 1) as Real).abs() < 1e-15);
                    assert!(ri.cross(*nrm).length() < 1e-9 * rmax, "{rule:?}: {ri}");
                    assert!(ri.length() > 1e-3 * rmax);
                    slid = slid.max((ui - nrm * ui.dot(*nrm)).length());
                }
                assert!(slid > 1e-6, "{slid}");
                // The same equilibrium, every node held in full where it went.
                let mut full = DofProblem::new(n);
                for d in p.held_dofs() {
                    full.hold(d, u[d]).unwrap();
                }
                full.forces.clone_from(&p.forces);
                full.finish();
                let mut plain = bar_system(SchurRule::Never);
                let (mut u2, mut r2) = (vec![0.0; n], vec![0.0; n]);
                plain.solve(&full, &mut u2, &mut r2).unwrap();
                let umax = u2.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
                for d in 0..n {
                    assert!((u[d] - u2[d]).abs() < 1e-10 * umax, "{rule:?} dof {d}");
                    assert!((r[d] - r2[d]).abs() < 1e-8 * rmax, "{rule:?} dof {d}");
                }
            }
        }
    }

    /// A node held along an oblique direction and in full at once, or twice, is refused. A
    /// hold along a coordinate axis is a unit row (held in the factorisation, not along).
    #[test]
    fn a_node_held_along_and_in_full_is_refused() {
        let mut s = bar_system(SchurRule::Always);
        let n = s.dofs();
        let (support, top) = nodes(&s);
        let mut p = DofProblem::new(n);
        for &v in &support {
            p.hold_node(v, Vec3::ZERO).unwrap();
        }
        p.hold_along(top[2], -Vec3::Y, 0.25).unwrap();
        assert!(p.constrained[3 * top[2] + 1]);
        assert_eq!(p.targets[3 * top[2] + 1], -0.25);
        assert!(p.along.is_empty());
        p.hold_along(top[3], Vec3::new(1.0, 1.0, 0.0), 0.0).unwrap();
        p.hold(3 * top[3], 0.0).unwrap();
        p.finish();
        let (mut u, mut r) = (vec![0.0; n], vec![0.0; n]);
        assert!(s.solve(&p, &mut u, &mut r).is_err());
        assert!(p.hold_along(top[3], Vec3::ZERO, 0.0).is_err());
        assert!(p.hold_along(n, Vec3::Y, 0.0).is_err());
    }

    /// The timed rule: on a tiny system a factorisation is as cheap as a few solves, so a
    /// large new set refactorises; the answer is the same either way.
    #[test]
    fn timed_rule_gives_the_same_answer() {
        let mut timed = bar_system(SchurRule::Timed);
        let mut slow = bar_system(SchurRule::Never);
        let n = timed.dofs();
        let (support, top) = nodes(&timed);
        for (k, count) in [0usize, 2, 8, 3, 12].iter().enumerate() {
            let mut p = DofProblem::new(n);
            for &s in &support {
                p.hold_node(s, Vec3::ZERO).unwrap();
            }
            for &t in &top[4..4 + count] {
                p.hold_node(t, Vec3::new(0.0, -1e-4 * (k + 1) as Real, 0.0))
                    .unwrap();
            }
            p.finish();
            let (mut u1, mut r1, mut u2, mut r2) =
                (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            timed.solve(&p, &mut u1, &mut r1).unwrap();
            slow.solve(&p, &mut u2, &mut r2).unwrap();
            let umax = u2.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
            for d in 0..n {
                assert!((u1[d] - u2[d]).abs() <= 1e-10 * umax.max(1e-300));
                assert!((r1[d] - r2[d]).abs() <= 1e-9 * (1.0 + r2[d].abs()));
            }
        }
        assert!(timed.refactorizations <= slow.refactorizations);
    }
}
