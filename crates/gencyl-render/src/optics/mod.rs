//! Optics: what light meets. The [`camera`] that sends rays into the scene, the [`light`]s that
//! emit (directional, point, spherical, the environment), the [`material`]s that scatter
//! (diffuse, Kajiya-Kay, Chiang hair, dielectric: a material becomes a BSDF at a hit), and the
//! X-ray CT [`scanner`] (parallel or cone beam, ASTRA's view vectors, the detector).
//!
//! Imports: [`crate::accel`] (a spherical light is a sphere) and [`crate::sampling`]. The
//! scene file builds these; light transport evaluates and samples them. A new light type goes
//! in `light.rs`, a new scattering model in `material/`.

pub mod camera;
pub mod light;
pub mod material;
pub mod scanner;

pub use camera::{Camera, Projection};
pub use light::{Environment, Light, LightSample};
pub use material::{Bsdf, Material, SceneMaterial};
