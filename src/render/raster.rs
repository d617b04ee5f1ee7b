//! A small CPU rasteriser: triangles with a depth buffer, translucent triangles blended over
//! it, depth-tested lines, and an 8-bit RGB picture that text can be drawn on.

use embedded_graphics::pixelcolor::Rgb888;
use embedded_graphics::prelude::{DrawTarget, OriginDimensions, Pixel, RgbColor, Size};

/// Linear RGB in [0, 1].
pub type Rgb = [f32; 3];

/// A picture being drawn: colour and depth per pixel. Depth is stored as 1/z (larger is
/// nearer), which interpolates linearly across a perspective-projected triangle.
pub struct Canvas {
    width: usize,
    height: usize,
    color: Vec<Rgb>,
    inverse_depth: Vec<f32>,
}

/// A vertex in picture space: x, y (pixels) and depth z > 0 (m along the view direction).
pub type ScreenPoint = [f64; 3];

impl Canvas {
    /// A canvas filled with a vertical gradient from `top` to `bottom`, and empty depth.
    pub fn new(width: usize, height: usize, top: Rgb, bottom: Rgb) -> Self {
        let mut color = Vec::with_capacity(width * height);
        for y in 0..height {
            let t = y as f32 / height.max(2).saturating_sub(1) as f32;
            let c = std::array::from_fn(|k| top[k] + (bottom[k] - top[k]) * t);
            color.extend(std::iter::repeat_n(c, width));
        }
        Canvas {
            width,
            height,
            color,
            inverse_depth: vec![0.0; width * height],
        }
    }

    /// Draws an opaque triangle where it is nearer than what is there.
    pub fn fill(&mut self, p: [ScreenPoint; 3], color: Rgb) {
        self.rasterise(p, |canvas, i, inverse_depth| {
            if inverse_depth > canvas.inverse_depth[i] {
                canvas.inverse_depth[i] = inverse_depth;
                canvas.color[i] = color;
            }
        });
    }

    /// Blends a translucent triangle (opacity `alpha`) over what is there, where it is nearer
    /// than the opaque surfaces; does not write depth. Translucent triangles must come back
    /// to front for the blend to be right.
    pub fn blend(&mut self, p: [ScreenPoint; 3], color: Rgb, alpha: f32) {
        self.rasterise(p, |canvas, i, inverse_depth| {
            if inverse_depth > canvas.inverse_depth[i] {
                let c = &mut canvas.color[i];
                *c = std::array::from_fn(|k| c[k] + (color[k] - c[k]) * alpha);
            }
        });
    }

    /// Calls `shade(canvas, pixel, 1/z)` for every pixel whose centre is inside `p`. Vertices
    /// are snapped to 1/256 pixel so that the edge tests are exact integers, and a centre
    /// exactly on an edge belongs to one side only (a tie rule on the edge's direction): two
    /// triangles sharing an edge cover each pixel once, which translucent blending needs.
    fn rasterise(&mut self, p: [ScreenPoint; 3], mut shade: impl FnMut(&mut Self, usize, f32)) {
        const SUB: f64 = 256.0;
        let limit = (4 * MAX_SIDE) as f64;
        let usable = |v: &ScreenPoint| v[2] > 0.0 && v[0].abs() < limit && v[1].abs() < limit;
        if !p.iter().all(usable) {
            return; // behind the camera or far off the picture: never the case for a fitted scene
        }
        let mut q = p.map(|v| [(v[0] * SUB).round() as i64, (v[1] * SUB).round() as i64]);
        let mut inverse = p.map(|v| 1.0 / v[2]);
        let mut area = edge(q[0], q[1], q[2]);
        if area == 0 {
            return;
        }
        if area < 0 {
            q.swap(1, 2);
            inverse.swap(1, 2);
            area = -area;
        }
        let x0 = (q.iter().map(|v| v[0]).min().unwrap_or(0) / SUB as i64 - 1).max(0) as usize;
        let y0 = (q.iter().map(|v| v[1]).min().unwrap_or(0) / SUB as i64 - 1).max(0) as usize;
        let x1 = ((q.iter().map(|v| v[0]).max().unwrap_or(0) / SUB as i64 + 2).max(0) as usize)
            .min(self.width);
        let y1 = ((q.iter().map(|v| v[1]).max().unwrap_or(0) / SUB as i64 + 2).max(0) as usize)
            .min(self.height);
        // An edge a → b owns the centres exactly on it if it runs down, or left along a row:
        // a shared edge runs the other way in the neighbour, which then does not own them.
        let owns = |a: [i64; 2], b: [i64; 2]| b[1] > a[1] || (b[1] == a[1] && b[0] < a[0]);
        let edges = [(q[1], q[2]), (q[2], q[0]), (q[0], q[1])];
        let bias = edges.map(|(a, b)| if owns(a, b) { 0 } else { 1 });
        let half = SUB as i64 / 2;
        for y in y0..y1 {
            for x in x0..x1 {
                let c = [x as i64 * SUB as i64 + half, y as i64 * SUB as i64 + half];
                let w = edges.map(|(a, b)| edge(a, b, c));
                if (0..3).all(|k| w[k] >= bias[k]) {
                    let inverse_depth =
                        (0..3).map(|k| w[k] as f64 * inverse[k]).sum::<f64>() / area as f64;
                    shade(self, y * self.width + x, inverse_depth as f32);
                }
            }
        }
    }

    /// Draws a line `width` pixels wide from `a` to `b`. With `depth_test`, only where it is
    /// not behind an opaque surface (with a relative bias of `1e-3`, so that edges lying on a
    /// surface are drawn).
    pub fn line(
        &mut self,
        a: ScreenPoint,
        b: ScreenPoint,
        color: Rgb,
        width: f64,
        depth_test: bool,
    ) {
        if !(a[2] > 0.0 && b[2] > 0.0) {
            return;
        }
        let length = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
        let samples = (2.0 * length).ceil().max(1.0) as usize;
        let r = width / 2.0;
        for s in 0..=samples {
            let t = s as f64 / samples as f64;
            let (x, y) = (a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t);
            let inverse_depth = ((1.0 - t) / a[2] + t / b[2]) as f32;
            let (xa, xb) = (
                (x - r).floor().max(0.0) as usize,
                ((x + r).ceil() as usize).min(self.width),
            );
            let (ya, yb) = (
                (y - r).floor().max(0.0) as usize,
                ((y + r).ceil() as usize).min(self.height),
            );
            for py in ya..yb {
                for px in xa..xb {
                    let (dx, dy) = (px as f64 + 0.5 - x, py as f64 + 0.5 - y);
                    if dx * dx + dy * dy > r * r {
                        continue;
                    }
                    let i = py * self.width + px;
                    if !depth_test || inverse_depth * 1.001 >= self.inverse_depth[i] {
                        self.color[i] = color;
                    }
                }
            }
        }
    }

    /// The picture, averaged down by `factor` in each direction (supersampling against jagged
    /// edges), in 8-bit sRGB-ish RGB (the colours are used as display values directly).
    pub fn downsample(&self, factor: usize) -> Picture {
        let (w, h) = (self.width / factor, self.height / factor);
        let mut rgb = Vec::with_capacity(3 * w * h);
        let norm = 1.0 / (factor * factor) as f32;
        for y in 0..h {
            for x in 0..w {
                let mut sum = [0.0f32; 3];
                for sy in 0..factor {
                    let row = (y * factor + sy) * self.width + x * factor;
                    for c in &self.color[row..row + factor] {
                        for k in 0..3 {
                            sum[k] += c[k];
                        }
                    }
                }
                rgb.extend(sum.map(|s| (s * norm * 255.0).round().clamp(0.0, 255.0) as u8));
            }
        }
        Picture {
            width: w,
            height: h,
            rgb,
        }
    }
}

/// Largest canvas side (supersampled pixels) for which the edge tests cannot overflow:
/// coordinates up to 4 × this in 1/256 pixel, squared, stay far below 2⁶³.
pub const MAX_SIDE: usize = 1 << 17;

/// Twice the signed area of (a, b, c) in the picture plane (1/256-pixel units, exact).
fn edge(a: [i64; 2], b: [i64; 2], c: [i64; 2]) -> i64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// An 8-bit RGB picture, row-major from the top left.
#[derive(Clone, Debug, PartialEq)]
pub struct Picture {
    /// Width (pixels).
    pub width: usize,
    /// Height (pixels).
    pub height: usize,
    /// `3 × width × height` bytes.
    pub rgb: Vec<u8>,
}

impl Picture {
    /// A picture of one colour.
    pub fn filled(width: usize, height: usize, color: [u8; 3]) -> Self {
        Picture {
            width,
            height,
            rgb: color.repeat(width * height),
        }
    }

    /// The colour at pixel (x, y).
    pub fn pixel(&self, x: usize, y: usize) -> [u8; 3] {
        let i = 3 * (y * self.width + x);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// Sets the colour at (x, y), if inside.
    pub fn set(&mut self, x: i64, y: i64, color: [u8; 3]) {
        if (0..self.width as i64).contains(&x) && (0..self.height as i64).contains(&y) {
            let i = 3 * (y as usize * self.width + x as usize);
            self.rgb[i..i + 3].copy_from_slice(&color);
        }
    }

    /// Copies `other` in with its top left corner at (x, y) (clipped).
    pub fn blit(&mut self, other: &Picture, x: usize, y: usize) {
        for row in 0..other.height.min(self.height.saturating_sub(y)) {
            let cols = other.width.min(self.width.saturating_sub(x));
            let src = 3 * row * other.width;
            let dst = 3 * ((y + row) * self.width + x);
            self.rgb[dst..dst + 3 * cols].copy_from_slice(&other.rgb[src..src + 3 * cols]);
        }
    }
}

impl OriginDimensions for Picture {
    fn size(&self) -> Size {
        Size::new(self.width as u32, self.height as u32)
    }
}

impl DrawTarget for Picture {
    type Color = Rgb888;
    type Error = std::convert::Infallible;

    fn draw_iter<I>(&mut self, pixels: I) -> Result<(), Self::Error>
    where
        I: IntoIterator<Item = Pixel<Self::Color>>,
    {
        for Pixel(p, c) in pixels {
            self.set(p.x as i64, p.y as i64, [c.r(), c.g(), c.b()]);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearer_triangle_wins_whatever_the_order() {
        let far = [[0.0, 0.0, 2.0], [10.0, 0.0, 2.0], [0.0, 10.0, 2.0]];
        let near = [[0.0, 0.0, 1.0], [0.0, 10.0, 1.0], [10.0, 0.0, 1.0]]; // other winding
        for order in [[far, near], [near, far]] {
            let mut c = Canvas::new(10, 10, [0.0; 3], [0.0; 3]);
            c.fill(
                order[0],
                if order[0] == far {
                    [1.0, 0.0, 0.0]
                } else {
                    [0.0, 1.0, 0.0]
                },
            );
            c.fill(
                order[1],
                if order[1] == far {
                    [1.0, 0.0, 0.0]
                } else {
                    [0.0, 1.0, 0.0]
                },
            );
            let p = c.downsample(1);
            assert_eq!(p.pixel(2, 2), [0, 255, 0]);
            assert_eq!(p.pixel(9, 9), [0, 0, 0], "outside both");
        }
    }

    #[test]
    fn translucent_blends_only_in_front() {
        let mut c = Canvas::new(4, 4, [0.0; 3], [0.0; 3]);
        let square = |z: f64| {
            [
                [[0.0, 0.0, z], [4.0, 0.0, z], [4.0, 4.0, z]],
                [[0.0, 0.0, z], [4.0, 4.0, z], [0.0, 4.0, z]],
            ]
        };
        for t in square(2.0) {
            c.fill(t, [1.0, 1.0, 1.0]);
        }
        for t in square(3.0) {
            c.blend(t, [1.0, 0.0, 0.0], 0.5); // behind: no effect
        }
        for t in square(1.0) {
            c.blend(t, [0.0, 0.0, 0.0], 0.5); // in front: halves
        }
        assert_eq!(c.downsample(1).pixel(1, 1), [128, 128, 128]);
    }
}
