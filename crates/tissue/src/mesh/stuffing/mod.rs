//! Isosurface stuffing (Labelle & Shewchuk, "Isosurface stuffing: fast tetrahedral meshes
//! with good dihedral angles", SIGGRAPH 2007), uniform sizing: a tetrahedral mesh of the
//! inside of a `Domain` (an implicit shape, a closed surface, a thresholded or labelled
//! image) whose dihedral angles lie in the paper's [10.7°, 164.8°]: proven by the paper for
//! its α, sampled on every stencil case for ours (`stencil_bounds`: 10.73°–164.4°).
//!
//! 1. Fill the domain's box with the BCC lattice of spacing h (`lattice`), one cube of
//!    margin, and take the sign of the domain at every lattice vertex.
//! 2. On every lattice edge whose ends have opposite signs, find the cut point where the
//!    boundary crosses it.
//! 3. Warp: a lattice vertex closer to a cut point on one of its edges than α times that
//!    edge's length (α = `ALPHA_LONG` for the edges of length h, `ALPHA_SHORT` for the
//!    black–red edges of length h√3/2) is violated; violated vertices move onto one of their
//!    violating cut points, in the order of `warping` (a target never moves), and take sign
//!    zero; the cut points of their edges are dropped.
//! 4. Fill every BCC tetrahedron by the stencil its signs select (`stencil`).
//!
//! A domain with several materials (`Domain::material_tags`: labels of one image) is
//! stuffed with every label a region of its own and the interfaces between them made of
//! mesh faces (`materials`): interface cut points, warping onto interfaces, each material's
//! stencil, and junction tetrahedra where three materials meet.
//!
//! Every output is measured (`report::measure`): angles, validity, volume, and the distance
//! between the boundaries; the caller refuses what breaks a guarantee.

mod bare;
pub mod domain;
pub mod follow;
pub mod image_domain;
mod interface_volume;
pub mod interfaces;
mod lattice;
pub mod manifold;
mod materials;
pub mod pieces;
pub mod report;
mod split_rule;
mod stencil;
#[cfg(test)]
mod stencil_bounds;
pub mod surface_domain;
pub mod triangle_index;
mod vertex_move;
mod warping;

use std::time::Instant;

use rustc_hash::FxHashMap;

use crate::error::MeshError;
use crate::math::{Real, Vec3, tet_signed_volume};
use crate::mesh::TetMesh;
use crate::model::Progress;

pub use domain::{Domain, Implicit};
pub use image_domain::ImageDomain;
pub use interfaces::{InterfaceReport, LabelVolume, Labels};
use lattice::Lattice;
use materials::{Side, may_warp};
pub use report::{JunctionCount, MeshingReport, dihedral_angles, measure, radius_ratio};
use split_rule::Site;
use stencil::{Fill, Key};
pub use surface_domain::SurfaceDomain;
pub use triangle_index::TriangleIndex;

/// Warping threshold on the long (length h) edges. Not the paper's 0.24999: with the paper's
/// pair our construction (the paper's stencils and parity rule, `warping`'s rule) is sampled
/// at 9.3°, below its proven 10.7°; this pair was chosen by scanning the three stencil
/// cases that bound the angle (a whole tetrahedron with three warped corners, which gets
/// worse as α grows; the pyramid with a warped apex, which gets better; one inside, one
/// outside and two warped corners) where they meet, and is sampled at 10.73°–164.3°
/// (`stencil_bounds`; docs/meshing.md, "Quadrilateral splits and the angle bound").
pub const ALPHA_LONG: Real = 0.2835;
/// Warping threshold on the short (length h·√3/2) edges (the paper's: 0.41189).
pub const ALPHA_SHORT: Real = 0.401;
/// The dihedral bounds (degrees) that stuffing keeps at uniform sizing: the paper's proven
/// [10.7°, 164.8°], held by our construction with these α by sampling every stencil case
/// (`stencil_bounds::every_stencil_keeps_the_dihedral_bounds`); a tetrahedron with all four
/// corners warped onto the boundary is kept only within them (`stencil::keep_all_zero`).
pub const PROVEN_DIHEDRAL_DEG: (Real, Real) = (10.7, 164.8);
/// Lattices beyond this many vertices are refused (memory: ~30 bytes each).
pub const MAX_LATTICE_VERTICES: usize = 16_000_000;

/// A tetrahedral mesh made by stuffing, its tags (one per tetrahedron, from
/// `Domain::tag_at`) and its report.
#[derive(Clone, Debug)]
pub struct Stuffed {
    pub mesh: TetMesh,
    pub tags: Vec<i32>,
    pub report: MeshingReport,
}

impl Stuffed {
    /// The mesh as file contents: vertices, tetrahedra and their tags.
    pub fn to_mesh_data(&self) -> crate::mesh::MeshData {
        crate::mesh::MeshData {
            vertices: self.mesh.vertices.clone(),
            tets: self.mesh.tets.clone(),
            tet_tags: self.tags.clone(),
            ..Default::default()
        }
    }
}

/// Gaussian σ of an image mask's blur, relative to the lattice spacing, by default.
pub const DEFAULT_IMAGE_SMOOTHING: Real = 0.5;

/// The tetrahedron count a size is chosen for when none is given.
pub const DEFAULT_TARGET_TETS: usize = 20_000;

/// The lattice spacing that fills `volume` (m³) with about `tets` tetrahedra: a BCC
/// tetrahedron has volume h³/12, so h = (12·V/N)^(1/3).
pub fn size_for(volume: Real, tets: usize) -> Real {
    (12.0 * volume.abs() / tets.max(1) as Real).cbrt()
}

/// Tetrahedra of one BCC tetrahedron with the material each belongs to.
type Parts = Vec<([Key; 4], u16)>;

/// A cut point: the lattice edge (a, b) it lies on and its position.
struct Cut {
    a: u32,
    b: u32,
    at: Vec3,
}

/// Meshes the inside of `domain` with lattice spacing `size` (m). The report is filled in;
/// whether to accept the mesh is the caller's call (`MeshingReport::violations`).
pub fn stuff(domain: &dyn Domain, size: Real, progress: &Progress) -> Result<Stuffed, MeshError> {
    let clock = Instant::now();
    let (lo, hi) = domain.bounds();
    if !(size.is_finite() && size > 0.0) {
        return Err(MeshError::Invalid(format!(
            "the tetrahedron size must be a positive length in m, not {size}"
        )));
    }
    if !(crate::math::is_finite_vec(lo) && crate::math::is_finite_vec(hi)) || hi.cmplt(lo).any() {
        return Err(MeshError::Invalid(format!(
            "the shape's bounds are not a box: {lo} .. {hi}"
        )));
    }
    // One cube of margin on every side, so that the outer red vertices are outside.
    let cubes = ((hi - lo) / size).ceil() + Vec3::splat(2.0);
    let count = (cubes.x + 1.0) * (cubes.y + 1.0) * (cubes.z + 1.0) * 2.0;
    if count > MAX_LATTICE_VERTICES as Real {
        return Err(MeshError::Invalid(format!(
            "size {size:e} m needs about {count:.3e} lattice vertices over the shape's box \
             ({:.3e} × {:.3e} × {:.3e} m), more than {MAX_LATTICE_VERTICES}; use a larger size",
            hi.x - lo.x,
            hi.y - lo.y,
            hi.z - lo.z
        )));
    }
    let lattice = Lattice {
        origin: lo - Vec3::splat(size),
        h: size,
        n: [cubes.x as usize, cubes.y as usize, cubes.z as usize],
    };
    let nl = lattice.vertex_count();

    // 1. Signs, and with several materials the material of every vertex (0 outside; a
    // vertex exactly on the boundary counts as outside, its cut point is then itself).
    progress.report("signs", 0.0);
    let mut pos: Vec<Vec3> = (0..nl as u32).map(|v| lattice.position(v)).collect();
    let mut sign: Vec<i8> = signs(domain, &pos, progress);
    let material_tags = domain.material_tags();
    let multi = material_tags.len() >= 2;
    let material: Vec<u16> = if multi {
        pos.iter()
            .zip(&sign)
            .map(|(&p, &s)| {
                if s < 0 {
                    1 + domain.material_at(p).min(material_tags.len() - 1) as u16
                } else {
                    0
                }
            })
            .collect()
    } else {
        Vec::new()
    };
    let mut side: Vec<Side> = material.iter().map(|&m| Side::single(m)).collect();

    // 2. Cut points.
    progress.report("cut points", 0.0);
    let mut cuts: Vec<Cut> = Vec::new();
    let mut cut_of: FxHashMap<(u32, u32), u32> = FxHashMap::default();
    lattice.for_each_edge(|a, b| {
        let (pa, pb) = (pos[a as usize], pos[b as usize]);
        let at = if multi {
            let (ma, mb) = (material[a as usize], material[b as usize]);
            if ma == mb {
                return;
            }
            if ma == 0 {
                domain.cut(pb, pa)
            } else if mb == 0 {
                domain.cut(pa, pb)
            } else {
                domain.interface_cut(pa, usize::from(ma - 1), pb, usize::from(mb - 1))
            }
        } else {
            let (sa, sb) = (sign[a as usize], sign[b as usize]);
            if sa * sb >= 0 {
                return;
            }
            if sa < 0 {
                domain.cut(pa, pb)
            } else {
                domain.cut(pb, pa)
            }
        };
        cut_of.insert((a.min(b), a.max(b)), cuts.len() as u32);
        cuts.push(Cut { a, b, at });
    });

    // 3. Warping. A cut point violates at most one end (both α < 1/2). Which violated
    // vertices move, and onto which cut point: `warping` (a vertex moves only onto a cut
    // point whose other end never moves, which the stencils' angle bound needs).
    progress.report("warping", 0.0);
    let mut violations: Vec<warping::Violation> = Vec::new();
    let alpha_of = |a: u32, b: u32| {
        if lattice.is_long(a, b) {
            ALPHA_LONG
        } else {
            ALPHA_SHORT
        }
    };
    for (c, cut) in cuts.iter().enumerate() {
        let (pa, pb) = (pos[cut.a as usize], pos[cut.b as usize]);
        let len = (pb - pa).length();
        let alpha = alpha_of(cut.a, cut.b);
        let (da, db) = ((cut.at - pa).length(), (cut.at - pb).length());
        let (v, other, dist) = if da < alpha * len {
            (cut.a, cut.b, da)
        } else if db < alpha * len {
            (cut.b, cut.a, db)
        } else {
            continue;
        };
        violations.push(warping::Violation {
            v,
            other,
            cut: c as u32,
            dist,
        });
    }
    let warps = if multi {
        // The rank is the material (0 outside); a vertex next to a third material stays,
        // and so does one that would complete a tetrahedron of four warped corners outside
        // the angle bounds (α_long > 1/4 lets a plane a quarter of the way along the long
        // edges take all four corners of a tetrahedron: flat). Such a tetrahedron is dropped
        // on the outer boundary, but between two labels it must be kept (see below).
        let cut_at = |c: u32| cuts[c as usize].at;
        warping::plan(
            nl,
            &mut violations,
            |v| material[v as usize],
            |v, other| may_warp(&lattice, &material, v, material[other as usize]),
            |v, c, onto| flat_all_zero(&lattice, v, cut_at(c), onto, &cut_at),
        )
    } else {
        warping::plan(
            nl,
            &mut violations,
            |v| u16::from(sign[v as usize] < 0),
            |_, _| true,
            |_, _, _| false,
        )
    };
    let warped = warps.len();
    for &(v, c) in &warps {
        let cut = &cuts[c as usize];
        let other = if cut.a == v { cut.b } else { cut.a };
        pos[v as usize] = cut.at;
        sign[v as usize] = 0;
        if multi {
            side[v as usize] = Side {
                a: material[v as usize],
                b: material[other as usize],
            };
        }
    }
    // A vertex refused a warp (next to a third material) keeps its cut points at least
    // α·length away, as warping would have left them. With one region nothing is left
    // violated (`warping`), so nothing is clamped.
    let mut clamped = 0;
    if multi {
        for w in &violations {
            if side[w.v as usize].is_single() && side[w.other as usize].is_single() {
                let (pv, po) = (pos[w.v as usize], pos[w.other as usize]);
                cuts[w.cut as usize].at = pv + alpha_of(w.v, w.other) * (po - pv);
                clamped += 1;
            }
        }
    }

    // 4. Stencils.
    progress.report("stencils", 0.0);
    let cut_base = nl as Key;
    let mut out = Output {
        of_lattice: vec![u32::MAX; nl],
        of_cut: vec![u32::MAX; cuts.len()],
        vertices: Vec::new(),
        tets: Vec::new(),
        tags: Vec::new(),
    };
    let mut pieces: Vec<[Key; 4]> = Vec::new();
    let missing_cut = std::cell::Cell::new(false);
    let cut_key = |a: u32, b: u32| -> Key {
        match cut_of.get(&(a.min(b), a.max(b))) {
            Some(&c) => cut_base + c as Key,
            None => {
                missing_cut.set(true);
                a as Key
            }
        }
    };
    // Reference geometry for orientation: unwarped lattice, cut points at edge midpoints.
    let reference = |k: Key| -> Vec3 {
        if k < cut_base {
            lattice.position(k as u32)
        } else {
            let c = &cuts[(k - cut_base) as usize];
            0.5 * (lattice.position(c.a) + lattice.position(c.b))
        }
    };
    let actual = |k: Key| -> Vec3 {
        if k < cut_base {
            pos[k as usize]
        } else {
            cuts[(k - cut_base) as usize].at
        }
    };
    // Quadrilaterals in lattice faces are split by the lattice rule (`split_rule`): both
    // BCC tetrahedra sharing one see the same face.
    let site = |k: Key| -> Site {
        if k < cut_base {
            Site::Vertex(lattice.coords(k as u32))
        } else {
            let c = &cuts[(k - cut_base) as usize];
            Site::Cut(lattice.coords(c.a), lattice.coords(c.b))
        }
    };
    let split = |q: [Key; 4]| split_rule::lattice_split(q, site, split_rule::PARITY);
    let quality = |t: &[[Key; 4]]| stencil_quality(t, &actual, &reference);
    let mut all_zero = Vec::new();
    let mut steiner: Vec<[Key; 6]> = Vec::new();
    let mut steiner_points = 0;
    let mut junctions = Junctions::default();
    // The smallest angle (radians) of the two-material stencils' tetrahedra.
    let mut stencil_min = Real::INFINITY;
    let tag_of = |m: u16| material_tags[usize::from(m) - 1];
    lattice.for_each_tet(|t| {
        if !multi {
            if t.iter().all(|&v| sign[v as usize] > 0) {
                return;
            }
            pieces.clear();
            steiner.clear();
            let fill = stencil::fill(
                t,
                |v| sign[v as usize],
                cut_key,
                &split,
                &quality,
                &mut pieces,
                &mut steiner,
            );
            if fill == Fill::AllZero {
                all_zero.push(t);
            }
            steiner_points += steiner.len();
            out.add(&pieces, &steiner, cut_base, &actual, &reference, |c| {
                domain.tag_at(c)
            });
            return;
        }
        let sides = t.map(|v| side[v as usize]);
        if sides.iter().all(|s| *s == Side::single(0)) {
            return;
        }
        let mut present: Vec<u16> = sides.iter().flat_map(|s| [s.a, s.b]).collect();
        present.sort_unstable();
        present.dedup();
        if sides.iter().all(|s| s.is_single()) && present.len() >= 3 {
            junctions.fill(
                t, &material, &cut_key, &actual, &reference, &split, &mut out, tag_of,
            );
            return;
        }
        // At most two materials: each one's stencil. A two-in two-out tetrahedron between
        // two labels has a quadrilateral of cut points inside it, which both prisms must
        // split alike: try both diagonals, keep the one whose worse prism is better.
        let inside: Vec<u16> = present.iter().copied().filter(|&m| m != 0).collect();
        let diagonals: Vec<Option<(Key, Key)>> = match inside.as_slice() {
            &[x, y] if !present.contains(&0) => {
                let ins: Vec<u32> = t
                    .iter()
                    .copied()
                    .filter(|&v| side[v as usize] == Side::single(x))
                    .collect();
                let outs: Vec<u32> = t
                    .iter()
                    .copied()
                    .filter(|&v| side[v as usize] == Side::single(y))
                    .collect();
                if ins.len() == 2 && outs.len() == 2 {
                    vec![
                        Some((cut_key(ins[0], outs[0]), cut_key(ins[1], outs[1]))),
                        Some((cut_key(ins[0], outs[1]), cut_key(ins[1], outs[0]))),
                    ]
                } else {
                    vec![None]
                }
            }
            _ => vec![None],
        };
        let mut best: Option<(Real, Parts, Vec<[Key; 6]>)> = None;
        let mut zero = false;
        for &diagonal in &diagonals {
            let forced = |q: [Key; 4]| {
                split(q).or_else(|| {
                    diagonal.map(|(x, y)| (q[0] == x && q[2] == y) || (q[0] == y && q[2] == x))
                })
            };
            let mut parts: Vec<([Key; 4], u16)> = Vec::new();
            let mut all_steiner: Vec<[Key; 6]> = Vec::new();
            let mut worst = Real::INFINITY;
            for &m in &inside {
                pieces.clear();
                steiner.clear();
                let fill = stencil::fill(
                    t,
                    |v| side[v as usize].sign(m),
                    cut_key,
                    &forced,
                    &quality,
                    &mut pieces,
                    &mut steiner,
                );
                zero |= fill == Fill::AllZero;
                worst = worst.min(if steiner.is_empty() {
                    quality(&pieces)
                } else {
                    0.0
                });
                // Steiner keys are numbered per tetrahedron across its materials.
                let shift = all_steiner.len() as Key;
                parts.extend(pieces.iter().map(|p| {
                    (
                        p.map(|k| {
                            if k >= stencil::STEINER_BASE {
                                k + shift
                            } else {
                                k
                            }
                        }),
                        m,
                    )
                }));
                all_steiner.extend_from_slice(&steiner);
            }
            if best.as_ref().is_none_or(|(q, _, _)| worst > *q) {
                best = Some((worst, parts, all_steiner));
            }
        }
        if zero {
            all_zero.push(t);
        }
        if let Some((worst, parts, all_steiner)) = best {
            stencil_min = stencil_min.min(worst);
            steiner_points += all_steiner.len();
            out.add_tagged(&parts, &all_steiner, cut_base, &actual, &reference, tag_of);
        }
    });
    // A tetrahedron with all four corners on the boundary is inside when its centre is; it
    // is kept only when it keeps the angle bound (`stencil::keep_all_zero`). Between two
    // labels (no corner on the outer boundary) it is always kept: leaving it out would
    // leave a hole inside the mesh.
    for t in all_zero {
        let keys = t.map(|v| v as Key);
        let centroid = keys.iter().map(|&k| actual(k)).sum::<Vec3>() / 4.0;
        if !multi {
            if domain.value(centroid) < 0.0 && stencil::keep_all_zero(keys.map(actual)) {
                out.add(&[keys], &[], cut_base, &actual, &reference, |c| {
                    domain.tag_at(c)
                });
            }
            continue;
        }
        let sides = t.map(|v| side[v as usize]);
        let mut common: Vec<u16> = vec![sides[0].a, sides[0].b];
        common.retain(|&m| sides.iter().all(|s| s.touches(m)));
        common.dedup();
        let m = if common.contains(&0) {
            let Some(&m) = common.iter().find(|&&m| m != 0) else {
                continue;
            };
            if !(domain.value(centroid) < 0.0 && stencil::keep_all_zero(keys.map(actual))) {
                continue;
            }
            m
        } else {
            let at = 1 + domain.material_at(centroid) as u16;
            match common.as_slice() {
                [] => continue,
                c if c.contains(&at) => at,
                c => c[0],
            }
        };
        stencil_min = dihedral_angles(keys.map(actual))
            .iter()
            .copied()
            .fold(stencil_min, Real::min);
        out.add_tagged(&[(keys, m)], &[], cut_base, &actual, &reference, tag_of);
    }
    if missing_cut.get() {
        return Err(MeshError::Invalid(
            "internal: a stencil asked for a cut point that was never made".into(),
        ));
    }
    let seconds = clock.elapsed().as_secs_f64();
    progress.report("report", 0.0);
    let Output {
        vertices,
        tets,
        mut tags,
        ..
    } = out;
    let mut mesh = TetMesh::new(vertices, tets);
    let mut manifold = manifold::make_boundary_manifold(&mut mesh, &mut tags);
    let pieces = pieces::pieces(&mut mesh, &mut tags, domain.one_piece());
    // Lattice vertices the removals laid bare inside the shape, back onto its boundary.
    // A lattice vertex the stencils left inside (sign < 0, never warped: still at its
    // lattice place) is never on the boundary as stuffed; one found there was laid bare.
    let bare_at = |p: Vec3| -> bool {
        let d = ((p - lattice.origin) * (2.0 / lattice.h)).round();
        lattice
            .id([d.x as i64, d.y as i64, d.z as i64])
            .is_some_and(|v| sign[v as usize] < 0 && pos[v as usize] == p)
    };
    let snapped = bare::snap_bare_vertices(&mut mesh, &tags, domain, size, &bare_at);
    manifold.bare_moved = snapped.onto + snapped.partly;
    manifold.bare_partly = snapped.partly;
    manifold.bare_left = snapped.left;
    // Boundary vertices onto features of the input at resolution h that the lattice
    // passed over (one label: an interface would move with them).
    let resolved = domain.at_resolution(size);
    let followed = if multi {
        follow::Followed::default()
    } else {
        follow::follow_input(&mut mesh, &tags, domain, resolved.as_deref(), size)
    };
    // Interfaces between labels off their chords (each label keeps its volume).
    if multi {
        interface_volume::keep_label_volumes(&mut mesh, &tags, domain, size);
    }
    let mut report = report::measure_against(
        &mesh,
        domain,
        resolved.as_deref(),
        domain_index(domain),
        size,
    );
    report.manifold = manifold;
    report.pieces = pieces;
    report.followed = followed;
    report.warped = warped;
    report.steiner_points = steiner_points;
    report.cut_points = cuts.len();
    report.seconds = seconds;
    if multi {
        report.labels = Some(interfaces::measure_labels(&mesh, &tags, domain, size));
        report.junctions = Some(JunctionCount {
            tets: junctions.tets,
            pieces: junctions.pieces,
            min_dihedral_deg: junctions.min_dihedral_deg,
            clamped_cuts: clamped,
            stencil_min_dihedral_deg: stencil_min.is_finite().then(|| stencil_min.to_degrees()),
        });
    }
    progress.report("report", 1.0);
    Ok(Stuffed { mesh, tags, report })
}

/// Whether moving lattice vertex `v` to `at` would complete a tetrahedron of the lattice
/// whose four corners have all moved (`onto`: the cut point each moved onto, or
/// `warping::STAYS`) with a dihedral angle outside the bounds (`stencil::keep_all_zero`).
fn flat_all_zero(
    lattice: &Lattice,
    v: u32,
    at: Vec3,
    onto: &[u32],
    cut_at: &dyn Fn(u32) -> Vec3,
) -> bool {
    let mut moved: Vec<(u32, [i64; 3])> = Vec::new();
    lattice.for_each_neighbour(v, |u| {
        if onto[u as usize] != warping::STAYS {
            moved.push((u, lattice.coords(u)));
        }
    });
    // Two lattice vertices are joined by an edge when they differ by a long edge (2 along
    // one axis, same colour) or a short one (1 along every axis).
    let joined = |a: [i64; 3], b: [i64; 3]| {
        let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]].map(i64::abs);
        d.iter().all(|&x| x == 1) || (d.iter().sum::<i64>() == 2 && d.contains(&2))
    };
    for (i, &(a, ca)) in moved.iter().enumerate() {
        for (j, &(b, cb)) in moved.iter().enumerate().skip(i + 1) {
            if !joined(ca, cb) {
                continue;
            }
            for &(c, cc) in &moved[j + 1..] {
                if joined(ca, cc) && joined(cb, cc) {
                    let p =
                        [v, a, b, c].map(|u| if u == v { at } else { cut_at(onto[u as usize]) });
                    if !stencil::keep_all_zero(p) {
                        return true;
                    }
                }
            }
        }
    }
    false
}

/// The exact-distance index of a surface domain, if `domain` is one.
fn domain_index(domain: &dyn Domain) -> Option<&TriangleIndex> {
    domain.surface_index()
}

/// Signs of the domain at `points` (-1, 0, +1), in parallel when the feature is on.
fn signs(domain: &dyn Domain, points: &[Vec3], progress: &Progress) -> Vec<i8> {
    let s = |p: &Vec3| {
        let f = domain.value(*p);
        if f < 0.0 {
            -1
        } else if f > 0.0 {
            1
        } else {
            0
        }
    };
    let mut out = Vec::with_capacity(points.len());
    for (k, chunk) in points.chunks(65536).enumerate() {
        #[cfg(feature = "parallel")]
        {
            use rayon::prelude::*;
            out.par_extend(chunk.par_iter().map(s));
        }
        #[cfg(not(feature = "parallel"))]
        out.extend(chunk.iter().map(s));
        progress.report("signs", (k + 1) as Real * 65536.0 / points.len() as Real);
    }
    out
}

/// The smallest dihedral angle of `tets` (radians), -1 when one is turned inside out
/// relative to the reference geometry: how a stencil picks between free splits.
fn stencil_quality(
    tets: &[[Key; 4]],
    at: &dyn Fn(Key) -> Vec3,
    reference: &dyn Fn(Key) -> Vec3,
) -> Real {
    let mut worst = Real::INFINITY;
    for t in tets {
        let (p, r) = (t.map(at), t.map(reference));
        if tet_signed_volume(p[0], p[1], p[2], p[3]) * tet_signed_volume(r[0], r[1], r[2], r[3])
            <= 0.0
        {
            return -1.0;
        }
        worst = dihedral_angles(p).iter().copied().fold(worst, Real::min);
    }
    worst
}

/// The mesh being made: output vertices (lattice vertices and cut points made on first
/// use), tetrahedra and their tags.
struct Output {
    of_lattice: Vec<u32>,
    of_cut: Vec<u32>,
    vertices: Vec<Vec3>,
    tets: Vec<[u32; 4]>,
    tags: Vec<i32>,
}

impl Output {
    /// Adds one BCC tetrahedron's pieces, its prisms' Steiner points first (new vertices at
    /// the prism centres), each piece tagged by `tag` at its centroid.
    fn add(
        &mut self,
        pieces: &[[Key; 4]],
        steiner: &[[Key; 6]],
        cut_base: Key,
        actual: &dyn Fn(Key) -> Vec3,
        reference: &dyn Fn(Key) -> Vec3,
        tag: impl Fn(Vec3) -> i32,
    ) {
        let extra = self.steiner_points(steiner, actual, reference);
        for piece in pieces {
            let centroid = piece
                .iter()
                .map(|&k| match k.checked_sub(stencil::STEINER_BASE) {
                    Some(s) => self.vertices[extra[s as usize].0 as usize],
                    None => actual(k),
                })
                .sum::<Vec3>()
                / 4.0;
            self.emit(*piece, &extra, cut_base, actual, reference);
            self.tags.push(tag(centroid));
        }
    }

    /// Adds pieces whose material is known, tagged `tag_of(material)`.
    fn add_tagged(
        &mut self,
        parts: &[([Key; 4], u16)],
        steiner: &[[Key; 6]],
        cut_base: Key,
        actual: &dyn Fn(Key) -> Vec3,
        reference: &dyn Fn(Key) -> Vec3,
        tag_of: impl Fn(u16) -> i32,
    ) {
        let extra = self.steiner_points(steiner, actual, reference);
        for &(piece, m) in parts {
            self.emit(piece, &extra, cut_base, actual, reference);
            self.tags.push(tag_of(m));
        }
    }

    fn steiner_points(
        &mut self,
        steiner: &[[Key; 6]],
        actual: &dyn Fn(Key) -> Vec3,
        reference: &dyn Fn(Key) -> Vec3,
    ) -> Vec<(u32, Vec3)> {
        steiner
            .iter()
            .map(|p| {
                let id = self.vertices.len() as u32;
                self.vertices
                    .push(p.iter().map(|&k| actual(k)).sum::<Vec3>() / 6.0);
                (id, p.iter().map(|&k| reference(k)).sum::<Vec3>() / 6.0)
            })
            .collect()
    }

    fn emit(
        &mut self,
        piece: [Key; 4],
        extra: &[(u32, Vec3)],
        cut_base: Key,
        actual: &dyn Fn(Key) -> Vec3,
        reference: &dyn Fn(Key) -> Vec3,
    ) {
        emit(
            piece,
            &|k| match k.checked_sub(stencil::STEINER_BASE) {
                Some(s) => extra[s as usize].1,
                None => reference(k),
            },
            actual,
            extra,
            cut_base,
            (&mut self.of_lattice, &mut self.of_cut),
            &mut self.vertices,
            &mut self.tets,
        );
    }
}

/// The junction tetrahedra (three materials or more) and the points where a face's three
/// materials meet, shared by the two tetrahedra on the face.
#[derive(Default)]
struct Junctions {
    triple: FxHashMap<[u32; 3], (u32, Vec3)>,
    tets: usize,
    pieces: usize,
    min_dihedral_deg: Option<Real>,
}

impl Junctions {
    /// Fills junction tetrahedron `t` (`materials::junction`): its face triangles joined to
    /// the mean of its interface points (cut points and face triple points).
    #[allow(clippy::too_many_arguments)]
    fn fill(
        &mut self,
        t: [u32; 4],
        material: &[u16],
        cut_key: &dyn Fn(u32, u32) -> Key,
        actual: &dyn Fn(Key) -> Vec3,
        reference: &dyn Fn(Key) -> Vec3,
        split: &stencil::Split<'_>,
        out: &mut Output,
        tag_of: impl Fn(u16) -> i32,
    ) {
        let m = |v: u32| material[v as usize];
        // Slot 0 is the centre, then the faces' triple points.
        let mut extra: Vec<(u32, Vec3)> = vec![(0, Vec3::ZERO)];
        let mut faces: Vec<[u32; 3]> = Vec::new();
        let (mut sum, mut sum_ref, mut count) = (Vec3::ZERO, Vec3::ZERO, 0.0);
        for i in 0..4 {
            for j in i + 1..4 {
                if m(t[i]) != m(t[j]) {
                    let k = cut_key(t[i], t[j]);
                    sum += actual(k);
                    sum_ref += reference(k);
                    count += 1.0;
                }
            }
        }
        for skip in 0..4 {
            let mut f = [0u32; 3];
            let mut n = 0;
            for (i, &v) in t.iter().enumerate() {
                if i != skip {
                    f[n] = v;
                    n += 1;
                }
            }
            let [a, b, c] = f.map(m);
            if a == b || b == c || a == c {
                continue;
            }
            f.sort_unstable();
            let (id, r) = *self.triple.entry(f).or_insert_with(|| {
                let ks = [
                    cut_key(f[0], f[1]),
                    cut_key(f[1], f[2]),
                    cut_key(f[0], f[2]),
                ];
                let id = out.vertices.len() as u32;
                out.vertices
                    .push(ks.iter().map(|&k| actual(k)).sum::<Vec3>() / 3.0);
                (id, ks.iter().map(|&k| reference(k)).sum::<Vec3>() / 3.0)
            });
            sum += out.vertices[id as usize];
            sum_ref += r;
            count += 1.0;
            extra.push((id, r));
            faces.push(f);
        }
        let centre = out.vertices.len() as u32;
        out.vertices.push(sum / count);
        extra[0] = (centre, sum_ref / count);
        let mut parts = Vec::new();
        materials::junction(
            t,
            m,
            cut_key,
            split,
            |f| {
                let i = faces.iter().position(|g| *g == f).unwrap_or(0);
                stencil::STEINER_BASE + 1 + i as Key
            },
            stencil::STEINER_BASE,
            &mut parts,
        );
        let cut_base = out.of_lattice.len() as Key;
        for &(piece, mat) in &parts {
            out.emit(piece, &extra, cut_base, actual, reference);
            out.tags.push(tag_of(mat));
            let tet = out.tets[out.tets.len() - 1];
            let p = tet.map(|v| out.vertices[v as usize]);
            let worst = dihedral_angles(p)
                .iter()
                .fold(Real::INFINITY, |a, &b| a.min(b.to_degrees()));
            self.min_dihedral_deg = Some(self.min_dihedral_deg.map_or(worst, |w| w.min(worst)));
        }
        self.tets += 1;
        self.pieces += parts.len();
    }
}

/// Adds one output tetrahedron: maps its keys to output vertices (made on first use) and
/// orients it positively as measured on the reference geometry.
#[allow(clippy::too_many_arguments)]
fn emit(
    piece: [Key; 4],
    reference: &dyn Fn(Key) -> Vec3,
    actual: &dyn Fn(Key) -> Vec3,
    steiner: &[(u32, Vec3)],
    cut_base: Key,
    (of_lattice, of_cut): (&mut [u32], &mut [u32]),
    vertices: &mut Vec<Vec3>,
    tets: &mut Vec<[u32; 4]>,
) {
    let mut tet = piece.map(|k| {
        if let Some(s) = k.checked_sub(stencil::STEINER_BASE) {
            return steiner[s as usize].0;
        }
        let slot = if k < cut_base {
            &mut of_lattice[k as usize]
        } else {
            &mut of_cut[(k - cut_base) as usize]
        };
        if *slot == u32::MAX {
            *slot = vertices.len() as u32;
            vertices.push(actual(k));
        }
        *slot
    });
    let r = piece.map(reference);
    if tet_signed_volume(r[0], r[1], r[2], r[3]) < 0.0 {
        tet.swap(2, 3);
    }
    tets.push(tet);
}

#[cfg(test)]
mod label_tests;
#[cfg(test)]
mod tests;
