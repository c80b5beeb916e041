//! Voxel grids from medical images: a threshold window or a set of label values, optionally
//! sampling every `stride`-th voxel along each axis to coarsen a fine scan.

use crate::error::MeshError;
use crate::image::VoxelImage;

use super::VoxelGrid;

/// Occupied where `lo <= value <= hi` (NaN never), sampling every `stride`-th voxel.
pub fn from_image_threshold(
    image: &VoxelImage,
    lo: f32,
    hi: f32,
    stride: usize,
) -> Result<VoxelGrid, MeshError> {
    if lo.is_nan() || hi.is_nan() || lo > hi {
        return Err(MeshError::Invalid(format!(
            "threshold window [{lo}, {hi}] is empty or not a number"
        )));
    }
    sample(image, stride, |v| lo <= v && v <= hi)
}

/// Occupied where the value is one of `labels` (segmentation images store integer labels).
pub fn from_image_labels(
    image: &VoxelImage,
    labels: &[f32],
    stride: usize,
) -> Result<VoxelGrid, MeshError> {
    if labels.is_empty() {
        return Err(MeshError::Invalid("no label values to select".into()));
    }
    sample(image, stride, |v| labels.contains(&v))
}

fn sample(
    image: &VoxelImage,
    stride: usize,
    inside: impl Fn(f32) -> bool,
) -> Result<VoxelGrid, MeshError> {
    if stride == 0 {
        return Err(MeshError::Invalid("image stride must be at least 1".into()));
    }
    let expected = image.dims.iter().product::<usize>();
    if image.values.len() != expected {
        return Err(MeshError::Invalid(format!(
            "the image has {} samples for dimensions {:?}",
            image.values.len(),
            image.dims
        )));
    }
    let dims = image.dims.map(|d| d.div_ceil(stride));
    let mut grid = VoxelGrid::new(dims, image.spacing * stride as f64, image.origin);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let v = image.value(i * stride, j * stride, k * stride);
                if v.is_some_and(&inside) {
                    grid.labels[i + dims[0] * (j + dims[1] * k)] = 1;
                }
            }
        }
    }
    if grid.occupied() == 0 {
        return Err(MeshError::Empty {
            what: "voxels in the selected window",
        });
    }
    Ok(grid)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::read_image;
    use crate::voxel::keep_largest;

    #[test]
    fn images_threshold_and_keep_their_largest_part() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/images/");
        let nii = read_image(format!("{dir}anatomical.nii"), 1.0).unwrap();
        let (lo, hi) = nii.min_max().unwrap();
        let mid = lo + 0.25 * (hi - lo);
        let g = from_image_threshold(&nii, mid, hi, 1).unwrap();
        let expected = nii.values.iter().filter(|&&v| mid <= v && v <= hi).count();
        assert_eq!(g.occupied(), expected);
        let mut largest = g.clone();
        let kept = keep_largest(&mut largest);
        assert_eq!(kept, largest.occupied());
        assert!(
            kept <= expected && kept > expected / 4,
            "{kept} of {expected}"
        );

        let mhd = read_image(format!("{dir}pelvis_f.mhd"), 0.001).unwrap();
        let (lo, hi) = mhd.min_max().unwrap();
        let g2 = from_image_threshold(&mhd, lo + 0.5 * (hi - lo), hi, 2).unwrap();
        assert_eq!(g2.dims, mhd.dims.map(|d| d.div_ceil(2)));
        assert!(g2.occupied() > 0);
        assert!(from_image_threshold(&mhd, hi + 1.0, hi + 2.0, 1).is_err());
        assert!(from_image_threshold(&mhd, 1.0, 0.0, 1).is_err());
        assert!(from_image_labels(&mhd, &[], 1).is_err());
    }
}
