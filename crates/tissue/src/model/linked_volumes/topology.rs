//! Topology edits of linked volumes on the shared `voxel::VoxelLinks`: `cut` removes the
//! springs whose segment crosses a scalpel sweep, `carve` removes the voxels under a ball
//! (with their springs), `join` restores springs between touching lattice neighbours.
//!
//! Springs change locally (only the edited pairs are removed or re-made with their
//! original stiffness, rest length and damper) and the integrator is invalidated, since
//! its cached Jacobians belong to the old springs. A carved element keeps its particle (ids
//! stay compact and stable) but has no spring left and is no longer drawn or held; it
//! drifts with its own velocity, out of sight. After any edit the drawn surface is the
//! closed boundary of the linked voxels (`voxel::DrawnBoundary`, redrawn near the edit),
//! numbered after the given surface's vertices, which stay (undrawn, following their
//! elements) so that constraints naming them keep their meaning.

use std::collections::HashSet;

use rustc_hash::FxHashSet;

use crate::error::SimError;
use crate::math::{Real, Vec3, is_finite_vec};
use crate::model::{CutInfo, CutPath};
use crate::voxel::DrawnSurface;
use crate::voxel::topology::Link;

use super::{LinkedVolumes, spring_for};

impl LinkedVolumes {
    /// Removes every spring crossing the blade's swept quad (current positions); the
    /// `Deformable::cut` of this model.
    pub fn cut_links(&mut self, blade: &CutPath) -> Result<CutInfo, SimError> {
        blade.check()?;
        let (x, id) = (&self.state.x, &self.element_of);
        let at = |v: usize| x[id[v] as usize];
        let removed = self.topology.cut(at, blade);
        if !removed.is_empty() {
            self.remove_springs(&removed);
            // The given surface's vertices drop the elements now across the blade (the drawn
            // ones are redrawn below).
            let (surface, x) = (&self.surface, &self.state.x);
            self.embedding.rebind_first(self.original_vertices, |v, n| {
                blade.crossing(surface[v], x[n as usize]).is_none()
            });
            self.topology_changed(&removed, &[]);
        }
        Ok(CutInfo {
            removed_elements: removed.len(),
            added_vertices: 0,
            topology_version: self.topology_version,
        })
    }

    /// Removes the elements whose current position is within `radius` of `centre`, with
    /// their springs; returns how many.
    pub fn carve(&mut self, centre: Vec3, radius: Real) -> Result<usize, SimError> {
        if !(is_finite_vec(centre) && radius.is_finite() && radius >= 0.0) {
            return Err(SimError::BadParameter {
                name: "carve",
                value: format!("{centre} r {radius}"),
                reason: "the tool must be finite with radius >= 0".into(),
            });
        }
        let (x, id) = (&self.state.x, &self.element_of);
        let at = |v: usize| x[id[v] as usize];
        let (gone, links) = self.topology.carve(at, centre, radius);
        if gone.is_empty() {
            return Ok(0);
        }
        self.remove_springs(&links);
        let carved: HashSet<u32> = gone.iter().map(|&v| self.element_of[v]).collect();
        self.embedding
            .rebind_first(self.original_vertices, |_, n| !carved.contains(&n));
        self.fixed_elements.retain(|e| !carved.contains(e));
        self.topology_changed(&links, &gone);
        Ok(gone.len())
    }

    /// Restores the springs between unlinked lattice neighbours whose current offset is
    /// their rest offset to `tol` m (touching as at rest); returns the springs added.
    pub fn join(&mut self, tol: Real) -> usize {
        let tol = tol.max(0.0);
        let (x, id, topo) = (&self.state.x, &self.element_of, &mut self.topology);
        let (spacing, origin) = (topo.spacing, topo.origin);
        let dims = topo.dims;
        let centre = |v: usize| {
            let (i, j, k) = (
                v % dims[0],
                (v / dims[0]) % dims[1],
                v / (dims[0] * dims[1]),
            );
            origin + Vec3::new(i as Real, j as Real, k as Real) * spacing
        };
        let added = topo.join(|a, b, _| {
            let (xa, xb) = (x[id[a] as usize], x[id[b] as usize]);
            ((xb - xa) - (centre(b) - centre(a))).length() <= tol
        });
        if added.is_empty() {
            return 0;
        }
        let springs: Vec<_> = added
            .iter()
            .filter_map(|&(a, d)| {
                let b = self.topology.linked(a as usize, d as usize)?;
                let ids = [self.element_of[a as usize], self.element_of[b]];
                Some(spring_for(
                    &self.material,
                    self.spring_modulus,
                    self.coef,
                    self.topology.spacing,
                    ids,
                    d as usize,
                ))
            })
            .collect();
        self.system.edit_springs(|_| true, &springs);
        self.topology_changed(&added, &[]);
        added.len()
    }

    /// The links in use (each once), for inspection and tests.
    pub fn link_count(&self) -> usize {
        self.topology.link_count()
    }

    /// Bumped on every cut, carve or join that changed something.
    pub fn topology_version(&self) -> u32 {
        self.topology_version
    }

    fn remove_springs(&mut self, links: &[Link]) {
        let key = |a: u32, b: u32| (a.min(b), a.max(b));
        let gone: FxHashSet<(u32, u32)> = links
            .iter()
            .filter_map(|&(a, d)| {
                let b = self.topology.lattice_neighbour(a as usize, d as usize)?;
                Some(key(self.element_of[a as usize], self.element_of[b]))
            })
            .collect();
        // Every spring is tested: a lookup by element first, so that only the few springs
        // at a cut element are hashed.
        let mut at_cut = vec![false; self.rest.len()];
        for &(a, b) in &gone {
            at_cut[a as usize] = true;
            at_cut[b as usize] = true;
        }
        self.system.edit_springs(
            |s| !(at_cut[s.a as usize] && gone.contains(&key(s.a, s.b))),
            &[],
        );
    }

    fn topology_changed(&mut self, edited: &[Link], removed: &[usize]) {
        self.topology_version += 1;
        // The volume term's stencils follow the links: none across a cut.
        self.system.rebuild_volume_term(&self.rest);
        self.integrator.invalidate();
        let surface = DrawnSurface {
            embedding: &mut self.embedding,
            original: self.original_vertices,
            triangles: &mut self.triangles,
            element_of: Some(&self.element_of),
        };
        self.drawn.redraw(surface, &self.topology, edited, removed);
        let n = self.embedding.len();
        self.surface.resize(n, Vec3::ZERO);
        self.fixed_vertex.resize(n, false);
        self.refresh_surface();
    }
}
