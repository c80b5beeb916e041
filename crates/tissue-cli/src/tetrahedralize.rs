//! `tissue mesh tetrahedralize IN OUT`: a closed surface or a segmented image to a
//! tetrahedral mesh by isosurface stuffing, with a progress bar and the quality report.

use std::path::Path;
use std::time::Duration;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};

use tissue::image::{ImageFormat, read_image};
use tissue::io::{self, Format};
use tissue::mesh::stuffing::{
    DEFAULT_TARGET_TETS, Domain, ImageDomain, SurfaceDomain, size_for, stuff,
};
use tissue::model::Progress;

/// What `mesh tetrahedralize` was asked.
pub struct Request<'a> {
    pub input: &'a Path,
    pub output: &'a Path,
    pub size: Option<f64>,
    pub labels: Option<&'a [tissue::image::LabelRef]>,
    pub threshold: Option<&'a [f32]>,
    pub scale: f64,
    pub smooth: Option<f64>,
    /// Cleaning of an image's selected voxels before meshing.
    pub cleaning: tissue::image::Cleaning,
    pub json: bool,
    pub force: bool,
}

pub fn tetrahedralize(r: &Request) -> anyhow::Result<()> {
    let format = Format::from_path(r.output)?;
    anyhow::ensure!(
        format.can_write() && !matches!(format, Format::Obj | Format::Stl | Format::Off),
        "{}: write the tetrahedra to a volume format (.vtu .vtk .msh .mesh .ele)",
        r.output.display()
    );
    let is_image = ImageFormat::from_path(r.input).is_some();
    let size_given = r.size;
    let domain: Box<dyn Domain> = if is_image {
        let image = read_image(r.input, r.scale)?;
        let range = image
            .min_max()
            .map_or("no numbers".to_string(), |(a, b)| format!("{a} .. {b}"));
        match (r.labels, r.threshold) {
            (Some(_), Some(_)) => anyhow::bail!("give --labels or --threshold, not both"),
            (Some(l), None) => Box::new(smooth_image(
                ImageDomain::from_labels(
                    &image,
                    &image
                        .label_values(l)
                        .map_err(|e| anyhow::anyhow!("{}: --labels: {e}", r.input.display()))?,
                )
                .with_context(|| format!("{}: values span {range}", r.input.display()))?
                .cleaned(r.cleaning)?,
                r.smooth,
                size_given,
            )),
            (None, Some(&[lo, hi])) => Box::new(smooth_image(
                ImageDomain::from_threshold(&image, lo, hi)
                    .with_context(|| format!("{}: values span {range}", r.input.display()))?
                    .cleaned(r.cleaning)?,
                r.smooth,
                size_given,
            )),
            (None, Some(t)) => anyhow::bail!("--threshold takes lo,hi; got {} values", t.len()),
            (None, None) => anyhow::bail!(
                "{} is an image: say which voxels to mesh with --labels 1,2 or --threshold lo,hi \
                 (its values span {range})",
                r.input.display()
            ),
        }
    } else {
        anyhow::ensure!(
            r.labels.is_none() && r.threshold.is_none(),
            "--labels and --threshold select voxels of an image; {} is a mesh",
            r.input.display()
        );
        let mesh = io::read(r.input)?;
        let surface = mesh.surface_mesh()?;
        Box::new(
            SurfaceDomain::new(&surface)
                .with_context(|| format!("{} cannot be meshed inside", r.input.display()))?,
        )
    };
    let size = match r.size {
        Some(h) => h,
        None => {
            let v = domain.reference_volume().unwrap_or(0.0);
            let h = size_for(v, DEFAULT_TARGET_TETS);
            eprintln!("--size not given: h = {h:.4e} m for about {DEFAULT_TARGET_TETS} tetrahedra");
            h
        }
    };
    let bar = ProgressBar::new(1000);
    bar.set_style(
        ProgressStyle::with_template("{spinner} meshing: {msg:<12} [{bar:30}] {elapsed}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.enable_steady_tick(Duration::from_millis(100));
    let b = bar.clone();
    let progress = Progress::new(move |stage, f| {
        b.set_message(stage.to_string());
        b.set_position((f * 1000.0) as u64);
    });
    let stuffed = stuff(domain.as_ref(), size, &progress);
    bar.finish_and_clear();
    let stuffed = stuffed?;
    let report = &stuffed.report;
    let violations = report.violations();
    if r.json {
        crate::outln!("{}", serde_json::to_string_pretty(report)?);
    } else {
        crate::out!("{report}");
    }
    if !violations.is_empty() && !r.force {
        anyhow::bail!(
            "not written: {}. A smaller --size follows the shape more closely; --force writes \
             the mesh anyway",
            violations.join("; ")
        );
    }
    io::write(r.output, &stuffed.to_mesh_data())?;
    eprintln!(
        "wrote {}: {} vertices, {} tetrahedra",
        r.output.display(),
        stuffed.mesh.vertices.len(),
        stuffed.mesh.tets.len()
    );
    Ok(())
}

/// The image's mask blurred by `--smooth` (default: h/2 when --size is given, else none).
fn smooth_image(d: ImageDomain, smooth: Option<f64>, size: Option<f64>) -> ImageDomain {
    let sigma = smooth.or(size.map(|h| tissue::mesh::stuffing::DEFAULT_IMAGE_SMOOTHING * h));
    match sigma {
        Some(s) if s > 0.0 => {
            eprintln!("mask smoothed with a Gaussian of σ = {s:.3e} m");
            d.smoothed(s)
        }
        _ => d,
    }
}
