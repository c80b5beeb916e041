//! `tissue haptic-bench SCENE`: drives the 1 kHz haptic loop with the scripted device
//! emulator over the UDP bridge while the scene's model runs in real time, and prints the
//! loop's timing: rate_hz, p50_us, p99_us, missed_deadlines, max_force.

use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::Args;
use serde::Serialize;
use tissue::Real;
use tissue::haptic::{HapticConfig, HapticLoop, Pose, UdpBridge, run_coupled, run_emulator};
use tissue::interact::InstrumentKind;
use tissue::scene::Scene;

#[derive(Args, Debug)]
pub struct HapticBenchArgs {
    /// The scene file (TOML); its first probe (or first instrument) is the haptic tool and
    /// its scripted path, played back and forth, is what the emulated hand does.
    pub scene: PathBuf,
    /// How long to run, in s.
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
    /// Loop rate, in Hz.
    #[arg(long, default_value_t = 1000.0)]
    pub rate: f64,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct BenchOutput {
    scene: String,
    model: &'static str,
    seconds: Real,
    rate_hz: Real,
    p50_us: Real,
    p99_us: Real,
    max_us: Real,
    ticks: u64,
    missed_deadlines: u64,
    max_force: Real,
    realtime_priority: bool,
    sim_updates_hz: Real,
    sim_errors: u64,
    device_round_trip_p50_us: Real,
    device_round_trip_p99_us: Real,
    device_forces_received: u64,
}

pub fn haptic_bench(args: &HapticBenchArgs) -> anyhow::Result<()> {
    if !(args.seconds.is_finite() && args.seconds > 0.0 && args.seconds <= 3600.0) {
        bail!("--seconds {}: must be in (0, 3600]", args.seconds);
    }
    let scene = Scene::load(&args.scene)?;
    let mut sim = scene.build()?;
    let index = sim
        .instruments()
        .iter()
        .position(|i| *i.kind() == InstrumentKind::Probe)
        .or(if sim.instruments().is_empty() {
            None
        } else {
            Some(0)
        })
        .with_context(|| format!("{}: the scene has no instrument", args.scene.display()))?;
    let trajectory = sim.instruments()[index].trajectory().clone();
    let span = trajectory
        .keys()
        .last()
        .map_or(0.0, |k| k.t)
        .max(scene.run.duration);
    // Back and forth along the scripted path: press in, come out, again.
    let path = move |t: Real| {
        let tau = if span > 0.0 { t % (2.0 * span) } else { 0.0 };
        trajectory.position(if tau <= span { tau } else { 2.0 * span - tau })
    };

    let lp = HapticLoop::start(HapticConfig {
        rate_hz: args.rate,
        ..HapticConfig::default()
    })?;
    let handle = lp.handle();
    handle.set_pose(Pose {
        position: path(0.0),
        ..Pose::default()
    });
    let bridge = UdpBridge::start(([127, 0, 0, 1], 0).into(), handle.clone())?;
    let target = bridge.local_addr();
    let (seconds, rate) = (args.seconds, args.rate);
    let device = std::thread::spawn(move || run_emulator(target, seconds, rate, &path));
    let coupling = run_coupled(&mut sim, index, &handle, scene.run.dt, seconds);
    let device = device
        .join()
        .map_err(|_| anyhow::anyhow!("the emulator thread panicked"))??;
    bridge.stop();
    let max_force = handle.max_force();
    let realtime_priority = handle.is_realtime();
    let stats = lp.stop();

    let out = BenchOutput {
        scene: args.scene.display().to_string(),
        model: sim.model().kind(),
        seconds,
        rate_hz: stats.rate_hz,
        p50_us: stats.p50_us,
        p99_us: stats.p99_us,
        max_us: stats.max_us,
        ticks: stats.ticks,
        missed_deadlines: stats.missed_deadlines,
        max_force,
        realtime_priority,
        sim_updates_hz: coupling.update_rate_hz,
        sim_errors: coupling.errors,
        device_round_trip_p50_us: device.round_trip.p50_us,
        device_round_trip_p99_us: device.round_trip.p99_us,
        device_forces_received: device.forces_received,
    };
    if args.json {
        crate::outln!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        crate::outln!(
            "haptic-bench {} ({}), {:.1} s",
            out.scene,
            out.model,
            seconds
        );
        crate::outln!("  rate_hz            {:.1}", out.rate_hz);
        crate::outln!("  p50_us             {:.0}", out.p50_us);
        crate::outln!("  p99_us             {:.0}", out.p99_us);
        crate::outln!(
            "  missed_deadlines   {} of {} ({:.3} %)",
            out.missed_deadlines,
            out.ticks,
            100.0 * out.missed_deadlines as Real / (out.ticks.max(1)) as Real
        );
        crate::outln!("  max_force          {:.4} N", out.max_force);
        crate::outln!("  realtime priority  {}", out.realtime_priority);
        crate::outln!("  sim updates        {:.1} /s", out.sim_updates_hz);
        crate::outln!(
            "  device round trip  p50 {:.0} us, p99 {:.0} us ({} forces)",
            out.device_round_trip_p50_us,
            out.device_round_trip_p99_us,
            out.device_forces_received
        );
    }
    if let Some(e) = coupling.last_error {
        eprintln!(
            "warning: {} simulation steps failed; last: {e}",
            coupling.errors
        );
    }
    Ok(())
}
