//! Scenes whose body is a volume image (`[image]`): the checks made when the scene is read,
//! the voxel grid made from the image when it is built, and the voxel models built on that
//! grid. Messages are completed with the scene file and the table's line by the caller.

use std::path::Path;

use crate::error::{Error, MeshError, SimError};
use crate::image::{ImageFormat, LabelRef, VoxelImage, read_image};
use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::model::Deformable;
use crate::model::chainmail::{ChainMail, ChainMailParams};
use crate::model::linked_volumes::{LinkedVolumes, LinkedVolumesParams};
use crate::model::registry::parse_params;
use crate::voxel::{
    VoxelGrid, from_image_labels, from_image_threshold, keep_component_at, keep_largest,
};

use super::spec::ImageSpec;

/// The kinds an `[image]` body builds: the voxel models.
pub const IMAGE_KINDS: [&str; 2] = ["chainmail", "linked-volumes"];

/// MetaImage headers state no unit: millimetres unless `scale` says otherwise.
const DEFAULT_SCALE: Real = 0.001;

/// `[model]` keys that size a voxelisation, meaningless when the image gives the voxels.
const VOXELISATION_KEYS: [&str; 2] = ["voxel_size", "resolution"];

/// Checks an `[image]` table without reading the image.
pub(super) fn check_image(spec: &ImageSpec) -> Result<(), String> {
    let format = ImageFormat::from_path(&spec.file).ok_or_else(|| {
        format!(
            "file = \"{}\": not an image format tissue reads (.nii, .nii.gz, .hdr/.img, .mhd, .mha, .nrrd, .nhdr)",
            spec.file.display()
        )
    })?;
    match (&spec.threshold, &spec.labels) {
        (Some(_), Some(_)) | (None, None) => {
            return Err("needs exactly one of `threshold = [lo, hi]` or `labels = [...]`".into());
        }
        (Some([lo, hi]), None) => {
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(format!("threshold = [{lo}, {hi}]: needs finite lo <= hi"));
            }
        }
        (None, Some(labels)) => {
            let finite = |l: &LabelRef| !matches!(l, LabelRef::Value(v) if !v.is_finite());
            if labels.is_empty() || !labels.iter().all(finite) {
                return Err(
                    "labels: needs at least one label (a finite value or a segment's name)".into(),
                );
            }
            if let Some(name) = labels.iter().find(|l| matches!(l, LabelRef::Name(_)))
                && format != ImageFormat::Nrrd
            {
                return Err(format!(
                    "labels: `{name}` is a segment name, but only NRRD segmentations \
                     (.seg.nrrd) name their labels; give this image's label values"
                ));
            }
        }
    }
    if spec.stride == 0 || spec.stride > 1000 {
        return Err(format!("stride = {}: must be in 1..=1000", spec.stride));
    }
    let finite = |v: &[Real]| v.iter().all(|x| x.is_finite());
    if let Some(s) = spec.seed
        && !finite(&s)
    {
        return Err("seed must be finite".into());
    }
    if let Some(o) = spec.origin
        && !finite(&o)
    {
        return Err("origin must be finite".into());
    }
    if let Some(s) = spec.spacing
        && !s.iter().all(|x| x.is_finite() && *x > 0.0)
    {
        return Err(format!(
            "spacing = {s:?}: every entry must be finite and > 0 m"
        ));
    }
    match (format, spec.scale) {
        (ImageFormat::Nifti | ImageFormat::Nrrd, Some(_)) => Err(
            "scale applies to MetaImage files (their header has no unit); a NIfTI or NRRD \
             header states its own (use `spacing` to override it)"
                .into(),
        ),
        (_, Some(s)) if !(s.is_finite() && s > 0.0) => {
            Err(format!("scale = {s}: must be finite and > 0"))
        }
        _ => Ok(()),
    }
}

/// Why an `[image]` scene cannot take a `[model]`: the kind or a voxelisation key.
pub(super) fn check_model(kind: &str, params: &toml::Table) -> Result<(), String> {
    if !IMAGE_KINDS.contains(&kind) {
        return Err(format!(
            "kind `{kind}` cannot be built from an [image]; image bodies build {} (use a \
             [mesh] for other kinds)",
            IMAGE_KINDS.join(" or ")
        ));
    }
    if let Some(key) = VOXELISATION_KEYS.iter().find(|k| params.contains_key(**k)) {
        return Err(format!(
            "`{key}` does not apply to an [image] body: the image's voxels (every `stride`-th) \
             are the lattice"
        ));
    }
    Ok(())
}

/// The regions of an image selected by two labels or more and meshed (`tet_size`): voxel
/// class k (1-based, the grid's label) is the k-th label of `labels`, and its tetrahedra
/// are tagged `tags[k - 1]`: the label's value where every value is a whole number (as
/// `tissue mesh --labels` tags them), else k. `names`: the segments naming those tags.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct LabelRegions {
    pub tags: Vec<i32>,
    pub names: Vec<(String, i32)>,
}

impl LabelRegions {
    fn of(image: &VoxelImage, labels: &[LabelRef], values: &[f32]) -> Self {
        let whole = values
            .iter()
            .all(|v| v.fract() == 0.0 && v.abs() < i32::MAX as f32);
        let tags: Vec<i32> = values
            .iter()
            .enumerate()
            .map(|(k, v)| if whole { *v as i32 } else { k as i32 + 1 })
            .collect();
        let mut names = Vec::new();
        for (k, l) in labels.iter().enumerate() {
            if let LabelRef::Name(n) = l {
                names.push((n.clone(), tags[k]));
            }
        }
        for seg in &image.segments {
            if let Some(k) = values.iter().position(|v| *v == seg.label) {
                for n in [&seg.name, &seg.id] {
                    if !names.iter().any(|(m, _)| m == n) {
                        names.push((n.clone(), tags[k]));
                    }
                }
            }
        }
        Self { tags, names }
    }
}

/// Reads the image at `path` and selects the voxels of the part to keep. With `regions`
/// (the body is meshed) and two labels or more, each voxel's grid label is its label's
/// class (`LabelRegions`), so that each label is meshed as a region of its own.
pub(super) fn image_grid(
    spec: &ImageSpec,
    path: &Path,
    regions: bool,
) -> Result<(VoxelGrid, LabelRegions), Failure> {
    let mut image = read_image(path, spec.scale.unwrap_or(DEFAULT_SCALE))
        .map_err(|e| Failure::File(e.into()))?;
    if let Some(s) = spec.spacing {
        image.spacing = Vec3::from(s);
    }
    if let Some(o) = spec.origin {
        image.origin = Vec3::from(o);
    }
    let range = value_range(&image);
    let why = |e: MeshError| match e {
        MeshError::Empty { .. } => format!("selects no voxel; the image's values span {range}"),
        other => format!("{other}; the image's values span {range}"),
    };
    let mut regions_out = LabelRegions::default();
    let mut grid = match (&spec.threshold, &spec.labels) {
        (Some([lo, hi]), _) => from_image_threshold(&image, *lo, *hi, spec.stride)
            .map_err(|e| key_error("threshold", why(e)))?,
        (None, Some(labels)) => {
            let values = image
                .label_values(labels)
                .map_err(|e| key_error("labels", e))?;
            let mut grid = from_image_labels(&image, &values, spec.stride)
                .map_err(|e| key_error("labels", why(e)))?;
            if regions && values.len() >= 2 {
                label_classes(&mut grid, &image, &values, spec.stride)
                    .map_err(|m| key_error("labels", m))?;
                regions_out = LabelRegions::of(&image, labels, &values);
            }
            grid
        }
        (None, None) => return Err(key_error("threshold", "needs threshold or labels".into())),
    };
    match spec.seed {
        None => {
            keep_largest(&mut grid);
        }
        Some(seed) => {
            let p = Vec3::from(seed);
            let voxel = grid.voxel_at(p).ok_or_else(|| {
                let hi = grid.centre(
                    grid.dims[0].saturating_sub(1),
                    grid.dims[1].saturating_sub(1),
                    grid.dims[2].saturating_sub(1),
                );
                key_error(
                    "seed",
                    format!(
                        "{seed:?} is outside the image, whose voxel centres span {} to {hi} m",
                        grid.origin
                    ),
                )
            })?;
            if keep_component_at(&mut grid, voxel).is_none() {
                let [i, j, k] = grid.coords(voxel);
                let s = spec.stride;
                let value = image
                    .value(i * s, j * s, k * s)
                    .map_or("none".to_string(), |v| v.to_string());
                return Err(key_error(
                    "seed",
                    format!(
                        "{seed:?} lies in voxel ({i}, {j}, {k}) of the sampled grid, value \
                         {value}, which is not selected"
                    ),
                ));
            }
        }
    }
    Ok((grid, regions_out))
}

/// Sets each selected voxel's grid label to its label's class: 1 + its position in
/// `values` (a `u8`, so at most 255 labels).
fn label_classes(
    grid: &mut VoxelGrid,
    image: &VoxelImage,
    values: &[f32],
    stride: usize,
) -> Result<(), String> {
    if values.len() > usize::from(u8::MAX) {
        return Err(format!(
            "{} labels: at most {} can be meshed as regions",
            values.len(),
            u8::MAX
        ));
    }
    for idx in 0..grid.len() {
        if !grid.is_occupied(idx) {
            continue;
        }
        let [i, j, k] = grid.coords(idx);
        let value = image.value(i * stride, j * stride, k * stride);
        if let Some(c) = value.and_then(|v| values.iter().position(|x| *x == v)) {
            grid.labels[idx] = c as u8 + 1;
        }
    }
    Ok(())
}

/// Why an image gave no grid: a key of `[image]` (the caller names the scene file and line)
/// or the image file itself (the error names it).
#[derive(Debug)]
pub(super) enum Failure {
    Key(String),
    File(Error),
}

fn key_error(key: &str, message: String) -> Failure {
    Failure::Key(format!("{key}: {message}"))
}

fn value_range(image: &VoxelImage) -> String {
    image
        .min_max()
        .map_or("nothing".into(), |(lo, hi)| format!("{lo} to {hi}"))
}

/// A voxel model of `kind` on `grid`, its surface the marching surface of the voxels.
pub(super) fn voxel_model(
    kind: &str,
    grid: VoxelGrid,
    material: Material,
    params: &toml::Table,
) -> Result<Box<dyn Deformable>, Error> {
    match kind {
        "chainmail" => {
            let p: ChainMailParams = parse_params("chainmail", params)?;
            Ok(Box::new(ChainMail::new(grid, None, material, p)?))
        }
        "linked-volumes" => {
            let p: LinkedVolumesParams = parse_params("linked-volumes", params)?;
            Ok(Box::new(LinkedVolumes::new(grid, None, material, p)?))
        }
        other => Err(SimError::UnknownModel {
            kind: other.to_string(),
            known: IMAGE_KINDS.join(", "),
        }
        .into()),
    }
}
