//! `tissue demo` (being written).
use crate::DemoArgs;
pub fn demo(_args: &DemoArgs) -> anyhow::Result<()> {
    anyhow::bail!("not built yet")
}
