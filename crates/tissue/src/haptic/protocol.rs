//! The UDP device-bridge protocol (docs/haptic-protocol.md): fixed-size little-endian
//! datagrams, a pose from the device and a force back. Fixed sizes and a magic make a stray
//! or truncated datagram easy to reject; every field is checked before it is used.

use thiserror::Error;

use crate::math::{Real, Vec3};

/// First four bytes of every datagram.
pub const MAGIC: [u8; 4] = *b"TSHP";
/// Protocol version carried in byte 4.
pub const VERSION: u8 = 1;
/// Byte 5: a pose from the device.
pub const TYPE_POSE: u8 = 1;
/// Byte 5: a force to the device.
pub const TYPE_FORCE: u8 = 2;
/// Header: magic, version, type, flags (u16), sequence (u32).
pub const HEADER_LEN: usize = 12;
/// Header + position (3 f64) + orientation quaternion w, x, y, z (4 f64).
pub const POSE_LEN: usize = HEADER_LEN + 7 * 8;
/// Header + force (3 f64) + the loop tick that computed it (u64).
pub const FORCE_LEN: usize = HEADER_LEN + 3 * 8 + 8;
/// Positions farther than this from the origin (m) are rejected as nonsense.
pub const MAX_POSITION: Real = 100.0;
/// Pose flag: the device button is pressed (a grasper closes while it is held).
pub const FLAG_BUTTON: u16 = 1;

/// An instrument pose sent by the device.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PosePacket {
    pub sequence: u32,
    pub flags: u16,
    /// Tool tip, in the scene's frame, m.
    pub position: Vec3,
    /// Unit quaternion (w, x, y, z) of the tool; carried for drivers, unused by probes.
    pub orientation: [Real; 4],
}

/// The force sent back, in N, on the tissue's instrument (render it on the hand as is).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForcePacket {
    /// The sequence number of the pose the force was computed for.
    pub sequence: u32,
    pub flags: u16,
    pub force: Vec3,
    pub tick: u64,
}

/// Why a datagram was rejected.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ProtocolError {
    #[error("datagram of {got} bytes, expected {expected}")]
    Length { got: usize, expected: usize },
    #[error("bad magic {0:02x?}, expected \"TSHP\"")]
    Magic([u8; 4]),
    #[error("protocol version {0}, this side speaks {VERSION}")]
    Version(u8),
    #[error("message type {got}, expected {expected}")]
    Type { got: u8, expected: u8 },
    #[error("field `{field}` is {value}: {reason}")]
    Field {
        field: &'static str,
        value: String,
        reason: &'static str,
    },
}

fn header(kind: u8, flags: u16, sequence: u32, out: &mut Vec<u8>) {
    out.extend_from_slice(&MAGIC);
    out.push(VERSION);
    out.push(kind);
    out.extend_from_slice(&flags.to_le_bytes());
    out.extend_from_slice(&sequence.to_le_bytes());
}

fn check_header(data: &[u8], kind: u8, len: usize) -> Result<(u16, u32), ProtocolError> {
    if data.len() != len {
        return Err(ProtocolError::Length {
            got: data.len(),
            expected: len,
        });
    }
    let magic: [u8; 4] = bytes(data, 0);
    if magic != MAGIC {
        return Err(ProtocolError::Magic(magic));
    }
    let (version, got) = (data.get(4).copied(), data.get(5).copied());
    if version != Some(VERSION) {
        return Err(ProtocolError::Version(version.unwrap_or(0)));
    }
    if got != Some(kind) {
        return Err(ProtocolError::Type {
            got: got.unwrap_or(0),
            expected: kind,
        });
    }
    Ok((
        u16::from_le_bytes(bytes(data, 6)),
        u32::from_le_bytes(bytes(data, 8)),
    ))
}

/// `N` bytes at `at`, zero-padded past the end (callers check the length first).
fn bytes<const N: usize>(data: &[u8], at: usize) -> [u8; N] {
    let mut out = [0u8; N];
    if let Some(s) = data.get(at..at + N) {
        out.copy_from_slice(s);
    }
    out
}

fn f64_at(data: &[u8], at: usize) -> Real {
    Real::from_le_bytes(bytes(data, at))
}

impl PosePacket {
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(POSE_LEN);
        header(TYPE_POSE, self.flags, self.sequence, &mut out);
        for x in self.position.to_array().iter().chain(&self.orientation) {
            out.extend_from_slice(&x.to_le_bytes());
        }
        out
    }

    /// Checks length, magic, version, type, finite values, the position range and a
    /// non-zero quaternion (returned normalised).
    pub fn decode(data: &[u8]) -> Result<Self, ProtocolError> {
        let (flags, sequence) = check_header(data, TYPE_POSE, POSE_LEN)?;
        let v: [Real; 7] = std::array::from_fn(|i| f64_at(data, HEADER_LEN + 8 * i));
        let position = Vec3::new(v[0], v[1], v[2]);
        if !crate::math::is_finite_vec(position) || position.length() > MAX_POSITION {
            return Err(ProtocolError::Field {
                field: "position",
                value: format!("{position:?}"),
                reason: "must be finite and within 100 m of the origin",
            });
        }
        let q = [v[3], v[4], v[5], v[6]];
        let norm = q.iter().map(|x| x * x).sum::<Real>().sqrt();
        if !(norm.is_finite() && norm > 1e-9) {
            return Err(ProtocolError::Field {
                field: "orientation",
                value: format!("{q:?}"),
                reason: "must be a finite non-zero quaternion",
            });
        }
        Ok(Self {
            sequence,
            flags,
            position,
            orientation: q.map(|x| x / norm),
        })
    }
}

impl ForcePacket {
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(FORCE_LEN);
        header(TYPE_FORCE, self.flags, self.sequence, &mut out);
        for x in self.force.to_array() {
            out.extend_from_slice(&x.to_le_bytes());
        }
        out.extend_from_slice(&self.tick.to_le_bytes());
        out
    }

    pub fn decode(data: &[u8]) -> Result<Self, ProtocolError> {
        let (flags, sequence) = check_header(data, TYPE_FORCE, FORCE_LEN)?;
        let force = Vec3::new(
            f64_at(data, HEADER_LEN),
            f64_at(data, HEADER_LEN + 8),
            f64_at(data, HEADER_LEN + 16),
        );
        if !crate::math::is_finite_vec(force) {
            return Err(ProtocolError::Field {
                field: "force",
                value: format!("{force:?}"),
                reason: "must be finite",
            });
        }
        Ok(Self {
            sequence,
            flags,
            force,
            tick: u64::from_le_bytes(bytes(data, HEADER_LEN + 24)),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose() -> PosePacket {
        PosePacket {
            sequence: 0xDEAD_BEEF,
            flags: FLAG_BUTTON,
            position: Vec3::new(0.01, -0.02, 0.5),
            orientation: [1.0, 0.0, 0.0, 0.0],
        }
    }

    #[test]
    fn round_trips_and_layout() {
        let bytes = pose().encode();
        assert_eq!(bytes.len(), 68);
        assert_eq!(&bytes[..6], b"TSHP\x01\x01");
        assert_eq!(&bytes[6..12], &[1, 0, 0xEF, 0xBE, 0xAD, 0xDE]);
        assert_eq!(&bytes[12..20], &0.01f64.to_le_bytes());
        assert_eq!(PosePacket::decode(&bytes), Ok(pose()));
        let f = ForcePacket {
            sequence: 7,
            flags: 0,
            force: Vec3::new(-1.5, 0.25, 3.0),
            tick: 123_456_789_012,
        };
        let b = f.encode();
        assert_eq!(b.len(), 44);
        assert_eq!(b[5], TYPE_FORCE);
        assert_eq!(ForcePacket::decode(&b), Ok(f));
    }

    #[test]
    fn quaternion_is_normalised() {
        let mut p = pose();
        p.orientation = [0.0, 0.0, 3.0, 4.0];
        let d = PosePacket::decode(&p.encode()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(d.orientation, [0.0, 0.0, 0.6, 0.8]);
    }

    #[test]
    fn malformed_datagrams_are_rejected() {
        let good = pose().encode();
        assert_eq!(
            PosePacket::decode(&good[..67]),
            Err(ProtocolError::Length {
                got: 67,
                expected: 68
            })
        );
        assert!(matches!(
            PosePacket::decode(&[good.clone(), vec![0]].concat()),
            Err(ProtocolError::Length { got: 69, .. })
        ));
        assert!(matches!(
            PosePacket::decode(&[]),
            Err(ProtocolError::Length { got: 0, .. })
        ));
        let mut b = good.clone();
        b[0] = b'X';
        assert!(matches!(
            PosePacket::decode(&b),
            Err(ProtocolError::Magic(_))
        ));
        let mut b = good.clone();
        b[4] = 2;
        assert_eq!(PosePacket::decode(&b), Err(ProtocolError::Version(2)));
        let mut b = good.clone();
        b[5] = TYPE_FORCE;
        assert!(matches!(
            PosePacket::decode(&b),
            Err(ProtocolError::Type {
                got: 2,
                expected: 1
            })
        ));
        let mut b = good.clone();
        b[12..20].copy_from_slice(&Real::NAN.to_le_bytes());
        assert!(matches!(
            PosePacket::decode(&b),
            Err(ProtocolError::Field {
                field: "position",
                ..
            })
        ));
        let mut b = good.clone();
        b[28..36].copy_from_slice(&1e3f64.to_le_bytes());
        assert!(matches!(
            PosePacket::decode(&b),
            Err(ProtocolError::Field {
                field: "position",
                ..
            })
        ));
        let mut b = good.clone();
        for k in 0..4 {
            b[36 + 8 * k..44 + 8 * k].copy_from_slice(&0f64.to_le_bytes());
        }
        assert!(matches!(
            PosePacket::decode(&b),
            Err(ProtocolError::Field {
                field: "orientation",
                ..
            })
        ));
        // A force datagram is not a pose, even with the right length elsewhere.
        assert!(matches!(
            ForcePacket::decode(&good),
            Err(ProtocolError::Length { got: 68, .. })
        ));
    }

    #[test]
    fn random_bytes_never_panic() {
        // A cheap deterministic generator: every length 0..100, arbitrary contents.
        let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
        for len in 0..100 {
            for _ in 0..50 {
                let data: Vec<u8> = (0..len)
                    .map(|_| {
                        s ^= s << 13;
                        s ^= s >> 7;
                        s ^= s << 17;
                        s as u8
                    })
                    .collect();
                let _ = PosePacket::decode(&data);
                let _ = ForcePacket::decode(&data);
            }
        }
    }
}
