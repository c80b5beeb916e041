//! Linear algebra for the models: sparse matrices with a fixed pattern and a sparse Cholesky
//! factorisation whose symbolic analysis (AMD or nested dissection, whichever fills less) is
//! done once and reused, with extra held unknowns imposed through a Schur complement instead of
//! a new factorisation (`schur`), and triangular solves split along the elimination tree
//! (`tree_solve`, serial or parallel as `chooser` measures); a matrix-free Jacobi-
//! preconditioned conjugate gradient for the implicit dynamic models; small dense contact
//! blocks solved in place (`small_dense`), and contacts held along their normals on a dense
//! response (`along`), and the mixed complementarity problem of points that may be pushed
//! but not pulled (`lcp`), whose rows the pre-computed kinds form on their dense vertex
//! response (`points`).

mod along;
pub mod cg;
pub mod chooser;
pub mod lcp;
mod lemke;
pub mod ordering;
pub(crate) mod points;
pub mod schur;
mod small_dense;
pub mod sparse;
mod tree_solve;

pub(crate) use along::{ContactResponse, HeldRows, block3};
pub use cg::{CgResult, CgWorkspace};
pub(crate) use points::{PointRows, Source, VertexResponse};
pub use schur::HeldSchur;
pub(crate) use small_dense::SmallDense;
pub use sparse::{BlockPattern, Ordering, SparseCholesky};
