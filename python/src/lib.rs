//! `gencyl._gencyl`: the Python bindings' native half (the package `gencyl` re-exports it).
//!
//! They only translate: numpy arrays and keyword arguments in, numpy arrays out. Every check,
//! every hit and every pixel comes from `gencyl-render`, through the same functions as the
//! command line's (`raycast::cast_rays`, `scenes::job::plan`, `integrator::render`), so a
//! Python result equals the command line's to the bit. Long calls run with the GIL released
//! and look for Ctrl-C between blocks of rays and bands of rows.

use std::ffi::CString;
use std::path::PathBuf;

use gencyl::{Aabb, GeneralizedCylinder, Ray, StrandFraming};
use gencyl_render::accel::{Scene as Cylinders, SceneHit};
use gencyl_render::formats::Window;
use gencyl_render::limits;
use gencyl_render::optics::Camera;
use gencyl_render::optics::scanner::{CtSetup, Quantity};
use gencyl_render::raycast::{self, BLOCK, part_number, rays_from_arrays};
use gencyl_render::scene_file::{
    BuiltStrands, FiberInput, Key, SceneDescription, SceneError, StrandInput, StrandParts,
    build_fiber, build_strand_from,
};
use gencyl_render::scenes::job::{self, PlanError, RenderRequest};
use gencyl_render::scenes::phantom as phantoms;
use gencyl_render::settings::{Integrator, RenderTable};
use gencyl_render::transport::ct::Projector;
use gencyl_render::transport::scatter::{FiberSection, Goniometer};
use gencyl_render::transport::{World, integrator};
use numpy::ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::{
    PyFileNotFoundError, PyMemoryError, PyOSError, PyTypeError, PyUserWarning, PyValueError,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;

/// A scene ready for ray queries and renders: cylinders under a BVH, with their materials,
/// lights, camera and `[render]` settings.
#[pyclass(module = "gencyl", name = "Scene", frozen)]
struct PyScene {
    world: World,
    camera: Option<Camera>,
    table: RenderTable,
    /// The `[ct]` scan, if the scene file has one.
    ct: Option<CtSetup>,
    /// For messages: the file, or how the scene was made.
    name: String,
}

/// The Python exception for a scene that cannot be loaded: the same message the command line
/// prints (a located diagnostic for a bad scene file).
fn scene_error(e: SceneError) -> PyErr {
    match &e {
        SceneError::Invalid(d) => PyValueError::new_err(d.render()),
        SceneError::Read { error, .. } if error.kind() == std::io::ErrorKind::NotFound => {
            PyFileNotFoundError::new_err(e.to_string())
        }
        SceneError::Read { .. } => PyOSError::new_err(e.to_string()),
        SceneError::Model(m) => PyValueError::new_err(m.clone()),
    }
}

/// A rayon pool of `threads` (default: the global pool, all cores).
fn pool(threads: Option<usize>) -> PyResult<Option<rayon::ThreadPool>> {
    let Some(n) = threads else {
        return Ok(None);
    };
    let n = limits::check_threads(n).map_err(|m| PyValueError::new_err(format!("threads: {m}")))?;
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .map(Some)
        .map_err(|e| PyOSError::new_err(format!("cannot start the worker threads: {e}")))
}

/// Runs `f` on `pool` (or the global pool).
fn on<T: Send>(pool: &Option<rayon::ThreadPool>, f: impl FnOnce() -> T + Send) -> T {
    match pool {
        Some(p) => p.install(f),
        None => f(),
    }
}

/// `f` of the values of a C-contiguous float64 numpy array of shape `(n, *tail)`, and `n`.
/// (`f` runs with the GIL held, so no Python thread changes the values meanwhile.)
fn read_rows<R>(
    name: &str,
    obj: &Bound<'_, PyAny>,
    tail: &[usize],
    f: impl FnOnce(&[f64]) -> PyResult<R>,
) -> PyResult<(usize, R)> {
    let want = {
        let dims: Vec<String> = tail.iter().map(usize::to_string).collect();
        format!("(N, {})", dims.join(", "))
    };
    let Ok(arr) = obj.cast::<PyArrayDyn<f64>>() else {
        let dtype = obj
            .getattr("dtype")
            .and_then(|d| d.str().map(|s| s.to_string()));
        return Err(PyTypeError::new_err(match dtype {
            Ok(d) => format!(
                "{name} must be a float64 array of shape {want}, got dtype {d} (np.asarray({name}, dtype=np.float64) converts it)"
            ),
            Err(_) => format!(
                "{name} must be a numpy float64 array of shape {want}, got {}",
                obj.get_type().name().map_or("?".into(), |n| n.to_string())
            ),
        }));
    };
    let shape = arr.shape();
    if shape.len() != tail.len() + 1 || shape[1..] != *tail {
        return Err(PyValueError::new_err(format!(
            "{name} must have shape {want}, got {shape:?}"
        )));
    }
    if !arr.is_c_contiguous() {
        return Err(PyValueError::new_err(format!(
            "{name} must be C-contiguous (np.ascontiguousarray({name}) copies it)"
        )));
    }
    let n = shape[0];
    if let Ok(values) = arr.readonly().as_slice() {
        return Ok((n, f(values)?));
    }
    // C-contiguous but misaligned (as arrays rebuilt from a byte stream can be): an aligned
    // copy.
    let copy = arr.call_method0("copy")?;
    let copy = copy.cast::<PyArrayDyn<f64>>()?.readonly();
    let values = copy
        .as_slice()
        .map_err(|e| PyValueError::new_err(format!("{name}: {e}")))?;
    Ok((n, f(values)?))
}

/// The values of a float64 array of shape `(n, *tail)` ([`read_rows`]), copied, and `n`.
fn rows_of(name: &str, obj: &Bound<'_, PyAny>, tail: &[usize]) -> PyResult<(usize, Vec<f64>)> {
    read_rows(name, obj, tail, |v| Ok(v.to_vec()))
}

/// Rays from `(M, 3)` origin and direction arrays, each checked as a ray file's line is (in
/// parallel on `pool`): the error names the first bad row. The arrays are read in place, with
/// the GIL held (a few nanoseconds a ray), so no Python thread changes them meanwhile.
fn rays_of(
    origins: &Bound<'_, PyAny>,
    directions: &Bound<'_, PyAny>,
    pool: &Option<rayon::ThreadPool>,
) -> PyResult<Vec<Ray>> {
    let (m, rays) = read_rows("origins", origins, &[3], |o| {
        let m = o.len() / 3;
        if u32::try_from(m).is_err() {
            return Err(PyValueError::new_err(format!(
                "{m} rays: at most {} per call (ray numbers are 32-bit)",
                u32::MAX
            )));
        }
        let (_, rays) = read_rows("directions", directions, &[3], |d| {
            if d.len() != o.len() {
                return Err(PyValueError::new_err(format!(
                    "origins has {m} rows and directions {}: one of each per ray",
                    d.len() / 3
                )));
            }
            on(pool, || rays_from_arrays(o, d))
                .map_err(|(i, e)| PyValueError::new_err(format!("ray {i}: {e}")))
        })?;
        Ok(rays)
    })?;
    debug_assert_eq!(m, rays.len());
    Ok(rays)
}

/// A value given once for every fiber or strand, or as `(start, end)`.
#[derive(FromPyObject)]
enum Pair {
    One(f64),
    Two([f64; 2]),
}

impl Pair {
    fn get(&self) -> [f64; 2] {
        match *self {
            Pair::One(x) => [x, x],
            Pair::Two(p) => p,
        }
    }
}

/// The argument a [`Key`] is about, for messages.
fn argument(key: Key) -> &'static str {
    match key {
        Key::Bezier => "bezier",
        Key::MajorRadius => "major_radius",
        Key::MinorRadius => "minor_radius",
        Key::Rotation => "rotation",
        Key::NormalHint => "normal_hint",
        Key::Points => "points",
        Key::Radius => "radius",
        Key::Ellipticity => "ellipticity",
        Key::Twist => "twist",
        Key::Whole => "the values together",
    }
}

/// Checks that `n` cylinders fit in a scene and in memory (as a scene file's are checked).
fn fits(argument: &str, n: u64, what: &str) -> PyResult<()> {
    if n > Cylinders::MAX_CYLINDERS as u64 {
        return Err(PyValueError::new_err(format!(
            "{argument}: {n} {what}, more than the {} a scene holds",
            Cylinders::MAX_CYLINDERS
        )));
    }
    limits::check_memory(
        n.saturating_mul(limits::PEAK_BYTES_PER_SEGMENT),
        &format!("{argument}: {n} {what}"),
    )
    .map_err(PyMemoryError::new_err)
}

/// Warns in Python (a `UserWarning`).
fn warn(py: Python<'_>, message: &str) -> PyResult<()> {
    let text = CString::new(message.replace('\0', " ")).expect("no NUL left");
    PyErr::warn(py, &py.get_type::<PyUserWarning>(), &text, 1)
}

/// The integrator named `name`.
fn parse_integrator(name: Option<&str>) -> PyResult<Option<Integrator>> {
    name.map(str::parse::<Integrator>)
        .transpose()
        .map_err(PyValueError::new_err)
}

/// `v`, checked to be in `1..=hi`.
fn checked<T: Copy + PartialOrd + From<u8> + std::fmt::Display>(
    name: &str,
    v: Option<T>,
    hi: T,
) -> PyResult<Option<T>> {
    match v {
        Some(x) if !(x >= T::from(1) && x <= hi) => Err(PyValueError::new_err(format!(
            "{name} must be in 1..={hi}, got {x}"
        ))),
        _ => Ok(v),
    }
}

/// The film channels of an integrator.
fn channel_names(i: Integrator) -> Vec<String> {
    i.channels().iter().map(|c| c.to_string()).collect()
}

impl PyScene {
    /// [`job::plan`] for this scene, its errors worded for Python.
    fn plan(&self, request: &RenderRequest) -> PyResult<job::RenderJob> {
        let name = &self.name;
        job::plan(&self.world, self.camera, &self.table, request).map_err(|e| {
            PyValueError::new_err(match &e {
                PlanError::Height { width, .. } => format!("width={width}: {}", e.message()),
                PlanError::Crop(m) => format!("crop: {m}"),
                PlanError::Pixels { .. } => format!(
                    "{name}: {} (the image must fit in memory; max_pixels= raises the limit)",
                    e.message()
                ),
                PlanError::Memory(m) => format!("{name}: {m}"),
            })
        })
    }

    fn from_description(desc: SceneDescription, name: String) -> PyResult<Self> {
        if desc.cylinders.len() > Cylinders::MAX_CYLINDERS {
            return Err(PyValueError::new_err(format!(
                "{name}: {} cylinders, more than the {} a scene holds",
                desc.cylinders.len(),
                Cylinders::MAX_CYLINDERS
            )));
        }
        let (camera, table, ct) = (desc.camera, desc.render, desc.ct.clone());
        let mut world = World::new(desc);
        job::light_if_unlit(&mut world);
        Ok(PyScene {
            world,
            camera,
            table,
            ct,
            name,
        })
    }

    fn from_cylinders_built(
        py: Python<'_>,
        built: Vec<Result<GeneralizedCylinder, (Key, String)>>,
        what: &str,
    ) -> PyResult<Self> {
        let mut cylinders = Vec::with_capacity(built.len());
        for (i, b) in built.into_iter().enumerate() {
            cylinders.push(b.map_err(|(key, m)| {
                PyValueError::new_err(format!("{what} {i}: {m} ({})", argument(key)))
            })?);
        }
        let desc = SceneDescription::from_cylinders(cylinders);
        py.detach(|| PyScene::from_description(desc, format!("the {what}s")))
    }
}

#[pymethods]
impl PyScene {
    /// Loads a TOML scene file or a `.hair` model (its strands in the built-in fiber material;
    /// `radius`, for `.hair` only, overrides the file's thickness). Raises `FileNotFoundError`,
    /// `OSError`, or `ValueError` with the located message the command line prints.
    #[staticmethod]
    #[pyo3(signature = (path, radius = None))]
    fn load(py: Python<'_>, path: PathBuf, radius: Option<f64>) -> PyResult<Self> {
        let name = path.display().to_string();
        py.detach(|| {
            let desc = SceneDescription::load_any(&path, radius).map_err(scene_error)?;
            PyScene::from_description(desc, name)
        })
    }

    /// Cylinders from arrays, one row each, as `[[cylinder]]` tables give them: `bezier`
    /// (N, 4, 3) control points, `major_radius` (N, 2) at u = 0 and 1, `minor_radius` (N, 2)
    /// (default: round), `rotation` (N, 2) radians, `caps`, `normal_hint` (N, 3).
    #[staticmethod]
    #[pyo3(signature = (bezier, major_radius, minor_radius = None, rotation = None, caps = true, normal_hint = None))]
    fn from_cylinders(
        py: Python<'_>,
        bezier: &Bound<'_, PyAny>,
        major_radius: &Bound<'_, PyAny>,
        minor_radius: Option<&Bound<'_, PyAny>>,
        rotation: Option<&Bound<'_, PyAny>>,
        caps: bool,
        normal_hint: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let (n, bez) = read_rows("bezier", bezier, &[4, 3], |v| {
            fits("bezier", v.len() as u64 / 12, "cylinders")?;
            Ok(v.to_vec())
        })?;
        let count = |name: &str, m: usize| -> PyResult<()> {
            if m == n {
                Ok(())
            } else {
                Err(PyValueError::new_err(format!(
                    "{name} has {m} rows and bezier {n}: one per cylinder"
                )))
            }
        };
        let optional = |name: &str, a: Option<&Bound<'_, PyAny>>, k: usize| {
            a.map(|a| {
                let (m, v) = rows_of(name, a, &[k])?;
                count(name, m).map(|()| v)
            })
            .transpose()
        };
        let (m, major) = rows_of("major_radius", major_radius, &[2])?;
        count("major_radius", m)?;
        let minor = optional("minor_radius", minor_radius, 2)?;
        let rot = optional("rotation", rotation, 2)?;
        let hint = optional("normal_hint", normal_hint, 3)?;
        let pair = |v: &[f64], i: usize| [v[2 * i], v[2 * i + 1]];
        let built = py.detach(|| {
            (0..n)
                .into_par_iter()
                .map(|i| {
                    let b = &bez[12 * i..12 * i + 12];
                    build_fiber(&FiberInput {
                        bezier: [0, 1, 2, 3].map(|k| [b[3 * k], b[3 * k + 1], b[3 * k + 2]]),
                        major_radius: pair(&major, i),
                        minor_radius: minor.as_ref().map(|v| pair(v, i)),
                        rotation: rot.as_ref().map(|v| pair(v, i)),
                        caps: [caps, caps],
                        normal_hint: hint
                            .as_ref()
                            .map(|v| [v[3 * i], v[3 * i + 1], v[3 * i + 2]]),
                        ..Default::default()
                    })
                })
                .collect()
        });
        PyScene::from_cylinders_built(py, built, "cylinder")
    }

    /// Strands through points, as `[[strand]]` tables give them: `points` a list of (K, 3)
    /// arrays (K >= 2), `radius` at root and tip (one number or a pair), `ellipticity` (minor
    /// / major, in (0, 1]), `twist` (radians at root and tip), `frame` (`"minimal"` or
    /// `"frenet"`), `control_points` (the arrays are the uniform cubic B-spline's control
    /// points, as a `[[strand]]` table's `control_points`, not points the strand goes through).
    #[staticmethod]
    #[pyo3(signature = (points, radius, ellipticity = None, twist = None, frame = "minimal", control_points = false))]
    fn from_strands(
        py: Python<'_>,
        points: Vec<Bound<'_, PyAny>>,
        radius: Pair,
        ellipticity: Option<f64>,
        twist: Option<Pair>,
        frame: &str,
        control_points: bool,
    ) -> PyResult<Self> {
        let framing = match frame {
            "minimal" | "rotation-minimizing" | "rmf" => StrandFraming::RotationMinimizing,
            "frenet" => StrandFraming::Frenet,
            other => {
                return Err(PyValueError::new_err(format!(
                    "frame must be \"minimal\" or \"frenet\", got {other:?}"
                )));
            }
        };
        let mut segments = 0u64;
        for p in &points {
            let k = p.len().unwrap_or(0) as u64;
            segments += k.saturating_sub(1);
        }
        fits("points", segments, "strand segments")?;
        let mut inputs = Vec::with_capacity(points.len());
        for (i, p) in points.iter().enumerate() {
            let (k, v) = rows_of(&format!("points[{i}]"), p, &[3])?;
            inputs.push(StrandInput {
                points: (0..k)
                    .map(|j| [v[3 * j], v[3 * j + 1], v[3 * j + 2]])
                    .collect(),
                through: !control_points,
                radius: radius.get(),
                ellipticity,
                twist: twist.as_ref().map(Pair::get),
                framing,
                ..Default::default()
            });
        }
        let built: Vec<Result<StrandParts, (Key, String)>> =
            py.detach(|| inputs.into_par_iter().map(build_strand_from).collect());
        let mut strands = BuiltStrands::default();
        for (i, b) in built.into_iter().enumerate() {
            let (cylinders, controls, taper) = b.map_err(|(key, m)| {
                PyValueError::new_err(format!("strand {i}: {m} ({})", argument(key)))
            })?;
            strands.push(cylinders, &controls, taper);
        }
        let desc = SceneDescription::from_strands(strands);
        py.detach(|| PyScene::from_description(desc, "the strands".into()))
    }

    /// The number of cylinders (strand segments count one each); hits' `object` numbers them.
    fn __len__(&self) -> usize {
        self.world.scene.len()
    }

    /// The bounds of the cylinders and spheres as a (2, 3) array `[min, max]`, or `None` for
    /// a scene without them.
    #[getter]
    fn bounds<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyAny>> {
        let Aabb { min, max } = self.world.bounds();
        (min.is_finite() && max.is_finite()).then(|| {
            Array2::from_shape_vec((2, 3), vec![min.x, min.y, min.z, max.x, max.y, max.z])
                .expect("six values")
                .into_pyarray(py)
                .into_any()
        })
    }

    /// The frame a render of this scene would have, `(width, height, channels)`: the
    /// scene's camera (else one framed at 640x480) at `width`, and the integrator's channels
    /// (`integrator`, else the scene's `[render]` one, else `path`'s).
    #[pyo3(signature = (width = None, integrator = None))]
    fn frame(
        &self,
        width: Option<u32>,
        integrator: Option<&str>,
    ) -> PyResult<(u32, u32, Vec<String>)> {
        let request = RenderRequest {
            overrides: RenderTable {
                integrator: parse_integrator(integrator)?,
                ..Default::default()
            },
            width: checked("width", width, 65536)?,
            ..Default::default()
        };
        let plan = self.plan(&request)?;
        Ok((
            plan.camera.width,
            plan.camera.height,
            channel_names(plan.settings.integrator),
        ))
    }

    /// The geometry of the scene's `[ct]` scan, as `gencyl ct` writes it in the sidecar (ASTRA's
    /// `type` and `vectors`, `rows`, `columns`, `quantity`, ...), without projecting.
    fn ct_geometry<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let setup = self.ct.as_ref().ok_or_else(|| {
            PyValueError::new_err(format!("{}: the scene has no [ct] table", self.name))
        })?;
        let projector = Projector::new(&self.world, setup);
        let all = 0..setup.scanner.views.len();
        let text = serde_json::to_string(&projector.sidecar(all, &self.name))
            .expect("JSON of plain values");
        py.import("json")?.call_method1("loads", (text,))
    }

    /// A label volume of the scene's cylinders on a grid of cubic voxels: a uint32 array
    /// (nz, ny, nx), 0 where the voxel's centre lies in no cylinder, else the cylinder's number
    /// plus one (the lowest where solids overlap), by the exact inside test. Voxel (i, j, k) is
    /// centred at `origin + voxel * (i + 0.5, j + 0.5, k + 0.5)`; `size = (nx, ny, nz)`.
    #[pyo3(signature = (origin, voxel, size, threads = None))]
    fn labels<'py>(
        &self,
        py: Python<'py>,
        origin: (f64, f64, f64),
        voxel: f64,
        size: (usize, usize, usize),
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let grid = phantoms::VoxelGrid {
            origin: [origin.0, origin.1, origin.2],
            voxel,
            size: [size.0, size.1, size.2],
        };
        // Rebuilt from the scene's packed store for the labelling's lifetime.
        let cylinders: Vec<_> = self
            .world
            .scene
            .cylinders()
            .map(|c| c.into_owned())
            .collect();
        let cylinders = cylinders.as_slice();
        let numbers: Vec<u32> = (0..cylinders.len() as u32).collect();
        let pool = pool(threads)?;
        let labels = py
            .detach(|| on(&pool, || phantoms::label_volume(cylinders, &numbers, grid)))
            .map_err(PyValueError::new_err)?;
        let array =
            Array3::from_shape_vec((size.2, size.1, size.0), labels).expect("a label per voxel");
        Ok(array.into_pyarray(py).into_any())
    }

    fn __repr__(&self) -> String {
        format!(
            "<gencyl.Scene {}: {} cylinders>",
            self.name,
            self.world.scene.len()
        )
    }

    /// Intersects rays `origins + t directions` ((M, 3) float64 each) with the cylinders.
    /// Returns a dict of arrays, one row per hit, rows in ray order (with `all`, every hit with
    /// t > tmin sorted by t, else the nearest): `ray` (int64), `t`, `u`, `v` (float64),
    /// `normal` (H, 3), `object` (int64), `part` (int8: 0 side, 1 cap at u = 0, 2 cap at u = 1,
    /// 3 seam). The same rows as `gencyl raycast` on the same scene and rays, to the bit.
    #[pyo3(signature = (origins, directions, tmin = 0.0, all = false, threads = None))]
    fn raycast<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        tmin: f64,
        all: bool,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        if tmin.is_nan() {
            return Err(PyValueError::new_err("tmin must be a number, not NaN"));
        }
        let pool = pool(threads)?;
        let rays = rays_of(origins, directions, &pool)?;
        let scene = &self.world.scene;
        let mut rows: Vec<(u32, SceneHit)> = Vec::new();
        for (b, block) in rays.chunks(BLOCK).enumerate() {
            let got = py.detach(|| {
                on(&pool, || {
                    raycast::cast_rays(scene, block, b * BLOCK, tmin, all)
                })
            });
            rows.extend(got);
            py.check_signals()?;
        }
        let h = rows.len();
        let column =
            |f: &dyn Fn(&SceneHit) -> f64| -> Vec<f64> { rows.iter().map(|(_, x)| f(x)).collect() };
        let normal: Vec<f64> = rows
            .iter()
            .flat_map(|(_, x)| x.hit.normal.to_array())
            .collect();
        let out = PyDict::new(py);
        out.set_item(
            "ray",
            rows.iter()
                .map(|r| r.0 as i64)
                .collect::<Vec<_>>()
                .into_pyarray(py),
        )?;
        out.set_item("t", column(&|x| x.hit.t).into_pyarray(py))?;
        out.set_item("u", column(&|x| x.hit.u).into_pyarray(py))?;
        out.set_item("v", column(&|x| x.hit.v).into_pyarray(py))?;
        out.set_item(
            "normal",
            Array2::from_shape_vec((h, 3), normal)
                .expect("3 per hit")
                .into_pyarray(py),
        )?;
        out.set_item(
            "object",
            rows.iter()
                .map(|r| r.1.object as i64)
                .collect::<Vec<_>>()
                .into_pyarray(py),
        )?;
        out.set_item(
            "part",
            rows.iter()
                .map(|r| part_number(r.1.hit.part) as i8)
                .collect::<Vec<_>>()
                .into_pyarray(py),
        )?;
        Ok(out)
    }

    /// X-ray path lengths of rays through the solids ((M, 3) float64 origins and directions):
    /// a dict of (M,) float64 arrays, `length` (the total length inside, in units of |d|:
    /// world units for unit directions) and `optical_depth` (the length weighted by each
    /// material's `mu`; the transmittance is `exp(-optical_depth)`).
    #[pyo3(signature = (origins, directions, threads = None))]
    fn xray<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let pool = pool(threads)?;
        let rays = rays_of(origins, directions, &pool)?;
        let (mut length, mut depth) = (
            Vec::with_capacity(rays.len()),
            Vec::with_capacity(rays.len()),
        );
        for block in rays.chunks(BLOCK) {
            let got: Vec<(f64, f64)> = py.detach(|| {
                on(&pool, || {
                    block
                        .par_iter()
                        .with_max_len(256)
                        .map_init(integrator::Buffers::default, |buf, ray| {
                            integrator::xray_length(&self.world, ray, buf)
                        })
                        .collect()
                })
            });
            for (l, d) in got {
                length.push(l);
                depth.push(d);
            }
            py.check_signals()?;
        }
        let out = PyDict::new(py);
        out.set_item("length", length.into_pyarray(py))?;
        out.set_item("optical_depth", depth.into_pyarray(py))?;
        Ok(out)
    }
}

/// A `scene` argument: a `Scene`, or the path of a scene file or `.hair` model (loaded, with
/// `radius` for a `.hair` model).
fn scene_argument(
    py: Python<'_>,
    scene: &Bound<'_, PyAny>,
    radius: Option<f64>,
) -> PyResult<Py<PyScene>> {
    match scene.cast::<PyScene>() {
        Ok(_) if radius.is_some() => Err(PyValueError::new_err(
            "radius applies when loading a .hair model by path, not to a Scene",
        )),
        Ok(s) => Ok(s.clone().unbind()),
        Err(_) => {
            let path: PathBuf = scene.extract().map_err(|_| {
                PyTypeError::new_err("scene must be a gencyl.Scene or the path of a scene file")
            })?;
            Py::new(py, PyScene::load(py, path, radius)?)
        }
    }
}

/// Renders a scene (a `Scene`, or the path of a scene file or `.hair` model) to
/// `(image, channels)`: a float32 array (H, W, C) of linear values and the channel names
/// (`R, G, B, A`, plus `Z` for `depth` or `L` for `xray`). The pixels are those `gencyl
/// render` computes with the same settings, bit for bit, and do not depend on `threads`.
/// `crop = (x0, y0, x1, y1)` renders that window of the frame (x1 and y1 excluded), equal to
/// the same pixels of the whole frame. Settings left `None` come from the scene's `[render]`
/// table, else the defaults (path tracing, 16 spp, depth 16, seed 1). The GIL is released
/// while rendering; Ctrl-C stops it between bands of rows.
#[pyfunction]
#[pyo3(signature = (scene, integrator = None, spp = None, width = None, max_depth = None, crop = None, seed = None, threads = None, max_pixels = None, radius = None))]
#[allow(clippy::too_many_arguments)]
fn render<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyAny>,
    integrator: Option<&str>,
    spp: Option<u32>,
    width: Option<u32>,
    max_depth: Option<u32>,
    crop: Option<(u32, u32, u32, u32)>,
    seed: Option<u64>,
    threads: Option<usize>,
    max_pixels: Option<u64>,
    radius: Option<f64>,
) -> PyResult<(Bound<'py, PyAny>, Vec<String>)> {
    let loaded = scene_argument(py, scene, radius)?;
    let scene: &PyScene = loaded.get();
    let request = RenderRequest {
        overrides: RenderTable {
            integrator: parse_integrator(integrator)?,
            spp: checked("spp", spp, 1_000_000)?,
            max_depth: checked("max_depth", max_depth, 1000)?,
            seed,
        },
        width: checked("width", width, 65536)?,
        crop: crop.map(|(x0, y0, x1, y1)| Window::new(x0, y0, x1, y1)),
        max_pixels: checked("max_pixels", max_pixels, u64::MAX)?.unwrap_or(limits::MAX_PIXELS),
    };
    let name = &scene.name;
    let plan = scene.plan(&request)?;
    for w in job::warnings(&scene.world, &plan.camera, name) {
        warn(py, &w)?;
    }
    let pool = pool(threads)?;
    let window = plan.window;
    let channels = plan.settings.integrator.channels();
    // Bands of rows between checks for Ctrl-C; each band's rows run in parallel.
    let band =
        (16 * pool
            .as_ref()
            .map_or_else(rayon::current_num_threads, |p| p.current_num_threads())) as u32;
    let mut data =
        Vec::with_capacity(window.width() as usize * window.height() as usize * channels.len());
    let mut dropped = 0;
    let mut y = window.y0;
    while y < window.y1 {
        let rows = Window::new(window.x0, y, window.x1, (y + band).min(window.y1));
        let done = py.detach(|| {
            on(&pool, || {
                integrator::render(&scene.world, &plan.camera, &plan.settings, rows, &|_| {})
            })
        });
        data.extend_from_slice(&done.film.data);
        dropped += done.non_finite_samples;
        py.check_signals()?;
        y = rows.y1;
    }
    if dropped > 0 {
        warn(
            py,
            &format!(
                "{dropped} samples were NaN or infinite and were left out (their pixels are the mean of the finite samples)"
            ),
        )?;
    }
    let image = Array3::from_shape_vec(
        (
            window.height() as usize,
            window.width() as usize,
            channels.len(),
        ),
        data,
    )
    .expect("a value per channel of every pixel");
    Ok((
        image.into_pyarray(py).into_any(),
        channel_names(plan.settings.integrator),
    ))
}

/// X-ray CT projections of a scene with a `[ct]` table (a `Scene`, or the path of a scene
/// file): `(projections, geometry)`, a float32 array (views, rows, columns) equal to the pages
/// `gencyl ct` writes, bit for bit, and the sidecar's geometry as a dict (ASTRA's `type` and
/// `vectors`, `rows`, `columns`, `quantity`, ...). `views = (a, b)` projects views a..b only
/// (b excluded); `quantity` and `material` override the table's as `--quantity` and
/// `--material` do. The GIL is released while projecting; Ctrl-C stops it between views.
#[pyfunction]
#[pyo3(signature = (scene, views = None, quantity = None, material = None, threads = None))]
fn ct<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyAny>,
    views: Option<(usize, usize)>,
    quantity: Option<&str>,
    material: Option<&str>,
    threads: Option<usize>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let loaded = scene_argument(py, scene, None)?;
    let scene: &PyScene = loaded.get();
    let name = &scene.name;
    let mut setup = scene
        .ct
        .clone()
        .ok_or_else(|| PyValueError::new_err(format!("{name}: the scene has no [ct] table")))?;
    if let Some(q) = quantity {
        setup.quantity = q
            .parse()
            .map_err(|e: String| PyValueError::new_err(format!("quantity: {e}")))?;
        if setup.quantity != Quantity::Length {
            setup.material = None;
        }
    }
    if let Some(m) = material {
        if setup.quantity != Quantity::Length {
            return Err(PyValueError::new_err(
                "material applies to the length quantity only (absorbance and transmission sum every material)",
            ));
        }
        let materials = &scene.world.materials;
        let index = materials.iter().position(|x| x.name == m).ok_or_else(|| {
            let known: Vec<&str> = materials.iter().map(|x| x.name.as_str()).collect();
            PyValueError::new_err(format!(
                "material: unknown material `{m}` (defined: {})",
                known.join(", ")
            ))
        })?;
        setup.material = Some(index as u32);
    }
    let total = setup.scanner.views.len();
    let (a, b) = views.unwrap_or((0, total));
    if !(a < b && b <= total) {
        return Err(PyValueError::new_err(format!(
            "views = ({a}, {b}): expected (a, b) with 0 <= a < b <= {total} (the scan's views)"
        )));
    }
    let (rows, columns) = (setup.scanner.rows as usize, setup.scanner.columns as usize);
    let bytes = (b - a) as u64 * (rows * columns) as u64 * 4;
    limits::check_memory(
        bytes,
        &format!("{} views of {rows} x {columns} pixels", b - a),
    )
    .map_err(|m| {
        PyMemoryError::new_err(format!("{m}: project fewer views at a time (views=(a, b))"))
    })?;
    let pool = pool(threads)?;
    let projector = Projector::new(&scene.world, &setup);
    let mut data = vec![0.0f32; (b - a) * rows * columns];
    for (k, page) in data.chunks_mut(rows * columns).enumerate() {
        py.detach(|| on(&pool, || projector.project(a + k, page)));
        py.check_signals()?;
    }
    let array = Array3::from_shape_vec((b - a, rows, columns), data)
        .expect("a value per pixel of every view");
    let text = serde_json::to_string(&projector.sidecar(a..b, name)).expect("JSON of plain values");
    let geometry = py.import("json")?.call_method1("loads", (text,))?;
    Ok((array.into_pyarray(py).into_any(), geometry))
}

/// A CT phantom with its exact ground truth, as `gencyl generate yarn|ply` makes it:
/// `(scene_toml, truth)`, the scene file's text (strands, a material, a camera and a `[ct]`
/// table) and the truth as a dict (fiber count, per-fiber volume, direction and radii, the
/// envelope and the fiber volume fraction computed from the geometry). `kind` is `"yarn"` or
/// `"ply"`; the keywords are the fields of the Rust `YarnSpec` / `PlySpec` (`fibers`, `length`,
/// `twist_deg`, `packing`, `radius`, `radius_sd`, `aspect`, `aspect_sd`, `section_twist`,
/// `migration`, `migration_period`, `segments`, `seed`, `material`; for a ply `width`,
/// `thickness`, `waviness`, `waviness_period`), the rest at their defaults.
#[pyfunction]
#[pyo3(signature = (kind, **spec))]
fn phantom<'py>(
    py: Python<'py>,
    kind: &str,
    spec: Option<&Bound<'py, PyDict>>,
) -> PyResult<(String, Bound<'py, PyAny>)> {
    let json = py.import("json")?;
    let text: String = match spec {
        Some(d) => json.call_method1("dumps", (d,))?.extract()?,
        None => "{}".into(),
    };
    let bad = |e: serde_json::Error| PyValueError::new_err(format!("{kind}: {e}"));
    let made = match kind {
        "yarn" => {
            let spec: phantoms::YarnSpec = serde_json::from_str(&text).map_err(bad)?;
            py.detach(|| phantoms::generate_yarn(&spec))
        }
        "ply" => {
            // As on the command line: a fiber count given alone sets the packing free.
            let mut value: serde_json::Value = serde_json::from_str(&text).map_err(bad)?;
            if let Some(o) = value.as_object_mut()
                && o.contains_key("fibers")
                && !o.contains_key("packing")
            {
                o.insert("packing".into(), 0.0.into());
            }
            let spec: phantoms::PlySpec = serde_json::from_value(value).map_err(bad)?;
            py.detach(|| phantoms::generate_ply(&spec))
        }
        other => {
            return Err(PyValueError::new_err(format!(
                "unknown phantom `{other}`: expected \"yarn\" or \"ply\""
            )));
        }
    }
    .map_err(PyValueError::new_err)?;
    let truth = json.call_method1("loads", (made.truth.to_json(),))?;
    Ok((made.scene_toml, truth))
}

/// A virtual goniometer, as `gencyl scatter` measures it: how one straight fiber (a circle,
/// an ellipse of minor / major radius `aspect`, or the Bezier loop `profile`, (K, 2) points)
/// scatters light arriving from `(theta_i, phi_i)` (degrees), traced through its exact solid.
/// Returns a dict: `values` (orders, bins, bins) float64, the fraction of the power that met
/// the fiber leaving per order, `theta_o` bin and relative-azimuth bin (the CSV's rows, bit for
/// bit), `theta_deg` and `phi_deg` (the bin centres), `lost`, `absorbed` and `hits`.
#[pyfunction]
#[pyo3(signature = (aspect = 1.0, profile = None, rotation = 0.0, eta = 1.55, sigma_a = 0.0, tilt = 0.0, theta_i = 0.0, phi_i = 0.0, rays = 100_000, max_order = 3, bins = 90, seed = 1, threads = None))]
#[allow(clippy::too_many_arguments)]
fn scatter<'py>(
    py: Python<'py>,
    aspect: f64,
    profile: Option<&Bound<'py, PyAny>>,
    rotation: f64,
    eta: f64,
    sigma_a: f64,
    tilt: f64,
    theta_i: f64,
    phi_i: f64,
    rays: usize,
    max_order: usize,
    bins: usize,
    seed: u64,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let section = match profile {
        None => FiberSection::Ellipse { aspect },
        Some(p) => {
            let (n, flat) = rows_of("profile", p, &[2])?;
            FiberSection::Profile(
                (0..n)
                    .map(|i| glam::DVec2::new(flat[2 * i], flat[2 * i + 1]))
                    .collect(),
            )
        }
    };
    let g = Goniometer {
        section,
        rotation: rotation.to_radians(),
        eta,
        sigma_a,
        tilt: tilt.to_radians(),
        theta_i: theta_i.to_radians(),
        phi_i: phi_i.to_radians(),
        rays,
        max_order,
        bins,
        seed,
    };
    g.validate().map_err(PyValueError::new_err)?;
    let pool = pool(threads)?;
    let s = py
        .detach(|| on(&pool, || g.measure()))
        .map_err(PyValueError::new_err)?;
    let out = PyDict::new(py);
    let theta: Vec<f64> = (0..s.bins).map(|k| s.theta_deg(k)).collect();
    let phi: Vec<f64> = (0..s.bins).map(|k| s.phi_deg(k)).collect();
    let values = Array3::from_shape_vec((s.orders, s.bins, s.bins), s.values)
        .expect("a value per bin of every order");
    out.set_item("values", values.into_pyarray(py))?;
    out.set_item("theta_deg", theta.into_pyarray(py))?;
    out.set_item("phi_deg", phi.into_pyarray(py))?;
    out.set_item("lost", s.lost)?;
    out.set_item("absorbed", s.absorbed)?;
    out.set_item("hits", s.hits)?;
    Ok(out)
}

/// The native module.
#[pymodule]
fn _gencyl(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyScene>()?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(ct, m)?)?;
    m.add_function(wrap_pyfunction!(phantom, m)?)?;
    m.add_function(wrap_pyfunction!(scatter, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
