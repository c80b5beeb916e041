//! What the viewer builds its simulations from: the scene without its scripted instruments,
//! the scaled mesh, the material, and the sizes of the viewer's own instruments, derived from
//! the organ's size. Rebuilding for another kind or material starts from here.

use tissue::interact::{Instrument, InstrumentKind, Trajectory};
use tissue::mesh::MeshData;
use tissue::model::{self, BuildInput};
use tissue::scene::Scene;
use tissue::sim::Simulation;
use tissue::{Error, Material, Real, Vec3};

use super::messages::Bounds;

/// The name of the viewer's probe, always instrument 0.
pub const PROBE: &str = "viewer-probe";

/// What does not change when the model is rebuilt.
#[derive(Clone)]
pub struct Setup {
    /// The scene without its scripted instruments.
    pub scene: Scene,
    /// The scene's mesh, scaled.
    pub mesh: MeshData,
    pub source: String,
    pub bounds: Bounds,
    pub park: Vec3,
    pub probe_radius: Real,
    pub grasp_radius: Real,
    pub scalpel_depth: Real,
}

impl Setup {
    pub fn load(scene: &Scene) -> Result<(Setup, Material), Error> {
        let path = scene.mesh_path();
        let mut mesh = tissue::io::read(&path)?;
        for v in &mut mesh.vertices {
            *v *= scene.mesh.scale;
        }
        let material = match (scene.material, mesh.material) {
            (Some(m), _) => m,
            (None, Some(r)) => Material {
                young_modulus: r.young_modulus,
                poisson_ratio: r.poisson_ratio,
                density: r.density,
                damping: 0.0,
                stiffness_damping: 0.0,
            }
            .validated()?,
            (None, None) => Material::new(3000.0, 0.3)?,
        };
        let (lo, hi) = mesh.vertices.iter().fold(
            (Vec3::splat(Real::INFINITY), Vec3::splat(-Real::INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        );
        let (center, diag) = if mesh.vertices.is_empty() {
            (Vec3::ZERO, 1.0)
        } else {
            ((lo + hi) * 0.5, (hi - lo).length().max(1e-6))
        };
        let probe_radius = scene
            .instruments
            .iter()
            .find(|i| i.value.kind == "probe")
            .and_then(|i| i.value.radius)
            .unwrap_or(0.04 * diag);
        let mut bare = scene.clone();
        bare.instruments.clear();
        Ok((
            Setup {
                scene: bare,
                mesh,
                source: path.display().to_string(),
                bounds: Bounds {
                    center,
                    radius: 3.0 * diag,
                },
                park: center + Vec3::new(0.0, 20.0 * diag, 0.0),
                probe_radius,
                grasp_radius: 1.5 * probe_radius,
                scalpel_depth: 0.15 * diag,
            },
            material,
        ))
    }

    /// Builds a simulation of `kind` with the viewer's probe as instrument 0.
    pub fn build(&self, kind: &str, material: Material) -> Result<Simulation, Error> {
        // A kind's settings do not fit another kind: other kinds get their defaults.
        let mut params = self.scene.model_params.clone();
        if kind != self.scene.model_kind {
            params.clear();
        }
        let model = model::build(
            kind,
            &BuildInput {
                mesh: &self.mesh,
                source: &self.source,
                material,
                params: &params,
            },
        )?;
        let mut sim = self.scene.build_with_model(model, &self.mesh)?;
        let probe = Instrument::new(
            PROBE,
            InstrumentKind::Probe,
            self.probe_radius,
            Trajectory::fixed(self.park),
        )?;
        sim.add_instrument(probe);
        Ok(sim)
    }
}
