//! Checks shared by the tests of several model families.

use crate::interact::{Constraints, Prescribed};
use crate::math::{Real, Vec3};

use super::Deformable;

/// The summed reactions of the first `entries` prescribed entries of `c` after a step with
/// their targets moved by `shift`: an instrument's force, to difference against
/// `Deformable::prescribed_stiffness`.
pub fn shifted_entries_force(
    m: &mut dyn Deformable,
    c: &Constraints,
    entries: usize,
    shift: Vec3,
) -> Vec3 {
    let mut moved = c.clone();
    for p in &mut moved.prescribed[..entries] {
        p.position += shift;
    }
    m.set_constraints(&moved).unwrap();
    m.step(0.01).unwrap();
    m.reactions().prescribed[..entries].iter().copied().sum()
}

/// (σ, ω_d): the decay rate and damped frequency of the oscillation in `z`, from its
/// extrema after `skip` samples: consecutive extrema are half a damped period apart and
/// their differences shrink by e^{−σ T/2}.
pub fn decay(z: &[Real], dt: Real, skip: usize) -> (Real, Real) {
    let mut ext = Vec::new();
    for k in skip.max(1)..z.len() - 1 {
        if (z[k] - z[k - 1]) * (z[k + 1] - z[k]) < 0.0 {
            // Parabolic refinement of the extremum's time and value.
            let (a, b, c) = (z[k - 1], z[k], z[k + 1]);
            let den = a - 2.0 * b + c;
            let s = if den != 0.0 { 0.5 * (a - c) / den } else { 0.0 };
            ext.push(((k as Real + s) * dt, b - 0.25 * (a - c) * s));
        }
    }
    assert!(ext.len() >= 5, "too few extrema: {ext:?}");
    let swings: Vec<(Real, Real)> = ext
        .windows(2)
        .map(|w| (0.5 * (w[0].0 + w[1].0), (w[1].1 - w[0].1).abs()))
        .collect();
    let (first, last) = (swings[0], swings[swings.len() - 1]);
    let sigma = (first.1 / last.1).ln() / (last.0 - first.0);
    let half = (ext[ext.len() - 1].0 - ext[0].0) / (ext.len() - 1) as Real;
    (sigma, std::f64::consts::PI / half)
}

/// Unit directions, pseudo-random from `seed`, for every other entry of `count` (the others
/// `None`: held in full).
pub fn every_other_direction(count: usize, seed: u64) -> Vec<Option<Vec3>> {
    let mut state = seed;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as Real / (1u64 << 53) as Real - 0.5
    };
    (0..count)
        .map(|k| {
            let d = Vec3::new(next(), next(), next());
            (k % 2 == 0).then(|| d.normalize())
        })
        .collect()
}

/// `c`'s prescribed entries held along `normals` (`Deformable::set_constraints_along`, which
/// must say it did so): an equilibrium where each entry with a direction n sits on its
/// plane nᵀ(x − t) = 0, has slid across it, and is pushed along n only (|r × n| < 1e-9 of
/// the largest reaction); the others reach their targets. Holding every entry in full where
/// that solution put it must then give the same reactions (1e-8) and surface (1e-12 m):
/// the same equilibrium, reached by the plain three-direction solve. Returns the reactions
/// and the surface of the solve along the normals.
pub fn check_held_along(
    model: &mut dyn Deformable,
    c: &Constraints,
    normals: &[Option<Vec3>],
) -> (Vec<Vec3>, Vec<Vec3>) {
    assert!(model.set_constraints_along(c, normals).unwrap());
    model.step(0.01).unwrap();
    let along: Vec<Vec3> = model.reactions().prescribed.to_vec();
    let reached: Vec<Vec3> = model.surface().positions.to_vec();
    let scale = along.iter().map(|r| r.length()).fold(0.0, Real::max);
    assert!(scale > 0.0);
    let (mut slid, mut off, mut sideways): (Real, Real, Real) = (0.0, 0.0, 0.0);
    for ((p, n), r) in c.prescribed.iter().zip(normals).zip(&along) {
        let x = reached[p.vertex as usize];
        match n {
            Some(n) => {
                off = off.max((x - p.position).dot(*n).abs());
                sideways = sideways.max(r.cross(*n).length() / scale);
                slid = slid.max((x - p.position).length());
            }
            None => off = off.max((x - p.position).length()),
        }
    }
    assert!(off < 1e-12, "off its plane by {off:e} m");
    assert!(
        sideways < 1e-9,
        "sideways reaction {sideways:e} of the largest"
    );
    assert!(slid > 1e-5, "{slid}");
    let pinned = Constraints {
        fixed: c.fixed.clone(),
        prescribed: c
            .prescribed
            .iter()
            .map(|p| Prescribed {
                vertex: p.vertex,
                position: reached[p.vertex as usize],
            })
            .collect(),
    };
    model.set_constraints(&pinned).unwrap();
    model.step(0.01).unwrap();
    let gap = |a: &[Vec3], b: &[Vec3]| {
        a.iter()
            .zip(b)
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, Real::max)
    };
    let reactions = gap(&along, model.reactions().prescribed) / scale;
    let surface = gap(&reached, model.surface().positions);
    eprintln!(
        "{}: held along normals: off the planes {off:.1e} m, sideways {sideways:.1e} of the \
         largest reaction, slid {slid:.1e} m; the full hold there: reactions {reactions:.1e} \
         relative, surface {surface:.1e} m",
        model.kind()
    );
    assert!(reactions < 1e-8, "{reactions:e}");
    assert!(surface < 1e-12, "{surface:e} m");
    (along, reached)
}

/// The cost and accuracy of `Deformable::set_point_contacts` on `model` (its supports
/// `fixed`): seeded points on the surface triangles within a quarter of the body's extent of
/// its highest vertex, pressed by the horizontal plane 3 % of the extent below that vertex;
/// per point count, the wall and CPU time of a contact update and step (the mean of 20
/// after one warm-up), the pushes and the complementarity on the surface the model reports.
/// The first line is today's vertex path on the same patch: its vertices that start below
/// the plane held along its normal at it (`set_constraints_along`). With `bulge` = 0 each
/// point rests on its triangle (every point's gap is then the weighted mean of its
/// vertices' gaps: a degenerate problem); else it rests off it along the triangle's normal
/// by `bulge` of the extent times 27 w₀w₁w₂ (a smooth bump, zero on the edges), as a fine
/// surface's vertices do. For the ignored studies (timings under load are noisy: compare
/// ratios within one run).
pub fn point_contact_study(
    model: &mut dyn Deformable,
    fixed: &[u32],
    counts: &[usize],
    bulge: Real,
) {
    use crate::benchmark::beam::process_cpu_seconds;
    use crate::interact::PointContact;
    use std::time::Instant;
    let rest = model.rest_surface().to_vec();
    let top = (0..rest.len())
        .max_by(|&a, &b| rest[a].z.total_cmp(&rest[b].z))
        .unwrap_or(0);
    let (lo, hi) = rest
        .iter()
        .fold((rest[0], rest[0]), |(lo, hi), x| (lo.min(*x), hi.max(*x)));
    let extent = (hi - lo).length();
    let is_fixed = |v: u32| fixed.contains(&v);
    let near: Vec<[u32; 3]> = model
        .surface()
        .triangles
        .iter()
        .copied()
        .filter(|t| {
            let c: Vec3 = t.iter().map(|&v| rest[v as usize]).sum::<Vec3>() / 3.0;
            let d = c - rest[top];
            d.x.hypot(d.y) < 0.25 * extent && !t.iter().all(|&v| is_fixed(v))
        })
        .collect();
    let normal = -Vec3::Z;
    let target = rest[top] - Vec3::Z * (0.03 * extent);
    let c = Constraints::fixed(fixed.to_vec());
    let mut state = 29u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as Real / (1u64 << 53) as Real
    };
    // Wall and CPU ms a step, and the step's inner iterations (the pivoting rounds).
    let time = |model: &mut dyn Deformable,
                update: &dyn Fn(&mut dyn Deformable)|
     -> Result<(Real, Real, usize), crate::error::SimError> {
        update(model);
        let rounds = model.step(0.01)?.iterations;
        let (t0, c0) = (Instant::now(), process_cpu_seconds());
        for _ in 0..20 {
            update(model);
            model.step(0.01)?;
        }
        Ok((
            t0.elapsed().as_secs_f64() / 20.0 * 1e3,
            (process_cpu_seconds() - c0) / 20.0 * 1e3,
            rounds,
        ))
    };
    let mut patch: Vec<u32> = near.iter().flatten().copied().collect();
    patch.sort_unstable();
    patch.dedup();
    let held: Vec<Prescribed> = patch
        .iter()
        .filter(|&&v| !is_fixed(v) && normal.dot(rest[v as usize] - target) < 0.0)
        .map(|&v| Prescribed {
            vertex: v,
            position: target,
        })
        .collect();
    let along = Constraints {
        fixed: fixed.to_vec(),
        prescribed: held.clone(),
    };
    let normals = vec![Some(normal); held.len()];
    let (wall, cpu, _) = time(model, &|m| {
        m.set_constraints_along(&along, &normals).unwrap();
    })
    .unwrap();
    let force: Real = model.reactions().prescribed.iter().map(|r| -r.z).sum();
    eprintln!(
        "{}: bulge {bulge}: {} triangles in the patch; vertex contacts along n: {} held, Σ push {force:.4e} N, \
         {wall:.3} ms wall, {cpu:.3} ms CPU a step",
        model.kind(),
        near.len(),
        held.len()
    );
    for &count in counts {
        let points: Vec<PointContact> = (0..count)
            .map(|_| {
                let t = near[(next() * near.len() as Real) as usize % near.len()];
                let (a, b) = (next(), next());
                let (a, b) = if a + b > 1.0 {
                    (1.0 - a, 1.0 - b)
                } else {
                    (a, b)
                };
                let weights = [1.0 - a - b, a, b];
                let [x0, x1, x2] = t.map(|v| rest[v as usize]);
                let up = (x1 - x0).cross(x2 - x0).normalize_or_zero();
                let bump = bulge * extent * 27.0 * weights[0] * weights[1] * weights[2];
                PointContact {
                    vertices: t,
                    weights,
                    rest: (0..3)
                        .map(|i| rest[t[i] as usize] * weights[i])
                        .sum::<Vec3>()
                        + up * bump,
                    normal,
                    target,
                }
            })
            .collect();
        let timed = time(model, &|m| {
            m.set_constraints(&c).unwrap();
            m.set_point_contacts(&points).unwrap();
        });
        let (wall, cpu, rounds) = match timed {
            Ok(t) => t,
            Err(e) => {
                eprintln!("{}: {count:>4} points: the step fails: {e}", model.kind());
                continue;
            }
        };
        let lambda = model.point_reactions().to_vec();
        let x = model.surface().positions;
        let (mut below, mut off, mut pulls): (Real, Real, usize) = (0.0, 0.0, 0);
        for (p, &l) in points.iter().zip(&lambda) {
            let moved: Vec3 = (0..3)
                .map(|i| (x[p.vertices[i] as usize] - rest[p.vertices[i] as usize]) * p.weights[i])
                .sum();
            let g = p.normal.dot(p.rest + moved - p.target);
            below = below.max(-g);
            if l > 0.0 {
                off = off.max(g.abs());
            }
            pulls += usize::from(l < 0.0);
        }
        let pushed = lambda.iter().filter(|&&l| l > 0.0).count();
        eprintln!(
            "{}: {count:>4} points, {pushed:>4} pushed, Σλ {:.4e} N, {wall:.3} ms wall, \
             {cpu:.3} ms CPU a step, {rounds} pivoting rounds; below the plane {below:.1e} m, a pushed point off it \
             {off:.1e} m, {pulls} pulling",
            model.kind(),
            lambda.iter().sum::<Real>()
        );
    }
}
