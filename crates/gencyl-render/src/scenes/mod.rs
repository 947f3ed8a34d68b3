//! Scenes made by the program rather than read from a file: the [`builtin`] scene (and the
//! camera and lights supplied when a scene has none) and the seeded generators of [`synth`]
//! (random fibers and rays, synthetic hair models) for tests and benchmarks, the X-ray CT
//! [`phantom`]s (yarns and composite plies with exact ground truth and label volumes), and the
//! [`job`] that makes a scene ready to render.
//!
//! Imports: [`crate::transport`], [`crate::scene_file`], [`crate::optics`], [`crate::accel`],
//! [`crate::sampling`].

pub mod builtin;
pub mod job;
pub mod phantom;
pub mod synth;
