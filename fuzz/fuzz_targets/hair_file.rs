//! `.hair` files: any bytes give strands or an error naming the file; the strands of a file
//! that parses build into cylinders or a named error.
#![no_main]
use gencyl_render::formats::hair::parse_hair;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    match parse_hair(data, "fuzz.hair") {
        Ok(h) => {
            for s in h.to_strands(None).into_iter().take(64) {
                let _ = s.cylinders();
            }
        }
        Err(e) => assert!(e.to_string().starts_with("fuzz.hair: ")),
    }
});
