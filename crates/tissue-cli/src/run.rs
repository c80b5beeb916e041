//! `tissue run` (being written).
use crate::RunArgs;
pub fn run(_args: &RunArgs) -> anyhow::Result<()> {
    anyhow::bail!("not built yet")
}
