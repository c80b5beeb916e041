//! Building the two parts for a region, and doing it off the interactive thread when the
//! region grows (as `bem` solves its contact rims): the old parts answer every step until
//! the new ones land.

use std::sync::mpsc::{self, Receiver, TryRecvError};
use std::time::Instant;

use crate::error::{Error, SimError};
use crate::math::Real;
use crate::mesh::TetMesh;
use crate::model::tensor_mass::TensorMass;

use super::CutRegion;
use super::model::Recipe;
use super::rest::RestPart;
use super::split::Split;

/// The parts of one region, built.
pub(super) struct Built {
    pub split: Split,
    pub rest: RestPart,
    pub tm: TensorMass,
    /// Build time, in s.
    pub seconds: Real,
}

impl Built {
    /// Splits the mesh, condenses the rest onto the interface, builds the region's tensors.
    pub fn new(
        mesh: &TetMesh,
        in_region: Vec<bool>,
        mode: &CutRegion,
        recipe: &Recipe,
    ) -> Result<Self, Error> {
        let start = Instant::now();
        let split = Split::new(mesh, in_region, &mode.describe())?;
        let rest = RestPart::new(&split, recipe.material)?;
        let mut tm = TensorMass::new(
            &split.region.mesh,
            recipe.material,
            recipe.tm_params.clone(),
            recipe.nonlinear,
            recipe.scheme,
        )?;
        // The rest is massless (static): the interface nodes, which the region integrates,
        // carry its lumped share, so their frequency is not raised by the rest's stiffness
        // on the region's share alone (the weight follows the mass).
        let shares: Vec<(usize, Real)> = split
            .interface
            .iter()
            .zip(rest.interface_masses())
            .map(|(&g, m)| (split.region.local[g as usize] as usize, m))
            .collect();
        tm.add_node_masses(&shares);
        tm.prepare_cutting();
        Ok(Self {
            split,
            rest,
            tm,
            seconds: start.elapsed().as_secs_f64(),
        })
    }
}

/// A region growth being built on its own thread.
pub(super) struct Growth {
    /// The grown region's tetrahedra.
    pub mask: Vec<bool>,
    pub steps_waited: u64,
    result: Receiver<Result<Built, String>>,
}

impl Growth {
    /// Starts building the parts for `mask` on a new thread.
    pub fn start(mesh: TetMesh, mask: Vec<bool>, mode: CutRegion, recipe: Recipe) -> Self {
        let (send, result) = mpsc::channel();
        let m = mask.clone();
        std::thread::spawn(move || {
            let built = Built::new(&mesh, m, &mode, &recipe).map_err(|e| e.to_string());
            // The model may have been dropped meanwhile: nobody to tell.
            let _ = send.send(built);
        });
        Self {
            mask,
            steps_waited: 0,
            result,
        }
    }

    /// The parts if they are ready.
    pub fn try_take(&mut self) -> Option<Result<Built, SimError>> {
        match self.result.try_recv() {
            Ok(r) => Some(r.map_err(failed)),
            Err(TryRecvError::Empty) => None,
            Err(TryRecvError::Disconnected) => Some(Err(failed("its thread stopped".into()))),
        }
    }

    /// Waits for the parts.
    pub fn wait(self) -> Result<Built, SimError> {
        match self.result.recv() {
            Ok(r) => r.map_err(failed),
            Err(_) => Err(failed("its thread stopped".into())),
        }
    }
}

fn failed(reason: String) -> SimError {
    SimError::BadParameter {
        name: "cut_region",
        value: "auto".into(),
        reason: format!("growing the region failed: {reason}"),
    }
}
