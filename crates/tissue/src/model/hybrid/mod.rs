//! `hybrid`: the survey's hybrid model (§4) — tensor-mass where the scalpel goes,
//! pre-computed linear FEM everywhere else — with a cut region chosen in the scene or
//! grown automatically around the blade.
//!
//! One tetrahedral mesh is split by its tetrahedra into the cut region and the rest. The
//! region is a `TensorMass` (linear or St Venant–Kirchhoff, `nonlinear`) on its own
//! tetrahedra, integrated in time; it cuts through the tensor-mass cut code. The rest is
//! linear FEM on the other tetrahedra, condensed onto the interface nodes (those of both
//! parts) and its outer surface (`rest`). Coupled as the survey says: every force evaluation
//! of the region's integrator takes the interface displacements from the region and adds
//! the forces the rest returns for them; contacts and supports may fall on either part.
//!
//! - `split`: the two sub-meshes, the interface, which tetrahedra a cut may remove
//! - `rest`: the rest's pre-computed responses and its `NodeCoupling` to the region
//! - `grow`: building the parts for a region, on a thread when the region grows
//! - `model`: `Hybrid`, the drawn surface over both parts, constraints, cuts, growth
//! - `deformable`: the interface
//!
//! This is the one module that imports two model families (`tensor_mass`, `fem`).

mod deformable;
mod grow;
mod model;
mod rest;
mod split;
mod sym_panels;

use serde::Deserialize;

use crate::error::{Error, SimError};
use crate::integrate::Scheme;
use crate::interact::Region;
use crate::math::{Real, Vec3};
use crate::model::BuildInput;
use crate::model::registry::parse_params;
use crate::model::tensor_mass::{Fragments, TensorMassParams};

use model::Recipe;
pub use model::{GrowthRecord, Hybrid};

/// How the cut region is chosen.
#[derive(Clone, Debug, PartialEq)]
pub enum CutRegion {
    /// The tetrahedra whose centroid the region selects (`Indices`: tetrahedron indices).
    Given(Region),
    /// Around the scalpels: the tetrahedra within `auto_radius` of `auto_seeds` at first,
    /// then of the blade as it moves.
    Auto,
}

impl CutRegion {
    /// For error messages.
    pub fn describe(&self) -> String {
        match self {
            CutRegion::Given(r) => format!("{r:?}"),
            CutRegion::Auto => "\"auto\"".into(),
        }
    }
}

#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
enum CutRegionSpec {
    Word(String),
    Region(Region),
}

/// The `[model]` keys of `hybrid` (the region's tensor-mass keys pass through).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct HybridKeys {
    /// Default `"auto"`.
    cut_region: CutRegionSpec,
    /// St Venant–Kirchhoff in the region (default) or linear tensor-mass.
    #[serde(default = "yes")]
    nonlinear: bool,
    /// Automatic mode: tetrahedra within this distance of the blade join the region, in m
    /// (default: a tenth of the organ's bounding-box diagonal, at least three mean edge
    /// lengths). The region grows when a tetrahedron within half of it from the blade is
    /// outside the region or on its border; it then takes in everything within this
    /// distance plus the border's depth (2.5 mean edge lengths).
    auto_radius: Option<Real>,
    /// Automatic mode: the starting region's centres (the scene fills them in from the
    /// scalpels' first blade positions; without any, the organ's topmost point).
    #[serde(default)]
    auto_seeds: Vec<[Real; 3]>,
    /// Hold a fine contact surface's points exactly (default false: the coarse vertices'
    /// planes). A point whose vertices lie on both sides of the interface cannot be held
    /// and stops the step with an error, so this is for instruments that stay on one part.
    #[serde(default)]
    exact_fine_points: bool,
}

fn yes() -> bool {
    true
}

const OWN_KEYS: [&str; 5] = [
    "cut_region",
    "nonlinear",
    "auto_radius",
    "auto_seeds",
    "exact_fine_points",
];

impl Hybrid {
    /// Builds the model from the registry's input.
    pub fn from_input(input: &BuildInput<'_>) -> Result<Self, Error> {
        let mut own = toml::Table::new();
        let mut table = input.params.clone();
        for k in OWN_KEYS {
            if let Some(v) = table.remove(k) {
                own.insert(k.into(), v);
            }
        }
        // No region given (a live switch of kind, `tissue compare`, a bare library call):
        // the automatic one, which grows around wherever a blade goes.
        own.entry("cut_region")
            .or_insert_with(|| toml::Value::String("auto".into()));
        let keys: HybridKeys = parse_params("hybrid", &own)?;
        let scheme = match table.remove("integrator") {
            None => Scheme::default(),
            Some(v) => Scheme::deserialize(v.clone()).map_err(|e| SimError::BadParameter {
                name: "integrator",
                value: v.to_string(),
                reason: e.to_string().trim().to_string(),
            })?,
        };
        let mut tm_params: TensorMassParams = parse_params("hybrid", &table)?;
        if table.contains_key("fragments") && tm_params.fragments == Fragments::Remove {
            return Err(SimError::BadParameter {
                name: "fragments",
                value: "remove".into(),
                reason: "in hybrid a piece of the region that a cut separates is usually still \
                         held by the rest across the interface: pieces are kept"
                    .into(),
            }
            .into());
        }
        tm_params.fragments = Fragments::Keep;
        let mesh = input.mesh.tet_mesh(input.source)?;
        mesh.validate_for_simulation()?;
        let mesh = mesh.compacted();
        let (lo, hi) = mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
        let h = mean_edge(&mesh);
        let auto_radius = keys
            .auto_radius
            .unwrap_or((0.1 * (hi - lo).length()).max(3.0 * h));
        if !(auto_radius.is_finite() && auto_radius > 0.0) {
            return Err(SimError::BadParameter {
                name: "auto_radius",
                value: auto_radius.to_string(),
                reason: "must be a finite distance > 0, in m".into(),
            }
            .into());
        }
        let cents = split::centroids(&mesh);
        let mut default_seed = None;
        let (mode, in_region) = match keys.cut_region {
            CutRegionSpec::Word(w) if w == "auto" => {
                let seeds: Vec<Vec3> = if keys.auto_seeds.is_empty() {
                    // No scalpel to start from: the organ's topmost point (scenes are y-up),
                    // where an instrument usually comes in from.
                    let top = mesh
                        .vertices
                        .iter()
                        .copied()
                        .max_by(|a, b| a.y.total_cmp(&b.y))
                        .unwrap_or(Vec3::ZERO);
                    default_seed = Some(top);
                    vec![top]
                } else {
                    keys.auto_seeds.iter().map(|&s| Vec3::from(s)).collect()
                };
                let mask = cents
                    .iter()
                    .map(|c| seeds.iter().any(|s| s.distance(*c) <= auto_radius))
                    .collect();
                (CutRegion::Auto, mask)
            }
            CutRegionSpec::Word(w) => {
                return Err(SimError::BadParameter {
                    name: "cut_region",
                    value: w,
                    reason: "the only word accepted is \"auto\"; otherwise a region table".into(),
                }
                .into());
            }
            CutRegionSpec::Region(r) => {
                let mut mask = vec![false; mesh.tets.len()];
                let picked = match &r {
                    Region::Indices(ids) => ids.clone(),
                    _ => r.select(&cents),
                };
                for t in picked {
                    if let Some(m) = mask.get_mut(t as usize) {
                        *m = true;
                    }
                }
                (CutRegion::Given(r), mask)
            }
        };
        let recipe = Recipe {
            material: input.material.validated()?,
            tm_params,
            nonlinear: keys.nonlinear,
            scheme,
        };
        let mut model = Self::build(mesh, in_region, mode, auto_radius, recipe)?;
        model.default_seed = default_seed;
        model.exact_points = keys.exact_fine_points;
        Ok(model)
    }
}

/// Mean edge length of the tetrahedra (each edge counted once per tetrahedron).
fn mean_edge(mesh: &crate::mesh::TetMesh) -> Real {
    let mut sum = 0.0;
    for t in 0..mesh.tets.len() {
        let c = mesh.corners(t);
        for (a, b) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
            sum += c[a].distance(c[b]);
        }
    }
    sum / (6 * mesh.tets.len()).max(1) as Real
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_contact;
#[cfg(test)]
mod tests_speed;
