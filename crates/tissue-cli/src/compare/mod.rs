//! `tissue compare`: every model kind on one organ, measured (the library's
//! `tissue::compare`), scored against the survey's Table 1, written as JSON, Markdown, HTML
//! and plots. Results are cached per kind by a hash of their inputs, so an interrupted run
//! resumes where it stopped.

mod plots;
mod table;

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use tissue::Material;
use tissue::compare::{
    CompareRecord, KindRecord, Organ, Reference, Scenario, Settings, measure_kind, reference,
    score_kind,
};
use tissue::io::{Format, parse};
use tissue::scene::Scene;

#[derive(Args, Debug)]
pub struct CompareArgs {
    /// A scene (.toml: its mesh, scale and material) or a mesh file (surface or
    /// tetrahedra); the built-in liver when omitted.
    pub organ: Option<PathBuf>,
    /// Only these kinds (comma-separated); all of `tissue models` by default.
    #[arg(long, value_delimiter = ',')]
    pub models: Option<Vec<String>>,
    /// Output directory (created if missing; holds the cache).
    #[arg(long, short, default_value = "compare-out")]
    pub out: PathBuf,
    /// CI's run: coarse and short scenarios (within 3 minutes on 2 cores).
    #[arg(long)]
    pub quick: bool,
    /// Kinds measured at once.
    #[arg(long, short, default_value_t = 2)]
    pub jobs: usize,
    /// Scale of a mesh file's coordinates to metres (a scene has its own).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Young's modulus (Pa) and Poisson ratio for a mesh file (a scene has its own).
    #[arg(long, default_value_t = 3000.0)]
    pub young_modulus: f64,
    #[arg(long, default_value_t = 0.3)]
    pub poisson_ratio: f64,
    /// No progress bars.
    #[arg(long, short)]
    pub quiet: bool,
}

const LIVER: &[u8] = include_bytes!("../../../../assets/meshes/liver.msh");

fn load_organ(args: &CompareArgs, settings: &Settings) -> anyhow::Result<Organ> {
    let t = Instant::now();
    let material = Material::new(args.young_modulus, args.poisson_ratio)?;
    let (mesh, name, material) = match &args.organ {
        None => {
            let mut mesh = parse(Format::Msh, LIVER, Path::new("liver.msh"))?;
            for v in &mut mesh.vertices {
                *v *= 0.01; // centimetres
            }
            (mesh, "liver.msh (built in)".to_string(), material)
        }
        Some(p) if p.extension().is_some_and(|e| e == "toml") => {
            let scene = Scene::load(p)?;
            let body = scene.load_body()?;
            let material = scene.material_for(&body)?;
            (body.mesh, body.source, material)
        }
        Some(p) => {
            let mut mesh = tissue::io::read(p)?;
            for v in &mut mesh.vertices {
                *v *= args.scale;
            }
            (mesh, p.display().to_string(), material)
        }
    };
    let read_seconds = t.elapsed().as_secs_f64();
    Ok(Organ::new(
        mesh,
        name,
        material,
        read_seconds,
        settings.surface_tets,
    )?)
}

/// A kind's cache key: the shared inputs and the kind with its probe's contact law (every
/// kind's: frictionless on the fine contact surface) and the fine surface's rule (its edge
/// in probe radii): a record cached under another rule is measured again.
fn kind_key(kind: &str, base: u64) -> u64 {
    use tissue::compare::drive::{ContactLaw, FINE_EDGE_PER_RADIUS};
    let law = ContactLaw::FineSurface.name();
    let rule = format!("fine edge {FINE_EDGE_PER_RADIUS:e} of the radius");
    fnv(
        rule.as_bytes(),
        fnv(law.as_bytes(), fnv(kind.as_bytes(), base)),
    )
}

/// FNV-1a: a stable hash of a kind's inputs for the cache.
fn fnv(bytes: &[u8], mut h: u64) -> u64 {
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x100_0000_01b3);
    }
    h
}

pub fn compare(args: &CompareArgs) -> anyhow::Result<()> {
    let start = Instant::now();
    let settings = if args.quick {
        Settings::quick()
    } else {
        Settings::full()
    };
    let organ = load_organ(args, &settings)?;
    let scenario = Scenario::of(&organ.mesh)?;
    let kinds: Vec<String> = match &args.models {
        Some(m) => {
            for k in m {
                anyhow::ensure!(
                    tissue::model::KINDS.iter().any(|x| x.name == k),
                    "unknown model kind `{k}`; see `tissue models`"
                );
            }
            m.clone()
        }
        None => tissue::model::KINDS
            .iter()
            .map(|k| k.name.to_string())
            .collect(),
    };
    std::fs::create_dir_all(args.out.join("cache"))
        .with_context(|| format!("creating {}", args.out.display()))?;

    let multi = MultiProgress::new();
    if args.quiet {
        multi.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    let style = ProgressStyle::with_template("{spinner} {prefix:26} {elapsed:>4} {wide_msg}")
        .unwrap_or_else(|_| ProgressStyle::default_spinner());
    let overall = multi.add(ProgressBar::new(kinds.len() as u64));
    overall.set_style(
        ProgressStyle::with_template("{prefix:26} [{bar:30}] {pos}/{len} kinds {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    overall.set_prefix("tissue compare");

    // The cache key: everything the reference and a kind's measurements depend on. The
    // reference is a function of these too, so it is cached under the same key.
    let base = {
        let mut h = fnv(env!("CARGO_PKG_VERSION").as_bytes(), 0xcbf2_9ce4_8422_2325);
        h = fnv(serde_json::to_string(&settings)?.as_bytes(), h);
        // The reference's contact law (a kind's own is in its key below).
        h = fnv(b"frictionless reference, all surface nodes", h);
        h = fnv(serde_json::to_string(&scenario)?.as_bytes(), h);
        h = fnv(format!("{:?}", organ.material).as_bytes(), h);
        h = fnv(
            format!("{:?}{:?}", organ.mesh.vertices, organ.mesh.tets).as_bytes(),
            h,
        );
        h
    };

    let rbar = multi.add(ProgressBar::new_spinner());
    rbar.set_style(style.clone());
    rbar.set_prefix("reference");
    rbar.enable_steady_tick(std::time::Duration::from_millis(200));
    let ref_file = args
        .out
        .join("cache")
        .join(format!("reference-{base:016x}.json"));
    let cached = std::fs::read_to_string(&ref_file)
        .ok()
        .and_then(|t| Reference::from_json(&t).ok());
    let reference = match cached {
        Some(r) => r,
        None => {
            let r = reference(&organ, &scenario, &settings, &|s| {
                rbar.set_message(s.to_string())
            })
            .context("computing the reference (quadratic fem-static)")?;
            if let Ok(t) = r.to_json() {
                let _ = std::fs::write(&ref_file, t);
            }
            r
        }
    };
    rbar.finish_with_message(format!(
        "done: probe force {:.4e} N, convergence {:.2} %",
        reference.force_shallow,
        100.0 * reference.record.convergence
    ));

    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<KindRecord>>> = Mutex::new(vec![None; kinds.len()]);
    std::thread::scope(|s| {
        for _ in 0..args.jobs.max(1) {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::SeqCst);
                    let Some(kind) = kinds.get(i) else { break };
                    let file = args
                        .out
                        .join("cache")
                        .join(format!("{kind}-{:016x}.json", kind_key(kind, base)));
                    let cached = std::fs::read_to_string(&file)
                        .ok()
                        .and_then(|t| serde_json::from_str::<KindRecord>(&t).ok());
                    let rec = match cached {
                        Some(r) => r,
                        None => {
                            let bar = multi.add(ProgressBar::new_spinner());
                            bar.set_style(style.clone());
                            bar.set_prefix(kind.clone());
                            bar.enable_steady_tick(std::time::Duration::from_millis(200));
                            let r = measure_kind(
                                kind,
                                &organ,
                                &scenario,
                                &reference,
                                &settings,
                                &|m| bar.set_message(m.to_string()),
                            );
                            bar.finish_and_clear();
                            multi.remove(&bar);
                            if let Ok(t) = serde_json::to_string_pretty(&r) {
                                let _ = std::fs::write(&file, t);
                            }
                            r
                        }
                    };
                    overall.inc(1);
                    if let Ok(mut v) = results.lock() {
                        v[i] = Some(rec);
                    }
                }
            });
        }
    });
    overall.finish();
    let kinds_rec: Vec<KindRecord> = results
        .into_inner()
        .map_err(|_| anyhow::anyhow!("a measuring thread failed"))?
        .into_iter()
        .flatten()
        .collect();
    let scores = kinds_rec
        .iter()
        .map(|r| score_kind(r, &scenario, &reference))
        .collect();
    let record = CompareRecord {
        version: env!("CARGO_PKG_VERSION").into(),
        command: std::env::args().collect::<Vec<_>>().join(" "),
        organ: organ.name.clone(),
        settings,
        scenario,
        reference: reference.record.clone(),
        kinds: kinds_rec,
        scores,
        wall_seconds: start.elapsed().as_secs_f64(),
    };
    write_outputs(&record, &args.out)?;
    crate::outln!(
        "tissue compare: {} kinds on {} in {:.1} s; outputs in {}",
        record.kinds.len(),
        record.organ,
        record.wall_seconds,
        args.out.display()
    );
    crate::outln!("{}", table::summary(&record));
    Ok(())
}

/// Writes compare.json, table1.md/html and the plots.
pub fn write_outputs(record: &CompareRecord, out: &Path) -> anyhow::Result<()> {
    let w = |name: &str, text: String| {
        std::fs::write(out.join(name), text).with_context(|| format!("writing {name}"))
    };
    w("compare.json", serde_json::to_string_pretty(record)?)?;
    w("table1.md", table::markdown(record))?;
    w("table1.html", table::html(record))?;
    plots::all(record, out)?;
    Ok(())
}
