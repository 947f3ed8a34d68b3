//! Scenes, acceleration and rendering for `gencyl` generalized cylinders.
//!
//! - [`scene`]: the TOML scene file ([`scene::SceneDescription`]) and the scene ready for ray
//!   queries ([`scene::Scene`]: the cylinders and a BVH over them; nearest, all and any hits).
//! - [`bvh`]: a binned-SAH bounding volume hierarchy with one closure-based traversal core.
//! - [`raycast`]: the ray file format and the batch intersection behind `gencyl raycast`.
//! - [`cull`]: a cheap ray-space test that rejects most missed cylinders before the exact solver.
//! - [`error`]: diagnostics that point into an input file.
//! - [`hair`]: Cem Yuksel's `.hair` files, read as strands.
//! - [`synth`]: seeded random fibers and rays, for tests and benchmarks.
//! - [`render`]: a first renderer (camera, hair shading, floor, soft shadows) and the built-in
//!   default scene.
//!
//! ```
//! use gencyl_render::scene::{Scene, SceneDescription};
//! use gencyl::Ray;
//! use glam::DVec3;
//!
//! let src = "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\n";
//! let scene = Scene::new(SceneDescription::parse(src, "scene.toml")?.cylinders);
//! let ray = Ray::new(DVec3::new(1.5, 0.0, 1.0), DVec3::new(0.0, 0.0, -1.0));
//! let hit = scene.nearest_hit(&ray, 0.0, f64::INFINITY, &mut Default::default()).unwrap();
//! assert_eq!((hit.object, hit.hit.t), (0, 0.9));
//! # Ok::<(), gencyl_render::scene::SceneError>(())
//! ```

pub mod bvh;
pub mod camera;
pub mod cull;
pub mod description;
pub mod error;
pub mod film;
pub mod hair;
pub mod integrator;
pub mod light;
pub mod material;
pub mod raycast;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod shapes;
pub mod synth;
pub mod world;
