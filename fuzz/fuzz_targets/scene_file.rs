//! Scene files: any bytes give a scene or a located error, never a panic, and an error's
//! message stays short.
#![no_main]
use gencyl_render::scene_file::SceneDescription;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Err(e) = SceneDescription::parse_bytes(data, "fuzz.toml") {
        let text = match e.diagnostic() {
            Some(d) => d.render(),
            None => e.to_string(),
        };
        assert!(text.len() < 4000, "a {}-byte message", text.len());
    }
});
