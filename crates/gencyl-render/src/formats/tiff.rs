//! Multi-page TIFF stacks: one grayscale page per view (CT projections, `float32`,
//! uncompressed) or per slice (label volumes, `uint32`, Deflate), written page by page so that
//! a stack never needs to be in memory whole. A stack of more than 4 GiB less 16 MiB of pixels is written as
//! BigTIFF (the classic format's offsets are 32-bit), which tifffile, ImageJ/Fiji and libtiff
//! read.

use std::io::{Seek, Write};
use std::path::Path;

use tiff::TiffResult;
use tiff::decoder::{Decoder, DecodingResult};
use tiff::encoder::colortype::{ColorType, Gray32, Gray32Float};
use tiff::encoder::{Compression, DeflateLevel, TiffEncoder, TiffKindBig, TiffValue};

/// Past this many pixel bytes a stack is BigTIFF.
const CLASSIC_LIMIT: u64 = (1 << 32) - (16 << 20);

/// A pixel type a stack holds.
pub trait Pixel: Copy + Default + Send + Sync + 'static {
    /// The TIFF colour type of one grayscale sample.
    type Color: ColorType<Inner = Self>;
}
impl Pixel for f32 {
    type Color = Gray32Float;
}
impl Pixel for u32 {
    type Color = Gray32;
}

/// Writes `pages` pages of `width x height` pixels to `out`, Deflate-compressed if `deflate`;
/// `page(k, pixels)` fills page `k` (row after row; it may fail, which ends the stack with its
/// message).
pub fn write_pages<P: Pixel, W: Write + Seek>(
    out: &mut W,
    size: (u32, u32),
    pages: usize,
    deflate: bool,
    mut page: impl FnMut(usize, &mut [P]) -> Result<(), String>,
) -> Result<(), String>
where
    [P]: TiffValue,
{
    write_stacks(
        std::slice::from_mut(out),
        size,
        pages,
        deflate,
        |k, stacks| page(k, &mut stacks[0]),
    )
}

/// [`write_pages`] for several stacks of the same size at once, one per writer of `outs`:
/// `page(k, pages)` fills page `k` of every stack (`pages[i]` for `outs[i]`).
pub fn write_stacks<P: Pixel, W: Write + Seek>(
    outs: &mut [W],
    (width, height): (u32, u32),
    pages: usize,
    deflate: bool,
    mut page: impl FnMut(usize, &mut [Vec<P>]) -> Result<(), String>,
) -> Result<(), String>
where
    [P]: TiffValue,
{
    // Pixels, and each page's directory (under 1 KiB) and strip table (at most a strip per
    // row, 16 bytes each): past 4 GiB less 16 MiB of that, BigTIFF.
    let bytes = u64::from(width) * u64::from(height) * pages as u64 * size_of::<P>() as u64
        + pages as u64 * (1024 + 16 * u64::from(height));
    let compression = if deflate {
        Compression::Deflate(DeflateLevel::Fast)
    } else {
        Compression::Uncompressed
    };
    // Compressed pages can only be smaller: the raw size decides.
    let big = bytes > CLASSIC_LIMIT;
    let mut encoders = outs
        .iter_mut()
        .map(|out| Encoder::new(out, big, compression))
        .collect::<Result<Vec<_>, String>>()?;
    let mut pixels = vec![vec![P::default(); width as usize * height as usize]; encoders.len()];
    for k in 0..pages {
        page(k, &mut pixels)?;
        for (encoder, px) in encoders.iter_mut().zip(&pixels) {
            encoder.write(width, height, px)?;
        }
    }
    Ok(())
}

/// A classic or BigTIFF encoder.
enum Encoder<'a, W: Write + Seek> {
    Classic(TiffEncoder<&'a mut W>),
    Big(TiffEncoder<&'a mut W, TiffKindBig>),
}

impl<'a, W: Write + Seek> Encoder<'a, W> {
    fn new(out: &'a mut W, big: bool, compression: Compression) -> Result<Self, String> {
        let tiff = |e: tiff::TiffError| format!("cannot write the TIFF: {e}");
        Ok(if big {
            Encoder::Big(
                TiffEncoder::new_big(out)
                    .map_err(tiff)?
                    .with_compression(compression),
            )
        } else {
            Encoder::Classic(
                TiffEncoder::new(out)
                    .map_err(tiff)?
                    .with_compression(compression),
            )
        })
    }

    fn write<P: Pixel>(&mut self, width: u32, height: u32, px: &[P]) -> Result<(), String>
    where
        [P]: TiffValue,
    {
        let written: TiffResult<()> = match self {
            Encoder::Classic(e) => e.write_image::<P::Color>(width, height, px),
            Encoder::Big(e) => e.write_image::<P::Color>(width, height, px),
        };
        written.map_err(|e| format!("cannot write the TIFF: {e}"))
    }
}

/// Every page of a grayscale `float32` or `uint32` stack: `(width, height, pages)`, the
/// pages row after row. For tests and small stacks (the whole stack is read).
pub fn read_pages<P: Pixel>(path: &Path) -> Result<(u32, u32, Vec<Vec<P>>), String>
where
    DecodingResult: Unpack<P>,
{
    let name = path.display();
    let file = std::fs::File::open(path).map_err(|e| format!("{name}: cannot read: {e}"))?;
    let mut decoder = Decoder::new(std::io::BufReader::new(file))
        .map_err(|e| format!("{name}: not a TIFF: {e}"))?;
    let (width, height) = decoder.dimensions().map_err(|e| format!("{name}: {e}"))?;
    let mut pages = Vec::new();
    loop {
        if decoder.dimensions().map_err(|e| format!("{name}: {e}"))? != (width, height) {
            return Err(format!("{name}: page {} has another size", pages.len()));
        }
        let image = decoder.read_image().map_err(|e| format!("{name}: {e}"))?;
        pages.push(
            image
                .unpack()
                .ok_or_else(|| format!("{name}: page {} holds another pixel type", pages.len()))?,
        );
        if !decoder.more_images() {
            break;
        }
        decoder.next_image().map_err(|e| format!("{name}: {e}"))?;
    }
    Ok((width, height, pages))
}

/// The pixels of a decoded page, if they are of type `P`.
pub trait Unpack<P> {
    /// The pixels, or `None` for another type.
    fn unpack(self) -> Option<Vec<P>>;
}
impl Unpack<f32> for DecodingResult {
    fn unpack(self) -> Option<Vec<f32>> {
        match self {
            DecodingResult::F32(v) => Some(v),
            _ => None,
        }
    }
}
impl Unpack<u32> for DecodingResult {
    fn unpack(self) -> Option<Vec<u32>> {
        match self {
            DecodingResult::U32(v) => Some(v),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pages_read_back_bit_for_bit() {
        let path = std::env::temp_dir().join(format!("gencyl-tiff-{}.tif", std::process::id()));
        let page = |k: usize, px: &mut [f32]| {
            for (i, p) in px.iter_mut().enumerate() {
                *p = (k * 100 + i) as f32 * 0.1 - 3.0;
            }
            Ok(())
        };
        let mut file = std::fs::File::create(&path).unwrap();
        write_pages::<f32, _>(&mut file, (5, 3), 4, false, page).unwrap();
        drop(file);
        let (w, h, pages) = read_pages::<f32>(&path).unwrap();
        assert_eq!((w, h, pages.len()), (5, 3, 4));
        for (k, got) in pages.iter().enumerate() {
            let mut want = vec![0.0; 15];
            page(k, &mut want).unwrap();
            assert_eq!(
                got.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                want.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
            );
        }
        assert!(
            read_pages::<u32>(&path)
                .unwrap_err()
                .contains("another pixel type")
        );
        let _ = std::fs::remove_file(&path);
    }

    #[test]
    fn a_failing_page_ends_the_stack_with_its_message() {
        let mut buf = std::io::Cursor::new(Vec::new());
        let err = write_pages::<u32, _>(&mut buf, (2, 2), 3, true, |k, _| {
            if k == 1 {
                Err("view 1 failed".into())
            } else {
                Ok(())
            }
        })
        .unwrap_err();
        assert_eq!(err, "view 1 failed");
    }
}
