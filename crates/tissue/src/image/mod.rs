//! Medical volume images (MRI, CT) and segmentations as input: NIfTI-1, MetaImage and NRRD
//! files read into a `VoxelImage`, a scalar grid in metres, for thresholding, voxel models and
//! meshing.
//!
//! | format | ext | notes |
//! |---|---|---|
//! | NIfTI-1 | `.nii`, `.nii.gz`, `.hdr` + `.img` | either byte order; units from the header |
//! | MetaImage | `.mhd` + raw, `.mha` | header has no unit: multiply by `scale` |
//! | NRRD | `.nrrd`, `.nhdr` + data, `.seg.nrrd` | raw, gzip, ascii, hex; millimetres unless `space units` says; segment names |
//!
//! All keep the grid axis-aligned: spacing and origin are read; NRRD also applies flipped or
//! permuted axes; no reader applies an oblique orientation.

pub mod ball;
pub mod clean;
pub mod grid;
pub mod metaimage;
pub mod nifti;
pub mod nrrd;

use std::path::Path;

use crate::error::{IoError, Location};

pub use ball::{close_ball, open_ball, open_close_ball};
pub use clean::{CleanReport, Cleaning, clean_mask};
pub use grid::{ByteOrder, ImageStats, LabelRef, Segment, SourceType, VoxelImage};

/// An image file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// `.nii`, `.nii.gz`, `.hdr`, `.img`.
    Nifti,
    /// `.mhd`, `.mha`.
    MetaImage,
    /// `.nrrd`, `.nhdr` (and 3D Slicer's `.seg.nrrd`).
    Nrrd,
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
            "nrrd" | "nhdr" => Some(ImageFormat::Nrrd),
            _ => None,
        }
    }
}

/// Reads a volume image, the format chosen by the extension.
///
/// `scale` is metres per header unit for formats whose header has no unit (MetaImage: SOFA's
/// `pelvis_f.mhd`, for one, is in arbitrary units). NIfTI and NRRD headers state their unit
/// (NRRD: millimetres when it does not), so they come in metres and `scale` is not applied.
pub fn read_image(path: impl AsRef<Path>, scale: f64) -> Result<VoxelImage, IoError> {
    let path = path.as_ref();
    match ImageFormat::from_path(path) {
        Some(ImageFormat::MetaImage) => metaimage::read(path, scale),
        Some(ImageFormat::Nifti) => nifti::read(path),
        Some(ImageFormat::Nrrd) => nrrd::read(path),
        None => Err(IoError::new(
            path,
            Location::File,
            "unknown image format; supported: .nii .nii.gz .hdr/.img .mhd .mha .nrrd .nhdr",
        )),
    }
}

#[cfg(test)]
mod gzip_tests {
    use super::*;

    #[test]
    fn gzipped_nifti_reads_as_the_plain_file() {
        use std::io::Write;
        let plain = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../assets/images/anatomical.nii"
        );
        let bytes = std::fs::read(plain).unwrap_or_else(|e| panic!("{e}"));
        let dir = std::env::temp_dir().join(format!("tissue-niigz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{e}"));
        let gz = dir.join("a.nii.gz");
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        enc.write_all(&bytes).unwrap_or_else(|e| panic!("{e}"));
        std::fs::write(&gz, enc.finish().unwrap_or_default()).unwrap_or_else(|e| panic!("{e}"));
        let a = read_image(plain, 1.0).unwrap_or_else(|e| panic!("{e}"));
        let b = read_image(&gz, 1.0).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(a, b);
        std::fs::write(&gz, b"\x1f\x8b not gzip").unwrap_or_else(|e| panic!("{e}"));
        let e = read_image(&gz, 1.0)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(e.contains("a.nii.gz") && e.contains("gzip"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
