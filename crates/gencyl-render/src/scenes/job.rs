//! A render made ready: what the scene leaves out supplied (a framed camera, default lights),
//! the caller's settings over the scene's `[render]` table, the window checked against the
//! frame and the memory it needs. The command line and the Python bindings both render through
//! [`plan`], so the same request gives the same pixels and the same errors.

use crate::formats::Window;
use crate::limits;
use crate::optics::Camera;
use crate::scenes::builtin;
use crate::settings::{RenderSettings, RenderTable};
use crate::transport::World;

/// What a caller may set over the scene's own camera and `[render]` table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderRequest {
    /// Integrator, samples, depth and seed; each given one wins over the scene's.
    pub overrides: RenderTable,
    /// Image width in pixels; the height keeps the camera's aspect ratio.
    pub width: Option<u32>,
    /// Only this window of the frame (checked against the frame by [`plan`]).
    pub crop: Option<Window>,
    /// Most pixels the rendered window may have.
    pub max_pixels: u64,
}

impl Default for RenderRequest {
    fn default() -> Self {
        RenderRequest {
            overrides: RenderTable::default(),
            width: None,
            crop: None,
            max_pixels: limits::MAX_PIXELS,
        }
    }
}

/// The camera, settings and window of a render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderJob {
    /// The camera, at the frame's final size.
    pub camera: Camera,
    /// The merged settings.
    pub settings: RenderSettings,
    /// The pixels to render (the whole frame unless cropped).
    pub window: Window,
}

/// Why a request cannot be rendered. Each front end words the setting its own way (`--width`
/// on the command line, `width=` in Python); [`PlanError::message`] gives the rest.
#[derive(Clone, Debug, PartialEq)]
pub enum PlanError {
    /// The width would make the height (at the camera's aspect ratio) exceed 65536.
    Height {
        /// The width asked for.
        width: u32,
        /// The height it implies.
        height: u64,
        /// The camera's own width and height.
        aspect: (u32, u32),
    },
    /// The crop window is empty or reaches past the frame.
    Crop(String),
    /// The window has more than `max_pixels` pixels.
    Pixels {
        /// Window width.
        width: u32,
        /// Window height.
        height: u32,
        /// The limit.
        limit: u64,
    },
    /// The film would not fit in memory.
    Memory(String),
}

impl PlanError {
    /// What is wrong, without naming the setting (the caller prefixes it).
    pub fn message(&self) -> String {
        match self {
            PlanError::Height {
                height,
                aspect: (w, h),
                ..
            } => format!(
                "the height would be {height} pixels (the camera's aspect ratio is {w}:{h}), more than 65536"
            ),
            PlanError::Crop(m) | PlanError::Memory(m) => m.clone(),
            PlanError::Pixels {
                width,
                height,
                limit,
            } => format!(
                "the image would be {width}x{height} = {} pixels, more than the limit of {limit}",
                *width as u64 * *height as u64
            ),
        }
    }
}

/// Gives a world that has neither lights nor an environment the default lighting
/// ([`builtin::default_lighting`]); a world with either is left as it is.
pub fn light_if_unlit(world: &mut World) {
    if world.lights.is_empty() && world.environment.is_none() {
        let (light, env) = builtin::default_lighting(world.bounds());
        world.lights.push(light);
        world.environment = Some(env);
    }
}

/// The camera (the scene's, else one framed on the world at 640x480), resized to
/// `request.width`, the settings (`request.overrides`, else `table`, else the defaults) and the
/// window, checked: a height of at most 65536, a crop inside the frame, at most
/// `request.max_pixels` pixels, a film that fits in memory.
pub fn plan(
    world: &World,
    camera: Option<Camera>,
    table: &RenderTable,
    request: &RenderRequest,
) -> Result<RenderJob, PlanError> {
    let mut camera = camera.unwrap_or_else(|| builtin::framed_camera(world.bounds(), 640, 480));
    if let Some(w) = request.width {
        let h = (w as u64 * camera.height as u64 + camera.width as u64 / 2) / camera.width as u64;
        camera.height =
            u32::try_from(h.max(1))
                .ok()
                .filter(|&h| h <= 65536)
                .ok_or(PlanError::Height {
                    width: w,
                    height: h,
                    aspect: (camera.width, camera.height),
                })?;
        camera.width = w;
    }
    let settings = table.settings(&request.overrides);
    let window = match request.crop {
        Some(c) => c
            .within(camera.width, camera.height)
            .map_err(PlanError::Crop)?,
        None => Window::full(camera.width, camera.height),
    };
    let pixels = window.width() as u64 * window.height() as u64;
    if pixels > request.max_pixels {
        return Err(PlanError::Pixels {
            width: window.width(),
            height: window.height(),
            limit: request.max_pixels,
        });
    }
    // The film (f32 per channel), and a copy of it while it is encoded.
    let channels = settings.integrator.channels().len() as u64;
    limits::check_memory(
        pixels * channels * 4 * 2,
        &format!("a {}x{} image", window.width(), window.height()),
    )
    .map_err(PlanError::Memory)?;
    Ok(RenderJob {
        camera,
        settings,
        window,
    })
}

/// Warnings about a world and its camera, each a sentence naming the scene (`name`): no
/// geometry, a light that emits nothing, a camera that sees no geometry.
pub fn warnings(world: &World, camera: &Camera, name: &str) -> Vec<String> {
    let mut out = Vec::new();
    let empty = world.scene.is_empty() && world.spheres.is_empty() && world.planes.is_empty();
    if empty {
        out.push(format!(
            "{name} has no geometry (no cylinders, strands, hair, spheres or planes, or only empty or degenerate strands): the image shows only the sky"
        ));
    }
    for (i, light) in world.lights.iter().enumerate() {
        if light.is_dark() {
            out.push(format!(
                "{name}: light {i} emits nothing (its value is zero)"
            ));
        }
    }
    if !empty && !sees_geometry(world, camera) {
        out.push(format!(
            "the camera sees no geometry of {name} (no probe ray through a 64x48 grid of the image hits anything)"
        ));
    }
    out
}

/// Whether any ray of a 64x48 grid over the camera's image hits something.
fn sees_geometry(world: &World, camera: &Camera) -> bool {
    let mut scratch = Default::default();
    let rays = camera.rays();
    (0..48).any(|j| {
        (0..64).any(|i| {
            let x = (i as f64 + 0.5) / 64.0 * camera.width as f64;
            let y = (j as f64 + 0.5) / 48.0 * camera.height as f64;
            world
                .intersect(&rays.ray(x, y), (0.0, f64::INFINITY), None, &mut scratch)
                .is_some()
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene_file::SceneDescription;
    use crate::settings::Integrator;

    fn world(src: &str) -> (World, Option<Camera>, RenderTable) {
        let d = SceneDescription::parse(src, "s.toml").unwrap();
        let (camera, table) = (d.camera, d.render);
        (World::new(d), camera, table)
    }

    const FIBER: &str =
        "[[cylinder]]\nbezier = [[0,0,0],[1,0,0],[2,0,0],[3,0,0]]\nmajor_radius = [0.1, 0.1]\n";

    #[test]
    fn a_plan_frames_resizes_crops_and_checks() {
        let (mut w, cam, table) = world(&format!("{FIBER}[render]\nspp = 3\n"));
        assert!(w.lights.is_empty() && w.environment.is_none());
        light_if_unlit(&mut w);
        assert_eq!((w.lights.len(), w.environment.is_some()), (1, true), "lit");
        let req = RenderRequest {
            width: Some(320),
            overrides: RenderTable {
                integrator: Some(Integrator::Depth),
                ..Default::default()
            },
            ..Default::default()
        };
        let job = plan(&w, cam, &table, &req).unwrap();
        assert_eq!(
            (job.camera.width, job.camera.height),
            (320, 240),
            "framed 4:3"
        );
        assert_eq!(job.window, Window::full(320, 240));
        assert_eq!(
            (job.settings.spp, job.settings.integrator),
            (3, Integrator::Depth)
        );
        assert!(
            warnings(&w, &job.camera, "s.toml").is_empty(),
            "a framed fiber is seen"
        );

        let crop = |c: Window| RenderRequest {
            crop: Some(c),
            ..req
        };
        let job = plan(&w, cam, &table, &crop(Window::new(10, 20, 30, 25))).unwrap();
        assert_eq!(job.window, Window::new(10, 20, 30, 25));
        let e = plan(&w, cam, &table, &crop(Window::new(0, 0, 321, 5))).unwrap_err();
        assert!(
            e.message().contains("reaches past the 320x240 frame"),
            "{e:?}"
        );
        let e = plan(
            &w,
            cam,
            &table,
            &RenderRequest {
                max_pixels: 100,
                ..req
            },
        )
        .unwrap_err();
        assert!(e.message().contains("more than the limit of 100"), "{e:?}");
        let e = plan(
            &w,
            cam,
            &table,
            &RenderRequest {
                width: Some(65536 * 2),
                ..Default::default()
            },
        )
        .unwrap_err();
        assert!(
            matches!(e, PlanError::Height { height: 98304, .. }),
            "{e:?}"
        );
    }

    #[test]
    fn warnings_name_what_is_wrong() {
        let (w, ..) = world("");
        let cam = builtin::framed_camera(w.bounds(), 64, 48);
        let got = warnings(&w, &cam, "e.toml");
        assert_eq!(got.len(), 1, "{got:?}");
        assert!(got[0].starts_with("e.toml has no geometry"), "{got:?}");
        let (w, ..) = world(FIBER);
        let mut away = builtin::framed_camera(w.bounds(), 64, 48);
        away.look_at = away.position + (away.position - away.look_at);
        let got = warnings(&w, &away, "f.toml");
        assert!(
            got.len() == 1 && got[0].starts_with("the camera sees no geometry of f.toml"),
            "{got:?}"
        );
    }
}
