//! Materials per region: the tetrahedra of a tagged mesh (labels of a segmentation meshed as
//! conforming regions, a volume file's physical tags) take the material of their tag, so a
//! tumour can be stiffer than the organ around it. Written once here for every model kind
//! that honours it (`model::registry::REGION_KINDS`); the others refuse such a body.
//!
//! Only the elastic constants and the density vary: Rayleigh damping stays the default
//! material's, because the models apply it as one α M + β K over the whole body.

use crate::error::MaterialError;

use super::Material;

/// One region's material: the tetrahedra tagged `tag` take `material`. `name` is how the
/// scene named it (a segment's name or the tag's number), for messages.
#[derive(Clone, Debug, PartialEq)]
pub struct RegionMaterial {
    pub name: String,
    pub tag: i32,
    pub material: Material,
}

/// The material of every element of a model.
///
/// `Uniform` is the path of every single-material body, unchanged (the same arithmetic on
/// the same constants as before per-region materials existed); `PerElement` holds one
/// material per tetrahedron, in the mesh's element order.
#[derive(Clone, Debug, PartialEq)]
pub enum ElementMaterials {
    Uniform(Material),
    PerElement {
        /// The material of the elements no region names (damping comes from it).
        default: Material,
        materials: Vec<Material>,
    },
}

impl ElementMaterials {
    /// The materials of `elements` tetrahedra tagged `tags` (one per element): `default`
    /// where no region names the tag. Without regions, `Uniform(default)`. Refuses a
    /// region whose tag no tetrahedron carries, a mesh without a tag per element, a region
    /// named twice, and constants out of range (naming the region).
    pub fn new(
        default: Material,
        regions: &[RegionMaterial],
        tags: &[i32],
        elements: usize,
    ) -> Result<Self, MaterialError> {
        let default = default.validated()?;
        if regions.is_empty() {
            return Ok(Self::Uniform(default));
        }
        let first = &regions[0].name;
        if tags.len() != elements {
            return Err(MaterialError::Region {
                region: first.clone(),
                reason: format!(
                    "the mesh has {} tags for {elements} tetrahedra; per-region materials need \
                     a tag on every tetrahedron (a labelled image meshed with tet_size, or a \
                     volume file with physical tags / cell data / region attributes)",
                    tags.len()
                ),
            });
        }
        for (k, r) in regions.iter().enumerate() {
            let named = |reason: String| MaterialError::Region {
                region: r.name.clone(),
                reason,
            };
            if let Some(other) = regions[..k].iter().find(|o| o.tag == r.tag) {
                return Err(named(format!(
                    "tag {} is already given a material by region `{}`",
                    r.tag, other.name
                )));
            }
            if !tags.contains(&r.tag) {
                return Err(named(format!(
                    "no tetrahedron is tagged {}; the mesh's tags are {}",
                    r.tag,
                    tag_list(tags)
                )));
            }
            let m = r.material.validated().map_err(|e| named(e.to_string()))?;
            if m.damping != default.damping || m.stiffness_damping != default.stiffness_damping {
                return Err(named(
                    "damping and stiffness_damping apply to the whole body; set them in \
                     [material] only"
                        .into(),
                ));
            }
        }
        let materials = tags
            .iter()
            .map(|t| {
                regions
                    .iter()
                    .find(|r| r.tag == *t)
                    .map_or(default, |r| r.material)
            })
            .collect();
        Ok(Self::PerElement { default, materials })
    }

    /// The material of element `e` (the default past the end: never reached by a model,
    /// whose element count is the one this was built for).
    #[inline]
    pub fn of(&self, e: usize) -> &Material {
        match self {
            Self::Uniform(m) => m,
            Self::PerElement { default, materials } => materials.get(e).unwrap_or(default),
        }
    }

    /// The material of the elements no region names; for a uniform body, its material.
    pub fn default_material(&self) -> &Material {
        match self {
            Self::Uniform(m) | Self::PerElement { default: m, .. } => m,
        }
    }

    /// The one material, if every element has it by construction (no regions).
    pub fn uniform(&self) -> Option<&Material> {
        match self {
            Self::Uniform(m) => Some(m),
            Self::PerElement { .. } => None,
        }
    }

    /// The largest Young's modulus over the elements, in Pa (plausibility bounds, stable
    /// step estimates).
    pub fn max_young_modulus(&self) -> f64 {
        match self {
            Self::Uniform(m) => m.young_modulus,
            Self::PerElement { default, materials } => materials
                .iter()
                .map(|m| m.young_modulus)
                .fold(default.young_modulus, f64::max),
        }
    }
}

/// The distinct tags of a mesh, for messages.
fn tag_list(tags: &[i32]) -> String {
    let mut t = tags.to_vec();
    t.sort_unstable();
    t.dedup();
    if t.is_empty() {
        return "none".into();
    }
    t.iter().map(i32::to_string).collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn region(name: &str, tag: i32, e: f64) -> RegionMaterial {
        RegionMaterial {
            name: name.into(),
            tag,
            material: Material::new(e, 0.45).unwrap(),
        }
    }

    #[test]
    fn each_element_takes_the_material_of_its_tag() {
        let organ = Material::new(3000.0, 0.45).unwrap();
        let m = ElementMaterials::new(organ, &[region("tumor", 2, 3e4)], &[1, 2, 1, 3], 4).unwrap();
        let e: Vec<f64> = (0..4).map(|k| m.of(k).young_modulus).collect();
        assert_eq!(e, [3000.0, 3e4, 3000.0, 3000.0]);
        assert_eq!(m.max_young_modulus(), 3e4);
        assert!(m.uniform().is_none());
        let plain = ElementMaterials::new(organ, &[], &[], 4).unwrap();
        assert_eq!(plain.uniform(), Some(&organ));
    }

    #[test]
    fn regions_the_mesh_cannot_carry_are_refused_by_name() {
        let organ = Material::new(3000.0, 0.45).unwrap();
        let e = ElementMaterials::new(organ, &[region("tumor", 7, 3e4)], &[1, 2], 2)
            .unwrap_err()
            .to_string();
        assert!(e.contains("tumor") && e.contains("tags are 1, 2"), "{e}");
        let e = ElementMaterials::new(organ, &[region("tumor", 2, 3e4)], &[], 2)
            .unwrap_err()
            .to_string();
        assert!(e.contains("tumor") && e.contains("0 tags for 2"), "{e}");
        let mut bad = region("tumor", 2, 3e4);
        bad.material.poisson_ratio = 0.5;
        let e = ElementMaterials::new(organ, &[bad], &[1, 2], 2)
            .unwrap_err()
            .to_string();
        assert!(e.contains("tumor") && e.contains("poisson_ratio"), "{e}");
        let mut damped = region("tumor", 2, 3e4);
        damped.material.damping = 1.0;
        let e = ElementMaterials::new(organ, &[damped], &[1, 2], 2)
            .unwrap_err()
            .to_string();
        assert!(e.contains("damping"), "{e}");
        let twice = [region("a", 2, 3e4), region("b", 2, 3e4)];
        let e = ElementMaterials::new(organ, &twice, &[1, 2], 2)
            .unwrap_err()
            .to_string();
        assert!(e.contains("already"), "{e}");
    }
}
