//! `tissue demo`: the liver scene built in (`scenes/liver-probe.toml` with the shipped
//! `liver.msh` and its smooth surface `liver-smooth.obj`), run and summarised; `--out` also writes the outputs, `--print-scene`
//! prints the scene file.

use std::path::Path;

use tissue::Real;
use tissue::io::{Format, parse};
use tissue::scene::Scene;

use crate::DemoArgs;
use crate::run::execute;

/// The scene `tissue run scenes/liver-probe.toml` runs; its meshes come from the binary.
const SCENE: &str = include_str!("../../../scenes/liver-probe.toml");
const LIVER: &[u8] = include_bytes!("../../../assets/meshes/liver.msh");
const LIVER_NAME: &str = "liver.msh (built in)";
/// The scene's `[mesh] visual`: the surface the probe touches.
const LIVER_SMOOTH: &[u8] = include_bytes!("../../../assets/meshes/liver-smooth.obj");
const LIVER_SMOOTH_NAME: &str = "liver-smooth.obj (built in)";

pub fn demo(args: &DemoArgs) -> anyhow::Result<()> {
    if args.print_scene {
        crate::out!("{SCENE}");
        return Ok(());
    }
    let scene = Scene::from_toml(
        SCENE,
        Path::new("scenes"),
        Path::new("liver-probe.toml (built in)"),
    )?;
    let mesh = parse(Format::Msh, LIVER, Path::new(LIVER_NAME))?;
    let smooth = parse(Format::Obj, LIVER_SMOOTH, Path::new(LIVER_SMOOTH_NAME))?;
    let sim = scene.build_with_meshes(mesh, LIVER_NAME, Some(smooth))?;
    let o = execute(&scene, sim, args.out.as_deref(), false)?;
    let change = 100.0 * (o.final_volume - o.initial_volume) / o.initial_volume;
    crate::outln!("tissue demo: a probe pressing 1 cm into a liver held at three ligament nodes");
    crate::outln!("  model              {}", o.model);
    crate::outln!(
        "  mesh               {} nodes, {} elements, {} surface vertices",
        o.nodes,
        o.elements,
        o.surface_vertices
    );
    crate::outln!(
        "  steps              {} in {:.3} s ({:.1} steps/s)",
        o.steps,
        o.wall_seconds,
        o.steps as Real / o.wall_seconds.max(1e-12)
    );
    crate::outln!("  max probe force    {:.4} N", o.max_instrument_force);
    crate::outln!("  max displacement   {:.3} mm", 1e3 * o.max_displacement);
    crate::outln!("  volume change      {change:+.3} %");
    if let Some(out) = &args.out {
        crate::outln!("  outputs            {}", out.display());
    }
    match o.error {
        Some(e) => anyhow::bail!(e),
        None => Ok(()),
    }
}
