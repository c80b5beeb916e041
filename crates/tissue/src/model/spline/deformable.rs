//! `SplineModel`: a control net stepped by a shared integrator, seen through its tessellated
//! surface by the rest of the library (`Deformable`).
//!
//! Constraints and loads refer to tessellated surface vertices. Fixed and prescribed vertices
//! are held by penalty springs (see `system`); their reactions are the spring forces. Open
//! ends of the v direction can instead be clamped exactly (`clamp_ends`): the first two and
//! last two control rows are held particles of the integrator (position and slope of the
//! edge), which is what a vessel sutured or clamped at both ends needs.

use std::time::Instant;

use crate::error::{Error, SimError};
use crate::integrate::{Hold, Integrator, ParticleState};
use crate::interact::{Constraints, Loads};
use crate::material::Material;
use crate::math::{Real, Vec3, is_finite_vec};
use crate::mesh::boundary_surface;
use crate::model::registry::parse_params;
use crate::model::{BuildInput, Deformable, ModelInfo, Reactions, StepInfo, SurfaceView};

use super::basis::KnotKind;
use super::energy::ShellEnergy;
use super::fit::fit_mesh;
pub use super::params::SplineParams;
use super::surface::SplineSurface;
use super::system::{ControlNet, Spring};
use super::tessellation::Tessellation;

/// Most solves of one step while its frictionless contacts settle (`SplineModel::advance`).
const MAX_CONTACT_SOLVES: usize = 12;

/// The deformable spline model (see the module docs).
#[derive(Debug)]
pub struct SplineModel {
    params: SplineParams,
    rest: SplineSurface,
    net: ControlNet,
    state: ParticleState,
    integrator: Integrator,
    tess: Tessellation,
    surface_positions: Vec<Vec3>,
    rest_surface: Vec<Vec3>,
    holds: Vec<Hold>,
    /// Spring index of each surface vertex (u32::MAX: free).
    spring_of: Vec<u32>,
    constraints: Constraints,
    fixed_reactions: Vec<Vec3>,
    prescribed_reactions: Vec<Vec3>,
    /// For each constraint entry, whether it owns its vertex's reaction (fixed first wins,
    /// else the last prescribed entry).
    fixed_owner: Vec<bool>,
    prescribed_owner: Vec<bool>,
    precompute_seconds: Real,
    fit_rms: Option<Real>,
}

impl SplineModel {
    /// Fits a net to the scene's surface (sheet or tube) and builds the model. A volume mesh
    /// is replaced by its boundary, which is then refused if it is closed.
    pub fn from_input(input: &BuildInput<'_>) -> Result<Self, Error> {
        let params: SplineParams = parse_params("spline", input.params)?;
        let fit = if input.mesh.triangles.is_empty() && input.mesh.has_volume() {
            let b = boundary_surface(&input.mesh.tet_mesh(input.source)?);
            fit_mesh(
                &b.surface.vertices,
                &b.surface.triangles,
                params.control[0],
                params.control[1],
                params.smoothing,
            )
        } else {
            fit_mesh(
                &input.mesh.vertices,
                &input.mesh.triangles,
                params.control[0],
                params.control[1],
                params.smoothing,
            )
        }
        .map_err(|e| match e {
            SimError::Unsupported {
                model,
                operation,
                reason,
            } => SimError::Unsupported {
                model,
                operation,
                reason: format!("{}: {reason}", input.source),
            },
            e => e,
        })?;
        let mut m = Self::new(fit.surface, input.material, params)?;
        m.fit_rms = Some(fit.rms_error);
        Ok(m)
    }

    /// A model whose rest shape is `rest` (its control points).
    pub fn new(
        rest: SplineSurface,
        material: Material,
        params: SplineParams,
    ) -> Result<Self, Error> {
        let start = Instant::now();
        let material = material.validated()?;
        if !(params.subdivisions >= 1 && params.subdivisions <= 64) {
            return Err(bad(
                "subdivisions",
                params.subdivisions.to_string(),
                "must lie in 1..=64",
            )
            .into());
        }
        // The rendered grid is (spans·k + 1)² at most: keep it below 2^24 vertices.
        let k = params.subdivisions;
        let grid = (rest.u.spans() * k + 1) * (rest.v.spans() * k + 1);
        if grid > 1 << 24 {
            return Err(bad(
                "subdivisions",
                k.to_string(),
                "the rendered surface would exceed 2^24 vertices",
            )
            .into());
        }
        let energy = ShellEnergy::new(&rest, &material, params.thickness)?;
        let stiffness = params
            .hold_stiffness
            .unwrap_or(100.0 * material.young_modulus * params.thickness);
        let net = ControlNet::new(
            energy,
            material.density,
            params.thickness,
            material.damping,
            stiffness,
        )?;
        let mut integrator = Integrator::new(params.integrator);
        integrator.settings.substeps = params.substeps;
        if let Some(n) = params.cg_iterations {
            integrator.settings.cg_max_iterations = n.max(1);
        }
        if let Some(t) = params.cg_tolerance {
            if !(t.is_finite() && t >= 0.0) {
                return Err(
                    bad("cg_tolerance", t.to_string(), "must be a finite value >= 0").into(),
                );
            }
            integrator.settings.cg_tolerance = t;
        }
        let mut holds = Vec::new();
        if params.clamp_ends {
            if rest.v.kind() != KnotKind::Clamped {
                return Err(
                    bad("clamp_ends", "true".into(), "the surface has no open ends").into(),
                );
            }
            let (nu, nv) = (rest.nu(), rest.nv());
            for j in [0, 1, nv - 2, nv - 1] {
                for i in 0..nu {
                    let p = i + nu * j;
                    holds.push(Hold {
                        particle: p,
                        target: rest.control[p],
                        along: None,
                        unilateral: false,
                    });
                }
            }
        }
        let mut tess = Tessellation::new(&rest, params.subdivisions);
        let mut rest_surface = vec![Vec3::ZERO; tess.len()];
        tess.apply(&rest.control, &mut rest_surface);
        Ok(Self {
            params,
            state: ParticleState::at_rest(rest.control.clone()),
            spring_of: vec![u32::MAX; rest_surface.len()],
            surface_positions: rest_surface.clone(),
            rest_surface,
            rest,
            net,
            integrator,
            tess,
            holds,
            constraints: Constraints::default(),
            fixed_reactions: Vec::new(),
            prescribed_reactions: Vec::new(),
            fixed_owner: Vec::new(),
            prescribed_owner: Vec::new(),
            precompute_seconds: start.elapsed().as_secs_f64(),
            fit_rms: None,
        })
    }

    pub fn params(&self) -> &SplineParams {
        &self.params
    }
    pub fn rest_shape(&self) -> &SplineSurface {
        &self.rest
    }
    /// Control point positions and velocities.
    pub fn state(&self) -> &ParticleState {
        &self.state
    }
    pub fn net(&self) -> &ControlNet {
        &self.net
    }
    pub fn tessellation(&self) -> &Tessellation {
        &self.tess
    }
    pub fn integrator(&self) -> &Integrator {
        &self.integrator
    }
    /// Elastic energy of the current control net, J.
    pub fn elastic_energy(&self) -> Real {
        self.net.energy.energy(&self.state.x)
    }
    /// Kinetic energy of the control net, J.
    pub fn kinetic_energy(&self) -> Real {
        self.state.kinetic_energy(use_masses(&self.net))
    }

    /// Replaces positions and velocities of the control points (finite, one per point).
    pub fn set_state(&mut self, x: &[Vec3], v: &[Vec3]) -> Result<(), SimError> {
        let n = self.state.x.len();
        if x.len() != n || v.len() != n || !x.iter().chain(v).all(|p| is_finite_vec(*p)) {
            return Err(bad(
                "state",
                format!("{} positions, {} velocities", x.len(), v.len()),
                "needs one finite position and velocity per control point",
            ));
        }
        self.state.x.copy_from_slice(x);
        self.state.v.copy_from_slice(v);
        self.integrator.invalidate();
        self.update_surface();
        Ok(())
    }

    /// Constant loads on control points (added to gravity and point loads set later).
    pub fn set_node_loads(&mut self, forces: &[Vec3]) -> Result<(), SimError> {
        if forces.len() != self.net.external.len() || !forces.iter().all(|f| is_finite_vec(*f)) {
            return Err(bad(
                "loads",
                format!("{} forces", forces.len()),
                "needs one finite force per control point",
            ));
        }
        self.net.external.copy_from_slice(forces);
        self.integrator.invalidate();
        Ok(())
    }

    /// Advances by `dt` with the configured scheme; on error the state is kept.
    ///
    /// Frictionless contacts (`system::Spring::normal`, implicit Euler only) are settled
    /// within the step: those whose vertex, moving on at its velocity, would end past its plane are engaged;
    /// after each solve an engaged one that pulls is let go for the rest of the step and a
    /// free one past its plane is taken, and the step is solved again from its start until
    /// nothing changes (each contact changes at most twice, so at most 2m + 1 solves for m
    /// contacts; `MAX_CONTACT_SOLVES` caps it and the step then says `capped`).
    pub fn advance(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        if !self.net.springs.iter().any(|s| s.normal.is_some()) {
            let info = self
                .integrator
                .step(&mut self.net, &mut self.state, &self.holds, dt)?;
            self.update_surface();
            self.collect_reactions();
            return Ok(info);
        }
        let (x, v) = (&self.state.x, &self.state.v);
        let ahead: Vec<Vec3> = x.iter().zip(v).map(|(x, v)| *x + *v * dt).collect();
        for s in &mut self.net.springs {
            s.engaged = s.gap(&ahead).is_some_and(|g| g < 0.0) || s.gap(x).is_some_and(|g| g < 0.0);
        }
        let start = (self.state.clone(), self.integrator.clone());
        let mut released = vec![false; self.net.springs.len()];
        let mut info = StepInfo::default();
        for solve in 1..=MAX_CONTACT_SOLVES {
            if solve > 1 {
                self.state.clone_from(&start.0);
                self.integrator.clone_from(&start.1);
            }
            // The engaged set changed the forces the integrator kept from the last step.
            self.integrator.forget_forces();
            let i = self
                .integrator
                .step(&mut self.net, &mut self.state, &self.holds, dt)
                .inspect_err(|_| {
                    self.state.clone_from(&start.0);
                    self.integrator.clone_from(&start.1);
                })?;
            info.iterations += i.iterations;
            info.residual = info.residual.max(i.residual);
            info.capped |= i.capped;
            info.substeps = i.substeps;
            let mut changed = false;
            for (s, gone) in self.net.springs.iter_mut().zip(&mut released) {
                let Some(gap) = s.gap(&self.state.x) else {
                    continue;
                };
                if s.engaged && gap > 0.0 {
                    (s.engaged, *gone, changed) = (false, true, true);
                } else if !s.engaged && !*gone && gap < 0.0 {
                    (s.engaged, changed) = (true, true);
                }
            }
            if !changed {
                break;
            }
            if solve == MAX_CONTACT_SOLVES {
                info.capped = true;
            }
        }
        self.update_surface();
        self.collect_reactions();
        Ok(info)
    }

    fn update_surface(&mut self) {
        self.tess.apply(&self.state.x, &mut self.surface_positions);
    }

    /// One penalty spring per held vertex (see `set_constraints`); a vertex whose entry
    /// (the last prescribed one, unless the vertex is fixed) has a direction in `normals`
    /// gets a contact spring along it.
    fn hold_vertices(&mut self, c: &Constraints, normals: &[Option<Vec3>]) -> Result<(), SimError> {
        let disp = c.surface_displacements(&self.rest_surface)?;
        let mut normal_of: Vec<Option<Vec3>> = vec![None; self.rest_surface.len()];
        for (k, p) in c.prescribed.iter().enumerate() {
            if let Some(slot) = normal_of.get_mut(p.vertex as usize) {
                *slot = normals
                    .get(k)
                    .copied()
                    .flatten()
                    .map(Vec3::normalize_or_zero)
                    .filter(|n| *n != Vec3::ZERO && is_finite_vec(*n));
            }
        }
        for &v in &c.fixed {
            if let Some(slot) = normal_of.get_mut(v as usize) {
                *slot = None;
            }
        }
        let mut springs = Vec::new();
        let mut new_of = vec![u32::MAX; self.spring_of.len()];
        for (v, d) in disp.iter().enumerate() {
            if let (Some(d), Some((nodes, weights))) = (d, self.tess.weights(v)) {
                // The target moves over the step from the spring's last one, or from the
                // vertex itself when the spring is new (module `system`).
                let from = match self.spring_of.get(v) {
                    Some(&s) if s != u32::MAX => self.net.springs.get(s as usize),
                    _ => None,
                }
                .filter(|s| s.vertex as usize == v)
                .map(|s| s.target)
                .or_else(|| self.surface_positions.get(v).copied())
                .unwrap_or(self.rest_surface[v] + *d);
                new_of[v] = springs.len() as u32;
                springs.push(Spring {
                    vertex: v as u32,
                    nodes,
                    weights,
                    target: self.rest_surface[v] + *d,
                    from,
                    normal: normal_of[v],
                    engaged: false,
                });
            }
        }
        self.spring_of = new_of;
        // The springs' stiffness depends on which vertices they hold, not on their
        // targets: a probe moving its held vertices (every step of a press) keeps the
        // measured stability limit, and only the kept forces and the energy ledger (whose
        // zero moved with the targets) are dropped. Re-measuring on every step cost 60 force
        // passes a step under an explicit scheme.
        let same_vertices = springs.len() == self.net.springs.len()
            && springs
                .iter()
                .zip(&self.net.springs)
                .all(|(a, b)| a.vertex == b.vertex);
        self.net.springs = springs;
        let mut taken = vec![false; self.rest_surface.len()];
        self.fixed_owner = c
            .fixed
            .iter()
            .map(|&v| !std::mem::replace(&mut taken[v as usize], true))
            .collect();
        let mut owner = vec![false; c.prescribed.len()];
        for (k, p) in c.prescribed.iter().enumerate().rev() {
            owner[k] = !std::mem::replace(&mut taken[p.vertex as usize], true);
        }
        self.prescribed_owner = owner;
        self.fixed_reactions = vec![Vec3::ZERO; c.fixed.len()];
        self.prescribed_reactions = vec![Vec3::ZERO; c.prescribed.len()];
        self.constraints = c.clone();
        if same_vertices {
            self.integrator.forget_forces();
        } else {
            self.integrator.invalidate();
        }
        self.collect_reactions();
        Ok(())
    }

    fn collect_reactions(&mut self) {
        let x = &self.state.x;
        let of = |v: u32| -> Vec3 {
            self.spring_of
                .get(v as usize)
                .and_then(|&s| self.net.springs.get(s as usize))
                .map(|s| self.net.spring_reaction(s, x))
                .unwrap_or(Vec3::ZERO)
        };
        for (k, &v) in self.constraints.fixed.iter().enumerate() {
            self.fixed_reactions[k] = if self.fixed_owner[k] {
                of(v)
            } else {
                Vec3::ZERO
            };
        }
        for (k, p) in self.constraints.prescribed.iter().enumerate() {
            self.prescribed_reactions[k] = if self.prescribed_owner[k] {
                of(p.vertex)
            } else {
                Vec3::ZERO
            };
        }
    }
}

fn use_masses(net: &ControlNet) -> &[Real] {
    use crate::integrate::ParticleSystem;
    net.masses()
}

fn bad(name: &'static str, value: String, reason: &str) -> SimError {
    SimError::BadParameter {
        name,
        value,
        reason: reason.into(),
    }
}

impl Deformable for SplineModel {
    fn kind(&self) -> &'static str {
        "spline"
    }

    fn surface(&self) -> SurfaceView<'_> {
        SurfaceView {
            positions: &self.surface_positions,
            triangles: &self.tess.triangles,
        }
    }

    fn rest_surface(&self) -> &[Vec3] {
        &self.rest_surface
    }

    /// One penalty spring per held vertex: fixed ones to their rest position, prescribed
    /// ones to their target (fixed wins; the last prescribed entry of a vertex wins).
    fn set_constraints(&mut self, c: &Constraints) -> Result<(), SimError> {
        self.hold_vertices(c, &[])
    }

    /// Entries with a direction are frictionless contacts: their springs act along the
    /// normal only and only push (`system::Spring::normal`), under implicit Euler. The
    /// explicit schemes hold them in full and leave the sliding to the relaxation (false):
    /// a penalty contact switched by the state at every substep bounced (no damping along
    /// n), and the force read at the step's end was that of a vertex mostly off its plane
    /// (the tube at 1 ms under symplectic Euler read 0 N with the probe 1 mm into it).
    fn set_constraints_along(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<bool, SimError> {
        if self.contacts_push_only() {
            self.hold_vertices(c, normals).map(|()| true)
        } else {
            self.hold_vertices(c, &[]).map(|()| false)
        }
    }

    fn contacts_push_only(&self) -> bool {
        self.integrator.scheme == crate::integrate::Scheme::ImplicitEuler
    }

    /// Gravity as the lumped share m_i g; point loads through the tessellation's transpose.
    fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        if !is_finite_vec(loads.gravity) {
            return Err(bad("gravity", loads.gravity.to_string(), "must be finite"));
        }
        let n = self.rest_surface.len();
        let mut surface = vec![Vec3::ZERO; n];
        for &(v, f) in &loads.point_loads {
            if v as usize >= n {
                return Err(SimError::BadConstraint {
                    vertex: v as usize,
                    count: n,
                });
            }
            if !is_finite_vec(f) {
                return Err(bad(
                    "point_loads",
                    format!("surface vertex {v} -> {f}"),
                    "the force is not finite",
                ));
            }
            surface[v as usize] += f;
        }
        let mut external: Vec<Vec3> = use_masses(&self.net)
            .iter()
            .map(|m| *m * loads.gravity)
            .collect();
        self.tess.apply_transpose(&surface, &mut external);
        self.net.external = external;
        self.integrator.invalidate();
        Ok(())
    }

    fn step(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        self.advance(dt)
    }

    fn reactions(&self) -> Reactions<'_> {
        Reactions {
            fixed: &self.fixed_reactions,
            prescribed: &self.prescribed_reactions,
        }
    }

    fn cut(&mut self, _blade: &crate::model::CutPath) -> Result<crate::model::CutInfo, SimError> {
        Err(SimError::Unsupported {
            model: "spline",
            operation: "cutting",
            reason: "a tensor-product spline surface is one smooth patch over a rectangle of \
                     parameters; a cut would need trimming curves or a new patch layout"
                .into(),
        })
    }

    fn kinetic_energy(&self) -> Option<Real> {
        Some(SplineModel::kinetic_energy(self))
    }

    /// The control points' velocities zeroed; the surface does not move.
    fn stop_motion(&mut self) -> bool {
        self.state.stop();
        self.integrator.motion_stopped();
        true
    }

    fn reset(&mut self) {
        self.state = ParticleState::at_rest(self.rest.control.clone());
        self.integrator.invalidate();
        self.update_surface();
        self.collect_reactions();
    }

    fn info(&self) -> ModelInfo {
        let n = self.state.x.len();
        let q = self.net.energy.points().len();
        let (cols, rows) = self.tess.grid();
        let mut details = vec![
            (
                "integrator".into(),
                self.integrator.scheme.name().to_string(),
            ),
            (
                "control".into(),
                format!("{} x {}", self.rest.nu(), self.rest.nv()),
            ),
            (
                "periodic_u".into(),
                (self.rest.u.kind() == KnotKind::Periodic).to_string(),
            ),
            ("thickness".into(), self.params.thickness.to_string()),
            ("tessellation".into(), format!("{cols} x {rows}")),
            (
                "hold_stiffness".into(),
                format!("{:.3e}", self.net.stiffness),
            ),
            ("clamp_ends".into(), self.params.clamp_ends.to_string()),
            ("steps".into(), self.integrator.steps().to_string()),
            (
                "elastic_energy".into(),
                format!("{:.3e}", self.elastic_energy()),
            ),
        ];
        if let Some(r) = self.fit_rms {
            details.push(("fit_rms_error".into(), format!("{r:.3e}")));
        }
        details.extend(self.integrator.details());
        ModelInfo {
            kind: self.kind(),
            nodes: n,
            dofs: 3 * n,
            elements: q / 16,
            surface_vertices: self.surface_positions.len(),
            memory_bytes: std::mem::size_of_val(self.net.energy.points())
                + n * 10 * 24
                + self.surface_positions.len() * 4 * 24,
            precompute_seconds: self.precompute_seconds,
            is_static: false,
            details,
        }
    }
}
