//! Cleaning a selected voxel mask the way a segmentation is cleaned in an editor before it
//! is meshed: a morphological opening and closing (single-voxel specks, bumps, pinholes and
//! cracks go), only the largest connected part kept, enclosed holes filled. A lattice of
//! spacing h cannot follow features smaller than h anyway; left in, they break the mesher's
//! boundary-distance guarantee or pull its volume away from the voxels'.

use serde::Serialize;

use crate::math::Real;

/// What `clean_mask` does. `Default` is what the CLI and scenes use.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cleaning {
    /// Radius (m) of a closing by a ball before everything else: cracks and channels of the
    /// background narrower than twice this are selected, nothing selected is removed; 0 for
    /// none. Done by `ImageDomain::cleaned`, which knows the voxel spacing
    /// (`image::close_ball`); `clean_mask` ignores it.
    pub close: Real,
    /// Radius (m) of an opening by a ball after `close`: sheets and strands thinner than
    /// twice this are unselected, nothing unselected is added; 0 for none
    /// (`image::open_ball`, by `ImageDomain::cleaned`; `clean_mask` ignores it).
    pub open: Real,
    /// Radius (voxels, 6-neighbourhood steps) of the opening then closing; 0 for none.
    pub open_close: usize,
    /// Keep only the largest 6-connected part.
    pub largest_component: bool,
    /// Select the unselected voxels that the outside cannot reach (6-connected).
    pub fill_holes: bool,
}

impl Default for Cleaning {
    fn default() -> Self {
        Self {
            open: 0.0,
            close: 0.0,
            open_close: 1,
            largest_component: true,
            fill_holes: true,
        }
    }
}

impl Cleaning {
    /// Leaves the mask as it is.
    pub const NONE: Self = Self {
        open: 0.0,
        close: 0.0,
        open_close: 0,
        largest_component: false,
        fill_holes: false,
    };
}

/// What cleaning changed, in voxels, and the opening-closing radius that was asked for (a
/// user's choice that changes the input every guarantee is measured against, so it is said).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct CleanReport {
    /// `Cleaning::open`: radius (m) of the ball opening; 0 for none.
    pub open: Real,
    /// Voxels the ball opening unselected (sheets and strands it removed).
    pub opened_voxels: usize,
    /// `Cleaning::close`: radius (m) of the ball closing; 0 for none.
    pub close: Real,
    /// Voxels the ball closing selected (cracks of the background it filled).
    pub closed_voxels: usize,
    /// `Cleaning::open_close`: radius in voxels of the opening then closing; 0 for none.
    pub open_close: usize,
    pub voxels_before: usize,
    pub voxels_after: usize,
    /// Parts dropped for not being the largest.
    pub parts_dropped: usize,
    /// Voxels added by filling enclosed holes.
    pub hole_voxels_filled: usize,
}

/// Cleans `mask` (x fastest, then y, then z, over `dims`) in place as `c` says.
pub fn clean_mask(mask: &mut [bool], dims: [usize; 3], c: Cleaning) -> CleanReport {
    let mut report = CleanReport {
        open_close: c.open_close,
        voxels_before: count(mask),
        ..Default::default()
    };
    for _ in 0..c.open_close {
        step(mask, dims, false);
    }
    for _ in 0..2 * c.open_close {
        step(mask, dims, true);
    }
    for _ in 0..c.open_close {
        step(mask, dims, false);
    }
    if c.largest_component {
        let parts = components(mask, dims, true);
        if let Some(largest) = (0..parts.sizes.len()).max_by_key(|&p| parts.sizes[p]) {
            report.parts_dropped = parts.sizes.len() - 1;
            for (m, &p) in mask.iter_mut().zip(&parts.of) {
                *m = *m && p == largest as u32;
            }
        }
    }
    if c.fill_holes {
        let outside = components(mask, dims, false);
        // Background parts that touch the image's border are the outside.
        let mut open = vec![false; outside.sizes.len()];
        for (n, &p) in outside.of.iter().enumerate() {
            if p != u32::MAX && on_border(n, dims) {
                open[p as usize] = true;
            }
        }
        for (m, &p) in mask.iter_mut().zip(&outside.of) {
            if !*m && p != u32::MAX && !open[p as usize] {
                *m = true;
                report.hole_voxels_filled += 1;
            }
        }
    }
    report.voxels_after = count(mask);
    report
}

fn count(mask: &[bool]) -> usize {
    mask.iter().filter(|&&m| m).count()
}

fn on_border(n: usize, [nx, ny, nz]: [usize; 3]) -> bool {
    let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
    i == 0 || j == 0 || k == 0 || i + 1 == nx || j + 1 == ny || k + 1 == nz
}

/// The in-range 6-neighbours of voxel `n`.
fn neighbours(n: usize, [nx, ny, nz]: [usize; 3]) -> impl Iterator<Item = usize> {
    let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
    let plane = nx * ny;
    [
        (i > 0).then(|| n - 1),
        (i + 1 < nx).then(|| n + 1),
        (j > 0).then(|| n - nx),
        (j + 1 < ny).then(|| n + nx),
        (k > 0).then(|| n - plane),
        (k + 1 < nz).then(|| n + plane),
    ]
    .into_iter()
    .flatten()
}

/// One dilation (`grow`) or erosion by the 6-neighbourhood. Beyond the image the mask
/// repeats its border voxel, so a body cut by the image's edge is not eaten from there.
fn step(mask: &mut [bool], dims: [usize; 3], grow: bool) {
    let src = mask.to_vec();
    for (n, m) in mask.iter_mut().enumerate() {
        *m = if grow {
            src[n] || neighbours(n, dims).any(|q| src[q])
        } else {
            src[n] && neighbours(n, dims).all(|q| src[q])
        };
    }
}

struct Parts {
    /// The part of every voxel of the chosen kind, `u32::MAX` for the others.
    of: Vec<u32>,
    sizes: Vec<usize>,
}

/// The 6-connected parts of the voxels whose mask is `selected`.
fn components(mask: &[bool], dims: [usize; 3], selected: bool) -> Parts {
    let mut of = vec![u32::MAX; mask.len()];
    let mut sizes = Vec::new();
    let mut stack = Vec::new();
    for start in 0..mask.len() {
        if mask[start] != selected || of[start] != u32::MAX {
            continue;
        }
        let part = sizes.len() as u32;
        let mut size = 0;
        of[start] = part;
        stack.push(start);
        while let Some(n) = stack.pop() {
            size += 1;
            for q in neighbours(n, dims) {
                if mask[q] == selected && of[q] == u32::MAX {
                    of[q] = part;
                    stack.push(q);
                }
            }
        }
        sizes.push(size);
    }
    Parts { of, sizes }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ball(n: usize, r: f64, c: f64) -> Vec<bool> {
        (0..n * n * n)
            .map(|v| {
                let p = [v % n, (v / n) % n, v / (n * n)].map(|x| x as f64 - c);
                (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() <= r
            })
            .collect()
    }

    /// A ball with a speck outside, an enclosed cavity and a one-voxel-thin hair: cleaning
    /// removes the speck and the hair, fills the cavity, and changes the ball's own surface
    /// by less than 2 % of its voxels.
    #[test]
    fn specks_spikes_pinholes_and_cavities_go_and_the_ball_stays() {
        let n = 24;
        let dims = [n; 3];
        let clean = ball(n, 7.0, 11.5);
        let mut noisy = clean.clone();
        let at = |i: usize, j: usize, k: usize| i + n * (j + n * k);
        noisy[at(2, 2, 2)] = true; // speck
        noisy[at(11, 11, 11)] = false; // cavity (enclosed)
        noisy[at(12, 12, 12)] = false;
        for z in 19..23 {
            noisy[at(11, 11, z)] = true; // a hair out of the top
        }
        let before = count(&noisy);
        let r = clean_mask(&mut noisy, dims, Cleaning::default());
        assert_eq!(r.voxels_before, before);
        // The opening takes the hair back to the one voxel its root regrows.
        assert!(!noisy[at(2, 2, 2)] && !noisy[at(11, 11, 20)], "{r:?}");
        assert!(noisy[at(11, 11, 11)] && noisy[at(12, 12, 12)], "{r:?}");
        let changed = noisy.iter().zip(&clean).filter(|(a, b)| a != b).count();
        assert!(
            (changed as f64) < 0.02 * count(&clean) as f64,
            "{changed} {r:?}"
        );
        // Without the opening, the speck is a second part and the cavity a hole.
        let mut noisy2 = clean.clone();
        noisy2[at(2, 2, 2)] = true;
        noisy2[at(11, 11, 11)] = false;
        let r = clean_mask(
            &mut noisy2,
            dims,
            Cleaning {
                open_close: 0,
                ..Cleaning::default()
            },
        );
        assert_eq!((r.parts_dropped, r.hole_voxels_filled), (1, 1), "{r:?}");
        assert_eq!(noisy2, clean);
    }

    #[test]
    fn nothing_changes_without_cleaning_and_an_empty_mask_stays_empty() {
        let mut m = ball(10, 3.0, 4.5);
        let want = m.clone();
        clean_mask(&mut m, [10; 3], Cleaning::NONE);
        assert_eq!(m, want);
        let mut e = vec![false; 1000];
        let r = clean_mask(&mut e, [10; 3], Cleaning::default());
        assert_eq!(r.voxels_after, 0);
    }
}
