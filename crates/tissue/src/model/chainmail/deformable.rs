//! `Deformable` for `ChainMail`, and its topology edits: `cut` (links crossed by a scalpel
//! sweep), `carve` (elements under a ball) and `join` (links between touching elements).
//! The links live in the shared `voxel::VoxelLinks`. After an edit the drawn surface is the
//! closed boundary of the linked voxels (`voxel::DrawnBoundary`, redrawn near the edit),
//! numbered after the given surface's vertices, which stay (undrawn, still following their
//! elements) so that constraints naming them keep their meaning.

use std::collections::BTreeMap;

use crate::error::SimError;
use crate::interact::{Constraints, Loads};
use crate::math::{Real, Vec3, is_finite_vec};
use crate::model::{CutInfo, CutPath, Deformable, ModelInfo, Reactions, StepInfo, SurfaceView};
use crate::voxel::DrawnSurface;
use crate::voxel::topology::Link;

use super::ChainMail;

impl ChainMail {
    /// Removes the elements whose centre lies within `radius` of `centre` (current
    /// positions); returns how many.
    pub fn carve(&mut self, centre: Vec3, radius: Real) -> Result<usize, SimError> {
        if !(is_finite_vec(centre) && radius.is_finite() && radius >= 0.0) {
            return Err(SimError::BadParameter {
                name: "carve",
                value: format!("{centre} r {radius}"),
                reason: "the tool must be finite with radius >= 0".into(),
            });
        }
        let l = &mut self.lattice;
        let x = &l.x;
        let (gone, links) = l.topology.carve(|v| x[v], centre, radius);
        l.unpin(&gone.iter().map(|&v| v as u32).collect::<Vec<_>>());
        if !gone.is_empty() {
            let topology = &self.lattice.topology;
            self.embedding.rebind_first(self.original_vertices, |_, n| {
                topology.is_occupied(n as usize)
            });
            self.topology_changed(&links, &gone);
        }
        Ok(gone.len())
    }

    /// Links elements that are lattice neighbours, unlinked, and within their link limits
    /// (to `tol` m); returns the links added.
    pub fn join(&mut self, tol: Real) -> usize {
        let added = self.lattice.join(tol.max(0.0));
        if !added.is_empty() {
            self.topology_changed(&added, &[]);
        }
        added.len()
    }

    /// After an edit: the drawn surface becomes the boundary of the linked voxels (closed
    /// whatever was cut); the given surface's vertices keep their numbers, undrawn.
    fn topology_changed(&mut self, edited: &[Link], removed: &[usize]) {
        self.topology_version += 1;
        let surface = DrawnSurface {
            embedding: &mut self.embedding,
            original: self.original_vertices,
            triangles: &mut self.triangles,
            element_of: None,
        };
        self.drawn
            .redraw(surface, &self.lattice.topology, edited, removed);
        let n = self.embedding.len();
        self.surface.resize(n, Vec3::ZERO);
        self.fixed_vertex.resize(n, false);
        self.vertex_area = vec![0.0; n];
        self.refresh_surface();
        for t in &self.triangles {
            let [a, b, c] = t.map(|v| self.surface[v as usize]);
            let share = 0.5 * (b - a).cross(c - a).length() / 3.0;
            for &v in t {
                self.vertex_area[v as usize] += share;
            }
        }
    }
}

impl Deformable for ChainMail {
    fn kind(&self) -> &'static str {
        "chainmail"
    }

    fn surface(&self) -> SurfaceView<'_> {
        SurfaceView {
            positions: &self.surface,
            triangles: &self.triangles,
        }
    }

    fn rest_surface(&self) -> &[Vec3] {
        &self.embedding.rest
    }

    fn set_constraints(&mut self, c: &Constraints) -> Result<(), SimError> {
        let held = c.surface_displacements(&self.embedding.rest)?;
        let mut is_fixed = vec![false; held.len()];
        for &v in &c.fixed {
            is_fixed[v as usize] = true;
        }
        let mut fixed = Vec::new();
        for (v, _) in is_fixed.iter().enumerate().filter(|(_, f)| **f) {
            {
                for (k, &n) in self.embedding.nodes[v].iter().enumerate() {
                    if self.embedding.weights[v][k] != 0.0 {
                        fixed.push(n);
                    }
                }
            }
        }
        fixed.sort_unstable();
        fixed.dedup();
        self.fixed_elements = fixed;
        self.fixed_vertex = is_fixed;
        self.fixed_reactions = vec![Vec3::ZERO; c.fixed.len()];
        self.prescribed_reactions = vec![Vec3::ZERO; c.prescribed.len()];
        self.constraints = c.clone();
        Ok(())
    }

    /// ChainMail has no forces: gravity and point loads are accepted and ignored.
    fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        if !is_finite_vec(loads.gravity)
            || loads.point_loads.iter().any(|(_, f)| !is_finite_vec(*f))
        {
            return Err(SimError::BadParameter {
                name: "loads",
                value: format!("gravity {}", loads.gravity),
                reason: "loads must be finite".into(),
            });
        }
        Ok(())
    }

    fn step(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(SimError::BadTimeStep { dt });
        }
        self.lattice.unpin(&self.pinned);
        let mut moves: Vec<(u32, Vec3)> = self
            .fixed_elements
            .iter()
            .map(|&e| (e, self.lattice.rest[e as usize]))
            .collect();
        // Each prescribed vertex asks the elements of its cell to move by what it misses
        // (weighted; an element shared by several vertices takes the weighted mean). In
        // element order: the propagation's result depends on the order of its sponsors, and
        // a `HashMap`'s order here (random per map) made the same press read forces 3.0e3 %
        // and 5.1e3 % off the reference in two runs of unchanged code.
        let mut wanted: BTreeMap<u32, (Vec3, Real)> = BTreeMap::new();
        for p in &self.constraints.prescribed {
            let v = p.vertex as usize;
            if self.fixed_vertex[v] {
                continue;
            }
            let missing = p.position - self.surface[v];
            for k in 0..8 {
                let w = self.embedding.weights[v][k];
                let n = self.embedding.nodes[v][k];
                // `fixed_elements` is sorted (`set_constraints`).
                if w != 0.0 && self.fixed_elements.binary_search(&n).is_err() {
                    let e = wanted.entry(n).or_insert((Vec3::ZERO, 0.0));
                    e.0 += w * missing;
                    e.1 += w;
                }
            }
        }
        moves.extend(
            wanted
                .into_iter()
                .map(|(n, (d, w))| (n, self.lattice.x[n as usize] + d / w)),
        );
        self.pinned = moves.iter().map(|m| m.0).collect();
        self.last = self.lattice.move_elements(&moves);
        self.lattice
            .relax(self.params.relax_iterations, self.params.relax_rate);
        if self.params.relax_iterations > 0 {
            let enforced = self.lattice.enforce();
            self.last.moved += enforced.moved;
            self.last.checks += enforced.checks;
            self.last.converged &= enforced.converged;
        }
        self.refresh_surface();
        if let Some(v) = self.surface.iter().position(|p| !is_finite_vec(*p)) {
            self.lattice.reset();
            self.refresh_surface();
            return Err(SimError::Diverged {
                step: self.steps + 1,
                node: v,
                reason: "a surface position is not finite".into(),
            });
        }
        for (k, p) in self.constraints.prescribed.iter().enumerate() {
            self.prescribed_reactions[k] = self.instrument_force(p.vertex as usize, p.position);
        }
        self.steps += 1;
        Ok(StepInfo {
            iterations: self.last.moved,
            residual: 0.0,
            ..StepInfo::default()
        })
    }

    fn reactions(&self) -> Reactions<'_> {
        Reactions {
            fixed: &self.fixed_reactions,
            prescribed: &self.prescribed_reactions,
        }
    }

    /// Removes every link whose segment (current positions) crosses the blade's swept quad.
    fn cut(&mut self, blade: &CutPath) -> Result<CutInfo, SimError> {
        blade.check()?;
        let x = &self.lattice.x;
        let cut = self.lattice.topology.cut(|v| x[v], blade);
        if !cut.is_empty() {
            // The given surface's vertices drop the elements now across the blade (the drawn
            // ones are redrawn below).
            let (surface, x) = (&self.surface, &self.lattice.x);
            self.embedding.rebind_first(self.original_vertices, |v, n| {
                blade.crossing(surface[v], x[n as usize]).is_none()
            });
            self.topology_changed(&cut, &[]);
        }
        Ok(CutInfo {
            removed_elements: cut.len(),
            added_vertices: 0,
            topology_version: self.topology_version,
        })
    }

    fn reset(&mut self) {
        self.lattice.reset();
        self.refresh_surface();
    }

    fn info(&self) -> ModelInfo {
        let l = &self.lattice;
        let elements = l.topology.labels.iter().filter(|&&c| c != 0).count();
        ModelInfo {
            kind: self.kind(),
            nodes: elements,
            dofs: 3 * elements,
            elements: l.link_count(),
            surface_vertices: self.surface.len(),
            memory_bytes: l.len() * (2 * 24 + 6) + self.surface.len() * (24 * 2 + 8 * 12),
            precompute_seconds: self.precompute_seconds,
            is_static: false,
            details: vec![
                ("lattice".into(), format!("{:?}", l.dims)),
                ("voxel_size".into(), format!("{:.4e}", l.spacing.x)),
                (
                    "force_stiffness".into(),
                    format!("{:.4e}", self.force_stiffness),
                ),
                ("last_moved".into(), self.last.moved.to_string()),
                ("steps".into(), self.steps.to_string()),
            ],
        }
    }
}
