//! (being written)
use crate::error::IoError;
use crate::mesh::MeshData;
use std::path::Path;
pub fn parse(_b: &[u8], _p: &Path) -> Result<MeshData, IoError> {
    todo!()
}
pub fn encode(_m: &MeshData, _b: bool) -> Result<Vec<u8>, String> {
    todo!()
}
