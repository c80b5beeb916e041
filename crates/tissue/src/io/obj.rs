//! (being written)
use std::path::Path;
use crate::error::IoError;
use crate::mesh::MeshData;
pub fn parse(_b: &[u8], _p: &Path) -> Result<MeshData, IoError> { todo!() }
pub fn encode(_m: &MeshData) -> Result<Vec<u8>, String> { todo!() }
