//! Materials: how light scatters where a ray meets a surface.

pub mod hair;
