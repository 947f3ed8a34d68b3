//! Render settings: which integrator, how many samples, how deep, which seed.
//!
//! Plain values and nothing else, so that the scene file format (which parses its `[render]`
//! table into a [`RenderTable`]), the command line and the integrators (which read
//! [`RenderSettings`]) can all use them without importing each other. Imports nothing of the
//! crate.

use std::str::FromStr;

/// What each pixel shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integrator {
    /// The outward normal, `(n + 1) / 2`.
    Normals,
    /// `(u, v / 2 pi, part / 2)`.
    Uv,
    /// Grey `1 / (1 + t / t_focus)` (`t_focus` the camera's distance to `look_at`), raw `Z`.
    Depth,
    /// Direct lighting.
    Direct,
    /// Path tracing.
    Path,
    /// X-ray path length and transmittance.
    Xray,
}

impl FromStr for Integrator {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Ok(match s {
            "normals" => Integrator::Normals,
            "uv" => Integrator::Uv,
            "depth" => Integrator::Depth,
            "direct" => Integrator::Direct,
            "path" => Integrator::Path,
            "xray" => Integrator::Xray,
            _ => {
                return Err(format!(
                    "unknown integrator `{s}`: expected normals, uv, depth, direct, path or xray"
                ));
            }
        })
    }
}

impl Integrator {
    /// The film's channels.
    pub fn channels(self) -> &'static [&'static str] {
        match self {
            Integrator::Depth => &["R", "G", "B", "A", "Z"],
            Integrator::Xray => &["R", "G", "B", "A", "L"],
            _ => &["R", "G", "B", "A"],
        }
    }
}

/// How to render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// The integrator.
    pub integrator: Integrator,
    /// Samples per pixel.
    pub spp: u32,
    /// Most scattering events on a path (specular ones included).
    pub max_depth: u32,
    /// Seed of the per-pixel sample streams.
    pub seed: u64,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            integrator: Integrator::Path,
            spp: 16,
            max_depth: 16,
            seed: 1,
        }
    }
}

/// Render settings a scene may give (`[render]`); the command line overrides them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RenderTable {
    /// `integrator`.
    pub integrator: Option<Integrator>,
    /// `spp`: samples per pixel.
    pub spp: Option<u32>,
    /// `max_depth`: most scattering events on a path.
    pub max_depth: Option<u32>,
    /// `seed` of the per-pixel sample streams.
    pub seed: Option<u64>,
}

impl RenderTable {
    /// The settings to render with: each of `overrides` (the command line's) where it is
    /// given, else this table's, else [`RenderSettings::default`]'s.
    pub fn settings(&self, overrides: &RenderTable) -> RenderSettings {
        let d = RenderSettings::default();
        RenderSettings {
            integrator: overrides
                .integrator
                .or(self.integrator)
                .unwrap_or(d.integrator),
            spp: overrides.spp.or(self.spp).unwrap_or(d.spp),
            max_depth: overrides
                .max_depth
                .or(self.max_depth)
                .unwrap_or(d.max_depth),
            seed: overrides.seed.or(self.seed).unwrap_or(d.seed),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The command line's value wins, then the scene's `[render]`, then the default.
    #[test]
    fn overrides_then_table_then_defaults() {
        let table = RenderTable {
            spp: Some(7),
            max_depth: Some(3),
            ..RenderTable::default()
        };
        let cli = RenderTable {
            max_depth: Some(9),
            seed: Some(42),
            ..RenderTable::default()
        };
        let s = table.settings(&cli);
        let d = RenderSettings::default();
        assert_eq!(
            (s.integrator, s.spp, s.max_depth, s.seed),
            (d.integrator, 7, 9, 42),
            "{s:?}"
        );
        assert_eq!(
            RenderTable::default().settings(&RenderTable::default()),
            d,
            "all defaults"
        );
    }
}
