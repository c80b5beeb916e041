//! The split of one tetrahedral mesh into the cut region (tensor-mass) and the rest
//! (pre-computed linear FEM): each part's sub-mesh with its node numbering, the interface
//! nodes they share, and which region tetrahedra a cut may remove.

use crate::error::SimError;
use crate::math::{Real, Vec3};
use crate::mesh::TetMesh;

pub(super) const NONE: u32 = u32::MAX;

/// A part's own mesh (nodes renumbered compactly, in ascending global order, as
/// `TetMesh::compacted` does) and the maps between the numberings.
#[derive(Clone, Debug)]
pub(super) struct Part {
    pub mesh: TetMesh,
    /// Global tetrahedron of each local one.
    pub tets: Vec<u32>,
    /// Global node → local node, or `NONE`.
    pub local: Vec<u32>,
    /// Local node → global node.
    pub global: Vec<u32>,
}

impl Part {
    fn new(mesh: &TetMesh, tets: Vec<u32>) -> Self {
        let mut local = vec![NONE; mesh.vertices.len()];
        for &t in &tets {
            for &v in &mesh.tets[t as usize] {
                local[v as usize] = 0;
            }
        }
        let mut global = Vec::new();
        for (v, slot) in local.iter_mut().enumerate() {
            if *slot == 0 {
                *slot = global.len() as u32;
                global.push(v as u32);
            }
        }
        let vertices = global.iter().map(|&g| mesh.vertices[g as usize]).collect();
        let sub = tets
            .iter()
            .map(|&t| mesh.tets[t as usize].map(|v| local[v as usize]))
            .collect();
        Self {
            mesh: TetMesh::new(vertices, sub),
            tets,
            local,
            global,
        }
    }
}

/// The two parts of the organ and their interface.
#[derive(Clone, Debug)]
pub(super) struct Split {
    /// Per global tetrahedron: in the cut region.
    pub in_region: Vec<bool>,
    pub region: Part,
    pub rest: Part,
    /// Global nodes of both parts, ascending.
    pub interface: Vec<u32>,
    /// Per global node: an interface node, or a node of a region tetrahedron that has one.
    /// A cut may only remove region tetrahedra with none of these nodes, so the interface
    /// stays covered by the region's tetrahedra on both sides of every cut.
    pub border: Vec<bool>,
    /// Fraction of the organ's volume in the region.
    pub volume_fraction: Real,
}

impl Split {
    /// Splits `mesh` (validated, compact) by the region's tetrahedra; `describe` names the
    /// region in errors.
    pub fn new(mesh: &TetMesh, in_region: Vec<bool>, describe: &str) -> Result<Self, SimError> {
        let region_tets: Vec<u32> = (0..mesh.tets.len() as u32)
            .filter(|&t| in_region[t as usize])
            .collect();
        let rest_tets: Vec<u32> = (0..mesh.tets.len() as u32)
            .filter(|&t| !in_region[t as usize])
            .collect();
        let refuse = |reason: String| SimError::BadParameter {
            name: "cut_region",
            value: describe.to_string(),
            reason,
        };
        if region_tets.is_empty() {
            return Err(refuse(
                "it selects no tetrahedron (a tetrahedron belongs to the region when its \
                 centroid is inside)"
                    .into(),
            ));
        }
        // An empty rest is legal: the region covers the organ (scalpel sweeps across the
        // whole of it grew the automatic region there, or the scene's region holds it all),
        // and the model is whole-organ tensor-mass (`Split::whole`).
        let region = Part::new(mesh, region_tets);
        let rest = Part::new(mesh, rest_tets);
        let interface: Vec<u32> = (0..mesh.vertices.len() as u32)
            .filter(|&v| region.local[v as usize] != NONE && rest.local[v as usize] != NONE)
            .collect();
        if interface.is_empty() && !rest.tets.is_empty() {
            return Err(refuse(
                "the region shares no node with the rest of the organ: the two parts would \
                 not be coupled"
                    .into(),
            ));
        }
        let mut border = vec![false; mesh.vertices.len()];
        for &v in &interface {
            border[v as usize] = true;
        }
        let touching: Vec<u32> = region
            .tets
            .iter()
            .copied()
            .filter(|&t| mesh.tets[t as usize].iter().any(|&v| border[v as usize]))
            .collect();
        for t in touching {
            for &v in &mesh.tets[t as usize] {
                border[v as usize] = true;
            }
        }
        let volume =
            |tets: &[u32]| -> Real { tets.iter().map(|&t| mesh.tet_volume(t as usize)).sum() };
        let volume_fraction = volume(&region.tets) / (volume(&region.tets) + volume(&rest.tets));
        Ok(Self {
            in_region,
            region,
            rest,
            interface,
            border,
            volume_fraction,
        })
    }

    /// Does the region cover every tetrahedron (nothing left to pre-compute)?
    pub fn whole(&self) -> bool {
        self.rest.tets.is_empty()
    }

    /// Can a cut remove global tetrahedron `t` (in the region, away from its border)?
    pub fn cuttable(&self, tets: &[[u32; 4]], t: usize) -> bool {
        self.in_region[t] && tets[t].iter().all(|&v| !self.border[v as usize])
    }
}

/// Centroid of every tetrahedron at rest.
pub(super) fn centroids(mesh: &TetMesh) -> Vec<Vec3> {
    (0..mesh.tets.len())
        .map(|t| mesh.corners(t).iter().copied().sum::<Vec3>() * 0.25)
        .collect()
}
