//! The `gencyl` command: exact ray casting of generalized cylinders (hair fibers).
//!
//! `gencyl raycast SCENE RAYS` writes the hits of every ray as CSV (see
//! `gencyl_render::raycast` and interface.md section 3); `gencyl render [SCENE]` renders a
//! PNG (the built-in scene without SCENE).
#![forbid(unsafe_code)]

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use gencyl_render::accel::{COUNTING, QueryCounts, Scene, Scratch};
use gencyl_render::formats::plot;
use gencyl_render::formats::{Film, Window, hair};
use gencyl_render::limits;
use gencyl_render::optics::scanner::Quantity;
use gencyl_render::raycast::{self, RaycastOptions};
use gencyl_render::scene_file::{SceneDescription, SceneError};
use gencyl_render::scenes::job::{self, PlanError, RenderJob, RenderRequest};
use gencyl_render::scenes::{builtin, phantom, synth};
use gencyl_render::settings::{Integrator, RenderTable};
use gencyl_render::transport::ct::Projector;
use gencyl_render::transport::scatter::{FiberSection, Goniometer, Scattering};
use gencyl_render::transport::{World, integrator};
use indicatif::{ProgressBar, ProgressStyle};

/// Exact ray tracing of generalized cylinders (hair fibers).
#[derive(Debug, Parser)]
#[command(name = "gencyl", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Intersect every ray of RAYS with the scene; write the hits as CSV to standard output
    /// (header `ray,t,u,v,nx,ny,nz,object,part`).
    Raycast(RaycastArgs),
    /// Render a scene to PNG or EXR: without SCENE, the built-in tuft of curly, elliptical,
    /// twisted fibers.
    Render(RenderArgs),
    /// Merge windows rendered with `--crop` into the full frame (bit-identical to rendering
    /// it whole).
    Merge(MergeArgs),
    /// Write a generated hair model (a head of wavy strands) as a `.hair` file, or (`generate
    /// yarn`, `generate ply`) a CT phantom: a scene of fibers with its exact ground truth.
    Generate(GenerateArgs),
    /// Time named scenes: load, BVH build, memory per segment, camera rays per second.
    Bench(BenchArgs),
    /// Write every cylinder of a scene (strands and hair files included) as interface.md
    /// `[[cylinder]]` tables, and optionally the scene's camera rays as a ray file: the same
    /// geometry and rays for another intersector.
    Export(ExportArgs),
    /// X-ray CT projections of a scene with a `[ct]` table: a multi-page float32 TIFF (one
    /// page per view) and a JSON sidecar with the geometry as ASTRA vectors.
    Ct(CtArgs),
    /// A virtual goniometer: how one fiber (circular, elliptical or profiled, a dielectric
    /// solid) scatters light, by path order, as CSV (`order,theta_deg,phi_deg,value`).
    Scatter(ScatterArgs),
}

#[derive(Debug, clap::Args)]
struct ScatterArgs {
    /// Minor / major radius of an elliptical section (1 = circle).
    #[arg(long, default_value_t = 1.0)]
    aspect: f64,
    /// A TOML file with `profile = [[x, y], ...]` (a Bezier loop, as the scene's `profile` key):
    /// the section instead of an ellipse.
    #[arg(long)]
    profile: Option<PathBuf>,
    /// Angle from the incident direction's projection onto the normal plane (toward the light)
    /// to the section's major axis, counterclockwise about the tangent, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    rotation: f64,
    /// Relative index of refraction.
    #[arg(long, default_value_t = 1.55)]
    eta: f64,
    /// Absorption per unit length inside, the section's bounding radius being 1.
    #[arg(long, default_value_t = 0.0)]
    sigma_a: f64,
    /// Cuticle tilt of the normal toward the tip, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    tilt: f64,
    /// Incident longitudinal angle (from the normal plane toward the tip), degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    theta_i: f64,
    /// Incident azimuth, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    phi_i: f64,
    /// Rays across the fiber.
    #[arg(long, default_value_t = 1_000_000)]
    rays: usize,
    /// Orders binned apart (0 = R, 1 = TT, 2 = TRT, ...); the last holds all higher ones.
    #[arg(long, default_value_t = 3)]
    max_order: usize,
    /// Bins over theta_o (-90..90) and over phi (-180..180).
    #[arg(long, default_value_t = 90)]
    bins: usize,
    /// Seed of the rays' jitter.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// The table.
    #[arg(short, long, default_value = "scatter.csv")]
    output: PathBuf,
    /// Also plot N_p(phi) (each order's power per phi bin) as PNG.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Also measure at this many incident azimuths over 360 degrees (from --phi-i) and write
    /// the (phi_i, phi_o) map to --map.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=3600))]
    sweep: Option<u32>,
    /// The map of --sweep, for the fiber as --rotation places it for the first azimuth:
    /// `.png` (row k: incident azimuth --phi-i + 360 k / N, top down; column: the outgoing
    /// azimuth minus --phi-i, from -180 to 180 degrees; brightness the square root of the
    /// power per bin, the largest white) or `.exr` (channels `total` and `p0`, `p1`, ... the
    /// raw fractions per bin, R, G, B the display values).
    #[arg(long)]
    map: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
}

#[derive(Debug, clap::Args)]
struct CtArgs {
    /// A scene file (TOML) with a `[ct]` table.
    scene: PathBuf,
    /// The projections (`.tif` or `.tiff`); the sidecar is the same name with `.json`.
    #[arg(short, long, default_value = "projections.tif")]
    output: PathBuf,
    /// Only views `a..b` of the scan (0-based, b excluded): the parts of a scan split this way
    /// concatenate, page by page, to the whole, bit for bit.
    #[arg(long)]
    views: Option<String>,
    /// What a pixel records (default: the `[ct]` table's): absorbance, transmission or length.
    #[arg(long)]
    quantity: Option<String>,
    /// With `--quantity length`: only this material's path length.
    #[arg(long)]
    material: Option<String>,
    /// Also the mean path length through each material the solids use, from the same rays:
    /// one more stack per material, OUT.length.NAME.tif (NAME with characters other than
    /// letters, digits, `-` and `_` made `_`; the sidecar's `length_stacks` names the files).
    #[arg(long)]
    lengths: bool,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(Debug, clap::Args)]
struct ExportArgs {
    /// A scene file (TOML) or a hair model (`.hair`).
    scene: PathBuf,
    /// The `[[cylinder]]` tables to write.
    #[arg(short, long, default_value = "cylinders.toml")]
    output: PathBuf,
    /// Also write the camera rays `gencyl bench` casts on this scene (one per pixel centre of a
    /// 4:3 image of about `--rays` pixels) as a ray file.
    #[arg(long)]
    camera_rays: Option<PathBuf>,
    /// Also write bench's incoherent rays on this scene (as many as the camera rays, from a
    /// sphere about the fibers through random points of their box) as a ray file.
    #[arg(long)]
    incoherent_rays: Option<PathBuf>,
    /// Camera rays for `--camera-rays` (and as many for `--incoherent-rays`; at most 2^26).
    #[arg(long, default_value_t = 76_800, value_parser = clap::value_parser!(u32).range(1..=1 << 26))]
    rays: u32,
    /// Fiber radius for a `.hair` model (default: half the file's thickness).
    #[arg(long, allow_negative_numbers = true)]
    radius: Option<f64>,
}

#[derive(Debug, clap::Args)]
struct RenderArgs {
    /// A scene file (TOML) or a hair model (`.hair`, Cem Yuksel's format); default: the
    /// built-in scene.
    scene: Option<PathBuf>,
    /// Output image: `.png` (8-bit sRGB) or `.exr` (linear float, every channel).
    #[arg(short, long, default_value = "gencyl.png")]
    output: PathBuf,
    /// Integrator: normals, uv, depth, direct, path or xray (default: the scene's, else path).
    #[arg(long)]
    integrator: Option<Integrator>,
    /// Image width in pixels; the height keeps the camera's aspect ratio.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65536))]
    width: Option<u32>,
    /// Most pixels the image may have (default 2^28 = 268435456: a film of 16-24 bytes per
    /// pixel, copied once when written, must fit in memory).
    #[arg(long, default_value_t = limits::MAX_PIXELS, value_parser = clap::value_parser!(u64).range(1..))]
    max_pixels: u64,
    /// Samples per pixel (default: the scene's, else 16).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    spp: Option<u32>,
    /// Most scattering events on a path (default: the scene's, else 16).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1000))]
    max_depth: Option<u32>,
    /// Seed of the per-pixel sample streams (default: the scene's, else 1).
    #[arg(long)]
    seed: Option<u64>,
    /// Render only the window `x0,y0,x1,y1` of the frame (pixels, x1 and y1 excluded); write
    /// it as `.exr` to merge windows with `gencyl merge`.
    #[arg(long)]
    crop: Option<String>,
    /// Fiber radius for a `.hair` model (default: half the file's thickness).
    #[arg(long, allow_negative_numbers = true)]
    radius: Option<f64>,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
    /// Also print what the rays did: queries by kind and how many hit, and per ray the BVH
    /// nodes walked, cylinder pieces reached, culls (and how many cleared their cylinder)
    /// and exact tests (counted in a build with `--features stats`).
    #[arg(long)]
    stats: bool,
}

#[derive(Debug, clap::Args)]
struct MergeArgs {
    /// Windows of one frame, as written by `gencyl render --crop ... -o part.exr`.
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// The merged image: `.png` or `.exr`.
    #[arg(short, long)]
    output: PathBuf,
    /// Most pixels the merged frame may have (default 2^28).
    #[arg(long, default_value_t = limits::MAX_PIXELS, value_parser = clap::value_parser!(u64).range(1..))]
    max_pixels: u64,
}

#[derive(Debug, clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
struct GenerateArgs {
    #[command(subcommand)]
    kind: Option<GenerateKind>,
    #[command(flatten)]
    hair: HairArgs,
}

#[derive(Debug, Subcommand)]
enum GenerateKind {
    /// A head of wavy strands as a `.hair` file (the default).
    Hair(HairArgs),
    /// A twisted yarn of elliptical fibers along z (a CT phantom): the scene (with a `[ct]`
    /// table), its ground truth as JSON and, with `--labels`, a voxel label volume.
    Yarn(YarnArgs),
    /// A unidirectional composite ply of fibers along x (a CT phantom), as `yarn` writes it.
    Ply(PlyArgs),
}

#[derive(Debug, clap::Args)]
struct PhantomOutput {
    /// The scene file to write; the truth goes beside it as STEM.truth.json.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Also write the label volume (0 background, fiber number + 1 inside, by the exact inside
    /// test at voxel centres) at this voxel size, as STEM.labels.tif (one uint32 page per z
    /// slice); its grid goes into the truth.
    #[arg(long)]
    labels: Option<f64>,
    /// Fiber radius sd, relative (default 0.1).
    #[arg(long)]
    radius_sd: Option<f64>,
    /// Mean minor/major radius (1 = round).
    #[arg(long)]
    aspect: Option<f64>,
    /// Relative sd of the aspect.
    #[arg(long)]
    aspect_sd: Option<f64>,
    /// Bezier segments per fiber (default: the fewest that follow the fiber's path).
    #[arg(long)]
    segments: Option<usize>,
    /// Seed.
    #[arg(long)]
    seed: Option<u64>,
    /// The fibers' material name.
    #[arg(long)]
    material: Option<String>,
}

#[derive(Debug, clap::Args)]
struct YarnArgs {
    /// Number of fibers (default 100).
    #[arg(long)]
    fibers: Option<usize>,
    /// Yarn length along z (default 1).
    #[arg(long)]
    length: Option<f64>,
    /// Helix angle at the yarn surface, degrees (default 20).
    #[arg(long, allow_negative_numbers = true)]
    twist: Option<f64>,
    /// Fiber volume fraction of the yarn's envelope cylinder (default 0.5).
    #[arg(long)]
    packing: Option<f64>,
    /// Mean fiber major radius (default 0.01).
    #[arg(long)]
    radius: Option<f64>,
    /// Turn of each fiber's section about its own axis over its length, radians.
    #[arg(long)]
    section_twist: Option<f64>,
    /// Radial migration amplitude, a fraction of the yarn radius (0 to 0.25).
    #[arg(long)]
    migration: Option<f64>,
    /// Migration period along z.
    #[arg(long)]
    migration_period: Option<f64>,
    #[command(flatten)]
    common: PhantomOutput,
}

#[derive(Debug, clap::Args)]
struct PlyArgs {
    /// Number of fibers (give this or --packing).
    #[arg(long)]
    fibers: Option<usize>,
    /// Ply length along x (default 1).
    #[arg(long)]
    length: Option<f64>,
    /// Width along y (default 0.4).
    #[arg(long)]
    width: Option<f64>,
    /// Thickness along z (default 0.1).
    #[arg(long)]
    thickness: Option<f64>,
    /// Fiber volume fraction of the box (default 0.55 when --fibers is not given).
    #[arg(long)]
    packing: Option<f64>,
    /// Mean fiber major radius (default 0.005).
    #[arg(long)]
    radius: Option<f64>,
    /// Waviness amplitude, a fraction of the mean radius (default 0: straight).
    #[arg(long)]
    waviness: Option<f64>,
    /// Wavelength of the waviness along x.
    #[arg(long)]
    waviness_period: Option<f64>,
    #[command(flatten)]
    common: PhantomOutput,
}

#[derive(Debug, clap::Args)]
struct HairArgs {
    /// The hair file to write.
    #[arg(short, long, default_value = "generated.hair")]
    output: PathBuf,
    /// Number of strands.
    #[arg(long, default_value_t = 100_000, value_parser = clap::value_parser!(u32).range(1..=10_000_000))]
    strands: u32,
    /// Segments per strand.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u16).range(1..=1000))]
    segments: u16,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

#[derive(Debug, clap::Args)]
struct BenchArgs {
    /// Also the generated 1.6-million-segment model (100,000 strands x 16; about 2 GB).
    #[arg(long)]
    large: bool,
    /// The `ponytail` scene (the TressFX ponytail over a scalp).
    #[arg(long, default_value = "examples/ponytail.toml")]
    ponytail: PathBuf,
    /// The `ponytail-elliptical` scene (the same strands with elliptical sections, timed on the
    /// same rays).
    #[arg(long, default_value = "examples/ponytail-elliptical.toml")]
    ponytail_elliptical: PathBuf,
    /// The `ponytail-trilobal` scene (the same strands with a three-lobed profile, the General
    /// method's, timed on the same rays).
    #[arg(long, default_value = "examples/ponytail-trilobal.toml")]
    ponytail_trilobal: PathBuf,
    /// Camera rays per scene (a 4:3 image of about this many pixels, one ray each; at most
    /// 2^26, whose rays take 3 GiB a set: the camera and incoherent sets, and with `--split` their
    /// parts too, are held at once).
    #[arg(long, default_value_t = 76_800, value_parser = clap::value_parser!(u32).range(1..=1 << 26))]
    rays: u32,
    /// Only this scene (`default`, `ponytail`, `ponytail-elliptical`, `ponytail-trilobal`,
    /// `generated-1.6M`; repeatable).
    #[arg(long = "scene")]
    scenes: Vec<String>,
    /// Only this ray set (`camera` or `incoherent`; repeatable).
    #[arg(long = "kind", value_parser = ["camera", "incoherent"])]
    kinds: Vec<String>,
    /// Only this thread count (default: 1 and all cores).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// Also time each ray set's rays that hit and those that miss apart: rows of kind
    /// `camera-hits`, `camera-misses`, `incoherent-hits` and `incoherent-misses` after the
    /// set's own (which rays hit is found first, untimed).
    #[arg(long)]
    split: bool,
    /// Time the named render instead of the ray sets: the scene's own camera, [render] settings
    /// and lights, on all cores (or --threads); prints wall-clock and CPU seconds.
    #[arg(long)]
    render: bool,
    /// The scene of `--render` (`ponytail-path`: 512x512, 64 spp, max depth 16).
    #[arg(long, default_value = "examples/ponytail-path.toml")]
    render_scene: PathBuf,
    /// Load and build each scene this many times and report the least load and build times
    /// (one run's vary by 5-10% on a shared machine; the least of several, within about 1%).
    /// The ray sets' rows only: `--render` loads and builds once.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1000))]
    builds: u32,
}

#[derive(Debug, clap::Args)]
struct RaycastArgs {
    /// The scene file (TOML, `[[cylinder]]` tables).
    scene: PathBuf,
    /// The ray file: `ox,oy,oz,dx,dy,dz` per line; `-` reads standard input.
    rays: String,
    /// Write every hit with t > tmin, sorted by t, rather than the nearest.
    #[arg(long)]
    all: bool,
    /// Only hits with t > TMIN count.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = parse_tmin)]
    tmin: f64,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// Print timings (scene preparation, intersection, rays per second) to standard error.
    #[arg(long)]
    stats: bool,
}

fn parse_tmin(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(t) if !t.is_nan() => Ok(t),
        Ok(_) => Err("tmin must be a number, not NaN".to_string()),
        Err(e) => Err(e.to_string()),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // Output cut short by the reader (`gencyl raycast ... | head`): not an error.
            if e.downcast_ref::<io::Error>()
                .is_some_and(|e| e.kind() == io::ErrorKind::BrokenPipe)
            {
                return ExitCode::SUCCESS;
            }
            match e
                .downcast_ref::<SceneError>()
                .and_then(SceneError::diagnostic)
            {
                Some(d) => eprintln!("{}", d.render()),
                None => eprintln!("error: {e:#}"),
            }
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    let result = match cli.command {
        Command::Raycast(args) => raycast_command(args),
        Command::Render(args) => render_command(args),
        Command::Merge(args) => merge_command(args),
        Command::Generate(args) => generate_command(args),
        Command::Bench(args) => bench_command(args),
        Command::Export(args) => export_command(args),
        Command::Ct(args) => ct_command(args),
        Command::Scatter(args) => scatter_command(args),
    };
    let exhausted = gencyl::budget::exhausted_searches();
    if exhausted > 0 {
        warn(format!(
            "{exhausted} root searches reached their work bound (geometry at the edge of what f64 resolves, or more crossings of one segment than a search keeps); their hits come from the bound's fallback and may be incomplete"
        ));
    }
    result
}

/// A warning: to standard error, not an error.
fn warn(message: impl std::fmt::Display) {
    eprintln!("warning: {message}");
}

/// A thread pool of `threads` (default: all cores), at most [`limits::max_threads`].
fn thread_pool(threads: Option<u16>) -> Result<rayon::ThreadPool> {
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        pool = pool.num_threads(limits::check_threads(n as usize).map_err(anyhow::Error::msg)?);
    }
    pool.build().context("cannot start the worker threads")
}

/// Checks, before any work, that `path` can be written: its extension (any case) is one of
/// `exts`, its folder exists and is a folder, and a file can be created there.
fn check_output(path: &Path, exts: &[&str]) -> Result<()> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    if !exts.contains(&ext.as_str()) {
        let list: Vec<String> = exts.iter().map(|e| format!(".{e}")).collect();
        bail!(
            "{}: the output must end in {}",
            path.display(),
            list.join(" or ")
        );
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        bail!(
            "{}: cannot write: the folder {} does not exist",
            path.display(),
            dir.display()
        );
    }
    if path.is_dir() {
        bail!("{}: cannot write: it is a folder", path.display());
    }
    let probe = dir.join(format!(".gencyl-write-check-{}", std::process::id()));
    std::fs::File::create(&probe).map_err(|e| {
        anyhow::anyhow!("{}: cannot write in {}: {e}", path.display(), dir.display())
    })?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

fn render_command(args: RenderArgs) -> Result<()> {
    let pool = thread_pool(args.threads)?;
    check_output(&args.output, &["png", "exr"])?;
    if let Some(r) = args.radius
        && !(r.is_finite() && r > 0.0)
    {
        bail!("--radius must be positive and finite, got {r}");
    }
    let crop = match &args.crop {
        Some(c) => Some(Window::parse_text(c).map_err(|e| anyhow::anyhow!("--crop: {e}"))?),
        None => None,
    };
    pool.install(|| {
        let t0 = Instant::now();
        let name = args
            .scene
            .as_ref()
            .map_or("the built-in scene".to_string(), |p| p.display().to_string());
        let desc = match &args.scene {
            None => builtin::default_scene(),
            Some(path) => {
                if args.radius.is_some() && !is_hair(path) {
                    bail!("--radius applies to .hair models; a scene file sets radii itself");
                }
                SceneDescription::load_any(path, args.radius)?
            }
        };
        let t1 = Instant::now();
        let (scene_camera, table) = (desc.camera, desc.render);
        let mut world = World::new(desc);
        let t2 = Instant::now();
        job::light_if_unlit(&mut world);
        let request = RenderRequest {
            overrides: RenderTable {
                integrator: args.integrator,
                spp: args.spp,
                max_depth: args.max_depth,
                seed: args.seed,
            },
            width: args.width,
            crop,
            max_pixels: args.max_pixels,
        };
        let RenderJob {
            camera,
            settings,
            window,
        } = job::plan(&world, scene_camera, &table, &request).map_err(|e| match e {
            PlanError::Height { width, .. } => anyhow::anyhow!("--width {width}: {}", e.message()),
            PlanError::Crop(m) => anyhow::anyhow!("--crop: {m}"),
            PlanError::Pixels { .. } => {
                anyhow::anyhow!(
                    "{name}: {} (the film must fit in memory; --max-pixels raises the limit)",
                    e.message()
                )
            }
            PlanError::Memory(m) => anyhow::anyhow!("{name}: {m}"),
        })?;
        for w in job::warnings(&world, &camera, &name) {
            warn(w);
        }
        let bar = progress_bar(args.quiet, window.height() as u64, "rows");
        let rendered = integrator::render(&world, &camera, &settings, window, &|done| {
            bar.set_position(done)
        });
        bar.finish_and_clear();
        let t3 = Instant::now();
        if rendered.non_finite_samples > 0 {
            warn(format!(
                "{} samples were NaN or infinite and were left out (their pixels are the mean of the finite samples)",
                rendered.non_finite_samples
            ));
        }
        rendered.film.write(&args.output)?;
        eprintln!(
            "{}: {}x{} ({}), {} spp, {:?}, {} cylinders; load {:.2} s, BVH {:.2} s, render {:.2} s",
            args.output.display(),
            window.width(),
            window.height(),
            if window == Window::full(camera.width, camera.height) {
                "full frame".to_string()
            } else {
                format!(
                    "window {},{},{},{} of {}x{}",
                    window.x0, window.y0, window.x1, window.y1, camera.width, camera.height
                )
            },
            settings.spp,
            settings.integrator,
            world.scene.len(),
            (t1 - t0).as_secs_f64(),
            (t2 - t1).as_secs_f64(),
            (t3 - t2).as_secs_f64()
        );
        if args.stats {
            eprint!("{}", query_report(&rendered.counts));
        }
        Ok(())
    })
}

/// `--stats`' report of what a run's ray queries did: two lines, as `render --stats` prints
/// them; one saying how to get them from a build without the counting.
fn query_report(c: &QueryCounts) -> String {
    if !COUNTING {
        return "queries: not counted in this build (cargo build --release --features stats)\n"
            .to_string();
    }
    counts_report(c)
}

/// The two lines of [`query_report`] for counts made.
fn counts_report(c: &QueryCounts) -> String {
    let share = |a: u64, b: u64| 100.0 * a as f64 / b.max(1) as f64;
    let per_ray = |x: u64| x as f64 / c.queries().max(1) as f64;
    let kinds = [
        (
            c.nearest,
            format!("nearest-hit ({:.1}% hit)", share(c.nearest_hits, c.nearest)),
        ),
        (
            c.any,
            format!("any-hit ({:.1}% blocked)", share(c.any_hits, c.any)),
        ),
        (c.all, "all-hits".to_string()),
    ];
    let kinds: Vec<String> = kinds
        .into_iter()
        .filter(|(n, _)| *n > 0)
        .map(|(n, what)| format!("{n} {what}"))
        .collect();
    format!(
        "queries: {}\nper query: {:.2} BVH nodes, {:.2} cylinder pieces reached, {:.2} culls ({:.1}% cleared), {:.3} exact tests, {:.3} on the fiber the ray leaves\n",
        if kinds.is_empty() {
            "none".to_string()
        } else {
            kinds.join(", ")
        },
        per_ray(c.nodes),
        per_ray(c.pieces),
        per_ray(c.culls),
        share(c.cleared, c.culls),
        per_ray(c.exact),
        per_ray(c.exact_leaving)
    )
}

fn ct_command(args: CtArgs) -> Result<()> {
    let pool = thread_pool(args.threads)?;
    check_output(&args.output, &["tif", "tiff"])?;
    let sidecar_path = args.output.with_extension("json");
    pool.install(|| {
        let t0 = Instant::now();
        let name = args.scene.display().to_string();
        let desc = SceneDescription::load(&args.scene)?;
        let Some(mut setup) = desc.ct.clone() else {
            bail!("{name}: the scene has no [ct] table (the scanner: see the README's CT section)");
        };
        if let Some(q) = &args.quantity {
            setup.quantity = q.parse().map_err(|e: String| anyhow::anyhow!("--quantity: {e}"))?;
            if setup.quantity != Quantity::Length {
                setup.material = None;
            }
        }
        if let Some(m) = &args.material {
            if setup.quantity != Quantity::Length {
                bail!("--material applies to the length quantity only (absorbance and transmission sum every material)");
            }
            let index = desc.materials.iter().position(|x| &x.name == m).ok_or_else(|| {
                let known: Vec<&str> = desc.materials.iter().map(|x| x.name.as_str()).collect();
                anyhow::anyhow!("--material: unknown material `{m}` (defined: {})", known.join(", "))
            })?;
            setup.material = Some(index as u32);
        }
        let total = setup.scanner.views.len();
        let views = match &args.views {
            Some(text) => parse_views(text, total)?,
            None => 0..total,
        };
        let world = World::new(desc);
        let t1 = Instant::now();
        // The materials of the solids, for --lengths.
        let mut used: Vec<u32> = if args.lengths {
            let spheres = world.spheres.iter().map(|(_, m)| *m);
            world.cylinder_materials.iter().copied().chain(spheres).collect()
        } else {
            Vec::new()
        };
        used.sort_unstable();
        used.dedup();
        let stem = args.output.with_extension("");
        // Each material's name as a file name: letters, digits, `-` and `_` kept, the rest `_`,
        // and the material's number added where two names would then be one.
        let file_names: Vec<String> = used
            .iter()
            .map(|&m| {
                world.materials[m as usize]
                    .name
                    .chars()
                    .map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' })
                    .collect()
            })
            .collect();
        let length_paths: Vec<PathBuf> = file_names
            .iter()
            .zip(&used)
            .map(|(name, m)| {
                let clash = file_names.iter().filter(|n| *n == name).count() > 1;
                let name = if clash { format!("{name}-{m}") } else { name.clone() };
                PathBuf::from(format!("{}.length.{name}.tif", stem.display()))
            })
            .collect();
        let projector = Projector::new(&world, &setup).with_lengths(used.clone());
        let bar = progress_bar(args.quiet, views.len() as u64, "views");
        let mut paths: Vec<&Path> = vec![&args.output];
        paths.extend(length_paths.iter().map(PathBuf::as_path));
        let io = |e: std::io::Error| format!("{}: cannot write: {e}", args.output.display());
        gencyl_render::formats::write_atomic_all(
            &paths,
            |outs| projector.write_stacks(outs, views.clone(), |n| bar.set_position(n as u64)),
            io,
        )
        .map_err(anyhow::Error::msg)?;
        bar.finish_and_clear();
        let t2 = Instant::now();
        let mut sidecar = projector.sidecar(views.clone(), &name);
        if args.lengths {
            let stacks: serde_json::Map<String, serde_json::Value> = used
                .iter()
                .zip(&length_paths)
                .map(|(&m, p)| {
                    let file = p.file_name().map(|n| n.to_string_lossy().into_owned());
                    (world.materials[m as usize].name.clone(), file.into())
                })
                .collect();
            sidecar["length_stacks"] = stacks.into();
        }
        let text = serde_json::to_string_pretty(&sidecar).expect("JSON of plain values");
        if let Err(e) = write_atomically(&sidecar_path, text.as_bytes()) {
            for p in paths {
                let _ = std::fs::remove_file(p);
            }
            return Err(e);
        }
        let s = &setup.scanner;
        let seconds = (t2 - t1).as_secs_f64();
        eprintln!(
            "{}: views {}..{} of {}, {}x{} pixels, {} rays per pixel, {}; {} cylinders; load and BVH {:.2} s, projections {:.2} s ({:.3} views/s); geometry in {}",
            args.output.display(),
            views.start,
            views.end,
            total,
            s.columns,
            s.rows,
            s.samples(),
            setup.quantity.name(),
            world.scene.len(),
            (t1 - t0).as_secs_f64(),
            seconds,
            views.len() as f64 / seconds.max(1e-9),
            sidecar_path.display()
        );
        Ok(())
    })
}

fn scatter_command(args: ScatterArgs) -> Result<()> {
    let pool = thread_pool(args.threads)?;
    check_output(&args.output, &["csv"])?;
    if let Some(p) = &args.plot {
        check_output(p, &["png"])?;
    }
    let section = match &args.profile {
        None => FiberSection::Ellipse {
            aspect: args.aspect,
        },
        Some(path) => {
            #[derive(serde::Deserialize)]
            #[serde(deny_unknown_fields)]
            struct ProfileFile {
                profile: Vec<[f64; 2]>,
            }
            let name = path.display();
            let bytes = limits::read_file(path, limits::MAX_SCENE_FILE, "profile file")
                .map_err(|e| anyhow::anyhow!("{name}: cannot read: {e}"))?;
            let text = std::str::from_utf8(&bytes)
                .map_err(|_| anyhow::anyhow!("{name}: not UTF-8 text"))?;
            let file: ProfileFile =
                toml::from_str(text).map_err(|e| anyhow::anyhow!("{name}: {}", e.message()))?;
            FiberSection::Profile(
                file.profile
                    .iter()
                    .map(|p| glam::DVec2::from_array(*p))
                    .collect(),
            )
        }
    };
    let g = Goniometer {
        section,
        rotation: args.rotation.to_radians(),
        eta: args.eta,
        sigma_a: args.sigma_a,
        tilt: args.tilt.to_radians(),
        theta_i: args.theta_i.to_radians(),
        phi_i: args.phi_i.to_radians(),
        rays: args.rays,
        max_order: args.max_order,
        bins: args.bins,
        seed: args.seed,
    };
    g.validate().map_err(anyhow::Error::msg)?;
    match (&args.map, args.sweep) {
        (Some(m), Some(_)) => check_output(m, &["png", "exr"])?,
        (None, None) => {}
        _ => bail!("--sweep and --map go together"),
    }
    let t0 = Instant::now();
    let s = pool.install(|| g.measure()).map_err(anyhow::Error::msg)?;
    let seconds = t0.elapsed().as_secs_f64();
    let map = match (&args.map, args.sweep) {
        (Some(_), Some(n)) => Some(scatter_map(&g, n, &pool)?),
        _ => None,
    };
    // The table, the plot and the map, all or none.
    let mut written: Vec<&Path> = Vec::new();
    let result = write_scatter(&args, &s, map.as_ref(), &mut written);
    if result.is_err() {
        for p in written {
            let _ = std::fs::remove_file(p);
        }
    }
    result?;
    let names = ["R", "TT", "TRT"];
    let label = |p: usize| match names.get(p) {
        Some(n) if p + 1 < s.orders => n.to_string(),
        _ if p + 1 == s.orders => format!("p>={p}"),
        _ => format!("p={p}"),
    };
    let per_order: Vec<String> = (0..s.orders)
        .map(|p| format!("{} {:.6}", label(p), s.azimuthal(p).iter().sum::<f64>()))
        .collect();
    eprintln!(
        "{}: {} rays ({} met the fiber) in {:.2} s ({:.0} rays/s); out {:.6} ({}), absorbed {:.6}, lost {:.2e}",
        args.output.display(),
        args.rays,
        s.hits,
        seconds,
        args.rays as f64 / seconds.max(1e-9),
        s.total(),
        per_order.join(", "),
        s.absorbed,
        s.lost
    );
    Ok(())
}

/// Writes the goniometer's table, plot and map, recording each file written.
fn write_scatter<'a>(
    args: &'a ScatterArgs,
    s: &Scattering,
    map: Option<&Film>,
    written: &mut Vec<&'a Path>,
) -> Result<()> {
    write_atomically(&args.output, s.csv().as_bytes())?;
    written.push(&args.output);
    if let Some(plot) = &args.plot {
        let colours = [[220, 40, 40], [40, 160, 40], [40, 80, 220], [150, 150, 150]];
        let curves: Vec<Vec<f64>> = (0..s.orders).map(|p| s.azimuthal(p)).collect();
        let drawn: Vec<plot::Curve> = curves
            .iter()
            .enumerate()
            .map(|(p, y)| plot::Curve {
                y,
                colour: colours[p.min(3)],
            })
            .collect();
        plot::write_line_plot(plot, &drawn, (-180.0, 180.0), &[-90.0, 0.0, 90.0])
            .map_err(anyhow::Error::msg)?;
        written.push(plot);
        eprintln!(
            "{}: power per phi bin, -180 to 180 degrees (grid at -90, 0, 90); red R, green TT, blue TRT, grey higher orders",
            plot.display()
        );
    }
    if let (Some(path), Some(film)) = (&args.map, map) {
        film.write(path)?;
        written.push(path);
        eprintln!(
            "{}: {} incident azimuths x {} outgoing azimuth bins (phi_o - phi_i of the first azimuth, -180 to 180 degrees, shifted to the nearest bin)",
            path.display(),
            film.frame.1,
            film.frame.0
        );
    }
    Ok(())
}

/// The goniometer at `n` incident azimuths `phi_i + 360 k / n` on one fiber (its section fixed
/// in the world): each row the power per bin of the outgoing azimuth `phi_o - phi_i` (the
/// first azimuth's; summed over `theta_o`), per order and in total.
fn scatter_map(g: &Goniometer, n: u32, pool: &rayon::ThreadPool) -> Result<Film> {
    let b = g.bins;
    let orders = g.max_order + 1;
    let mut names: Vec<String> = ["R", "G", "B", "A", "total"].map(String::from).to_vec();
    names.extend((0..orders).map(|p| format!("p{p}")));
    let refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let mut film = Film::new((b as u32, n), Window::full(b as u32, n), &refs);
    let bar = progress_bar(false, u64::from(n), "incident azimuths");
    for k in 0..n {
        let step = std::f64::consts::TAU * f64::from(k) / f64::from(n);
        // The same fiber lit from another azimuth: its section keeps its place in the world
        // (the rotation is measured from the light).
        let m = Goniometer {
            phi_i: g.phi_i + step,
            rotation: g.rotation - step,
            ..g.clone()
        };
        let s = pool.install(|| m.measure()).map_err(anyhow::Error::msg)?;
        // Relative bin j holds phi = phi_o - phi_i: its absolute azimuth is phi + phi_i.
        let shift = (step / std::f64::consts::TAU * b as f64).round() as usize;
        let per: Vec<Vec<f64>> = (0..orders).map(|p| s.azimuthal(p)).collect();
        for j in 0..b {
            let x = ((j + shift) % b) as u32;
            let px = film.pixel_mut(x, k);
            let total: f64 = per.iter().map(|v| v[j]).sum();
            px[4] = total as f32;
            for p in 0..orders {
                px[5 + p] = per[p][j] as f32;
            }
        }
        bar.set_position(u64::from(k) + 1);
    }
    bar.finish_and_clear();
    let top = film
        .data
        .chunks(names.len())
        .fold(0.0f32, |m, px| m.max(px[4]));
    let channels = names.len();
    for px in film.data.chunks_mut(channels) {
        let v = if top > 0.0 { (px[4] / top).sqrt() } else { 0.0 };
        px[..3].fill(v);
        px[3] = 1.0;
    }
    Ok(film)
}

/// `a..b` (0-based, `b` excluded) within a scan of `total` views.
fn parse_views(text: &str, total: usize) -> Result<std::ops::Range<usize>> {
    let bad = || {
        anyhow::anyhow!("--views {text}: expected a..b, 0 <= a < b <= {total} (the scan's views)")
    };
    let (a, b) = text.split_once("..").ok_or_else(bad)?;
    let a: usize = a.trim().parse().map_err(|_| bad())?;
    let b: usize = b.trim().parse().map_err(|_| bad())?;
    if a < b && b <= total {
        Ok(a..b)
    } else {
        Err(bad())
    }
}

/// A progress bar on standard error over `len` `units` with elapsed time and ETA (hidden when
/// `quiet`).
fn progress_bar(quiet: bool, len: u64, units: &str) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{{spinner}} {{bar:40}} {{pos}}/{{len}} {units}, {{elapsed}} (ETA {{eta}})"
        ))
        .expect("a valid template"),
    );
    bar
}

/// Whether `path` names a `.hair` model (by its extension, in any case).
fn is_hair(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("hair"))
}

fn merge_command(args: MergeArgs) -> Result<()> {
    check_output(&args.output, &["png", "exr"])?;
    let parts = args
        .parts
        .iter()
        .map(|p| Film::read_exr_within(p, args.max_pixels))
        .collect::<Result<Vec<_>, _>>()?;
    let full = Film::merge(&parts).with_context(|| {
        let names: Vec<String> = args
            .parts
            .iter()
            .enumerate()
            .map(|(i, p)| format!("{i}: {}", p.display()))
            .collect();
        format!("cannot merge parts {}", names.join(", "))
    })?;
    full.write(&args.output)?;
    eprintln!(
        "{}: {}x{} from {} windows",
        args.output.display(),
        full.frame.0,
        full.frame.1,
        parts.len()
    );
    Ok(())
}

/// Overrides a yarn's or a ply's defaults with the options they share (the two specs have
/// these fields by the same names).
macro_rules! set_common {
    ($spec:ident, $c:expr) => {
        set(&mut $spec.radius_sd, $c.radius_sd);
        set(&mut $spec.aspect, $c.aspect);
        set(&mut $spec.aspect_sd, $c.aspect_sd);
        set(&mut $spec.segments, $c.segments);
        set(&mut $spec.seed, $c.seed);
        set(&mut $spec.material, $c.material.clone());
    };
}

fn generate_command(args: GenerateArgs) -> Result<()> {
    match args.kind {
        None => generate_hair(args.hair),
        Some(GenerateKind::Hair(hair)) => generate_hair(hair),
        Some(GenerateKind::Yarn(y)) => {
            let mut spec = phantom::YarnSpec::default();
            set(&mut spec.fibers, y.fibers);
            set(&mut spec.length, y.length);
            set(&mut spec.twist_deg, y.twist);
            set(&mut spec.packing, y.packing);
            set(&mut spec.radius, y.radius);
            set(&mut spec.section_twist, y.section_twist);
            set(&mut spec.migration, y.migration);
            set(&mut spec.migration_period, y.migration_period);
            set_common!(spec, y.common);
            write_phantom(&y.common, "yarn.toml", || phantom::generate_yarn(&spec))
        }
        Some(GenerateKind::Ply(p)) => {
            let mut spec = phantom::PlySpec::default();
            if p.fibers.is_some() {
                spec.packing = 0.0;
            }
            set(&mut spec.fibers, p.fibers);
            set(&mut spec.length, p.length);
            set(&mut spec.width, p.width);
            set(&mut spec.thickness, p.thickness);
            set(&mut spec.packing, p.packing);
            set(&mut spec.radius, p.radius);
            set(&mut spec.waviness, p.waviness);
            set(&mut spec.waviness_period, p.waviness_period);
            set_common!(spec, p.common);
            write_phantom(&p.common, "ply.toml", || phantom::generate_ply(&spec))
        }
    }
}

/// Overrides a default with an option given on the command line.
fn set<T>(field: &mut T, value: Option<T>) {
    if let Some(v) = value {
        *field = v;
    }
}

/// Generates a phantom and writes its scene, its truth (STEM.truth.json) and, if asked, its
/// label volume (STEM.labels.tif); nothing is written unless the phantom is made.
fn write_phantom(
    out: &PhantomOutput,
    default: &str,
    generate: impl FnOnce() -> Result<phantom::Phantom, String>,
) -> Result<()> {
    let t0 = Instant::now();
    let scene_path = out.output.clone().unwrap_or_else(|| PathBuf::from(default));
    check_output(&scene_path, &["toml"])?;
    let stem = scene_path.with_extension("");
    let sibling = |suffix: &str| PathBuf::from(format!("{}.{suffix}", stem.display()));
    let (truth_path, labels_path) = (sibling("truth.json"), sibling("labels.tif"));
    if let Some(v) = out.labels
        && !(v > 0.0 && v.is_finite())
    {
        bail!("--labels: the voxel size must be positive and finite, got {v}");
    }
    let made = generate().map_err(anyhow::Error::msg)?;
    let mut truth: serde_json::Value =
        serde_json::from_str(&made.truth.to_json()).context("the truth as JSON")?;
    let labels = match out.labels {
        Some(voxel) => {
            let grid = made
                .truth
                .grid(voxel)
                .map_err(|e| anyhow::anyhow!("--labels {voxel}: {e}"))?;
            let desc =
                SceneDescription::parse(&made.scene_toml, &scene_path.display().to_string())?;
            let labels = phantom::label_volume(&desc.cylinders, &made.fiber_of_cylinder(), grid)
                .map_err(|e| anyhow::anyhow!("--labels {voxel}: {e}"))?;
            truth["labels"] = serde_json::json!({
                "file": labels_path.file_name().map(|n| n.to_string_lossy().into_owned()),
                "origin": grid.origin,
                "voxel": grid.voxel,
                "size": grid.size,
                "layout": "page k is the z slice at origin.z + (k + 0.5) voxel; row j, column i the voxel centred at origin + (i + 0.5, j + 0.5, k + 0.5) voxel; 0 background, fiber label (index + 1) inside",
            });
            Some((grid, labels))
        }
        None => None,
    };
    let text = serde_json::to_string_pretty(&truth).context("the truth as JSON")?;
    // The scene, its truth and its labels, all or none.
    let written = (|| -> Result<()> {
        write_atomically(&scene_path, made.scene_toml.as_bytes())?;
        write_atomically(&truth_path, text.as_bytes())?;
        if let Some((grid, labels)) = &labels {
            phantom::write_labels_tiff(&labels_path, labels, *grid).map_err(anyhow::Error::msg)?;
        }
        Ok(())
    })();
    if written.is_err() {
        for p in [&scene_path, &truth_path, &labels_path] {
            let _ = std::fs::remove_file(p);
        }
    }
    written?;
    let t = &made.truth;
    eprintln!(
        "{}: {} fibers, fiber volume fraction {:.6} (of the envelope, exact from the geometry); truth in {}{}; {:.2} s",
        scene_path.display(),
        t.fiber_count,
        t.fiber_volume_fraction,
        truth_path.display(),
        labels.as_ref().map_or(String::new(), |(g, _)| format!(
            ", labels ({} x {} x {}) in {}",
            g.size[0],
            g.size[1],
            g.size[2],
            labels_path.display()
        )),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

fn generate_hair(args: HairArgs) -> Result<()> {
    let t0 = Instant::now();
    check_output(&args.output, &["hair"])?;
    let points = args.strands as u64 * (args.segments as u64 + 1);
    if points > u32::MAX as u64 {
        bail!(
            "--strands {} --segments {}: {points} points, more than the {} a .hair file can hold (its point count is a u32)",
            args.strands,
            args.segments,
            u32::MAX
        );
    }
    // Points in memory (f64 positions and thickness), the file's bytes (f32 positions and
    // thickness), and the file's copy on its way to disk.
    limits::check_memory(points * (32 + 16 + 16), "generating the model").map_err(|m| {
        anyhow::anyhow!(
            "--strands {} --segments {}: {m}",
            args.strands,
            args.segments
        )
    })?;
    let (strands, thickness) =
        synth::hair_model(args.strands as usize, args.segments as usize, args.seed);
    let bytes = hair::write_hair(&strands, Some(&thickness), "gencyl generate");
    drop((strands, thickness));
    write_atomically(&args.output, &bytes)?;
    eprintln!(
        "{}: {} strands x {} segments ({} bytes) in {:.2} s",
        args.output.display(),
        args.strands,
        args.segments,
        bytes.len(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The image `bench` casts about `rays` camera rays through: 4:3, one ray per pixel; refused
/// where the `sets` ray sets of that many rays held at once would not fit in memory.
fn bench_image(rays: u32, sets: u64) -> Result<(u32, u32)> {
    let width = ((rays as f64 * 4.0 / 3.0).sqrt().round() as u32).max(4);
    let height = (width * 3 / 4).max(3);
    let bytes = sets * width as u64 * height as u64 * std::mem::size_of::<gencyl::Ray>() as u64;
    limits::check_memory(bytes, &format!("--rays {rays}")).map_err(anyhow::Error::msg)?;
    Ok((width, height))
}

/// The camera rays of `bench`: the scene's camera (or one framed on `world`) at
/// `width x height`, one ray through each pixel centre, row by row.
fn bench_rays(
    world: &World,
    camera: Option<gencyl_render::optics::Camera>,
    (width, height): (u32, u32),
) -> Vec<gencyl::Ray> {
    let mut camera =
        camera.unwrap_or_else(|| builtin::framed_camera(world.bounds(), width, height));
    camera.width = width;
    camera.height = height;
    let rays = camera.rays();
    (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .map(|(x, y)| rays.ray(x as f64 + 0.5, y as f64 + 0.5))
        .collect()
}

fn export_command(args: ExportArgs) -> Result<()> {
    check_output(&args.output, &["toml"])?;
    for p in [&args.camera_rays, &args.incoherent_rays]
        .into_iter()
        .flatten()
    {
        check_output(p, &["csv", "txt", "rays"])?;
    }
    if args.radius.is_some() && !is_hair(&args.scene) {
        bail!("--radius applies to .hair models; a scene file sets radii itself");
    }
    let desc = SceneDescription::load_any(&args.scene, args.radius)?;
    let tables = gencyl_render::scene_file::export::cylinder_tables(&desc.cylinders)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.scene.display()))?;
    let header = format!(
        "# {} cylinders of {}, written by gencyl export (interface.md [[cylinder]] tables)\n\n",
        desc.cylinders.len(),
        args.scene.display()
    );
    write_atomically(&args.output, (header + &tables).as_bytes())?;
    eprintln!(
        "{}: {} cylinders",
        args.output.display(),
        desc.cylinders.len()
    );
    if args.camera_rays.is_some() || args.incoherent_rays.is_some() {
        // The camera and incoherent sets.
        let image = bench_image(args.rays, 2)?;
        let camera = desc.camera;
        let world = World::new(desc);
        let [camera_rays, incoherent] = bench_ray_sets(&world, camera, image);
        for (path, rays, kind) in [
            (&args.camera_rays, camera_rays, "camera"),
            (&args.incoherent_rays, incoherent, "incoherent"),
        ] {
            if let Some(path) = path {
                write_rays(path, &rays)?;
                eprintln!(
                    "{}: {} {kind} rays ({}x{} image)",
                    path.display(),
                    rays.len(),
                    image.0,
                    image.1
                );
            }
        }
    }
    Ok(())
}

/// Writes rays as a ray file (interface.md section 3), with a header line.
fn write_rays(path: &Path, rays: &[gencyl::Ray]) -> Result<()> {
    let mut text = String::from("ox,oy,oz,dx,dy,dz\n");
    for r in rays {
        use std::fmt::Write as _;
        let (o, d) = (r.origin, r.dir);
        let _ = writeln!(
            text,
            "{:?},{:?},{:?},{:?},{:?},{:?}",
            o.x, o.y, o.z, d.x, d.y, d.z
        );
    }
    write_atomically(path, text.as_bytes())
}

/// `rays` parted into those that hit the world (nearest-hit query, as `bench` times it) and
/// those that miss, each in its order.
fn split_by_hit(world: &World, rays: &[gencyl::Ray]) -> (Vec<gencyl::Ray>, Vec<gencyl::Ray>) {
    let mut scratch = Scratch::default();
    rays.iter().partition(|r| {
        world
            .intersect(r, (0.0, f64::INFINITY), None, &mut scratch)
            .is_some()
    })
}

/// Bench's two ray sets on a scene: `camera`, one ray per pixel centre of `image`, and
/// `incoherent`, as many rays from a sphere about the fibers' box through random points of it
/// (a fixed seed).
fn bench_ray_sets(
    world: &World,
    camera: Option<gencyl_render::optics::Camera>,
    image: (u32, u32),
) -> [Vec<gencyl::Ray>; 2] {
    let camera_rays = bench_rays(world, camera, image);
    let b = world.scene.bvh().bounds();
    let incoherent = synth::rays_through_box(
        camera_rays.len(),
        1,
        b.min,
        b.max,
        (b.max - b.min).max_element(),
    );
    [camera_rays, incoherent]
}

/// Writes `bytes` to `path` through a temporary file beside it, renamed into place: on error
/// nothing is left behind.
fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = path.with_extension("partial");
    let written = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path));
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        bail!("{}: cannot write: {e}", path.display());
    }
    Ok(())
}

/// CPU time of all the process's threads so far (Linux: the first field of each
/// `/proc/self/task/*/schedstat`, nanoseconds on the CPU), in seconds.
fn process_cpu_seconds() -> Option<f64> {
    let mut ns = 0u64;
    for task in std::fs::read_dir("/proc/self/task").ok()? {
        let stat = std::fs::read_to_string(task.ok()?.path().join("schedstat")).ok()?;
        ns += stat.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(ns as f64 * 1e-9)
}

/// `bench --render`: renders `args.render_scene` as its file says (the image is not kept) and
/// prints one CSV row: load and BVH (`prepare_s`), the render's wall clock (`render_s`), and
/// the CPU seconds of all threads over both (`cpu_s`).
fn bench_render(args: &BenchArgs) -> Result<()> {
    let pool = thread_pool(args.threads)?;
    let name = args
        .render_scene
        .file_stem()
        .map_or("render".into(), |s| s.to_string_lossy().into_owned());
    let cpu0 = process_cpu_seconds();
    let t0 = Instant::now();
    let desc = SceneDescription::load(&args.render_scene)?;
    let Some(camera) = desc.camera else {
        bail!(
            "{}: a bench render needs the scene's [camera]",
            args.render_scene.display()
        );
    };
    let table = desc.render;
    let world = World::new(desc);
    let settings = table.settings(&RenderTable::default());
    let window = Window::full(camera.width, camera.height);
    let t1 = Instant::now();
    let rendered = pool.install(|| integrator::render(&world, &camera, &settings, window, &|_| {}));
    let t2 = Instant::now();
    let cpu = process_cpu_seconds()
        .zip(cpu0)
        .map_or(f64::NAN, |(b, a)| b - a);
    let mut out = io::stdout().lock();
    writeln!(
        out,
        "render,segments,width,height,spp,max_depth,threads,prepare_s,render_s,cpu_s,non_finite_samples"
    )?;
    writeln!(
        out,
        "{name},{},{},{},{},{},{},{:.3},{:.3},{cpu:.2},{}",
        world.scene.len(),
        camera.width,
        camera.height,
        settings.spp,
        settings.max_depth,
        pool.current_num_threads(),
        (t1 - t0).as_secs_f64(),
        (t2 - t1).as_secs_f64(),
        rendered.non_finite_samples
    )?;
    Ok(())
}

fn bench_command(args: BenchArgs) -> Result<()> {
    if args.render {
        return bench_render(&args);
    }
    // The camera and incoherent sets, and with `--split` their parts as well.
    let (width, height) = bench_image(args.rays, if args.split { 4 } else { 2 })?;
    if args.large {
        limits::check_memory(
            1_600_000 * limits::PEAK_BYTES_PER_SEGMENT,
            "--large (the generated 1.6M-segment model)",
        )
        .map_err(anyhow::Error::msg)?;
    }
    let wanted = |list: &[String], name: &str| list.is_empty() || list.iter().any(|s| s == name);
    const SCENES: [&str; 5] = [
        "default",
        "ponytail",
        "ponytail-elliptical",
        "ponytail-trilobal",
        "generated-1.6M",
    ];
    for s in &args.scenes {
        if !SCENES.contains(&s.as_str()) {
            bail!("--scene {s}: the scenes are {}", SCENES.join(", "));
        }
        if s == "generated-1.6M" && !args.large {
            bail!("--scene generated-1.6M needs --large");
        }
    }
    let thread_counts = match args.threads {
        Some(t) => vec![limits::check_threads(t as usize).map_err(anyhow::Error::msg)?],
        None if rayon::current_num_threads() > 1 => vec![1, rayon::current_num_threads()],
        None => vec![1],
    };
    // Written with `?`, so a reader that stops early (`| head`) ends the run quietly.
    let mut out = io::stdout().lock();
    writeln!(
        out,
        "scene,segments,load_s,bvh_s,bytes_per_segment,peak_mib,rays_kind,threads,rays,rays_per_s,hit_fraction"
    )?;
    type Loader<'a> = Box<dyn Fn() -> Result<SceneDescription> + 'a>;
    let mut scenes: Vec<(&str, Loader)> = vec![
        ("default", Box::new(|| Ok(builtin::default_scene()))),
        (
            "ponytail",
            Box::new(|| Ok(SceneDescription::load(&args.ponytail)?)),
        ),
        (
            "ponytail-elliptical",
            Box::new(|| Ok(SceneDescription::load(&args.ponytail_elliptical)?)),
        ),
        (
            "ponytail-trilobal",
            Box::new(|| Ok(SceneDescription::load(&args.ponytail_trilobal)?)),
        ),
    ];
    if args.large {
        scenes.push((
            "generated-1.6M",
            Box::new(|| {
                let (strands, thickness) = synth::hair_model(100_000, 16, 1);
                let bytes = hair::write_hair(&strands, Some(&thickness), "bench");
                let path =
                    std::env::temp_dir().join(format!("gencyl-bench-{}.hair", std::process::id()));
                std::fs::write(&path, bytes)?;
                let d = SceneDescription::from_hair_file(&path, None).map_err(anyhow::Error::msg);
                std::fs::remove_file(&path)?;
                d
            }),
        ));
    }
    for (name, load) in scenes {
        if !wanted(&args.scenes, name) {
            continue;
        }
        // The peak resident memory of this scene's load and build (Linux: writing 5 to
        // clear_refs resets the high-water mark VmHWM).
        let _ = std::fs::write("/proc/self/clear_refs", "5");
        // The least of `builds` loads and builds (each world dropped before the next load;
        // the last one kept), and the peak of the first (later ones may find memory the
        // allocator kept from the ones before).
        let (mut load_s, mut bvh_s, mut peak_mib) = (f64::INFINITY, f64::INFINITY, f64::NAN);
        let mut built = None;
        for build in 0..args.builds {
            drop(built.take());
            let t0 = Instant::now();
            let desc = load()?;
            let t1 = Instant::now();
            let camera = desc.camera;
            let world = World::new(desc);
            let t2 = Instant::now();
            load_s = load_s.min((t1 - t0).as_secs_f64());
            bvh_s = bvh_s.min((t2 - t1).as_secs_f64());
            if build == 0 {
                peak_mib = limits::peak_resident_memory()
                    .map_or(f64::NAN, |b| b as f64 / (1 << 20) as f64);
            }
            built = Some((world, camera));
        }
        let (world, camera) = built.expect("at least one build");
        let n = world.scene.len();
        let [camera_rays, incoherent] = bench_ray_sets(&world, camera, (width, height));
        let mut sets = Vec::new();
        for (kind, rays) in [("camera", camera_rays), ("incoherent", incoherent)] {
            if !wanted(&args.kinds, kind) {
                continue;
            }
            let parts = args.split.then(|| split_by_hit(&world, &rays));
            sets.push((kind.to_string(), rays));
            if let Some((hits, misses)) = parts {
                sets.push((format!("{kind}-hits"), hits));
                sets.push((format!("{kind}-misses"), misses));
            }
        }
        for (kind, rays) in &sets {
            for &threads in &thread_counts {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()?;
                let start = Instant::now();
                let hits: usize = pool.install(|| {
                    use rayon::prelude::*;
                    rays.par_chunks(256)
                        .with_max_len(1)
                        .map_init(Scratch::default, |scratch, chunk| {
                            chunk
                                .iter()
                                .filter(|r| {
                                    world
                                        .intersect(r, (0.0, f64::INFINITY), None, scratch)
                                        .is_some()
                                })
                                .count()
                        })
                        .sum()
                });
                let secs = start.elapsed().as_secs_f64();
                writeln!(
                    out,
                    "{name},{n},{load_s:.3},{bvh_s:.3},{:.0},{peak_mib:.0},{kind},{threads},{},{:.0},{:.3}",
                    world.scene.memory_bytes() as f64 / n.max(1) as f64,
                    rays.len(),
                    rays.len() as f64 / secs,
                    hits as f64 / rays.len() as f64
                )?;
            }
        }
    }
    Ok(())
}

fn raycast_command(args: RaycastArgs) -> Result<()> {
    let pool = thread_pool(args.threads)?;
    let threads = pool.current_num_threads();
    pool.install(|| {
        let t0 = Instant::now();
        let desc = SceneDescription::load(&args.scene)?;
        let t1 = Instant::now();
        let scene = Scene::with_strands(desc.cylinders, desc.strands);
        let t2 = Instant::now();
        let rays = raycast::read_rays(&args.rays)?;
        let t3 = Instant::now();

        let stdout = io::stdout().lock();
        let mut out = io::BufWriter::with_capacity(1 << 20, stdout);
        let stats = raycast::raycast(&scene, &rays, args.tmin, RaycastOptions { all: args.all }, &mut out)?;
        out.flush()?;
        let t4 = Instant::now();

        if args.stats {
            let bvh = scene.bvh().stats();
            let n = scene.len();
            let ms = |a: Instant, b: Instant| (b - a).as_secs_f64() * 1e3;
            let mut e = io::stderr().lock();
            writeln!(
                e,
                "scene: {n} cylinders; prepared in {:.1} ms (read and build {:.1} ms, BVH {:.1} ms: {} pieces, {} nodes, depth {}, {:.0} bytes/cylinder; {:.0} bytes/cylinder with the cylinders)",
                ms(t0, t2),
                ms(t0, t1),
                ms(t1, t2),
                bvh.primitives,
                bvh.nodes,
                bvh.depth,
                bvh.bytes as f64 / n.max(1) as f64,
                scene.memory_bytes() as f64 / n.max(1) as f64,
            )?;
            writeln!(e, "rays: {} read in {:.1} ms", rays.len(), ms(t2, t3))?;
            writeln!(
                e,
                "intersect: {:.1} ms on {threads} thread{}, {:.0} rays/s, {} hits (writing took {:.1} ms more)",
                stats.intersect_time.as_secs_f64() * 1e3,
                if threads == 1 { "" } else { "s" },
                stats.rays_per_second(),
                stats.rows,
                ms(t3, t4) - stats.intersect_time.as_secs_f64() * 1e3,
            )?;
            write!(e, "{}", query_report(&stats.counts))?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The report names the kinds of queries made, with their hit shares, and gives the per
    /// query figures as counts over queries.
    #[test]
    fn counts_report_divides_by_the_queries() {
        let c = QueryCounts {
            nearest: 300,
            nearest_hits: 75,
            any: 100,
            any_hits: 66,
            nodes: 4000,
            pieces: 1000,
            culls: 800,
            cleared: 600,
            exact: 200,
            exact_leaving: 100,
            ..QueryCounts::default()
        };
        assert_eq!(
            counts_report(&c),
            "queries: 300 nearest-hit (25.0% hit), 100 any-hit (66.0% blocked)\n\
             per query: 10.00 BVH nodes, 2.50 cylinder pieces reached, 2.00 culls (75.0% cleared), \
             0.500 exact tests, 0.250 on the fiber the ray leaves\n"
        );
        let all = QueryCounts {
            all: 4,
            ..QueryCounts::default()
        };
        assert!(counts_report(&all).starts_with("queries: 4 all-hits\n"));
        assert!(counts_report(&QueryCounts::default()).starts_with("queries: none\n"));
    }
}
