//! Reactions reported in the order the constraints were given. A vertex may appear in several
//! entries (fixed twice, fixed and prescribed, touched by two instruments); its force is
//! reported once, at its first fixed entry or else at its last prescribed one (fixed wins,
//! and the last instrument to claim a vertex holds it), so that sums over entries count each
//! vertex once. Every model that takes `Constraints` keeps one of these.

use crate::interact::Constraints;
use crate::math::Vec3;

use super::Reactions;

#[derive(Clone, Debug, Default)]
pub struct ConstraintReactions {
    constraints: Constraints,
    fixed_owner: Vec<bool>,
    prescribed_owner: Vec<bool>,
    fixed: Vec<Vec3>,
    prescribed: Vec<Vec3>,
    taken: Vec<bool>,
}

impl ConstraintReactions {
    /// Records new constraints (their vertex ids checked by the caller); reactions are zero
    /// until `distribute`. Reuses its buffers.
    pub fn set(&mut self, c: &Constraints) {
        let top = c
            .fixed
            .iter()
            .copied()
            .chain(c.prescribed.iter().map(|p| p.vertex))
            .max()
            .map_or(0, |v| v as usize + 1);
        self.taken.clear();
        self.taken.resize(top, false);
        let taken = &mut self.taken;
        self.fixed_owner.clear();
        self.fixed_owner.extend(
            c.fixed
                .iter()
                .map(|&v| !std::mem::replace(&mut taken[v as usize], true)),
        );
        self.prescribed_owner.clear();
        self.prescribed_owner.resize(c.prescribed.len(), false);
        for (k, p) in c.prescribed.iter().enumerate().rev() {
            self.prescribed_owner[k] = !std::mem::replace(&mut taken[p.vertex as usize], true);
        }
        self.fixed.clear();
        self.fixed.resize(c.fixed.len(), Vec3::ZERO);
        self.prescribed.clear();
        self.prescribed.resize(c.prescribed.len(), Vec3::ZERO);
        // Field by field: a derived `clone_from` would allocate anew on every contact update.
        self.constraints.fixed.clone_from(&c.fixed);
        self.constraints.prescribed.clone_from(&c.prescribed);
    }

    pub fn constraints(&self) -> &Constraints {
        &self.constraints
    }

    /// Fills every entry from the force the tissue exerts at each constrained vertex.
    pub fn distribute(&mut self, force_at: impl Fn(u32) -> Vec3) {
        let c = &self.constraints;
        for (k, &v) in c.fixed.iter().enumerate() {
            self.fixed[k] = if self.fixed_owner[k] {
                force_at(v)
            } else {
                Vec3::ZERO
            };
        }
        for (k, p) in c.prescribed.iter().enumerate() {
            self.prescribed[k] = if self.prescribed_owner[k] {
                force_at(p.vertex)
            } else {
                Vec3::ZERO
            };
        }
    }

    /// The vertices whose reactions the prescribed entries `entries` report (each vertex
    /// once, at the entry that owns it); `None` when the range is out of bounds.
    pub fn owned_prescribed(&self, entries: std::ops::Range<usize>) -> Option<Vec<u32>> {
        let prescribed = self.constraints.prescribed.get(entries.clone())?;
        let owners = self.prescribed_owner.get(entries)?;
        Some(
            prescribed
                .iter()
                .zip(owners)
                .filter(|&(_, &owner)| owner)
                .map(|(p, _)| p.vertex)
                .collect(),
        )
    }

    pub fn reactions(&self) -> Reactions<'_> {
        Reactions {
            fixed: &self.fixed,
            prescribed: &self.prescribed,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::interact::Prescribed;

    #[test]
    fn each_vertex_reports_once_fixed_first_then_last_instrument() {
        let held = |vertex| Prescribed {
            vertex,
            position: Vec3::ZERO,
        };
        let c = Constraints {
            fixed: vec![4, 2, 4],
            prescribed: vec![held(2), held(7), held(9), held(7)],
        };
        let mut book = ConstraintReactions::default();
        book.set(&c);
        book.distribute(|v| Vec3::splat(v as f64));
        let r = book.reactions();
        assert_eq!(r.fixed, &[Vec3::splat(4.0), Vec3::splat(2.0), Vec3::ZERO]);
        assert_eq!(
            r.prescribed,
            &[Vec3::ZERO, Vec3::ZERO, Vec3::splat(9.0), Vec3::splat(7.0)]
        );
        // Fewer constraints later reuse the buffers and forget the old entries.
        book.set(&Constraints::fixed(vec![1]));
        assert_eq!(book.reactions().fixed, &[Vec3::ZERO]);
        assert!(book.reactions().prescribed.is_empty());
    }
}
