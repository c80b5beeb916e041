//! `tissue mesh` (being written).
use crate::MeshCommand;
pub fn mesh(_cmd: &MeshCommand) -> anyhow::Result<()> {
    anyhow::bail!("not built yet")
}
