//! Scenes, acceleration and rendering for `gencyl` generalized cylinders.
//!
//! The crate is in folders by job. Imports run one way, down this list (a module may import
//! the ones below it, never one above):
//!
//! - [`scenes`]: the built-in scene, the camera and lights supplied when a scene has none,
//!   seeded generators of fibers, rays and hair models.
//! - [`raycast`]: the batch behind `gencyl raycast`: ray files in, hits out as CSV.
//! - [`transport`]: light transport: the [`transport::World`] a render queries and the
//!   integrators that turn camera rays into pixels.
//! - [`scene_file`]: the TOML scene format: parse, check, locate errors, build
//!   ([`scene_file::SceneDescription`]), one file per table family.
//! - [`optics`]: what light meets: the camera, lights, materials (BSDFs).
//! - [`formats`]: file formats other than the scene file: `.hair` models, ray files and the hit
//!   CSV, images (PNG, EXR), errors located in a text file.
//! - [`accel`]: ray queries on geometry: the cylinders under a BVH with a ray-space cull
//!   ([`accel::Scene`]), the analytic sphere and plane.
//! - [`settings`], [`sampling`], [`limits`]: plain render settings; random streams and warps;
//!   the limits on input and memory (leaves).
//!
//! So a new light type goes in `optics/light.rs` (and its table in `scene_file/lights.rs`), a new
//! file format in `formats/`, a new BVH node layout in `accel/bvh/`, a new integrator in
//! `transport/integrator.rs`.
//!
//! ```
//! use gencyl_render::accel::Scene;
//! use gencyl_render::scene_file::SceneDescription;
//! use gencyl::Ray;
//! use glam::DVec3;
//!
//! let src = "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\n";
//! let scene = Scene::new(SceneDescription::parse(src, "scene.toml")?.cylinders);
//! let ray = Ray::new(DVec3::new(1.5, 0.0, 1.0), DVec3::new(0.0, 0.0, -1.0));
//! let hit = scene.nearest_hit(&ray, 0.0, f64::INFINITY, &mut Default::default()).unwrap();
//! assert_eq!((hit.object, hit.hit.t), (0, 0.9));
//! # // The first layout's paths still name the same items:
//! # let _: Option<(gencyl_render::scene::Scene, gencyl_render::description::SceneDescription)> = None;
//! # let _ = (gencyl_render::integrator::render, gencyl_render::render::default_scene);
//! # let _: Option<(gencyl_render::film::Film, gencyl_render::world::World)> = None;
//! # Ok::<(), gencyl_render::scene_file::SceneError>(())
//! ```

pub mod accel;
pub mod formats;
pub mod limits;
pub mod optics;
pub mod raycast;
pub mod sampling;
pub mod scene_file;
pub mod scenes;
pub mod settings;
pub mod transport;

// The paths of the crate's first layout (one flat folder), kept for its users.
pub use accel::{bvh, cull, shapes};
pub use formats::{diagnostic as error, film, hair};
pub use optics::{camera, light, material};
pub use scene_file as description;
pub use scenes::{builtin as render, synth};
pub use transport::{integrator, world};

/// The cylinders ready for ray queries, and the scene file they come from (the first layout's
/// `scene` module).
pub mod scene {
    pub use crate::accel::scene::*;
    pub use crate::scene_file::{SceneDescription, SceneError};
}
