//! The limits gencyl puts on what it reads and allocates, each with its reason, so that every
//! input ends in bounded time and memory with a message that names the limit.
//!
//! | limit | value | why |
//! |---|---|---|
//! | [`MAX_PIXELS`] | 2^28 pixels per image (`--max-pixels` raises it) | a film holds 16-24 bytes per pixel, and writing it copies it: 2^28 pixels are about 13 GB at most |
//! | [`MAX_SCENE_FILE`] | 64 MiB | scene files are text; a larger one is a mistake (`/dev/zero`, say) |
//! | [`MAX_HAIR_FILE`] | 2 GiB | the largest a `.hair` file's u32 point count and layout describe |
//! | [`MAX_RAY_LINE`] | 4096 bytes | a ray line is six numbers |
//! | [`max_threads`] | 8 per core | more threads only share the same cores |
//! | [`MAX_LENGTH`] | 1e15 | coordinates, radii and sizes: see [`gencyl::limits`] |
//! | [`MAX_RADIANCE`] | 1e20 | light and sky values: sums over samples and f32 images stay finite |
//!
//! and every large allocation is first compared with the memory the process can still get
//! ([`available_memory`]: the system's available memory, and the address-space limit if one is
//! set).
//!
//! Files are read only if they are regular files or pipes, and never beyond their cap.

use std::io::{self, Read};
use std::path::Path;

/// Most pixels in one image, unless raised on the command line.
pub const MAX_PIXELS: u64 = 1 << 28;
/// Largest scene file read.
pub const MAX_SCENE_FILE: u64 = 64 << 20;
/// Largest `.hair` file read.
pub const MAX_HAIR_FILE: u64 = 2 << 30;
/// Longest line of a ray file, in bytes.
pub const MAX_RAY_LINE: usize = 4096;
/// Threads per core at most.
pub const THREADS_PER_CORE: usize = 8;
/// Largest coordinate, radius or size in a scene.
pub const MAX_LENGTH: f64 = gencyl::limits::MAX_COORDINATE;
/// Largest radiance, intensity or sky value.
pub const MAX_RADIANCE: f64 = 1e20;
/// Memory a scene takes per segment at its peak while being built (cylinder, strand data,
/// BVH build and nodes), measured on the generated 1.6M-segment model (1,812 to 2,004 MiB, at
/// most 1,313 bytes a segment, 2026-12-02), with a margin: the basis of the estimates that
/// refuse a scene too large for memory.
pub const PEAK_BYTES_PER_SEGMENT: u64 = 1400;

/// The most worker threads allowed: [`THREADS_PER_CORE`] per core.
pub fn max_threads() -> usize {
    THREADS_PER_CORE * std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Checks a thread count against [`max_threads`].
pub fn check_threads(n: usize) -> Result<usize, String> {
    let max = max_threads();
    if n == 0 || n > max {
        Err(format!(
            "--threads {n}: must be 1 to {max} ({THREADS_PER_CORE} per core on this machine's {} cores; more threads only share the same cores)",
            max / THREADS_PER_CORE
        ))
    } else {
        Ok(n)
    }
}

/// Reads the whole file at `path`, which must be a regular file or a pipe, of at most `cap`
/// bytes; `what` names the kind of file for messages ("scene file"). A device, a folder or a
/// file over the cap is an error (of kind `InvalidInput`), found before reading where the
/// size is known and otherwise after at most `cap + 1` bytes.
pub fn read_file(path: &Path, cap: u64, what: &str) -> io::Result<Vec<u8>> {
    let meta = std::fs::metadata(path)?;
    stream_kind(&meta)?;
    let too_big = |n: String| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{n} bytes: larger than the {} a {what} may have",
                bytes(cap)
            ),
        )
    };
    if meta.is_file() && meta.len() > cap {
        return Err(too_big(meta.len().to_string()));
    }
    let mut out = Vec::new();
    std::fs::File::open(path)?
        .take(cap + 1)
        .read_to_end(&mut out)?;
    if out.len() as u64 > cap {
        return Err(too_big(format!("over {cap}")));
    }
    Ok(out)
}

/// Refuses a file that is neither a regular file nor a pipe, naming what it is.
fn stream_kind(meta: &std::fs::Metadata) -> io::Result<()> {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    let kind = if t.is_file() || t.is_fifo() {
        return Ok(());
    } else if t.is_dir() {
        "a folder"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_socket() {
        "a socket"
    } else {
        "not a file"
    };
    Err(io::Error::new(
        io::ErrorKind::InvalidInput,
        format!("{kind}, not a regular file or a pipe"),
    ))
}

/// Checks that `path` can be read as a stream (a regular file or a pipe): for the ray files,
/// which are read line by line, and EXR files, whose headers are read first.
pub fn check_readable(path: &Path) -> io::Result<()> {
    stream_kind(&std::fs::metadata(path)?)
}

/// The memory this process can still allocate, if known: the system's available memory
/// (`MemAvailable`), and, if the address space is limited (`ulimit -v`), what is left of it.
pub fn available_memory() -> Option<u64> {
    let available = kib_field("/proc/meminfo", "MemAvailable:");
    // "Max address space   8192000000   8192000000   bytes"
    let limit = std::fs::read_to_string("/proc/self/limits")
        .ok()
        .and_then(|l| {
            let line = l.lines().find(|l| l.starts_with("Max address space"))?;
            line["Max address space".len()..]
                .split_whitespace()
                .next()?
                .parse::<u64>()
                .ok()
        });
    let used = kib_field("/proc/self/status", "VmSize:").unwrap_or(0);
    let left = limit.map(|l| l.saturating_sub(used));
    match (available, left) {
        (Some(a), Some(l)) => Some(a.min(l)),
        (a, l) => a.or(l),
    }
}

/// The process's peak resident memory (`VmHWM`), if the system reports it. Writing `5` to
/// `/proc/self/clear_refs` resets it, to measure one phase.
pub fn peak_resident_memory() -> Option<u64> {
    kib_field("/proc/self/status", "VmHWM:")
}

/// A `key:   N kB` line of a `/proc` file, in bytes.
fn kib_field(file: &str, key: &str) -> Option<u64> {
    let text = std::fs::read_to_string(file).ok()?;
    let line = text.lines().find(|l| l.starts_with(key))?;
    let kib: u64 = line[key.len()..].split_whitespace().next()?.parse().ok()?;
    Some(kib * 1024)
}

/// Refuses an allocation of about `need` bytes for `what` that the process cannot get.
pub fn check_memory(need: u64, what: &str) -> Result<(), String> {
    match available_memory() {
        Some(have) if need > have => Err(format!(
            "{what} needs about {}, more than the {} this process can still allocate",
            bytes(need),
            bytes(have)
        )),
        _ => Ok(()),
    }
}

/// A byte count for people, in binary units: `512 bytes`, `1.5 KiB`, `64 MiB`.
pub fn bytes(n: u64) -> String {
    const UNITS: [&str; 7] = ["bytes", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut x = n as f64;
    let mut u = 0;
    while x >= 1024.0 && u + 1 < UNITS.len() {
        x /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{n} bytes")
    } else if x.fract() == 0.0 {
        format!("{x:.0} {}", UNITS[u])
    } else {
        format!("{x:.1} {}", UNITS[u])
    }
}

/// Text from a file for a message: at most `max` characters, cut with an ellipsis.
pub fn cut(text: &str, max: usize) -> String {
    match text.char_indices().nth(max) {
        Some((i, _)) => format!("{}... ({} more bytes)", &text[..i], text.len() - i),
        None => text.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_and_folders_are_refused_before_reading() {
        for p in ["/dev/zero", "/dev/urandom", "/dev/null", "/tmp"] {
            let e = read_file(Path::new(p), MAX_SCENE_FILE, "scene file").unwrap_err();
            assert_eq!(e.kind(), io::ErrorKind::InvalidInput, "{p}");
            assert!(
                e.to_string().contains("not a regular file or a pipe"),
                "{p}: {e}"
            );
        }
    }

    #[test]
    fn files_over_the_cap_are_refused() {
        let dir = std::env::temp_dir().join(format!("gencyl-limits-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("big.toml");
        std::fs::write(&p, vec![b'#'; 1000]).unwrap();
        let e = read_file(&p, 999, "scene file").unwrap_err();
        assert!(
            e.to_string()
                .contains("1000 bytes: larger than the 999 bytes"),
            "{e}"
        );
        assert_eq!(read_file(&p, 1000, "scene file").unwrap().len(), 1000);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn thread_counts_are_bounded_by_the_cores() {
        assert!(check_threads(1).is_ok());
        assert!(check_threads(max_threads()).is_ok());
        let e = check_threads(65535).unwrap_err();
        assert!(e.contains("must be 1 to"), "{e}");
        assert!(check_threads(0).is_err());
    }

    #[test]
    fn memory_checks_refuse_what_cannot_fit() {
        assert!(available_memory().is_some_and(|m| m > 0));
        let e = check_memory(u64::MAX / 2, "the image").unwrap_err();
        assert!(
            e.starts_with("the image needs about 8 EiB, more than the"),
            "{e}"
        );
        assert!(check_memory(1 << 20, "a small buffer").is_ok());
    }

    #[test]
    fn messages_are_cut() {
        let long = "x".repeat(10_000_000);
        let c = cut(&long, 40);
        assert!(c.len() < 80, "{c}");
        assert!(c.ends_with("(9999960 more bytes)"), "{c}");
        assert_eq!(cut("short", 40), "short");
        assert_eq!(bytes(64 << 20), "64 MiB");
        assert_eq!(bytes(1536), "1.5 KiB");
    }
}
