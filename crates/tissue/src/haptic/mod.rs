//! Haptics: the 1 kHz force loop, the local linear contact model it evaluates between full
//! simulation updates, its timing statistics, the UDP device bridge (docs/haptic-protocol.md)
//! and a scripted device emulator.
//!
//! Threads: the device (or the emulator) writes poses through the bridge into the loop's pose
//! slot; the loop thread turns the pose into a force at 1 kHz with `LocalContact`; the
//! simulation thread (`coupling`) steps the full model with the same pose as often as the
//! model allows and re-anchors the local model with each result.

pub mod bridge;
pub mod coupling;
pub mod emulator;
pub mod haptic_loop;
pub mod local_model;
pub mod protocol;
pub mod realtime;
pub mod stats;

#[cfg(test)]
mod tests;

pub use bridge::UdpBridge;
pub use coupling::{CouplingReport, run_coupled, step_coupled};
pub use emulator::{EmulatorReport, run_emulator};
pub use haptic_loop::{ForceSample, HapticConfig, HapticHandle, HapticLoop, Pose};
pub use local_model::LocalContact;
pub use protocol::{ForcePacket, PosePacket, ProtocolError};
pub use stats::{TimingStats, TimingSummary};
