//! File formats other than the scene file, each documented next to its parser:
//!
//! - [`hair`]: Cem Yuksel's `.hair` hair models, read and written;
//! - [`rays`]: ray files (`ox,oy,oz,dx,dy,dz` per line) and the hit CSV of interface.md
//!   section 3;
//! - [`film`]: images of named `f32` channels over a window of a frame, PNG and EXR files, and
//!   merging windows back into a frame;
//! - [`tiff`]: multi-page TIFF stacks (CT projections, label volumes);
//! - [`plot`]: line plots as PNG (the goniometer's curves);
//! - [`diagnostic`]: errors that point into a text file (`path:line:column: message`).
//!
//! Every file is written through [`write_atomic`]: complete or not at all.
//!
//! Imports: the geometry crate, and [`crate::accel`] for the hits a CSV row prints. A new file
//! format goes here, as its own file.

pub mod diagnostic;
pub mod film;
pub mod hair;
pub mod plot;
pub mod rays;
pub mod tiff;

pub use diagnostic::Diagnostic;
pub use film::{Film, FilmError, Window};

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

/// Runs `encode` into a fresh temp file beside `path`, `.<name>.<pid>-<n>.tmp`, then renames it
/// over `path`: the file is complete or absent, never half-written. The temp file is removed on
/// any failure; `io` turns an I/O error into the caller's error.
pub fn write_atomic<E>(
    path: &Path,
    encode: impl FnOnce(&mut BufWriter<File>) -> Result<(), E>,
    io: impl Fn(std::io::Error) -> E,
) -> Result<(), E> {
    write_atomic_all(&[path], |outs| encode(&mut outs[0]), io)
}

/// [`write_atomic`] for several files written together: `encode` fills one temp file per path,
/// and only when all are complete are they renamed into place; on any failure every temp file
/// is removed (and no path is touched unless a rename itself fails).
pub fn write_atomic_all<E>(
    paths: &[&Path],
    encode: impl FnOnce(&mut [BufWriter<File>]) -> Result<(), E>,
    io: impl Fn(std::io::Error) -> E,
) -> Result<(), E> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let temps: Vec<_> = paths
        .iter()
        .map(|path| {
            let name = path.file_name().unwrap_or_default().to_string_lossy();
            let n = COUNTER.fetch_add(1, Ordering::Relaxed);
            path.with_file_name(format!(".{name}.{}-{n}.tmp", std::process::id()))
        })
        .collect();
    let result = (|| {
        let mut outs = Vec::with_capacity(temps.len());
        for tmp in &temps {
            let file = File::options()
                .write(true)
                .create_new(true)
                .open(tmp)
                .map_err(&io)?;
            outs.push(BufWriter::new(file));
        }
        encode(&mut outs)?;
        for out in outs {
            let file = out.into_inner().map_err(|e| io(e.into_error()))?;
            file.sync_all().map_err(&io)?;
        }
        for (tmp, path) in temps.iter().zip(paths) {
            std::fs::rename(tmp, path).map_err(&io)?;
        }
        Ok(())
    })();
    if result.is_err() {
        for tmp in &temps {
            let _ = std::fs::remove_file(tmp);
        }
    }
    result
}
