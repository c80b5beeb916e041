//! A segmented volume image as a domain: the voxels selected (by labels or a threshold
//! window) make a mask, and the boundary is the 1/2 level of the mask's trilinear
//! interpolation, which passes half way between a selected voxel centre and an unselected
//! one, so the meshed volume follows the selected voxels' volume.

use crate::error::MeshError;
use crate::image::{
    CleanReport, Cleaning, VoxelImage, clean_mask, close_ball, open_ball, open_close_ball,
};
use crate::math::{Real, Vec3};
use crate::voxel::VoxelGrid;

use super::domain::Domain;

#[derive(Clone, Debug)]
pub struct ImageDomain {
    dims: [usize; 3],
    spacing: Vec3,
    origin: Vec3,
    /// 1 for a selected voxel, 0 otherwise (between after `smoothed`).
    mask: Vec<f32>,
    /// The label of every voxel (its value, rounded), for tags; empty for a threshold.
    labels: Vec<i32>,
    /// The level of the (blurred) mask that is the boundary: 1/2. (Choosing instead the
    /// level that keeps the voxel count after a blur was tried: on the brain image it brought
    /// back sub-lattice features and did not bring the volume closer.)
    level: f32,
    lo: Vec3,
    hi: Vec3,
    selected: usize,
    /// What `cleaned` changed (the selected voxels before it are the report's second
    /// reference volume).
    cleaning: Option<CleanReport>,
    /// The cleaning kept the largest part only: the mesh keeps its largest piece.
    one_piece: bool,
    /// With two labels or more, each meshed as its own region (`Domain::material_tags`):
    /// the labels, and per label its indicator field (1 on its selected voxels, 0
    /// elsewhere; blurred with the mask), whose trilinear interpolations decide which
    /// label holds a point (the largest) and where two labels meet (equal values).
    materials: Vec<i32>,
    fields: Vec<Vec<f32>>,
    material_voxels: Vec<usize>,
}

impl ImageDomain {
    /// The voxels whose value is one of `labels`; every tetrahedron is tagged with the label
    /// of the selected voxel nearest to its centre.
    pub fn from_labels(image: &VoxelImage, labels: &[f32]) -> Result<Self, MeshError> {
        if labels.is_empty() {
            return Err(MeshError::Invalid("no label to mesh was given".into()));
        }
        let mask: Vec<bool> = image.values.iter().map(|v| labels.contains(v)).collect();
        let tags = image.values.iter().map(|&v| v.round() as i32).collect();
        let mut materials: Vec<i32> = Vec::new();
        for l in labels {
            let t = l.round() as i32;
            if !materials.contains(&t) {
                materials.push(t);
            }
        }
        Ok(
            Self::from_mask(image, mask, tags, &format!("labels {labels:?}"))?
                .with_materials(materials),
        )
    }

    /// The voxels with `lo <= value <= hi`, all tagged 1.
    pub fn from_threshold(image: &VoxelImage, lo: f32, hi: f32) -> Result<Self, MeshError> {
        let mask = image.threshold(lo, hi);
        Self::from_mask(image, mask, Vec::new(), &format!("threshold {lo}..{hi}"))
    }

    /// The occupied voxels of a voxel grid (a scene's `[image]` after threshold, stride and
    /// component selection), tagged by their material class.
    pub fn from_grid(grid: &VoxelGrid) -> Result<Self, MeshError> {
        let image = VoxelImage {
            dims: grid.dims,
            spacing: grid.spacing,
            origin: grid.origin,
            values: Vec::new(),
            source_type: crate::image::SourceType::U8,
            byte_order: crate::image::ByteOrder::Little,
            segments: Vec::new(),
        };
        let mask = grid.labels.iter().map(|&l| l > 0).collect();
        let tags = grid.labels.iter().map(|&l| i32::from(l)).collect();
        let mut materials: Vec<i32> = grid
            .labels
            .iter()
            .filter(|&&l| l > 0)
            .map(|&l| i32::from(l))
            .collect();
        materials.sort_unstable();
        materials.dedup();
        Ok(Self::from_mask(&image, mask, tags, "the grid")?.with_materials(materials))
    }

    /// With two labels or more, each becomes a region of its own: its indicator field is
    /// built from the selected voxels (`fields`). One label keeps the single-region path.
    fn with_materials(mut self, materials: Vec<i32>) -> Self {
        if materials.len() < 2 {
            self.materials.clear();
            self.fields.clear();
            self.material_voxels.clear();
            return self;
        }
        let n = self.mask.len();
        let mut fields = vec![vec![0f32; n]; materials.len()];
        let mut counts = vec![0usize; materials.len()];
        for (v, (&mask, &label)) in self.mask.iter().zip(&self.labels).enumerate() {
            if mask < 0.5 {
                continue;
            }
            // A selected voxel whose label is not one of the materials (a hole filled by
            // the cleaning whose label could not be spread) joins the first.
            let k = materials.iter().position(|&m| m == label).unwrap_or(0);
            fields[k][v] = 1.0;
            counts[k] += 1;
        }
        self.materials = materials;
        self.fields = fields;
        self.material_voxels = counts;
        self
    }

    /// The label tags meshed as separate regions (empty for one region).
    pub fn materials(&self) -> &[i32] {
        &self.materials
    }

    /// Trilinear interpolation of a voxel field at `p`.
    fn interpolate(&self, field: &[f32], p: Vec3) -> Real {
        let u = (p - self.origin) / self.spacing;
        let f = u.floor();
        let (i, j, k) = (f.x as i64, f.y as i64, f.z as i64);
        let t = u - f;
        let [nx, ny, nz] = self.dims.map(|v| v as i64);
        let mut m = 0.0;
        for c in 0..8 {
            let (di, dj, dk) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
            let w = (if di == 1 { t.x } else { 1.0 - t.x })
                * (if dj == 1 { t.y } else { 1.0 - t.y })
                * (if dk == 1 { t.z } else { 1.0 - t.z });
            let (a, b, cc) = (i + di, j + dj, k + dk);
            if w > 0.0 && a >= 0 && b >= 0 && cc >= 0 && a < nx && b < ny && cc < nz {
                m += w * Real::from(field[(a + nx * (b + ny * cc)) as usize]);
            }
        }
        m
    }

    fn from_mask(
        image: &VoxelImage,
        mask: Vec<bool>,
        labels: Vec<i32>,
        what: &str,
    ) -> Result<Self, MeshError> {
        let [nx, ny, _] = image.dims;
        let (mut lo, mut hi) = (Vec3::splat(Real::INFINITY), Vec3::splat(-Real::INFINITY));
        let mut selected = 0;
        for (n, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
            let p = image.position(n % nx, (n / nx) % ny, n / (nx * ny));
            lo = lo.min(p);
            hi = hi.max(p);
            selected += 1;
        }
        if selected == 0 {
            return Err(MeshError::Invalid(format!(
                "no voxel of the image is selected by {what}"
            )));
        }
        Ok(Self {
            dims: image.dims,
            spacing: image.spacing,
            origin: image.origin,
            mask: mask.iter().map(|&m| if m { 1.0 } else { 0.0 }).collect(),
            labels,
            level: 0.5,
            lo: lo - image.spacing,
            hi: hi + image.spacing,
            selected,
            cleaning: None,
            one_piece: false,
            materials: Vec::new(),
            fields: Vec::new(),
            material_voxels: Vec::new(),
        })
    }

    /// Cleans the selected voxels (a closing by a ball of radius `c.close` when asked, then
    /// `image::clean_mask`: opening and closing, the largest part, enclosed holes filled)
    /// before any blur. The reference volume becomes the cleaned voxels'; the report also
    /// gives the volume against the voxels as selected. A voxel added by the cleaning takes
    /// the label of a selected neighbour.
    pub fn cleaned(mut self, c: Cleaning) -> Result<Self, MeshError> {
        if c == Cleaning::NONE {
            return Ok(self);
        }
        for (what, r) in [("opening", c.open), ("closing", c.close)] {
            if !(r.is_finite() && r >= 0.0) {
                return Err(MeshError::Invalid(format!(
                    "the {what} radius must be a length of 0 m or more, not {r}"
                )));
            }
        }
        let before: Vec<bool> = self.mask.iter().map(|&m| m >= 0.5).collect();
        // The ball filters first, in metres whatever the voxels' shape (the voxel-step
        // opening-closing of `clean_mask` reaches 3 times farther along a 2.5 mm axis than
        // along a 0.78 mm one): the closing first, so that bundles parted by cracks become
        // one body before the opening looks for what is thin.
        let closed = close_ball(&before, self.dims, self.spacing, c.close);
        let mut mask = open_ball(&closed, self.dims, self.spacing, c.open);
        let (closed_voxels, opened_voxels) =
            (mask_added(&before, &closed), mask_added(&mask, &closed));
        let mut report = clean_mask(&mut mask, self.dims, c);
        report.voxels_before = selected_in(&before);
        report.close = c.close;
        report.closed_voxels = closed_voxels;
        report.open = c.open;
        report.opened_voxels = opened_voxels;
        if report.voxels_after == 0 {
            return Err(MeshError::Invalid(format!(
                "cleaning removed all {} selected voxels (an opening of {} voxel(s) erases \
                 parts thinner than {} voxels); select more voxels or clean less",
                report.voxels_before,
                c.open_close,
                2 * c.open_close + 1
            )));
        }
        if !self.labels.is_empty() {
            // Added voxels take a label from a selected neighbour, spreading inwards.
            let [nx, ny, _] = self.dims;
            let mut known: Vec<bool> = before.iter().zip(&mask).map(|(b, m)| *b && *m).collect();
            let mut changed = true;
            while changed {
                changed = false;
                for n in 0..mask.len() {
                    if !mask[n] || known[n] {
                        continue;
                    }
                    let near = [1, nx, nx * ny]
                        .iter()
                        .flat_map(|&s| [n.checked_sub(s), Some(n + s)])
                        .flatten()
                        .find(|&q| q < mask.len() && known[q]);
                    if let Some(q) = near {
                        self.labels[n] = self.labels[q];
                        known[n] = true;
                        changed = true;
                    }
                }
            }
        }
        self.mask = mask.iter().map(|&m| if m { 1.0 } else { 0.0 }).collect();
        self.selected = report.voxels_after;
        self.cleaning = Some(report);
        self.one_piece = c.largest_component;
        let materials = std::mem::take(&mut self.materials);
        Ok(self.with_materials(materials))
    }

    /// Blurs the mask with a Gaussian of standard deviation `sigma` (m) along each axis, so
    /// that the 1/2 level no longer follows features much smaller than `sigma` (single-voxel
    /// bumps and holes of a noisy segmentation, which a lattice of spacing h cannot follow
    /// anyway). The reference volume stays the selected voxels' volume. 0 leaves the mask
    /// as it is.
    pub fn smoothed(mut self, sigma: Real) -> Self {
        if !(sigma.is_finite() && sigma > 0.0) {
            return self;
        }
        blur(&mut self.mask, self.dims, self.spacing, sigma);
        for field in &mut self.fields {
            blur(field, self.dims, self.spacing, sigma);
        }
        let grow = Vec3::splat(3.0 * sigma);
        self.lo -= grow;
        self.hi += grow;
        self
    }

    /// The same domain with every feature thinner than `size` gone: the voxels inside (the
    /// mask at or above its level) opened then closed by a ball of radius `size`/2
    /// (`image::open_close_ball`). Voxels the filter leaves as they were keep their (blurred)
    /// values, so the boundary is unchanged wherever the input is resolvable at this size;
    /// the others become 1 or 0. When the input is one piece (`one_piece`: the mesh keeps its
    /// largest piece), only the largest part of the filtered voxels is kept. This is the
    /// input a lattice of spacing `size` can follow, which the report checks the boundary
    /// guarantee against.
    pub fn at_resolution(&self, size: Real) -> Self {
        let inside: Vec<bool> = self.mask.iter().map(|&m| m >= self.level).collect();
        let mut resolved = open_close_ball(&inside, self.dims, self.spacing, 0.5 * size);
        if self.one_piece {
            // The mesh keeps its largest piece (`pieces`), so a part that the ball cut off
            // (joined to the rest only by a strand thinner than h, which the lattice cannot
            // follow) is not held against it either; the whole input's distance and the
            // "pieces:" line still report it. (The pelvis at 8 mm: a part of 3,239 voxels,
            // 2.8 h from the mesh, which had dropped it as a loose piece.)
            clean_mask(
                &mut resolved,
                self.dims,
                Cleaning {
                    open: 0.0,
                    close: 0.0,
                    open_close: 0,
                    largest_component: true,
                    fill_holes: false,
                },
            );
        }
        let mut out = self.clone();
        for ((m, &was), &now) in out.mask.iter_mut().zip(&inside).zip(&resolved) {
            if was != now {
                *m = if now { 1.0 } else { 0.0 };
            }
        }
        out
    }

    /// Number of selected voxels.
    pub fn selected_voxels(&self) -> usize {
        self.selected
    }

    fn at(&self, i: i64, j: i64, k: i64) -> f32 {
        let [nx, ny, nz] = self.dims.map(|v| v as i64);
        if i < 0 || j < 0 || k < 0 || i >= nx || j >= ny || k >= nz {
            return 0.0;
        }
        self.mask[(i + nx * (j + ny * k)) as usize]
    }
}

impl Domain for ImageDomain {
    fn value(&self, p: Vec3) -> Real {
        let u = (p - self.origin) / self.spacing;
        let f = u.floor();
        let (i, j, k) = (f.x as i64, f.y as i64, f.z as i64);
        let t = u - f;
        let mut m = 0.0;
        for c in 0..8 {
            let (di, dj, dk) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
            let w = (if di == 1 { t.x } else { 1.0 - t.x })
                * (if dj == 1 { t.y } else { 1.0 - t.y })
                * (if dk == 1 { t.z } else { 1.0 - t.z });
            if w > 0.0 {
                m += w * Real::from(self.at(i + di, j + dj, k + dk));
            }
        }
        Real::from(self.level) - m
    }

    fn bounds(&self) -> (Vec3, Vec3) {
        (self.lo, self.hi)
    }

    fn reference_volume(&self) -> Option<Real> {
        Some(self.selected as Real * self.spacing.x * self.spacing.y * self.spacing.z)
    }

    fn cleaning(&self) -> Option<(CleanReport, Real)> {
        let voxel = self.spacing.x * self.spacing.y * self.spacing.z;
        let c = self.cleaning.clone()?;
        let before = c.voxels_before as Real * voxel;
        Some((c, before))
    }

    fn at_resolution(&self, size: Real) -> Option<Box<dyn Domain>> {
        Some(Box::new(ImageDomain::at_resolution(self, size)))
    }

    fn one_piece(&self) -> bool {
        self.one_piece
    }

    fn material_tags(&self) -> &[i32] {
        &self.materials
    }

    /// The label whose indicator is largest at `p` (ties to the first listed).
    fn material_at(&self, p: Vec3) -> usize {
        let mut best = (0, Real::NEG_INFINITY);
        for (k, field) in self.fields.iter().enumerate() {
            let g = self.interpolate(field, p);
            if g > best.1 {
                best = (k, g);
            }
        }
        best.0
    }

    fn interface_value(&self, p: Vec3, a: usize, b: usize) -> Real {
        match (self.fields.get(a), self.fields.get(b)) {
            (Some(fa), Some(fb)) => self.interpolate(fb, p) - self.interpolate(fa, p),
            _ => 0.0,
        }
    }

    fn material_volumes(&self) -> Vec<Real> {
        let voxel = self.spacing.x * self.spacing.y * self.spacing.z;
        self.material_voxels
            .iter()
            .map(|&n| n as Real * voxel)
            .collect()
    }

    fn tag_at(&self, p: Vec3) -> i32 {
        if self.labels.is_empty() {
            return 1;
        }
        let u = ((p - self.origin) / self.spacing).round();
        let c = [u.x as i64, u.y as i64, u.z as i64];
        let [nx, ny, _] = self.dims.map(|v| v as i64);
        let mut best: Option<(Real, i32)> = None;
        for dk in -1..=1 {
            for dj in -1..=1 {
                for di in -1..=1 {
                    let (i, j, k) = (c[0] + di, c[1] + dj, c[2] + dk);
                    if self.at(i, j, k) < self.level {
                        continue;
                    }
                    let q = self.origin + Vec3::new(i as Real, j as Real, k as Real) * self.spacing;
                    let d = (q - p).length_squared();
                    if best.is_none_or(|(b, _)| d < b) {
                        best = Some((d, self.labels[(i + nx * (j + ny * k)) as usize]));
                    }
                }
            }
        }
        best.map_or(0, |(_, l)| l)
    }
}

/// Blurs a voxel field in place with a Gaussian of standard deviation `sigma` (m) along
/// each axis (voxels beyond the image count as 0).
fn blur(field: &mut [f32], dims: [usize; 3], spacing: Vec3, sigma: Real) {
    for axis in 0..3 {
        let s = sigma / spacing[axis];
        let radius = (3.0 * s).ceil() as usize;
        if radius == 0 {
            continue;
        }
        let kernel: Vec<f32> = {
            let k: Vec<Real> = (0..=2 * radius)
                .map(|i| {
                    let x = i as Real - radius as Real;
                    (-0.5 * x * x / (s * s)).exp()
                })
                .collect();
            let sum: Real = k.iter().sum();
            k.iter().map(|v| (v / sum) as f32).collect()
        };
        let [nx, ny, _] = dims;
        let stride = [1, nx, nx * ny][axis];
        let n = dims[axis];
        let mut line = vec![0f32; n];
        let src = field.to_vec();
        for start in 0..src.len() {
            // Each line along `axis` once, from its first voxel.
            if (start / stride) % n != 0 {
                continue;
            }
            for (i, l) in line.iter_mut().enumerate() {
                *l = src[start + i * stride];
            }
            for i in 0..n {
                let mut acc = 0.0f32;
                for (j, &w) in kernel.iter().enumerate() {
                    let k = i as i64 + j as i64 - radius as i64;
                    if k >= 0 && (k as usize) < n {
                        acc += w * line[k as usize];
                    }
                }
                field[start + i * stride] = acc;
            }
        }
    }
}

/// Number of voxels `after` selects that `before` did not.
fn mask_added(before: &[bool], after: &[bool]) -> usize {
    before
        .iter()
        .zip(after)
        .filter(|(b, a)| **a && !**b)
        .count()
}

/// Number of voxels `mask` selects.
fn selected_in(mask: &[bool]) -> usize {
    mask.iter().filter(|&&m| m).count()
}
