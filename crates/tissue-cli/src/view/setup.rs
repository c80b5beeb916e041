//! What the viewer builds its simulations from: the scene without its scripted instruments,
//! the loaded body (the scaled mesh, or an image's voxel grid and its surface), the material,
//! and the sizes of the viewer's own instruments, derived from the organ's size. Rebuilding
//! for another kind or material starts from here.

use tissue::interact::{Instrument, InstrumentKind, Trajectory};
use tissue::model::{BodyNeed, BodyShape, KINDS, Progress, REGION_KINDS};
use tissue::scene::{Body, IMAGE_KINDS, Scene};
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
    /// The scene's mesh (scaled) or image grid.
    pub body: Body,
    pub bounds: Bounds,
    pub park: Vec3,
    pub probe_radius: Real,
    /// The scene's pushing instrument asks for sticking contact (read before the scripted
    /// instruments are taken out): the viewer's probe then sticks too.
    pub probe_sticks: bool,
    pub grasp_radius: Real,
    pub scalpel_depth: Real,
}

impl Setup {
    pub fn load(scene: &Scene) -> Result<(Setup, Material), Error> {
        let body = scene.load_body()?;
        let material = match (scene.material, body.mesh.material) {
            (None, None) => Material::new(3000.0, 0.3)?,
            _ => scene.material_for(&body)?,
        };
        let mesh = &body.mesh;
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
        let probe_sticks = scene
            .instruments
            .iter()
            .map(|i| &i.value)
            .find(|i| matches!(i.kind.as_str(), "probe" | "capsule" | "plane" | "box"))
            .is_some_and(|i| i.contact.as_deref() == Some("sticking"));
        let mut bare = scene.clone();
        bare.instruments.clear();
        Ok((
            Setup {
                scene: bare,
                body,
                bounds: Bounds {
                    center,
                    radius: 3.0 * diag,
                },
                park: center + Vec3::new(0.0, 20.0 * diag, 0.0),
                probe_radius,
                probe_sticks,
                grasp_radius: 1.5 * probe_radius,
                scalpel_depth: 0.15 * diag,
            },
            material,
        ))
    }

    /// The kinds this body can be built as: the voxel kinds on an image; on a mesh, the kinds
    /// whose need (`BodyNeed`: tetrahedra, a closed or an open surface) the mesh meets. A
    /// surface liver lists the 5 surface and voxel kinds, not the 11 that would only refuse.
    /// A scene with per-region materials lists only the kinds that honour them.
    pub fn buildable_kinds(&self) -> Vec<&'static str> {
        let shape = BodyShape::of(&self.body.mesh);
        let regions = !self.scene.material_regions.is_empty();
        KINDS
            .iter()
            .map(|k| k.name)
            .filter(|k| match self.body.grid {
                Some(_) => IMAGE_KINDS.contains(k),
                None => BodyNeed::of(k).is_some_and(|need| shape.allows(need)),
            })
            .filter(|k| !regions || REGION_KINDS.contains(k))
            .collect()
    }

    /// Builds a simulation of `kind` with the viewer's probe as instrument 0. Models with long
    /// pre-computations report them to `progress` (most do it when their supports are set,
    /// inside `build_with_model`).
    pub fn build(
        &self,
        kind: &str,
        material: Material,
        progress: Progress,
    ) -> Result<Simulation, Error> {
        // A kind's settings do not fit another kind: other kinds get their defaults.
        let mut params = self.scene.model_params.clone();
        if kind != self.scene.model_kind {
            params.clear();
        }
        let mut model = self
            .scene
            .build_model(kind, &self.body, material, &params)?;
        // The page steps the model against the wall clock.
        model.set_real_time(true);
        model.set_progress(progress);
        let mut sim = self.scene.build_with_model(model, &self.body.mesh)?;
        // Frictionless sliding, `Instrument::new`'s default for a probe, unless the scene
        // asks its pushing instrument to stick (a scene on a mesh too coarse for its probe
        // to slide on: docs/contact.md, "Frictionless by default").
        let probe = Instrument::new(
            PROBE,
            InstrumentKind::Probe,
            self.probe_radius,
            Trajectory::fixed(self.park),
        )?;
        // (The bare scene has no instruments left to ask: `probe_sticks` was read before.)
        sim.add_instrument(if self.probe_sticks {
            probe.sticking()
        } else {
            probe
        });
        Ok(sim)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scene whose body is an image: the viewer sizes its probe from the marching surface,
    /// rebuilds the other voxel kind on the same grid, and refuses mesh kinds by name.
    #[test]
    fn an_image_scene_sets_up_and_rebuilds_voxel_kinds() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../scenes/brain-linked-volumes.toml"
        );
        let scene = Scene::load(path).unwrap_or_else(|e| panic!("{e}"));
        let (setup, material) = Setup::load(&scene).unwrap_or_else(|e| panic!("{e}"));
        assert!(setup.body.grid.is_some());
        assert_eq!(setup.buildable_kinds(), ["chainmail", "linked-volumes"]);
        // The block spans 0.068 x 0.084 x 0.052 m around (0.064, 0, 0.008).
        assert!(setup.bounds.center.distance(Vec3::new(0.064, 0.0, 0.008)) < 1e-9);
        for kind in ["linked-volumes", "chainmail"] {
            let sim = setup
                .build(kind, material, Progress::silent())
                .unwrap_or_else(|e| panic!("{kind}: {e}"));
            assert_eq!(sim.model().kind(), kind);
            assert_eq!(sim.instrument_forces().len(), 1);
        }
        let e = setup
            .build("fem-static", material, Progress::silent())
            .err()
            .map(|e| e.to_string());
        assert!(
            e.as_deref()
                .is_some_and(|e| e.contains("cannot be built from an [image]")),
            "{e:?}"
        );
    }

    /// A mesh scene lists the kinds its mesh can be built as, and only those.
    #[test]
    fn a_mesh_scene_lists_only_the_kinds_its_mesh_can_be_built_as() {
        let listed = |name: &str| {
            let path = format!("{}/../../scenes/{name}", env!("CARGO_MANIFEST_DIR"));
            let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
            let (setup, _) = Setup::load(&scene).unwrap_or_else(|e| panic!("{e}"));
            setup.buildable_kinds()
        };
        assert_eq!(
            listed("liver-bem.toml"),
            [
                "spring-mass",
                "simplex-spring-mass",
                "bem",
                "chainmail",
                "linked-volumes"
            ]
        );
        assert_eq!(listed("tube-spline.toml"), ["spring-mass", "spline"]);
        let tetrahedral = listed("liver-probe.toml");
        assert_eq!(tetrahedral.len(), KINDS.len() - 1);
        assert!(!tetrahedral.contains(&"spline"));
        // Per-region materials: only the kinds that give each region its own.
        assert_eq!(listed("organ-fem-tumour.toml"), REGION_KINDS);
    }
}
