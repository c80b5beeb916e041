//! Scalpel strokes for the BEM: the incision is opened once per stroke, not per frame.
//!
//! A simulator calls `cut` with the blade's sweep over one frame. At an interactive rate
//! that sweep is a millimetre or two, shorter than the surface's edges, and one groove per
//! frame would leave a perforated line (each groove closes at its ends) and pay a bordering
//! update per frame. So consecutive sweeps that continue each other are joined into one
//! stroke, and the stroke's groove opens when the blade leaves the tissue (its edge no
//! longer meets the surface), when a sweep does not continue the stroke (a new stroke
//! starts), or at once when a single sweep is long enough to open a groove by itself (a
//! scene that moves the scalpel through the organ in one step).

use crate::error::SimError;
use crate::math::segment_triangle;
use crate::model::{CutInfo, CutPath};

use super::cut::{CutUpdate, OPENING, incise};
use super::model::Bem;

impl Bem {
    /// One frame's sweep of a scalpel stroke (see the module docs).
    pub(super) fn cut_stroke(&mut self, blade: &CutPath) -> Result<CutInfo, SimError> {
        if !blade.is_finite() {
            self.pending_cut = None;
            return self.incise(blade, CutUpdate::Bordering);
        }
        let mut info = CutInfo {
            topology_version: self.cuts,
            ..CutInfo::default()
        };
        let start = match self.pending_cut.take() {
            Some((start, end)) if end == blade.start => start,
            Some((start, end)) => {
                info = merge(info, self.incise_when_ready(&CutPath { start, end })?);
                blade.start
            }
            None => blade.start,
        };
        let stroke = CutPath {
            start,
            end: blade.end,
        };
        let opens_alone = incise(&self.surface, blade, OPENING)?.is_some();
        if opens_alone || !self.blade_meets_surface(blade.end) {
            let done = self.incise_when_ready(&stroke)?;
            return Ok(merge(info, done));
        }
        self.pending_cut = Some((stroke.start, stroke.end));
        Ok(info)
    }

    /// Whether the blade edge (a segment) crosses the rest surface.
    fn blade_meets_surface(&self, [p, q]: [crate::math::Vec3; 2]) -> bool {
        (0..self.surface.triangles.len())
            .any(|t| segment_triangle(p, q, self.surface.corners(t)).is_some())
    }
}

fn merge(a: CutInfo, b: CutInfo) -> CutInfo {
    CutInfo {
        removed_elements: a.removed_elements + b.removed_elements,
        added_vertices: a.added_vertices + b.added_vertices,
        topology_version: a.topology_version.max(b.topology_version),
    }
}
