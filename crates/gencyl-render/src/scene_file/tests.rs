//! The scene format end to end: every table, its defaults, its located errors.

use gencyl::Section;
use glam::DVec3;

use super::*;
use crate::optics::material::Material;
use crate::optics::{Environment, Light, Projection};
use crate::settings::{Integrator, RenderTable};

const GOOD: &str =
    "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\n";

fn err(src: &str) -> String {
    match SceneDescription::parse(src, "s.toml") {
        Ok(s) => panic!("accepted {src:?}: {} cylinders", s.cylinders.len()),
        Err(e) => e.to_string(),
    }
}

/// Each scene text fails with a message that starts as given.
fn expect_errors<S: AsRef<str>>(cases: &[(S, &str)]) {
    for (src, want) in cases {
        let got = err(src.as_ref());
        assert!(
            got.starts_with(want),
            "for {:?}\n got: {got}\nwant: {want}...",
            src.as_ref()
        );
    }
}

#[test]
fn parses_defaults() {
    let s = SceneDescription::parse(GOOD, "s.toml").unwrap();
    assert_eq!(s.cylinders.len(), 1, "one cylinder");
    let c = &s.cylinders[0];
    assert_eq!(c.caps(), [true, true], "caps default to true");
    for (caps, want) in [
        ("false", [false, false]),
        ("[true, false]", [true, false]),
        ("[false, true]", [false, true]),
    ] {
        let s = SceneDescription::parse(&format!("{GOOD}caps = {caps}\n"), "s.toml").unwrap();
        assert_eq!(s.cylinders[0].caps(), want, "caps = {caps}");
    }
    assert_eq!(c.sweep().minor, [0.1, 0.1], "minor defaults to major");
    assert_eq!(c.sweep().rotation, [0.0, 0.0], "rotation defaults to 0");
    assert!(
        matches!(c.section(), Section::Circle(_)),
        "section defaults to the circle"
    );
}

#[test]
fn empty_scene_is_valid() {
    for src in ["", "# nothing\n", "cylinder = []\n"] {
        let s = SceneDescription::parse(src, "s.toml").unwrap();
        assert!(s.cylinders.is_empty(), "{src:?}");
    }
}

#[test]
fn rejects_shapes_and_values_with_locations() {
    let cases: &[(&str, &str)] = &[
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\ncolour = 1\n",
            "s.toml:4:1: unknown field `colour`",
        ),
        ("colour = 1\n", "s.toml:1:1: unknown field `colour`"),
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1, 0.2]\n",
            "s.toml:3:16:",
        ),
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0],[4,0,0]]\nmajor_radius = [0.1, 0.1]\n",
            "s.toml:2:",
        ),
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0]]\nmajor_radius = [0.1, 0.1]\n",
            "s.toml:2:",
        ),
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = \"thick\"\n",
            "s.toml:3:16:",
        ),
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [nan, 0.1]\n",
            "s.toml:3:16: major_radius must be finite, got [NaN, 0.1] (cylinder 0)",
        ),
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\nminor_radius = [0.1, -0.1]\n",
            "s.toml:4:16: minor_radius must be positive at both ends",
        ),
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,inf],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\n",
            "s.toml:2:10: bezier control point 1 is not finite",
        ),
        (
            "[[cylinder]]\nbezier = [[1,1,1],[1,1,1],[1,1,1],[1,1,1]]\nmajor_radius = [0.1, 0.1]\n",
            "s.toml:2:10: the axis has zero length",
        ),
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[0,0,0],[1,0,0]]\nmajor_radius = [0.1, 0.1]\n",
            "s.toml:2:10: the axis has a cusp",
        ),
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\nnormal_hint = [2, 0, 0]\n",
            "s.toml:4:15: normal_hint is parallel",
        ),
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\nnormal_hint = [0, 0, 0]\n",
            "s.toml:4:15: normal_hint must be a finite non-zero vector",
        ),
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\nprofile = [[1, 0], [0, 1]]\n",
            "s.toml:4:11: bad profile: a profile needs 3k points",
        ),
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\nprofile = [[1, 0], [2, 0], [3, 0]]\n",
            "s.toml:4:11: bad profile: the profile encloses no area",
        ),
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\nrotation = [0, inf]\n",
            "s.toml:4:12: rotation must be finite",
        ),
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\ncaps = 1\n",
            "s.toml:4:8: invalid type: integer `1`, expected true, false, or [start, end]",
        ),
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\ncaps = [true]\n",
            "s.toml:4:8: invalid length 1, expected an array of 2 elements",
        ),
        (
            "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\n",
            "s.toml:1:1: missing field `major_radius`",
        ),
        ("[[cylinder]\n", "s.toml:1:"),
        ("[cylinder]\nbezier = 1\n", "s.toml:"),
    ];
    expect_errors(cases);
}

#[test]
fn second_cylinder_is_named() {
    let src = format!(
        "{GOOD}{GOOD}\n[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.0]\n"
    );
    assert!(err(&src).ends_with("(cylinder 2)"), "{}", err(&src));
    assert!(err(&src).starts_with("s.toml:10:16:"), "{}", err(&src));
}

#[test]
fn garbage_bytes_are_an_error() {
    let e = SceneDescription::parse_bytes(b"[[cylinder]]\n\xff\xfe", "s.toml").unwrap_err();
    assert_eq!(
        e.to_string(),
        "s.toml:2:1: the file is not valid UTF-8 text",
        "{e}"
    );
    let e = SceneDescription::parse_bytes(b"\x00\x01\x02", "s.toml").unwrap_err();
    assert!(e.to_string().starts_with("s.toml:1:"), "{e}");
}

const FULL: &str = r#"
[render]
integrator = "xray"
spp = 3
max_depth = 5
seed = 9

[camera]
type = "orthographic"
position = [0, 0, 5]
look_at = [0, 0, 0]
view_height = 2
resolution = [64, 32]

[[light]]
type = "directional"
direction = [0, -2, 0]
irradiance = [1, 0.5, 0.25]

[[light]]
type = "point"
position = [1, 2, 3]
intensity = 4

[environment]
top = 1
bottom = [0, 0, 0.1]

[material.glass]
type = "dielectric"
eta = 1.5
sigma_a = [0.1, 0.2, 0.3]
xray_mu = 2.5

[material.kk]
type = "kajiya_kay"
exponent = 12

[[cylinder]]
bezier = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]
major_radius = [0.1, 0.1]
material = "glass"
transform = { scale = 2, rotate = [0, 0, 1, 90], translate = [1, 0, 0] }

[[strand]]
control_points = [[0, 0, 0], [0, 1, 0], [0.5, 2, 0], [0, 3, 0.5]]
radius = [0.05, 0.02]
material = "kk"

[[sphere]]
center = [0, -1, 0]
radius = 0.5
transform = { translate = [0, 0, 1] }

[[plane]]
point = [0, -2, 0]
normal = [0, 3, 0]
"#;

#[test]
fn every_table_parses_and_transforms_apply() {
    let d = SceneDescription::parse(FULL, "s.toml").unwrap();
    assert_eq!(
        d.render,
        RenderTable {
            integrator: Some(Integrator::Xray),
            spp: Some(3),
            max_depth: Some(5),
            seed: Some(9)
        },
        "render table"
    );
    let cam = d.camera.unwrap();
    assert_eq!(
        cam.projection,
        Projection::Orthographic { height: 2.0 },
        "camera"
    );
    assert_eq!((cam.width, cam.height), (64, 32), "resolution");
    assert_eq!(d.lights.len(), 2, "lights");
    assert_eq!(
        d.lights[0],
        Light::Directional {
            direction: -DVec3::Y,
            irradiance: DVec3::new(1.0, 0.5, 0.25)
        },
        "directional light, direction normalized"
    );
    assert!(
        matches!(d.environment, Some(Environment::Gradient { .. })),
        "sky"
    );
    // Cylinder 0: scaled by 2, turned 90 degrees about z, moved by +x: the axis from
    // (1, 0, 0) to (1, 6, 0), radius 0.2.
    let c = &d.cylinders[0];
    assert!(
        (c.axis().point(1.0) - DVec3::new(1.0, 6.0, 0.0)).length() < 1e-12,
        "moved"
    );
    assert_eq!(c.sweep().major, [0.2, 0.2], "scaled radius");
    assert_eq!(d.cylinders.len(), 1 + 3, "the strand's 3 segments follow");
    let name = |i: u32| d.materials[i as usize].name.as_str();
    assert_eq!(name(d.cylinder_materials[0]), "glass", "cylinder material");
    assert_eq!(name(d.cylinder_materials[3]), "kk", "strand material");
    let glass = &d.materials[d.cylinder_materials[0] as usize];
    assert_eq!(glass.xray_mu, vec![2.5], "xray_mu");
    assert_eq!(
        d.spheres[0].0.center,
        DVec3::new(0.0, -1.0, 1.0),
        "sphere moved"
    );
    assert_eq!(
        name(d.spheres[0].1),
        SURFACE_MATERIAL,
        "default surface material"
    );
    assert_eq!(d.planes[0].0.normal, DVec3::Y, "plane normal normalized");
    // The strand's control points are B-spline control points: it starts at the first.
    assert!(
        d.cylinders[1].axis().point(0.0).length() < 1e-15,
        "strand root"
    );
}

#[test]
fn strand_points_are_interpolated() {
    let src = "[[strand]]\npoints = [[0, 0, 0], [0, 1, 0], [0.5, 2, 0], [0, 3, 0.5]]\nradius = [0.05, 0.02]\n";
    let d = SceneDescription::parse(src, "s.toml").unwrap();
    let want = [[0.0, 1.0, 0.0], [0.5, 2.0, 0.0], [0.0, 3.0, 0.5]];
    for (c, w) in d.cylinders.iter().zip(want) {
        let end = c.axis().point(1.0);
        assert!(
            (end - DVec3::from_array(w)).length() < 1e-12,
            "passes through {w:?}: {end}"
        );
    }
    assert_eq!(d.cylinders[0].caps(), [true, false], "root cap only");
    assert_eq!(d.cylinders[2].caps(), [false, true], "tip cap only");
    let major = d.cylinders[1].sweep().major;
    assert!(
        (major[0] - 0.04).abs() < 1e-15 && (major[1] - 0.03).abs() < 1e-15,
        "radius tapers linearly root to tip: {major:?}"
    );
}

#[test]
fn appearance_errors_are_located() {
    let strand = "[[strand]]\npoints = [[0, 0, 0], [0, 1, 0]]\nradius = [0.05, 0.02]\n";
    let cases: &[(String, &str)] = &[
        (
            "[[light]]\ntype = \"laser\"\n".into(),
            "s.toml:2:8: unknown light type `laser`",
        ),
        (
            "[[light]]\ntype = \"point\"\nposition = [0, 0, 0]\nintensity = 1\nradius = 2\n".into(),
            "s.toml:5:10: `radius` does not apply to a point light",
        ),
        (
            "[[light]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradiance = 1\n".into(),
            "s.toml:1:1: a sphere light needs `radius`",
        ),
        (
            "[[light]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = -1\nradiance = 1\n".into(),
            "s.toml:4:10: radius must be positive and at most 1e15, got -1",
        ),
        (
            "[[light]]\ntype = \"point\"\nposition = [0, 0, 0]\nintensity = [1, -1, 1]\n".into(),
            "s.toml:4:13: intensity must be finite and non-negative",
        ),
        (
            "[environment]\ncolor = 1\ntop = 1\n".into(),
            "s.toml:1:1: an environment has either",
        ),
        (
            "[material.m]\ntype = \"diffuse\"\neta = 1.5\n".into(),
            "s.toml:3:7: `eta` does not apply to a diffuse material",
        ),
        (
            "[material.m]\ntype = \"diffuse\"\nalbedo = 2\n".into(),
            "s.toml:1:1: albedo must be finite and in [0, 1]",
        ),
        (
            "[material.m]\ntype = \"hair\"\nbeta_m = 0\n".into(),
            "s.toml:3:10: beta_m must be in (0, 1], got 0",
        ),
        (
            "[material.m]\ntype = \"hair\"\nmelanin = 1\ncolor = 0.5\n".into(),
            "s.toml:1:1: a hair material takes one of",
        ),
        (
            "[material.m]\ntype = \"velvet\"\n".into(),
            "s.toml:2:8: unknown material type `velvet`",
        ),
        (
            format!("{strand}material = \"nope\"\n"),
            "s.toml:4:12: unknown material `nope` (defined: fiber, surface)",
        ),
        (
            "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, 1]\nfov = 200\n".into(),
            "s.toml:4:7: fov must be in (0, 179], got 200",
        ),
        (
            "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 1, 0]\n".into(),
            "s.toml:1:1: camera up is parallel to the view direction",
        ),
        (
            "[camera]\ntype = \"orthographic\"\nposition = [0, 0, 0]\nlook_at = [0, 0, 1]\n".into(),
            "s.toml:1:1: an orthographic camera needs `view_height`",
        ),
        (
            "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, 1]\nresolution = [0, 10]\n".into(),
            "s.toml:4:14: resolution must be 1 to 65536",
        ),
        (
            "[render]\nintegrator = \"magic\"\n".into(),
            "s.toml:2:14: unknown integrator `magic`",
        ),
        (
            "[render]\nspp = 0\n".into(),
            "s.toml:2:7: spp must be at least 1",
        ),
        (
            "[[strand]]\nradius = [0.05, 0.02]\n".into(),
            "s.toml:1:1: a strand needs `points` or `control_points`",
        ),
        (
            "[[strand]]\npoints = [[0, 0, 0], [0, 0, 0]]\nradius = [0.05, 0.02]\n".into(),
            "s.toml:2:10: point 1 repeats point 0 (strand 0)",
        ),
        (
            "[[strand]]\npoints = [[0, 0, 0]]\nradius = [0.05, 0.02]\n".into(),
            "s.toml:2:10: a strand needs at least 2 points",
        ),
        (
            "[[strand]]\npoints = [[0, 0, 0], [0, 1, nan]]\nradius = [0.05, 0.02]\n".into(),
            "s.toml:2:10: point 1 is not finite",
        ),
        (
            "[[strand]]\npoints = [[0, 0, 0], [0, 1, 0]]\nradius = [0.05, 0]\n".into(),
            "s.toml:3:10: radius must be positive and finite at root and tip",
        ),
        (
            format!("{strand}ellipticity = 1.5\n"),
            "s.toml:4:15: ellipticity must be in (0, 1], got 1.5",
        ),
        (
            format!("{strand}transform = {{ scale = 0 }}\n"),
            "s.toml:4:23: transform scale must be positive and at most 1e15, got 0",
        ),
        (
            format!("{strand}transform = {{ rotate = [0, 0, 0, 30] }}\n"),
            "s.toml:4:24: transform rotate must be [axis x, y, z, degrees]",
        ),
        (
            "[[hair]]\nfile = \"no/such/file.hair\"\n".into(),
            "s.toml:2:8: cannot read no/such/file.hair:",
        ),
        (
            "[[sphere]]\ncenter = [0, 0, 0]\nradius = 0\n".into(),
            "s.toml:3:10: radius must be positive and at most 1e15, got 0",
        ),
        (
            "[[plane]]\npoint = [0, 0, 0]\nnormal = [0, 0, 0]\n".into(),
            "s.toml:3:10: normal must not be zero",
        ),
    ];
    expect_errors(cases);
}

#[test]
fn hair_files_in_scenes_are_read_relative_to_the_scene() {
    let dir = std::env::temp_dir().join(format!("gencyl-hair-scene-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("models")).unwrap();
    let strands = vec![
        vec![
            DVec3::ZERO,
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(0.3, 2.0, 0.0),
        ],
        vec![DVec3::X, DVec3::new(1.0, 1.0, 0.2)],
    ];
    let bytes = crate::formats::hair::write_hair(&strands, None, "two strands");
    std::fs::write(dir.join("models/two.hair"), &bytes).unwrap();
    std::fs::write(dir.join("models/cut.hair"), &bytes[..bytes.len() - 3]).unwrap();
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        "[[hair]]\nfile = \"models/two.hair\"\nradius = 0.01\nellipticity = 0.5\n",
    )
    .unwrap();
    let d = SceneDescription::load(&scene).unwrap();
    assert_eq!(d.cylinders.len(), 3, "2 + 1 segments");
    assert_eq!(
        d.cylinders[0].sweep().minor,
        [0.005, 0.005],
        "ellipticity applied"
    );
    let end = d.cylinders[1].axis().point(1.0);
    assert!(
        (end - DVec3::new(0.3, 2.0, 0.0)).length() < 1e-6,
        "through the file's points"
    );
    std::fs::write(&scene, "\n[[hair]]\nfile = \"models/cut.hair\"\n").unwrap();
    let e = SceneDescription::load(&scene).unwrap_err().to_string();
    assert!(
        e.contains("scene.toml:3:8: models/cut.hair: ") && e.contains("truncated"),
        "{e}"
    );
    // A profile: every strand's section; a bad one is an error at the key's value.
    let lobes = "[[1, 0], [1, 0.35], [0.55, 0.55], [-0.5, 0.87], [-0.45, 0.45], [-0.5, 0], \
                 [-0.5, -0.87], [0.1, -0.75], [0.55, -0.55]]";
    std::fs::write(
        &scene,
        format!("[[hair]]\nfile = \"models/two.hair\"\nradius = 0.01\nprofile = {lobes}\n"),
    )
    .unwrap();
    let d = SceneDescription::load(&scene).unwrap();
    assert_eq!(d.cylinders.len(), 3, "2 + 1 segments");
    for c in &d.cylinders {
        let Section::Loop(l) = c.section() else {
            panic!("a profiled strand: {:?}", c.section())
        };
        assert_eq!(l.pieces().len(), 3, "three pieces");
    }
    std::fs::write(
        &scene,
        "[[hair]]\nfile = \"models/two.hair\"\nprofile = [[1, 0], [0, 1]]\n",
    )
    .unwrap();
    let e = SceneDescription::load(&scene).unwrap_err().to_string();
    assert!(
        e.contains("scene.toml:3:11: bad profile: a profile needs 3k points"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A strand's `frame` key: without it (or with `"minimal"`, `"rmf"`, ...) the segments get the
/// rotation-minimising framing (projection frames, twist folded into the sweep's rotation), with
/// `"frenet"` the Frenet frames of interface.md (as `[[cylinder]]` tables always do), the same
/// in a `[[hair]]` table; any other value is an error at the value.
#[test]
fn strand_frame_key_chooses_the_framing() {
    let strand = "[[strand]]\npoints = [[0, 0, 0], [0, 1, 0.2], [0.5, 2, 0], [0, 3, 0.5]]\nradius = [0.05, 0.02]\nellipticity = 0.5\n";
    let framings = |src: &str| -> Vec<gencyl::Framing> {
        SceneDescription::parse(src, "s.toml")
            .unwrap()
            .cylinders
            .iter()
            .map(|c| c.framing().clone())
            .collect()
    };
    let projected = |f: &[gencyl::Framing]| {
        f.len() == 3 && f.iter().all(|f| matches!(f, gencyl::Framing::Projected(_)))
    };
    assert!(projected(&framings(strand)), "default: rotation-minimising");
    for name in [
        "minimal",
        "rotation-minimizing",
        "rotation-minimising",
        "rmf",
    ] {
        let f = framings(&format!("{strand}frame = \"{name}\"\n"));
        assert!(projected(&f), "frame = {name:?}: {f:?}");
    }
    assert_eq!(
        framings(&format!("{strand}frame = \"frenet\"\n")),
        vec![gencyl::Framing::Frenet; 3],
        "frame = \"frenet\""
    );
    expect_errors(&[(
        format!("{strand}frame = \"bishop\"\n"),
        "s.toml:5:9: frame must be \"minimal\" or \"frenet\", got \"bishop\"",
    )]);

    let dir = std::env::temp_dir().join(format!("gencyl-hair-frame-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let strands = vec![vec![
        DVec3::ZERO,
        DVec3::new(0.0, 1.0, 0.2),
        DVec3::new(0.3, 2.0, 0.0),
    ]];
    let bytes = crate::formats::hair::write_hair(&strands, None, "one strand");
    std::fs::write(dir.join("one.hair"), &bytes).unwrap();
    let scene = dir.join("scene.toml");
    for (frame, want_projected) in [("", true), ("frame = \"frenet\"\n", false)] {
        std::fs::write(
            &scene,
            format!("[[hair]]\nfile = \"one.hair\"\nradius = 0.01\nellipticity = 0.5\n{frame}"),
        )
        .unwrap();
        let d = SceneDescription::load(&scene).unwrap();
        assert_eq!(d.cylinders.len(), 2, "two segments");
        assert!(
            d.cylinders
                .iter()
                .all(|c| matches!(c.framing(), gencyl::Framing::Projected(_)) == want_projected),
            "hair file with {frame:?}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `section = "exact"`: its values and errors, and the tables it builds from the fibers.
#[test]
fn exact_hair_sections_are_checked_and_tabulated() {
    let strand =
        "[[strand]]\npoints = [[0, 0, 0], [0, 1, 0]]\nradius = [0.05, 0.05]\nmaterial = \"m\"\n";
    let loop_strand = format!(
        "{strand}profile = [[1, 0], [1, 0.5], [0.5, 1], [0, 1], [-0.5, 1], [-1, 0.5], [-1, 0], [-1, -0.5], [-0.5, -1], [0, -1], [0.5, -1], [1, -0.5]]\n"
    );
    let cases: &[(String, &str)] = &[
        (
            "[material.m]\ntype = \"hair\"\nsection = \"round\"\n".into(),
            "s.toml:3:11: section must be \"circular\" or \"exact\", got \"round\"",
        ),
        (
            "[material.m]\ntype = \"diffuse\"\nsection = \"exact\"\n".into(),
            "s.toml:3:11: `section` does not apply to a diffuse material",
        ),
        (
            "[material.m]\ntype = \"hair\"\nsection = \"exact\"\neta = 20\n".into(),
            "s.toml:1:1: section = \"exact\" needs eta in (1, 10], got 20",
        ),
        (
            format!("{strand}{loop_strand}[material.m]\ntype = \"hair\"\nsection = \"exact\"\n"),
            "s.toml:10:1: material `m` has section = \"exact\" and is used by fibers of different section shapes",
        ),
    ];
    expect_errors(cases);
    // Round strands: one table at aspect 1; `circular` is Chiang's model.
    let round =
        format!("{strand}[material.m]\ntype = \"hair\"\nsection = \"exact\"\nsigma_a = 0.3\n");
    let d = SceneDescription::parse(&round, "s.toml").unwrap();
    let m = d.materials.iter().find(|m| m.name == "m").unwrap();
    match &m.material {
        Material::ExactHair {
            tables: Some(t), ..
        } => {
            assert_eq!(t.nodes.len(), 1);
            assert_eq!(t.nodes[0].0, 1.0);
        }
        other => panic!("{other:?}"),
    }
    let chiang = SceneDescription::parse(
        &format!("{strand}[material.m]\ntype = \"hair\"\nsection = \"circular\"\n"),
        "s.toml",
    )
    .unwrap();
    assert!(matches!(
        chiang
            .materials
            .iter()
            .find(|m| m.name == "m")
            .unwrap()
            .material,
        Material::Hair(_)
    ));
}

/// A long text of cylinder tables in many spellings after a preamble: `n` tables.
fn long_cylinder_text(n: usize, crlf: bool) -> String {
    let mut s = String::from(
        "# preamble\n[camera]\nposition = [0, 0, -10]\nlook_at = [0, 0, 0]\n\n\
         [material.red]\ntype = \"diffuse\"\nalbedo = 0.5\n\n",
    );
    for i in 0..n {
        let x = i as f64 * 0.37;
        let header = match i % 5 {
            0 => "[[cylinder]]\n".to_string(),
            1 => "[[cylinder]]   # a comment\n".to_string(),
            2 => "[[cylinder]]\t\n".to_string(),
            // Not cut here (indented): it stays in the piece before.
            3 => "  [[cylinder]]\n".to_string(),
            _ => "\n[[cylinder]]\n".to_string(),
        };
        s += &header;
        s += &format!(
            "bezier = [[{x},0,0],[{},0.2,0],[{},-0.1,0.3],[{},0,0]]\nmajor_radius = [0.05, {}]\n",
            x + 1.0,
            x + 2.0,
            x + 3.0,
            0.04 + 1e-3 * (i % 7) as f64
        );
        match i % 4 {
            0 => s += "caps = [true, false]\nrotation = [0.1, 0.2]\n",
            1 => s += "minor_radius = [0.02, 0.03]\nmaterial = \"red\"\n",
            2 => s += "[cylinder.transform]\ntranslate = [0, 1, 2]\n",
            _ => s += "caps = false\n",
        }
    }
    if crlf { s.replace('\n', "\r\n") } else { s }
}

/// Debug text of what a scene holds, to compare two parses bit for bit.
fn summary(s: &SceneDescription) -> String {
    format!(
        "{:?} {:?} {:?} {:?}",
        s.cylinders, s.cylinder_materials, s.camera, s.materials
    )
}

/// Long cylinder files parse in pieces (the fast path is taken) to exactly what the whole
/// text gives.
#[test]
fn long_cylinder_files_parse_in_pieces_as_a_whole() {
    for crlf in [false, true] {
        let src = long_cylinder_text(20_000, crlf);
        assert!(src.len() > 2 * SPLIT_MIN, "long enough: {}", src.len());
        let whole = SceneDescription::parse_whole(&src, "s.toml", Path::new("")).unwrap();
        let split = parse_split(&src, Path::new("")).expect("the split parse applies");
        assert_eq!(split.cylinders.len(), 20_000);
        assert_eq!(summary(&split), summary(&whole), "crlf {crlf}");
        let via = SceneDescription::parse(&src, "s.toml").unwrap();
        assert_eq!(summary(&via), summary(&whole));
    }
    // A file of cylinders alone, from its first byte (as a generator writes it).
    let src = long_cylinder_text(20_000, false).replace("material = \"red\"\n", "");
    let src = &src[src.find("[[cylinder]]").unwrap()..];
    let split = parse_split(src, Path::new("")).expect("the split parse applies");
    let whole = SceneDescription::parse_whole(src, "s.toml", Path::new("")).unwrap();
    assert_eq!(split.cylinders.len(), 20_000);
    assert_eq!(summary(&split), summary(&whole), "cylinders alone");
}

/// Where pieces could mean something else than the whole, or anything is wrong, the split
/// parse declines, and the whole text's answer (and message) stands.
#[test]
fn the_split_parse_declines_what_it_cannot_vouch_for() {
    let body = long_cylinder_text(12_000, false);
    let tail_start = body.find("\n[[cylinder]]").unwrap() + 1;
    let (pre, tail) = body.split_at(tail_start);
    let cases: Vec<(String, &str)> = vec![
        // Static array of cylinders extended by headers: not valid TOML.
        (
            format!(
                "{pre}cylinder = [{{bezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]], major_radius = [0.1, 0.1]}}]\n{tail}"
            ),
            "invalid",
        ),
        // A later table other than cylinders (a second camera): a duplicate in the whole.
        (
            format!("{body}\n[camera]\nposition = [1, 1, 1]\n"),
            "invalid",
        ),
        // A cylinder that fails to build, far in.
        (
            format!(
                "{body}[[cylinder]]\nbezier = [[0,0,0],[0,0,0],[0,0,0],[0,0,0]]\nmajor_radius = [0.1, 0.1]\n{body_tail}",
                body_tail = "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\n"
            ),
            "invalid",
        ),
        // A header line inside a multi-line string: cut there, the piece before is unterminated.
        (
            format!(
                "{pre}[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\nmaterial = \"\"\"\n[[cylinder]]\n\"\"\"\n{tail}"
            ),
            "invalid",
        ),
    ];
    for (i, (src, _)) in cases.iter().enumerate() {
        assert!(src.len() > SPLIT_MIN);
        assert!(
            parse_split(src, Path::new("")).is_none(),
            "case {i}: split parse applied"
        );
        let whole = SceneDescription::parse_whole(src, "s.toml", Path::new(""));
        let via = SceneDescription::parse(src, "s.toml");
        match (whole, via) {
            (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string(), "case {i}"),
            (a, b) => panic!("case {i}: whole {:?}, parse {:?}", a.is_ok(), b.is_ok()),
        }
    }
}
