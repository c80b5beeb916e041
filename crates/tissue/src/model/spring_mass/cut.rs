//! Progressive cutting of the `spring-mass` surface along a scalpel sweep.
//!
//! Each call takes the ruled quad the blade swept during one step (two triangles) and:
//! 1. finds the springs (edges) it crosses, at the current positions; a crossing is kept at
//!    25-75 % of the edge so that no sliver triangle or very short spring is created, and
//!    crossings of earlier sweeps that were not used yet are remembered ("pending");
//! 2. cuts every triangle with two crossed edges (with three, the first two), and every
//!    triangle with one crossed edge whose opposite corner is the open end (tip) of an
//!    earlier incision, so that an incision continues from where the last sweep stopped;
//! 3. splits every crossed edge of a cut triangle at its crossing (the crossed spring is
//!    removed) and re-triangulates each touched triangle in its own winding, so orientation
//!    is kept; the segments across cut triangles are marked;
//! 4. separates the surface along the marked segments: around each vertex on them, the
//!    triangles that stay connected through unmarked edges keep the vertex, every other such
//!    group gets its own copy, so each lip gets its own vertices and every vertex's triangles
//!    form one fan (the surface stays manifold);
//! 5. rebuilds springs and masses: stiffnesses and masses from the rest geometry (new
//!    vertices at the interpolated rest positions, so the total area and mass are kept),
//!    rest lengths kept for springs that existed and taken from the current geometry for new
//!    ones; a pressure is kept only while the surface stays closed.
//!
//! An incision's front lies inside the first triangle it has not crossed twice: the surface
//! opens one triangle behind the blade. Vertices are only appended, so the indices of
//! existing surface vertices (constraints, loads) stay valid.

use std::collections::{HashMap, HashSet};

use crate::error::SimError;
use crate::math::{Real, Vec3};
use crate::mesh::SurfaceMesh;
use crate::mesh::topology::{edge_faces, triangle_edges};
use crate::model::{CutInfo, CutPath, Deformable};

use super::SpringModel;
use super::SurfaceLink;
use super::surface::{closed_pressure, membrane_parts};

/// Crossings are kept this far from the edge ends (fraction of the edge).
const MARGIN: Real = 0.25;

/// What the cutter remembers between sweeps.
#[derive(Clone, Debug, Default)]
pub(crate) struct Cutter {
    /// Crossed edges not split yet: (edge, fraction from its smaller vertex).
    pending: HashMap<[u32; 2], Real>,
    /// Open ends of incisions.
    tips: HashSet<u32>,
}

#[inline]
fn key(a: u32, b: u32) -> [u32; 2] {
    if a < b { [a, b] } else { [b, a] }
}

pub(crate) fn cut_model(model: &mut SpringModel, blade: &CutPath) -> Result<CutInfo, SimError> {
    blade.check()?;
    let x = &model.state.x;
    let old_edges = triangle_edges(&model.triangles);
    // 1. Crossings: this sweep's, then the pending ones of edges that still exist.
    let mut crossed: HashMap<[u32; 2], Real> = HashMap::new();
    for &[a, b] in &old_edges {
        let (p, q) = (x[a as usize], x[b as usize]);
        if let Some(s) = blade.crossing(p, q) {
            crossed.insert([a, b], s.clamp(MARGIN, 1.0 - MARGIN));
        }
    }
    for (e, s) in &model.cutter.pending {
        if old_edges.binary_search(e).is_ok() {
            crossed.entry(*e).or_insert(*s);
        }
    }
    // A sweep starts where the last one ended, so it may graze the edges around an open tip:
    // those crossings are dropped and the incision continues from the tip itself.
    let tips = &model.cutter.tips;
    crossed.retain(|e, _| !tips.contains(&e[0]) && !tips.contains(&e[1]));
    // 2. Which triangles are cut, and through which two of their features.
    let tris = model.triangles.clone();
    let mut cut_pair: Vec<Option<Cut>> = vec![None; tris.len()];
    for (t, tri) in tris.iter().enumerate() {
        let hit: Vec<usize> = (0..3)
            .filter(|&k| crossed.contains_key(&key(tri[k], tri[(k + 1) % 3])))
            .collect();
        cut_pair[t] = match hit.as_slice() {
            [i, j, ..] => Some(Cut::Edges(*i, *j)),
            [k] if model.cutter.tips.contains(&tri[(k + 2) % 3]) => Some(Cut::FromTip(*k)),
            _ => None,
        };
    }
    if cut_pair.iter().all(Option::is_none) {
        model.cutter.pending = crossed;
        return Ok(CutInfo {
            removed_elements: 0,
            added_vertices: 0,
            topology_version: model.topology_version,
        });
    }
    // 3. Split the crossed edges of cut triangles: one new vertex each.
    let mut split: HashMap<[u32; 2], u32> = HashMap::new();
    let mut rest = model.rest.clone();
    let mut xs = model.state.x.clone();
    let mut vs = model.state.v.clone();
    for (t, tri) in tris.iter().enumerate() {
        let Some(c) = cut_pair[t] else { continue };
        for k in c.edges() {
            let e = key(tri[k], tri[(k + 1) % 3]);
            if split.contains_key(&e) {
                continue;
            }
            let s = crossed.get(&e).copied().unwrap_or(0.5);
            let (a, b) = (e[0] as usize, e[1] as usize);
            let lerp = |v: &[Vec3]| v[a] + s * (v[b] - v[a]);
            split.insert(e, rest.len() as u32);
            rest.push(lerp(&rest));
            xs.push(lerp(&xs));
            vs.push(lerp(&vs));
        }
    }
    let mut triangles = Vec::with_capacity(tris.len() + 3 * split.len());
    let mut marked: HashSet<[u32; 2]> = HashSet::new();
    for (t, tri) in tris.iter().enumerate() {
        let mids = [0, 1, 2].map(|k| split.get(&key(tri[k], tri[(k + 1) % 3])).copied());
        subdivide(*tri, mids, cut_pair[t], &rest, &mut triangles, &mut marked);
    }
    // 4. Separate along the marked segments.
    let mut on_cut: Vec<u32> = marked.iter().flatten().copied().collect();
    on_cut.sort_unstable();
    on_cut.dedup();
    let mut tips = model.cutter.tips.clone();
    for &v in &on_cut {
        let groups = fans(v, &triangles, &marked);
        if groups.len() == 1 {
            tips.insert(v);
            continue;
        }
        tips.remove(&v);
        for group in groups.iter().skip(1) {
            let copy = rest.len() as u32;
            rest.push(rest[v as usize]);
            xs.push(xs[v as usize]);
            vs.push(vs[v as usize]);
            for &t in group {
                for w in &mut triangles[t] {
                    if *w == v {
                        *w = copy;
                    }
                }
            }
        }
    }
    // 5. Rebuild springs, masses and pressure.
    let added = rest.len() - model.rest.len();
    let old_rest: HashMap<[u32; 2], Real> = model
        .body
        .network
        .springs
        .iter()
        .map(|s| (key(s.a, s.b), s.rest_length))
        .collect();
    let (mut network, masses) = membrane_parts(&rest, &triangles, &model.material, &model.params);
    let mut kept = 0;
    for s in &mut network.springs {
        match old_rest.get(&key(s.a, s.b)) {
            Some(&l) => {
                s.rest_length = l;
                kept += 1;
            }
            None => s.rest_length = (xs[s.b as usize] - xs[s.a as usize]).length(),
        }
    }
    let removed = old_rest.len() - kept;
    let surface = SurfaceMesh::new(rest.clone(), triangles.clone());
    let pressure = match model.body.pressure {
        Some(_) if edge_faces(&triangles).border_edges().next().is_none() => {
            closed_pressure(&surface, &model.material).ok()
        }
        _ => None,
    };
    model.body.network = network;
    model.body.masses = masses;
    model.body.pressure = pressure;
    model.body.changed();
    let n = rest.len();
    model.state.x = xs;
    model.state.v = vs;
    model.rest = rest;
    let explicit = model.integrator.scheme != crate::integrate::Scheme::ImplicitEuler;
    model.body.set_split_damping(explicit, &model.rest);
    model.link = SurfaceLink::Nodes((0..n as u32).collect());
    model.triangles = triangles;
    model.surface_rest = model.rest.clone();
    model.surface_positions = model.state.x.clone();
    let loads = model.loads.clone();
    model.set_loads(&loads)?;
    model.integrator.invalidate();
    model.cutter.pending = crossed
        .into_iter()
        .filter(|(e, _)| !split.contains_key(e))
        .collect();
    model.cutter.tips = tips;
    model.topology_version += 1;
    Ok(CutInfo {
        removed_elements: removed,
        added_vertices: added,
        topology_version: model.topology_version,
    })
}

/// How a triangle is cut: between the crossings of two of its edges (edge k joins corners k
/// and k+1), or from its corner opposite edge k (an incision tip) to the crossing of edge k.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Cut {
    Edges(usize, usize),
    FromTip(usize),
}

impl Cut {
    fn edges(self) -> Vec<usize> {
        match self {
            Cut::Edges(i, j) => vec![i, j],
            Cut::FromTip(k) => vec![k],
        }
    }
}

/// Re-triangulates one triangle whose edges k carry new vertices `mids[k]`, keeping its
/// winding, and marks the segment of its cut.
fn subdivide(
    tri: [u32; 3],
    mids: [Option<u32>; 3],
    cut: Option<Cut>,
    rest: &[Vec3],
    out: &mut Vec<[u32; 3]>,
    marked: &mut HashSet<[u32; 2]>,
) {
    let mut mark = |a: u32, b: u32| {
        marked.insert(key(a, b));
    };
    match mids {
        [None, None, None] => out.push(tri),
        [Some(_), None, None] | [None, Some(_), None] | [None, None, Some(_)] => {
            let k = mids.iter().position(Option::is_some).unwrap_or(0);
            let (a, b, c) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
            let m = mids[k].unwrap_or(a);
            out.push([a, m, c]);
            out.push([m, b, c]);
            if cut == Some(Cut::FromTip(k)) {
                mark(m, c);
            }
        }
        [Some(m0), Some(m1), Some(m2)] => {
            out.push([tri[0], m0, m2]);
            out.push([m0, tri[1], m1]);
            out.push([m2, m1, tri[2]]);
            out.push([m0, m1, m2]);
            if let Some(Cut::Edges(i, j)) = cut {
                mark(mids[i].unwrap_or(m0), mids[j].unwrap_or(m1));
            }
        }
        _ => {
            // Two split edges: the apex is the corner they share.
            let k = (0..3).find(|&k| mids[k].is_some() && mids[(k + 2) % 3].is_some());
            let k = k.unwrap_or(0);
            let (a, b, c) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
            let (ma, mb) = (mids[k].unwrap_or(a), mids[(k + 2) % 3].unwrap_or(a));
            out.push([a, ma, mb]);
            let r = |v: u32| rest[v as usize];
            if (r(ma) - r(c)).length() <= (r(b) - r(mb)).length() {
                out.push([ma, b, c]);
                out.push([ma, c, mb]);
            } else {
                out.push([ma, b, mb]);
                out.push([b, c, mb]);
            }
            if cut.is_some() {
                mark(ma, mb);
            }
        }
    }
}

/// The triangles around `v`, grouped by connection through unmarked edges at `v`.
fn fans(v: u32, triangles: &[[u32; 3]], marked: &HashSet<[u32; 2]>) -> Vec<Vec<usize>> {
    let around: Vec<usize> = (0..triangles.len())
        .filter(|&t| triangles[t].contains(&v))
        .collect();
    let mut parent: Vec<usize> = (0..around.len()).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    let mut by_other: HashMap<u32, usize> = HashMap::new();
    for (i, &t) in around.iter().enumerate() {
        for &w in &triangles[t] {
            if w == v || marked.contains(&key(v, w)) {
                continue;
            }
            if let Some(&j) = by_other.get(&w) {
                let (ri, rj) = (find(&mut parent, i), find(&mut parent, j));
                parent[ri] = rj;
            } else {
                by_other.insert(w, i);
            }
        }
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut label: HashMap<usize, usize> = HashMap::new();
    for (i, &t) in around.iter().enumerate() {
        let root = find(&mut parent, i);
        let g = *label.entry(root).or_insert_with(|| {
            groups.push(Vec::new());
            groups.len() - 1
        });
        groups[g].push(t);
    }
    groups
}

/// Number of fans around `v` (1 for a manifold vertex).
#[cfg(test)]
pub(crate) fn fan_count(v: u32, triangles: &[[u32; 3]]) -> usize {
    fans(v, triangles, &HashSet::new()).len()
}
