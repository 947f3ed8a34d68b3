//! End-to-end tests of the `gencyl` binary: `gencyl raycast` against interface.md section 3.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use gencyl_render::scenes::synth::{FiberParams, random_fibers, random_rays, rays_csv, scene_toml};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// A scratch file under the target directory, unique to `name`.
fn scratch(name: &str, contents: &[u8]) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("gencyl-cli-tests");
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, contents).unwrap();
    p
}

/// Runs `gencyl` with `args`, feeding `stdin` if given.
fn gencyl(args: &[&str], stdin: Option<&[u8]>) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_gencyl"))
        .args(args)
        .stdin(if stdin.is_some() {
            Stdio::piped()
        } else {
            Stdio::null()
        })
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("gencyl runs");
    if let Some(input) = stdin {
        let mut pipe = child.stdin.take().unwrap();
        let input = input.to_vec();
        // Write from a thread so a large input cannot deadlock against a full stdout pipe.
        std::thread::spawn(move || {
            let _ = pipe.write_all(&input);
        });
    }
    child.wait_with_output().expect("gencyl finishes")
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Runs a command that must succeed; returns standard output.
fn ok(args: &[&str], stdin: Option<&[u8]>) -> String {
    let out = gencyl(args, stdin);
    assert!(
        out.status.success(),
        "gencyl {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("UTF-8 output")
}

/// The rows of a hit CSV as numbers (`None` for `*`), after checking the header.
fn rows(csv: &str) -> Vec<Vec<Option<f64>>> {
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("ray,t,u,v,nx,ny,nz,object,part"),
        "header of {csv}"
    );
    lines
        .map(|l| {
            let r: Vec<Option<f64>> = l
                .split(',')
                .map(|x| {
                    if x == "*" {
                        None
                    } else {
                        Some(x.parse().expect("a number"))
                    }
                })
                .collect();
            assert_eq!(r.len(), 9, "row {l}");
            r
        })
        .collect()
}

/// Compares rows: integers exactly, floats to 1e-9 (the example's values are exact; the
/// solver is accurate to a few ulps), `*` in `want` matching anything.
fn assert_rows(got: &str, want: &str) {
    let (g, w) = (rows(got), rows(want));
    assert_eq!(g.len(), w.len(), "row count\n got:\n{got}\nwant:\n{want}");
    for (gr, wr) in g.iter().zip(&w) {
        for (i, (x, y)) in gr.iter().zip(wr).enumerate() {
            if let (Some(x), Some(y)) = (x, y) {
                let tol = if [0, 7, 8].contains(&i) { 0.0 } else { 1e-9 };
                assert!(
                    (x - y).abs() <= tol,
                    "column {i}: {x} vs {y}\n got:\n{got}\nwant:\n{want}"
                );
            }
        }
    }
}

fn straight() -> (PathBuf, PathBuf) {
    (
        data("straight-cylinder.toml"),
        data("straight-cylinder.rays.csv"),
    )
}

#[test]
fn straight_cylinder_matches_expected() {
    let (scene, rays) = straight();
    let got = ok(&["raycast", path(&scene), path(&rays)], None);
    let want = std::fs::read_to_string(data("straight-cylinder.expected.csv")).unwrap();
    assert_rows(&got, &want);
    // v is in [0, 2 pi) and normals are unit length.
    for r in rows(&got) {
        let v = r[3].unwrap();
        assert!((0.0..std::f64::consts::TAU).contains(&v), "v = {v}");
        let n = (r[4].unwrap().powi(2) + r[5].unwrap().powi(2) + r[6].unwrap().powi(2)).sqrt();
        assert!((n - 1.0).abs() < 1e-12, "|n| = {n}");
    }
}

/// `raycast --stats` reports the queries: one a ray, and the share that hit is the rows'
/// (one row a hit); `render --stats` reports its rays too. A build without the counting
/// (`--features stats`) says how to get them.
#[test]
fn stats_report_the_queries() {
    let counted = cfg!(feature = "stats");
    let not_counted = "queries: not counted in this build (cargo build --release --features stats)";
    let (scene, rays) = straight();
    let out = gencyl(&["raycast", "--stats", path(&scene), path(&rays)], None);
    assert!(out.status.success());
    let hits = String::from_utf8(out.stdout).unwrap().lines().count() - 1;
    let err = String::from_utf8(out.stderr).unwrap();
    let rays = 5;
    let want = if counted {
        format!(
            "queries: {rays} nearest-hit ({:.1}% hit)",
            100.0 * hits as f64 / rays as f64
        )
    } else {
        not_counted.to_string()
    };
    assert!(err.lines().any(|l| l == want), "{want:?} in\n{err}");
    assert_eq!(err.contains("per query: "), counted, "{err}");
    let image = std::env::temp_dir().join(format!("gencyl-stats-{}.png", std::process::id()));
    let out = gencyl(
        &[
            "render",
            "--stats",
            "-q",
            "--width",
            "24",
            "--spp",
            "1",
            "-o",
            path(&image),
        ],
        None,
    );
    let _ = std::fs::remove_file(&image);
    assert!(out.status.success());
    let err = String::from_utf8(out.stderr).unwrap();
    let queries = err
        .lines()
        .find_map(|l| l.strip_prefix("queries: "))
        .unwrap_or_else(|| panic!("no queries line in\n{err}"));
    if counted {
        let camera_rays = 24 * 18;
        let nearest: u64 = queries.split(' ').next().unwrap().parse().unwrap();
        assert!(
            nearest >= camera_rays,
            "{queries}: a nearest-hit query a camera ray at least"
        );
        assert!(queries.contains("any-hit"), "shadow rays: {queries}");
    } else {
        assert_eq!(format!("queries: {queries}"), not_counted);
    }
}

#[test]
fn all_gives_entry_and_exit_sorted_by_t() {
    let (scene, rays) = straight();
    let got = ok(&["raycast", "--all", path(&scene), path(&rays)], None);
    // Ray 0 enters the side at z = 0.1 and leaves at z = -0.1; ray 2 enters the start cap and
    // leaves through the end cap; ray 3 starts inside; ray 4 crosses the side twice.
    let want = "ray,t,u,v,nx,ny,nz,object,part\n\
        0,0.9,0.5,*,0,0,1,0,0\n\
        0,1.1,0.5,*,0,0,-1,0,0\n\
        2,1,0,*,-1,0,0,0,1\n\
        2,4,1,*,1,0,0,0,2\n\
        3,1.5,1,*,1,0,0,0,2\n\
        4,0.45,0.65,*,0,0,1,0,0\n\
        4,0.55,0.683333333333333333,*,0,0,-1,0,0\n";
    assert_rows(&got, want);
    let r = rows(&got);
    for w in r.windows(2) {
        if w[0][0] == w[1][0] {
            assert!(w[0][1] < w[1][1], "rows of a ray sorted by t: {w:?}");
        }
    }
}

#[test]
fn tmin_drops_nearer_hits() {
    let (scene, rays) = straight();
    let got = ok(
        &["raycast", "--tmin", "1.0", path(&scene), path(&rays)],
        None,
    );
    // t > tmin strictly: ray 2's cap hit at exactly t = 1 no longer counts.
    let want = "ray,t,u,v,nx,ny,nz,object,part\n\
        0,1.1,0.5,*,0,0,-1,0,0\n\
        2,4,1,*,1,0,0,0,2\n\
        3,1.5,1,*,1,0,0,0,2\n";
    assert_rows(&got, want);
    // A negative tmin sees behind the origin: ray 3 left the start cap at t = -1.5.
    let got = ok(
        &["raycast", "--tmin", "-10", path(&scene), path(&rays)],
        None,
    );
    let r = rows(&got);
    let ray3 = r.iter().find(|r| r[0] == Some(3.0)).unwrap();
    assert_eq!((ray3[1], ray3[8]), (Some(-1.5), Some(1.0)), "{got}");
    let got2 = ok(&["raycast", "--tmin=-10", path(&scene), path(&rays)], None);
    assert_eq!(got, got2, "--tmin=-10 and --tmin -10");
}

/// `--tmin=-inf` takes the whole line, as a very negative finite `tmin` does, on a scene whose
/// BVH has empty slots and rays running toward negative coordinates (the box test once entered
/// the empty slots of such rays, and the walk panicked).
#[test]
fn tmin_of_minus_infinity_takes_the_whole_line() {
    // Sixty bent fibers in rows of eight (a BVH with empty slots in its nodes).
    let mut scene = String::new();
    for i in 0..60 {
        let (x, z) = ((i % 8) as f64 * 0.5, (i / 8) as f64 * 0.4);
        let (a, b, c, e) = (x + 0.05, x - 0.05, z + 0.1, z - 0.1);
        scene += &format!(
            "[[cylinder]]\nbezier = [[{x}, 0, {z}], [{a}, 0.3, {c}], [{b}, 0.6, {e}], [{x}, 1, {z}]]\n\
             major_radius = [0.1, 0.1]\n\n"
        );
    }
    let scene = scratch("tmin-inf.toml", scene.as_bytes());
    // Down through the grid and along it, toward negative coordinates.
    let mut rays = String::from("ox,oy,oz,dx,dy,dz\n");
    for i in 0..40 {
        let t = i as f64 / 40.0;
        let (x, y, dx) = (3.5 - 3.5 * t, 0.5 + 0.3 * t, -0.3 + 0.2 * t);
        rays += &format!("{x},{y},4,{dx},-0.1,-1\n");
        rays += &format!("5,{t},{},-1,0,{}\n", 3.0 * t, 0.01 - 0.02 * t);
    }
    let rays = scratch("tmin-inf.csv", rays.as_bytes());
    for all in [false, true] {
        let args = |tmin: &'static str| {
            let mut a = vec!["raycast", tmin, path(&scene), path(&rays)];
            if all {
                a.insert(1, "--all");
            }
            a
        };
        let whole = ok(&args("--tmin=-inf"), None);
        assert_eq!(whole, ok(&args("--tmin=-1e300"), None), "all: {all}");
        assert!(
            rows(&whole).len() > 40,
            "the rays cross the fibers: {whole}"
        );
    }
}

#[test]
fn dash_reads_standard_input() {
    let (scene, rays) = straight();
    let text = std::fs::read(&rays).unwrap();
    let from_file = ok(&["raycast", path(&scene), path(&rays)], None);
    let from_stdin = ok(&["raycast", path(&scene), "-"], Some(&text));
    assert_eq!(from_file, from_stdin, "file and stdin");
}

#[test]
fn empty_scene_and_empty_rays() {
    let (scene, rays) = straight();
    let empty = scratch("empty.toml", b"");
    assert_eq!(
        ok(&["raycast", path(&empty), path(&rays)], None),
        "ray,t,u,v,nx,ny,nz,object,part\n",
        "no cylinder"
    );
    let no_rays = scratch("empty.csv", b"# nothing\n\n");
    assert_eq!(
        ok(&["raycast", path(&scene), path(&no_rays)], None),
        "ray,t,u,v,nx,ny,nz,object,part\n",
        "no ray"
    );
}

#[test]
fn thread_counts_give_identical_output() {
    let params = FiberParams {
        count: 200,
        elliptical_fraction: 0.05,
        ..FiberParams::default()
    };
    let scene = scratch(
        "random200.toml",
        scene_toml(&random_fibers(&params, 42)).as_bytes(),
    );
    let rays = scratch(
        "random2000.csv",
        rays_csv(&random_rays(2000, 43, &params)).as_bytes(),
    );
    for all in [false, true] {
        let mut args = vec!["raycast", path(&scene), path(&rays)];
        if all {
            args.push("--all");
        }
        let one = ok(&[&args[..], &["--threads", "1"]].concat(), None);
        let two = ok(&[&args[..], &["--threads", "2"]].concat(), None);
        let default = ok(&args, None);
        assert_eq!(one, two, "--threads 1 vs 2 (all = {all})");
        assert_eq!(one, default, "--threads 1 vs default (all = {all})");
        let n = rows(&one).len();
        assert!(n > 300, "a meaningful number of hits: {n} (all = {all})");
        // Rows in ray order, and with --all, by t within a ray.
        let r = rows(&one);
        for w in r.windows(2) {
            assert!(
                w[0][0] < w[1][0] || (all && w[0][0] == w[1][0] && w[0][1] <= w[1][1]),
                "order: {w:?}"
            );
        }
    }
}

#[test]
fn many_rays_stream() {
    // 200,000 rays through standard input.
    let (scene, _) = straight();
    let mut text = String::from("ox,oy,oz,dx,dy,dz\n");
    for i in 0..200_000 {
        let x = (i % 1000) as f64 * 0.003;
        text.push_str(&format!("{x},0,1,0,0,-1\n"));
    }
    let got = ok(&["raycast", path(&scene), "-"], Some(text.as_bytes()));
    // x in [0, 3) always hits the side at t = 0.9.
    assert_eq!(got.lines().count(), 200_001, "one row per ray");
    assert!(
        got.lines().nth(200_000).unwrap().starts_with("199999,0.9,"),
        "last row"
    );
}

/// Runs a command that must fail without output; returns its message.
fn fails(args: &[&str], stdin: Option<&[u8]>) -> String {
    let out = gencyl(args, stdin);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        !out.status.success(),
        "gencyl {args:?} succeeded; stdout: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(
        out.stdout.is_empty(),
        "gencyl {args:?} wrote to stdout: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(!err.contains("panicked"), "gencyl {args:?} panicked: {err}");
    err
}

const AXIS: &str = "bezier = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]";

#[test]
fn bad_scenes_name_file_and_line() {
    let (_, rays) = straight();
    let cases: &[(&str, String, &str)] = &[
        ("unknown-key", format!("[[cylinder]]\n{AXIS}\nmajor_radius = [0.1, 0.1]\ncolour = \"red\"\n"), ":4:1: unknown field `colour`"),
        ("unknown-table", "[lighting]\nfov = 40\n".to_string(), ":1:2: unknown field `lighting`"),
        ("three-radii", format!("[[cylinder]]\n{AXIS}\nmajor_radius = [0.1, 0.1, 0.1]\n"), ":3:16: invalid length 3"),
        ("five-points", "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0],[4,0,0]]\nmajor_radius = [0.1, 0.1]\n".to_string(), ":2:10: invalid length 5"),
        ("string-radius", format!("[[cylinder]]\n{AXIS}\nmajor_radius = \"thin\"\n"), ":3:16: invalid type: string"),
        ("nan-radius", format!("[[cylinder]]\n{AXIS}\nmajor_radius = [nan, 0.1]\n"), ":3:16: major_radius must be finite, got [NaN, 0.1]"),
        ("zero-radius", format!("[[cylinder]]\n{AXIS}\nmajor_radius = [0.0, 0.03]\n"), ":3:16: major_radius must be positive at both ends, got [0.0, 0.03]"),
        ("inf-point", "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,inf],[3,0,0]]\nmajor_radius = [0.1, 0.1]\n".to_string(), ":2:10: bezier control point 2 is not finite"),
        ("zero-length", "[[cylinder]]\nbezier = [[1,2,3],[1,2,3],[1,2,3],[1,2,3]]\nmajor_radius = [0.1, 0.1]\n".to_string(), ":2:10: the axis has zero length"),
        ("cusp", "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[0,0,0],[1,0,0]]\nmajor_radius = [0.1, 0.1]\n".to_string(), ":2:10: the axis has a cusp"),
        ("bad-profile-count", format!("[[cylinder]]\n{AXIS}\nmajor_radius = [0.1, 0.1]\nprofile = [[1, 0], [0, 1]]\n"), ":4:11: bad profile: a profile needs 3k points"),
        ("bad-profile-area", format!("[[cylinder]]\n{AXIS}\nmajor_radius = [0.1, 0.1]\nprofile = [[1, 0], [2, 0], [3, 0]]\n"), ":4:11: bad profile: the profile encloses no area"),
        ("syntax", "[[cylinder]\n".to_string(), ":1:12:"),
        ("second-cylinder", format!("[[cylinder]]\n{AXIS}\nmajor_radius = [0.1, 0.1]\n\n[[cylinder]]\n{AXIS}\nmajor_radius = [0.1, -1]\n"), ":7:16: major_radius must be positive at both ends, got [0.1, -1.0] (cylinder 1)"),
    ];
    for (name, src, want) in cases {
        let file = format!("{name}.toml");
        let scene = scratch(&file, src.as_bytes());
        let err = fails(&["raycast", path(&scene), path(&rays)], None);
        let want = format!("{file}{want}");
        assert!(
            err.contains(&want),
            "{name}: message\n{err}\nshould contain\n{want}"
        );
    }
    // Bytes that are not text, and a file that is not there.
    let scene = scratch("garbage.toml", &[0x5b, 0xff, 0xfe, 0x00, 0x80, 0x0a]);
    let err = fails(&["raycast", path(&scene), path(&rays)], None);
    assert!(
        err.contains("garbage.toml:1:2: the file is not valid UTF-8 text"),
        "{err}"
    );
    let err = fails(&["raycast", "no-such-scene.toml", path(&rays)], None);
    assert!(err.contains("no-such-scene.toml: cannot read"), "{err}");
}

#[test]
fn bad_rays_name_file_and_line_and_write_nothing() {
    let (scene, _) = straight();
    let good = "ox,oy,oz,dx,dy,dz\n1.5,0,1,0,0,-1\n".repeat(3);
    let cases: &[(&str, &str, &str)] = &[
        ("five", "1,2,3,4,5\n", ":7: expected 6 numbers, found 5"),
        ("nan", "1,2,3,4,5,NaN\n", ":7: dz is not finite (NaN)"),
        ("inf", "1,2,3,4,1e999,6\n", ":7: dy is not finite (inf)"),
        (
            "zero-dir",
            "1,2,3,0,0,0\n",
            ":7: the direction (dx, dy, dz) is zero",
        ),
        ("word", "1,2,3,4,five,6\n", ":7: dy is not a number"),
        ("empty-field", "1,2,3,4,,6\n", ":7: dy is missing"),
    ];
    for (name, line, want) in cases {
        let text = format!("{good}{line}1.5,0,1,0,0,-1\n");
        let file = format!("{name}.csv");
        let rays = scratch(&file, text.as_bytes());
        let err = fails(&["raycast", path(&scene), path(&rays)], None);
        assert!(err.contains(&format!("{file}{want}")), "{name}: {err}");
        // The same from standard input.
        let err = fails(&["raycast", path(&scene), "-"], Some(text.as_bytes()));
        assert!(
            err.contains(&format!("<stdin>{want}")),
            "{name} on stdin: {err}"
        );
    }
    let rays = scratch("binary.csv", &[b'1', b',', 0xff, 0xfe, b'\n']);
    let err = fails(&["raycast", path(&scene), path(&rays)], None);
    assert!(
        err.contains("binary.csv:1: the line is not valid UTF-8 text"),
        "{err}"
    );
    let err = fails(&["raycast", path(&scene), "no-such-rays.csv"], None);
    assert!(err.contains("no-such-rays.csv: cannot read"), "{err}");
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let err = fails(&["raycast", path(&scene), path(dir)], None);
    assert!(err.contains("cannot read"), "{err}");
}

#[test]
fn bad_arguments() {
    let (scene, rays) = straight();
    for args in [
        vec!["raycast", path(&scene)],
        vec!["raycast", "--threads", "0", path(&scene), path(&rays)],
        vec!["raycast", "--tmin", "nan", path(&scene), path(&rays)],
        vec!["raycast", "--tmin", "x", path(&scene), path(&rays)],
        vec!["frobnicate"],
    ] {
        fails(&args, None);
    }
    assert!(
        ok(&["raycast", "--help"], None).contains("--threads"),
        "help"
    );
}

/// The real TressFX ponytail (data/ponytail.hair, MIT, see data/README.md) renders; a truncated
/// copy and a bad radius are errors that leave no image behind.
#[test]
fn render_a_hair_model_and_reject_broken_ones() {
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/ponytail.hair");
    let out = scratch("ponytail.png", b"");
    std::fs::remove_file(&out).unwrap();
    let run = gencyl(
        &[
            "render",
            path(&model),
            "-o",
            path(&out),
            "--width",
            "48",
            "--spp",
            "1",
        ],
        None,
    );
    assert!(
        run.status.success(),
        "render failed: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let png = std::fs::read(&out).unwrap();
    assert_eq!(&png[1..4], b"PNG", "a PNG was written");
    assert!(
        String::from_utf8_lossy(&run.stderr).contains("73995 cylinders"),
        "every segment kept"
    );

    let bytes = std::fs::read(&model).unwrap();
    let cut = scratch("cut.hair", &bytes[..bytes.len() - 5]);
    let bad_png = scratch("bad.png", b"");
    std::fs::remove_file(&bad_png).unwrap();
    let err = fails(&["render", path(&cut), "-o", path(&bad_png)], None);
    assert!(
        err.contains("cut.hair") && err.contains("truncated"),
        "message: {err}"
    );
    let err = fails(
        &[
            "render",
            path(&model),
            "--radius",
            "-1",
            "-o",
            path(&bad_png),
        ],
        None,
    );
    assert!(err.contains("--radius"), "message: {err}");
    assert!(!bad_png.exists(), "no image after an error");
}

/// Runs a command that must succeed; returns standard error (render summaries go there).
fn ok_err(args: &[&str]) -> String {
    let out = gencyl(args, None);
    assert!(
        out.status.success(),
        "gencyl {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stderr).expect("UTF-8 output")
}

/// The built-in scene renders with no arguments but the output (small, for speed).
#[test]
fn render_the_built_in_scene() {
    let out = scratch("default.png", b"");
    std::fs::remove_file(&out).unwrap();
    let log = ok_err(&[
        "render",
        "-q",
        "--width",
        "40",
        "--spp",
        "1",
        "-o",
        path(&out),
    ]);
    assert!(log.contains("40x30 (full frame)"), "summary: {log}");
    assert!(
        log.contains("624 cylinders"),
        "48 strands of 13 segments: {log}"
    );
    assert_eq!(&std::fs::read(&out).unwrap()[1..4], b"PNG", "a PNG");
}

/// Windows rendered with --crop to EXR and merged equal the whole frame rendered at once, bit
/// for bit; a generated model renders; bad crops, extensions and merges are errors that write
/// nothing.
#[test]
fn crop_merge_generate_and_their_errors() {
    let model = scratch("gen.hair", b"");
    let log = ok_err(&[
        "generate",
        "-o",
        path(&model),
        "--strands",
        "30",
        "--segments",
        "5",
    ]);
    assert!(log.contains("30 strands x 5 segments"), "{log}");
    let render = |extra: &[&str], out: &Path| {
        let mut args = vec![
            "render",
            path(&model),
            "-q",
            "--width",
            "24",
            "--spp",
            "2",
            "--integrator",
            "direct",
            "-o",
            path(out),
        ];
        args.extend_from_slice(extra);
        ok_err(&args)
    };
    let whole = scratch("whole.exr", b"");
    let log = render(&[], &whole);
    assert!(log.contains("150 cylinders"), "30 x 5 segments: {log}");
    let parts: Vec<PathBuf> = ["0,0,24,7", "0,7,10,18", "10,7,24,18"]
        .iter()
        .enumerate()
        .map(|(i, crop)| {
            let p = scratch(&format!("part{i}.exr"), b"");
            render(&["--crop", crop], &p);
            p
        })
        .collect();
    let merged = scratch("merged.exr", b"");
    let mut args = vec!["merge", "-o", path(&merged)];
    args.extend(parts.iter().map(|p| path(p)));
    ok_err(&args);
    let read = |p: &Path| gencyl_render::formats::Film::read_exr(p).unwrap();
    let (a, b) = (read(&whole), read(&merged));
    assert_eq!(a.frame, (24, 18), "frame size");
    let bits =
        |f: &gencyl_render::formats::Film| f.data.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a), bits(&b), "merged windows equal the whole frame");

    let nothing = scratch("nothing.png", b"");
    std::fs::remove_file(&nothing).unwrap();
    let err = fails(
        &[
            "render",
            path(&model),
            "--width",
            "24",
            "--crop",
            "0,0,30,5",
            "-o",
            path(&nothing),
        ],
        None,
    );
    assert!(err.contains("--crop") && err.contains("past"), "{err}");
    let err = fails(&["render", path(&model), "-o", "x.jpg"], None);
    assert!(err.contains(".png or .exr"), "{err}");
    let err = fails(
        &[
            "merge",
            "-o",
            path(&nothing),
            path(&parts[0]),
            path(&parts[0]),
        ],
        None,
    );
    assert!(err.contains("overlap"), "{err}");
    let err = fails(
        &[
            "merge",
            "-o",
            path(&nothing),
            path(&parts[0]),
            path(&parts[1]),
        ],
        None,
    );
    assert!(err.contains("not covered"), "{err}");
    let scene = scratch("missing-hair.toml", b"[[hair]]\nfile = \"nowhere.hair\"\n");
    let err = fails(&["render", path(&scene), "-o", path(&nothing)], None);
    assert!(
        err.contains("missing-hair.toml:2:8: cannot read nowhere.hair"),
        "{err}"
    );
    assert!(!nothing.exists(), "no image after an error");
}

/// The example scenes `bench` times by default, as arguments naming them from the test's
/// folder.
fn bench_scenes() -> [String; 6] {
    let example = |f: &str| {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../examples")
            .join(f)
            .to_str()
            .unwrap()
            .to_string()
    };
    [
        "--ponytail".into(),
        example("ponytail.toml"),
        "--ponytail-elliptical".into(),
        example("ponytail-elliptical.toml"),
        "--ponytail-trilobal".into(),
        example("ponytail-trilobal.toml"),
    ]
}

/// `bench` prints one CSV row per scene and thread count, with positive rates. The elliptical
/// ponytail is timed on the round one's rays: its sections lie inside the round ones, so it
/// has no more hits; the trilobal one's lobes reach about as far.
#[test]
fn bench_reports_named_scenes() {
    let scenes = bench_scenes();
    let mut args = vec!["bench", "--rays", "300"];
    args.extend(scenes.iter().map(String::as_str));
    let out = ok(&args, None);
    let rows: Vec<Vec<&str>> = out
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert!(rows.len() >= 2, "rows: {out}");
    for r in &rows {
        assert_eq!(r.len(), 11, "columns: {r:?}");
        let rate: f64 = r[9].parse().unwrap();
        assert!(rate > 0.0 && rate.is_finite(), "rays per second: {r:?}");
        let peak: f64 = r[5].parse().unwrap();
        assert!(peak > 1.0 && peak < 4096.0, "peak MiB: {r:?}");
    }
    for kind in ["camera", "incoherent"] {
        assert!(
            rows.iter().any(|r| r[0] == "ponytail" && r[6] == kind),
            "{kind}: {out}"
        );
    }
    assert!(
        rows.iter().any(|r| r[0] == "ponytail" && r[1] == "73995"),
        "{out}"
    );
    for kind in ["camera", "incoherent"] {
        let hits = |scene: &str| -> f64 {
            let r = rows
                .iter()
                .find(|r| r[0] == scene && r[6] == kind)
                .unwrap_or_else(|| panic!("{scene} {kind}: {out}"));
            assert_eq!(r[1], "73995", "{r:?}");
            r[10].parse().unwrap()
        };
        let (round, elliptical) = (hits("ponytail"), hits("ponytail-elliptical"));
        assert!(
            elliptical <= round && elliptical > 0.5 * round,
            "{kind}: hit fractions {elliptical} (elliptical) against {round}: {out}"
        );
        // The lobes reach the round fiber's radius (their control points a little beyond).
        let trilobal = hits("ponytail-trilobal");
        assert!(
            trilobal <= 1.1 * round && trilobal > 0.3 * round,
            "{kind}: hit fractions {trilobal} (trilobal) against {round}: {out}"
        );
    }
}

/// The one row of `bench` on the built-in scene's `kind` rays (200 of them) on 1 thread, with
/// `extra` arguments, as its columns.
fn bench_default_row(kind: &str, extra: &[&str]) -> Vec<String> {
    let mut args = vec![
        "bench",
        "--rays",
        "200",
        "--scene",
        "default",
        "--kind",
        kind,
        "--threads",
        "1",
    ];
    args.extend(extra);
    let out = ok(&args, None);
    let rows: Vec<&str> = out.lines().skip(1).collect();
    assert_eq!(rows.len(), 1, "one row: {out}");
    rows[0].split(',').map(String::from).collect()
}

/// `bench --scene --kind --threads` keeps only the rows asked for; an unknown scene is refused.
#[test]
fn bench_selects_rows() {
    let r = bench_default_row("incoherent", &[]);
    assert_eq!(
        (r[0].as_str(), r[6].as_str(), r[7].as_str()),
        ("default", "incoherent", "1"),
        "{r:?}"
    );
    let err = fails(&["bench", "--scene", "nope"], None);
    assert!(err.contains("--scene nope"), "{err}");
    let err = fails(&["bench", "--scene", "generated-1.6M"], None);
    assert!(err.contains("needs --large"), "{err}");
}

/// `bench --split` follows each ray set's row with rows for its rays that hit and those that
/// miss: every ray of the first hits, none of the second does, and together they are the set
/// (as many rays as its hit fraction says hit).
#[test]
fn bench_splits_rays_that_hit_from_those_that_miss() {
    let out = ok(
        &[
            "bench",
            "--rays",
            "300",
            "--scene",
            "default",
            "--threads",
            "1",
            "--split",
        ],
        None,
    );
    let rows: Vec<Vec<&str>> = out
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    let kinds: Vec<&str> = rows.iter().map(|r| r[6]).collect();
    assert_eq!(
        kinds,
        [
            "camera",
            "camera-hits",
            "camera-misses",
            "incoherent",
            "incoherent-hits",
            "incoherent-misses"
        ],
        "{out}"
    );
    for set in rows.chunks(3) {
        let count = |r: &[&str]| -> usize { r[8].parse().unwrap() };
        let fraction = |r: &[&str]| -> f64 { r[10].parse().unwrap() };
        let (all, hits, misses) = (&set[0], &set[1], &set[2]);
        assert_eq!(count(hits) + count(misses), count(all), "{out}");
        assert!(count(hits) > 0 && count(misses) > 0, "both parts: {out}");
        assert_eq!((fraction(hits), fraction(misses)), (1.0, 0.0), "{out}");
        let expected = fraction(all) * count(all) as f64;
        assert!(
            (count(hits) as f64 - expected).abs() <= 0.5e-3 * count(all) as f64 + 0.5,
            "{out}"
        );
        for r in set {
            let rate: f64 = r[9].parse().unwrap();
            assert!(rate > 0.0 && rate.is_finite(), "{r:?}");
        }
    }
}

/// `bench --builds N` reports the same scene (segments, bytes, hit fraction) as one build, with
/// finite times; zero builds are refused.
#[test]
fn bench_takes_the_least_of_several_builds() {
    let (one, three) = (
        bench_default_row("camera", &["--builds", "1"]),
        bench_default_row("camera", &["--builds", "3"]),
    );
    for r in [&one, &three] {
        for col in [2, 3] {
            let secs: f64 = r[col].parse().unwrap();
            assert!(secs >= 0.0 && secs.is_finite(), "{r:?}");
        }
        let peak: f64 = r[5].parse().unwrap();
        assert!(peak > 1.0 && peak < 4096.0, "peak MiB: {r:?}");
    }
    // Segments, bytes a segment, ray count and hit fraction.
    for col in [0, 1, 4, 8, 10] {
        assert_eq!(one[col], three[col], "column {col}: {one:?} {three:?}");
    }
    let err = fails(&["bench", "--builds", "0"], None);
    assert!(err.contains("--builds"), "{err}");
}

/// `bench --render` renders a scene as its file says and reports its timings in one row; a
/// scene without a camera is refused before any output.
#[test]
fn bench_times_a_named_render() {
    let scene = scratch(
        "bench-render.toml",
        format!(
            "[render]\nintegrator = \"path\"\nspp = 2\nmax_depth = 3\n[camera]\nposition = [0, 0, -3]\nlook_at = [0, 0, 0]\nfov = 40\nresolution = [24, 16]\n[[cylinder]]\n{AXIS}\nmajor_radius = [0.1, 0.1]\n"
        )
        .as_bytes(),
    );
    let out = ok(
        &[
            "bench",
            "--render",
            "--render-scene",
            path(&scene),
            "--threads",
            "1",
        ],
        None,
    );
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 2, "a header and one row: {out}");
    assert!(
        lines[0].starts_with("render,segments,width,height,spp,max_depth,threads"),
        "{out}"
    );
    let r: Vec<&str> = lines[1].split(',').collect();
    assert_eq!(&r[1..7], ["1", "24", "16", "2", "3", "1"], "{out}");
    for v in &r[7..10] {
        let x: f64 = v.parse().unwrap();
        assert!(x >= 0.0 && x.is_finite(), "timings: {out}");
    }
    let no_camera = scene_with("bench-no-camera.toml", "");
    let err = fails(
        &["bench", "--render", "--render-scene", path(&no_camera)],
        None,
    );
    assert!(err.contains("needs the scene's [camera]"), "{err}");
}

// Bad input (issue: every bad input ends cleanly). Each case is small: the limits are checked
// before anything large is allocated, so none of these needs gigabytes.

/// A scene of one straight round cylinder and `extra` tables.
fn scene_with(name: &str, extra: &str) -> PathBuf {
    scratch(
        name,
        format!("[[cylinder]]\n{AXIS}\nmajor_radius = [0.1, 0.1]\n{extra}").as_bytes(),
    )
}

/// Checks that `message` names each of `needles`.
fn names(message: &str, needles: &[&str]) {
    for n in needles {
        assert!(message.contains(n), "{n:?} not in: {message}");
    }
}

#[test]
fn image_sizes_are_limited_before_allocating() {
    let out = scratch("limit.png", b"");
    let huge = scene_with(
        "huge.toml",
        "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nresolution = [65536, 65536]\n",
    );
    let e = fails(&["render", "-q", path(&huge), "-o", path(&out)], None);
    names(
        &e,
        &[
            "huge.toml",
            "65536x65536 = 4294967296 pixels",
            "268435456",
            "--max-pixels",
        ],
    );
    let tall = scene_with(
        "tall.toml",
        "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nresolution = [1, 65536]\n",
    );
    for w in ["40000", "65536"] {
        let e = fails(
            &["render", "-q", path(&tall), "--width", w, "-o", path(&out)],
            None,
        );
        names(&e, &["--width", "the height would be", "more than 65536"]);
    }
    // The limit is a flag: a tiny one refuses a small image, and names the flag.
    let small = scene_with("small.toml", "");
    let e = fails(
        &[
            "render",
            "-q",
            path(&small),
            "--width",
            "64",
            "--max-pixels",
            "100",
            "-o",
            path(&out),
        ],
        None,
    );
    names(&e, &["64x48 = 3072 pixels", "limit of 100"]);
}

#[test]
fn threads_rays_and_strands_are_limited() {
    let s = scene_with("threads.toml", "");
    let out = scratch("threads.png", b"");
    let e = fails(
        &[
            "render",
            "-q",
            path(&s),
            "--threads",
            "65535",
            "-o",
            path(&out),
        ],
        None,
    );
    names(&e, &["--threads 65535", "per core"]);
    let rays = scratch("threads.csv", b"0,0,1,0,0,-1\n");
    let e = fails(
        &["raycast", path(&s), path(&rays), "--threads", "65535"],
        None,
    );
    names(&e, &["--threads 65535", "per core"]);
    let e = fails(&["bench", "--rays", "4294967295"], None);
    names(&e, &["4294967295", "67108864"]);
    let hair = scratch("limit.hair", b"");
    for (strands, why) in [
        ("10000000", ["10010000000 points", "u32"]),
        (
            "4000000",
            ["needs about", "this process can still allocate"],
        ),
    ] {
        let args = [
            "generate",
            "--strands",
            strands,
            "--segments",
            "1000",
            "-o",
            path(&hair),
        ];
        names(&fails(&args, None), &why);
    }
}

/// `bench --split` holds each ray set's two parts beside the sets: its memory check counts
/// them, so 2^26 rays (3 GiB a set, 12 GiB in all) are refused at once under an 8.6 GiB
/// address-space limit, not when an allocation fails midway.
#[test]
fn bench_split_counts_the_parts_in_its_memory_check() {
    let out = Command::new("sh")
        .args([
            "-c",
            "ulimit -v 9000000 && exec \"$0\" \"$@\"",
            env!("CARGO_BIN_EXE_gencyl"),
            "bench",
            "--rays",
            "67108864",
            "--scene",
            "default",
            "--split",
        ])
        .stdin(Stdio::null())
        .output()
        .expect("sh runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && out.stdout.is_empty(), "{err}");
    names(&err, &["--rays 67108864", "needs about 12.0 GiB"]);
}

#[test]
fn devices_and_endless_files_are_refused() {
    let s = scene_with("dev.toml", "");
    let out = scratch("dev.png", b"");
    let e = fails(&["raycast", path(&s), "/dev/zero"], None);
    names(&e, &["/dev/zero", "character device"]);
    // Standard input without a newline: the line cap ends it after 4 KiB.
    let e = fails(&["raycast", path(&s), "-"], Some(&vec![0u8; 1 << 20]));
    names(&e, &["<stdin>:1", "longer than 4096 bytes"]);
    for scene in ["/dev/zero", "/dev/urandom", "/dev/null"] {
        let e = fails(&["render", "-q", scene, "-o", path(&out)], None);
        names(&e, &[scene, "not a regular file or a pipe"]);
    }
    let link = Path::new(env!("CARGO_TARGET_TMPDIR")).join("gencyl-cli-tests/zero.hair");
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
    let e = fails(&["render", "-q", path(&link), "-o", path(&out)], None);
    names(&e, &["zero.hair", "character device"]);
    let h = scratch(
        "dev-hair.toml",
        format!("[[hair]]\nfile = \"{}\"\n", path(&link)).as_bytes(),
    );
    let e = fails(&["render", "-q", path(&h), "-o", path(&out)], None);
    names(&e, &["dev-hair.toml:2:8", "character device"]);
}

#[test]
fn geometry_beyond_f64_is_refused_with_the_reason() {
    let out = scratch("geom.png", b"");
    let rays = scratch("geom.csv", b"0.5,-5,0,0,1,0\n");
    let profile = "profile = [[1, 0], [1, 0.35], [0.55, 0.55], [-0.5, 0.87], [-0.45, 0.45], [-0.5, 0], [-0.5, -0.87], [0.1, -0.75], [0.55, -0.55]]";
    let cases = [
        (format!("{AXIS}\nmajor_radius = [1e20, 0.03]\n{profile}"), "changes by a factor", "3:16"),
        (format!("{AXIS}\nmajor_radius = [1e300, 1e300]"), "times the axis' extent", "3:16"),
        ("bezier = [[1e300, 0, 0], [1e300, 1, 0], [1e300, 2, 0], [1e300, 3, 0]]\nmajor_radius = [1, 1]".to_string(), "more than 1e15", "2:10"),
        ("bezier = [[1e4, 0, 0], [1e4, 1, 0], [1e4, 2, 0], [1e4, 3, 0]]\nmajor_radius = [1e-12, 1e-12]".to_string(), "of the fiber's scale", "3:16"),
    ];
    for (i, (body, why, at)) in cases.iter().enumerate() {
        let s = scratch(
            &format!("geom{i}.toml"),
            format!("[[cylinder]]\n{body}\n").as_bytes(),
        );
        let e = fails(&["raycast", path(&s), path(&rays)], None);
        names(&e, &[&format!("geom{i}.toml:{at}"), why]);
        let e = fails(&["render", "-q", path(&s), "-o", path(&out)], None);
        names(&e, &[why]);
    }
    let big = [
        (
            "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1e300\n",
            "radius must be positive and at most 1e15",
        ),
        (
            "[[light]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = 1e300\n",
            "is above 1e20",
        ),
        ("[environment]\ncolor = 1e300\n", "is above 1e20"),
        (
            "[camera]\nposition = [1e300, 0, 0]\nlook_at = [0, 0, 0]\n",
            "position [1.000000e300, 0, 0] is beyond 1e15",
        ),
        (
            "[camera]\ntype = \"fisheye\"\n",
            "unknown camera type `fisheye`",
        ),
    ];
    for (i, (extra, why)) in big.iter().enumerate() {
        let s = scene_with(&format!("big{i}.toml"), extra);
        let e = fails(&["render", "-q", path(&s), "-o", path(&out)], None);
        names(&e, &[&format!("big{i}.toml:"), why]);
    }
    let strand = gencyl_render::formats::hair::write_hair(
        &[vec![
            glam::DVec3::ZERO,
            glam::DVec3::X,
            glam::DVec3::new(2.0, 0.5, 0.0),
        ]],
        None,
        "one strand",
    );
    let h = scratch("radius.hair", &strand);
    let e = fails(
        &[
            "render",
            "-q",
            path(&h),
            "--radius",
            "1e300",
            "-o",
            path(&out),
        ],
        None,
    );
    names(
        &e,
        &["radius.hair: strand 0, segment 0", "times the axis' extent"],
    );
}

/// Reads a PNG's RGB bytes.
fn png_rgb(p: &Path) -> Vec<u8> {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(p).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    buf
}

#[test]
fn huge_directions_still_normalise() {
    // A plane whose normal is [1e200, 0, 0] and a light along [1e200, -1e200, 0] are a wall
    // at x = -1 lit from the side: the image is not black.
    let s = scene_with(
        "dirs.toml",
        "[[plane]]\npoint = [-1, 0, 0]\nnormal = [1e200, 0, 0]\n[[light]]\ntype = \"directional\"\ndirection = [-1e200, -1e200, 0]\nirradiance = 3\n[camera]\nposition = [5, 0, 0]\nlook_at = [0, 0, 0]\nresolution = [32, 24]\n",
    );
    let out = scratch("dirs.png", b"");
    ok_err(&["render", "-q", path(&s), "--spp", "2", "-o", path(&out)]);
    let rgb = png_rgb(&out);
    let lit = rgb.iter().filter(|&&b| b > 20).count();
    assert!(
        lit > rgb.len() / 2,
        "the wall is lit: {lit} of {} bytes",
        rgb.len()
    );
}

#[test]
fn empty_dark_and_unseen_scenes_warn() {
    let out = scratch("warn.png", b"");
    // What a small render of `scene` prints on standard error (it must succeed).
    let stderr_of = |scene: &Path| {
        ok_err(&[
            "render",
            "-q",
            path(scene),
            "--width",
            "16",
            "--spp",
            "1",
            "-o",
            path(&out),
        ])
    };
    let e = stderr_of(&scratch("empty.toml", b""));
    names(&e, &["warning: ", "empty.toml has no geometry"]);
    let dark = "[[light]]\ntype = \"point\"\nposition = [0, 3, 0]\nintensity = 0\n";
    let e = stderr_of(&scene_with("dark.toml", dark));
    names(&e, &["warning: ", "dark.toml: light 0 emits nothing"]);
    let away = "[camera]\nposition = [0, 0, -5]\nlook_at = [0, 0, -10]\n";
    let e = stderr_of(&scene_with("away.toml", away));
    names(&e, &["warning: the camera sees no geometry"]);
    // A scene that is seen, lit and not empty gets no warning.
    let e = stderr_of(&scene_with("fine.toml", ""));
    assert!(!e.contains("warning"), "{e}");
    // A .hair file whose strands are all degenerate (single points) is an empty scene.
    let degenerate = gencyl_render::formats::hair::write_hair(
        &[vec![glam::DVec3::ONE; 3], vec![glam::DVec3::ZERO; 2]],
        None,
        "degenerate",
    );
    let e = stderr_of(&scratch("degenerate.hair", &degenerate));
    names(&e, &["warning: ", "degenerate.hair has no geometry"]);
}

#[test]
fn outputs_are_checked_first_and_nothing_is_left_behind() {
    let s = scene_with("out.toml", "");
    let e = fails(
        &["render", "-q", path(&s), "-o", "/nonexistent-folder/x.png"],
        None,
    );
    names(&e, &["/nonexistent-folder/x.png", "does not exist"]);
    // Once only: the cause is not repeated.
    assert_eq!(e.matches("does not exist").count(), 1, "{e}");
    let missing = Path::new(env!("CARGO_TARGET_TMPDIR")).join("gencyl-cli-tests/missing-part.exr");
    let merged = Path::new(env!("CARGO_TARGET_TMPDIR")).join("gencyl-cli-tests/merged.exr");
    let e = fails(&["merge", path(&missing), "-o", path(&merged)], None);
    names(&e, &["missing-part.exr: cannot read"]);
    assert_eq!(e.matches("No such file").count(), 1, "{e}");
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("gencyl-cli-tests");
    let e = fails(&["render", "-q", path(&s), "-o", path(&dir)], None);
    names(&e, &["the output must end in .png or .exr"]);
    // Upper-case extensions are extensions.
    let upper = dir.join("UPPER.PNG");
    let _ = std::fs::remove_file(&upper);
    ok_err(&[
        "render",
        "-q",
        path(&s),
        "--width",
        "16",
        "--spp",
        "1",
        "-o",
        path(&upper),
    ]);
    assert_eq!(&std::fs::read(&upper).unwrap()[1..4], b"PNG");
    // generate into a folder that does not exist, and over a folder: an error, no .partial.
    let generate_into = |out: &str| {
        fails(
            &["generate", "--strands", "10", "--segments", "2", "-o", out],
            None,
        )
    };
    let e = generate_into("/nonexistent-folder/g.hair");
    names(&e, &["does not exist"]);
    let target = dir.join("a-folder.hair");
    std::fs::create_dir_all(&target).unwrap();
    let e = generate_into(path(&target));
    names(&e, &["a-folder.hair", "it is a folder"]);
    assert!(
        !dir.join("a-folder.hair.partial").exists(),
        "no partial file left"
    );
}

#[test]
fn long_values_are_cut_in_messages() {
    let out = scratch("cut.png", b"");
    let digits = scratch(
        "digits.toml",
        format!(
            "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1{}\n",
            "0".repeat(300)
        )
        .as_bytes(),
    );
    let e = fails(&["render", "-q", path(&digits), "-o", path(&out)], None);
    names(&e, &["digits.toml:3:"]);
    assert!(e.len() < 2000, "{} bytes: {e}", e.len());
    let string = scratch(
        "string.toml",
        format!(
            "[[sphere]]\ncenter = [0, 0, 0]\nradius = \"{}\"\n",
            "x".repeat(10_000_000)
        )
        .as_bytes(),
    );
    let e = fails(&["render", "-q", path(&string), "-o", path(&out)], None);
    names(&e, &["string.toml:3:10", "more bytes)"]);
    assert!(e.len() < 2000, "{} bytes", e.len());
}

#[test]
fn lying_exr_headers_are_refused_before_reading() {
    // A valid EXR of one pixel whose display window claims 100000 x 100000 pixels.
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("gencyl-cli-tests");
    std::fs::create_dir_all(&dir).unwrap();
    let part = dir.join("claims-1e10.exr");
    let film = gencyl_render::formats::Film::new(
        (100_000, 100_000),
        gencyl_render::formats::Window::new(0, 0, 1, 1),
        &["R", "G", "B"],
    );
    film.write(&part).unwrap();
    assert!(std::fs::metadata(&part).unwrap().len() < 2000);
    let out = dir.join("merged-1e10.exr");
    let e = fails(&["merge", path(&part), "-o", path(&out)], None);
    names(&e, &["claims-1e10.exr", "100000x100000", "--max-pixels"]);
    assert!(!out.exists());
}

/// `gencyl export`: cylinders written as interface.md tables give the same hits. Frenet-framed
/// cylinders (elliptical, twisted, profiled, one end capped) to the bit in every column; round
/// strands (whose strand frame a table cannot carry) to the bit in `t` and `u`, normals to
/// 1e-12, `v` their own; an elliptical strand is refused with the cylinder named. The camera rays are those `bench` casts.
#[test]
fn export_writes_the_same_geometry() {
    let profile = "profile = [[1, 0], [1, 0.35], [0.55, 0.55], [-0.5, 0.87], [-0.45, 0.45], [-0.5, 0], [-0.5, -0.87], [0.1, -0.75], [0.55, -0.55]]";
    let scene = scratch(
        "export-src.toml",
        format!(
            "[[cylinder]]\nbezier = [[0, 0, 0], [1, 0.4, 0.1], [2, -0.3, 0.2], [3, 0.1, 0.6]]\nmajor_radius = [0.2, 0.12]\nminor_radius = [0.08, 0.05]\nrotation = [0.3, 4]\ncaps = false\n\
             [[cylinder]]\nbezier = [[0, 1, 0], [1, 1.5, 0.2], [2, 0.7, -0.2], [3, 1.1, 0.3]]\nmajor_radius = [0.15, 0.15]\n{profile}\n\
             [[strand]]\npoints = [[0, 2, 0], [1, 2.3, 0.2], [2, 1.8, -0.1], [3, 2.2, 0.1]]\nradius = [0.1, 0.06]\n\
             [camera]\nposition = [1.5, 1, 8]\nlook_at = [1.5, 1, 0]\n"
        )
        .as_bytes(),
    );
    let out = scratch("export-out.toml", b"");
    let rays = scratch("export-rays.csv", b"");
    let incoherent = scratch("export-incoherent.csv", b"");
    ok_err(&[
        "export",
        path(&scene),
        "-o",
        path(&out),
        "--camera-rays",
        path(&rays),
        "--incoherent-rays",
        path(&incoherent),
        "--rays",
        "3000",
    ]);
    let text = std::fs::read_to_string(&out).unwrap();
    assert_eq!(
        text.lines().filter(|l| *l == "[[cylinder]]").count(),
        2 + 3,
        "two cylinders, three strand segments"
    );
    assert!(
        text.contains("caps = false")
            && text.contains("caps = [true, false]")
            && text.contains("caps = [false, true]"),
        "{text}"
    );
    let ray_text = std::fs::read_to_string(&rays).unwrap();
    assert_eq!(
        ray_text.lines().count(),
        1 + 63 * 47,
        "a header and bench's 63x47 image"
    );
    let a = ok(&["raycast", "--all", path(&scene), path(&rays)], None);
    let b = ok(&["raycast", "--all", path(&out), path(&rays)], None);
    let (ra, rb) = (rows(&a), rows(&b));
    assert_eq!(ra.len(), rb.len(), "same number of hits");
    assert!(ra.len() > 200, "the rays hit: {} rows", ra.len());
    let mut strand_v_differs = 0;
    for (x, y) in ra.iter().zip(&rb) {
        let object = x[7].unwrap();
        if object < 2.0 {
            assert_eq!(x, y, "cylinder rows identical");
        } else {
            // Ray, t, u, object and part to the bit; the normal to rounding (the frame enters
            // its arithmetic, not its value); v is the frame's.
            let exact = |r: &Vec<Option<f64>>| [&r[..3], &r[7..]].concat();
            assert_eq!(
                exact(x),
                exact(y),
                "strand rows identical but for v and the normal"
            );
            for k in 4..7 {
                assert!(
                    (x[k].unwrap() - y[k].unwrap()).abs() < 1e-12,
                    "normal {x:?} {y:?}"
                );
            }
            strand_v_differs += (x[3] != y[3]) as usize;
        }
    }
    assert!(strand_v_differs > 0, "the strand frame is not Frenet's");
    // Bench's incoherent set: as many rays, from a sphere about the fibers, about half of them
    // hitting (they aim at random points of the fibers' box), with the same hits on both files.
    let inc_text = std::fs::read_to_string(&incoherent).unwrap();
    assert_eq!(
        inc_text.lines().count(),
        1 + 63 * 47,
        "as many as the camera rays"
    );
    let a = ok(&["raycast", path(&scene), path(&incoherent)], None);
    let b = ok(&["raycast", path(&out), path(&incoherent)], None);
    let (ra, rb) = (rows(&a), rows(&b));
    assert_eq!(ra.len(), rb.len(), "same number of hits");
    assert!(
        ra.len() > 100 && ra.len() < 63 * 47,
        "some incoherent rays hit, not all: {}",
        ra.len()
    );
    let origins: std::collections::HashSet<&str> = inc_text
        .lines()
        .skip(1)
        .map(|l| l.rsplitn(4, ',').last().unwrap())
        .collect();
    assert!(
        origins.len() > 1000,
        "rays from many origins, not a camera's one"
    );
    let elliptical = scratch(
        "export-ellipse.toml",
        b"[[strand]]\npoints = [[0, 0, 0], [1, 0.3, 0], [2, 0, 0.2]]\nradius = [0.1, 0.1]\nellipticity = 0.5\n",
    );
    let e = fails(&["export", path(&elliptical), "-o", path(&out)], None);
    names(
        &e,
        &["export-ellipse.toml: cylinder 0", "not round", "Frenet"],
    );
}

/// A reader that stops after the first line (`gencyl bench | head -1`) ends the run without a
/// panic and with status 0.
#[test]
fn bench_output_cut_short_is_not_a_crash() {
    use std::io::{BufRead, BufReader};
    let mut child = Command::new(env!("CARGO_BIN_EXE_gencyl"))
        .args(["bench", "--rays", "300"])
        .args(bench_scenes())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.starts_with("scene,"), "{first}");
    // The pipe is closed here: the next row hits a broken pipe.
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert!(out.status.success(), "{err}");
}

/// A small fiber bundle with a `[ct]` table.
fn ct_scene(name: &str, ct: &str) -> PathBuf {
    let src = format!(
        "[material.fiber]\ntype = \"dielectric\"\nxray_mu = 2\n\
         [[strand]]\npoints = [[0, 0, -1], [0, 0.02, 0], [0, 0, 1]]\nradius = [0.1, 0.1]\n\
         ellipticity = 0.6\ntwist = [0, 3]\nmaterial = \"fiber\"\n\
         [[strand]]\npoints = [[0.3, 0.1, -1], [0.32, 0.1, 0], [0.3, 0.12, 1]]\n\
         radius = [0.08, 0.08]\nmaterial = \"fiber\"\n\
         [[sphere]]\ncenter = [-0.3, 0, 0.1]\nradius = 0.1\n[ct]\n{ct}"
    );
    scratch(name, src.as_bytes())
}

fn tiff_pages(p: &Path) -> Vec<Vec<u32>> {
    let (_, _, pages) = gencyl_render::formats::tiff::read_pages::<f32>(p).unwrap();
    pages
        .into_iter()
        .map(|page| page.into_iter().map(f32::to_bits).collect())
        .collect()
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
}

#[test]
fn ct_views_split_concatenate_to_the_whole_bit_for_bit() {
    let scene = ct_scene(
        "ct-split.toml",
        "beam = \"cone\"\ndetector = [24, 6]\npixel = [0.04, 0.2]\nviews = 7\n\
         source_distance = 3\ndetector_distance = 1\nsamples = 4\nfocal_spot = 0.01\n",
    );
    let out = |name: &str| scratch(name, b"");
    let (whole, a, b) = (out("ct-whole.tif"), out("ct-a.tif"), out("ct-b.tif"));
    ok(
        &[
            "ct",
            path(&scene),
            "-o",
            path(&whole),
            "-q",
            "--threads",
            "2",
        ],
        None,
    );
    ok(
        &[
            "ct",
            path(&scene),
            "-o",
            path(&a),
            "-q",
            "--views",
            "0..3",
            "--threads",
            "1",
        ],
        None,
    );
    ok(
        &["ct", path(&scene), "-o", path(&b), "-q", "--views", "3..7"],
        None,
    );
    let pages = tiff_pages(&whole);
    assert_eq!(pages.len(), 7);
    let mut parts = tiff_pages(&a);
    parts.extend(tiff_pages(&b));
    assert!(parts == pages, "the parts' pages are the whole's");
    assert!(
        pages.iter().flatten().any(|&x| f32::from_bits(x) > 0.1),
        "the fibers absorb"
    );
    // The sidecars: ASTRA's cone_vec, and each part's vectors are its views' of the whole.
    let (jw, ja, jb) = (
        json(&whole.with_extension("json")),
        json(&a.with_extension("json")),
        json(&b.with_extension("json")),
    );
    assert_eq!(jw["type"], "cone_vec");
    assert_eq!(
        (jw["rows"].as_u64(), jw["columns"].as_u64()),
        (Some(6), Some(24))
    );
    assert_eq!(jw["quantity"], "absorbance");
    let vectors = jw["vectors"].as_array().unwrap();
    assert_eq!(vectors.len(), 7);
    assert!(vectors.iter().all(|v| v.as_array().unwrap().len() == 12));
    assert_eq!(ja["vectors"].as_array().unwrap()[..], vectors[..3]);
    assert_eq!(jb["vectors"].as_array().unwrap()[..], vectors[3..]);
    assert_eq!(jb["views"], serde_json::json!([3, 7]));
}

#[test]
fn ct_quantity_and_material_from_the_command_line() {
    let scene = ct_scene(
        "ct-quantity.toml",
        "detector = [16, 4]\npixel = [0.06, 0.3]\nviews = 3\n",
    );
    let run = |name: &str, extra: &[&str]| {
        let out = scratch(name, b"");
        let mut args = vec!["ct", path(&scene), "-o", path(&out), "-q"];
        args.extend_from_slice(extra);
        ok(&args, None);
        let (_, _, pages) = gencyl_render::formats::tiff::read_pages::<f32>(&out).unwrap();
        pages
    };
    let all = run("ct-len.tif", &["--quantity", "length"]);
    let fiber = run(
        "ct-fiber.tif",
        &["--quantity", "length", "--material", "fiber"],
    );
    let absorbance = run("ct-abs.tif", &[]);
    let transmission = run("ct-tr.tif", &["--quantity", "transmission"]);
    let mut sphere_seen = false;
    for k in 0..3 {
        for i in 0..64 {
            let (l, f) = (all[k][i] as f64, fiber[k][i] as f64);
            // mu 2 for the fibers, 1 for the sphere (the built-in surface material).
            let a = 2.0 * f + (l - f);
            assert!(f <= l * (1.0 + 1e-6), "{f} <= {l}");
            assert!(
                (absorbance[k][i] as f64 - a).abs() <= 1e-5 * a + 1e-6,
                "{} vs {a}",
                absorbance[k][i]
            );
            let t = transmission[k][i] as f64;
            assert!((t - (-(absorbance[k][i] as f64)).exp()).abs() < 1e-6, "{t}");
            sphere_seen |= l - f > 0.01;
        }
    }
    assert!(sphere_seen, "the sphere's path counts in the total");
}

#[test]
fn ct_errors_are_clear_and_leave_nothing() {
    let no_ct = scratch(
        "ct-none.toml",
        b"[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\n",
    );
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("gencyl-cli-tests/ct-none.tif");
    let _ = std::fs::remove_file(&out);
    let run = |args: &[&str]| {
        let o = gencyl(args, None);
        assert!(!o.status.success(), "{args:?} must fail");
        String::from_utf8(o.stderr).unwrap()
    };
    let e = run(&["ct", path(&no_ct), "-o", path(&out)]);
    assert!(
        e.contains("ct-none.toml: the scene has no [ct] table"),
        "{e}"
    );
    assert!(!out.exists() && !out.with_extension("json").exists());
    let scene = ct_scene(
        "ct-err.toml",
        "detector = [4, 4]\npixel = [0.1, 0.1]\nviews = 5\n",
    );
    for (views, _) in [("3..3", ()), ("0..6", ()), ("a..b", ()), ("4", ())] {
        let e = run(&["ct", path(&scene), "-o", path(&out), "--views", views]);
        assert!(
            e.contains(&format!("--views {views}: expected a..b, 0 <= a < b <= 5")),
            "{e}"
        );
    }
    let e = run(&["ct", path(&scene), "-o", path(&out), "--material", "fiber"]);
    assert!(
        e.contains("--material applies to the length quantity only"),
        "{e}"
    );
    let e = run(&[
        "ct",
        path(&scene),
        "-o",
        path(&out),
        "--quantity",
        "length",
        "--material",
        "x",
    ]);
    assert!(e.contains("--material: unknown material `x`"), "{e}");
    let e = run(&["ct", path(&scene), "-o", "projections.png"]);
    assert!(e.contains("the output must end in .tif or .tiff"), "{e}");
    assert!(!out.exists());
}

#[test]
fn generate_yarn_writes_scene_truth_and_labels_and_ct_runs_on_it() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("gencyl-cli-tests/yarn");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("y.toml");
    let err = ok(
        &[
            "generate",
            "yarn",
            "--fibers",
            "20",
            "--radius",
            "0.02",
            "--packing",
            "0.4",
            "--aspect",
            "0.8",
            "--twist",
            "15",
            "-o",
            path(&scene),
            "--labels",
            "0.01",
        ],
        None,
    );
    assert!(err.is_empty());
    let truth = json(&dir.join("y.truth.json"));
    assert_eq!(truth["fiber_count"], 20);
    let fraction = truth["fiber_volume_fraction"].as_f64().unwrap();
    assert!((fraction - 0.4).abs() < 1e-6, "{fraction}");
    let size: Vec<u64> = truth["labels"]["size"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_u64().unwrap())
        .collect();
    let (w, h, pages) =
        gencyl_render::formats::tiff::read_pages::<u32>(&dir.join("y.labels.tif")).unwrap();
    assert_eq!(
        [w as u64, h as u64, pages.len() as u64],
        [size[0], size[1], size[2]]
    );
    let labelled: std::collections::BTreeSet<u32> = pages.iter().flatten().copied().collect();
    assert_eq!(labelled.len(), 21, "background and the 20 fibers");
    // The scene carries a [ct] table: a few of its views project.
    let out = dir.join("p.tif");
    ok(
        &[
            "ct",
            path(&scene),
            "-o",
            path(&out),
            "--views",
            "0..2",
            "-q",
        ],
        None,
    );
    assert_eq!(tiff_pages(&out).len(), 2);
    // An impossible packing: an error, and nothing written.
    let bad = dir.join("bad.toml");
    let o = gencyl(
        &["generate", "yarn", "--packing", "0.95", "-o", path(&bad)],
        None,
    );
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("packing 0.9500 is not reachable"), "{e}");
    assert!(!bad.exists() && !dir.join("bad.truth.json").exists());
    let o = gencyl(
        &[
            "generate",
            "ply",
            "--fibers",
            "10",
            "--labels",
            "nan",
            "-o",
            path(&bad),
        ],
        None,
    );
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--labels"));
    // The hair generator keeps its command line.
    let hair = dir.join("h.hair");
    ok(
        &[
            "generate",
            "--strands",
            "3",
            "--segments",
            "2",
            "-o",
            path(&hair),
        ],
        None,
    );
    assert!(hair.exists());
}

#[test]
fn scatter_writes_its_table_plot_and_map() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("gencyl-cli-tests/scatter");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let (csv, png, map) = (dir.join("s.csv"), dir.join("s.png"), dir.join("m.exr"));
    ok(
        &[
            "scatter",
            "--aspect",
            "0.8",
            "--rotation",
            "20",
            "--theta-i",
            "15",
            "--rays",
            "2000",
            "--bins",
            "36",
            "--max-order",
            "2",
            "-o",
            path(&csv),
            "--plot",
            path(&png),
            "--sweep",
            "3",
            "--map",
            path(&map),
        ],
        None,
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("order,theta_deg,phi_deg,value"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 3 * 36 * 36, "every bin of every order");
    let total: f64 = rows.iter().map(|r| r[3]).sum();
    assert!(
        (total - 1.0).abs() < 1e-6,
        "no absorption: the rows sum to 1, got {total}"
    );
    // The specular cone: all power at theta_o = -theta_i (the bin of -15 degrees).
    let off: f64 = rows
        .iter()
        .filter(|r| (r[1] + 15.0).abs() > 5.0)
        .map(|r| r[3])
        .sum();
    assert!(off < 1e-9, "{off} off the cone");
    assert!(
        rows.iter()
            .all(|r| r[2] > -180.0 && r[2] < 180.0 && (0.0..=2.0).contains(&r[0]))
    );
    assert!(std::fs::metadata(&png).unwrap().len() > 1000);
    let film = gencyl_render::formats::Film::read_exr(&map).unwrap();
    assert_eq!(film.frame, (36, 3));
    assert!(film.channel_index("p2").is_some());
    // One elliptical fiber lit from three azimuths: each row sums to 1, and the rows are not
    // one measurement turned (the section stays put while the light goes round).
    let total = film.channel_index("total").unwrap();
    let row = |k: u32| {
        (0..36)
            .map(|x| film.pixel(x, k)[total] as f64)
            .collect::<Vec<_>>()
    };
    for k in 0..3 {
        assert!((row(k).iter().sum::<f64>() - 1.0).abs() < 1e-5);
    }
    let turned: Vec<f64> = (0..36).map(|x| row(0)[(x + 36 - 12) % 36]).collect();
    let differ = row(1)
        .iter()
        .zip(&turned)
        .map(|(a, b)| (a - b).abs())
        .sum::<f64>();
    assert!(
        differ > 0.01,
        "row 1 is row 0 turned by 120 degrees: {differ}"
    );
    // Errors: a bad profile file, a map without a sweep, nonsense numbers; nothing written.
    let bad = scratch("bad-profile.toml", b"profile = [[0, 0], [1, 0]]\n");
    let out = dir.join("x.csv");
    for args in [
        vec!["scatter", "--profile", path(&bad), "-o", path(&out)],
        vec!["scatter", "--map", path(&map), "-o", path(&out)],
        vec!["scatter", "--eta", "0.9", "-o", path(&out)],
        vec!["scatter", "--aspect", "nan", "-o", path(&out)],
    ] {
        let o = gencyl(&args, None);
        assert!(!o.status.success(), "{args:?}");
        assert!(!out.exists());
    }
    let e = String::from_utf8(
        gencyl(
            &["scatter", "--profile", path(&bad), "-o", path(&out)],
            None,
        )
        .stderr,
    )
    .unwrap();
    assert!(e.contains("profile: a profile needs 3k points"), "{e}");
}

#[test]
fn ct_lengths_per_material_in_one_pass_equal_one_run_per_material() {
    let scene = ct_scene(
        "ct-lengths.toml",
        "beam = \"cone\"\ndetector = [20, 5]\npixel = [0.05, 0.2]\nviews = 4\n\
         source_distance = 3\ndetector_distance = 1\nsamples = 4\n",
    );
    let out = scratch("ct-lengths.tif", b"");
    ok(
        &["ct", path(&scene), "-o", path(&out), "-q", "--lengths"],
        None,
    );
    let sidecar = json(&out.with_extension("json"));
    let stacks = sidecar["length_stacks"].as_object().unwrap();
    assert_eq!(
        stacks.len(),
        2,
        "the fibers' and the sphere's materials: {stacks:?}"
    );
    for (material, file) in stacks {
        let one = scratch(&format!("ct-one-{material}.tif"), b"");
        ok(
            &[
                "ct",
                path(&scene),
                "-o",
                path(&one),
                "-q",
                "--quantity",
                "length",
                "--material",
                material,
            ],
            None,
        );
        let together = out.with_file_name(file.as_str().unwrap());
        assert!(tiff_pages(&together) == tiff_pages(&one), "{material}");
        assert!(
            tiff_pages(&one)
                .iter()
                .flatten()
                .any(|&x| f32::from_bits(x) > 0.01)
        );
    }
    // The quantity's own stack is the same as without --lengths.
    let plain = scratch("ct-plain.tif", b"");
    ok(&["ct", path(&scene), "-o", path(&plain), "-q"], None);
    assert!(tiff_pages(&plain) == tiff_pages(&out));
}
