//! Light transport: the [`World`] a render queries (the cylinders' BVH, spheres, planes,
//! materials and lights, built from a scene description) and the [`integrator`]s that give a
//! camera ray its value (debug views, direct lighting, path tracing, X-ray path lengths) and
//! render a window of the frame in parallel, and the X-ray [`ct`] projector (a scan's
//! projections, view by view).
//!
//! Imports: everything below it: [`crate::scene_file`] (what a world is built from),
//! [`crate::optics`], [`crate::accel`], [`crate::formats`] (the film it renders into),
//! [`crate::settings`] and [`crate::sampling`]. A new integrator goes in `integrator.rs`.

pub mod ct;
pub mod integrator;
pub mod scatter;
pub mod world;

pub use integrator::{Buffers, render};
pub use world::{Crossing, Fibers, Surface, World, WorldHit};
