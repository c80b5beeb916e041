//! `tissue mesh inspect | convert | repair | tetrahedralize`.

use anyhow::Context;
use std::path::Path;

use tissue::image::{ImageFormat, read_image};
use tissue::io::{self, Format, MshVersion, WriteOptions};
use tissue::mesh::MeshData;
use tissue::mesh::inspect::inspect;
use tissue::mesh::repair::{RepairOptions, repair};

use crate::MeshCommand;

pub fn mesh(cmd: &MeshCommand) -> anyhow::Result<()> {
    match cmd {
        MeshCommand::Inspect { file, json } => {
            if let Some(format) = ImageFormat::from_path(file) {
                return inspect_image(file, format, *json);
            }
            let mesh = io::read(file)?;
            let report = inspect(&mesh);
            if *json {
                crate::outln!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                crate::outln!("{}", file.display());
                crate::out!("{report}");
            }
            Ok(())
        }
        MeshCommand::Convert {
            input,
            output,
            msh_version,
            ascii,
        } => {
            let format = Format::from_path(output)?;
            anyhow::ensure!(
                format.can_write(),
                "{}: tissue reads this format but does not write it",
                output.display()
            );
            let mesh = io::read(input)?;
            let options = WriteOptions {
                msh_version: if *msh_version == 2 {
                    MshVersion::V2
                } else {
                    MshVersion::V4
                },
                binary: !*ascii,
            };
            io::write_with(output, &mesh, &options)?;
            crate::outln!("{}", written(output, &mesh)?);
            Ok(())
        }
        MeshCommand::Repair {
            input,
            output,
            tolerance,
        } => {
            let format = Format::from_path(output)?;
            anyhow::ensure!(
                format.can_write(),
                "{}: cannot write this format",
                output.display()
            );
            let mut mesh = io::read(input)?;
            let options = RepairOptions {
                merge_tolerance: Some(*tolerance),
                ..RepairOptions::default()
            };
            let report = repair(&mut mesh, &options);
            io::write(output, &mesh)
                .with_context(|| format!("writing the repaired mesh of {}", input.display()))?;
            crate::outln!("{report}");
            crate::outln!("{}", written(output, &mesh)?);
            Ok(())
        }
        MeshCommand::Tetrahedralize {
            input,
            output,
            size,
            labels,
            threshold,
            scale,
            smooth,
            open,
            close,
            open_close,
            all_parts,
            keep_holes,
            json,
            force,
        } => crate::tetrahedralize::tetrahedralize(&crate::tetrahedralize::Request {
            input,
            output,
            size: *size,
            labels: labels.as_deref(),
            threshold: threshold.as_deref(),
            scale: *scale,
            smooth: *smooth,
            cleaning: tissue::image::Cleaning {
                open: *open,
                close: *close,
                open_close: *open_close,
                largest_component: !*all_parts,
                fill_holes: !*keep_holes,
            },
            json: *json,
            force: *force,
        }),
    }
}

/// What a written file holds, read back from it (so the counts are the file's, whatever the
/// format kept), and what of `source` it left out.
fn written(output: &Path, source: &MeshData) -> anyhow::Result<String> {
    let back = io::read(output)
        .with_context(|| format!("reading back {} to count what it holds", output.display()))?;
    let mut line = format!("wrote {}: {}", output.display(), counts(&back));
    let lost = dropped(source, &back);
    if !lost.is_empty() {
        line.push_str(&format!(
            "\n  dropped (the format cannot hold them): {}",
            lost.join(", ")
        ));
    }
    Ok(line)
}

/// What `source` had that `written` lacks, in words.
fn dropped(source: &MeshData, written: &MeshData) -> Vec<String> {
    let mut out = Vec::new();
    let count = |out: &mut Vec<String>, had: usize, kept: usize, what: &str| {
        if kept < had {
            out.push(format!("{} of {had} {what}", had - kept));
        }
    };
    count(
        &mut out,
        source.tets.len(),
        written.tets.len(),
        "tetrahedra",
    );
    count(
        &mut out,
        source.tets10.len(),
        written.tets10.len(),
        "10-node tetrahedra",
    );
    count(
        &mut out,
        source.fixed_vertices.len(),
        written.fixed_vertices.len(),
        "fixed vertices",
    );
    count(
        &mut out,
        source.triangle_tags.len(),
        written.triangle_tags.len(),
        "triangle tags",
    );
    count(
        &mut out,
        source.tet_tags.len(),
        written.tet_tags.len(),
        "tetrahedron tags",
    );
    count(
        &mut out,
        source.point_data.len(),
        written.point_data.len(),
        "point data fields",
    );
    if source.has_volume() && !written.has_volume() && !written.triangles.is_empty() {
        let n = source.vertices.len().saturating_sub(written.vertices.len());
        out.push(format!(
            "the interior ({n} vertices inside; the boundary surface was written)"
        ));
    } else if written.triangles.len() < source.triangles.len() {
        count(
            &mut out,
            source.triangles.len(),
            written.triangles.len(),
            "triangles",
        );
    }
    if source.material.is_some() && written.material.is_none() {
        out.push("the material record".into());
    }
    out
}

fn counts(mesh: &MeshData) -> String {
    let mut parts = vec![format!("{} vertices", mesh.vertices.len())];
    for (n, what) in [
        (mesh.triangles.len(), "triangles"),
        (mesh.tets.len(), "tetrahedra"),
        (mesh.tets10.len(), "10-node tetrahedra"),
    ] {
        if n > 0 {
            parts.push(format!("{n} {what}"));
        }
    }
    parts.join(", ")
}

/// `mesh inspect` of a volume image (.nii, .hdr/.img, .mhd, .mha, .nrrd): grid, value range,
/// zeros, and the segments of a segmentation.
fn inspect_image(file: &Path, format: ImageFormat, json: bool) -> anyhow::Result<()> {
    // MetaImage has no unit; report its numbers as they are rather than guess a scale.
    let image = read_image(file, 1.0)?;
    let unit = match format {
        ImageFormat::Nifti => "m",
        ImageFormat::MetaImage => "file units, MetaImage states none",
        ImageFormat::Nrrd => "m",
    };
    let s = image.stats();
    let [sx, sy, sz] = image.spacing.to_array();
    let [ox, oy, oz] = image.origin.to_array();
    if json {
        let report = serde_json::json!({
            "kind": "image",
            "format": format!("{format:?}"),
            "dims": image.dims,
            "voxels": s.count,
            "spacing": [sx, sy, sz],
            "origin": [ox, oy, oz],
            "unit": unit,
            "value_type": image.source_type,
            "byte_order": image.byte_order,
            "min": s.min,
            "max": s.max,
            "mean": s.mean,
            "zeros": s.zeros,
            "negatives": s.negatives,
            "segments": image.segments,
        });
        crate::outln!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        let [nx, ny, nz] = image.dims;
        crate::outln!("{}", file.display());
        crate::outln!(
            "image ({format:?}): {nx} × {ny} × {nz} = {} voxels",
            s.count
        );
        crate::outln!("spacing: {sx} {sy} {sz} ({unit})");
        crate::outln!("origin:  {ox} {oy} {oz} ({unit}; centre of voxel 0)");
        crate::outln!("values:  {}, {}", image.source_type, image.byte_order);
        crate::outln!("range:   {} .. {}, mean {:.4}", s.min, s.max, s.mean);
        let pct = |n: usize| 100.0 * n as f64 / s.count.max(1) as f64;
        crate::outln!("zeros:   {} ({:.2} %)", s.zeros, pct(s.zeros));
        crate::outln!("negative: {} ({:.2} %)", s.negatives, pct(s.negatives));
        for seg in &image.segments {
            let n = image.values.iter().filter(|&&v| v == seg.label).count();
            crate::outln!(
                "segment: {} ({}): value {}, {n} voxels",
                seg.name,
                seg.id,
                seg.label
            );
        }
    }
    Ok(())
}
