//! Writes a random fiber scene and random rays aimed into it, for benchmarks of
//! `gencyl raycast`:
//!
//! ```text
//! cargo run --release -p gencyl-render --example random_scene -- OUT_DIR [FIBERS] [RAYS] [SEED] [ELLIPTICAL_FRACTION]
//! gencyl raycast --stats OUT_DIR/scene.toml OUT_DIR/rays.csv > /dev/null
//! ```
//!
//! Defaults: 1,000 curved round fibers about 1 unit long, radius 0.02, midpoints in the unit
//! cube; 100,000 rays from a sphere of radius 2 about the cube's centre, aimed at uniform
//! points in the cube; seed 1; no elliptical fibers. It also prints the BVH's build time and
//! size for that scene.

use std::time::Instant;

use gencyl_render::accel::Scene;
use gencyl_render::scenes::synth::{FiberParams, random_fibers, random_rays, rays_csv, scene_toml};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.is_empty() || args[0].starts_with('-') {
        eprintln!(
            "usage: random_scene OUT_DIR [FIBERS=1000] [RAYS=100000] [SEED=1] [ELLIPTICAL_FRACTION=0]"
        );
        std::process::exit(2);
    }
    let arg = |i: usize, default: f64| -> Result<f64, std::num::ParseFloatError> {
        args.get(i).map_or(Ok(default), |s| s.parse::<f64>())
    };
    let dir = std::path::Path::new(&args[0]);
    let params = FiberParams {
        count: arg(1, 1000.0)? as usize,
        elliptical_fraction: arg(4, 0.0)?,
        ..FiberParams::default()
    };
    let n_rays = arg(2, 100_000.0)? as usize;
    let seed = arg(3, 1.0)? as u64;
    std::fs::create_dir_all(dir)?;
    let specs = random_fibers(&params, seed);
    std::fs::write(dir.join("scene.toml"), scene_toml(&specs))?;
    std::fs::write(
        dir.join("rays.csv"),
        rays_csv(&random_rays(n_rays, seed + 1, &params)),
    )?;

    let cylinders: Vec<_> = specs.iter().map(|s| s.build()).collect::<Result<_, _>>()?;
    let t = Instant::now();
    let scene = Scene::new(cylinders);
    let build = t.elapsed();
    let s = scene.bvh().stats();
    println!(
        "wrote {} fibers and {n_rays} rays to {}; BVH: built in {:.2} ms, {} pieces, {} nodes, {} leaves, depth {}, {:.0} bytes/cylinder ({:.0} with the cylinders)",
        specs.len(),
        dir.display(),
        build.as_secs_f64() * 1e3,
        s.primitives,
        s.nodes,
        s.leaves,
        s.depth,
        s.bytes as f64 / specs.len().max(1) as f64,
        scene.memory_bytes() as f64 / specs.len().max(1) as f64,
    );
    Ok(())
}
