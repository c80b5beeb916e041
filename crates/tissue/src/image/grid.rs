//! `VoxelImage`: a 3-D grid of scalar samples (an MRI or CT volume) on an axis-aligned
//! lattice in world coordinates (metres), with the type and byte order it was stored in.

use std::fmt;

use serde::Serialize;

use crate::math::{Real, Vec3};

/// The scalar type the file stored its voxels in. Values are converted to `f32` on load;
/// 32-bit integers and `f64` beyond 2^24 lose their low digits, which no image threshold
/// or mesher can notice.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum SourceType {
    #[serde(rename = "uint8")]
    U8,
    #[serde(rename = "int8")]
    I8,
    #[serde(rename = "int16")]
    I16,
    #[serde(rename = "uint16")]
    U16,
    #[serde(rename = "int32")]
    I32,
    #[serde(rename = "uint32")]
    U32,
    #[serde(rename = "int64")]
    I64,
    #[serde(rename = "uint64")]
    U64,
    #[serde(rename = "float32")]
    F32,
    #[serde(rename = "float64")]
    F64,
}

impl SourceType {
    /// Bytes per voxel.
    pub fn size(self) -> usize {
        match self {
            SourceType::U8 | SourceType::I8 => 1,
            SourceType::I16 | SourceType::U16 => 2,
            SourceType::I32 | SourceType::U32 | SourceType::F32 => 4,
            SourceType::I64 | SourceType::U64 | SourceType::F64 => 8,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            SourceType::U8 => "uint8",
            SourceType::I8 => "int8",
            SourceType::I16 => "int16",
            SourceType::U16 => "uint16",
            SourceType::I32 => "int32",
            SourceType::U32 => "uint32",
            SourceType::I64 => "int64",
            SourceType::U64 => "uint64",
            SourceType::F32 => "float32",
            SourceType::F64 => "float64",
        }
    }
}

impl fmt::Display for SourceType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Byte order of the stored voxels (meaningless, but still recorded, for 1-byte types).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ByteOrder {
    Little,
    Big,
}

impl fmt::Display for ByteOrder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ByteOrder::Little => "little-endian",
            ByteOrder::Big => "big-endian",
        })
    }
}

/// A scalar volume image. Voxel (i, j, k) has its centre at `origin + (i·sx, j·sy, k·sz)`;
/// orientation (rotation, axis flips) of the source file is not kept.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelImage {
    /// Voxel counts along x, y, z (each at least 1).
    pub dims: [usize; 3],
    /// Distance between voxel centres along x, y, z, in metres (positive).
    pub spacing: Vec3,
    /// World position of the centre of voxel (0, 0, 0), in metres.
    pub origin: Vec3,
    /// `dims[0]·dims[1]·dims[2]` samples, x fastest, then y, then z; scaling already applied.
    pub values: Vec<f32>,
    /// How the file stored the samples.
    pub source_type: SourceType,
    /// Byte order of the stored samples.
    pub byte_order: ByteOrder,
    /// Named segments of a segmentation file (3D Slicer's `.seg.nrrd`), each with the value
    /// its voxels hold in `values`; empty for other images.
    pub segments: Vec<Segment>,
}

/// A named segment of a segmentation image.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Segment {
    /// The name the user gave it (`liver`, `tumor`).
    pub name: String,
    /// The file's identifier (`Segment_1`).
    pub id: String,
    /// The value of its voxels in `VoxelImage::values`.
    pub label: f32,
}

/// One item of a label selection: a voxel value, or a segment's name.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(untagged)]
pub enum LabelRef {
    Value(f32),
    Name(String),
}

impl std::str::FromStr for LabelRef {
    type Err = std::convert::Infallible;

    /// A number is a voxel value, anything else a segment's name.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let s = s.trim();
        Ok(match s.parse::<f32>() {
            Ok(v) => LabelRef::Value(v),
            Err(_) => LabelRef::Name(s.to_string()),
        })
    }
}

impl fmt::Display for LabelRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LabelRef::Value(v) => write!(f, "{v}"),
            LabelRef::Name(n) => f.write_str(n),
        }
    }
}

/// Summary numbers of an image (NaN samples are left out of all but `count`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ImageStats {
    pub count: usize,
    pub min: f32,
    pub max: f32,
    pub mean: f64,
    pub zeros: usize,
    pub negatives: usize,
}

impl VoxelImage {
    /// Number of voxels.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// Linear index of voxel (i, j, k) into `values`, or `None` outside the grid.
    pub fn index(&self, i: usize, j: usize, k: usize) -> Option<usize> {
        let [nx, ny, nz] = self.dims;
        (i < nx && j < ny && k < nz).then(|| i + nx * (j + ny * k))
    }

    /// The sample at voxel (i, j, k), or `None` outside the grid.
    pub fn value(&self, i: usize, j: usize, k: usize) -> Option<f32> {
        self.index(i, j, k)
            .and_then(|n| self.values.get(n).copied())
    }

    /// World position (metres) of the centre of voxel (i, j, k); defined outside the grid too.
    pub fn position(&self, i: usize, j: usize, k: usize) -> Vec3 {
        self.origin + Vec3::new(i as Real, j as Real, k as Real) * self.spacing
    }

    /// Smallest and largest sample, ignoring NaN; `None` if there is no number at all.
    pub fn min_max(&self) -> Option<(f32, f32)> {
        self.values
            .iter()
            .filter(|v| !v.is_nan())
            .fold(None, |acc, &v| match acc {
                None => Some((v, v)),
                Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
            })
    }

    /// A mask, in the order of `values`: true where `lo <= value <= hi` (NaN is never inside).
    pub fn threshold(&self, lo: f32, hi: f32) -> Vec<bool> {
        self.values.iter().map(|&v| lo <= v && v <= hi).collect()
    }

    /// The voxel values a label selection stands for: numbers as given, names looked up
    /// among the segments (the error lists the names the image has).
    pub fn label_values(&self, labels: &[LabelRef]) -> Result<Vec<f32>, String> {
        labels
            .iter()
            .map(|l| match l {
                LabelRef::Value(v) => Ok(*v),
                LabelRef::Name(n) => self
                    .segments
                    .iter()
                    .find(|s| s.name == *n || s.id == *n)
                    .map(|s| s.label)
                    .ok_or_else(|| {
                        if self.segments.is_empty() {
                            format!("`{n}` is not a number and the image names no segments")
                        } else {
                            let names: Vec<&str> =
                                self.segments.iter().map(|s| s.name.as_str()).collect();
                            format!(
                                "no segment is named `{n}`; the image has {}",
                                names.join(", ")
                            )
                        }
                    }),
            })
            .collect()
    }

    /// Count, range, mean, zero and negative voxels.
    pub fn stats(&self) -> ImageStats {
        let (min, max) = self.min_max().unwrap_or((f32::NAN, f32::NAN));
        let mut sum = 0.0f64;
        let mut finite = 0usize;
        for &v in self.values.iter().filter(|v| !v.is_nan()) {
            sum += f64::from(v);
            finite += 1;
        }
        ImageStats {
            count: self.values.len(),
            min,
            max,
            mean: if finite > 0 {
                sum / finite as f64
            } else {
                f64::NAN
            },
            zeros: self.values.iter().filter(|&&v| v == 0.0).count(),
            negatives: self.values.iter().filter(|&&v| v < 0.0).count(),
        }
    }
}

/// Converts stored samples to `f32`, then applies `value·slope + inter` when `scaling` is
/// given. `bytes.len()` must be a multiple of the type size (readers check the exact size
/// first); a trailing partial sample would be dropped, never read out of bounds.
pub(crate) fn decode(
    bytes: &[u8],
    ty: SourceType,
    order: ByteOrder,
    scaling: Option<(f64, f64)>,
) -> Vec<f32> {
    fn arr<const N: usize>(c: &[u8], order: ByteOrder) -> [u8; N] {
        let mut a = [0u8; N];
        for (dst, src) in a.iter_mut().zip(c) {
            *dst = *src;
        }
        if order == ByteOrder::Big {
            a.reverse();
        }
        a
    }
    let size = ty.size();
    let raw = bytes.chunks_exact(size).map(|c| -> f64 {
        // Every branch reads little-endian after `arr` has put the bytes in that order.
        match ty {
            SourceType::U8 => f64::from(c.first().copied().unwrap_or(0)),
            SourceType::I8 => f64::from(c.first().copied().unwrap_or(0) as i8),
            SourceType::I16 => f64::from(i16::from_le_bytes(arr(c, order))),
            SourceType::U16 => f64::from(u16::from_le_bytes(arr(c, order))),
            SourceType::I32 => f64::from(i32::from_le_bytes(arr(c, order))),
            SourceType::U32 => f64::from(u32::from_le_bytes(arr(c, order))),
            // Labels and intensities far beyond 2^53 do not occur in images; the nearest
            // f64 is what f32 samples could hold anyway.
            SourceType::I64 => i64::from_le_bytes(arr(c, order)) as f64,
            SourceType::U64 => u64::from_le_bytes(arr(c, order)) as f64,
            SourceType::F32 => f64::from(f32::from_le_bytes(arr(c, order))),
            SourceType::F64 => f64::from_le_bytes(arr(c, order)),
        }
    });
    match scaling {
        Some((slope, inter)) => raw.map(|v| (v * slope + inter) as f32).collect(),
        None => raw.map(|v| v as f32).collect(),
    }
}

/// Voxel count and byte count of a grid, or `None` when they overflow `usize`.
pub(crate) fn data_size(dims: [usize; 3], ty: SourceType) -> Option<(usize, usize)> {
    let n = dims[0].checked_mul(dims[1])?.checked_mul(dims[2])?;
    Some((n, n.checked_mul(ty.size())?))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image() -> VoxelImage {
        VoxelImage {
            dims: [2, 3, 4],
            spacing: Vec3::new(0.5, 1.0, 2.0),
            origin: Vec3::new(1.0, -1.0, 0.0),
            values: (0..24).map(|v| v as f32 - 3.0).collect(),
            source_type: SourceType::I8,
            byte_order: ByteOrder::Little,
            segments: Vec::new(),
        }
    }

    #[test]
    fn x_runs_fastest_and_positions_are_centres() {
        let im = image();
        assert_eq!(im.index(1, 0, 0), Some(1));
        assert_eq!(im.index(0, 1, 0), Some(2));
        assert_eq!(im.index(0, 0, 1), Some(6));
        assert_eq!(im.index(1, 2, 3), Some(23));
        assert_eq!(im.index(2, 0, 0), None);
        assert_eq!(im.value(1, 2, 3), Some(20.0));
        assert_eq!(im.value(0, 3, 0), None);
        assert_eq!(im.position(1, 2, 3), Vec3::new(1.5, 1.0, 6.0));
    }

    #[test]
    fn stats_and_threshold_count_exactly() {
        let im = image();
        assert_eq!(im.min_max(), Some((-3.0, 20.0)));
        let s = im.stats();
        assert_eq!((s.count, s.zeros, s.negatives), (24, 1, 3));
        assert!((s.mean - 8.5).abs() < 1e-12);
        let mask = im.threshold(0.0, 4.0);
        assert_eq!(mask.iter().filter(|&&b| b).count(), 5);
        assert!(mask[3] && mask[7] && !mask[8]);
    }

    #[test]
    fn decode_respects_order_type_and_scaling() {
        let be = [0x01, 0x02, 0xff, 0xfe];
        let v = decode(&be, SourceType::I16, ByteOrder::Big, None);
        assert_eq!(v, vec![258.0, -2.0]);
        let v = decode(&be, SourceType::U16, ByteOrder::Little, Some((2.0, 1.0)));
        assert_eq!(v, vec![1027.0, 130_559.0]);
        let f = 1.5f64.to_be_bytes();
        assert_eq!(decode(&f, SourceType::F64, ByteOrder::Big, None), vec![1.5]);
        assert_eq!(
            decode(&[0x80, 5], SourceType::I8, ByteOrder::Big, None),
            vec![-128.0, 5.0]
        );
    }

    #[test]
    fn data_size_overflow_is_none() {
        assert_eq!(data_size([2, 3, 4], SourceType::F32), Some((24, 96)));
        assert_eq!(data_size([usize::MAX, 2, 1], SourceType::U8), None);
    }
}
