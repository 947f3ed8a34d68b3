//! Images: windows of a full frame, PNG and EXR output, merging windows.
//!
//! A [`Film`] holds named `f32` channels over a [`Window`] of a full frame, so a frame can be
//! rendered in pieces and the pieces merged back bit-identically with [`Film::merge`].
//!
//! Channel order: [`Film::new`] keeps the order it is given; EXR files store channels sorted by
//! name, so [`Film::read_exr`] returns the canonical order: "R", "G", "B" first (those present),
//! then the others alphabetically. Compare films read from files with films read from files.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, ImageAttributes, IntegerBounds, Layer,
    LayerAttributes, ReadChannels, ReadLayers, Text, WritableImage,
};

/// A rectangle of pixels [x0, x1) x [y0, y1) of a full frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    /// Left column (included).
    pub x0: u32,
    /// Top row (included).
    pub y0: u32,
    /// Right column (excluded).
    pub x1: u32,
    /// Bottom row (excluded).
    pub y1: u32,
}

impl Window {
    /// The window [x0, x1) x [y0, y1).
    pub const fn new(x0: u32, y0: u32, x1: u32, y1: u32) -> Self {
        Window { x0, y0, x1, y1 }
    }

    /// The whole frame.
    pub fn full(width: u32, height: u32) -> Self {
        Window::new(0, 0, width, height)
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.x1.saturating_sub(self.x0)
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.y1.saturating_sub(self.y0)
    }

    /// Parses "x0,y0,x1,y1" (the CLI's --crop) and checks it against the frame: non-empty,
    /// inside. Error messages name the problem, e.g.
    /// "crop window 0,0,900,10 reaches past the 640x480 frame".
    pub fn parse(s: &str, width: u32, height: u32) -> Result<Window, String> {
        Window::parse_text(s)?.within(width, height)
    }

    /// Parses "x0,y0,x1,y1" (four whole numbers), not yet checked against a frame.
    pub fn parse_text(s: &str) -> Result<Window, String> {
        // For messages: a 10 MB argument is not echoed whole.
        let shown = |t: &str| crate::limits::cut(t, 60);
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        if parts.len() != 4 {
            return Err(format!(
                "crop window \"{}\" must be four numbers x0,y0,x1,y1, not {}",
                shown(s),
                parts.len()
            ));
        }
        let mut v = [0u32; 4];
        for (slot, part) in v.iter_mut().zip(&parts) {
            *slot = part.parse().map_err(|_| {
                format!(
                    "crop window \"{}\": \"{}\" is not a whole number >= 0",
                    shown(s),
                    shown(part)
                )
            })?;
        }
        Ok(Window::new(v[0], v[1], v[2], v[3]))
    }

    /// This window, checked against a `width x height` frame: non-empty and inside it.
    pub fn within(self, width: u32, height: u32) -> Result<Window, String> {
        let w = self;
        let text = format!("{},{},{},{}", w.x0, w.y0, w.x1, w.y1);
        if w.x0 >= w.x1 || w.y0 >= w.y1 {
            return Err(format!(
                "crop window {text} is empty (need x0 < x1 and y0 < y1)"
            ));
        }
        if w.x1 > width || w.y1 > height {
            return Err(format!(
                "crop window {text} reaches past the {width}x{height} frame"
            ));
        }
        Ok(w)
    }

    fn contains(&self, x: u32, y: u32) -> bool {
        (self.x0..self.x1).contains(&x) && (self.y0..self.y1).contains(&y)
    }

    fn area(&self) -> usize {
        self.width() as usize * self.height() as usize
    }
}

/// What can go wrong reading, writing or merging films.
#[derive(Debug, thiserror::Error)]
pub enum FilmError {
    /// The file system refused: the file, "read" or "write", the cause (in the message, and
    /// not again as the error's source, so that a chain of causes prints it once).
    #[error("{path}: cannot {1}: {2}", path = .0.display())]
    Io(PathBuf, &'static str, std::io::Error),
    /// A file that is not an EXR, holds what a film cannot, or cannot be encoded: file, problem.
    #[error("{path}: {1}", path = .0.display())]
    File(PathBuf, String),
    /// A film whose fields disagree (data length, window outside the frame).
    #[error("malformed film: {0}")]
    Malformed(String),
    /// Parts that cannot be merged: mismatched frames or channels, overlaps, gaps.
    #[error("{0}")]
    Merge(String),
}

/// An image of named f32 channels over a window of a full frame; pixel (x, y) in full-frame
/// coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    /// Full frame width, height.
    pub frame: (u32, u32),
    /// The part of the frame this film holds.
    pub window: Window,
    /// Channel names, e.g. ["R","G","B"] or ["R","G","B","L"].
    pub channels: Vec<String>,
    /// Interleaved channels, rows of the window from the top.
    pub data: Vec<f32>,
}

/// Canonical channel order: R, G, B first, then the rest alphabetically.
fn channel_rank(name: &str) -> (u8, &str) {
    match name {
        "R" => (0, ""),
        "G" => (1, ""),
        "B" => (2, ""),
        other => (3, other),
    }
}

impl Film {
    /// A film of zeros. Panics if the window is not inside the frame.
    pub fn new(frame: (u32, u32), window: Window, channels: &[&str]) -> Self {
        let inside = window.x0 <= window.x1 && window.y0 <= window.y1;
        let inside = inside && window.x1 <= frame.0 && window.y1 <= frame.1;
        assert!(
            inside,
            "window {window:?} is not inside the frame {frame:?}"
        );
        let channels: Vec<String> = channels.iter().map(|c| c.to_string()).collect();
        let data = vec![0.0; window.area() * channels.len()];
        Film {
            frame,
            window,
            channels,
            data,
        }
    }

    fn offset(&self, x: u32, y: u32) -> usize {
        let w = self.window;
        assert!(
            w.contains(x, y),
            "pixel ({x}, {y}) is outside the film's window {w:?}"
        );
        let i = (y - w.y0) as usize * w.width() as usize + (x - w.x0) as usize;
        i * self.channels.len()
    }

    /// The channel values of pixel (x, y), in full-frame coordinates. Panics outside the window.
    pub fn pixel(&self, x: u32, y: u32) -> &[f32] {
        let (i, n) = (self.offset(x, y), self.channels.len());
        &self.data[i..i + n]
    }

    /// The channel values of pixel (x, y), mutable. Panics outside the window.
    pub fn pixel_mut(&mut self, x: u32, y: u32) -> &mut [f32] {
        let (i, n) = (self.offset(x, y), self.channels.len());
        &mut self.data[i..i + n]
    }

    /// Index of the channel called `name`.
    pub fn channel_index(&self, name: &str) -> Option<usize> {
        self.channels.iter().position(|c| c == name)
    }

    /// Checks that the fields agree with each other.
    fn check(&self) -> Result<(), FilmError> {
        let (w, (fw, fh)) = (&self.window, self.frame);
        if w.x0 > w.x1 || w.y0 > w.y1 || w.x1 > fw || w.y1 > fh {
            let msg = format!("window {:?} is not inside the {fw}x{fh} frame", *w);
            return Err(FilmError::Malformed(msg));
        }
        let (len, area, n) = (self.data.len(), w.area(), self.channels.len());
        if len != area * n {
            let msg = format!("{len} samples for {area} pixels of {n} channels");
            return Err(FilmError::Malformed(msg));
        }
        Ok(())
    }

    /// Writes by extension: `.png` → 8-bit sRGB of R, G, B (values clamped to `[0, 1]`, the standard
    /// sRGB curve; a crop film writes just its window); `.exr` → linear f32, every channel,
    /// ZIP-compressed (lossless), with data window = the crop window and display window = the
    /// full frame. Atomic: written to a hidden temp file in the same directory, then renamed; on
    /// error nothing new is left at `path` (an existing file stays as it was) and no temp file
    /// remains. Other extensions: an error naming the extension and the supported ones.
    pub fn write(&self, path: &Path) -> Result<(), FilmError> {
        self.check()?;
        if self.window.area() == 0 {
            return Err(file_err(path, "cannot write: the film's window is empty"));
        }
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        match ext.to_ascii_lowercase().as_str() {
            "png" => write_atomic(path, |out| self.encode_png(path, out)),
            "exr" => write_atomic(path, |out| self.encode_exr(path, out)),
            _ => Err(file_err(
                path,
                format!("cannot write images of type \".{ext}\" (supported: .png, .exr)"),
            )),
        }
    }

    fn encode_png(&self, path: &Path, out: &mut BufWriter<File>) -> Result<(), FilmError> {
        let mut rgb = [0; 3];
        for (slot, name) in rgb.iter_mut().zip(["R", "G", "B"]) {
            let msg = || format!("cannot write: a PNG needs R, G, B; the film has no \"{name}\"");
            *slot = self
                .channel_index(name)
                .ok_or_else(|| file_err(path, msg()))?;
        }
        let n = self.channels.len();
        let bytes: Vec<u8> = (0..self.window.area())
            .flat_map(|p| rgb.map(|c| srgb8(self.data[p * n + c])))
            .collect();
        let png_err = |e: png::EncodingError| match e {
            png::EncodingError::IoError(source) => FilmError::Io(path.into(), "write", source),
            other => file_err(path, format!("cannot write: {other}")),
        };
        let mut enc = png::Encoder::new(out, self.window.width(), self.window.height());
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header().map_err(png_err)?;
        writer.write_image_data(&bytes).map_err(png_err)?;
        writer.finish().map_err(png_err)
    }

    fn encode_exr(&self, path: &Path, out: &mut BufWriter<File>) -> Result<(), FilmError> {
        let err = |problem: String| file_err(path, format!("cannot write: {problem}"));
        let to_i32 = |v: u32| i32::try_from(v).map_err(|_| err(format!("{v} is too large")));
        let n = self.channels.len();
        let mut list = exr::prelude::SmallVec::new();
        for (c, name) in self.channels.iter().enumerate() {
            let text = Text::new_or_none(name)
                .ok_or_else(|| err(format!("channel name \"{name}\" is not valid")))?;
            let samples = self.data.iter().skip(c).step_by(n).copied().collect();
            list.push(AnyChannel::new(text, FlatSamples::F32(samples)));
        }
        let (w, frame) = (self.window, self.frame);
        let attributes = LayerAttributes {
            layer_position: exr::math::Vec2(to_i32(w.x0)?, to_i32(w.y0)?),
            ..Default::default()
        };
        let size = (w.width() as usize, w.height() as usize);
        let channels = AnyChannels::sort(list);
        let layer = Layer::new(size, attributes, Encoding::SMALL_LOSSLESS, channels);
        let display = IntegerBounds::new((0, 0), (frame.0 as usize, frame.1 as usize));
        let image = Image::new(ImageAttributes::new(display), layer);
        image.write().to_buffered(out).map_err(|e| match e {
            exr::error::Error::Io(source) => FilmError::Io(path.into(), "write", source),
            other => err(other.to_string()),
        })
    }

    /// Reads an EXR written by [`Film::write`] (or any scanline/tiled f32 or f16 EXR with one
    /// layer): channels (in canonical order, see the module docs), data window, display window.
    /// Frames of more than [`crate::limits::MAX_PIXELS`] pixels are refused.
    pub fn read_exr(path: &Path) -> Result<Film, FilmError> {
        Self::read_exr_within(path, crate::limits::MAX_PIXELS)
    }

    /// [`Film::read_exr`] for frames of up to `max_pixels`: the headers are read and checked
    /// first (a regular file or pipe; display window and data window within `max_pixels`, the
    /// data within the memory the process can get), so a file that claims a huge image is
    /// refused before anything is allocated for it.
    pub fn read_exr_within(path: &Path, max_pixels: u64) -> Result<Film, FilmError> {
        let unsupported = |problem: String| file_err(path, format!("unsupported EXR: {problem}"));
        crate::limits::check_readable(path).map_err(|e| FilmError::Io(path.into(), "read", e))?;
        let meta = exr::meta::MetaData::read_from_file(path, false).map_err(|e| match e {
            exr::error::Error::Io(source) => FilmError::Io(path.into(), "read", source),
            exr::error::Error::Invalid(m) => file_err(path, format!("not an EXR file: {m}")),
            exr::error::Error::NotSupported(m) => unsupported(m.into_owned()),
            exr::error::Error::Aborted => unsupported("reading was aborted".into()),
        })?;
        for h in &meta.headers {
            let display = h.shared_attributes.display_window.size;
            let frame = display.0 as u64 * display.1 as u64;
            let data = h.layer_size.0 as u64 * h.layer_size.1 as u64;
            let big = frame.max(data);
            if big > max_pixels {
                return Err(file_err(
                    path,
                    format!(
                        "the header claims a {}x{} frame ({big} pixels), more than the limit of {max_pixels} (--max-pixels raises it)",
                        display.0, display.1
                    ),
                ));
            }
            let need = data * (h.channels.list.len() as u64).max(1) * 4 * 3;
            crate::limits::check_memory(need, "reading its pixels")
                .map_err(|m| file_err(path, m))?;
        }
        let image = exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .from_file(path)
            .map_err(|e| match e {
                exr::error::Error::Io(source) => FilmError::Io(path.into(), "read", source),
                exr::error::Error::Invalid(m) => file_err(path, format!("not an EXR file: {m}")),
                exr::error::Error::NotSupported(m) => unsupported(m.into_owned()),
                exr::error::Error::Aborted => unsupported("reading was aborted".into()),
            })?;
        let [layer] = &image.layer_data[..] else {
            let n = image.layer_data.len();
            return Err(unsupported(format!("{n} layers, expected 1")));
        };
        let display = image.attributes.display_window;
        let pos = layer.attributes.layer_position - display.position;
        let (w, h) = (layer.size.0 as u64, layer.size.1 as u64);
        let (fw, fh) = (display.size.0 as u64, display.size.1 as u64);
        let window = match (u32::try_from(pos.0), u32::try_from(pos.1)) {
            (Ok(x0), Ok(y0)) if x0 as u64 + w <= fw && y0 as u64 + h <= fh => {
                Window::new(x0, y0, x0 + w as u32, y0 + h as u32)
            }
            _ => return Err(unsupported("data window outside the display window".into())),
        };
        let mut channels: Vec<(String, Vec<f32>)> = Vec::new();
        for ch in &layer.channel_data.list {
            let values = match &ch.sample_data {
                FlatSamples::F32(v) => v.clone(),
                FlatSamples::F16(v) => v.iter().map(|s| s.to_f32()).collect(),
                FlatSamples::U32(_) => {
                    return Err(unsupported(format!(
                        "channel {} holds u32 samples",
                        ch.name
                    )));
                }
            };
            channels.push((ch.name.to_string(), values));
        }
        channels.sort_by(|a, b| channel_rank(&a.0).cmp(&channel_rank(&b.0)));
        let n = channels.len();
        let mut data = vec![0.0; window.area() * n];
        for (c, (_, values)) in channels.iter().enumerate() {
            for (p, v) in values.iter().enumerate() {
                data[p * n + c] = *v;
            }
        }
        let channels = channels.into_iter().map(|(name, _)| name).collect();
        Ok(Film {
            frame: (fw as u32, fh as u32),
            window,
            channels,
            data,
        })
    }

    /// Assembles windows of one frame into the full frame. Errors name the parts by index:
    /// different frame sizes or channel lists (same names in the same order), overlapping
    /// windows, pixels left uncovered. Values are copied exactly, so the result is bit-identical
    /// to a full render whose pixels are the same f32 values.
    pub fn merge(parts: &[Film]) -> Result<Film, FilmError> {
        let merge_err = |msg: String| Err(FilmError::Merge(msg));
        let Some(first) = parts.first() else {
            return merge_err("no parts to merge".into());
        };
        let (fw, fh) = first.frame;
        for (i, part) in parts.iter().enumerate() {
            if let Err(e) = part.check() {
                return merge_err(format!("part {i}: {e}"));
            } else if part.frame != first.frame {
                let (w, h) = part.frame;
                return merge_err(format!("part {i} has frame {w}x{h}, part 0 has {fw}x{fh}"));
            } else if part.channels != first.channels {
                let (a, b) = (&part.channels, &first.channels);
                return merge_err(format!("part {i} has channels {a:?}, part 0 has {b:?}"));
            }
        }
        for (a, pa) in parts.iter().enumerate() {
            for (b, pb) in parts.iter().enumerate().skip(a + 1) {
                let (wa, wb) = (pa.window, pb.window);
                let (x, y) = (wa.x0.max(wb.x0), wa.y0.max(wb.y0));
                if x < wa.x1.min(wb.x1) && y < wa.y1.min(wb.y1) {
                    return merge_err(format!("parts {a} and {b} overlap at pixel ({x}, {y})"));
                }
            }
        }
        let full = Window::full(fw, fh);
        let at = |x: u32, y: u32| y as usize * fw as usize + x as usize;
        if parts.iter().map(|p| p.window.area()).sum::<usize>() != full.area() {
            // No overlaps and all windows inside: some pixel is uncovered. Find the first.
            let mut hit = vec![false; full.area()];
            for w in parts.iter().map(|p| p.window) {
                for y in w.y0..w.y1 {
                    hit[at(w.x0, y)..at(w.x1, y)].fill(true);
                }
            }
            let i = hit.iter().position(|h| !h).unwrap_or(0);
            let (x, y) = (i % fw as usize, i / fw as usize);
            return merge_err(format!("pixel ({x}, {y}) is not covered by any part"));
        }
        let names: Vec<&str> = first.channels.iter().map(String::as_str).collect();
        let mut out = Film::new(first.frame, full, &names);
        let n = names.len();
        for part in parts.iter().filter(|p| p.window.area() > 0) {
            let w = part.window;
            let len = w.width() as usize * n;
            for (y, src) in (w.y0..w.y1).zip(part.data.chunks_exact(len)) {
                let dst = at(w.x0, y) * n;
                out.data[dst..dst + len].copy_from_slice(src);
            }
        }
        Ok(out)
    }
}

/// Linear `[0, 1]` to 8-bit sRGB with the standard curve (as `render::write_png`).
fn srgb8(v: f32) -> u8 {
    let c = (v as f64).clamp(0.0, 1.0);
    let s = if c <= 0.0031308 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

fn file_err(path: &Path, problem: impl Into<String>) -> FilmError {
    FilmError::File(path.to_owned(), problem.into())
}

/// [`super::write_atomic`] with the film's errors.
fn write_atomic(
    path: &Path,
    encode: impl FnOnce(&mut BufWriter<File>) -> Result<(), FilmError>,
) -> Result<(), FilmError> {
    super::write_atomic(path, encode, |e| FilmError::Io(path.into(), "write", e))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh, empty directory, removed when dropped.
    struct TempDir(PathBuf);
    impl TempDir {
        fn new(test: &str) -> Self {
            let name = format!("gencyl-film-{test}-{}", std::process::id());
            let dir = std::env::temp_dir().join(name);
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(&dir).unwrap();
            TempDir(dir)
        }
        fn entries(&self) -> Vec<String> {
            let entries = std::fs::read_dir(&self.0).unwrap();
            let mut v: Vec<String> = entries
                .map(|e| e.unwrap().file_name().into_string().unwrap())
                .collect();
            v.sort();
            v
        }
    }
    impl Drop for TempDir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    fn assert_identical(a: &Film, b: &Film) {
        assert_eq!(
            (a.frame, a.window, &a.channels),
            (b.frame, b.window, &b.channels)
        );
        let bits = |f: &Film| f.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(a), bits(b));
    }

    /// A deterministic pattern of finite, varied f32 values.
    fn pattern(frame: (u32, u32), channels: &[&str]) -> Film {
        let mut f = Film::new(frame, Window::full(frame.0, frame.1), channels);
        for (i, v) in f.data.iter_mut().enumerate() {
            let h = (i as u32).wrapping_mul(0x9e37_79b9).rotate_left(13) ^ 0x5bd1_e995;
            let x = f32::from_bits(h);
            *v = if x.is_finite() { x } else { h as f32 };
        }
        f
    }

    fn crop(full: &Film, w: Window) -> Film {
        let names: Vec<&str> = full.channels.iter().map(String::as_str).collect();
        let mut c = Film::new(full.frame, w, &names);
        for (x, y) in (w.y0..w.y1).flat_map(|y| (w.x0..w.x1).map(move |x| (x, y))) {
            c.pixel_mut(x, y).copy_from_slice(full.pixel(x, y));
        }
        c
    }

    fn err_text<T: std::fmt::Debug>(r: Result<T, FilmError>) -> String {
        r.unwrap_err().to_string()
    }

    #[test]
    fn window_parse() {
        assert_eq!(
            Window::parse("0,0,640,480", 640, 480),
            Ok(Window::full(640, 480))
        );
        let w = Window::parse(" 10, 4 ,20,30", 640, 480).unwrap();
        assert_eq!(
            (w, w.width(), w.height()),
            (Window::new(10, 4, 20, 30), 10, 26)
        );
        let err = |s| Window::parse(s, 640, 480).unwrap_err();
        assert_eq!(
            err("1,2,3"),
            "crop window \"1,2,3\" must be four numbers x0,y0,x1,y1, not 3"
        );
        assert!(err("1,2,3,4,5").contains("must be four numbers"));
        assert!(err("a,0,10,10").ends_with("\"a\" is not a whole number >= 0"));
        assert!(err("-1,0,10,10").ends_with("\"-1\" is not a whole number >= 0"));
        assert_eq!(
            err("5,0,5,10"),
            "crop window 5,0,5,10 is empty (need x0 < x1 and y0 < y1)"
        );
        assert!(err("0,9,10,3").ends_with("is empty (need x0 < x1 and y0 < y1)"));
        assert_eq!(
            err("0,0,900,10"),
            "crop window 0,0,900,10 reaches past the 640x480 frame"
        );
        assert!(err("0,0,10,481").contains("reaches past"));
    }

    #[test]
    fn exr_round_trip() {
        let dir = TempDir::new("roundtrip");
        let specials = [
            0.0,
            -0.0,
            f32::from_bits(1),
            f32::MIN_POSITIVE,
            1e30,
            -1e30,
            f32::MAX,
        ];
        let mut full = pattern((13, 7), &["R", "G", "B", "L"]);
        full.data[..specials.len()].copy_from_slice(&specials);
        full.data[specials.len()..][..3].copy_from_slice(&[0.1, 1.0, -3.5]);
        let path = dir.0.join("full.exr");
        full.write(&path).unwrap();
        assert_identical(&Film::read_exr(&path).unwrap(), &full);

        let part = crop(&full, Window::new(3, 2, 11, 7));
        let path = dir.0.join("crop.exr");
        part.write(&path).unwrap();
        let back = Film::read_exr(&path).unwrap();
        assert_eq!(
            (back.frame, back.window),
            ((13, 7), Window::new(3, 2, 11, 7))
        );
        assert_identical(&back, &part);

        // Channels come back in canonical order, values following their names.
        let mixed = pattern((5, 4), &["T", "B", "L", "R", "G"]);
        let path = dir.0.join("mixed.exr");
        mixed.write(&path).unwrap();
        let back = Film::read_exr(&path).unwrap();
        assert_eq!(back.channels, ["R", "G", "B", "L", "T"]);
        for (x, y) in [(0, 0), (4, 3), (2, 1)] {
            for (c, name) in mixed.channels.iter().enumerate() {
                let b = back.channel_index(name).unwrap();
                assert_eq!(
                    back.pixel(x, y)[b].to_bits(),
                    mixed.pixel(x, y)[c].to_bits()
                );
            }
        }
        assert_eq!(dir.entries(), ["crop.exr", "full.exr", "mixed.exr"]);

        std::fs::write(dir.0.join("junk.exr"), b"not an image").unwrap();
        let e = err_text(Film::read_exr(&dir.0.join("junk.exr")));
        assert!(
            e.ends_with("junk.exr: not an EXR file: file identifier missing"),
            "{e}"
        );
        let e = err_text(Film::read_exr(&dir.0.join("missing.exr")));
        assert!(e.contains("missing.exr: cannot read: "), "{e}");
    }

    #[test]
    fn crop_merge() {
        let dir = TempDir::new("merge");
        let full = pattern((37, 23), &["R", "G", "B", "L"]);
        let windows = [
            (0, 0, 20, 9),
            (20, 0, 37, 9),
            (0, 9, 11, 23),
            (11, 9, 37, 23),
        ];
        let mut parts = Vec::new();
        for (i, &(x0, y0, x1, y1)) in windows.iter().enumerate() {
            let path = dir.0.join(format!("part{i}.exr"));
            crop(&full, Window::new(x0, y0, x1, y1))
                .write(&path)
                .unwrap();
            parts.push(Film::read_exr(&path).unwrap());
        }
        let path = dir.0.join("full.exr");
        full.write(&path).unwrap();
        let full_back = Film::read_exr(&path).unwrap();
        assert_identical(&Film::merge(&parts).unwrap(), &full_back);
        assert_identical(&full_back, &full);
        parts.reverse();
        assert_identical(&Film::merge(&parts).unwrap(), &full);
        parts.reverse();

        let err = |p: &[Film]| err_text(Film::merge(p));
        let mut overlap = parts.clone();
        overlap[3] = crop(&full, Window::new(10, 9, 37, 23));
        assert_eq!(err(&overlap), "parts 2 and 3 overlap at pixel (10, 9)");
        assert_eq!(err(&parts[..3]), "pixel (11, 9) is not covered by any part");
        assert_eq!(err(&[]), "no parts to merge");
        let mut frames = parts.clone();
        frames[1].frame = (38, 23);
        assert_eq!(err(&frames), "part 1 has frame 38x23, part 0 has 37x23");
        let mut chans = parts.clone();
        chans[2].channels[3] = "T".into();
        assert!(err(&chans).starts_with("part 2 has channels [\"R\", \"G\", \"B\", \"T\"]"));
        let mut short = parts.clone();
        short[1].data.pop();
        assert!(err(&short).starts_with("part 1: malformed film: "));
    }

    #[test]
    fn png_srgb() {
        let dir = TempDir::new("png");
        let values = [0.0, 1.0, 0.5, 0.0031308, 0.001, 2.0, -1.0];
        let mut film = Film::new((7, 1), Window::full(7, 1), &["B", "G", "R", "L"]);
        for (x, v) in values.iter().enumerate() {
            film.pixel_mut(x as u32, 0)
                .copy_from_slice(&[0.5, v * 0.5, *v, 9.0]);
        }
        let decode = |p: &Path| {
            let file = std::io::BufReader::new(File::open(p).unwrap());
            let mut reader = png::Decoder::new(file).read_info().unwrap();
            let mut buf = vec![0; reader.output_buffer_size().unwrap()];
            let info = reader.next_frame(&mut buf).unwrap();
            assert_eq!(
                (info.color_type, info.bit_depth),
                (png::ColorType::Rgb, png::BitDepth::Eight)
            );
            buf.truncate(info.buffer_size());
            (info.width, info.height, buf)
        };
        let path = dir.0.join("a.png");
        film.write(&path).unwrap();
        let (w, h, buf) = decode(&path);
        assert_eq!((w, h), (7, 1));
        let reds: Vec<u8> = buf.chunks(3).map(|p| p[0]).collect();
        assert_eq!(reds, [0, 255, 188, 10, 3, 255, 0]);
        assert!(buf.chunks(3).all(|p| p[2] == 188), "B = 0.5 everywhere");
        assert_eq!(buf[3 * 2 + 1], 137, "G = 0.25");

        let part = Film::new((10, 8), Window::new(2, 3, 7, 5), &["R", "G", "B"]);
        let path = dir.0.join("crop.PNG");
        part.write(&path).unwrap();
        let (w, h, buf) = decode(&path);
        assert_eq!((w, h, buf.len()), (5, 2, 30));
        assert_eq!(dir.entries(), ["a.png", "crop.PNG"]);
    }

    #[test]
    fn atomic_write() {
        let dir = TempDir::new("atomic");
        let film = pattern((4, 3), &["R", "G", "B"]);
        let e = err_text(film.write(&dir.0.join("missing/out.exr")));
        assert!(e.contains("out.exr: cannot write: "), "{e}");
        let e = err_text(film.write(&dir.0.join("out.jpg")));
        assert!(
            e.ends_with("out.jpg: cannot write images of type \".jpg\" (supported: .png, .exr)")
        );
        assert!(film.write(&dir.0.join("noext")).is_err());
        assert!(dir.entries().is_empty(), "{:?}", dir.entries());

        // Failures after the temp file exists remove it and keep the old file intact.
        let path = dir.0.join("keep.png");
        film.write(&path).unwrap();
        let before = std::fs::read(&path).unwrap();
        let e = err_text(Film::new((4, 3), Window::full(4, 3), &["L"]).write(&path));
        assert!(e.ends_with("the film has no \"R\""), "{e}");
        let empty = Film::new((4, 3), Window::new(1, 1, 1, 3), &["R"]);
        let e = err_text(empty.write(&dir.0.join("empty.exr")));
        assert!(
            e.ends_with("empty.exr: cannot write: the film's window is empty"),
            "{e}"
        );
        assert_eq!(dir.entries(), ["keep.png"]);
        assert_eq!(std::fs::read(&path).unwrap(), before);
    }
}
