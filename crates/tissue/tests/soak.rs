//! Soak: every shipped scene (one per model kind and more) driven by random instrument moves
//! through the live position the viewer and the haptic device use: small hand-like steps,
//! fast jumps, deep pushes into the body and moves that leave it and come back. Every
//! accepted step must have finite instrument forces within the plausibility bound; every
//! refused one must be a named error (the simulation keeps its last plausible step, and the
//! soak goes on from there with the next move). A panic fails the soak.
//!
//! The quick test takes a few steps per scene; the long one (ignored) takes `SOAK_STEPS`
//! (default 20000) per scene, a hundredth of that for static models, and stops a scene early
//! when its wall-time budget `SOAK_SECONDS` (default: none) is spent. `SOAK_THREADS` (default
//! one) scenes run at once; `SOAK_SCENES=a.toml,b.toml` soaks only those; `SOAK_VERBOSE=1`
//! prints every refusal. The run of record (docs/hardening.md):
//! `SOAK_STEPS=300000 SOAK_SECONDS=150 SOAK_THREADS=2 cargo test --release --workspace --test
//! soak a_long -- --ignored --nocapture`.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use tissue::Vec3;
use tissue::interact::plausibility::body_size;
use tissue::scene::Scene;

/// A small deterministic generator (64-bit LCG, top bits): the soak is reproducible.
struct Lcg(u64);

impl Lcg {
    fn unit(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    fn in_box(&mut self, lo: Vec3, hi: Vec3) -> Vec3 {
        Vec3::new(
            lo.x + (hi.x - lo.x) * self.unit(),
            lo.y + (hi.y - lo.y) * self.unit(),
            lo.z + (hi.z - lo.z) * self.unit(),
        )
    }
}

/// What a soak did.
#[derive(Default, Debug)]
struct Tally {
    steps: u64,
    refused: u64,
    /// Accepted steps with a non-finite or out-of-bound output, and panics.
    failures: Vec<String>,
    /// One example of each refusal, for the log.
    examples: Vec<String>,
}

fn scene_files() -> Vec<PathBuf> {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes"));
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    files.retain(|p| p.extension().is_some_and(|x| x == "toml"));
    files.sort();
    files
}

/// After this many refused steps in a row a scene is stuck and its soak ends (its last
/// plausible state is kept). Refusals spread over a run (a blade that leaves a fixed cut
/// region now and then) do not end it.
const STUCK_AFTER: u32 = 20;

fn soak_scene(
    file: &PathBuf,
    steps: &(dyn Fn(bool) -> u64 + Sync),
    budget: Option<Duration>,
    seed: u64,
    tally: &mut Tally,
) {
    let name = file.file_name().map(|n| n.to_string_lossy().into_owned());
    let name = name.unwrap_or_default();
    let built = Scene::load(file)
        .map_err(|e| e.to_string())
        .and_then(|s| Ok((s.build().map_err(|e| e.to_string())?, s)));
    let (mut sim, scene) = match built {
        Ok(x) => x,
        Err(e) => return tally.failures.push(format!("{name}: does not build: {e}")),
    };
    if sim.instruments().is_empty() {
        return;
    }
    // The budget is for stepping: a slow build (bem's) does not eat it.
    let started = Instant::now();
    let steps = steps(sim.model().info().is_static);
    let rest = sim.model().rest_surface().to_vec();
    let size = body_size(&rest);
    let (lo, hi) = rest.iter().fold(
        (Vec3::splat(f64::MAX), Vec3::splat(f64::MIN)),
        |(l, h), p| (l.min(*p), h.max(*p)),
    );
    // Out to a fifth of the body beyond its box: leaving and re-entering.
    let (out_lo, out_hi) = (lo - Vec3::splat(0.2 * size), hi + Vec3::splat(0.2 * size));
    let bound = sim.plausibility().max_force;
    let mut rng = Lcg(seed);
    let mut at = rng.in_box(out_lo, out_hi);
    let (mut refused_here, mut in_a_row) = (0u64, 0u32);
    for _ in 0..steps {
        if budget.is_some_and(|b| started.elapsed() > b) {
            break;
        }
        let r = rng.unit();
        at = if r < 0.05 {
            rng.in_box(out_lo, out_hi) // a fast jump anywhere, in or out
        } else if r < 0.1 {
            rng.in_box(lo, hi) // deep: straight into the body
        } else {
            // A hand's step: up to 2 % of the body per step.
            let d = rng.in_box(Vec3::splat(-1.0), Vec3::splat(1.0));
            (at + 0.02 * size * d).clamp(out_lo, out_hi)
        };
        let k = (rng.unit() * sim.instruments().len() as f64) as usize;
        let k = k.min(sim.instruments().len() - 1);
        if let Err(e) = sim.set_instrument_position(k, Some(at)) {
            tally
                .failures
                .push(format!("{name}: live position refused: {e}"));
            return;
        }
        tally.steps += 1;
        match sim.step(scene.run.dt) {
            Ok(report) => {
                in_a_row = 0;
                for f in &report.forces {
                    if !(f.is_finite() && f.length() <= bound) {
                        tally.failures.push(format!(
                            "{name}: step {} accepted force {f} (bound {bound:e})",
                            report.step
                        ));
                        return;
                    }
                }
            }
            Err(e) => {
                tally.refused += 1;
                refused_here += 1;
                in_a_row += 1;
                if refused_here == 1 {
                    tally.examples.push(format!("{name}: {e}"));
                }
                if std::env::var_os("SOAK_VERBOSE").is_some() {
                    eprintln!(
                        "{name}: move {} refused after {:.1} s: {e}",
                        tally.steps,
                        started.elapsed().as_secs_f64()
                    );
                }
                if in_a_row > STUCK_AFTER {
                    tally.examples.push(format!(
                        "{name}: stuck after {} refusals in a row, its soak ends",
                        STUCK_AFTER + 1
                    ));
                    return;
                }
                // The refused move is dropped: the next starts from a fresh place.
                at = rng.in_box(out_lo, out_hi);
            }
        }
    }
}

fn soak(steps: impl Fn(bool) -> u64 + Sync, budget: Option<Duration>, skip: &[&str]) -> Tally {
    // `SOAK_SCENES=a.toml,b.toml` soaks only those.
    let only: Option<Vec<String>> = std::env::var("SOAK_SCENES")
        .ok()
        .map(|s| s.split(',').map(str::to_owned).collect());
    let files: Vec<PathBuf> = scene_files()
        .into_iter()
        .filter(|f| !f.file_name().is_some_and(|n| skip.iter().any(|s| n == *s)))
        .filter(|f| {
            only.as_ref().is_none_or(|o| {
                f.file_name()
                    .is_some_and(|n| o.iter().any(|s| n == s.as_str()))
            })
        })
        .collect();
    let threads: usize = std::env::var("SOAK_THREADS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1usize)
        .max(1);
    let next = AtomicUsize::new(0);
    let total = Mutex::new(Tally::default());
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(file) = files.get(i) else { break };
                    let mut tally = Tally::default();
                    let started = Instant::now();
                    let run = catch_unwind(AssertUnwindSafe(|| {
                        soak_scene(file, &steps, budget, 0x5eed + i as u64, &mut tally)
                    }));
                    if run.is_err() {
                        tally.failures.push(format!("{}: panicked", file.display()));
                    }
                    eprintln!(
                        "{}: {} steps ({} refused) in {:.1} s",
                        file.file_name().unwrap_or_default().to_string_lossy(),
                        tally.steps,
                        tally.refused,
                        started.elapsed().as_secs_f64()
                    );
                    let mut t = total.lock().unwrap_or_else(|e| e.into_inner());
                    t.steps += tally.steps;
                    t.refused += tally.refused;
                    t.failures.append(&mut tally.failures);
                    t.examples.append(&mut tally.examples);
                }
            });
        }
    });
    let tally = total.into_inner().unwrap_or_else(|e| e.into_inner());
    eprintln!(
        "soak: {} steps, {} refused with a named error, {} failures",
        tally.steps,
        tally.refused,
        tally.failures.len()
    );
    for e in &tally.examples {
        eprintln!("  refused: {e}");
    }
    tally
}

#[test]
fn a_short_soak_of_every_scene() {
    let t = soak(
        |is_static| if is_static { 2 } else { 20 },
        None,
        &["liver-bem.toml"],
    );
    assert!(t.failures.is_empty(), "{:#?}", t.failures);
    assert!(t.steps > 100, "{t:?}");
}

#[test]
#[ignore = "long: SOAK_STEPS (default 20000) random moves per scene"]
fn a_long_soak_of_every_scene() {
    let n: u64 = std::env::var("SOAK_STEPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20_000);
    let budget = std::env::var("SOAK_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .map(Duration::from_secs_f64);
    let t = soak(|is_static| if is_static { n / 100 } else { n }, budget, &[]);
    assert!(t.failures.is_empty(), "{:#?}", t.failures);
}
