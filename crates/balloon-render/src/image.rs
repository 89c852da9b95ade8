//! An 8-bit RGB image and its PNG encoding.

use crate::RenderError;
use std::io::{BufWriter, Write};
use std::path::Path;

/// An RGB image, 8 bits per channel, rows top to bottom.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    width: u32,
    height: u32,
    rgb: Vec<u8>,
}

/// Largest accepted side, pixels (keeps a typo such as `64000x48000` from allocating gigabytes).
pub(crate) const MAX_SIDE: u32 = 16384;

impl Image {
    /// A `width x height` image filled with `color`. Both sides must be in `1..=16384`.
    pub fn new(width: u32, height: u32, color: [u8; 3]) -> Result<Self, RenderError> {
        check_size(width, height)?;
        let mut rgb = vec![0u8; 3 * width as usize * height as usize];
        for px in rgb.chunks_exact_mut(3) {
            px.copy_from_slice(&color);
        }
        Ok(Self { width, height, rgb })
    }

    /// Width, pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height, pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The pixels, `3 * width * height` bytes, RGB, row-major from the top.
    pub fn pixels(&self) -> &[u8] {
        &self.rgb
    }

    /// Mutable pixels.
    pub fn pixels_mut(&mut self) -> &mut [u8] {
        &mut self.rgb
    }

    /// The pixel at column `x`, row `y` (`None` outside).
    pub fn get(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        (x < self.width && y < self.height).then(|| {
            let i = 3 * (y as usize * self.width as usize + x as usize);
            [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
        })
    }

    /// Sets the pixel at `(x, y)`; coordinates outside the image are ignored.
    #[inline]
    pub fn set(&mut self, x: i64, y: i64, color: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as u64) < self.width as u64 && (y as u64) < self.height as u64 {
            let i = 3 * (y as usize * self.width as usize + x as usize);
            self.rgb[i..i + 3].copy_from_slice(&color);
        }
    }

    /// Fills the rectangle `[x0, x0 + w) x [y0, y0 + h)` (clipped) with `color`.
    pub fn fill_rect(&mut self, x0: i64, y0: i64, w: i64, h: i64, color: [u8; 3]) {
        for y in y0.max(0)..(y0 + h).min(self.height as i64) {
            for x in x0.max(0)..(x0 + w).min(self.width as i64) {
                self.set(x, y, color);
            }
        }
    }

    /// Reuses the allocation for a `width x height` image filled with `color`.
    pub(crate) fn reset(&mut self, width: u32, height: u32, color: [u8; 3]) {
        self.width = width;
        self.height = height;
        self.rgb.clear();
        self.rgb.resize(3 * width as usize * height as usize, 0);
        for px in self.rgb.chunks_exact_mut(3) {
            px.copy_from_slice(&color);
        }
    }

    /// Encodes the image as an 8-bit RGB PNG into `out`.
    pub fn encode_png<W: Write>(&self, out: W) -> Result<(), RenderError> {
        self.encode_png_named(out, Path::new("<memory>"))
    }

    fn encode_png_named<W: Write>(&self, out: W, path: &Path) -> Result<(), RenderError> {
        let enc_err = |e: png::EncodingError| RenderError::Encode {
            path: path.to_path_buf(),
            format: "PNG",
            source: Box::new(e),
        };
        let mut enc = png::Encoder::new(out, self.width, self.height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(enc_err)?;
        w.write_image_data(&self.rgb).map_err(enc_err)?;
        w.finish().map_err(enc_err)?;
        Ok(())
    }

    /// Reads an 8-bit RGB or RGBA PNG file (alpha is dropped), e.g. to check a render.
    pub fn read_png(path: &Path) -> Result<Self, RenderError> {
        let dec_err = |e: png::DecodingError| RenderError::Decode {
            path: path.to_path_buf(),
            format: "PNG",
            source: Box::new(e),
        };
        let file = std::fs::File::open(path).map_err(|source| RenderError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let mut reader = png::Decoder::new(std::io::BufReader::new(file))
            .read_info()
            .map_err(dec_err)?;
        let size = reader
            .output_buffer_size()
            .ok_or_else(|| dec_err(png::DecodingError::LimitsExceeded))?;
        let mut buf = vec![0; size];
        let info = reader.next_frame(&mut buf).map_err(dec_err)?;
        let channels = match (info.color_type, info.bit_depth) {
            (png::ColorType::Rgb, png::BitDepth::Eight) => 3,
            (png::ColorType::Rgba, png::BitDepth::Eight) => 4,
            (c, d) => {
                return Err(RenderError::UnsupportedPng {
                    path: path.to_path_buf(),
                    color_type: match c {
                        png::ColorType::Grayscale => "grayscale",
                        png::ColorType::GrayscaleAlpha => "grayscale-alpha",
                        png::ColorType::Indexed => "indexed",
                        png::ColorType::Rgb => "RGB",
                        png::ColorType::Rgba => "RGBA",
                    },
                    bit_depth: d as u8,
                });
            }
        };
        let mut img = Image::new(info.width, info.height, [0; 3])?;
        for (dst, src) in img
            .rgb
            .chunks_exact_mut(3)
            .zip(buf[..info.buffer_size()].chunks_exact(channels))
        {
            dst.copy_from_slice(&src[..3]);
        }
        Ok(img)
    }

    /// Writes the image as a PNG file, atomically: to a temporary name beside `path`, then
    /// renamed, so `path` is either the complete new image or untouched.
    pub fn write_png(&self, path: &Path) -> Result<(), RenderError> {
        write_atomically(path, |w| self.encode_png_named(w, path))
    }
}

/// Checks an image size.
pub(crate) fn check_size(width: u32, height: u32) -> Result<(), RenderError> {
    for (name, v) in [("width", width), ("height", height)] {
        if v == 0 || v > MAX_SIDE {
            return Err(RenderError::invalid(
                name,
                v,
                "image sides must be between 1 and 16384 pixels",
            ));
        }
    }
    Ok(())
}

/// Creates `path` through a temporary file in the same folder and a rename.
pub(crate) fn write_atomically(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<std::fs::File>) -> Result<(), RenderError>,
) -> Result<(), RenderError> {
    let io = |source| RenderError::Io {
        path: path.to_path_buf(),
        source,
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "image".into());
    let tmp = path.with_file_name(format!(".{name}.tmp"));
    let file = std::fs::File::create(&tmp).map_err(|source| RenderError::Io {
        path: tmp.clone(),
        source,
    })?;
    let mut w = BufWriter::new(file);
    let result = body(&mut w).and_then(|()| w.flush().map_err(io));
    drop(w);
    // A failed write or rename (disk full, a folder in the way) leaves no temporary file.
    let result = result.and_then(|()| std::fs::rename(&tmp, path).map_err(io));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file that is not a PNG is a typed decode error naming the file, with the decoder's
    /// error as its source; an unsupported layout names the layout.
    #[test]
    fn bad_png_files_are_typed_errors() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("not.png");
        std::fs::write(&path, b"GIF89a, not a png").unwrap();
        let err = Image::read_png(&path).unwrap_err();
        assert!(
            matches!(&err, RenderError::Decode { format: "PNG", .. }),
            "{err}"
        );
        assert!(err.to_string().contains("not.png"), "{err}");
        assert!(std::error::Error::source(&err).is_some());
        let gray = dir.path().join("gray.png");
        let mut enc = png::Encoder::new(std::fs::File::create(&gray).unwrap(), 2, 2);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(&[0, 1, 2, 3]).unwrap();
        w.finish().unwrap();
        let err = Image::read_png(&gray).unwrap_err();
        assert!(
            matches!(
                err,
                RenderError::UnsupportedPng {
                    color_type: "grayscale",
                    bit_depth: 8,
                    ..
                }
            ),
            "{err}"
        );
    }

    #[test]
    fn png_round_trips_through_the_decoder() {
        let mut img = Image::new(7, 5, [10, 20, 30]).unwrap();
        img.set(3, 2, [255, 0, 128]);
        img.set(-1, 2, [1, 1, 1]); // ignored
        let mut bytes = Vec::new();
        img.encode_png(&mut bytes).unwrap();
        let dec = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = dec.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (7, 5));
        assert_eq!(&buf[..info.buffer_size()], img.pixels());
        assert_eq!(img.get(3, 2), Some([255, 0, 128]));
        assert_eq!(img.get(7, 0), None);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.png");
        img.write_png(&p).unwrap();
        assert_eq!(Image::read_png(&p).unwrap(), img);
        std::fs::write(&p, b"not a png").unwrap();
        assert!(
            Image::read_png(&p)
                .unwrap_err()
                .to_string()
                .contains("a.png")
        );
    }

    #[test]
    fn bad_sizes_and_paths_are_clear_errors() {
        let e = Image::new(0, 10, [0; 3]).unwrap_err();
        assert!(e.to_string().contains("width"), "{e}");
        let e = Image::new(10, 20000, [0; 3]).unwrap_err();
        assert!(e.to_string().contains("height"), "{e}");
        let img = Image::new(2, 2, [0; 3]).unwrap();
        let e = img
            .write_png(Path::new("/nonexistent-dir/x/y.png"))
            .unwrap_err();
        assert!(e.to_string().contains("nonexistent-dir"), "{e}");
    }
}
