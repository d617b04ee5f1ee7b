//! A small CPU rasteriser: triangles with a depth buffer (flat or with colours interpolated
//! from their vertices), translucent triangles blended over it, depth-tested lines, and an
//! 8-bit RGBA picture that text can be drawn on.

/// Linear RGB in [0, 1].
pub type Rgb = [f32; 3];
/// Premultiplied RGBA in [0, 1]: colour times coverage, and coverage.
type Rgba = [f32; 4];

/// A picture being drawn: colour, coverage and depth per pixel. Depth is stored as 1/z
/// (larger is nearer), which interpolates linearly across a perspective-projected triangle.
pub struct Canvas {
    width: usize,
    height: usize,
    color: Vec<Rgba>,
    inverse_depth: Vec<f32>,
}

/// A vertex in picture space: x, y (pixels) and depth z > 0 (m along the view direction).
pub type ScreenPoint = [f64; 3];

impl Canvas {
    /// A canvas filled with a vertical gradient from `top` to `bottom` (`Some`) or transparent
    /// (`None`), and empty depth.
    pub fn new(width: usize, height: usize, backdrop: Option<(Rgb, Rgb)>) -> Self {
        let mut color = Vec::with_capacity(width * height);
        for y in 0..height {
            let c = match backdrop {
                Some((top, bottom)) => {
                    let t = y as f32 / height.max(2).saturating_sub(1) as f32;
                    let c: Rgb = std::array::from_fn(|k| top[k] + (bottom[k] - top[k]) * t);
                    [c[0], c[1], c[2], 1.0]
                }
                None => [0.0; 4],
            };
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
        self.fill_with(p, |_| color);
    }

    /// Draws an opaque triangle whose colour at a pixel is `shade(w)`, `w` the pixel's
    /// perspective-correct barycentric weights of the three vertices (so that attributes
    /// given per vertex interpolate as on the 3-D triangle).
    pub fn fill_with(&mut self, p: [ScreenPoint; 3], shade: impl Fn([f32; 3]) -> Rgb) {
        self.rasterise(p, |canvas, i, inverse_depth, w| {
            if inverse_depth > canvas.inverse_depth[i] {
                canvas.inverse_depth[i] = inverse_depth;
                let c = shade(w);
                canvas.color[i] = [c[0], c[1], c[2], 1.0];
            }
        });
    }

    /// Blends a translucent triangle (opacity `alpha`) over what is there, where it is nearer
    /// than the opaque surfaces; does not write depth. Translucent triangles must come back
    /// to front for the blend to be right.
    pub fn blend(&mut self, p: [ScreenPoint; 3], color: Rgb, alpha: f32) {
        self.blend_with(p, alpha, |_| color);
    }

    /// [`Canvas::blend`] with the colour `shade(w)` of [`Canvas::fill_with`].
    pub fn blend_with(&mut self, p: [ScreenPoint; 3], alpha: f32, shade: impl Fn([f32; 3]) -> Rgb) {
        self.blend_varying(p, |w| (shade(w), alpha));
    }

    /// [`Canvas::blend`] with the colour and the opacity `shade(w)` varying over the triangle
    /// (`w` as for [`Canvas::fill_with`]): glass that is more opaque where seen edge-on.
    pub fn blend_varying(&mut self, p: [ScreenPoint; 3], shade: impl Fn([f32; 3]) -> (Rgb, f32)) {
        self.rasterise(p, |canvas, i, inverse_depth, w| {
            if inverse_depth > canvas.inverse_depth[i] {
                let (color, alpha) = shade(w);
                let c = &mut canvas.color[i];
                // "Over" on premultiplied colour: the backdrop keeps 1 − alpha of itself.
                *c = std::array::from_fn(|k| {
                    let top = if k < 3 { color[k] } else { 1.0 };
                    top * alpha + c[k] * (1.0 - alpha)
                });
            }
        });
    }

    /// Calls `shade(canvas, pixel, 1/z, w)` for every pixel whose centre is inside `p`, `w`
    /// the perspective-correct barycentric weights of `p`'s vertices there. Vertices
    /// are snapped to 1/256 pixel so that the edge tests are exact integers, and a centre
    /// exactly on an edge belongs to one side only (a tie rule on the edge's direction): two
    /// triangles sharing an edge cover each pixel once, which translucent blending needs.
    fn rasterise(
        &mut self,
        p: [ScreenPoint; 3],
        mut shade: impl FnMut(&mut Self, usize, f32, [f32; 3]),
    ) {
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
        // Vertex k of the (possibly swapped) triangle is vertex order[k] of `p`.
        let mut order = [0, 1, 2];
        if area < 0 {
            q.swap(1, 2);
            inverse.swap(1, 2);
            order.swap(1, 2);
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
                    // Edge k's value is the weight of vertex k (opposite it) times the area.
                    let scaled: [f64; 3] = std::array::from_fn(|k| w[k] as f64 * inverse[k]);
                    let sum = scaled[0] + scaled[1] + scaled[2];
                    let mut weights = [0.0f32; 3];
                    for k in 0..3 {
                        weights[order[k]] = (scaled[k] / sum) as f32;
                    }
                    shade(
                        self,
                        y * self.width + x,
                        (sum / area as f64) as f32,
                        weights,
                    );
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
                        self.color[i] = [color[0], color[1], color[2], 1.0];
                    }
                }
            }
        }
    }

    /// The picture, averaged down by `factor` in each direction (supersampling against jagged
    /// edges), in 8-bit RGBA (the colours are used as display values directly).
    pub fn downsample(&self, factor: usize) -> Picture {
        let (w, h) = (self.width / factor, self.height / factor);
        let mut rgba = Vec::with_capacity(4 * w * h);
        let norm = 1.0 / (factor * factor) as f32;
        // Rounded to nearest; `as` saturates (and maps NaN to 0), so no clamp is needed.
        let byte = |v: f32| (v * 255.0 + 0.5) as u8;
        for y in 0..h {
            for x in 0..w {
                let mut sum = [0.0f32; 4];
                for sy in 0..factor {
                    let row = (y * factor + sy) * self.width + x * factor;
                    for c in &self.color[row..row + factor] {
                        for k in 0..4 {
                            sum[k] += c[k];
                        }
                    }
                }
                // Back from premultiplied: the colour of what covers the pixel.
                let unmultiply = if sum[3] > 0.0 { 1.0 / sum[3] } else { 0.0 };
                rgba.extend([
                    byte(sum[0] * unmultiply),
                    byte(sum[1] * unmultiply),
                    byte(sum[2] * unmultiply),
                    byte(sum[3] * norm),
                ]);
            }
        }
        Picture {
            width: w,
            height: h,
            rgba,
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

/// An 8-bit RGBA picture (straight, not premultiplied, alpha), row-major from the top left.
#[derive(Clone, Debug, PartialEq)]
pub struct Picture {
    /// Width (pixels).
    pub width: usize,
    /// Height (pixels).
    pub height: usize,
    /// `4 × width × height` bytes.
    pub rgba: Vec<u8>,
}

impl Picture {
    /// An opaque picture of one colour.
    pub fn filled(width: usize, height: usize, color: [u8; 3]) -> Self {
        Picture {
            width,
            height,
            rgba: [color[0], color[1], color[2], 255].repeat(width * height),
        }
    }

    /// A fully transparent picture.
    pub fn transparent(width: usize, height: usize) -> Self {
        Picture {
            width,
            height,
            rgba: vec![0; 4 * width * height],
        }
    }

    /// The colour at pixel (x, y).
    pub fn pixel(&self, x: usize, y: usize) -> [u8; 3] {
        let i = 4 * (y * self.width + x);
        [self.rgba[i], self.rgba[i + 1], self.rgba[i + 2]]
    }

    /// The opacity at pixel (x, y), 0 … 255.
    pub fn alpha(&self, x: usize, y: usize) -> u8 {
        self.rgba[4 * (y * self.width + x) + 3]
    }

    /// Whether every pixel is opaque.
    pub fn is_opaque(&self) -> bool {
        self.rgba.chunks_exact(4).all(|p| p[3] == 255)
    }

    /// The colours without opacity, `3 × width × height` bytes (for GIF and video).
    pub fn rgb(&self) -> Vec<u8> {
        self.rgba
            .chunks_exact(4)
            .flat_map(|p| [p[0], p[1], p[2]])
            .collect()
    }

    /// Sets an opaque colour at (x, y), if inside.
    pub fn set(&mut self, x: i64, y: i64, color: [u8; 3]) {
        self.paint(x, y, color, 1.0);
    }

    /// Paints `color` over (x, y) covering the fraction `coverage` of the pixel (anti-aliased
    /// text and marks), if inside.
    pub fn paint(&mut self, x: i64, y: i64, color: [u8; 3], coverage: f32) {
        if !(0..self.width as i64).contains(&x) || !(0..self.height as i64).contains(&y) {
            return;
        }
        let cover = coverage.clamp(0.0, 1.0);
        let i = 4 * (y as usize * self.width + x as usize);
        let under = self.rgba[i + 3] as f32 / 255.0 * (1.0 - cover);
        let alpha = cover + under;
        if alpha <= 0.0 {
            return;
        }
        for (channel, &c) in self.rgba[i..i + 3].iter_mut().zip(&color) {
            let mixed = (c as f32 * cover + *channel as f32 * under) / alpha;
            *channel = mixed.round().clamp(0.0, 255.0) as u8;
        }
        self.rgba[i + 3] = (alpha * 255.0).round() as u8;
    }

    /// Paints the axis-aligned rectangle [x0, x1) × [y0, y1) (pixels, clipped) in `color`.
    pub fn fill_rect(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, color: [u8; 3]) {
        // Partly covered border pixels get their covered fraction: thin marks stay sharp.
        let (xa, xb) = (x0.floor() as i64, x1.ceil() as i64);
        let (ya, yb) = (y0.floor() as i64, y1.ceil() as i64);
        for y in ya..yb {
            let cy = ((y + 1) as f64).min(y1) - (y as f64).max(y0);
            for x in xa..xb {
                let cx = ((x + 1) as f64).min(x1) - (x as f64).max(x0);
                self.paint(x, y, color, (cx * cy) as f32);
            }
        }
    }

    /// Copies `other` in with its top left corner at (x, y) (clipped).
    pub fn blit(&mut self, other: &Picture, x: usize, y: usize) {
        for row in 0..other.height.min(self.height.saturating_sub(y)) {
            let cols = other.width.min(self.width.saturating_sub(x));
            let src = 4 * row * other.width;
            let dst = 4 * ((y + row) * self.width + x);
            self.rgba[dst..dst + 4 * cols].copy_from_slice(&other.rgba[src..src + 4 * cols]);
        }
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
            let mut c = Canvas::new(10, 10, Some(([0.0; 3], [0.0; 3])));
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
        let mut c = Canvas::new(4, 4, Some(([0.0; 3], [0.0; 3])));
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

    #[test]
    fn transparent_backdrop_keeps_coverage_and_colour_apart() {
        let mut c = Canvas::new(4, 4, None);
        let half = [[0.0, 0.0, 1.0], [4.0, 0.0, 1.0], [0.0, 4.0, 1.0]];
        c.blend(half, [1.0, 0.0, 0.0], 0.25);
        let p = c.downsample(1);
        // Covered pixels: red at a quarter opacity; the others transparent.
        assert_eq!((p.pixel(0, 0), p.alpha(0, 0)), ([255, 0, 0], 64));
        assert_eq!(p.alpha(3, 3), 0);
        // Three of four supersamples covered by an opaque green: green, 3/4 opaque.
        let mut c = Canvas::new(2, 2, None);
        c.fill(
            [[0.0, 0.0, 1.0], [2.0, 0.0, 1.0], [0.0, 2.0, 1.0]],
            [0.0, 1.0, 0.0],
        );
        c.fill(
            [[2.0, 0.0, 1.0], [2.0, 1.0, 1.0], [1.0, 1.0, 1.0]],
            [0.0, 1.0, 0.0],
        );
        let p = c.downsample(2);
        assert_eq!(p.pixel(0, 0), [0, 255, 0]);
        assert_eq!(p.alpha(0, 0), 191);
    }

    #[test]
    fn vertex_colours_interpolate_linearly_in_3d() {
        // A triangle receding in depth: the weights are those of the 3-D triangle, not of
        // its picture (1/z interpolates linearly in the picture, attributes/z too).
        let mut c = Canvas::new(64, 64, Some(([0.0; 3], [0.0; 3])));
        let p = [[0.0, 0.0, 1.0], [64.0, 0.0, 3.0], [0.0, 64.0, 1.0]];
        c.fill_with(p, |w| [w[1], 0.0, 0.0]);
        let red = c.downsample(1).pixel(32, 0)[0] as f64 / 255.0;
        let (s, t) = (32.5 / 64.0, 0.5 / 64.0); // the pixel centre's picture weights of 1, 2
        let (w0, w1, w2) = (1.0 - s - t, s / 3.0, t);
        let expect = w1 / (w0 + w1 + w2);
        assert!(
            (red - expect).abs() <= 0.5 / 255.0 + 1e-6,
            "{red} vs {expect}"
        );
    }

    #[test]
    fn painting_blends_straight_alpha() {
        let mut p = Picture::transparent(1, 1);
        p.paint(0, 0, [200, 0, 0], 0.5);
        assert_eq!((p.pixel(0, 0), p.alpha(0, 0)), ([200, 0, 0], 128));
        p.paint(0, 0, [0, 0, 200], 0.5);
        // Over: 0.5 of blue on 0.25 (= 0.5 × 0.5) of red left beneath, alpha 0.75.
        // (The first alpha is stored as 128/255, so 0.751 → 192.)
        assert_eq!(p.pixel(0, 0), [67, 0, 133]);
        assert_eq!(p.alpha(0, 0), 192);
        let mut q = Picture::filled(1, 1, [0, 0, 0]);
        q.paint(0, 0, [255, 255, 255], 0.25);
        assert_eq!((q.pixel(0, 0), q.alpha(0, 0)), ([64, 64, 64], 255));
    }
}
