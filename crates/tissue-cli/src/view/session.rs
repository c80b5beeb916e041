//! The viewer's simulation thread: owns the `Simulation`, applies the page's commands, steps
//! the model in real time (never ahead of the wall clock, dropping time when the model is
//! slower), runs the 1 kHz haptic loop on the probe, and publishes frames at ~30 Hz.
//!
//! The viewer's own instruments replace the scene's scripted ones: a probe (always present,
//! parked far from the organ when not in use, driven by the page or a UDP device), a grasper
//! created when the page grasps and removed when it lets go, and a scalpel that exists while
//! a drawn path is swept.

use std::collections::VecDeque;
use std::net::SocketAddr;
use std::sync::mpsc::{Receiver, TryRecvError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tissue::haptic::{HapticConfig, HapticHandle, HapticLoop, Pose, UdpBridge, step_coupled};
use tissue::interact::{Instrument, InstrumentKind, Trajectory};
use tissue::model::Progress;
use tissue::sim::Simulation;
use tissue::{Material, Real, SimError, Vec3};

use super::hub::Hub;
use super::messages::{Bounds, Command};
use super::publish;
use super::setup::Setup;

use super::setup::PROBE;
pub const GRASPER: &str = "viewer-grasper";
pub const SCALPEL: &str = "viewer-scalpel";
/// Wall time spent stepping before a frame is published regardless.
const STEP_BUDGET: Duration = Duration::from_millis(25);
const FRAME_EVERY: Duration = Duration::from_millis(33);
/// Rate windows (0.5 s each) of steps slower than real time before slow motion is said.
const SLOW_WINDOWS: u32 = 4;
/// After a blow-up is reported, further failures within this window are counted, not
/// reported one by one (a cascade of messages says nothing the first one did not).
const QUIET_AFTER_FAILURE: Duration = Duration::from_secs(3);

struct CutJob {
    remaining: VecDeque<Vec3>,
    total: usize,
}

type Built = Result<(Simulation, String, Material), String>;

/// What a build in progress is doing, written by its progress callback, read by the frames.
#[derive(Clone, Debug, Default)]
pub struct BuildStatus {
    pub kind: String,
    pub stage: String,
    /// 0..1, or negative while the stage's length is unknown.
    pub fraction: Real,
    pub started: Option<Instant>,
}

/// The last reported blow-up and how many followed it unreported.
struct Failure {
    at: Instant,
    more: u32,
}

pub struct Session {
    setup: Arc<Setup>,
    kind: String,
    material: Material,
    sim: Simulation,
    dt: Real,
    _haptic: HapticLoop,
    handle: HapticHandle,
    _bridge: Option<UdpBridge>,
    hub: Arc<Hub>,
    /// Where the page wants the grasper; the simulated one goes there at `MAX_TOOL_SPEED`.
    grasp: Option<Vec3>,
    /// Where the page wants the probe while it presses (`None`: parked, or driven by a
    /// device through the haptic handle); the simulated probe goes there at `MAX_TOOL_SPEED`.
    probe_goal: Option<Vec3>,
    /// The largest force on the probe (the model's reaction, what `step_coupled` hands the
    /// haptic loop) since the page's current press began; 0 otherwise. A frame shows one
    /// instant of a force that can last a few steps: the spring-mass liver pushes back
    /// ~1 mN while the probe goes in, then dents past it and touches it only in bursts,
    /// and a page drawing 1-5 frames/s in software WebGL showed 0 N for the whole press.
    press_peak: Real,
    cut: Option<CutJob>,
    /// The blade's path is done and the model computes the incision off the thread (`bem`
    /// in real time): since when.
    incision_pending: Option<Instant>,
    /// The scalpel was removed at the end of its path; the next step reports the cut.
    cut_ending: bool,
    building: Option<Receiver<Built>>,
    build_status: Arc<Mutex<BuildStatus>>,
    /// The model's notices already said on the page (`tell_notices`).
    told: Vec<String>,
    substeps: u32,
    /// The volume node under each surface vertex (`metrics::surface_nodes`), for the strain
    /// colours; refreshed with every init (a rebuild or a cut).
    strain_nodes: Option<Vec<Option<u32>>>,
    failure: Option<Failure>,
    steps_in_window: u64,
    /// Computation time of the successful steps in the rate window, s.
    step_seconds_in_window: Real,
    window_start: Instant,
    sim_rate: Real,
    slow: SlowMotion,
    last_error: Option<(String, Instant)>,
}

impl Session {
    pub fn new(
        setup: Setup,
        material: Material,
        hub: Arc<Hub>,
        device: Option<SocketAddr>,
    ) -> anyhow::Result<Session> {
        let kind = setup.scene.model_kind.clone();
        let sim = setup.build(&kind, material, Progress::silent())?;
        let haptic = HapticLoop::start(HapticConfig::default())?;
        let handle = haptic.handle();
        handle.set_pose(Pose {
            position: setup.park,
            ..Pose::default()
        });
        let bridge = match device {
            Some(addr) => {
                let b = UdpBridge::start(addr, handle.clone())?;
                eprintln!(
                    "tissue view: haptic device bridge listening on udp://{}",
                    b.local_addr()
                );
                Some(b)
            }
            None => None,
        };
        let dt = setup.scene.run.dt;
        let mut s = Session {
            setup: Arc::new(setup),
            kind,
            material,
            sim,
            dt,
            _haptic: haptic,
            handle,
            _bridge: bridge,
            hub,
            grasp: None,
            probe_goal: None,
            press_peak: 0.0,
            cut: None,
            incision_pending: None,
            cut_ending: false,
            building: None,
            build_status: Arc::new(Mutex::new(BuildStatus::default())),
            substeps: 0,
            strain_nodes: None,
            failure: None,
            steps_in_window: 0,
            step_seconds_in_window: 0.0,
            window_start: Instant::now(),
            slow: SlowMotion::default(),
            sim_rate: 0.0,
            last_error: None,
            told: Vec::new(),
        };
        s.publish_init();
        s.tell_notices();
        Ok(s)
    }

    pub fn bounds(&self) -> Bounds {
        self.setup.bounds
    }

    /// Runs until the command channel closes (the server is gone).
    pub fn run(mut self, commands: Receiver<Command>) {
        let mut wall0 = Instant::now();
        let mut sim0 = self.sim.time();
        let mut last_frame = Instant::now() - FRAME_EVERY;
        loop {
            loop {
                match commands.try_recv() {
                    Ok(c) => self.apply(c),
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => return,
                }
            }
            if self.poll_build() {
                wall0 = Instant::now();
                sim0 = self.sim.time();
            }
            let started = Instant::now();
            // The current model keeps running while another one is being built.
            while self.sim.time() - sim0 < wall0.elapsed().as_secs_f64()
                && started.elapsed() < STEP_BUDGET
            {
                self.step_once();
            }
            let behind = wall0.elapsed().as_secs_f64() - (self.sim.time() - sim0);
            if behind > 0.1 {
                // Slower than real time: drop the backlog rather than chase it.
                wall0 = Instant::now();
                sim0 = self.sim.time();
            }
            if last_frame.elapsed() >= FRAME_EVERY {
                last_frame = Instant::now();
                self.publish_frame();
            }
            let ahead = (self.sim.time() - sim0) - wall0.elapsed().as_secs_f64();
            std::thread::sleep(Duration::from_secs_f64(ahead.clamp(0.0005, 0.005)));
        }
    }

    fn index_of(&self, name: &str) -> Option<usize> {
        self.sim.instruments().iter().position(|i| i.name == name)
    }

    fn apply(&mut self, c: Command) {
        match c {
            Command::Probe(p) => {
                // From the park the probe goes straight to the first point (outside the
                // organ: the page starts a press touching it); after that it follows.
                let parked = self.handle.pose().position == self.setup.park;
                if p.is_none() || parked {
                    // A press starts, or ends: its peak starts again from nothing.
                    self.press_peak = 0.0;
                    self.handle.set_pose(Pose {
                        position: p.unwrap_or(self.setup.park),
                        ..self.handle.pose()
                    });
                }
                self.probe_goal = p;
            }
            Command::Grasp(p) => self.grasp_at(p),
            Command::Release => {
                self.grasp = None;
                if let Some(i) = self.index_of(GRASPER) {
                    self.sim.remove_instrument(i);
                }
            }
            Command::Cut { path, into } => self.start_cut(path, into),
            Command::SetModel(kind) => self.rebuild(kind, self.material),
            Command::SetMaterial {
                young_modulus,
                poisson_ratio,
            } => {
                let m = Material {
                    young_modulus,
                    poisson_ratio,
                    ..self.material
                };
                match m.validated() {
                    Ok(m) => self.rebuild(self.kind.clone(), m),
                    Err(e) => self.hub.notify("error", &format!("material rejected: {e}")),
                }
            }
            Command::Reset => {
                self.drop_tools("reset");
                self.sim.model_mut().reset();
                self.dt = self.setup.scene.run.dt;
                self.failure = None;
                self.substeps = 0;
                // A fresh init: the page rescales its colours and shows the dt again.
                self.publish_init();
                self.hub.notify(
                    "info",
                    &format!("reset to the rest state (dt {:.3e} s)", self.dt),
                );
            }
        }
    }

    /// Removes the grasper and the scalpel and parks the probe; a cut in progress is
    /// abandoned with a notice saying `why`.
    fn drop_tools(&mut self, why: &str) {
        for name in [GRASPER, SCALPEL] {
            if let Some(i) = self.index_of(name) {
                self.sim.remove_instrument(i);
            }
        }
        self.grasp = None;
        if let Some(job) = self.cut.take() {
            self.hub.notify(
                "error",
                &format!(
                    "the cut in progress was stopped ({why}) with {} of its path points left",
                    job.remaining.len()
                ),
            );
        }
        // A switch drops the old model with what it was computing; a Reset keeps it.
        if why.starts_with("switching") && self.incision_pending.take().is_some() {
            self.hub.notify(
                "error",
                &format!(
                    "the incision {} was computing is dropped ({why}: the new model starts uncut)",
                    self.kind
                ),
            );
        }
        self.handle.set_pose(Pose {
            position: self.setup.park,
            ..self.handle.pose()
        });
        self.probe_goal = None;
        self.press_peak = 0.0;
        self.handle.clear_contact();
    }

    fn grasp_at(&mut self, p: Vec3) {
        if self.index_of(GRASPER).is_none() {
            // Reach at least the nearest surface vertex, so a grasp never comes up empty on a
            // coarse mesh.
            let nearest = self
                .sim
                .model()
                .surface()
                .positions
                .iter()
                .map(|q| q.distance(p))
                .fold(Real::INFINITY, Real::min);
            let radius = self.setup.grasp_radius.max(1.05 * nearest);
            let kind = InstrumentKind::Grasper {
                grasp_at: self.sim.time(),
                release_at: None,
            };
            match Instrument::new(GRASPER, kind, radius, Trajectory::fixed(p)) {
                Ok(g) => self.sim.add_instrument(g),
                Err(e) => return self.hub.notify("error", &format!("grasp: {e}")),
            }
        }
        self.grasp = Some(p);
    }

    fn start_cut(&mut self, path: Vec<Vec3>, into: Vec3) {
        if self.cut.is_some() {
            return self.hub.notify("error", "a cut is already in progress");
        }
        let depth = self.setup.scalpel_depth;
        let tips: VecDeque<Vec3> = path.iter().map(|&p| p + into * depth).collect();
        let Some(&first) = tips.front() else { return };
        let kind = InstrumentKind::Scalpel {
            direction: -into,
            length: 2.0 * depth,
        };
        match Instrument::new(
            SCALPEL,
            kind,
            self.setup.probe_radius,
            Trajectory::fixed(first),
        ) {
            Ok(s) => self.sim.add_instrument(s),
            Err(e) => return self.hub.notify("error", &format!("scalpel: {e}")),
        }
        let total = tips.len();
        self.cut = Some(CutJob {
            remaining: tips,
            total,
        });
    }

    fn rebuild(&mut self, kind: String, material: Material) {
        if self.building.is_some() {
            return self.hub.notify("error", "a model is already being built");
        }
        self.hub.notify(
            "info",
            &format!("building {kind}; {} keeps running meanwhile", self.kind),
        );
        let (tx, rx) = std::sync::mpsc::channel();
        let setup = Arc::clone(&self.setup);
        let status = Arc::clone(&self.build_status);
        *lock(&status) = BuildStatus {
            kind: kind.clone(),
            stage: "setting up the model".into(),
            fraction: -1.0,
            started: Some(Instant::now()),
        };
        let sink = Arc::clone(&status);
        let progress = Progress::new(move |stage, fraction| {
            let mut g = lock(&sink);
            g.stage = stage.to_string();
            g.fraction = fraction;
        });
        let spawned = std::thread::Builder::new()
            .name("tissue-view-build".into())
            .spawn(move || {
                let r = setup
                    .build(&kind, material, progress)
                    .map(|sim| (sim, kind.clone(), material))
                    .map_err(|e| format!("building {kind} failed: {e}"));
                let _ = tx.send(r);
            });
        match spawned {
            Ok(_) => self.building = Some(rx),
            Err(e) => self
                .hub
                .notify("error", &format!("cannot start a build: {e}")),
        }
    }

    /// Swaps in a finished build; true when the simulation changed.
    fn poll_build(&mut self) -> bool {
        let Some(rx) = &self.building else {
            return false;
        };
        let result = match rx.try_recv() {
            Ok(r) => r,
            Err(TryRecvError::Empty) => return false,
            Err(TryRecvError::Disconnected) => Err("the build thread stopped".into()),
        };
        self.building = None;
        match result {
            Ok((sim, kind, material)) => {
                self.drop_tools(&format!("switching to {kind}"));
                self.sim = sim;
                self.kind = kind;
                self.material = material;
                self.dt = self.setup.scene.run.dt;
                self.substeps = 0;
                self.failure = None;
                self.told.clear();
                self.slow = SlowMotion::default();
                self.publish_init();
                let took = lock(&self.build_status)
                    .started
                    .map_or(0.0, |t| t.elapsed().as_secs_f64());
                self.hub.notify(
                    "info",
                    &format!(
                        "now running {} (E = {} Pa, nu = {}, dt {:.3e} s; built in {took:.1} s)",
                        self.kind, material.young_modulus, material.poisson_ratio, self.dt
                    ),
                );
                self.tell_notices();
                true
            }
            Err(e) => {
                self.hub.notify("error", &e);
                false
            }
        }
    }

    fn step_once(&mut self) {
        if let Some(job) = &mut self.cut
            && let Some(tip) = job.remaining.pop_front()
            && let Some(i) = self
                .sim
                .instruments()
                .iter()
                .position(|x| x.name == SCALPEL)
        {
            let _ = self.sim.set_instrument_position(i, Some(tip));
        }
        let reach = MAX_TOOL_SPEED * self.dt;
        if let (Some(p), Some(i)) = (self.grasp, self.index_of(GRASPER)) {
            let now = self.sim.instruments()[i].position();
            let _ = self
                .sim
                .set_instrument_position(i, Some(approach(now, p, reach)));
        }
        if let Some(goal) = self.probe_goal {
            let pose = self.handle.pose();
            self.handle.set_pose(Pose {
                position: approach(pose.position, goal, reach),
                ..pose
            });
        }
        let before = (
            self.sim.model().surface().triangles.len(),
            self.sim.topology_version(),
        );
        let stepping = Instant::now();
        match step_coupled(&mut self.sim, 0, &self.handle, self.dt) {
            Ok(report) => {
                // Only the page's presses: a device drives the handle with no press to delimit.
                if self.probe_goal.is_some() {
                    let f = report.forces.first().map_or(0.0, |f| f.length());
                    self.press_peak = self.press_peak.max(f);
                }
                self.steps_in_window += 1;
                self.step_seconds_in_window += stepping.elapsed().as_secs_f64();
                self.substeps = report.info.substeps;
                // The step after the scalpel left: a model that opens a stroke when the
                // blade goes (bem) has opened it, or started computing it off the thread.
                if std::mem::take(&mut self.cut_ending) {
                    if self.sim.model().background().is_some() {
                        self.incision_pending = Some(Instant::now());
                        self.hub.notify(
                            "info",
                            "the blade's path is done; the incision is computed in the \
                             background while the simulation goes on",
                        );
                    } else {
                        self.hub.notify("info", "the cut is done");
                    }
                    // A cut can change what the model is (`hybrid`: its region grows).
                    self.tell_notices();
                }
                if self.cut.as_ref().is_some_and(|j| j.remaining.is_empty()) {
                    self.finish_cut();
                }
                let after = (
                    self.sim.model().surface().triangles.len(),
                    self.sim.topology_version(),
                );
                if after != before {
                    self.publish_init();
                }
                if let Some(since) = self.incision_pending
                    && self.sim.model().background().is_none()
                {
                    self.incision_pending = None;
                    let opened = if after != before {
                        "the incision is open"
                    } else {
                        "the blade opened no groove"
                    };
                    self.hub.notify(
                        "info",
                        &format!(
                            "the cut is done: {opened}, {:.1} s after the blade's path ended",
                            since.elapsed().as_secs_f64()
                        ),
                    );
                }
            }
            Err(e) => {
                // The step that opened a held stroke, or swapped in an incision computed
                // off the thread, failed because of it.
                let incising = std::mem::take(&mut self.cut_ending)
                    || (self.incision_pending.is_some() && self.sim.model().background().is_none());
                if incising
                    && !matches!(e, SimError::Diverged { .. } | SimError::Implausible { .. })
                {
                    self.incision_pending = None;
                    self.hub.notify("error", &format!("cutting failed: {e}"));
                } else {
                    self.step_failed(e);
                }
            }
        }
    }

    /// The blade's path is swept: the scalpel goes; the next step says what came of it.
    fn finish_cut(&mut self) {
        self.cut = None;
        if let Some(i) = self.index_of(SCALPEL) {
            self.sim.remove_instrument(i);
        }
        self.cut_ending = true;
    }

    /// Says each of the model's notices (`ModelInfo::notices`) once: after a build and after
    /// a cut, the moments they can appear.
    fn tell_notices(&mut self) {
        let info = self.sim.model().info();
        for notice in info.notices() {
            if !self.told.iter().any(|t| t == notice) {
                self.hub.notify("info", notice);
                self.told.push(notice.to_string());
            }
        }
    }

    fn step_failed(&mut self, e: SimError) {
        if self.cut.is_some() {
            self.cut = None;
            if let Some(i) = self.index_of(SCALPEL) {
                self.sim.remove_instrument(i);
            }
            let msg = match &e {
                SimError::Unsupported { .. } => format!("{} cannot cut: {e}", self.kind),
                _ => format!("cutting failed: {e}"),
            };
            return self.hub.notify("error", &msg);
        }
        if matches!(e, SimError::Diverged { .. } | SimError::Implausible { .. }) {
            return self.blew_up(e);
        }
        // The same failure every step would flood the log: say it once a second.
        let text = e.to_string();
        let repeat = self
            .last_error
            .as_ref()
            .is_some_and(|(t, at)| *t == text && at.elapsed() < Duration::from_secs(1));
        if !repeat {
            self.hub.notify("error", &format!("step failed: {text}"));
            self.last_error = Some((text, Instant::now()));
        }
    }

    /// A step diverged or left the plausible range. The simulation kept its last good state,
    /// but that state is what led here: go back to rest (plausible by construction), let go
    /// of the grasp that was pulling, and tell the haptic loop there is no contact, so no
    /// force from the failing state reaches the page or the device. Said once; failures
    /// within the next few seconds are counted into one follow-up line.
    fn blew_up(&mut self, e: SimError) {
        self.handle.clear_contact();
        self.grasp = None;
        if let Some(i) = self.index_of(GRASPER) {
            self.sim.remove_instrument(i);
        }
        self.sim.model_mut().reset();
        // Models with a published stability limit below the step get it; models that
        // substep on their own (substeps > 0) already take a step they can.
        if self.substeps == 0 {
            let critical = self
                .sim
                .model()
                .info()
                .details
                .iter()
                .find(|(k, _)| k == "critical_dt")
                .and_then(|(_, v)| v.parse::<Real>().ok())
                .filter(|c| c.is_finite() && *c > 0.0 && *c < self.dt);
            if let Some(c) = critical {
                self.dt = 0.9 * c;
            }
        }
        match &mut self.failure {
            Some(f) if f.at.elapsed() < QUIET_AFTER_FAILURE => {
                f.more += 1;
                return;
            }
            _ => {}
        }
        let earlier = self.failure.take().map_or(0, |f| f.more);
        let tail = if earlier > 0 {
            format!(" ({earlier} more failures after the previous report)")
        } else {
            String::new()
        };
        self.failure = Some(Failure {
            at: Instant::now(),
            more: 0,
        });
        self.hub.notify(
            "error",
            &format!(
                "{} blew up: {e}; restored the rest state and released the grasp (dt {:.3e} s){tail}",
                self.kind, self.dt
            ),
        );
    }

    /// Says once per model when its steps take longer than the time they cover
    /// (`SlowMotion`): the page then shows the organ in slow motion (the session drops the
    /// backlog rather than chase it), and the user should know why and what to change.
    fn watch_slow_motion(&mut self) {
        let seconds = self.step_seconds_in_window;
        let steps = self.steps_in_window;
        let building = self.building.is_some();
        if let Some(cost) = self.slow.observe(steps, seconds, self.dt, building) {
            self.hub.notify(
                "info",
                &format!(
                    "{} needs {:.1} ms per {:.1} ms step on this machine: the organ moves at \
                     about {:.0} % of real time. A larger dt, a coarser mesh or a faster kind \
                     keeps up (`tissue compare` lists every kind's cost)",
                    self.kind,
                    cost * 1e3,
                    self.dt * 1e3,
                    100.0 * self.dt / cost
                ),
            );
        }
    }

    fn publish_init(&mut self) {
        self.strain_nodes = tissue::metrics::surface_nodes(self.sim.model());
        let msg = publish::init_message(&self.sim, &self.setup, &self.kind, self.material, self.dt);
        self.hub.set_init(msg);
    }

    fn publish_frame(&mut self) {
        let secs = self.window_start.elapsed().as_secs_f64();
        if secs >= 0.5 {
            self.sim_rate = self.steps_in_window as Real / secs;
            self.watch_slow_motion();
            self.steps_in_window = 0;
            self.step_seconds_in_window = 0.0;
            self.window_start = Instant::now();
        }
        let figures = publish::Figures {
            dt: self.dt,
            sim_rate: self.sim_rate,
            haptic: self.handle.stats(),
            haptic_force: self.handle.latest().force,
            probe_active: self.handle.pose().position != self.setup.park,
            press_peak: self.press_peak,
            kind: &self.kind,
            substeps: self.substeps,
            strain_nodes: self.strain_nodes.as_deref(),
            building: self
                .building
                .is_some()
                .then(|| lock(&self.build_status).clone()),
            cut: self
                .cut
                .as_ref()
                .map(|c| (c.total - c.remaining.len(), c.total)),
            background: self.sim.model().background(),
        };
        self.hub.set_frame(publish::frame_message(
            &self.sim,
            &figures,
            [PROBE, GRASPER, SCALPEL],
        ));
    }
}

/// The fastest the viewer's instruments move in simulated time, m/s. The page sends the
/// pointer's position at its frame rate, in wall time. Applied as it came, each message was
/// a jump within one step (0.375 mm in one 50 µs step on `liver-spring-mass`: 7.5 m/s),
/// and in a model slower than real time the page's 0.4 s press took a few ms of its time.
/// Vertices held by a probe slammed that fast flew off it: `simplex-spring-mass` there was
/// dented 13 mm by a 5 mm press and felt 0 N with no vertex in contact. Hands move
/// instruments in tissue at centimetres per second, so in real time this is not felt.
pub const MAX_TOOL_SPEED: Real = 0.1;

/// `from` moved toward `to` by at most `reach`.
fn approach(from: Vec3, to: Vec3, reach: Real) -> Vec3 {
    let d = to - from;
    let len = d.length();
    // A remainder within rounding of the reach lands (it would be a step of 1e-19 m).
    if len <= reach * (1.0 + 1e-9) {
        to
    } else {
        from + d * (reach / len)
    }
}

/// Whether a model keeps up with real time, watched over the rate windows (0.5 s each).
#[derive(Clone, Debug, Default)]
struct SlowMotion {
    /// Consecutive windows whose steps took longer than their dt.
    windows: u32,
    /// Already said for this model.
    told: bool,
}

impl SlowMotion {
    /// One window: `steps` successful steps took `seconds`. Returns the mean step time, in
    /// s, the first time it has exceeded `dt` for `SLOW_WINDOWS` windows in a row. Failed
    /// steps (they have their own notices), windows without steps and a model being built
    /// alongside (it takes a core) do not count.
    fn observe(&mut self, steps: u64, seconds: Real, dt: Real, building: bool) -> Option<Real> {
        if steps == 0 {
            return None;
        }
        let cost = seconds / steps as Real;
        if cost <= dt || building {
            self.windows = 0;
            return None;
        }
        self.windows += 1;
        (self.windows >= SLOW_WINDOWS && !std::mem::replace(&mut self.told, true)).then_some(cost)
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

#[cfg(test)]
mod slow_motion_tests {
    use super::*;

    #[test]
    fn slow_motion_is_said_once_after_a_run_of_slow_windows() {
        let mut s = SlowMotion::default();
        // 10 ms steps taking 25 ms: said at the fourth window, then never again.
        let said: Vec<_> = (0..8).map(|_| s.observe(20, 0.5, 0.01, false)).collect();
        assert_eq!(said.iter().filter(|c| c.is_some()).count(), 1);
        assert_eq!(said[SLOW_WINDOWS as usize - 1], Some(0.025));
        // A fast window, or a slow one with a build alongside, breaks the run; a window
        // without steps (a failing model) neither counts nor breaks it.
        let mut s = SlowMotion::default();
        for (steps, seconds, building) in [(200, 0.05, false), (20, 0.5, true)] {
            for _ in 0..SLOW_WINDOWS - 1 {
                assert_eq!(s.observe(20, 0.5, 0.01, false), None);
            }
            assert_eq!(s.observe(steps, seconds, 0.01, building), None);
        }
        assert_eq!(s.observe(0, 0.5, 0.01, false), None);
        assert_eq!(s.windows, 0);
    }
}

#[cfg(test)]
mod tool_speed_tests {
    use super::*;

    #[test]
    fn an_instrument_approaches_its_goal_at_the_speed_limit_and_lands_on_it() {
        let (from, to) = (Vec3::ZERO, Vec3::new(0.003, 0.004, 0.0));
        let reach = MAX_TOOL_SPEED * 5e-5;
        let mut at = from;
        let mut steps = 0;
        while at != to {
            let next = approach(at, to, reach);
            assert!(next.distance(at) <= reach * (1.0 + 1e-9));
            at = next;
            steps += 1;
        }
        // 5 mm at 0.1 m/s is 50 ms: 1000 steps of 50 µs, the last one landing exactly.
        assert_eq!(steps, 1000);
        assert_eq!(approach(to, to, reach), to);
    }
}

#[cfg(test)]
mod press_peak_tests {
    use super::*;
    use tissue::scene::Scene;

    /// The viewer's press on the demo liver switched to `spring-mass`, driven as the page
    /// drives it (the points a page sent: the first a third of the way in, then the probe's
    /// centre on the rest surface, one radius deep). The bendless membrane pushes back ~1 mN
    /// while the probe goes in, then the vertex under it pops through its ring to its
    /// mirror image (the same spring lengths) and the probe hangs in the dent touching it
    /// in bursts: most steps read 0 N. The frames carry the press's peak, which says the
    /// press reached the model whatever instants the page happens to draw.
    #[test]
    fn a_press_on_the_spring_mass_liver_keeps_its_peak_past_the_dent() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/liver-probe.toml");
        let scene = Scene::load(path).unwrap_or_else(|e| panic!("{e}"));
        let (mut setup, material) = Setup::load(&scene).unwrap_or_else(|e| panic!("{e}"));
        setup.scene.model_kind = "spring-mass".into();
        let hub = Arc::new(Hub::default());
        let mut s =
            Session::new(setup, material, Arc::clone(&hub), None).unwrap_or_else(|e| panic!("{e}"));
        let first = Vec3::new(-0.001_504, 0.040_135, 0.027_232);
        let deep = Vec3::new(-0.002_129, 0.037_918, 0.023_085);
        s.apply(Command::Probe(Some(first)));
        s.apply(Command::Probe(Some(deep)));
        let mut zero_steps = 0;
        let steps = (2.0 / s.dt).round() as usize;
        for _ in 0..steps {
            s.step_once();
            let f = s.sim.instruments()[0].force().length();
            zero_steps += usize::from(f == 0.0);
        }
        eprintln!(
            "spring-mass press: peak {:.3e} N, {zero_steps} of {steps} steps at 0 N",
            s.press_peak
        );
        assert!(
            s.press_peak > 1e-4 && s.press_peak < 0.02,
            "{}",
            s.press_peak
        );
        assert!(
            2 * zero_steps > steps,
            "{zero_steps} of {steps} steps at 0 N"
        );
        s.publish_frame();
        let frame: serde_json::Value =
            serde_json::from_str(&hub.frame().text).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(frame["press_peak"].as_f64(), Some(s.press_peak));
        // Letting go parks the probe and forgets the peak; the next press starts from 0.
        s.apply(Command::Probe(None));
        assert_eq!(s.press_peak, 0.0);
    }
}
