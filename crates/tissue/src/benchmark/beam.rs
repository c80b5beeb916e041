//! The clamped beam benchmark (issue 24): a 1 m × 0.1 m × 0.1 m beam of hexahedral cells
//! split into 6 tetrahedra, clamped at x = 0, sagging under gravity (E = 1e8 Pa, ν = 0.3,
//! ρ = 1000 kg/m³, stiffness damping β = 0.02 s), stepped at dt = 1 ms for 1 s.
//!
//! Each case reports the cost of one simulated millisecond, the settled tip deflection (mean
//! over the last 0.1 s) against P1, the static linear deflection `fem-static` computes on the
//! same mesh (at this load the beam bends by ~1.5% of its length, so geometric
//! nonlinearity moves the answer by far less than the 1% the targets ask), the oscillation
//! left (half the tip's range over the last 0.1 s), and what the steps reported (substeps,
//! capped steps, worst residual). A kind that cannot run the case gets the reason instead.

use std::time::Instant;

use crate::error::Error;
use crate::interact::{Constraints, Loads};
use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::mesh::generate::{BoxSplit, box_tets};
use crate::mesh::{MeshData, TetMesh};
use crate::model::registry::{BuildInput, build};
use crate::model::{Deformable, StepInfo};

/// The beam's length along x, in m.
pub const LENGTH: Real = 1.0;
/// The beam's square cross-section side, in m.
pub const WIDTH: Real = 0.1;

/// The dynamic kinds the benchmark runs by default (every kind whose `step` advances time).
pub const DYNAMIC_KINDS: &[&str] = &[
    "fem-corotational",
    "fem-explicit",
    "fem-semi-implicit",
    "tensor-mass",
    "tensor-mass-nonlinear",
    "spring-mass",
    "simplex-spring-mass",
    "volumetric-spring-mass",
    "linked-volumes",
    "spline",
];

/// The named sizes of the issue: cells along (x, y, z), 6 tetrahedra per cell.
pub const SIZES: &[(&str, [usize; 3])] = &[
    ("1k", [20, 3, 3]),
    ("5k", [32, 5, 5]),
    ("20k", [50, 8, 8]),
    ("80k", [80, 13, 13]),
];

/// The cells of a named size (`1k`, `5k`, `20k`, `80k`), or `None`.
pub fn size_cells(name: &str) -> Option<[usize; 3]> {
    SIZES.iter().find(|(n, _)| *n == name).map(|(_, c)| *c)
}

/// The scenario's settings (the issue's by default).
#[derive(Clone, Debug, PartialEq)]
pub struct BeamSpec {
    pub cells: [usize; 3],
    pub young_modulus: Real,
    pub poisson_ratio: Real,
    pub density: Real,
    /// Rayleigh stiffness damping β, in s.
    pub stiffness_damping: Real,
    pub dt: Real,
    /// Simulated time, in s.
    pub duration: Real,
    /// Window at the end over which the settled tip and the oscillation are measured, in s.
    pub window: Real,
    pub gravity: Vec3,
}

impl BeamSpec {
    /// The issue's beam with the given cells.
    pub fn new(cells: [usize; 3]) -> Self {
        Self {
            cells,
            young_modulus: 1e8,
            poisson_ratio: 0.3,
            density: 1000.0,
            stiffness_damping: 0.02,
            dt: 1e-3,
            duration: 1.0,
            window: 0.1,
            gravity: Vec3::new(0.0, 0.0, -9.81),
        }
    }

    /// The tetrahedral mesh (6 tetrahedra per cell).
    pub fn mesh(&self) -> TetMesh {
        box_tets(
            Vec3::ZERO,
            Vec3::new(LENGTH, WIDTH, WIDTH),
            self.cells,
            BoxSplit::Six,
        )
    }

    pub fn material(&self) -> Result<Material, Error> {
        let mut m =
            Material::new(self.young_modulus, self.poisson_ratio)?.with_density(self.density)?;
        m.stiffness_damping = self.stiffness_damping;
        Ok(m)
    }

    /// Steps in the run.
    pub fn steps(&self) -> usize {
        (self.duration / self.dt).round().max(1.0) as usize
    }
}

/// What one (kind, mesh) case did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct BeamCase {
    pub kind: String,
    pub tets: usize,
    /// Unknowns of the model (`ModelInfo::dofs`).
    pub dofs: usize,
    /// Steps completed (all of them unless `error` is set).
    pub steps: usize,
    /// Wall time per simulated millisecond, in ms.
    pub wall_ms_per_ms: Real,
    /// Process CPU time (all threads) per simulated millisecond, in ms (Linux; else 0).
    pub cpu_ms_per_ms: Real,
    /// Model build time, in s.
    pub build_seconds: Real,
    /// Settled tip deflection along gravity (mean over the window), in m (negative: down).
    pub tip: Real,
    /// P1's tip deflection on the same mesh, in m.
    pub p1_tip: Real,
    /// tip / p1_tip.
    pub tip_ratio: Real,
    /// Half the tip's range over the window, relative to |p1_tip|.
    pub oscillation: Real,
    /// Most substeps any step reported (`StepInfo::substeps`).
    pub max_substeps: u32,
    /// Steps whose iterative solver stopped at its cap (`StepInfo::capped`).
    pub capped_steps: usize,
    /// Largest residual a step reported.
    pub worst_residual: Real,
    /// Mean inner iterations per step.
    pub mean_iterations: Real,
    /// Why the case could not be run or did not finish.
    pub error: Option<String>,
}

/// Surface vertices at the clamped end (x = 0) and at the tip (x = L).
fn ends(rest_surface: &[Vec3]) -> (Vec<u32>, Vec<u32>) {
    let eps = 1e-9 * LENGTH;
    let pick = |f: &dyn Fn(Real) -> bool| {
        (0..rest_surface.len() as u32)
            .filter(|&i| f(rest_surface[i as usize].x))
            .collect::<Vec<_>>()
    };
    (pick(&|x| x <= eps), pick(&|x| x >= LENGTH - eps))
}

fn tip_deflection(model: &dyn Deformable, tip: &[u32], down: Vec3) -> Real {
    let (now, rest) = (model.surface().positions, model.rest_surface());
    let sum: Real = tip
        .iter()
        .map(|&i| (now[i as usize] - rest[i as usize]).dot(down))
        .sum();
    -sum / tip.len().max(1) as Real
}

fn build_clamped(
    kind: &str,
    spec: &BeamSpec,
    mesh: &TetMesh,
    params: &toml::Table,
) -> Result<(Box<dyn Deformable>, Vec<u32>), Error> {
    let data = MeshData::from_tets(mesh);
    let input = BuildInput {
        mesh: &data,
        source: "beam benchmark",
        material: spec.material()?,
        params,
        regions: &[],
    };
    let mut model = build(kind, &input)?;
    let (clamp, tip) = ends(model.rest_surface());
    if clamp.is_empty() || tip.is_empty() {
        return Err(crate::error::SimError::BadParameter {
            name: "beam",
            value: kind.to_string(),
            reason: "the model's surface has no vertex at the clamped end or at the tip".into(),
        }
        .into());
    }
    model.set_constraints(&Constraints::fixed(clamp))?;
    model.set_loads(&Loads {
        gravity: spec.gravity,
        point_loads: Vec::new(),
    })?;
    Ok((model, tip))
}

/// P1: the tip deflection `fem-static` (linear tetrahedra) finds on `mesh`, in m.
pub fn p1_tip(spec: &BeamSpec, mesh: &TetMesh) -> Result<Real, Error> {
    let (mut model, tip) = build_clamped("fem-static", spec, mesh, &toml::Table::new())?;
    model.step(spec.dt)?;
    Ok(tip_deflection(
        model.as_ref(),
        &tip,
        spec.gravity.normalize_or_zero(),
    ))
}

/// `[model]` settings from `key = value` TOML lines (`tissue bench beam --param`).
pub fn params_from_lines(lines: &[String]) -> Result<toml::Table, Error> {
    let text = lines.join("\n");
    text.parse::<toml::Table>().map_err(|e| {
        crate::error::SimError::BadParameter {
            name: "param",
            value: text.clone(),
            reason: e.to_string().trim().to_string(),
        }
        .into()
    })
}

/// Process CPU time (all threads), in s; 0 where it cannot be read.
pub fn process_cpu_seconds() -> Real {
    #[cfg(target_os = "linux")]
    {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: clock_gettime writes into the timespec we own.
        let ok = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) } == 0;
        if ok {
            return ts.tv_sec as Real + 1e-9 * ts.tv_nsec as Real;
        }
    }
    0.0
}

/// Runs `kind` (with the `[model]` settings `params`, empty for its defaults) on the beam
/// `mesh` against the P1 tip `p1`. Never fails: a kind that cannot run the case gets the
/// reason in `error`, with what it did until then.
pub fn run_case(
    kind: &str,
    spec: &BeamSpec,
    mesh: &TetMesh,
    params: &toml::Table,
    p1: Real,
) -> BeamCase {
    match CaseRun::start(kind, spec, mesh, params, p1) {
        Ok(mut run) => {
            run.advance(spec.steps());
            run.finish()
        }
        Err(case) => *case,
    }
}

/// One case in progress: `run_case` in slices, so that cases can take turns
/// (`run_interleaved`).
pub struct CaseRun {
    case: BeamCase,
    model: Box<dyn Deformable>,
    tip: Vec<u32>,
    spec: BeamSpec,
    /// Steps from the end at which the tip starts being recorded.
    window: usize,
    tips: Vec<Real>,
    iterations: usize,
    /// Wall and process CPU seconds spent stepping.
    wall: Real,
    cpu: Real,
    stopped: bool,
}

impl CaseRun {
    /// Builds the model, clamped and loaded; a case that cannot run comes back as `Err`
    /// with its reason in `error` (boxed: a case is ten times a pointer).
    pub fn start(
        kind: &str,
        spec: &BeamSpec,
        mesh: &TetMesh,
        params: &toml::Table,
        p1: Real,
    ) -> Result<Self, Box<BeamCase>> {
        let mut case = BeamCase {
            kind: kind.to_string(),
            tets: mesh.tets.len(),
            p1_tip: p1,
            ..BeamCase::default()
        };
        let start = Instant::now();
        let (model, tip) = match build_clamped(kind, spec, mesh, params) {
            Ok(m) => m,
            Err(e) => {
                case.error = Some(e.to_string());
                return Err(Box::new(case));
            }
        };
        case.build_seconds = start.elapsed().as_secs_f64();
        let info = model.info();
        case.dofs = info.dofs;
        if info.is_static {
            case.error = Some("a static model: it does not step in time".into());
            return Err(Box::new(case));
        }
        let steps = spec.steps();
        Ok(Self {
            case,
            model,
            tip,
            spec: spec.clone(),
            window: ((spec.window / spec.dt).round() as usize).clamp(1, steps),
            tips: Vec::new(),
            iterations: 0,
            wall: 0.0,
            cpu: 0.0,
            stopped: false,
        })
    }

    /// Steps still to run (0 once finished or stopped by an error).
    pub fn remaining(&self) -> usize {
        if self.stopped {
            0
        } else {
            self.spec.steps() - self.case.steps
        }
    }

    /// Runs up to `steps` more steps; returns the wall seconds they took (stepping only).
    pub fn advance(&mut self, steps: usize) -> Real {
        let (total, down) = (self.spec.steps(), self.spec.gravity.normalize_or_zero());
        let (wall0, cpu0) = (Instant::now(), process_cpu_seconds());
        for _ in 0..steps.min(self.remaining()) {
            let info: StepInfo = match self.model.step(self.spec.dt) {
                Ok(i) => i,
                Err(e) => {
                    self.case.error = Some(format!("step {}: {e}", self.case.steps + 1));
                    self.stopped = true;
                    break;
                }
            };
            let case = &mut self.case;
            case.steps += 1;
            self.iterations += info.iterations;
            case.max_substeps = case.max_substeps.max(info.substeps);
            case.capped_steps += usize::from(info.capped);
            case.worst_residual = case.worst_residual.max(info.residual);
            if case.steps + self.window > total {
                self.tips
                    .push(tip_deflection(self.model.as_ref(), &self.tip, down));
            }
        }
        let wall = wall0.elapsed().as_secs_f64();
        self.wall += wall;
        self.cpu += process_cpu_seconds() - cpu0;
        wall
    }

    /// The case's figures over the steps run.
    pub fn finish(mut self) -> BeamCase {
        let case = &mut self.case;
        let simulated_ms = (case.steps.max(1) as Real) * self.spec.dt * 1e3;
        case.wall_ms_per_ms = self.wall * 1e3 / simulated_ms;
        case.cpu_ms_per_ms = self.cpu * 1e3 / simulated_ms;
        case.mean_iterations = self.iterations as Real / case.steps.max(1) as Real;
        if !self.tips.is_empty() {
            case.tip = self.tips.iter().sum::<Real>() / self.tips.len() as Real;
            let (lo, hi) = self
                .tips
                .iter()
                .fold((Real::INFINITY, Real::NEG_INFINITY), |(a, b), &t| {
                    (a.min(t), b.max(t))
                });
            case.oscillation = 0.5 * (hi - lo) / case.p1_tip.abs().max(Real::MIN_POSITIVE);
        }
        case.tip_ratio = case.tip / case.p1_tip;
        self.case
    }
}

/// One case run on several thread counts in turn (`run_interleaved`).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Interleaved {
    /// The thread counts, in the order given.
    pub threads: Vec<usize>,
    /// Each thread count's case (its wall and CPU figures over its own slices).
    pub cases: Vec<BeamCase>,
    /// Steps per slice.
    pub slice_steps: usize,
    /// For each later thread count, the first's slice time over its slice time, one per
    /// slice both ran in full (the same simulated interval, back to back).
    pub speedups: Vec<Vec<Real>>,
}

impl Interleaved {
    /// The median and the quartiles of `speedups[k]`.
    pub fn speedup_quartiles(&self, k: usize) -> Option<[Real; 3]> {
        let mut r = self.speedups.get(k)?.clone();
        if r.is_empty() {
            return None;
        }
        r.sort_by(Real::total_cmp);
        let at = |q: Real| r[((r.len() - 1) as Real * q).round() as usize];
        Some([at(0.25), at(0.5), at(0.75)])
    }
}

/// Runs `kind` on the beam once per thread count in `threads`, the runs taking turns by
/// slices of `slice_steps` steps (the order of each round reversed from the last), each on
/// its own pool of that many workers.
///
/// Why: on a shared machine the speed of one core drifts by 20-30% over minutes (another
/// guest on the host), more than the gap between one thread and two that a benchmark is
/// after. Runs one after another see different machines; slices back to back see the same
/// one, so the ratio of paired slices measures the code, and its spread the machine.
pub fn run_interleaved(
    kind: &str,
    spec: &BeamSpec,
    mesh: &TetMesh,
    params: &toml::Table,
    p1: Real,
    threads: &[usize],
    slice_steps: usize,
) -> Result<Interleaved, Error> {
    let pools = threads
        .iter()
        .map(|&n| super::Pool::new(Some(n)))
        .collect::<Result<Vec<_>, _>>()?;
    let mut runs = Vec::new();
    for pool in &pools {
        match pool.install(|| CaseRun::start(kind, spec, mesh, params, p1)) {
            Ok(run) => runs.push(run),
            // A case that cannot run cannot run on any thread count.
            Err(case) => {
                return Ok(Interleaved {
                    threads: threads.to_vec(),
                    cases: vec![*case; threads.len()],
                    slice_steps,
                    speedups: vec![Vec::new(); threads.len().saturating_sub(1)],
                });
            }
        }
    }
    let slice = slice_steps.max(1);
    let mut speedups = vec![Vec::new(); threads.len().saturating_sub(1)];
    let mut round = 0;
    while runs.iter().any(|r| r.remaining() > 0) {
        let mut took = vec![0.0; runs.len()];
        let mut full = true;
        let order: Vec<usize> = if round % 2 == 0 {
            (0..runs.len()).collect()
        } else {
            (0..runs.len()).rev().collect()
        };
        for k in order {
            let want = slice.min(runs[k].remaining());
            full &= want == slice;
            let run = &mut runs[k];
            took[k] = pools[k].install(|| run.advance(want));
            full &= !run.stopped;
        }
        if full {
            for (k, s) in speedups.iter_mut().enumerate() {
                s.push(took[0] / took[k + 1]);
            }
        }
        round += 1;
    }
    Ok(Interleaved {
        threads: threads.to_vec(),
        cases: runs.into_iter().map(CaseRun::finish).collect(),
        slice_steps: slice,
        speedups,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn named_sizes_have_the_issue_s_tetrahedron_counts() {
        let counts: Vec<usize> = SIZES.iter().map(|(_, c)| 6 * c[0] * c[1] * c[2]).collect();
        assert_eq!(counts, vec![1080, 4800, 19200, 81120]);
    }

    /// P1 on the coarse beam against Euler-Bernoulli, δ = q L⁴ / (8 E I): a 3-cell-thick
    /// linear-tetrahedron beam is stiffer than the continuum (locking), so it lands a few
    /// tens of percent below, never above.
    #[test]
    fn p1_tip_is_below_euler_bernoulli_and_of_its_size() {
        let spec = BeamSpec::new([20, 3, 3]);
        let p1 = p1_tip(&spec, &spec.mesh()).unwrap();
        let q = spec.density * 9.81 * WIDTH * WIDTH;
        let i = WIDTH.powi(4) / 12.0;
        let eb = -q * LENGTH.powi(4) / (8.0 * spec.young_modulus * i);
        let r = p1 / eb;
        assert!(r > 0.3 && r < 1.0, "P1 {p1} vs Euler-Bernoulli {eb}");
    }

    /// Taking turns changes nothing but the clock: each thread count's run ends where the
    /// run in one piece does (the same bits on this small beam, whose factor is ordered
    /// alike on any thread count), and every full round gives one speed-up.
    #[test]
    fn interleaved_runs_end_where_single_runs_do() {
        let mut spec = BeamSpec::new([10, 2, 2]);
        spec.duration = 0.05;
        let mesh = spec.mesh();
        let p1 = p1_tip(&spec, &mesh).unwrap();
        let params = toml::Table::new();
        let single = run_case("fem-corotational", &spec, &mesh, &params, p1);
        let turns =
            run_interleaved("fem-corotational", &spec, &mesh, &params, p1, &[1, 2], 20).unwrap();
        assert_eq!(turns.threads, vec![1, 2]);
        for case in &turns.cases {
            assert_eq!(case.steps, 50);
            assert!(case.error.is_none());
            assert_eq!(case.tip, single.tip);
            assert_eq!(case.oscillation, single.oscillation);
        }
        // Slices of 20, 20, 10 steps: two full rounds.
        assert_eq!(turns.speedups.len(), 1);
        assert_eq!(turns.speedups[0].len(), 2);
        assert!(turns.speedups[0].iter().all(|r| r.is_finite() && *r > 0.0));
        let c = run_interleaved("fem-static", &spec, &mesh, &params, p1, &[1, 2], 20).unwrap();
        assert!(c.cases.iter().all(|c| c.error.is_some()));
    }

    #[test]
    fn a_case_that_cannot_build_says_why_and_a_static_kind_is_refused() {
        let spec = BeamSpec::new([4, 1, 1]);
        let mesh = spec.mesh();
        let c = run_case("no-such-kind", &spec, &mesh, &toml::Table::new(), -1.0);
        assert!(c.error.unwrap().contains("no-such-kind"));
        let c = run_case("fem-static", &spec, &mesh, &toml::Table::new(), -1.0);
        assert!(c.error.unwrap().contains("static"));
    }
}
