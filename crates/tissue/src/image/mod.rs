//! Medical volume images (MRI, CT) as input: NIfTI-1 and MetaImage files read into a
//! `VoxelImage`, a scalar grid in metres, for thresholding, voxel models and meshing.
//!
//! | format | ext | notes |
//! |---|---|---|
//! | NIfTI-1 | `.nii`, `.hdr` + `.img` | either byte order; units from the header; not gzipped |
//! | MetaImage | `.mhd` + raw, `.mha` | header has no unit: multiply by `scale` |
//!
//! Both keep the grid axis-aligned: spacing and origin are read, orientation is not.

pub mod grid;
pub mod metaimage;
pub mod nifti;

use std::path::Path;

use crate::error::{IoError, Location};

pub use grid::{ByteOrder, ImageStats, SourceType, VoxelImage};

/// An image file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// `.nii`, `.hdr`, `.img` (and `.nii.gz`, which is refused with a clear message).
    Nifti,
    /// `.mhd`, `.mha`.
    MetaImage,
}

impl ImageFormat {
    /// The image format named by a path's extension, if it names one.
    pub fn from_path(path: &Path) -> Option<Self> {
        let name = path.file_name()?.to_str()?.to_ascii_lowercase();
        let ext = name.rsplit_once('.')?.1;
        match ext {
            "nii" | "hdr" | "img" => Some(ImageFormat::Nifti),
            "gz" if name.ends_with(".nii.gz") => Some(ImageFormat::Nifti),
            "mhd" | "mha" => Some(ImageFormat::MetaImage),
            _ => None,
        }
    }
}

/// Reads a volume image, the format chosen by the extension.
///
/// `scale` is metres per header unit for formats whose header has no unit (MetaImage: SOFA's
/// `pelvis_f.mhd`, for one, is in arbitrary units). NIfTI headers state their unit, so NIfTI
/// images come in metres and `scale` is not applied to them.
pub fn read_image(path: impl AsRef<Path>, scale: f64) -> Result<VoxelImage, IoError> {
    let path = path.as_ref();
    match ImageFormat::from_path(path) {
        Some(ImageFormat::MetaImage) => metaimage::read(path, scale),
        Some(ImageFormat::Nifti) => {
            let gz = path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("gz"));
            if gz {
                return Err(IoError::new(
                    path,
                    Location::File,
                    "compressed NIfTI is not supported; gunzip it first",
                ));
            }
            nifti::read(path)
        }
        None => Err(IoError::new(
            path,
            Location::File,
            "unknown image format; supported: .nii .hdr/.img .mhd .mha",
        )),
    }
}
