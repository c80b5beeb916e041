//! The organ and the shared scenario geometry: where it is held, where the probe presses,
//! the plate that compresses it, the axis it is turned about. Everything is chosen from the
//! organ's bounding box, so any organ gets the same scenarios; every model selects its own
//! surface vertices from these regions (models draw different surfaces).

use serde::{Deserialize, Serialize};

use std::time::Instant;

use crate::error::{Error, MeshError, SimError};
use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::mesh::stuffing::{SurfaceDomain, size_for, stuff};
use crate::mesh::{MeshData, split_tets};
use crate::model::{BuildInput, Deformable, Progress, build};

/// The scenario geometry derived from the organ (SI units). "Up" is +y, as in the scenes.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Scenario {
    pub lo: [Real; 3],
    pub hi: [Real; 3],
    /// Organ height along y, m.
    pub height: Real,
    /// Bounding-box diagonal, m.
    pub size: Real,
    /// Surface vertices with y below this are held (the bottom slab).
    pub fixed_below: Real,
    /// The probe's contact point on top of the organ and its radius, m.
    pub probe_point: [Real; 3],
    pub probe_radius: Real,
    /// Quasi-static indentation depths, m (5 % and 20 % of the height).
    pub shallow: Real,
    pub deep: Real,
    /// Surface vertices with y above this are carried by the compression plate.
    pub plate_above: Real,
    /// The plate's travel, m (10 % of the height).
    pub compression: Real,
    /// The far-side point whose response time is the survey's "delay".
    pub far_point: [Real; 3],
    /// Volume of the organ's surface, m³.
    pub volume: Real,
    /// Vertices of the organ's surface (the unit of "dimension of the system").
    pub surface_vertices: usize,
}

impl Scenario {
    /// The scenarios for an organ (its surface from `mesh`).
    pub fn of(mesh: &MeshData) -> Result<Self, Error> {
        let surface = mesh.surface_mesh()?;
        let (lo, hi) = surface.bounds().ok_or(crate::error::MeshError::Empty {
            what: "surface vertices",
        })?;
        let height = hi.y - lo.y;
        let size = (hi - lo).length();
        let centre = 0.5 * (lo + hi);
        // The top point nearest the middle: the highest vertex within a quarter of the
        // horizontal extent of the box centre.
        let reach = 0.25 * Vec3::new(hi.x - lo.x, 0.0, hi.z - lo.z).length();
        let top = surface
            .vertices
            .iter()
            .filter(|p| Vec3::new(p.x - centre.x, 0.0, p.z - centre.z).length() <= reach)
            .copied()
            .max_by(|a, b| a.y.total_cmp(&b.y))
            .unwrap_or(Vec3::new(centre.x, hi.y, centre.z));
        // A blunt indenter (radius half the height): its contact patch spans several
        // elements of a coarse organ, so the force converges under refinement.
        let radius = 0.5 * height.max(1e-9);
        let far = surface
            .vertices
            .iter()
            .filter(|p| p.y > lo.y + 0.3 * height)
            .copied()
            .max_by(|a, b| {
                let d = |p: &Vec3| Vec3::new(p.x - top.x, 0.0, p.z - top.z).length();
                d(a).total_cmp(&d(b))
            })
            .unwrap_or(hi);
        Ok(Self {
            lo: lo.into(),
            hi: hi.into(),
            height,
            size,
            fixed_below: lo.y + 0.1 * height,
            probe_point: top.into(),
            probe_radius: radius,
            shallow: 0.05 * height,
            deep: 0.2 * height,
            plate_above: hi.y - 0.1 * height,
            compression: 0.1 * height,
            far_point: far.into(),
            volume: surface.signed_volume().abs(),
            surface_vertices: surface.vertices.len(),
        })
    }

    pub fn probe(&self) -> Vec3 {
        Vec3::from(self.probe_point)
    }

    /// The fixed surface vertices of a model: the bottom slab, or, where the slab holds
    /// fewer than three vertices that span a plane (a coarse or stuffed surface can put just
    /// one or two there, and a static model is then free to move rigidly), the lowest
    /// vertices up to the first three that do.
    pub fn fixed(&self, rest: &[Vec3]) -> Vec<u32> {
        let mut v: Vec<u32> = (0..rest.len() as u32)
            .filter(|&i| rest[i as usize].y <= self.fixed_below)
            .collect();
        if spans_a_plane(rest, &v) {
            return v;
        }
        let mut by_height: Vec<u32> = (0..rest.len() as u32).collect();
        by_height.sort_by(|&a, &b| rest[a as usize].y.total_cmp(&rest[b as usize].y));
        v.clear();
        for i in by_height {
            v.push(i);
            if spans_a_plane(rest, &v) {
                break;
            }
        }
        v
    }

    /// The surface vertices the plate carries.
    pub fn plate(&self, rest: &[Vec3]) -> Vec<u32> {
        (0..rest.len() as u32)
            .filter(|&i| rest[i as usize].y >= self.plate_above)
            .collect()
    }

    /// The surface vertices within `r` of the probe point (a patch on top).
    pub fn patch(&self, rest: &[Vec3], r: Real) -> Vec<u32> {
        let p = self.probe();
        let mut v: Vec<u32> = (0..rest.len() as u32)
            .filter(|&i| rest[i as usize].distance(p) <= r)
            .collect();
        if v.is_empty()
            && let Some(i) = nearest(rest, p)
        {
            v.push(i);
        }
        v
    }
}

/// Whether some three of the listed vertices are not collinear (a body held there cannot
/// move rigidly).
fn spans_a_plane(rest: &[Vec3], v: &[u32]) -> bool {
    let p = |i: u32| rest[i as usize];
    let Some((&a, others)) = v.split_first() else {
        return false;
    };
    let Some(&b) = others
        .iter()
        .max_by(|&&x, &&y| p(x).distance(p(a)).total_cmp(&p(y).distance(p(a))))
    else {
        return false;
    };
    let (pa, pb) = (p(a), p(b));
    let scale = pa.distance(pb);
    scale > 0.0
        && v.iter()
            .any(|&c| (pb - pa).cross(p(c) - pa).length() > 1e-6 * scale * scale)
}

/// The vertex of `points` nearest to `p`.
pub fn nearest(points: &[Vec3], p: Vec3) -> Option<u32> {
    (0..points.len() as u32).min_by(|&a, &b| {
        points[a as usize]
            .distance_squared(p)
            .total_cmp(&points[b as usize].distance_squared(p))
    })
}

/// The organ as the comparison uses it: a loaded mesh and the material.
#[derive(Clone, Debug)]
pub struct Organ {
    /// The mesh as loaded: tetrahedra, or a closed surface only.
    pub mesh: MeshData,
    /// Names the organ in messages and in the record.
    pub name: String,
    pub material: Material,
    /// Seconds it took to read the file (counted in every model's mesh acquisition).
    pub read_seconds: Real,
    /// For an organ given as a surface: its tetrahedra by the project's own isosurface
    /// stuffing, for the kinds that need a volume and for the reference.
    pub stuffed: Option<Stuffing>,
}

/// Tetrahedra made from a surface-only organ, and what making them cost (counted in the
/// mesh data acquisition of every kind that needs them).
#[derive(Clone, Debug)]
pub struct Stuffing {
    pub mesh: MeshData,
    pub seconds: Real,
    /// The lattice spacing used, m.
    pub size: Real,
    /// The mesher's checks the tetrahedra fail (volume or boundary off the surface), if any.
    pub issues: Vec<String>,
}

impl Stuffing {
    /// "; they miss the surface: …" when the mesher's checks failed, for notes.
    pub fn misses(&self) -> String {
        if self.issues.is_empty() {
            String::new()
        } else {
            format!("; they miss the surface: {}", self.issues.join("; "))
        }
    }
}

impl Organ {
    /// The organ of `mesh`. A surface without tetrahedra is stuffed with about `tet_target`
    /// tetrahedra (`mesh::stuffing`) so the kinds that need a volume, and the reference, have
    /// one; the kinds that build on a surface still get the surface.
    pub fn new(
        mesh: MeshData,
        name: String,
        material: Material,
        read_seconds: Real,
        tet_target: usize,
    ) -> Result<Self, Error> {
        let stuffed = if mesh.has_volume() {
            None
        } else {
            let t = Instant::now();
            let surface = mesh.surface_mesh()?;
            let domain = SurfaceDomain::new(&surface).map_err(|e| {
                Error::from(MeshError::Invalid(format!(
                    "{name}: only a closed surface can be tetrahedralised for the kinds that \
                     need a volume: {e}"
                )))
            })?;
            // Coarse stuffing loses thin parts (the volume and boundary checks of the mesher):
            // finer lattices until it passes, at most twice the target's tetrahedra (the
            // reference refines them, and its cost grows eightfold with each split); the
            // finest one is kept, and what it misses is said in the record.
            let mut size = size_for(surface.signed_volume(), tet_target);
            let (mesh_t, issues) = loop {
                let stuffed = stuff(&domain, size, &Progress::silent()).map_err(|e| {
                    Error::from(MeshError::Invalid(format!(
                        "{name}: tetrahedralising the surface: {e}"
                    )))
                })?;
                let v = stuffed.report.violations();
                // The next lattice (0.8 h) holds about 1/0.8³ ≈ 2 times as many tetrahedra.
                if v.is_empty() || stuffed.mesh.tets.len() > tet_target {
                    break (stuffed.to_mesh_data(), v);
                }
                size *= 0.8;
            };
            Some(Stuffing {
                mesh: mesh_t,
                seconds: t.elapsed().as_secs_f64(),
                size,
                issues,
            })
        };
        Ok(Self {
            mesh,
            name,
            material,
            read_seconds,
            stuffed,
        })
    }

    /// The organ's tetrahedra: the loaded ones, or those stuffed from its surface.
    pub fn tets(&self) -> &MeshData {
        self.stuffed.as_ref().map_or(&self.mesh, |s| &s.mesh)
    }

    /// The organ with every tetrahedron split into eight (the mesh-size ladder): a volume
    /// organ, whatever the input was.
    pub fn refined(&self) -> Result<Organ, Error> {
        let tets = split_tets(&self.tets().tet_mesh(&self.name)?)?;
        Ok(Organ {
            mesh: MeshData::from_tets(&tets),
            name: self.name.clone(),
            material: self.material,
            read_seconds: self.read_seconds,
            stuffed: None,
        })
    }

    /// Builds `kind` on this organ with the model's default settings and `material`: on the
    /// loaded mesh, or on the stuffed tetrahedra when the kind refuses a surface alone.
    pub fn build(&self, kind: &str, material: Material) -> Result<Box<dyn Deformable>, Error> {
        self.build_with(kind, material, &toml::Table::new())
    }

    /// `build` with model parameters.
    pub fn build_with(
        &self,
        kind: &str,
        material: Material,
        params: &toml::Table,
    ) -> Result<Box<dyn Deformable>, Error> {
        match build_on(kind, &self.mesh, &self.name, material, params) {
            Err(Error::Mesh(MeshError::NeedsVolume { .. })) if self.stuffed.is_some() => {
                build_on(kind, self.tets(), &self.name, material, params)
            }
            r => r,
        }
    }
}

/// Builds `kind` on `mesh`; a panic inside the model becomes an error naming it.
pub fn build_on(
    kind: &str,
    mesh: &MeshData,
    source: &str,
    material: Material,
    params: &toml::Table,
) -> Result<Box<dyn Deformable>, Error> {
    let input = BuildInput {
        mesh,
        source,
        material,
        params,
        regions: &[],
    };
    guarded(|| build(kind, &input)).and_then(|r| r)
}

/// Runs `f`, turning a panic into an error (a model's bug must not stop the comparison).
pub fn guarded<T>(f: impl FnOnce() -> T) -> Result<T, Error> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).map_err(|p| {
        let msg = p
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_else(|| "unknown panic".into());
        Error::from(SimError::BadParameter {
            name: "model",
            value: "panicked".into(),
            reason: msg,
        })
    })
}
