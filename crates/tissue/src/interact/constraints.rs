//! Constraints and loads on surface vertices: the model-facing side of every instrument.

use crate::math::Vec3;

/// A surface vertex held at a given position (contact with an instrument, grasping).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Prescribed {
    pub vertex: u32,
    /// Target position, in m.
    pub position: Vec3,
}

/// Fixed and prescribed surface vertices.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Constraints {
    /// Vertices held at their rest position (ligaments, attachments).
    pub fixed: Vec<u32>,
    pub prescribed: Vec<Prescribed>,
}

impl Constraints {
    pub fn fixed(fixed: Vec<u32>) -> Self {
        Self {
            fixed,
            prescribed: Vec::new(),
        }
    }
}

/// External loads.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Loads {
    /// Gravitational acceleration, in m/s².
    pub gravity: Vec3,
    /// Forces on surface vertices, in N.
    pub point_loads: Vec<(u32, Vec3)>,
}
