//! Acceleration: ray queries on the geometry of a scene.
//!
//! - [`scene`]: the [`Scene`], the cylinders under a BVH over pieces of their axes, queried for
//!   the nearest hit, every hit or any hit;
//! - [`bvh`]: the bounding volume hierarchy (node layout and traversal in `bvh/mod.rs`, the
//!   binned-SAH builder in `bvh/build.rs`);
//! - [`cull`]: the ray-space test that rejects most missed axis pieces before the exact solver;
//! - [`frustum`]: the region a bundle of rays from one point sweeps (a pixel's camera rays), whose
//!   BVH leaves its rays walk instead of the tree;
//! - [`prefetch`]: loading the walk's next nodes and cylinders ahead of their use (the one
//!   `unsafe` block of the project: a cache hint);
//! - [`shapes`]: the analytic sphere and plane.
//!
//! Imports: the geometry crate only (its tests draw random fibers from
//! [`crate::scenes::synth`]). Everything that queries geometry builds on this.

pub mod bvh;
pub mod cull;
pub mod frustum;
pub mod prefetch;
pub mod scene;
pub mod shapes;

pub use bvh::{Bvh, RegionList};
pub use frustum::Frustum;
pub use scene::{Leaving, QueryCounts, Scene, SceneHit, Scratch, sort_hits};
pub use shapes::{Plane, Sphere};

/// Whether the queries count what they do ([`QueryCounts`]): with the `stats` feature, and in
/// this crate's tests; compiled out otherwise (the counting costs rays about 1.5%).
pub const COUNTING: bool = cfg!(any(test, feature = "stats"));
