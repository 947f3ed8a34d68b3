//! Everything a render needs besides the camera: the cylinders with their BVH, spheres,
//! planes, emitting spheres, materials, lights and the environment; ray queries over all of it.

use gencyl::{Aabb, Frame, GeneralizedCylinder, Part, Ray, Section};
use glam::DVec3;

use crate::accel::shapes::{Plane, Sphere};
use crate::accel::{Frustum, Leaving, RegionList, Scene, SceneHit, Scratch};
use crate::optics::light::{Environment, Light};
use crate::optics::material::{Material, SceneMaterial, SectionAt, ShadingPoint};
use crate::scene_file::SceneDescription;
use crate::transport::ct::Attenuation;

/// What a ray hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Surface {
    /// Cylinder `object` at `(u, v)` on `part`.
    Fiber {
        /// Cylinder number.
        object: u32,
        /// Axis parameter.
        u: f64,
        /// Section parameter.
        v: f64,
        /// Side or cap.
        part: Part,
    },
    /// Sphere number.
    Sphere(u32),
    /// Plane number.
    Plane(u32),
    /// Spherical light number (an index into the lights).
    Light(u32),
}

/// The fiber a ray spawned on surface `s` leaves.
fn fiber(s: Option<Surface>) -> Option<Leaving> {
    match s {
        Some(Surface::Fiber { object, u, .. }) => Some(Leaving { object, u }),
        _ => None,
    }
}

/// The nearest hit of a ray on the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldHit {
    /// Ray parameter.
    pub t: f64,
    /// The point.
    pub point: DVec3,
    /// Outward unit normal (planes: their normal).
    pub normal: DVec3,
    /// What was hit.
    pub surface: Surface,
}

/// A boundary crossing of a solid along a ray, for X-ray path lengths.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crossing {
    /// Ray parameter.
    pub t: f64,
    /// Whether the ray enters the solid there (`d . n < 0`).
    pub entering: bool,
    /// The solid's material.
    pub material: u32,
}

/// The scene, ready to render.
#[derive(Clone, Debug)]
pub struct World {
    /// Cylinders and their BVH.
    pub scene: Scene,
    /// Material of each cylinder.
    pub cylinder_materials: Vec<u32>,
    /// Spheres and their materials.
    pub spheres: Vec<(Sphere, u32)>,
    /// Planes and their materials.
    pub planes: Vec<(Plane, u32)>,
    /// Materials.
    pub materials: Vec<SceneMaterial>,
    /// Lights.
    pub lights: Vec<Light>,
    /// Environment light, if any.
    pub environment: Option<Environment>,
    /// X-ray attenuation of the materials (under the `[ct]` spectrum, if any).
    pub attenuation: Attenuation,
    /// Per material: whether it shades a fiber as a far-field scatterer (hair, Kajiya-Kay),
    /// whose solid rays pass through: only its entries are hits, never its exits.
    far_field: Vec<bool>,
}

/// Which fibers a ray may meet ([`World::intersect_where`]).
#[derive(Clone, Copy, Debug)]
pub enum Fibers<'a> {
    /// Any: the ray walks the fibers' BVH.
    All,
    /// None: its frustum's list is empty ([`World::list_fibers`]).
    None,
    /// Those whose BVH leaves a region's list holds: a ray within the region.
    Listed(&'a RegionList),
}

impl World {
    /// Builds the BVH over a scene description's cylinders (in parallel).
    pub fn new(desc: SceneDescription) -> World {
        let far_field = desc
            .materials
            .iter()
            .map(|m| {
                matches!(
                    m.material,
                    Material::Hair(_) | Material::ExactHair { .. } | Material::KajiyaKay { .. }
                )
            })
            .collect();
        let attenuation = Attenuation::new(
            &desc.materials,
            desc.ct.as_ref().and_then(|c| c.spectrum.as_ref()),
        );
        World {
            far_field,
            attenuation,
            scene: Scene::with_strands(desc.cylinders, desc.strands),
            cylinder_materials: desc.cylinder_materials,
            spheres: desc.spheres,
            planes: desc.planes,
            materials: desc.materials,
            lights: desc.lights,
            environment: desc.environment,
        }
    }

    /// Bounds of the cylinders and spheres (not planes or lights).
    pub fn bounds(&self) -> Aabb {
        let b = self
            .scene
            .cylinders()
            .fold(Aabb::EMPTY, |b, c| b.union(c.bounds()));
        self.spheres.iter().fold(b, |b, (s, _)| {
            b.union(Aabb {
                min: s.center - DVec3::splat(s.radius),
                max: s.center + DVec3::splat(s.radius),
            })
        })
    }

    /// Spheres to test along with the cylinders: the scene's and the emitting ones.
    fn spheres(&self) -> impl Iterator<Item = (Sphere, Surface)> + '_ {
        let solid = self
            .spheres
            .iter()
            .enumerate()
            .map(|(i, (s, _))| (*s, Surface::Sphere(i as u32)));
        let lights = self.lights.iter().enumerate().filter_map(|(i, l)| match l {
            Light::Sphere { sphere, .. } => Some((*sphere, Surface::Light(i as u32))),
            _ => None,
        });
        solid.chain(lights)
    }

    /// Whether a ray may stop where it leaves this cylinder: not at the exit of a far-field
    /// fiber.
    fn exits_stop(&self, object: u32) -> bool {
        !self.far_field[self.cylinder_materials[object as usize] as usize]
    }

    /// The nearest hit with `tmin < t < tmax` (exits of far-field fibers do not count), of a
    /// ray that leaves the surface `leaving` if it is spawned from a hit (the same answer,
    /// found faster: [`Scene::nearest_hit_where`]).
    pub fn intersect(
        &self,
        ray: &Ray,
        range: (f64, f64),
        leaving: Option<Surface>,
        scratch: &mut Scratch,
    ) -> Option<WorldHit> {
        self.intersect_where(ray, range, leaving, Fibers::All, scratch)
    }

    /// The leaves of the fibers' BVH that may meet `frustum`, into `out`
    /// ([`crate::accel::Bvh::list_region`], in at most `limit` nodes, else marked whole):
    /// empty where no ray within it can hit a fiber.
    pub fn list_fibers(&self, frustum: &Frustum, limit: usize, out: &mut RegionList) {
        let bvh = self.scene.bvh();
        bvh.list_region(frustum.eye(), frustum.planes(), frustum.axis(), limit, out);
    }

    /// [`World::intersect`] with the fibers a ray may meet: all of them, none (a ray within
    /// a frustum whose list is empty), or those of a list (a camera ray within its pixel's
    /// frustum, spawned from no surface). The same hit.
    pub fn intersect_where(
        &self,
        ray: &Ray,
        (tmin, tmax): (f64, f64),
        leaving: Option<Surface>,
        fibers: Fibers,
        scratch: &mut Scratch,
    ) -> Option<WorldHit> {
        let exits_stop = |i| self.exits_stop(i);
        let range = (tmin, tmax);
        let found = match fibers {
            Fibers::None => None,
            Fibers::All => {
                self.scene
                    .nearest_hit_where(ray, range, fiber(leaving), scratch, exits_stop)
            }
            Fibers::Listed(list) => {
                debug_assert!(leaving.is_none(), "a listed ray leaves no surface");
                self.scene
                    .nearest_hit_listed(ray, range, list, scratch, exits_stop)
            }
        };
        let best: Option<WorldHit> = found.map(|SceneHit { hit, object }| WorldHit {
            t: hit.t,
            point: hit.point,
            normal: hit.normal,
            surface: Surface::Fiber {
                object,
                u: hit.u,
                v: hit.v,
                part: hit.part,
            },
        });
        self.nearest_other(ray, (tmin, tmax), best)
    }

    /// The nearest of `best` and the hits on spheres and planes with `tmin < t < tmax`.
    fn nearest_other(
        &self,
        ray: &Ray,
        (tmin, tmax): (f64, f64),
        mut best: Option<WorldHit>,
    ) -> Option<WorldHit> {
        let mut limit = best.map_or(tmax, |b| b.t);
        for (s, surface) in self.spheres() {
            if let Some((t0, t1)) = s.crossings(ray) {
                let t = if t0 > tmin { t0 } else { t1 };
                if t > tmin && t < limit {
                    let point = ray.at(t);
                    limit = t;
                    best = Some(WorldHit {
                        t,
                        point,
                        normal: s.normal(point),
                        surface,
                    });
                }
            }
        }
        for (i, (p, _)) in self.planes.iter().enumerate() {
            if let Some(t) = p.crossing(ray)
                && t > tmin
                && t < limit
            {
                limit = t;
                best = Some(WorldHit {
                    t,
                    point: ray.at(t),
                    normal: p.normal,
                    surface: Surface::Plane(i as u32),
                });
            }
        }
        best
    }

    /// Whether anything blocks the ray within `tmin < t < tmax` (exits of far-field fibers
    /// do not), for a ray that leaves the surface `leaving` if any (as [`World::intersect`]).
    pub fn occluded(
        &self,
        ray: &Ray,
        (tmin, tmax): (f64, f64),
        leaving: Option<Surface>,
        scratch: &mut Scratch,
    ) -> bool {
        let hit = |t: f64| t > tmin && t < tmax;
        self.spheres()
            .any(|(s, _)| s.crossings(ray).is_some_and(|(t0, t1)| hit(t0) || hit(t1)))
            || self
                .planes
                .iter()
                .any(|(p, _)| p.crossing(ray).is_some_and(hit))
            || self
                .scene
                .any_hit_where(ray, (tmin, tmax), fiber(leaving), scratch, |i| {
                    self.exits_stop(i)
                })
    }

    /// Every boundary crossing of a solid (cylinders and spheres; planes bound nothing)
    /// with `t > tmin`, appended to `out` in no particular order.
    pub fn crossings(
        &self,
        ray: &Ray,
        tmin: f64,
        out: &mut Vec<Crossing>,
        hits: &mut Vec<SceneHit>,
        scratch: &mut Scratch,
    ) {
        hits.clear();
        self.scene.all_hits(ray, tmin, f64::INFINITY, hits, scratch);
        // A tangent touch (d . n = 0) neither enters nor leaves.
        let crossing = hits.iter().filter(|h| h.hit.normal.dot(ray.dir) != 0.0);
        out.extend(crossing.map(|h| Crossing {
            t: h.hit.t,
            entering: h.hit.normal.dot(ray.dir) < 0.0,
            material: self.cylinder_materials[h.object as usize],
        }));
        for (s, m) in &self.spheres {
            if let Some((t0, t1)) = s.crossings(ray) {
                for (t, entering) in [(t0, true), (t1, false)] {
                    if t > tmin {
                        out.push(Crossing {
                            t,
                            entering,
                            material: *m,
                        });
                    }
                }
            }
        }
    }

    /// The material of a surface (`None` for lights).
    pub fn material(&self, s: Surface) -> Option<&SceneMaterial> {
        let i = match s {
            Surface::Fiber { object, .. } => self.cylinder_materials[object as usize],
            Surface::Sphere(i) => self.spheres[i as usize].1,
            Surface::Plane(i) => self.planes[i as usize].1,
            Surface::Light(_) => return None,
        };
        Some(&self.materials[i as usize])
    }

    /// The shading geometry at a hit: the normal, and for fibers the tangent and the section.
    pub fn shading_point(&self, h: &WorldHit) -> ShadingPoint {
        self.shading_point_for(h, true)
    }

    /// [`Self::shading_point`], with a fiber's section only `with_section` (the frame's `n` and
    /// `b` and the sweep's turn are then not computed: most materials need the tangent alone,
    /// [`Material::uses_section`]).
    pub fn shading_point_for(&self, h: &WorldHit, with_section: bool) -> ShadingPoint {
        let Surface::Fiber { object, u, .. } = h.surface else {
            return ShadingPoint {
                normal: h.normal,
                tangent: None,
                section: None,
            };
        };
        let c = &*self.scene.cylinder(object);
        if !with_section {
            return ShadingPoint {
                normal: h.normal,
                tangent: Some(c.tangent(u)),
                section: None,
            };
        }
        let frame = c.frame(u);
        ShadingPoint {
            normal: h.normal,
            tangent: Some(frame.t),
            section: Some(section_at(c, frame, u)),
        }
    }
}

/// The section of fiber `c` at `u`: the sweep turns the section's first axis from `n` by
/// `rho(u)` toward `b` and scales it by `A(u)`, the second by `B(u)`. For an ellipse the major
/// axis is the longer of the two (`aspect = min / max`); for a profile the first axis, with
/// `aspect = B / A`.
pub fn section_at(c: &GeneralizedCylinder, frame: Frame, u: f64) -> SectionAt {
    let sweep = c.sweep();
    let rho = sweep.rotation[0] + (sweep.rotation[1] - sweep.rotation[0]) * u;
    let (s, co) = rho.sin_cos();
    let first = co * frame.n + s * frame.b;
    let second = co * frame.b - s * frame.n;
    let (a, b) = (sweep.major_at(u), sweep.minor_at(u));
    match c.section() {
        Section::Circle(_) if b > a => SectionAt {
            major: second,
            aspect: a / b,
        },
        _ => SectionAt {
            major: first,
            aspect: b / a,
        },
    }
}
