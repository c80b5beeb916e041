//! Linear algebra for the models: sparse matrices with a fixed pattern and a sparse Cholesky
//! factorisation whose symbolic analysis is done once and reused.

pub mod sparse;

pub use sparse::{BlockPattern, SparseCholesky};
