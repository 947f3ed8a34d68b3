//! EXR input of `gencyl merge`: any bytes, read as a part, give a film within the pixel limit
//! or an error naming the file; never a panic or an allocation beyond the limit.
#![no_main]
use gencyl_render::formats::Film;
use libfuzzer_sys::fuzz_target;

/// A small limit, so that a header claiming a large image must be refused.
const MAX_PIXELS: u64 = 1 << 16;

fuzz_target!(|data: &[u8]| {
    let path = std::env::temp_dir().join(format!("gencyl-fuzz-{}.exr", std::process::id()));
    std::fs::write(&path, data).unwrap();
    match Film::read_exr_within(&path, MAX_PIXELS) {
        Ok(film) => {
            assert!(film.frame.0 as u64 * film.frame.1 as u64 <= MAX_PIXELS);
            let _ = Film::merge(&[film]);
        }
        Err(e) => assert!(e.to_string().contains("gencyl-fuzz-")),
    }
});
