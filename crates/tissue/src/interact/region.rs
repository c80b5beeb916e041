//! Regions that select surface vertices: for fixed supports and loads in scenes.

use serde::{Deserialize, Serialize};

use crate::math::{Real, Vec3};

/// A set of vertices by geometry or by index.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase", deny_unknown_fields)]
pub enum Region {
    /// Vertices inside the axis-aligned box (bounds included).
    Box { min: [Real; 3], max: [Real; 3] },
    /// Vertices inside the ball.
    Sphere { center: [Real; 3], radius: Real },
    /// Vertices within `tolerance` of the plane or behind it: (x - point)·normal ≤ tolerance.
    Plane {
        point: [Real; 3],
        normal: [Real; 3],
        #[serde(default)]
        tolerance: Real,
    },
    /// Explicit surface vertex indices.
    Indices(Vec<u32>),
}

impl Region {
    /// Indices of the vertices (positions given) that the region selects, ascending.
    pub fn select(&self, positions: &[Vec3]) -> Vec<u32> {
        let pick = |f: &dyn Fn(Vec3) -> bool| {
            (0..positions.len() as u32)
                .filter(|&i| f(positions[i as usize]))
                .collect()
        };
        match self {
            Region::Box { min, max } => {
                let (lo, hi) = (Vec3::from(*min), Vec3::from(*max));
                pick(&|p| p.cmpge(lo).all() && p.cmple(hi).all())
            }
            Region::Sphere { center, radius } => {
                let c = Vec3::from(*center);
                pick(&|p| p.distance_squared(c) <= radius * radius)
            }
            Region::Plane {
                point,
                normal,
                tolerance,
            } => {
                let (o, n) = (Vec3::from(*point), Vec3::from(*normal).normalize_or_zero());
                pick(&|p| (p - o).dot(n) <= *tolerance)
            }
            Region::Indices(ids) => {
                let mut v: Vec<u32> = ids
                    .iter()
                    .copied()
                    .filter(|&i| (i as usize) < positions.len())
                    .collect();
                v.sort_unstable();
                v.dedup();
                v
            }
        }
    }

    /// Indices that do not exist among `count` vertices (to report, not silently drop).
    pub fn out_of_range(&self, count: usize) -> Vec<u32> {
        match self {
            Region::Indices(ids) => ids
                .iter()
                .copied()
                .filter(|&i| i as usize >= count)
                .collect(),
            _ => Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_select_expected_vertices() {
        let p: Vec<Vec3> = (0..5).map(|i| Vec3::new(i as f64, 0.0, 0.0)).collect();
        assert_eq!(
            Region::Box {
                min: [0.5, -1.0, -1.0],
                max: [2.0, 1.0, 1.0]
            }
            .select(&p),
            vec![1, 2]
        );
        assert_eq!(
            Region::Sphere {
                center: [4.0, 0.0, 0.0],
                radius: 1.0
            }
            .select(&p),
            vec![3, 4]
        );
        let plane = Region::Plane {
            point: [1.0, 0.0, 0.0],
            normal: [1.0, 0.0, 0.0],
            tolerance: 0.0,
        };
        assert_eq!(plane.select(&p), vec![0, 1]);
        assert_eq!(Region::Indices(vec![4, 1, 1, 9]).select(&p), vec![1, 4]);
        assert_eq!(Region::Indices(vec![4, 9]).out_of_range(5), vec![9]);
    }
}
