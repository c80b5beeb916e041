//! The model kinds built in, by name: the names are a contract kept across the project.

use crate::error::MaterialError;
use crate::error::{Error, SimError};
use crate::material::{ElementMaterials, Material, RegionMaterial};
use crate::mesh::MeshData;
use crate::model::Deformable;
use crate::model::bem;
use crate::model::fem;
use crate::model::hybrid;
use crate::model::spline;
use crate::model::spring_mass::{Kind as SpringKind, SpringModel};
use crate::model::tensor_mass;
use crate::model::{chainmail, linked_volumes};

/// A model kind and what it is, for `tissue models`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KindInfo {
    pub name: &'static str,
    pub summary: &'static str,
}

/// Every model kind that `build` accepts.
pub const KINDS: &[KindInfo] = &[
    KindInfo {
        name: "fem-static",
        summary: "linear elastostatics on 4- or 10-node tetrahedra, sparse Cholesky (the reference)",
    },
    KindInfo {
        name: "fem-condensed",
        summary: "linear FEM condensed to the surface and pre-inverted (Bro-Nielsen fast FEM)",
    },
    KindInfo {
        name: "fem-precomputed-tensors",
        summary: "linear FEM as pre-computed displacement/force tensors, superposed (Cotin)",
    },
    KindInfo {
        name: "fem-explicit",
        summary: "linear elastodynamics, central differences, lumped mass (dt below 2/omega_max)",
    },
    KindInfo {
        name: "fem-semi-implicit",
        summary: "linear elastodynamics, stiffness at t+dt, K + cM factorised once per dt",
    },
    KindInfo {
        name: "fem-corotational",
        summary: "corotated linear tetrahedra (polar), implicit Euler, CG preconditioned by the rotated rest factor",
    },
    KindInfo {
        name: "spring-mass",
        summary: "damped springs on the surface triangles' edges, constants from E (van Gelder), cuts",
    },
    KindInfo {
        name: "simplex-spring-mass",
        summary: "springs on the T2 simplex mesh (dual of the surface, 3 links per node)",
    },
    KindInfo {
        name: "volumetric-spring-mass",
        summary: "springs on tetrahedron edges, or a surface with internal parent nodes",
    },
    KindInfo {
        name: "bem",
        summary: "linear elastostatics by boundary elements on the surface, pre-inverted, Woodbury contacts",
    },
    KindInfo {
        name: "spline",
        summary: "deformable cubic B-spline shell (Terzopoulos): sheets and tubes fitted to a mesh",
    },
    KindInfo {
        name: "chainmail",
        summary: "3D ChainMail on voxels: link limits, wavefront propagation, relaxation, cut/carve/join",
    },
    KindInfo {
        name: "linked-volumes",
        summary: "voxel masses linked by springs and dampers (6/18/26 neighbours), stiffness from E, cut/carve/join",
    },
    KindInfo {
        name: "tensor-mass",
        summary: "Cotin's tensor-mass: linear stiffness tensors on vertices and edges, explicit, cuts",
    },
    KindInfo {
        name: "tensor-mass-nonlinear",
        summary: "Picinbono's St Venant-Kirchhoff tensor-mass, volume penalty, fibres, hybrid, cuts",
    },
    KindInfo {
        name: "hybrid",
        summary: "tensor-mass in a cut region (given, or grown around the scalpel), pre-computed linear FEM elsewhere",
    },
];

/// What a model is built from.
#[derive(Clone, Copy, Debug)]
pub struct BuildInput<'a> {
    pub mesh: &'a MeshData,
    /// Names the mesh's origin (a file path) in error messages.
    pub source: &'a str,
    pub material: Material,
    /// The model's own settings (the scene's `[model]` table without `kind`).
    pub params: &'a toml::Table,
    /// Materials of tagged regions (scene `[material.regions.*]`), overriding `material`
    /// on the tetrahedra of their tag; empty for one material. Only `REGION_KINDS` take it.
    pub regions: &'a [RegionMaterial],
}

impl BuildInput<'_> {
    /// The material of each of `elements` tetrahedra (the mesh's tetrahedra in order, the
    /// tags from `mesh.tet_tags`): `Uniform(material)` without regions.
    pub fn element_materials(&self, elements: usize) -> Result<ElementMaterials, MaterialError> {
        ElementMaterials::new(self.material, self.regions, &self.mesh.tet_tags, elements)
    }
}

/// The kinds that give each tagged region its own material (`BuildInput::regions`); every
/// other kind refuses a body with per-region materials rather than use one material.
pub const REGION_KINDS: &[&str] = &[
    "fem-static",
    "fem-condensed",
    "fem-precomputed-tensors",
    "fem-explicit",
    "fem-semi-implicit",
    "fem-corotational",
];

/// Why `kind` cannot take per-region materials, naming the kinds that can.
pub fn regions_refusal(kind: &str) -> Option<String> {
    (!REGION_KINDS.contains(&kind)).then(|| {
        format!(
            "`{kind}` takes one material for the whole body; per-region materials \
             ([material.regions]) are honoured by {} (or remove the regions to use the \
             default material everywhere)",
            REGION_KINDS.join(", ")
        )
    })
}

/// What a kind needs of the body it is built on: the refusal its build would give, judged
/// in one pass over the mesh before any work, so that a viewer lists only the kinds a body
/// can be built as. A build may still refuse for other reasons, and says why.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BodyNeed {
    /// Tetrahedra: the FEM kinds, both tensor-mass kinds, volumetric springs, hybrid.
    Volume,
    /// A closed surface (a volume's boundary is one): bem, the simplex mesh, the voxel
    /// kinds, whose inside is undefined for an open one.
    ClosedSurface,
    /// An open patch or a tube: spline.
    OpenSurface,
    /// Any surface, or a volume's boundary: spring-mass.
    AnySurface,
}

impl BodyNeed {
    /// The need of a kind; `None` for an unknown name.
    pub fn of(kind: &str) -> Option<Self> {
        Some(match kind {
            "fem-static"
            | "fem-condensed"
            | "fem-precomputed-tensors"
            | "fem-explicit"
            | "fem-semi-implicit"
            | "fem-corotational"
            | "volumetric-spring-mass"
            | "tensor-mass"
            | "tensor-mass-nonlinear"
            | "hybrid" => Self::Volume,
            "bem" | "simplex-spring-mass" | "chainmail" | "linked-volumes" => Self::ClosedSurface,
            "spline" => Self::OpenSurface,
            "spring-mass" => Self::AnySurface,
            _ => return None,
        })
    }
}

/// The facts of a body that `BodyNeed` is judged on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BodyShape {
    pub volume: bool,
    /// No border edge on the surface (always so for a volume's boundary).
    pub closed: bool,
}

impl BodyShape {
    pub fn of(mesh: &MeshData) -> Self {
        let volume = mesh.has_volume();
        let closed = volume
            || (!mesh.triangles.is_empty()
                && crate::mesh::topology::edge_faces(&mesh.triangles)
                    .border_edges()
                    .next()
                    .is_none());
        Self { volume, closed }
    }

    pub fn allows(&self, need: BodyNeed) -> bool {
        match need {
            BodyNeed::Volume => self.volume,
            BodyNeed::ClosedSurface => self.closed,
            BodyNeed::OpenSurface => !self.closed,
            BodyNeed::AnySurface => true,
        }
    }
}

/// Builds a model by kind name.
pub fn build(kind: &str, input: &BuildInput<'_>) -> Result<Box<dyn Deformable>, Error> {
    if !input.regions.is_empty()
        && let Some(reason) = regions_refusal(kind)
        && let Some(info) = KINDS.iter().find(|k| k.name == kind)
    {
        return Err(SimError::Unsupported {
            model: info.name,
            operation: "per-region materials",
            reason,
        }
        .into());
    }
    match kind {
        "fem-static" => Ok(Box::new(fem::FemStatic::from_input(input)?)),
        "fem-condensed" => Ok(Box::new(fem::FemCondensed::from_input(input)?)),
        "fem-precomputed-tensors" => Ok(Box::new(fem::FemPrecomputedTensors::from_input(input)?)),
        "fem-explicit" => Ok(Box::new(fem::FemExplicit::from_input(input)?)),
        "fem-semi-implicit" => Ok(Box::new(fem::FemSemiImplicit::from_input(input)?)),
        "fem-corotational" => Ok(Box::new(fem::FemCorotational::from_input(input)?)),
        "spring-mass" => Ok(Box::new(SpringModel::from_input(
            SpringKind::Surface,
            input,
        )?)),
        "simplex-spring-mass" => Ok(Box::new(SpringModel::from_input(
            SpringKind::Simplex,
            input,
        )?)),
        "volumetric-spring-mass" => Ok(Box::new(SpringModel::from_input(
            SpringKind::Volumetric,
            input,
        )?)),
        "bem" => Ok(Box::new(bem::Bem::from_input(input)?)),
        "spline" => Ok(Box::new(spline::SplineModel::from_input(input)?)),
        "chainmail" => Ok(Box::new(chainmail::ChainMail::from_input(input)?)),
        "linked-volumes" => Ok(Box::new(linked_volumes::LinkedVolumes::from_input(input)?)),
        "tensor-mass" => Ok(Box::new(tensor_mass::TensorMass::from_input(input, false)?)),
        "tensor-mass-nonlinear" => Ok(Box::new(tensor_mass::TensorMass::from_input(input, true)?)),
        "hybrid" => Ok(Box::new(hybrid::Hybrid::from_input(input)?)),
        _ => Err(SimError::UnknownModel {
            kind: kind.to_string(),
            known: KINDS.iter().map(|k| k.name).collect::<Vec<_>>().join(", "),
        }
        .into()),
    }
}

/// Deserialises a model's settings table, naming the bad or unknown key on failure.
pub fn parse_params<T: serde::de::DeserializeOwned>(
    kind: &'static str,
    params: &toml::Table,
) -> Result<T, SimError> {
    T::deserialize(toml::Value::Table(params.clone())).map_err(|e| SimError::BadParameter {
        name: "model",
        value: kind.to_string(),
        reason: e.to_string().trim().to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;
    use crate::mesh::generate::{icosphere, tube};

    /// The need a kind declares is exactly what its build accepts: on a closed surface, an
    /// open tube and a tetrahedral block, every kind builds where `BodyShape::allows` says
    /// so and is refused where it does not (a viewer lists only the first).
    #[test]
    fn every_kind_builds_exactly_on_the_bodies_its_need_allows() {
        let material = Material::new(3000.0, 0.3).unwrap();
        let params = toml::Table::new();
        let bodies = [
            (
                "closed sphere",
                MeshData::from_surface(&icosphere(Vec3::ZERO, 0.05, 2)),
            ),
            (
                "open tube",
                MeshData::from_surface(&tube(0.01, 0.08, 16, 12)),
            ),
            ("tetrahedral liver", {
                let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/meshes/liver.msh");
                let m = crate::io::read(path)
                    .unwrap()
                    .tet_mesh("liver.msh")
                    .unwrap();
                let scaled = m.vertices.iter().map(|v| *v * 0.01).collect();
                MeshData::from_tets(&crate::mesh::TetMesh::new(scaled, m.tets))
            }),
        ];
        for (name, mesh) in &bodies {
            let shape = BodyShape::of(mesh);
            for kind in KINDS {
                let need = BodyNeed::of(kind.name).unwrap();
                let input = BuildInput {
                    mesh,
                    source: name,
                    material,
                    params: &params,
                    regions: &[],
                };
                let built = build(kind.name, &input);
                assert_eq!(
                    built.is_ok(),
                    shape.allows(need),
                    "{} on the {name} ({shape:?}, needs {need:?}): {:?}",
                    kind.name,
                    built.err().map(|e| e.to_string())
                );
            }
        }
    }
}
