//! The numbers every meshing run is checked against: element shape (dihedral angles, radius
//! ratio), validity (inverted or degenerate elements), volume against the input's, and the
//! distance between the mesh boundary and the input boundary.

use std::fmt;

use serde::Serialize;

use crate::math::{Real, Vec3, tet_signed_volume};
use crate::mesh::TetMesh;
use crate::mesh::boundary::boundary_surface;

use super::domain::{Domain, crossings_in_box};
use super::triangle_index::TriangleIndex;

/// The guarantee checked on every uniform-size output (the stencils keep 10.7°: proven by
/// Labelle & Shewchuk for their α, sampled for ours in `stencil_bounds`).
pub const MIN_DIHEDRAL_DEG: Real = 10.0;
/// Largest allowed relative volume error.
pub const MAX_VOLUME_ERROR: Real = 0.01;
/// Largest allowed relative volume error of one label against its voxels.
pub const MAX_LABEL_VOLUME_ERROR: Real = 0.01;
/// A tetrahedron is degenerate below this volume, relative to h³.
const DEGENERATE_VOLUME: Real = 1e-9;

/// What a meshing run produced and how good it is.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MeshingReport {
    /// Lattice spacing h (m): the long edge of the BCC tetrahedra.
    pub size: Real,
    pub vertices: usize,
    pub tets: usize,
    pub boundary_triangles: usize,
    /// Lattice vertices moved onto the surface, and cut points made.
    pub warped: usize,
    pub cut_points: usize,
    /// Prism centres added where the quadrilateral diagonals leave no 3-tetrahedron split.
    pub steiner_points: usize,
    pub min_dihedral_deg: Real,
    pub median_dihedral_deg: Real,
    pub max_dihedral_deg: Real,
    /// Radius ratio 3·r_in/r_circ (1 for the regular tetrahedron).
    pub min_radius_ratio: Real,
    pub median_radius_ratio: Real,
    pub inverted: usize,
    pub degenerate: usize,
    /// Mesh volume (m³), the input's (closed surface or voxel count), and the relative error.
    pub volume: Real,
    pub reference_volume: Option<Real>,
    pub volume_error: Option<Real>,
    /// An image cleaned before meshing: what changed, the selected voxels' volume before the
    /// cleaning (m³) and the mesh's relative error against it (for information; the
    /// guarantee is against the cleaned voxels).
    pub cleaning: Option<crate::image::CleanReport>,
    pub uncleaned_volume: Option<Real>,
    pub uncleaned_volume_error: Option<Real>,
    /// Largest distance from a mesh boundary point (vertex, face centroid, edge midpoint) to
    /// the input boundary (m).
    pub mesh_to_input: Real,
    /// Largest distance from an input boundary sample to the mesh boundary (m), over the
    /// whole input, features thinner than h included.
    pub input_to_mesh: Real,
    /// The fraction of the input boundary samples farther than h/2 from the mesh boundary
    /// (what the mesh misses), and the farthest sample (m).
    pub input_beyond_half_size: Real,
    pub farthest_input_sample: [Real; 3],
    /// For an image: the largest distance from the input *at resolution h* (the voxels
    /// opened and closed by a ball of radius h/2, so without the sheets, strands, cracks
    /// and channels thinner than h that no lattice of spacing h can follow) to the mesh
    /// boundary (m). The boundary guarantee is checked with this when it is given.
    pub resolved_input_to_mesh: Option<Real>,
    /// Where `resolved_input_to_mesh` is reached (m): the sample of the input at resolution
    /// h farthest from the mesh, so a broken boundary promise says where.
    pub farthest_resolved_sample: Option<[Real; 3]>,
    /// max of `mesh_to_input` and the checked input→mesh distance (`resolved_input_to_mesh`
    /// when given, else `input_to_mesh`): the (sampled) Hausdorff distance the guarantee
    /// holds to h/2.
    pub hausdorff: Real,
    /// How `mesh_to_input` was measured: "exact" (a surface) or "first-order" (|f|/|∇f|).
    pub distance_method: &'static str,
    /// Wall time of the meshing itself, in s.
    pub seconds: Real,
    /// Vertices split and tetrahedra removed so that the boundary is a 2-manifold, and any
    /// defect left (`manifold`).
    pub manifold: super::manifold::ManifoldRepair,
    /// The mesh's pieces, and those dropped when the input is one piece (`pieces`).
    pub pieces: super::pieces::Pieces,
    /// Boundary vertices moved onto features of the input at resolution h that the lattice
    /// passed over (`follow`).
    pub followed: super::follow::Followed,
    /// Several labels meshed as separate regions: each label's tetrahedra and volume
    /// against its voxels, and the interfaces' distance to the input's (`interfaces`).
    pub labels: Option<super::interfaces::Labels>,
    /// Several labels: the tetrahedra where three materials meet, filled without the
    /// stencils' angle bound (`materials`), and the smallest angle they reached.
    pub junctions: Option<JunctionCount>,
}

/// The junction tetrahedra of a mesh of several labels (`materials::junction`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct JunctionCount {
    /// Lattice tetrahedra with three or four materials, and the tetrahedra made of them.
    pub tets: usize,
    pub pieces: usize,
    /// Their smallest dihedral angle (degrees), before the manifold repair.
    pub min_dihedral_deg: Option<Real>,
    /// Cut points kept α·length from a vertex that could not be warped (next to a third
    /// material).
    pub clamped_cuts: usize,
    /// The smallest dihedral angle (degrees) of every other tetrahedron: the two-material
    /// stencils, which keep the single-surface stencils' bound (`stencil_bounds`), before
    /// the manifold repair.
    pub stencil_min_dihedral_deg: Option<Real>,
}

impl MeshingReport {
    /// The guarantees this mesh breaks, in words; empty when it keeps them all.
    pub fn violations(&self) -> Vec<String> {
        let mut v = Vec::new();
        if self.tets == 0 {
            v.push(
                "no tetrahedra: the shape is thinner than the size; use a smaller --size".into(),
            );
        }
        if self.inverted > 0 {
            v.push(format!("{} inverted tetrahedra", self.inverted));
        }
        if self.degenerate > 0 {
            v.push(format!("{} degenerate tetrahedra", self.degenerate));
        }
        if self.tets > 0 && self.min_dihedral_deg < MIN_DIHEDRAL_DEG {
            v.push(format!(
                "minimum dihedral angle {:.2}° < {MIN_DIHEDRAL_DEG}°",
                self.min_dihedral_deg
            ));
        }
        if self.hausdorff > 0.5 * self.size {
            v.push(format!(
                "boundary {:.3e} m from the input, more than h/2 = {:.3e} m",
                self.hausdorff,
                0.5 * self.size
            ));
        }
        let m = &self.manifold;
        if m.edges_left + m.vertices_left > 0 {
            v.push(format!(
                "boundary not a 2-manifold: {} edges shared by more than two triangles, {} \
                 vertices where parts touch",
                m.edges_left, m.vertices_left
            ));
        }
        if let Some(e) = self.volume_error
            && e.abs() > MAX_VOLUME_ERROR
        {
            v.push(format!(
                "volume {:+.2} % off the input's (more than {} %)",
                100.0 * e,
                100.0 * MAX_VOLUME_ERROR
            ));
        }
        if let Some(labels) = &self.labels {
            for l in &labels.volumes {
                if let Some(e) = l.volume_error
                    && e.abs() > MAX_LABEL_VOLUME_ERROR
                {
                    v.push(format!(
                        "label {}: volume {:+.2} % off its voxels' (more than {} %)",
                        l.tag,
                        100.0 * e,
                        100.0 * MAX_LABEL_VOLUME_ERROR
                    ));
                }
                if l.tets == 0 {
                    v.push(format!(
                        "label {}: no tetrahedra (thinner than the size)",
                        l.tag
                    ));
                }
            }
            let i = &labels.interface;
            let far = i.mesh_to_input.max(i.input_to_mesh);
            if far > 0.5 * self.size {
                v.push(format!(
                    "interface between labels {far:.3e} m from the voxels', more than h/2 = \
                     {:.3e} m",
                    0.5 * self.size
                ));
            }
            if i.nonconforming_faces > 0 {
                v.push(format!(
                    "{} faces where labels do not conform",
                    i.nonconforming_faces
                ));
            }
        }
        v
    }
}

impl fmt::Display for MeshingReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{} tetrahedra, {} vertices, {} boundary triangles (size h = {:.4e} m; {} cut points, {} warped vertices, {} Steiner points) in {:.2} s",
            self.tets,
            self.vertices,
            self.boundary_triangles,
            self.size,
            self.cut_points,
            self.warped,
            self.steiner_points,
            self.seconds
        )?;
        writeln!(
            f,
            "dihedral angles: min {:.2}°, median {:.2}°, max {:.2}°",
            self.min_dihedral_deg, self.median_dihedral_deg, self.max_dihedral_deg
        )?;
        writeln!(
            f,
            "radius ratio:    min {:.3}, median {:.3}; inverted {}, degenerate {}",
            self.min_radius_ratio, self.median_radius_ratio, self.inverted, self.degenerate
        )?;
        match (self.reference_volume, self.volume_error) {
            (Some(r), Some(e)) => writeln!(
                f,
                "volume:          {:.6e} m³ against the input's {:.6e} m³ ({:+.3} %)",
                self.volume,
                r,
                100.0 * e
            )?,
            _ => writeln!(f, "volume:          {:.6e} m³", self.volume)?,
        }
        if let (Some(c), Some(r), Some(e)) = (
            &self.cleaning,
            self.uncleaned_volume,
            self.uncleaned_volume_error,
        ) {
            let mut closing = String::new();
            if c.close > 0.0 {
                closing.push_str(&format!(
                    "closed by a ball of radius {:.3e} m ({} voxels of cracks filled), ",
                    c.close, c.closed_voxels
                ));
            }
            if c.open > 0.0 {
                closing.push_str(&format!(
                    "opened by a ball of radius {:.3e} m ({} voxels of strands removed), ",
                    c.open, c.opened_voxels
                ));
            }
            writeln!(
                f,
                "cleaned image:   {} → {} voxels ({closing}opened then closed by {} voxels, {} \
                 parts dropped, {} hole voxels filled); volume against the voxels before \
                 cleaning {:.6e} m³: {:+.3} %",
                c.voxels_before,
                c.voxels_after,
                c.open_close,
                c.parts_dropped,
                c.hole_voxels_filled,
                r,
                100.0 * e
            )?;
        }
        writeln!(
            f,
            "boundary:        mesh→input {:.3e} m ({}), input→mesh {:.3e} m{}; Hausdorff {:.3e} m = {:.3} h",
            self.mesh_to_input,
            self.distance_method,
            self.resolved_input_to_mesh.unwrap_or(self.input_to_mesh),
            if let Some([x, y, z]) = self.farthest_resolved_sample {
                format!(" (from the input at resolution h; farthest at {x:.4}, {y:.4}, {z:.4} m)")
            } else {
                String::new()
            },
            self.hausdorff,
            self.hausdorff / self.size
        )?;
        if self.input_beyond_half_size > 0.0 {
            let [x, y, z] = self.farthest_input_sample;
            writeln!(
                f,
                "not followed:    {:.2} % of the input boundary lies farther than h/2 from the mesh, \
                 up to {:.3e} m = {:.2} h (at {x:.4}, {y:.4}, {z:.4} m){}",
                100.0 * self.input_beyond_half_size,
                self.input_to_mesh,
                self.input_to_mesh / self.size,
                if self.resolved_input_to_mesh.is_some() {
                    ": sheets, strands, cracks or channels of the input thinner than h, which \
                     a lattice of spacing h cannot follow; a smaller size follows them"
                } else {
                    ""
                }
            )?;
        }
        if self.manifold.split > 0 {
            writeln!(
                f,
                "manifold:        {} vertices split where parts of the mesh touched along an \
                 edge or at a vertex (each part its own copy, moved at most a fifth of an edge \
                 into it)",
                self.manifold.split
            )?;
        }
        if self.manifold.removed > 0 {
            writeln!(
                f,
                "manifold:        {} tetrahedra ({:.3e} m³) removed where parts of the mesh \
                 touched and no split could part them",
                self.manifold.removed, self.manifold.removed_volume
            )?;
        }
        let m = &self.manifold;
        if m.bare_moved + m.bare_left > 0 {
            writeln!(
                f,
                "bare vertices:   {} boundary vertices inside the shape moved onto its boundary \
                 ({} only part of the way), {} left inside",
                m.bare_moved, m.bare_partly, m.bare_left
            )?;
        }
        let fo = &self.followed;
        if fo.onto + fo.partly + fo.refused + fo.off_chords > 0 {
            writeln!(
                f,
                "followed:        {} boundary vertices moved onto the input where the mesh \
                 passed over it by more than 0.45 h ({} only part of the way), {} pulls refused \
                 (angles, or the mesh→input distance); {} moved off their faces' chords",
                fo.onto + fo.partly,
                fo.partly,
                fo.refused,
                fo.off_chords
            )?;
        }
        let p = &self.pieces;
        if p.dropped > 0 {
            writeln!(
                f,
                "pieces:          {} small pieces dropped ({} tetrahedra, {:.3e} m³): joined \
                 to the rest only by strands thinner than h, which the lattice cannot follow",
                p.dropped, p.dropped_tets, p.dropped_volume
            )?;
        } else if p.count > 1 {
            writeln!(
                f,
                "pieces:          {} (a piece that no support holds leaves a model singular)",
                p.count
            )?;
        }
        if let Some(labels) = &self.labels {
            for l in &labels.volumes {
                write!(
                    f,
                    "label {:<9} {} tetrahedra, volume {:.6e} m³",
                    format!("{}:", l.tag),
                    l.tets,
                    l.volume
                )?;
                match (l.voxel_volume, l.volume_error) {
                    (Some(r), Some(e)) => {
                        writeln!(f, " against its voxels' {r:.6e} m³ ({:+.3} %)", 100.0 * e)?
                    }
                    _ => writeln!(f)?,
                }
            }
            let i = &labels.interface;
            writeln!(
                f,
                "interfaces:      {} triangles ({} rim edges where they meet the boundary); \
                 mesh→voxel interface {:.3e} m = {:.3} h, voxel interface→mesh {:.3e} m = {:.3} h",
                i.triangles,
                i.rim_edges,
                i.mesh_to_input,
                i.mesh_to_input / self.size,
                i.input_to_mesh,
                i.input_to_mesh / self.size
            )?;
        }
        if let Some(j) = &self.junctions
            && j.tets > 0
        {
            writeln!(
                f,
                "junctions:       {} lattice tetrahedra where three labels (or two and the \
                 outside) meet, filled by {} cones (min dihedral {:.2}°, no proven bound); {} \
                 cut points held α·length from a vertex that could not be warped; the other \
                 tetrahedra (two-material stencils, sampled bound 10.7°) min {:.2}°",
                j.tets,
                j.pieces,
                j.min_dihedral_deg.unwrap_or(0.0),
                j.clamped_cuts,
                j.stencil_min_dihedral_deg.unwrap_or(0.0)
            )?;
        }
        let v = self.violations();
        if v.is_empty() {
            writeln!(
                f,
                "guarantees kept: no inverted or degenerate element, min dihedral ≥ {MIN_DIHEDRAL_DEG}°, boundary a 2-manifold within h/2{}",
                if self.volume_error.is_some() {
                    ", volume within 1 %"
                } else {
                    ""
                }
            )
        } else {
            writeln!(f, "GUARANTEES BROKEN: {}", v.join("; "))
        }
    }
}

/// The six dihedral angles of a tetrahedron, in radians: the angle at edge (i, j) between
/// the two faces through it, measured between the other two corners projected onto the
/// plane normal to the edge.
pub fn dihedral_angles(p: [Vec3; 4]) -> [Real; 6] {
    const EDGES: [(usize, usize, usize, usize); 6] = [
        (0, 1, 2, 3),
        (0, 2, 1, 3),
        (0, 3, 1, 2),
        (1, 2, 0, 3),
        (1, 3, 0, 2),
        (2, 3, 0, 1),
    ];
    EDGES.map(|(i, j, k, l)| {
        let e = (p[j] - p[i]).normalize_or_zero();
        let u = p[k] - p[i];
        let v = p[l] - p[i];
        let u = u - e * e.dot(u);
        let v = v - e * e.dot(v);
        let c = u.dot(v) / (u.length() * v.length());
        if c.is_finite() {
            c.clamp(-1.0, 1.0).acos()
        } else {
            0.0
        }
    })
}

/// 3·r_in / r_circ: 1 for the regular tetrahedron, 0 when flat.
pub fn radius_ratio(p: [Vec3; 4]) -> Real {
    let v = tet_signed_volume(p[0], p[1], p[2], p[3]).abs();
    let area = |a: Vec3, b: Vec3, c: Vec3| 0.5 * (b - a).cross(c - a).length();
    let faces = area(p[1], p[2], p[3])
        + area(p[0], p[2], p[3])
        + area(p[0], p[1], p[3])
        + area(p[0], p[1], p[2]);
    let (a, b, c) = (p[0] - p[3], p[1] - p[3], p[2] - p[3]);
    let num = a.length_squared() * b.cross(c)
        + b.length_squared() * c.cross(a)
        + c.length_squared() * a.cross(b);
    let r_circ = num.length() / (12.0 * v);
    let r_in = 3.0 * v / faces;
    let q = 3.0 * r_in / r_circ;
    if q.is_finite() { q } else { 0.0 }
}

/// Mesh→input estimates above this share of h are made tighter by `refined_distance`.
const REFINE_ABOVE: Real = 0.4;
/// The spacing, relative to h, of the lines along which `refined_distance` finds the
/// boundary.
const REFINE_SPACING: Real = 1.0 / 16.0;

/// The distance from `p` to the boundary of `domain`, given an upper bound `estimate`, made
/// tighter where it matters: above `REFINE_ABOVE`·h, the nearest of the boundary points
/// where lines h/16 apart through the box of half-width `estimate` around `p` cross it.
/// Every such point is on the boundary, so the result is still never an underestimate. Why:
/// where an image's mask is flat (more than a voxel from the boundary, without a blur) the
/// first-order estimate |f|/|∇f| is infinite and the bound is the nearest of the input's
/// samples, which lie on lines h/4 apart and so can be about h/8 farther than the boundary
/// between them (issue 25: the brain at 6 mm, 0.616 h by the samples).
pub(super) fn refined_distance(domain: &dyn Domain, p: Vec3, estimate: Real, size: Real) -> Real {
    if !(estimate.is_finite() && estimate > REFINE_ABOVE * size) {
        return estimate;
    }
    let r = Vec3::splat(estimate);
    crossings_in_box(domain, p - r, p + r, REFINE_SPACING * size)
        .iter()
        .map(|&q| (q - p).length())
        .fold(estimate, Real::min)
}

fn median(mut v: Vec<Real>) -> Real {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_unstable_by(Real::total_cmp);
    v[v.len() / 2]
}

/// Measures a mesh against the domain it was made from. `size` is the lattice spacing.
pub fn measure(
    mesh: &TetMesh,
    domain: &dyn Domain,
    exact_distance: Option<&TriangleIndex>,
    size: Real,
) -> MeshingReport {
    let resolved = domain.at_resolution(size);
    measure_against(mesh, domain, resolved.as_deref(), exact_distance, size)
}

/// `measure`, with the input at resolution h already made (`Domain::at_resolution`: four
/// distance transforms of the image, 1-2 s on the pelvis, which the mesher made already).
pub fn measure_against(
    mesh: &TetMesh,
    domain: &dyn Domain,
    resolved: Option<&dyn Domain>,
    exact_distance: Option<&TriangleIndex>,
    size: Real,
) -> MeshingReport {
    let mut angles = Vec::with_capacity(6 * mesh.tets.len());
    let mut ratios = Vec::with_capacity(mesh.tets.len());
    let (mut inverted, mut degenerate) = (0, 0);
    let mut volume = 0.0;
    let flat = DEGENERATE_VOLUME * size * size * size;
    for t in 0..mesh.tets.len() {
        let p = mesh.corners(t);
        let v = tet_signed_volume(p[0], p[1], p[2], p[3]);
        volume += v;
        if v.abs() <= flat {
            degenerate += 1;
        } else if v < 0.0 {
            inverted += 1;
        }
        angles.extend(dihedral_angles(p).map(Real::to_degrees));
        ratios.push(radius_ratio(p));
    }
    let min_dihedral_deg = angles.iter().copied().fold(Real::INFINITY, Real::min);
    let max_dihedral_deg = angles.iter().copied().fold(0.0, Real::max);
    let min_radius_ratio = ratios.iter().copied().fold(Real::INFINITY, Real::min);
    let boundary = if mesh.tets.is_empty() {
        Default::default()
    } else {
        boundary_surface(mesh).surface
    };
    // Mesh → input: the boundary's vertices, face centroids and edge midpoints.
    let mut probes = boundary.vertices.clone();
    for t in 0..boundary.triangles.len() {
        let [a, b, c] = boundary.corners(t);
        probes.extend([
            (a + b + c) / 3.0,
            0.5 * (a + b),
            0.5 * (b + c),
            0.5 * (c + a),
        ]);
    }
    // Input → mesh: boundary samples of the input, about h/4 apart; of the whole input (what
    // the mesh misses, reported) and of the input at resolution h (what it must follow).
    let samples = domain.boundary_samples(0.25 * size);
    let index = TriangleIndex::new(&boundary.vertices, &boundary.triangles);
    let (mut input_to_mesh, mut farthest, mut beyond) = (0.0, Vec3::ZERO, 0usize);
    for &p in &samples {
        let d = index.distance(p);
        if d > 0.5 * size {
            beyond += 1;
        }
        if d > input_to_mesh {
            (input_to_mesh, farthest) = (d, p);
        }
    }
    let resolved_far = resolved.map(|r| {
        r.boundary_samples(0.25 * size)
            .iter()
            .map(|&p| (index.distance(p), p))
            .fold((0.0, Vec3::ZERO), |a, b| if b.0 > a.0 { b } else { a })
    });
    let resolved_input_to_mesh = resolved_far.map(|(d, _)| d);
    // Without the exact surface, the first-order estimate, bounded above by the distance to
    // the nearest boundary sample (which is on the boundary, so never an underestimate);
    // the samples are indexed as one-point triangles.
    let nearest_sample = (exact_distance.is_none() && !samples.is_empty()).then(|| {
        let points: Vec<[u32; 3]> = (0..samples.len() as u32).map(|i| [i, i, i]).collect();
        TriangleIndex::new(&samples, &points)
    });
    let step = 1e-3 * size;
    let mesh_to_input = probes
        .iter()
        .map(|&p| match (exact_distance, &nearest_sample) {
            (Some(index), _) => index.distance(p),
            (None, Some(near)) => refined_distance(
                domain,
                p,
                domain.boundary_distance(p, step).min(near.distance(p)),
                size,
            ),
            (None, None) => domain.boundary_distance(p, step),
        })
        .fold(0.0, Real::max);
    let reference_volume = domain.reference_volume();
    let cleaning = domain.cleaning();
    MeshingReport {
        size,
        vertices: mesh.vertices.len(),
        tets: mesh.tets.len(),
        boundary_triangles: boundary.triangles.len(),
        warped: 0,
        cut_points: 0,
        steiner_points: 0,
        min_dihedral_deg: if mesh.tets.is_empty() {
            0.0
        } else {
            min_dihedral_deg
        },
        median_dihedral_deg: median(angles),
        max_dihedral_deg,
        min_radius_ratio: if mesh.tets.is_empty() {
            0.0
        } else {
            min_radius_ratio
        },
        median_radius_ratio: median(ratios),
        inverted,
        degenerate,
        volume,
        reference_volume,
        volume_error: reference_volume
            .filter(|&r| r > 0.0)
            .map(|r| (volume - r) / r),
        uncleaned_volume: cleaning.as_ref().map(|c| c.1),
        uncleaned_volume_error: cleaning
            .as_ref()
            .filter(|c| c.1 > 0.0)
            .map(|c| (volume - c.1) / c.1),
        cleaning: cleaning.map(|c| c.0),
        mesh_to_input,
        input_to_mesh,
        input_beyond_half_size: beyond as Real / samples.len().max(1) as Real,
        farthest_input_sample: farthest.to_array(),
        resolved_input_to_mesh,
        farthest_resolved_sample: resolved_far.map(|(_, p)| p.to_array()),
        hausdorff: mesh_to_input.max(resolved_input_to_mesh.unwrap_or(input_to_mesh)),
        distance_method: if exact_distance.is_some() {
            "exact"
        } else {
            "first-order"
        },
        seconds: 0.0,
        manifold: Default::default(),
        pieces: Default::default(),
        followed: Default::default(),
        labels: None,
        junctions: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_and_right_corner_tetrahedra() {
        let reg = [
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(1.0, -1.0, -1.0),
            Vec3::new(-1.0, 1.0, -1.0),
            Vec3::new(-1.0, -1.0, 1.0),
        ];
        let want = (1.0f64 / 3.0).acos();
        assert!(
            dihedral_angles(reg)
                .iter()
                .all(|a| (a - want).abs() < 1e-12)
        );
        assert!((radius_ratio(reg) - 1.0).abs() < 1e-12);
        let corner = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        let a = dihedral_angles(corner).map(Real::to_degrees);
        // Three right angles at the corner edges, three of acos(1/√3) ≈ 54.74° elsewhere.
        let mut s = a.to_vec();
        s.sort_by(Real::total_cmp);
        assert!((s[0] - 54.735_610_317).abs() < 1e-6 && (s[2] - 54.735_610_317).abs() < 1e-6);
        assert!(s[3..].iter().all(|x| (x - 90.0).abs() < 1e-9));
    }

    /// A boundary whose function carries only its sign (as a voxel mask far from its edge):
    /// the plane x = 0. A pessimistic bound of 0.7 h at a point 0.3 h from it comes down to
    /// the true distance within the local lines' spacing, and never below it; a bound
    /// under 0.4 h is left alone.
    #[test]
    fn a_pessimistic_distance_bound_is_refined_and_never_undershoots() {
        let h = 0.01;
        let plane = super::super::domain::Implicit {
            f: |p: Vec3| 0.5 * p.x.signum(),
            lo: Vec3::splat(-0.05),
            hi: Vec3::splat(0.05),
            volume: None,
        };
        let p = Vec3::new(0.3 * h, 0.123 * h, -0.2 * h);
        let d = refined_distance(&plane, p, 0.7 * h, h);
        assert!(d >= 0.3 * h - 1e-12 && d <= 0.3 * h + h / 16.0, "{}", d / h);
        assert_eq!(refined_distance(&plane, p, 0.35 * h, h), 0.35 * h);
        assert!(refined_distance(&plane, p, Real::INFINITY, h).is_infinite());
    }
}
