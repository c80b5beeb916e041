//! Constraints and loads on surface vertices: the model-facing side of every instrument.

use crate::error::SimError;
use crate::math::{Real, Vec3, is_finite_vec};

/// A surface vertex held at a given position (contact with an instrument, grasping).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Prescribed {
    pub vertex: u32,
    /// Target position, in m.
    pub position: Vec3,
}

/// A point tied to three surface vertices (a vertex of a fine contact surface,
/// `interact::fine_surface`: x = rest + Σ wᵢ (xᵢ − Xᵢ)) that an instrument may push but not
/// pull, frictionless: n·(x − target) ≥ 0 with a push λ n, λ ≥ 0, and λ = 0 where the point
/// is off the instrument's plane (`Deformable::set_point_contacts`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointContact {
    /// The surface vertices the point follows, and their weights (summing to 1).
    pub vertices: [u32; 3],
    pub weights: [Real; 3],
    /// The point at rest, in m.
    pub rest: Vec3,
    /// The instrument's outward unit normal at the point (the plane's normal).
    pub normal: Vec3,
    /// A point of the instrument's plane, in m.
    pub target: Vec3,
}

impl PointContact {
    /// The displacement along the normal the point's vertices must give it to reach the
    /// plane: Σ wᵢ n·uᵢ ≥ n·(target − rest).
    pub fn reach(&self) -> Real {
        self.normal.dot(self.target - self.rest)
    }

    /// Checks the vertices exist among `count` and every number is finite.
    pub fn check(&self, count: usize) -> Result<(), SimError> {
        if let Some(&v) = self.vertices.iter().find(|&&v| v as usize >= count) {
            return Err(SimError::BadConstraint {
                vertex: v as usize,
                count,
            });
        }
        let finite = self.weights.iter().all(|w| w.is_finite())
            && is_finite_vec(self.rest)
            && is_finite_vec(self.normal)
            && is_finite_vec(self.target);
        if !finite || (self.normal.length() - 1.0).abs() > 1e-6 {
            return Err(SimError::BadParameter {
                name: "point contact",
                value: format!("on surface vertices {:?}", self.vertices),
                reason: "its weights, rest, target must be finite and its normal a unit vector"
                    .into(),
            });
        }
        Ok(())
    }
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

    /// The held displacement of each of the surface vertices at `rest` (`None`: free), with
    /// fixed winning over prescribed. Checked fully first: a vertex that does not exist or a
    /// non-finite target is an error naming it, and nothing is returned.
    pub fn surface_displacements(&self, rest: &[Vec3]) -> Result<Vec<Option<Vec3>>, SimError> {
        let count = rest.len();
        let check = |v: u32| {
            if (v as usize) < count {
                Ok(v as usize)
            } else {
                Err(SimError::BadConstraint {
                    vertex: v as usize,
                    count,
                })
            }
        };
        let mut disp = vec![None; count];
        for &v in &self.fixed {
            disp[check(v)?] = Some(Vec3::ZERO);
        }
        for p in &self.prescribed {
            check(p.vertex)?;
            if !is_finite_vec(p.position) {
                return Err(SimError::BadParameter {
                    name: "prescribed",
                    value: format!("surface vertex {} -> {}", p.vertex, p.position),
                    reason: "the target position is not finite".into(),
                });
            }
        }
        let is_fixed: Vec<bool> = disp.iter().map(Option::is_some).collect();
        for p in &self.prescribed {
            let v = p.vertex as usize;
            if !is_fixed[v] {
                disp[v] = Some(p.position - rest[v]);
            }
        }
        Ok(disp)
    }

    /// `surface_displacements` with the direction each held vertex is held along only
    /// (`Deformable::set_constraints_along`): `normals[k]` of the prescribed entry k whose
    /// target the vertex takes (its last), normalised; `None` for fixed vertices, for entries
    /// without a direction (or past the end of `normals`) and for a direction that does not
    /// normalise (zero or not finite), which are held in all three directions.
    pub fn surface_holds(
        &self,
        rest: &[Vec3],
        normals: &[Option<Vec3>],
    ) -> Result<Vec<Option<SurfaceHold>>, SimError> {
        let disp = self.surface_displacements(rest)?;
        let mut along: Vec<Option<Vec3>> = vec![None; disp.len()];
        let fixed: Vec<bool> = {
            let mut f = vec![false; disp.len()];
            for &v in &self.fixed {
                f[v as usize] = true;
            }
            f
        };
        for (k, p) in self.prescribed.iter().enumerate() {
            let v = p.vertex as usize;
            if !fixed[v] {
                let n = normals.get(k).copied().flatten();
                along[v] = n.map(Vec3::normalize_or_zero).filter(|n| *n != Vec3::ZERO);
            }
        }
        Ok(disp
            .into_iter()
            .zip(along)
            .map(|(d, along)| {
                d.map(|displacement| SurfaceHold {
                    displacement,
                    along,
                })
            })
            .collect())
    }
}

/// How a surface vertex is held (`Constraints::surface_holds`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHold {
    /// The held displacement from rest, in m (along `along` only when it is given).
    pub displacement: Vec3,
    /// A unit direction: held along it only (free across it), else in all three directions.
    pub along: Option<Vec3>,
}

/// External loads.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Loads {
    /// Gravitational acceleration, in m/s².
    pub gravity: Vec3,
    /// Forces on surface vertices, in N.
    pub point_loads: Vec<(u32, Vec3)>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_wins_and_bad_input_is_named() {
        let rest = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        let c = Constraints {
            fixed: vec![1],
            prescribed: vec![
                Prescribed {
                    vertex: 1,
                    position: Vec3::ONE,
                },
                Prescribed {
                    vertex: 2,
                    position: Vec3::new(0.0, 1.5, 0.0),
                },
            ],
        };
        let d = c.surface_displacements(&rest).unwrap();
        assert_eq!(
            d,
            vec![None, Some(Vec3::ZERO), Some(Vec3::new(0.0, 0.5, 0.0))]
        );
        let bad = Constraints::fixed(vec![3])
            .surface_displacements(&rest)
            .unwrap_err();
        assert_eq!(
            bad,
            SimError::BadConstraint {
                vertex: 3,
                count: 3
            }
        );
        let nan = Constraints {
            fixed: vec![],
            prescribed: vec![Prescribed {
                vertex: 0,
                position: Vec3::NAN,
            }],
        };
        let e = nan.surface_displacements(&rest).unwrap_err().to_string();
        assert!(e.contains("surface vertex 0"), "{e}");
    }
}
