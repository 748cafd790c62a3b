//! The image a ROS map_server YAML file names, as grey values: PGM (P5 binary or P2 text, 8 or
//! 16 bits), or PNG (grey, grey with alpha, RGB, RGBA or a palette; 1-16 bits), as Nav2's
//! `map_saver_cli --fmt png` writes. A PNG's pixel is the mean of its colour channels, and
//! its alpha is averaged in where map_server does so: in trinary mode, where an opaque pixel
//! so reads lighter (map_server's unknown grey, 205, reads as free in an RGBA image, in
//! map_server as here); scale and raw modes leave alpha out.

use std::io::Cursor;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Most pixels an image may have.
pub const MAX_PIXELS: usize = map::limits::GRID_FILE_CELLS;

/// Why an image was rejected.
#[derive(Debug, Error, PartialEq)]
#[error("{path}: {message}")]
pub struct ImageError {
    pub path: PathBuf,
    pub message: String,
}

/// How a PNG pixel's channels become one value ([`read`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channels {
    /// The mean of the colour channels and the alpha (map_server's trinary mode).
    WithAlpha,
    /// The mean of the colour channels, the alpha left out (scale mode).
    ColourOnly,
    /// As `ColourOnly`, truncated to a whole value of 0-255 (raw mode: the value is the
    /// occupancy in percent).
    ColourTruncated,
}

/// Reads a PGM or PNG image (told apart by its first bytes); `path` names it in errors.
pub fn read(bytes: &[u8], path: &Path, channels: Channels) -> Result<Pgm, ImageError> {
    if bytes.starts_with(b"\x89PNG") {
        read_png(bytes, path, channels)
    } else {
        Pgm::parse(bytes, path)
    }
}

/// Decodes a PNG into grey values: 8-bit images as sums over the averaged channels, with
/// `maxval` 255 times their count, so that a value over `maxval` is the exact mean; 16-bit
/// images as the mean rounded, of 65535.
fn read_png(bytes: &[u8], path: &Path, channels: Channels) -> Result<Pgm, ImageError> {
    let err = |message: String| ImageError { path: path.to_owned(), message };
    // the decoder may allocate for at most the largest image read, at 8 bytes a pixel
    let limits = png::Limits { bytes: MAX_PIXELS.saturating_mul(8) };
    let mut decoder = png::Decoder::new_with_limits(Cursor::new(bytes), limits);
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder.read_info().map_err(|e| err(format!("not a readable PNG: {e}")))?;
    let (width, height) = (reader.info().width as usize, reader.info().height as usize);
    let pixels = width.saturating_mul(height);
    if pixels == 0 || pixels > MAX_PIXELS {
        return Err(err(format!("a {width} x {height} image: at least 1 and at most {MAX_PIXELS} pixels are read")));
    }
    let (colour, depth) = reader.output_color_type();
    let size = reader.output_buffer_size().ok_or_else(|| err(format!("a {width} x {height} image is too large")))?;
    let mut buffer = vec![0; size];
    let frame = reader.next_frame(&mut buffer).map_err(|e| err(format!("the image data is broken: {e}")))?;
    let samples = colour.samples();
    let wide = depth == png::BitDepth::Sixteen;
    let sample_bytes = if wide { 2 } else { 1 };
    let row_bytes = width * samples * sample_bytes;
    if frame.line_size < row_bytes || buffer.len() < frame.line_size * height {
        return Err(err(format!("the image data stops short of {width} x {height} pixels")));
    }
    let has_alpha = matches!(colour, png::ColorType::GrayscaleAlpha | png::ColorType::Rgba);
    let averaged = if has_alpha && channels != Channels::WithAlpha { samples - 1 } else { samples };
    let sample = |px: &[u8], k: usize| -> u32 {
        if wide {
            u32::from(u16::from_be_bytes([px[2 * k], px[2 * k + 1]]))
        } else {
            u32::from(px[k])
        }
    };
    let count = averaged as u32;
    let full: u32 = if wide { 65535 } else { 255 };
    let exact_sum = !wide && channels != Channels::ColourTruncated;
    let mut values = Vec::with_capacity(pixels);
    for row in buffer.chunks(frame.line_size).take(height) {
        for px in row[..row_bytes].chunks_exact(samples * sample_bytes) {
            let sum: u32 = (0..averaged).map(|k| sample(px, k)).sum();
            let value = match channels {
                _ if exact_sum => sum,
                Channels::ColourTruncated => sum / count,
                _ => (sum + count / 2) / count,
            };
            values.push(value.min(u32::from(u16::MAX)) as u16);
        }
    }
    let maxval = if exact_sum { full * count } else { full };
    Ok(Pgm { width, height, maxval: maxval.min(u32::from(u16::MAX)) as u16, values })
}

/// A grey image: `width` x `height` values of `maxval` at most, the top row first. A PGM holds
/// one as it is; a PNG is read into one ([`read`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Pgm {
    pub width: usize,
    pub height: usize,
    pub maxval: u16,
    pub values: Vec<u16>,
}

impl Pgm {
    /// Parses a P5 (binary) or P2 (text) PGM; `path` names it in errors.
    pub fn parse(bytes: &[u8], path: &Path) -> Result<Self, ImageError> {
        let err = |message: String| ImageError { path: path.to_owned(), message };
        let binary = match bytes.get(..2) {
            Some(b"P5") => true,
            Some(b"P2") => false,
            _ => return Err(err("neither a PGM (P5, P2) nor a PNG image".into())),
        };
        // the header: magic, width, height, maxval, with comments; one whitespace byte after
        let mut pos = 2;
        let mut header = [0usize; 3];
        for (k, what) in ["width", "height", "maxval"].iter().enumerate() {
            header[k] = next_number(bytes, &mut pos).ok_or_else(|| err(format!("the header has no {what}")))?;
        }
        let [width, height, maxval] = header;
        if width == 0 || height == 0 || !(1..=65535).contains(&maxval) {
            return Err(err(format!(
                "a {width} x {height} image with maxval {maxval}: none of them may be 0, and maxval is at most 65535"
            )));
        }
        let cells = width
            .checked_mul(height)
            .filter(|&n| n <= MAX_PIXELS)
            .ok_or_else(|| err(format!("{width} x {height} pixels: at most {MAX_PIXELS} are read")))?;
        let maxval = maxval as u16;
        let mut values = Vec::with_capacity(cells);
        if binary {
            let data = bytes.get(pos + 1..).unwrap_or(&[]);
            let wide = maxval > 255;
            let need = cells * if wide { 2 } else { 1 };
            if data.len() < need {
                return Err(err(format!("the image data stops after {} of {need} bytes", data.len())));
            }
            if wide {
                values.extend(data[..need].chunks_exact(2).map(|b| u16::from_be_bytes([b[0], b[1]])));
            } else {
                values.extend(data[..need].iter().map(|&b| u16::from(b)));
            }
        } else {
            for k in 0..cells {
                let v =
                    next_number(bytes, &mut pos).ok_or_else(|| err(format!("the image has {k} of {cells} values")))?;
                values.push(v.min(65535) as u16);
            }
        }
        if let Some(k) = values.iter().position(|&v| v > maxval) {
            return Err(err(format!("pixel {k} has value {} above maxval {maxval}", values[k])));
        }
        Ok(Pgm { width, height, maxval, values })
    }

    /// The image as binary PGM (P5, 8 bits when `maxval` allows).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = format!("P5\n# gema2\n{} {}\n{}\n", self.width, self.height, self.maxval).into_bytes();
        if self.maxval > 255 {
            out.extend(self.values.iter().flat_map(|v| v.to_be_bytes()));
        } else {
            out.extend(self.values.iter().map(|&v| v as u8));
        }
        out
    }
}

/// The next decimal number of a PGM header or text body, skipping whitespace and comments.
fn next_number(bytes: &[u8], pos: &mut usize) -> Option<usize> {
    loop {
        match bytes.get(*pos)? {
            b'#' => {
                while bytes.get(*pos).is_some_and(|&b| b != b'\n') {
                    *pos += 1;
                }
            }
            b if b.is_ascii_whitespace() => *pos += 1,
            _ => break,
        }
    }
    let start = *pos;
    while bytes.get(*pos).is_some_and(u8::is_ascii_digit) {
        *pos += 1;
    }
    std::str::from_utf8(&bytes[start..*pos]).ok()?.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A `width` x `height` PNG of `colour` and `depth` holding `data` (rows top first), with a
    /// palette and its transparency when given.
    fn png_of(
        width: u32,
        height: u32,
        colour: png::ColorType,
        depth: png::BitDepth,
        data: &[u8],
        palette: Option<(&[u8], &[u8])>,
    ) -> Vec<u8> {
        let mut out = Vec::new();
        {
            let mut e = png::Encoder::new(&mut out, width, height);
            e.set_color(colour);
            e.set_depth(depth);
            if let Some((rgb, alpha)) = palette {
                e.set_palette(rgb.to_vec());
                e.set_trns(alpha.to_vec());
            }
            let mut w = e.write_header().unwrap();
            w.write_image_data(data).unwrap();
        }
        out
    }

    /// Each pixel's mean over its averaged channels, in 0..=1.
    fn shades(p: &Pgm) -> Vec<f64> {
        p.values.iter().map(|&v| f64::from(v) / f64::from(p.maxval)).collect()
    }

    #[test]
    fn a_grey_png_reads_as_the_same_pgm() {
        use png::{BitDepth::*, ColorType::*};
        let values = [0u8, 254, 205, 10, 20, 30];
        let png = png_of(3, 2, Grayscale, Eight, &values, None);
        let p = read(&png, Path::new("a.png"), Channels::WithAlpha).unwrap();
        let pgm = Pgm::parse(b"P2\n3 2\n255\n0 254 205\n10 20 30\n", Path::new("a.pgm")).unwrap();
        assert_eq!(p, pgm);
        // 16 bits, big-endian
        let wide = png_of(2, 1, Grayscale, Sixteen, &[0xff, 0xff, 0x01, 0x02], None);
        let p = read(&wide, Path::new("b.png"), Channels::WithAlpha).unwrap();
        assert_eq!((p.maxval, p.values.clone()), (65535, vec![65535, 0x0102]));
        // 1-bit grey expands to 0 and 255: a row is padded to a whole byte
        let bits = png_of(3, 1, Grayscale, One, &[0b1010_0000], None);
        assert_eq!(read(&bits, Path::new("c.png"), Channels::WithAlpha).unwrap().values, vec![255, 0, 255]);
    }

    #[test]
    fn colour_channels_are_averaged_and_alpha_only_in_trinary_mode() {
        use png::{BitDepth::*, ColorType::*};
        // black, white, and a red pixel; opaque and half transparent
        let rgba = [0, 0, 0, 255, 255, 255, 255, 255, 255, 0, 0, 128];
        let png = png_of(3, 1, Rgba, Eight, &rgba, None);
        let with = shades(&read(&png, Path::new("a.png"), Channels::WithAlpha).unwrap());
        let expect = [255.0 / 4.0, 1.0 * 255.0, (255.0 + 128.0) / 4.0].map(|s| s / 255.0);
        for (got, want) in with.iter().zip(expect) {
            assert!((got - want).abs() < 1e-12, "{with:?}");
        }
        let without = shades(&read(&png, Path::new("a.png"), Channels::ColourOnly).unwrap());
        assert_eq!(without, vec![0.0, 1.0, 1.0 / 3.0]);
        // raw mode: the truncated mean, of 255
        let raw = read(&png_of(1, 1, Rgb, Eight, &[100, 0, 1], None), Path::new("r.png"), Channels::ColourTruncated);
        assert_eq!(raw.map(|p| (p.values, p.maxval)), Ok((vec![33], 255)));
        // grey with alpha
        let ga = png_of(2, 1, GrayscaleAlpha, Eight, &[0, 255, 200, 0], None);
        assert_eq!(shades(&read(&ga, Path::new("g.png"), Channels::ColourOnly).unwrap()), vec![0.0, 200.0 / 255.0]);
        assert_eq!(shades(&read(&ga, Path::new("g.png"), Channels::WithAlpha).unwrap()), vec![0.5, 100.0 / 255.0]);
    }

    #[test]
    fn a_palette_png_reads_through_its_palette_and_transparency() {
        use png::{BitDepth::*, ColorType::*};
        // entry 0 black, 1 white, 2 map_server's unknown grey; entry 2 fully transparent
        let palette: [u8; 9] = [0, 0, 0, 255, 255, 255, 205, 205, 205];
        let png = png_of(3, 1, Indexed, Eight, &[1, 0, 2], Some((&palette, &[255, 255, 0])));
        let p = read(&png, Path::new("p.png"), Channels::ColourOnly).unwrap();
        assert_eq!(shades(&p), vec![1.0, 0.0, 205.0 / 255.0]);
        let p = read(&png, Path::new("p.png"), Channels::WithAlpha).unwrap();
        assert_eq!(shades(&p), vec![1.0, 255.0 / 1020.0, 615.0 / 1020.0]);
    }

    #[test]
    fn broken_pngs_are_refused_in_words() {
        use png::{BitDepth::*, ColorType::*};
        let good = png_of(4, 4, Grayscale, Eight, &[7; 16], None);
        // the image data cut short
        let cut = &good[..good.len() - 20];
        let e = read(cut, Path::new("m.png"), Channels::WithAlpha).unwrap_err().to_string();
        assert!(e.starts_with("m.png: ") && e.contains("broken"), "{e}");
        // a header claiming more pixels than are read, with its checksum mended
        let mut huge = good.clone();
        huge[16..24].copy_from_slice(&[0, 1, 0, 0, 0, 1, 0, 0]);
        let crc = crc32(&huge[12..29]);
        huge[29..33].copy_from_slice(&crc.to_be_bytes());
        let e = read(&huge, Path::new("m.png"), Channels::WithAlpha).unwrap_err().to_string();
        assert!(e.contains("65536 x 65536") && e.contains("at most"), "{e}");
        // a signature and nothing else
        let e = read(b"\x89PNG\r\n\x1a\n", Path::new("m.png"), Channels::WithAlpha).unwrap_err().to_string();
        assert!(e.contains("not a readable PNG"), "{e}");
    }

    /// The CRC-32 a PNG chunk ends with.
    fn crc32(bytes: &[u8]) -> u32 {
        let mut c = 0xffff_ffffu32;
        for &b in bytes {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 == 1 { 0xedb8_8320 ^ (c >> 1) } else { c >> 1 };
            }
        }
        !c
    }

    proptest! {
        /// Bytes after a PNG signature never panic the reader.
        #[test]
        fn arbitrary_png_bytes_are_an_error_or_an_image(bytes in proptest::collection::vec(any::<u8>(), 0..96)) {
            let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
            png.extend(&bytes);
            let _ = read(&png, Path::new("x.png"), Channels::WithAlpha);
        }
    }
}
