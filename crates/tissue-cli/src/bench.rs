//! `tissue bench beam`: the benchmark of record (issue 24). Runs the clamped beam
//! (`tissue::benchmark::beam`) for every dynamic kind at its defaults on the named sizes and
//! prints, per kind and mesh, the cost of one simulated millisecond, the settled tip against
//! P1 (`fem-static` on the same mesh), the oscillation left, substeps and capped steps.

use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use tissue::Real;
use tissue::benchmark::beam::{self, BeamCase, BeamSpec};

#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// The clamped beam under gravity (1 m × 0.1 × 0.1 m, E = 1e8 Pa, ν = 0.3, β = 0.02 s,
    /// dt = 1 ms, 1 s): cost per simulated ms and settled tip against fem-static's P1.
    Beam(BeamArgs),
}

#[derive(Args, Debug)]
pub struct BeamArgs {
    /// Meshes, by name: 1k, 5k, 20k, 80k (1,080 / 4,800 / 19,200 / 81,120 tetrahedra).
    #[arg(long, value_delimiter = ',', default_value = "1k,5k,20k")]
    pub sizes: Vec<String>,
    /// Model kinds (default: every dynamic kind).
    #[arg(long, value_delimiter = ',')]
    pub kinds: Vec<String>,
    /// Worker threads for the models' parallel loops (default: one per core). Several counts
    /// (`--threads 1,2`) run each case once per count, taking turns by slices (`--slice`),
    /// and print each later count's speed-up over the first, slice by slice: the way to
    /// compare thread counts on a machine whose speed drifts.
    #[arg(long, value_delimiter = ',')]
    pub threads: Vec<usize>,
    /// With several `--threads`: simulated time of one slice, in s.
    #[arg(long, default_value_t = 0.05)]
    pub slice: Real,
    /// A `[model]` setting passed to every kind, as key=value in TOML (e.g.
    /// `cg_tolerance=1e-5`); repeatable. Kinds that do not know the key refuse it.
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,
    /// Simulated time, in s.
    #[arg(long, default_value_t = 1.0)]
    pub duration: Real,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

pub fn bench(cmd: &BenchCommand) -> anyhow::Result<()> {
    match cmd {
        BenchCommand::Beam(args) => beam_bench(args),
    }
}

#[derive(serde::Serialize)]
struct SizeRun {
    size: String,
    tets: usize,
    p1_tip: Real,
    cases: Vec<BeamCase>,
    /// With several `--threads`: each kind's runs and their slice-by-slice speed-ups.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    interleaved: Vec<beam::Interleaved>,
}

fn beam_bench(args: &BeamArgs) -> anyhow::Result<()> {
    if !(args.duration.is_finite() && args.duration > 0.0 && args.duration <= 100.0) {
        bail!("--duration {}: must be in (0, 100] s", args.duration);
    }
    let params = beam::params_from_lines(&args.params)?;
    let sizes = args
        .sizes
        .iter()
        .map(|s| {
            beam::size_cells(s)
                .map(|c| (s.clone(), c))
                .with_context(|| {
                    let known: Vec<&str> = beam::SIZES.iter().map(|(n, _)| *n).collect();
                    format!("--sizes: unknown size {s:?} (known: {})", known.join(", "))
                })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let kinds: Vec<String> = if args.kinds.is_empty() {
        beam::DYNAMIC_KINDS.iter().map(|k| k.to_string()).collect()
    } else {
        args.kinds.clone()
    };
    if args.threads.contains(&0) {
        bail!("--threads: counts must be at least 1");
    }
    let steps_per_slice = (args.slice / 1e-3).round();
    if args.threads.len() > 1 && !(steps_per_slice >= 1.0 && args.slice <= args.duration) {
        bail!(
            "--slice {}: must be at least one 1 ms step and at most --duration {} s",
            args.slice,
            args.duration
        );
    }
    let threads = match args.threads.as_slice() {
        [] => None,
        [n] => Some(*n),
        _ => None,
    };
    let interleave = args.threads.len() > 1;
    if !args.json {
        crate::outln!(
            "clamped beam, dt = 1 ms, {} s simulated, threads: {}; cost = wall (process CPU) \
             ms per simulated ms; tip/P1 = settled tip over fem-static's; osc = half the tip's \
             range over the last 0.1 s / |P1|",
            args.duration,
            match args.threads.as_slice() {
                [] => "one per core".to_string(),
                [n] => n.to_string(),
                many => format!(
                    "{} in turn, slices of {} s",
                    many.iter()
                        .map(|n| n.to_string())
                        .collect::<Vec<_>>()
                        .join(", "),
                    args.slice
                ),
            },
        );
    }
    let mut runs = Vec::new();
    for (name, cells) in sizes {
        let mut spec = BeamSpec::new(cells);
        spec.duration = args.duration;
        let mesh = spec.mesh();
        let p1 =
            beam::p1_tip(&spec, &mesh).with_context(|| format!("fem-static on the {name} beam"))?;
        if !args.json {
            crate::outln!(
                "\n{name}: {} tets, {} nodes, P1 tip {p1:.5e} m",
                mesh.tets.len(),
                mesh.vertices.len()
            );
            crate::outln!(
                "{:<24} {:>9} {:>9} {:>8} {:>9} {:>5} {:>7} {:>9} {:>6}",
                "kind",
                "wall",
                "cpu",
                "tip/P1",
                "osc",
                "sub",
                "capped",
                "resid",
                "iters"
            );
        }
        let mut cases = Vec::new();
        let mut interleaved = Vec::new();
        for kind in interleave.then_some(&kinds).into_iter().flatten() {
            let run = beam::run_interleaved(
                kind,
                &spec,
                &mesh,
                &params,
                p1,
                &args.threads,
                steps_per_slice as usize,
            )?;
            if !args.json {
                for (n, case) in run.threads.iter().zip(&run.cases) {
                    let mut row = case.clone();
                    row.kind = format!("{} ×{n}", case.kind);
                    print_row(&row)?;
                }
                for (k, n) in run.threads.iter().enumerate().skip(1) {
                    if let Some([q1, median, q3]) = run.speedup_quartiles(k - 1) {
                        crate::outln!(
                            "{:<24} ×{n} over ×{}: median {median:.3} (quartiles {q1:.3}, {q3:.3}) \
                             over {} slice pairs",
                            "",
                            run.threads[0],
                            run.speedups[k - 1].len()
                        );
                    }
                }
            }
            interleaved.push(run);
        }
        for kind in (!interleave).then_some(&kinds).into_iter().flatten() {
            let case = tissue::benchmark::with_threads(threads, || {
                beam::run_case(kind, &spec, &mesh, &params, p1)
            })?;
            if !args.json {
                print_row(&case)?;
            }
            cases.push(case);
        }
        runs.push(SizeRun {
            size: name,
            tets: mesh.tets.len(),
            p1_tip: p1,
            cases,
            interleaved,
        });
    }
    if args.json {
        crate::outln!("{}", serde_json::to_string_pretty(&runs)?);
    }
    Ok(())
}

fn print_row(c: &BeamCase) -> anyhow::Result<()> {
    if c.steps > 0 {
        crate::outln!(
            "{:<24} {:>9.3} {:>9.3} {:>8.4} {:>9.2e} {:>5} {:>7} {:>9.1e} {:>6.1}",
            c.kind,
            c.wall_ms_per_ms,
            c.cpu_ms_per_ms,
            c.tip_ratio,
            c.oscillation,
            c.max_substeps,
            c.capped_steps,
            c.worst_residual,
            c.mean_iterations
        );
    }
    if let Some(e) = &c.error {
        crate::outln!("{:<24} cannot: {e}", c.kind);
    }
    Ok(())
}
