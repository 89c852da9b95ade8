//! Animated GIF output: a median-cut palette per frame and a streaming writer.

use crate::image::check_size;
use crate::{Image, RenderError};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// Reduces `img` to at most 256 colours by median cut on a 5-bit-per-channel histogram.
/// Returns the palette (mean colour of each box) and one palette index per pixel. An image with
/// at most 256 distinct 5-bit colours keeps them all.
pub fn quantize(img: &Image) -> (Vec<[u8; 3]>, Vec<u8>) {
    const BINS: usize = 1 << 15;
    let bin = |p: &[u8]| {
        ((p[0] as usize >> 3) << 10) | ((p[1] as usize >> 3) << 5) | (p[2] as usize >> 3)
    };
    // count and colour sums per bin
    let mut count = vec![0u32; BINS];
    let mut sums = vec![[0u64; 3]; BINS];
    for p in img.pixels().chunks_exact(3) {
        let b = bin(p);
        count[b] += 1;
        for k in 0..3 {
            sums[b][k] += p[k] as u64;
        }
    }
    // Occupied bins as (r5, g5, b5, bin index).
    let mut occupied: Vec<([u8; 3], u16)> = (0..BINS)
        .filter(|&b| count[b] > 0)
        .map(|b| {
            (
                [(b >> 10) as u8, ((b >> 5) & 31) as u8, (b & 31) as u8],
                b as u16,
            )
        })
        .collect();
    // Boxes are ranges of `occupied`.
    let mut boxes: Vec<(usize, usize)> = vec![(0, occupied.len())];
    while boxes.len() < 256 {
        // Pick the box with the largest (longest side x pixel count) that can be split.
        let mut best: Option<(usize, usize, f64)> = None;
        for (i, &(s, e)) in boxes.iter().enumerate() {
            if e - s < 2 {
                continue;
            }
            let (axis, range) = longest_axis(&occupied[s..e]);
            if range == 0 {
                continue;
            }
            let n: u64 = occupied[s..e]
                .iter()
                .map(|o| count[o.1 as usize] as u64)
                .sum();
            let score = range as f64 * n as f64;
            if best.is_none_or(|b| score > b.2) {
                best = Some((i, axis, score));
            }
        }
        let Some((i, axis, _)) = best else { break };
        let (s, e) = boxes[i];
        let slice = &mut occupied[s..e];
        slice.sort_unstable_by_key(|o| o.0[axis]);
        let total: u64 = slice.iter().map(|o| count[o.1 as usize] as u64).sum();
        let mut acc = 0u64;
        let mut cut = 1;
        for (k, o) in slice.iter().enumerate() {
            acc += count[o.1 as usize] as u64;
            if 2 * acc >= total {
                cut = (k + 1).clamp(1, slice.len() - 1);
                break;
            }
        }
        boxes[i] = (s, s + cut);
        boxes.push((s + cut, e));
    }
    let mut lut = vec![0u8; BINS];
    let mut palette = Vec::with_capacity(boxes.len());
    for (pi, &(s, e)) in boxes.iter().enumerate() {
        let mut n = 0u64;
        let mut c = [0u64; 3];
        for o in &occupied[s..e] {
            let b = o.1 as usize;
            n += count[b] as u64;
            for k in 0..3 {
                c[k] += sums[b][k];
            }
            lut[b] = pi as u8;
        }
        let n = n.max(1);
        palette.push(c.map(|v| ((v + n / 2) / n) as u8));
    }
    if palette.is_empty() {
        palette.push([0, 0, 0]);
    }
    let indices = img.pixels().chunks_exact(3).map(|p| lut[bin(p)]).collect();
    (palette, indices)
}

fn longest_axis(bins: &[([u8; 3], u16)]) -> (usize, u8) {
    let mut lo = [u8::MAX; 3];
    let mut hi = [0u8; 3];
    for (c, _) in bins {
        for k in 0..3 {
            lo[k] = lo[k].min(c[k]);
            hi[k] = hi[k].max(c[k]);
        }
    }
    let ranges = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
    let axis = (0..3).max_by_key(|&k| ranges[k]).unwrap_or(0);
    (axis, ranges[axis])
}

/// Writes an animated GIF frame by frame (each frame with its own palette), looping forever.
/// The file is written under a temporary name and renamed by [`GifWriter::finish`], so the
/// target is either a complete GIF or absent.
pub struct GifWriter {
    encoder: Option<gif::Encoder<BufWriter<File>>>,
    path: PathBuf,
    tmp: PathBuf,
    width: u16,
    height: u16,
    frames: usize,
}

impl std::fmt::Debug for GifWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GifWriter")
            .field("path", &self.path)
            .field("width", &self.width)
            .field("height", &self.height)
            .field("frames", &self.frames)
            .finish()
    }
}

impl GifWriter {
    /// Starts a `width x height` GIF at `path` (sides in `1..=16384`).
    pub fn create(path: &Path, width: u32, height: u32) -> Result<Self, RenderError> {
        check_size(width, height)?;
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "anim.gif".into());
        let tmp = path.with_file_name(format!(".{name}.tmp"));
        let file = File::create(&tmp).map_err(|source| RenderError::Io {
            path: tmp.clone(),
            source,
        })?;
        let mut encoder = gif::Encoder::new(BufWriter::new(file), width as u16, height as u16, &[])
            .map_err(|e| encode_err(path, e))?;
        encoder
            .set_repeat(gif::Repeat::Infinite)
            .map_err(|e| encode_err(path, e))?;
        Ok(Self {
            encoder: Some(encoder),
            path: path.to_path_buf(),
            tmp,
            width: width as u16,
            height: height as u16,
            frames: 0,
        })
    }

    /// Appends `img` (same size as the GIF) shown for `delay_cs` hundredths of a second
    /// (at least 2: most viewers treat smaller delays as 10).
    pub fn add_frame(&mut self, img: &Image, delay_cs: u16) -> Result<(), RenderError> {
        if img.width() != self.width as u32 || img.height() != self.height as u32 {
            return Err(RenderError::invalid(
                "frame size",
                format!("{}x{}", img.width(), img.height()),
                &format!("every GIF frame must be {}x{}", self.width, self.height),
            ));
        }
        if delay_cs < 2 {
            return Err(RenderError::invalid(
                "delay_cs",
                delay_cs,
                "the frame delay must be at least 2 hundredths of a second",
            ));
        }
        let (palette, indices) = quantize(img);
        let mut frame = gif::Frame {
            width: self.width,
            height: self.height,
            delay: delay_cs,
            buffer: std::borrow::Cow::Owned(indices),
            palette: Some(palette.iter().flatten().copied().collect()),
            ..gif::Frame::default()
        };
        frame.dispose = gif::DisposalMethod::Keep;
        let enc = self.encoder.as_mut().expect("encoder present until finish");
        enc.write_frame(&frame)
            .map_err(|e| encode_err(&self.path, e))?;
        self.frames += 1;
        Ok(())
    }

    /// Frames written so far.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Writes the trailer, renames the file into place and returns the number of frames.
    pub fn finish(mut self) -> Result<usize, RenderError> {
        let enc = self.encoder.take().expect("encoder present until finish");
        let result = enc
            .into_inner()
            .map_err(|e| encode_err(&self.path, e))
            .and_then(|mut w| {
                std::io::Write::flush(&mut w).map_err(|source| RenderError::Io {
                    path: self.path.clone(),
                    source,
                })
            })
            .and_then(|()| {
                std::fs::rename(&self.tmp, &self.path).map_err(|source| RenderError::Io {
                    path: self.path.clone(),
                    source,
                })
            });
        // A failed trailer, flush or rename leaves no temporary file.
        if result.is_err() {
            let _ = std::fs::remove_file(&self.tmp);
        }
        result.map(|()| self.frames)
    }
}

impl Drop for GifWriter {
    fn drop(&mut self) {
        // Not finished: remove the partial temporary file.
        if self.encoder.take().is_some() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Reads every frame of a GIF as a full RGB image (frames composed onto the canvas as a viewer
/// shows them) and the frame delays in hundredths of a second, e.g. to check an animation.
pub fn read_gif(path: &Path) -> Result<Vec<(Image, u16)>, RenderError> {
    let dec_err = |e: gif::DecodingError| RenderError::Decode {
        path: path.to_path_buf(),
        format: "GIF",
        source: Box::new(e),
    };
    let file = File::open(path).map_err(|source| RenderError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut opts = gif::DecodeOptions::new();
    opts.set_color_output(gif::ColorOutput::RGBA);
    let mut d = opts
        .read_info(std::io::BufReader::new(file))
        .map_err(dec_err)?;
    let (w, h) = (d.width() as u32, d.height() as u32);
    let mut canvas = Image::new(w, h, [0; 3])?;
    let mut out = Vec::new();
    while let Some(f) = d.read_next_frame().map_err(dec_err)? {
        for y in 0..f.height as u32 {
            for x in 0..f.width as u32 {
                let i = 4 * (y as usize * f.width as usize + x as usize);
                if f.buffer[i + 3] > 0 {
                    canvas.set(
                        (f.left as u32 + x) as i64,
                        (f.top as u32 + y) as i64,
                        [f.buffer[i], f.buffer[i + 1], f.buffer[i + 2]],
                    );
                }
            }
        }
        out.push((canvas.clone(), f.delay));
    }
    Ok(out)
}

fn encode_err(path: &Path, e: gif::EncodingError) -> RenderError {
    RenderError::Encode {
        path: path.to_path_buf(),
        format: "GIF",
        source: Box::new(e),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(w: u32, h: u32, shift: u8) -> Image {
        let mut img = Image::new(w, h, [0; 3]).unwrap();
        for y in 0..h {
            for x in 0..w {
                img.set(
                    x as i64,
                    y as i64,
                    [(x * 255 / w) as u8, (y * 255 / h) as u8, shift],
                );
            }
        }
        img
    }

    #[test]
    fn few_colours_are_kept_and_many_are_reduced_with_small_error() {
        let mut img = Image::new(4, 2, [10, 200, 30]).unwrap();
        img.set(0, 0, [250, 0, 0]);
        let (pal, idx) = quantize(&img);
        assert_eq!(pal.len(), 2);
        assert_eq!(pal[idx[0] as usize], [250, 0, 0]);
        assert_eq!(pal[idx[1] as usize], [10, 200, 30]);
        let img = gradient(256, 256, 77);
        let (pal, idx) = quantize(&img);
        assert_eq!(pal.len(), 256);
        let mut err = 0.0;
        for (p, &i) in img.pixels().chunks(3).zip(&idx) {
            let q = pal[i as usize];
            err += (0..3)
                .map(|k| (p[k] as f64 - q[k] as f64).abs())
                .sum::<f64>();
        }
        let mean = err / (256.0 * 256.0 * 3.0);
        assert!(mean < 6.0, "mean abs error {mean}");
    }

    #[test]
    fn gif_decodes_with_all_frames_and_the_asked_size() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.gif");
        let mut g = GifWriter::create(&path, 64, 48).unwrap();
        for s in [0u8, 120, 240] {
            g.add_frame(&gradient(64, 48, s), 10).unwrap();
        }
        assert!(g.add_frame(&gradient(10, 10, 0), 10).is_err());
        assert!(g.add_frame(&gradient(64, 48, 0), 1).is_err());
        assert!(!path.exists(), "renamed only when finished");
        assert_eq!(g.finish().unwrap(), 3);
        let mut opts = gif::DecodeOptions::new();
        opts.set_color_output(gif::ColorOutput::RGBA);
        let mut d = opts.read_info(File::open(&path).unwrap()).unwrap();
        assert_eq!((d.width(), d.height()), (64, 48));
        let mut blues = Vec::new();
        while let Some(f) = d.read_next_frame().unwrap() {
            assert_eq!(f.delay, 10);
            blues.push(f.buffer[2]);
        }
        assert_eq!(blues.len(), 3);
        assert!(blues[0] < 10 && blues[2] > 230, "{blues:?}");
        let frames = read_gif(&path).unwrap();
        assert_eq!(frames.len(), 3);
        assert_eq!(frames[2].1, 10);
        assert_eq!(frames[2].0.get(0, 0).unwrap()[2], blues[2]);
        // An unfinished writer leaves nothing behind.
        let p2 = dir.path().join("b.gif");
        drop(GifWriter::create(&p2, 8, 8).unwrap());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
