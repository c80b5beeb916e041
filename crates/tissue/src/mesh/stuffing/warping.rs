//! Which lattice vertices warp, and onto which cut point.
//!
//! A cut point closer to an end of its edge than α·length violates that end. Every violated
//! vertex must either move onto one of its violating cut points (the cut points of its
//! edges are then dropped: it lies on the boundary) or lose those cut points because their
//! other ends moved. Which of these happens matters for the angles: the stencils keep their
//! bound (`stencil_bounds`) only if **a vertex moves onto a cut point whose other end never
//! moves**. When the other end may move too (as our first rule allowed: each vertex onto
//! its nearest cut point still alive, in index order), a tetrahedron can have two corners
//! warped towards each other's places and flatten (`split_rule_study` with `ANY_ORDER=1`:
//! 9.3° instead of 12.5° for a whole tetrahedron with three warped corners at the paper's
//! α, 7.3° at α = (0.27, 0.43), 10.54° instead of 10.73° at the α used here).
//! SOFA's `MeshTetraStuffing` and ModalSound's `IsoStuffer` both warp in an order that keeps
//! the targets fixed (outside vertices first, onto inside vertices that are not violated,
//! then the inside vertices still violated, onto outside ones); this is that order, made
//! complete:
//!
//! 1. until nothing changes, a violated vertex moves onto its nearest violating cut point
//!    whose other end is not violated (an end that is not violated never becomes so, as cut
//!    points only disappear, so it never moves);
//! 2. then the vertices still violated, by increasing rank, each onto its nearest violating
//!    cut point whose other end has a lower rank and has not moved (a lower rank was
//!    processed before, so that end never moves afterwards).
//!
//! With one region the rank is 0 outside and 1 inside. Every violation graph is then
//! bipartite (a cut point joins an inside and an outside vertex) and step 2 leaves nothing
//! violated: an outside vertex still violated after step 1 is violated only by cut points
//! whose inside ends are violated, and each of those moves in step 2 (its violating cut
//! points go to outside vertices, which never move in step 2), dropping the cut point.
//! With several labels the rank is the material, and a vertex refused a warp (next to a
//! third material, or completing a tetrahedron with all four corners on interfaces whose
//! angles break the bounds: between two labels it must be kept, see `stuff`) may stay
//! violated: the caller keeps its cut points α·length away.

use rustc_hash::FxHashMap;

use crate::math::Real;

/// A cut point violating a vertex.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Violation {
    /// The violated vertex.
    pub v: u32,
    /// The other end of the cut point's edge.
    pub other: u32,
    /// The cut point's index.
    pub cut: u32,
    /// Its distance from `v`.
    pub dist: Real,
}

/// No cut point: a vertex that has not moved.
pub(crate) const STAYS: u32 = u32::MAX;

/// The warps, in order, as (vertex, cut point index); `violations` in any order, `rank` and
/// `allowed(v, other)` (whether v may move onto a cut point of edge (v, other)) as above;
/// `veto(v, cut, onto)` refuses a warp given the cut point every vertex moved onto so far
/// (`STAYS` for none).
pub(crate) fn plan(
    vertices: usize,
    violations: &mut [Violation],
    rank: impl Fn(u32) -> u16,
    allowed: impl Fn(u32, u32) -> bool,
    veto: impl Fn(u32, u32, &[u32]) -> bool,
) -> Vec<(u32, u32)> {
    violations.sort_unstable_by(|x, y| x.v.cmp(&y.v).then(x.dist.total_cmp(&y.dist)));
    let mut ranges: Vec<(u32, usize, usize)> = Vec::new();
    for (i, c) in violations.iter().enumerate() {
        match ranges.last_mut() {
            Some(r) if r.0 == c.v => r.2 = i + 1,
            _ => ranges.push((c.v, i, i + 1)),
        }
    }
    let index: FxHashMap<u32, usize> = ranges.iter().enumerate().map(|(i, r)| (r.0, i)).collect();
    let mut moved = vec![STAYS; vertices];
    let live = |c: &Violation, moved: &[u32]| {
        moved[c.v as usize] == STAYS && moved[c.other as usize] == STAYS
    };
    let violated = |w: u32, moved: &[u32]| {
        index.get(&w).is_some_and(|&i| {
            let (_, s, e) = ranges[i];
            violations[s..e].iter().any(|c| live(c, moved))
        })
    };
    let mut warps = Vec::new();
    loop {
        let mut changed = false;
        for &(v, s, e) in &ranges {
            if moved[v as usize] != STAYS {
                continue;
            }
            let target = violations[s..e].iter().find(|c| {
                live(c, &moved)
                    && allowed(v, c.other)
                    && !violated(c.other, &moved)
                    && !veto(v, c.cut, &moved)
            });
            if let Some(c) = target {
                moved[v as usize] = c.cut;
                warps.push((v, c.cut));
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    let mut rest: Vec<(u16, u32, usize, usize)> = ranges
        .iter()
        .filter(|&&(v, _, _)| violated(v, &moved))
        .map(|&(v, s, e)| (rank(v), v, s, e))
        .collect();
    rest.sort_unstable();
    for (r, v, s, e) in rest {
        let target = violations[s..e].iter().find(|c| {
            live(c, &moved) && rank(c.other) < r && allowed(v, c.other) && !veto(v, c.cut, &moved)
        });
        if let Some(c) = target {
            moved[v as usize] = c.cut;
            warps.push((v, c.cut));
        }
    }
    warps
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::stuffing::stencil_bounds::Rng;

    /// On random bipartite violation graphs (one region: inside and outside vertices, every
    /// cut point violating at most one end), the plan leaves no cut point violating an end
    /// that did not move, and no vertex moves onto a cut point whose other end moved.
    #[test]
    fn one_region_plans_leave_nothing_violated_and_targets_fixed() {
        let mut rng = Rng(5);
        for _ in 0..2000 {
            let n = 2 + rng.below(30);
            let inside: Vec<bool> = (0..n).map(|_| rng.below(2) == 0).collect();
            let mut violations = Vec::new();
            let mut cuts = 0u32;
            for a in 0..n as u32 {
                for b in a + 1..n as u32 {
                    if inside[a as usize] == inside[b as usize] || rng.below(4) != 0 {
                        continue;
                    }
                    // The cut point violates a, b or neither.
                    let (v, other) = match rng.below(3) {
                        0 => (a, b),
                        1 => (b, a),
                        _ => {
                            cuts += 1;
                            continue;
                        }
                    };
                    violations.push(Violation {
                        v,
                        other,
                        cut: cuts,
                        dist: rng.unit(),
                    });
                    cuts += 1;
                }
            }
            let rank = |v: u32| u16::from(inside[v as usize]);
            let warps = plan(
                n,
                &mut violations.clone(),
                rank,
                |_, _| true,
                |_, _, _| false,
            );
            let mut moved = vec![false; n];
            for &(v, _) in &warps {
                assert!(!moved[v as usize], "{v} moved twice: {warps:?}");
                moved[v as usize] = true;
            }
            let of_cut: FxHashMap<u32, Violation> =
                violations.iter().map(|c| (c.cut, *c)).collect();
            for &(v, cut) in &warps {
                let c = of_cut[&cut];
                assert_eq!(c.v, v);
                assert!(
                    !moved[c.other as usize],
                    "{v} moved onto {c:?} whose end moved"
                );
            }
            for c in &violations {
                assert!(
                    moved[c.v as usize] || moved[c.other as usize],
                    "{c:?} still violates: {warps:?}"
                );
            }
        }
    }
}
