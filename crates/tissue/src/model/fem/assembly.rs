//! Assembly of the global stiffness: the sparsity pattern is built once from the element
//! connectivity, together with a table that sends each element-matrix entry to its slot in
//! the global values, so that filling (or refilling, for the non-linear variants) is a plain
//! scatter-add with no search.

use crate::error::SimError;
use crate::math::Real;
use crate::solve::BlockPattern;

/// The pattern of a mesh's stiffness and the element-to-global slot table.
#[derive(Clone, Debug)]
pub struct Assembler {
    pub pattern: BlockPattern,
    /// Nodes per element (4 or 10).
    pub nodes_per_element: usize,
    /// Flat element connectivity, `nodes_per_element` node ids per element.
    pub elements: Vec<u32>,
    /// For element e and local nodes (a, b): the position of node a among node b's
    /// neighbours, at `e·m² + a·m + b`. The 3×3 block (a, b) lives in the columns of node b.
    positions: Vec<u32>,
}

impl Assembler {
    /// Builds the pattern over `nodes` nodes; element node ids must be `< nodes`.
    pub fn new(
        nodes: usize,
        elements: Vec<u32>,
        nodes_per_element: usize,
    ) -> Result<Self, SimError> {
        let m = nodes_per_element;
        if m == 0
            || !elements.len().is_multiple_of(m)
            || elements.iter().any(|&n| n as usize >= nodes)
        {
            return Err(SimError::BadParameter {
                name: "elements",
                value: format!("{} node ids", elements.len()),
                reason: format!("not a list of {m}-node elements over {nodes} nodes"),
            });
        }
        let pattern = BlockPattern::from_elements(nodes, 3, &elements, m);
        let mut positions = Vec::with_capacity(elements.len() * m);
        for e in elements.chunks_exact(m) {
            for &a in e {
                for &b in e {
                    let pos = pattern
                        .neighbour_position(b as usize, a as usize)
                        .unwrap_or(usize::MAX);
                    positions.push(pos as u32);
                }
            }
        }
        Ok(Self {
            pattern,
            nodes_per_element: m,
            elements,
            positions,
        })
    }

    pub fn element_count(&self) -> usize {
        self.elements.len() / self.nodes_per_element
    }

    /// Nodes of element `e`.
    pub fn element(&self, e: usize) -> &[u32] {
        let m = self.nodes_per_element;
        &self.elements[e * m..(e + 1) * m]
    }

    /// Adds the element matrix `ke` (row-major, 3m × 3m, dofs node after node) of element `e`
    /// into `values`.
    pub fn scatter(&self, e: usize, ke: &[Real], values: &mut [Real]) {
        let m = self.nodes_per_element;
        let n3 = 3 * m;
        let nodes = self.element(e);
        let pos = &self.positions[e * m * m..(e + 1) * m * m];
        let cp = &self.pattern.col_ptr;
        for (b, &nb) in nodes.iter().enumerate() {
            for j in 0..3 {
                let col_start = cp[3 * nb as usize + j];
                for a in 0..m {
                    let base = col_start + 3 * pos[a * m + b] as usize;
                    let row = 3 * a;
                    for i in 0..3 {
                        values[base + i] += ke[(row + i) * n3 + 3 * b + j];
                    }
                }
            }
        }
    }

    /// The global matrix: Σ_e scatter(e, element(e)). `element` writes element e's matrix
    /// into the buffer it is given and returns false for an element it cannot compute.
    pub fn assemble(
        &self,
        mut element: impl FnMut(usize, &mut [Real]) -> bool,
    ) -> Result<Vec<Real>, SimError> {
        let n3 = 3 * self.nodes_per_element;
        let mut values = vec![0.0; self.pattern.nnz()];
        let mut ke = vec![0.0; n3 * n3];
        for e in 0..self.element_count() {
            ke.iter_mut().for_each(|v| *v = 0.0);
            if !element(e, &mut ke) {
                return Err(SimError::Mesh(crate::error::MeshError::DegenerateTet {
                    tet: e,
                    volume: 0.0,
                    quality: 0.0,
                }));
            }
            self.scatter(e, &ke, &mut values);
        }
        Ok(values)
    }
}
