//! Line plots as PNG, drawn here (no plotting library, no fonts): curves over a fixed `x`
//! range on a white canvas with grey grid lines, for the goniometer's `N_p(phi)` curves. The
//! caller says in words what the axes and colours are.

use std::path::Path;

/// A curve: `y` values at evenly spaced `x` over the plot's range (bin centres), and its colour.
pub struct Curve<'a> {
    /// The values.
    pub y: &'a [f64],
    /// RGB.
    pub colour: [u8; 3],
}

/// Canvas size and margin, pixels.
const WIDTH: usize = 900;
const HEIGHT: usize = 450;
const MARGIN: usize = 30;

/// Writes the curves over `x` from `x0` to `x1` (each curve's `n` values at the centres of `n`
/// equal bins), `y` from 0 to the largest value (times 1.05), with vertical grid lines at the
/// `x` of `grid`, as an 8-bit RGB PNG, atomically.
pub fn write_line_plot(
    path: &Path,
    curves: &[Curve],
    (x0, x1): (f64, f64),
    grid: &[f64],
) -> Result<(), String> {
    let mut img = vec![255u8; WIDTH * HEIGHT * 3];
    let (w, h) = ((WIDTH - 2 * MARGIN) as f64, (HEIGHT - 2 * MARGIN) as f64);
    let top = curves
        .iter()
        .flat_map(|c| c.y.iter().copied())
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max)
        * 1.05;
    let top = if top > 0.0 { top } else { 1.0 };
    let px = |x: f64| MARGIN as f64 + (x - x0) / (x1 - x0) * w;
    let py = |y: f64| MARGIN as f64 + h - (y / top).clamp(0.0, 1.0) * h;
    for &g in grid {
        let x = px(g);
        line(&mut img, (x, py(0.0)), (x, py(top)), [200, 200, 200], 1);
    }
    for y in [0.25, 0.5, 0.75, 1.0] {
        let y = py(y * top / 1.05);
        line(&mut img, (px(x0), y), (px(x1), y), [225, 225, 225], 1);
    }
    line(&mut img, (px(x0), py(0.0)), (px(x1), py(0.0)), [0, 0, 0], 1);
    line(&mut img, (px(x0), py(0.0)), (px(x0), py(top)), [0, 0, 0], 1);
    for c in curves {
        let n = c.y.len();
        let at = |k: usize| {
            let x = x0 + (k as f64 + 0.5) / n as f64 * (x1 - x0);
            (px(x), py(c.y[k]))
        };
        for k in 1..n {
            line(&mut img, at(k - 1), at(k), c.colour, 2);
        }
    }
    super::write_atomic(
        path,
        |out| {
            let mut enc = png::Encoder::new(out, WIDTH as u32, HEIGHT as u32);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            let mut writer = enc.write_header().map_err(|e| e.to_string())?;
            writer.write_image_data(&img).map_err(|e| e.to_string())?;
            writer.finish().map_err(|e| e.to_string())
        },
        |e| e.to_string(),
    )
    .map_err(|e| format!("{}: cannot write: {e}", path.display()))
}

/// A straight line of `thick` pixels (a square brush stepped along the longer axis).
fn line(img: &mut [u8], (xa, ya): (f64, f64), (xb, yb): (f64, f64), c: [u8; 3], thick: i64) {
    let steps = (xb - xa).abs().max((yb - ya).abs()).ceil().max(1.0) as usize;
    for s in 0..=steps {
        let t = s as f64 / steps as f64;
        let (x, y) = (xa + t * (xb - xa), ya + t * (yb - ya));
        for dx in 0..thick {
            for dy in 0..thick {
                let (x, y) = (x.round() as i64 + dx, y.round() as i64 + dy);
                if (0..WIDTH as i64).contains(&x) && (0..HEIGHT as i64).contains(&y) {
                    let i = (y as usize * WIDTH + x as usize) * 3;
                    img[i..i + 3].copy_from_slice(&c);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plot_is_a_png_with_its_curve_drawn() {
        let path = std::env::temp_dir().join(format!("gencyl-plot-{}.png", std::process::id()));
        let y: Vec<f64> = (0..90).map(|k| (k as f64 * 0.1).sin().abs()).collect();
        write_line_plot(
            &path,
            &[Curve {
                y: &y,
                colour: [255, 0, 0],
            }],
            (-180.0, 180.0),
            &[0.0],
        )
        .unwrap();
        let decoder =
            png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (WIDTH as u32, HEIGHT as u32));
        let red = buf.chunks(3).filter(|p| p == &[255, 0, 0]).count();
        assert!(red > 500, "the curve is drawn: {red} pixels");
        let _ = std::fs::remove_file(&path);
    }
}
