//! `Deformable` for `ChainMail`, and its topology edits: `cut` (links crossed by a scalpel
//! sweep), `carve` (elements under a ball) and `join` (links between touching elements).
//! After an edit the rendered surface follows: vertices drop the corner elements now on the
//! other side of a cut or carved away, and triangles crossed by the blade or left without
//! elements are no longer drawn (vertex indices stay, so constraints stay valid).

use std::collections::HashMap;

use crate::error::SimError;
use crate::interact::{Constraints, Loads};
use crate::math::{Real, Vec3, is_finite_vec};
use crate::model::{CutInfo, CutPath, Deformable, ModelInfo, Reactions, StepInfo, SurfaceView};

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
        let gone: Vec<usize> = (0..l.len())
            .filter(|&v| l.class[v] != 0 && l.x[v].distance(centre) <= radius)
            .collect();
        for &v in &gone {
            l.remove(v);
        }
        if !gone.is_empty() {
            let class = &self.lattice.class;
            let orphans = self.embedding.rebind(|_, n| class[n as usize] != 0);
            self.drop_triangles_of(&orphans);
            self.topology_version += 1;
            self.refresh_surface();
        }
        Ok(gone.len())
    }

    /// Links elements that are lattice neighbours, unlinked, and within their link limits
    /// (to `tol` m); returns the links added.
    pub fn join(&mut self, tol: Real) -> usize {
        let added = self.lattice.join(tol.max(0.0));
        if added > 0 {
            self.topology_version += 1;
        }
        added
    }

    fn drop_triangles_of(&mut self, vertices: &[usize]) {
        if vertices.is_empty() {
            return;
        }
        let mut gone = vec![false; self.surface.len()];
        for &v in vertices {
            gone[v] = true;
        }
        self.triangles
            .retain(|t| t.iter().all(|&v| !gone[v as usize]));
    }
}

/// Where segment p→q crosses triangle (a, b, c), if it does (parameter in [0, 1]).
fn segment_hits(p: Vec3, q: Vec3, [a, b, c]: [Vec3; 3]) -> bool {
    let d = q - p;
    let (e1, e2) = (b - a, c - a);
    let h = d.cross(e2);
    let det = e1.dot(h);
    if det.abs() < 1e-300 {
        return false;
    }
    let s = p - a;
    let u = s.dot(h) / det;
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let qv = s.cross(e1);
    let v = d.dot(qv) / det;
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    let t = e2.dot(qv) / det;
    (0.0..=1.0).contains(&t)
}

fn blade_triangles(blade: &CutPath) -> [[Vec3; 3]; 2] {
    let [s0, s1] = blade.start;
    let [e0, e1] = blade.end;
    [[s0, s1, e1], [s0, e1, e0]]
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
        let is_fixed: std::collections::HashSet<u32> =
            self.fixed_elements.iter().copied().collect();
        let mut moves: Vec<(u32, Vec3)> = self
            .fixed_elements
            .iter()
            .map(|&e| (e, self.lattice.rest[e as usize]))
            .collect();
        // Each prescribed vertex asks the elements of its cell to move by what it misses.
        let mut wanted: HashMap<u32, (Vec3, Real)> = HashMap::new();
        for p in &self.constraints.prescribed {
            let v = p.vertex as usize;
            if self.fixed_vertex[v] {
                continue;
            }
            let missing = p.position - self.surface[v];
            for k in 0..8 {
                let w = self.embedding.weights[v][k];
                let n = self.embedding.nodes[v][k];
                if w != 0.0 && !is_fixed.contains(&n) {
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
            let v = p.vertex as usize;
            let back = self.embedding.rest[v] - p.position;
            let depth = self.distance.depth_at(p.position).abs();
            self.prescribed_reactions[k] = if self.fixed_vertex[v] {
                Vec3::ZERO
            } else {
                self.force_stiffness * depth * self.vertex_area[v] * back.normalize_or_zero()
            };
        }
        self.steps += 1;
        Ok(StepInfo {
            iterations: self.last.moved,
            residual: 0.0,
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
        if !blade
            .start
            .iter()
            .chain(&blade.end)
            .all(|p| is_finite_vec(*p))
        {
            return Err(SimError::BadParameter {
                name: "cut",
                value: format!("{blade:?}"),
                reason: "the blade must be finite".into(),
            });
        }
        let tris = blade_triangles(blade);
        let reach = self.lattice.spacing.max_element() * 2.0;
        let (mut lo, mut hi) = (Vec3::splat(Real::INFINITY), Vec3::splat(Real::NEG_INFINITY));
        for p in blade.start.iter().chain(&blade.end) {
            lo = lo.min(*p - Vec3::splat(reach));
            hi = hi.max(*p + Vec3::splat(reach));
        }
        let crosses = |p: Vec3, q: Vec3| tris.iter().any(|t| segment_hits(p, q, *t));
        let l = &mut self.lattice;
        let mut removed = 0;
        for a in 0..l.len() {
            let xa = l.x[a];
            if l.class[a] == 0 || xa.cmplt(lo).any() || xa.cmpgt(hi).any() {
                continue;
            }
            for d in [1, 3, 5] {
                if l.neighbour(a, d).is_some_and(|b| crosses(xa, l.x[b])) {
                    l.unlink(a, d);
                    removed += 1;
                }
            }
        }
        if removed > 0 {
            let (surface, x) = (&self.surface, &self.lattice.x);
            let orphans = self
                .embedding
                .rebind(|v, n| !crosses(surface[v], x[n as usize]));
            let cut_triangles: Vec<usize> = self
                .triangles
                .iter()
                .enumerate()
                .filter(|(_, t)| {
                    (0..3)
                        .any(|k| crosses(surface[t[k] as usize], surface[t[(k + 1) % 3] as usize]))
                })
                .map(|(i, _)| i)
                .collect();
            let mut keep = vec![true; self.triangles.len()];
            for i in cut_triangles {
                keep[i] = false;
            }
            let mut it = keep.iter();
            self.triangles.retain(|_| *it.next().unwrap_or(&true));
            self.drop_triangles_of(&orphans);
            self.topology_version += 1;
            self.refresh_surface();
        }
        Ok(CutInfo {
            removed_elements: removed,
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
        let elements = l.class.iter().filter(|&&c| c != 0).count();
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
