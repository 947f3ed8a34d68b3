//! The `gencyl` command: exact ray casting of generalized cylinders (hair fibers).
//!
//! `gencyl raycast SCENE RAYS` writes the hits of every ray as CSV (see
//! `gencyl_render::raycast` and interface.md section 3); `gencyl render [SCENE]` renders a
//! PNG (the built-in scene without SCENE).

use std::io::{self, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use gencyl_render::raycast::{self, RaycastOptions};
use gencyl_render::scene::{Scene, SceneDescription, SceneError};
use gencyl_render::{hair, render};

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
    /// Render a scene to a PNG image: without SCENE, the built-in tuft of curly, elliptical,
    /// twisted fibers; with SCENE, its `[[cylinder]]`s, framed automatically.
    Render(RenderArgs),
}

#[derive(Debug, clap::Args)]
struct RenderArgs {
    /// A scene file (TOML, `[[cylinder]]` tables) or a hair model (`.hair`, Cem Yuksel's
    /// format); default: the built-in scene.
    scene: Option<PathBuf>,
    /// Fiber radius for a `.hair` model (default: half the file's thickness).
    #[arg(long, allow_negative_numbers = true)]
    radius: Option<f64>,
    /// Output image (PNG).
    #[arg(short, long, default_value = "gencyl.png")]
    output: PathBuf,
    /// Image width in pixels (the height follows the 4:3 aspect).
    #[arg(long, value_parser = clap::value_parser!(u32).range(8..=16384))]
    width: Option<u32>,
    /// Samples per pixel.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=4096))]
    spp: Option<u32>,
    /// Seed of the per-pixel sample streams.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
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
    match cli.command {
        Command::Raycast(args) => raycast_command(args),
        Command::Render(args) => render_command(args),
    }
}

fn render_command(args: RenderArgs) -> Result<()> {
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(n) = args.threads {
        pool = pool.num_threads(n as usize);
    }
    let pool = pool.build().context("cannot start the worker threads")?;
    pool.install(|| {
        let t0 = Instant::now();
        let (cylinders, mut stage) = match &args.scene {
            None => render::default_scene(),
            Some(path) if path.extension().is_some_and(|e| e == "hair") => {
                let name = path.display().to_string();
                let bytes = std::fs::read(path).with_context(|| format!("cannot read {name}"))?;
                let hair = hair::parse_hair(&bytes, &name)?;
                if let Some(r) = args.radius
                    && !(r.is_finite() && r > 0.0)
                {
                    anyhow::bail!("--radius must be positive and finite, got {r}");
                }
                let cylinders = hair::strands_to_cylinders(&hair.to_strands(args.radius), &name)?;
                let stage = render::framed_stage(&cylinders);
                (cylinders, stage)
            }
            Some(path) => {
                let cylinders = SceneDescription::load(path)?.cylinders;
                let stage = render::framed_stage(&cylinders);
                (cylinders, stage)
            }
        };
        if let Some(w) = args.width {
            stage.camera.height = (w * 3 / 4).max(1);
            stage.camera.width = w;
        }
        if let Some(spp) = args.spp {
            stage.spp = spp;
        }
        stage.seed = args.seed;
        let scene = Scene::new(cylinders);
        let t1 = Instant::now();
        let image = render::render(&scene, &stage);
        let t2 = Instant::now();
        render::write_png(&image, &args.output)
            .with_context(|| format!("cannot write {}", args.output.display()))?;
        eprintln!(
            "{}: {}x{}, {} spp, {} cylinders; scene {:.2} s, render {:.2} s",
            args.output.display(),
            stage.camera.width,
            stage.camera.height,
            stage.spp,
            scene.cylinders().len(),
            (t1 - t0).as_secs_f64(),
            (t2 - t1).as_secs_f64()
        );
        Ok(())
    })
}

fn raycast_command(args: RaycastArgs) -> Result<()> {
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(n) = args.threads {
        pool = pool.num_threads(n as usize);
    }
    let pool = pool.build().context("cannot start the worker threads")?;
    let threads = pool.current_num_threads();
    pool.install(|| {
        let t0 = Instant::now();
        let desc = SceneDescription::load(&args.scene)?;
        let t1 = Instant::now();
        let scene = Scene::new(desc.cylinders);
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
            let n = scene.cylinders().len();
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
        }
        Ok(())
    })
}
