//! Writing cylinders back as interface.md `[[cylinder]]` tables (`gencyl export`), so that a
//! scene's strands and hair files can be read by tools that know only that section (the Embree
//! comparison, other renderers).
//!
//! Numbers are written in Rust's shortest round-trip form, so every value reads back to the same
//! `f64`. A cylinder keeps its axis, radii, rotation, profile and caps (`caps = [start, end]`
//! where the ends differ, an extension of interface.md's boolean). The frame is the one thing a
//! `[[cylinder]]` table cannot choose: it is Frenet's (or, on a straight axis, the one given by
//! `normal_hint`). A strand segment with the strand frame is therefore written only if its
//! section is round with a uniform scale, where the surface does not depend on the frame (only
//! the hits' `v` does); an elliptical or profiled one is an error naming the cylinder.

use std::fmt::Write;

use gencyl::{Framing, GeneralizedCylinder, Section, SweepRule};

/// The `[[cylinder]]` tables of `cylinders`, in order (so cylinder numbers are kept).
pub fn cylinder_tables(cylinders: &[GeneralizedCylinder]) -> Result<String, String> {
    let mut out = String::new();
    for (i, c) in cylinders.iter().enumerate() {
        write_table(&mut out, c).map_err(|why| format!("cylinder {i}: {why}"))?;
    }
    Ok(out)
}

fn write_table(out: &mut String, c: &GeneralizedCylinder) -> Result<(), String> {
    let sweep = c.sweep();
    let round = matches!(c.section(), Section::Circle(_)) && sweep.uniform_scale().is_some();
    let hint = match c.framing() {
        Framing::Frenet => None,
        Framing::Fixed(f) => Some(f.n),
        Framing::Projected(_) if round => None,
        Framing::Projected(_) => {
            return Err(
                "its section is not round and turns with the strand frame, which a [[cylinder]] table (Frenet's frame) cannot express"
                    .into(),
            );
        }
    };
    let p = c.axis().points;
    let v3 = |v: glam::DVec3| format!("[{:?}, {:?}, {:?}]", v.x, v.y, v.z);
    let pair = |a: [f64; 2]| format!("[{:?}, {:?}]", a[0], a[1]);
    let _ = writeln!(out, "[[cylinder]]");
    let _ = writeln!(
        out,
        "bezier = [{}, {}, {}, {}]",
        v3(p[0]),
        v3(p[1]),
        v3(p[2]),
        v3(p[3])
    );
    let _ = writeln!(out, "major_radius = {}", pair(sweep.major));
    if sweep.minor != sweep.major {
        let _ = writeln!(out, "minor_radius = {}", pair(sweep.minor));
    }
    if sweep.rotation != [0.0, 0.0] {
        let _ = writeln!(out, "rotation = {}", pair(sweep.rotation));
    }
    match c.caps() {
        [true, true] => {}
        [false, false] => {
            let _ = writeln!(out, "caps = false");
        }
        [a, b] => {
            let _ = writeln!(out, "caps = [{a}, {b}]");
        }
    }
    if let Some(n) = hint {
        let _ = writeln!(out, "normal_hint = {}", v3(n));
    }
    if let Section::Loop(l) = c.section() {
        let points: Vec<String> = l
            .pieces()
            .iter()
            .flat_map(|q| [q[0], q[1], q[2]])
            .map(|q| format!("[{:?}, {:?}]", q.x, q.y))
            .collect();
        let _ = writeln!(out, "profile = [{}]", points.join(", "));
    }
    let _ = writeln!(out);
    Ok(())
}
