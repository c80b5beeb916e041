//! `FemStatic`: the reference linear elastostatic model behind the `Deformable` interface.
//!
//! Built once: the linear mesh is compacted to the vertices its tetrahedra use, optionally
//! raised to 10-node tetrahedra, K is assembled and analysed symbolically. Each step solves
//! K u = f with the constraints eliminated (see `system`). Surface vertices are the corner
//! nodes of the boundary; on quadratic meshes the mid-edge nodes of constrained surface edges
//! follow their ends, and their reactions go half to each end so that reactions still
//! balance the loads.

use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::error::{Error, SimError};
use crate::interact::Loads;
use crate::material::{ElementMaterials, Material};
use crate::math::{Real, Vec3, is_finite_vec, triangle_area_vector};
use crate::mesh::{Boundary, TetMesh, boundary_surface};
use crate::model::registry::parse_params;
use crate::model::{BuildInput, ConstraintReactions};

use super::assembly::Assembler;
use super::quadratic_mesh::QuadraticMesh;
use super::system::{DofProblem, System};
use super::{element_linear, element_quadratic};

/// Interpolation order of the tetrahedra.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Order {
    /// 4-node tetrahedra, constant strain: cheap, too stiff in bending.
    #[default]
    Linear,
    /// 10-node tetrahedra, linear strain: accurate in bending, 30×30 element matrices.
    Quadratic,
}

/// Which mechanical nodes make the surface of a quadratic mesh (what is drawn, touched and
/// held).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SurfaceNodes {
    /// The corners only: each boundary triangle as it is; a mid-edge node follows the mean of
    /// its ends when both are held.
    #[default]
    Corners,
    /// Corners and mid-edge nodes: each boundary triangle split into four through its
    /// mid-edge nodes, so instruments touch (and hold) every surface node: twice the contact
    /// resolution of the corners for the same unknowns. Linear meshes have corners only.
    All,
}

/// The `[model]` settings of `fem-static`.
#[derive(Clone, Copy, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct FemStaticParams {
    #[serde(default)]
    order: Order,
    #[serde(default)]
    surface_nodes: SurfaceNodes,
}

/// Held displacement components and forces on mechanical nodes: the node-level interface.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NodalProblem {
    /// (node, axis 0..3, displacement in m).
    pub held: Vec<(usize, usize, Real)>,
    /// (node, force in N); forces on the same node add up.
    pub forces: Vec<(usize, Vec3)>,
}

impl NodalProblem {
    /// Holds all three components of `node` at zero.
    pub fn fix_node(&mut self, node: usize) -> &mut Self {
        self.prescribe_node(node, Vec3::ZERO)
    }
    /// Holds `node` at displacement `d`.
    pub fn prescribe_node(&mut self, node: usize, d: Vec3) -> &mut Self {
        for axis in 0..3 {
            self.held.push((node, axis, d[axis]));
        }
        self
    }
    /// Holds one component (a roller support when `value` is zero).
    pub fn hold(&mut self, node: usize, axis: usize, value: Real) -> &mut Self {
        self.held.push((node, axis, value));
        self
    }
    pub fn force(&mut self, node: usize, f: Vec3) -> &mut Self {
        self.forces.push((node, f));
        self
    }
}

/// Nodal displacements and reactions (f − K u on held components, zero on free ones).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NodalSolution {
    pub displacements: Vec<Vec3>,
    pub reactions: Vec<Vec3>,
}

/// Linear elastostatics on 4- or 10-node tetrahedra: the reference model.
pub struct FemStatic {
    /// The default material (the only one without regions).
    pub(super) material: Material,
    /// Each element's material (`Uniform(material)` without regions).
    pub(super) materials: ElementMaterials,
    pub(super) order: Order,
    /// The compacted linear mesh at rest (corner nodes 0..n).
    pub(super) mesh: TetMesh,
    pub(super) rest: Vec<Vec3>,
    pub(super) positions: Vec<Vec3>,
    pub(super) quadratic: Option<QuadraticMesh>,
    pub(super) system: System,
    pub(super) boundary: Boundary,
    pub(super) surface_positions: Vec<Vec3>,
    /// Mid-edge nodes of boundary edges: (mid node, surface vertex a, surface vertex b).
    pub(super) surface_mids: Vec<(u32, u32, u32)>,
    pub(super) problem: DofProblem,
    pub(super) loads: Loads,
    /// Which given constraint receives its vertex's reaction (the first mention; fixed wins).
    pub(super) reactions: ConstraintReactions,
    pub(super) u: Vec<Real>,
    pub(super) r: Vec<Real>,
    pub(super) u_trial: Vec<Real>,
    pub(super) r_trial: Vec<Real>,
    pub(super) surface_reaction: Vec<Vec3>,
    /// The push on each point contact at the last step (`Deformable::point_reactions`).
    pub(super) point_pushes: Vec<Real>,
    pub(super) precompute_seconds: Real,
}

impl std::fmt::Debug for FemStatic {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FemStatic")
            .field("order", &self.order)
            .field("nodes", &self.rest.len())
            .field("elements", &self.mesh.tets.len())
            .finish()
    }
}

impl FemStatic {
    /// Builds the model from the registry's input (`[model] order = "linear" | "quadratic"`).
    pub fn from_input(input: &BuildInput<'_>) -> Result<Self, Error> {
        let params: FemStaticParams = parse_params("fem-static", input.params)?;
        let mesh = input.mesh.tet_mesh(input.source)?;
        let materials = input.element_materials(mesh.tets.len())?;
        let model = Self::with_materials(&mesh, materials, params.order)?;
        Ok(match params.surface_nodes {
            SurfaceNodes::Corners => model,
            SurfaceNodes::All => model.with_mid_edge_surface(),
        })
    }

    /// Makes every mid-edge node of the boundary a surface vertex (`SurfaceNodes::All`): each
    /// boundary triangle becomes four. The corners keep their surface indices; the mid-edge
    /// nodes follow them. No effect on a linear mesh.
    pub fn with_mid_edge_surface(mut self) -> Self {
        let Some(q) = &self.quadratic else {
            return self;
        };
        let b = &self.boundary;
        let mut vertices = b.surface.vertices.clone();
        let mut nodes = b.nodes.clone();
        let mut index: std::collections::HashMap<u32, u32> = std::collections::HashMap::new();
        let mut triangles = Vec::with_capacity(4 * b.surface.triangles.len());
        let mut face_tets = Vec::with_capacity(4 * b.face_tets.len());
        for (t, tri) in b.surface.triangles.iter().enumerate() {
            let mut mid = |x: u32, y: u32| -> u32 {
                let (na, nb) = (b.nodes[x as usize], b.nodes[y as usize]);
                // Every edge of a quadratic tetrahedron has its mid node.
                let m = q.mid(na, nb).unwrap_or(na);
                *index.entry(m).or_insert_with(|| {
                    vertices.push(self.rest[m as usize]);
                    nodes.push(m);
                    (vertices.len() - 1) as u32
                })
            };
            let [a, b_, c] = *tri;
            let (ab, bc, ca) = (mid(a, b_), mid(b_, c), mid(c, a));
            triangles.extend([[a, ab, ca], [ab, b_, bc], [ca, bc, c], [ab, bc, ca]]);
            let ft = b.face_tets.get(t).copied().unwrap_or(0);
            face_tets.extend([ft; 4]);
        }
        self.boundary = Boundary {
            surface: crate::mesh::SurfaceMesh::new(vertices, triangles),
            nodes,
            face_tets,
        };
        self.surface_mids.clear();
        self.surface_positions = self.boundary.surface.vertices.clone();
        self.surface_reaction = vec![Vec3::ZERO; self.boundary.nodes.len()];
        self
    }

    /// Validates mesh and material, assembles K and analyses it.
    pub fn new(mesh: &TetMesh, material: Material, order: Order) -> Result<Self, Error> {
        Self::with_materials(mesh, ElementMaterials::Uniform(material), order)
    }

    /// Like `new`, each element with its own material (`materials.of(e)`, e in the order
    /// of `mesh.tets`).
    pub fn with_materials(
        mesh: &TetMesh,
        materials: ElementMaterials,
        order: Order,
    ) -> Result<Self, Error> {
        let material = materials.default_material().validated()?;
        mesh.validate_for_simulation()?;
        let start = Instant::now();
        let mesh = mesh.compacted();
        let quadratic = (order == Order::Quadratic).then(|| QuadraticMesh::from_linear(&mesh));
        let (rest, elements, m) = match &quadratic {
            None => (mesh.vertices.clone(), mesh.tets.concat(), 4),
            Some(q) => (q.nodes.clone(), q.tets.concat(), 10),
        };
        let assembler = Assembler::new(rest.len(), elements, m)?;
        let k = assembler.assemble(|e, ke| {
            let corners = mesh.corners(e);
            let material = materials.of(e);
            match order {
                Order::Linear => element_linear::stiffness(&corners, material)
                    .map(|k| ke.copy_from_slice(k.as_flattened()))
                    .is_some(),
                Order::Quadratic => element_quadratic::stiffness(&corners, material)
                    .map(|k| ke.copy_from_slice(k.as_flattened()))
                    .is_some(),
            }
        })?;
        let system = System::new(assembler, k, rest.clone())?;
        let boundary = boundary_surface(&mesh);
        let surface_mids = match &quadratic {
            None => Vec::new(),
            Some(q) => boundary_mids(&boundary, q),
        };
        let dofs = system.dofs();
        Ok(Self {
            material,
            materials,
            order,
            positions: rest.clone(),
            rest,
            quadratic,
            surface_positions: boundary.surface.vertices.clone(),
            surface_reaction: vec![Vec3::ZERO; boundary.nodes.len()],
            point_pushes: Vec::new(),
            boundary,
            surface_mids,
            problem: DofProblem::new(dofs),
            loads: Loads::default(),
            reactions: ConstraintReactions::default(),
            u: vec![0.0; dofs],
            r: vec![0.0; dofs],
            u_trial: vec![0.0; dofs],
            r_trial: vec![0.0; dofs],
            precompute_seconds: start.elapsed().as_secs_f64(),
            system,
            mesh,
        })
    }

    pub fn order(&self) -> Order {
        self.order
    }
    pub fn material(&self) -> &Material {
        &self.material
    }
    /// Each element's material (`Uniform` without regions).
    pub fn element_materials(&self) -> &ElementMaterials {
        &self.materials
    }
    /// The (compacted) linear mesh at rest; its vertices are nodes 0..n of every order.
    pub fn linear_mesh(&self) -> &TetMesh {
        &self.mesh
    }
    /// The quadratic mesh, for `Order::Quadratic`.
    pub fn quadratic_mesh(&self) -> Option<&QuadraticMesh> {
        self.quadratic.as_ref()
    }
    /// The assembled stiffness K (all dofs, no constraint), in N/m.
    pub fn stiffness(&self) -> Result<faer::sparse::SparseColMat<usize, Real>, SimError> {
        self.system.assembler.pattern.to_faer(&self.system.k)
    }
    /// K's pattern and values, without copying.
    pub fn stiffness_parts(&self) -> (&crate::solve::BlockPattern, &[Real]) {
        (&self.system.assembler.pattern, &self.system.k)
    }
    /// Rest positions of all mechanical nodes (corners, then mid-edge nodes).
    pub fn rest_nodes(&self) -> &[Vec3] {
        &self.rest
    }
    /// Current positions of all mechanical nodes.
    pub fn node_positions(&self) -> &[Vec3] {
        &self.positions
    }
    /// Current nodal displacements, flat (x0, y0, z0, x1, ...), in m.
    pub fn displacements(&self) -> &[Real] {
        &self.u
    }
    /// The mechanical node of each surface vertex.
    pub fn surface_nodes(&self) -> &[u32] {
        &self.boundary.nodes
    }
    /// Numeric factorisations so far (a new one only when the constrained set changes and
    /// the change cannot be imposed through the Schur complement on the last one).
    pub fn refactorizations(&self) -> usize {
        self.system.refactorizations
    }

    /// Columns of the Schur complement computed for held dofs beyond the factorised set.
    pub fn schur_columns(&self) -> usize {
        self.system.schur_columns
    }

    /// When extra held dofs go through the Schur complement (studies compare the rules).
    pub fn set_schur_rule(&mut self, rule: super::SchurRule) {
        self.system.schur_rule = rule;
    }

    /// Nodal forces (flat, per dof) of a uniform body force density `b` (N/m³), consistent
    /// with the element order.
    pub fn body_load(&self, b: Vec3) -> Vec<Real> {
        self.element_body_loads(|_| b)
    }

    /// Nodal forces (flat, per dof) of gravity `g` (m/s²) on each element's density.
    pub fn gravity_load(&self, g: Vec3) -> Vec<Real> {
        match self.materials.uniform() {
            Some(m) => self.body_load(g * m.density),
            None => self.element_body_loads(|e| g * self.materials.of(e).density),
        }
    }

    /// Nodal forces of the body force density `b(e)` (N/m³) on each element e.
    fn element_body_loads(&self, b_of: impl Fn(usize) -> Vec3) -> Vec<Real> {
        let mut f = vec![0.0; self.system.dofs()];
        let asm = &self.system.assembler;
        for e in 0..asm.element_count() {
            let b = b_of(e);
            let v = self.mesh.tet_volume(e);
            let nodes = asm.element(e);
            let add = |f: &mut [Real], n: u32, x: Vec3| {
                for k in 0..3 {
                    f[3 * n as usize + k] += x[k];
                }
            };
            match self.order {
                Order::Linear => {
                    for (n, x) in nodes.iter().zip(element_linear::body_load(v, b)) {
                        add(&mut f, *n, x);
                    }
                }
                Order::Quadratic => {
                    for (n, x) in nodes.iter().zip(element_quadratic::body_load(v, b)) {
                        add(&mut f, *n, x);
                    }
                }
            }
        }
        f
    }

    /// Consistent nodal forces (flat, per dof) of a uniform traction `t` (N/m²) on the given
    /// boundary triangles (indices into `surface().triangles`): a third of t·A per corner on
    /// linear meshes; a third per mid-edge node and nothing on corners on quadratic ones.
    pub fn traction_load(&self, triangles: &[usize], t: Vec3) -> Vec<Real> {
        let mut f = vec![0.0; self.system.dofs()];
        let s = &self.boundary.surface;
        for &tri in triangles {
            let Some(&[a, b, c]) = s.triangles.get(tri) else {
                continue;
            };
            let [pa, pb, pc] = [a, b, c].map(|v| s.vertices[v as usize]);
            let area = triangle_area_vector(pa, pb, pc).length();
            let [na, nb, nc] = [a, b, c].map(|v| self.boundary.nodes[v as usize]);
            let targets: Vec<u32> = match &self.quadratic {
                // Triangles split through their mid-edge nodes: a third per node.
                _ if self.surface_mids.is_empty() => vec![na, nb, nc],
                None => vec![na, nb, nc],
                Some(q) => [(na, nb), (nb, nc), (nc, na)]
                    .iter()
                    .filter_map(|&(x, y)| q.mid(x, y))
                    .collect(),
            };
            for n in targets {
                for k in 0..3 {
                    f[3 * n as usize + k] += t[k] * area / 3.0;
                }
            }
        }
        f
    }

    /// Solves a node-level problem without touching the model's state (the factorisation
    /// cache is shared: the same held set as the last solve costs only a solve).
    pub fn solve_nodal(&mut self, p: &NodalProblem) -> Result<NodalSolution, SimError> {
        let nodes = self.rest.len();
        let mut dp = DofProblem::new(3 * nodes);
        for &(node, axis, value) in &p.held {
            if node >= nodes || axis > 2 || !value.is_finite() {
                return Err(SimError::BadParameter {
                    name: "held",
                    value: format!("node {node} axis {axis} = {value}"),
                    reason: format!("needs node < {nodes}, axis < 3 and a finite value"),
                });
            }
            dp.hold(3 * node + axis, value)?;
        }
        dp.finish();
        for &(node, force) in &p.forces {
            if node >= nodes || !is_finite_vec(force) {
                return Err(SimError::BadParameter {
                    name: "forces",
                    value: format!("node {node} = {force}"),
                    reason: format!("needs node < {nodes} and a finite force"),
                });
            }
            for k in 0..3 {
                dp.forces[3 * node + k] += force[k];
            }
        }
        self.solve_dofs(&dp)
    }

    /// Like `solve_nodal`, with forces given per dof (e.g. from `body_load`).
    pub fn solve_dofs(&mut self, dp: &DofProblem) -> Result<NodalSolution, SimError> {
        let n = self.system.dofs();
        let (mut u, mut r) = (vec![0.0; n], vec![0.0; n]);
        self.system.solve(dp, &mut u, &mut r)?;
        let v = |x: &[Real]| {
            x.chunks_exact(3)
                .map(|c| Vec3::new(c[0], c[1], c[2]))
                .collect()
        };
        Ok(NodalSolution {
            displacements: v(&u),
            reactions: v(&r),
        })
    }
}

/// The mid-edge nodes of the boundary triangles' edges, each once.
fn boundary_mids(b: &Boundary, q: &QuadraticMesh) -> Vec<(u32, u32, u32)> {
    let mut out = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for tri in &b.surface.triangles {
        for (x, y) in [(tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])] {
            let (na, nb) = (b.nodes[x as usize], b.nodes[y as usize]);
            if let Some(m) = q.mid(na, nb)
                && seen.insert(m)
            {
                out.push((m, x, y));
            }
        }
    }
    out
}
