//! The model kinds built in, by name: the names are a contract kept across the project.

use crate::error::{Error, SimError};
use crate::material::Material;
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
}

/// Builds a model by kind name.
pub fn build(kind: &str, input: &BuildInput<'_>) -> Result<Box<dyn Deformable>, Error> {
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
