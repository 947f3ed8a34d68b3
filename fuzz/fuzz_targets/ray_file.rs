//! Ray files: any bytes give rays (every number finite, every direction non-zero) or an error
//! naming the file and the line.
#![no_main]
use gencyl_render::formats::rays::parse_rays;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    match parse_rays(data, "fuzz.csv") {
        Ok(rays) => {
            for r in rays {
                assert!(r.origin.is_finite() && r.dir.is_finite() && r.dir != glam::DVec3::ZERO);
            }
        }
        Err(e) => assert!(e.to_string().starts_with("fuzz.csv")),
    }
});
