//! Text on pictures, drawn from an outline font (DejaVu Sans, embedded in the binary) at any
//! size and anti-aliased, so that labels scale with the picture.

use super::raster::Picture;
use ab_glyph::{point, Font, FontRef, GlyphId, PxScale, ScaleFont};
use std::sync::OnceLock;

/// Where a line of text sits relative to its anchor's x.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Align {
    /// The text starts at x.
    Left,
    /// The text is centred on x.
    Centre,
    /// The text ends at x.
    Right,
}

/// DejaVu Sans Regular: Latin, Greek and the mathematical signs the labels use (σ, ε, ‖, ⁻).
fn font() -> &'static FontRef<'static> {
    static FONT: OnceLock<FontRef<'static>> = OnceLock::new();
    FONT.get_or_init(|| {
        // The font is part of the binary; a parse failure is a build defect, not user input.
        FontRef::try_from_slice(dejavu::sans::regular()).expect("the embedded DejaVu Sans parses")
    })
}

/// The glyphs of `text` and their pen positions (pixels from the text's start) at `size`.
fn layout(text: &str, size: f32) -> (Vec<(GlyphId, f32)>, f32) {
    let scaled = font().as_scaled(PxScale::from(size));
    let mut caret = 0.0;
    let mut previous: Option<GlyphId> = None;
    let mut glyphs = Vec::with_capacity(text.len());
    for c in text.chars() {
        let id = scaled.glyph_id(c);
        if let Some(p) = previous {
            caret += scaled.kern(p, id);
        }
        glyphs.push((id, caret));
        caret += scaled.h_advance(id);
        previous = Some(id);
    }
    (glyphs, caret)
}

/// Width of `text` drawn at `size` pixels (the font's em height).
pub fn text_width(text: &str, size: f64) -> f64 {
    layout(text, size as f32).1 as f64
}

/// Height of a line of text at `size`: ascent to descent (pixels).
pub fn line_height(size: f64) -> f64 {
    let scaled = font().as_scaled(PxScale::from(size as f32));
    (scaled.ascent() - scaled.descent()) as f64
}

/// Draws one line of `text` at `size` pixels in `color`, its top (the font's ascent) at `y`
/// and aligned on `x` (pixels).
pub fn draw_text(
    picture: &mut Picture,
    text: &str,
    x: f64,
    y: f64,
    size: f64,
    align: Align,
    color: [u8; 3],
) {
    let size = size as f32;
    let (glyphs, width) = layout(text, size);
    let start = x as f32
        - match align {
            Align::Left => 0.0,
            Align::Centre => width / 2.0,
            Align::Right => width,
        };
    let baseline = y as f32 + font().as_scaled(PxScale::from(size)).ascent();
    for (id, pen) in glyphs {
        let glyph = id.with_scale_and_position(size, point(start + pen, baseline));
        if let Some(outline) = font().outline_glyph(glyph) {
            let bounds = outline.px_bounds();
            outline.draw(|gx, gy, coverage| {
                picture.paint(
                    bounds.min.x as i64 + gx as i64,
                    bounds.min.y as i64 + gy as i64,
                    color,
                    coverage,
                );
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_scales_with_its_size() {
        let ink = |size: f64| {
            let mut p = Picture::filled(600, 200, [255; 3]);
            draw_text(
                &mut p,
                "von Mises σ (MPa)",
                10.0,
                10.0,
                size,
                Align::Left,
                [0; 3],
            );
            let (mut rows, mut cols) = (Vec::new(), Vec::new());
            for y in 0..p.height {
                for x in 0..p.width {
                    if p.pixel(x, y)[0] < 128 {
                        rows.push(y);
                        cols.push(x);
                    }
                }
            }
            let span = |v: &[usize]| (v.iter().max().unwrap() - v.iter().min().unwrap()) as f64;
            (span(&cols), span(&rows))
        };
        let (w1, h1) = ink(14.0);
        let (w4, h4) = ink(56.0);
        // Four times the size: four times the ink's extent, to a pixel or two of hinting-free
        // rounding at the small size (glyph edges fall on pixel boundaries differently).
        assert!((w4 / w1 - 4.0).abs() < 0.15, "width {w1} → {w4}");
        assert!((h4 / h1 - 4.0).abs() < 0.4, "height {h1} → {h4}");
        assert!((text_width("von Mises σ (MPa)", 56.0) - w4).abs() < 0.1 * w4);
    }

    #[test]
    fn alignment_puts_the_text_left_centred_or_right_of_x() {
        for (align, expect) in [
            (Align::Left, 300.0),
            (Align::Centre, 250.0),
            (Align::Right, 200.0),
        ] {
            let mut p = Picture::filled(600, 60, [255; 3]);
            let w = text_width("0.25", 20.0);
            let x = match align {
                Align::Left => 300.0,
                Align::Centre => 250.0 + w / 2.0,
                Align::Right => 200.0 + w,
            };
            draw_text(&mut p, "0.25", x, 10.0, 20.0, align, [0; 3]);
            let first = (0..p.width)
                .find(|&c| (0..p.height).any(|r| p.pixel(c, r)[0] < 200))
                .unwrap() as f64;
            assert!(
                (first - expect).abs() < 3.0,
                "{align:?}: ink starts at {first}"
            );
        }
    }
}
