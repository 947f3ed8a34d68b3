//! File formats other than the scene file, each documented next to its parser:
//!
//! - [`hair`]: Cem Yuksel's `.hair` hair models, read and written;
//! - [`rays`]: ray files (`ox,oy,oz,dx,dy,dz` per line) and the hit CSV of interface.md
//!   section 3;
//! - [`film`]: images of named `f32` channels over a window of a frame, PNG and EXR files, and
//!   merging windows back into a frame;
//! - [`diagnostic`]: errors that point into a text file (`path:line:column: message`).
//!
//! Imports: the geometry crate, and [`crate::accel`] for the hits a CSV row prints. A new file
//! format goes here, as its own file.

pub mod diagnostic;
pub mod film;
pub mod hair;
pub mod rays;

pub use diagnostic::Diagnostic;
pub use film::{Film, FilmError, Window};
