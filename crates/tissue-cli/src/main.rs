//! `tissue`: run, inspect and convert deformable tissue models from the command line.

mod bench;
mod compare;
mod demo;
mod haptic_bench;
mod mesh_cmd;
mod out;
mod run;
mod tetrahedralize;
mod view;

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};

/// Real-time deformable models of soft tissue for surgery simulation.
#[derive(Parser, Debug)]
#[command(name = "tissue", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run a scene file: writes a VTU time series (+ .pvd for ParaView), forces.csv and
    /// summary.json into the output directory.
    Run(RunArgs),
    /// Run the built-in liver scene (a probe pressing on a liver held at its ligaments) and
    /// print a short summary.
    Demo(DemoArgs),
    /// Inspect, convert and repair mesh files.
    #[command(subcommand)]
    Mesh(MeshCommand),
    /// List the model kinds built in: name, then a one-line description.
    Models,
    /// Serve the interactive browser viewer of a scene on 127.0.0.1 and print its URL.
    View(view::ViewArgs),
    /// Drive the 1 kHz haptic loop with a scripted device over UDP and print its timing.
    HapticBench(haptic_bench::HapticBenchArgs),
    /// Benchmarks of record: `tissue bench beam` runs the clamped beam for every dynamic kind.
    #[command(subcommand)]
    Bench(bench::BenchCommand),
    /// Measure every model kind on one organ and score them against the survey's Table 1:
    /// compare.json, table1.md/html, radars and plots (SVG, PNG) in the output directory.
    Compare(compare::CompareArgs),
}

#[derive(Args, Debug)]
pub struct RunArgs {
    /// The scene file (TOML).
    pub scene: PathBuf,
    /// Output directory (created if missing).
    #[arg(long, short, default_value = "out")]
    pub out: PathBuf,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Also write the run's outputs (VTU series, forces.csv, summary.json) here.
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Print the built-in scene file and exit.
    #[arg(long)]
    pub print_scene: bool,
}

#[derive(Subcommand, Debug)]
pub enum MeshCommand {
    /// Counts, bounds, volume, quality histogram and problems of a mesh file; dimensions,
    /// spacing and value range of an image (.nii, .mhd, .mha, .nrrd).
    Inspect {
        file: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Convert between formats (chosen by the extensions): .obj .stl .ply(read) .msh .vtk .vtu .mesh
    Convert {
        input: PathBuf,
        output: PathBuf,
        /// Gmsh version to write: 2 or 4 (4.1).
        #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(2..=4))]
        msh_version: u8,
        /// Write text where the format also has binary (STL, VTU).
        #[arg(long)]
        ascii: bool,
    },
    /// Merge duplicate vertices, drop unused ones and degenerate or duplicate elements, and
    /// orient everything outward; prints what was fixed.
    Repair {
        input: PathBuf,
        output: PathBuf,
        /// Distance below which vertices are merged, relative to the bounding-box diagonal.
        #[arg(long, default_value_t = 1e-9)]
        tolerance: f64,
    },
    /// Tetrahedral mesh of a closed surface (.obj .stl .ply .off .vtp .vtk ...) or of a segmented
    /// image (.nii .nii.gz .mhd .mha .nrrd .nhdr .seg.nrrd) by isosurface stuffing, with its quality report; refuses
    /// to write a mesh that breaks a guarantee (min dihedral 10°, boundary within h/2,
    /// volume within 1 %) unless --force.
    Tetrahedralize {
        input: PathBuf,
        /// A volume format: .vtu .vtk .msh .mesh .ele (TetGen).
        output: PathBuf,
        /// Lattice spacing h in m (the longest tetrahedron edges); default: about 20,000
        /// tetrahedra.
        #[arg(long)]
        size: Option<f64>,
        /// Image voxel values to mesh (each tagged with its label), e.g. --labels 1,2, or
        /// segment names of a 3D Slicer segmentation, e.g. --labels liver,tumor.
        #[arg(long, value_delimiter = ',')]
        labels: Option<Vec<tissue::image::LabelRef>>,
        /// Image value window to mesh, --threshold lo,hi.
        #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
        threshold: Option<Vec<f32>>,
        /// Metres per header unit of a MetaImage (whose header states none).
        #[arg(long, default_value_t = 0.001)]
        scale: f64,
        /// Gaussian σ (m) blurring an image's mask before meshing, so that features much
        /// smaller than the tetrahedra do not count; default: size/2 (0 for none).
        #[arg(long)]
        smooth: Option<f64>,
        /// Radius (m) of a closing by a ball before the other cleaning of an image's
        /// selected voxels: cracks narrower than twice this are filled, and every guarantee
        /// is measured against the filtered voxels (0 for none).
        #[arg(long, default_value_t = 0.0)]
        close: f64,
        /// Radius (m) of an opening by a ball after --close: sheets and strands thinner than
        /// twice this are removed, and every guarantee is measured against the filtered
        /// voxels (0 for none).
        #[arg(long, default_value_t = 0.0)]
        open: f64,
        /// Radius in voxels of the morphological opening then closing that cleans an
        /// image's selected voxels before meshing (0 for none).
        #[arg(long, default_value_t = 1)]
        open_close: usize,
        /// Mesh every connected part of an image's selection, not only the largest.
        #[arg(long)]
        all_parts: bool,
        /// Leave holes enclosed by an image's selection unselected.
        #[arg(long)]
        keep_holes: bool,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
        /// Write the mesh even when it breaks a guarantee.
        #[arg(long)]
        force: bool,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run(args) => run::run(&args),
        Command::Demo(args) => demo::demo(&args),
        Command::Mesh(cmd) => mesh_cmd::mesh(&cmd),
        Command::View(args) => view::view(&args),
        Command::HapticBench(args) => haptic_bench::haptic_bench(&args),
        Command::Bench(cmd) => bench::bench(&cmd),
        Command::Models => models(),
        Command::Compare(args) => compare::compare(&args),
    };
    // What is still buffered fails here, not silently at exit.
    let result = result.and_then(|()| {
        out::flush().map_err(|e| anyhow::Error::new(e).context("writing to standard output"))
    });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        // The reader left (`tissue models | head -1`): nothing more to say to anyone.
        Err(e) if out::is_broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            // Not `eprintln!`: it panics when stderr is closed too.
            let _ = writeln!(std::io::stderr(), "error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn models() -> anyhow::Result<()> {
    for k in tissue::model::KINDS {
        outln!("{:<26} {}", k.name, k.summary);
    }
    Ok(())
}
