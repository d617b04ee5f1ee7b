//! Writing pictures: PNG files and animated GIFs.

use super::raster::Picture;
use super::RenderError;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

fn create(path: &Path) -> Result<BufWriter<File>, RenderError> {
    File::create(path)
        .map(BufWriter::new)
        .map_err(|source| RenderError::Io {
            path: path.into(),
            source,
        })
}

fn encoding(path: &Path, message: impl ToString) -> RenderError {
    RenderError::Encode {
        path: path.into(),
        message: message.to_string(),
    }
}

/// Writes `picture` as an 8-bit PNG: RGB when it is opaque, RGBA otherwise.
pub fn save_png(picture: &Picture, path: &Path) -> Result<(), RenderError> {
    let mut encoder = png::Encoder::new(create(path)?, picture.width as u32, picture.height as u32);
    let opaque = picture.is_opaque();
    encoder.set_color(if opaque {
        png::ColorType::Rgb
    } else {
        png::ColorType::Rgba
    });
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| encoding(path, e))?;
    let data = if opaque {
        picture.rgb()
    } else {
        picture.rgba.clone()
    };
    writer
        .write_image_data(&data)
        .map_err(|e| encoding(path, e))?;
    writer.finish().map_err(|e| encoding(path, e))
}

/// An animated GIF being written frame by frame (looping).
pub struct GifWriter {
    path: PathBuf,
    encoder: gif::Encoder<BufWriter<File>>,
    size: (u16, u16),
    /// Delay between frames (1/100 s).
    delay: u16,
}

impl GifWriter {
    /// Starts a GIF of `width × height` pixels showing `fps` frames per second.
    pub fn create(path: &Path, width: usize, height: usize, fps: f64) -> Result<Self, RenderError> {
        let size = match (u16::try_from(width), u16::try_from(height)) {
            (Ok(w), Ok(h)) => (w, h),
            _ => {
                return Err(encoding(
                    path,
                    "a GIF is at most 65535 pixels wide and high",
                ))
            }
        };
        let mut encoder =
            gif::Encoder::new(create(path)?, size.0, size.1, &[]).map_err(|e| encoding(path, e))?;
        encoder
            .set_repeat(gif::Repeat::Infinite)
            .map_err(|e| encoding(path, e))?;
        Ok(GifWriter {
            path: path.into(),
            encoder,
            size,
            delay: (100.0 / fps).round().clamp(2.0, 65535.0) as u16,
        })
    }

    /// Appends one frame (colours quantised to the GIF's 256).
    pub fn push(&mut self, picture: &Picture) -> Result<(), RenderError> {
        if (picture.width, picture.height) != (self.size.0 as usize, self.size.1 as usize) {
            return Err(encoding(
                &self.path,
                "all frames of a GIF must have one size",
            ));
        }
        // Speed 10 of 30: NeuQuant's default quality, ~10 ms for a 640 × 480 frame.
        let mut frame = gif::Frame::from_rgb_speed(self.size.0, self.size.1, &picture.rgb(), 10);
        frame.delay = self.delay;
        self.encoder
            .write_frame(&frame)
            .map_err(|e| encoding(&self.path, e))
    }
}
