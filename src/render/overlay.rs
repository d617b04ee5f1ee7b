//! What is drawn over the scene: the frame label and the colour bar with ticks and units,
//! sized with the picture.

use super::raster::{Picture, Rgb};
use super::text::{draw_text, line_height, text_width, Align};
use super::ColorField;

/// Sizes of text and marks for a picture: those of a picture 600 pixels high, times
/// `height / 600` (never below 1, where text would stop being legible). The height alone
/// sets the scale, so that a picture widened by a colour-bar strip keeps its sizes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Overlay {
    /// The factor on the 800 × 600 sizes.
    pub scale: f64,
    /// Colour of text and marks.
    pub ink: [u8; 3],
}

/// Text size at scale 1 (pixels, the font's em height).
const TEXT: f64 = 14.0;
/// Width of the colour-bar strip at scale 1 (pixels).
const STRIP: f64 = 150.0;
/// Width of the ice's feature lines at scale 1 (pixels).
const LINE: f64 = 1.2;

impl Overlay {
    /// The overlay of a picture `height` pixels high whose background is `background` (dark
    /// backgrounds get light ink; a transparent one, `None`, dark ink).
    pub fn new(height: usize, background: Option<Rgb>) -> Self {
        let scale = (height as f64 / 600.0).max(1.0);
        let dark = background.is_some_and(|c| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2] < 0.5);
        Overlay {
            scale,
            ink: if dark { [235, 235, 240] } else { [20, 20, 24] },
        }
    }

    /// Text size (pixels).
    pub fn text_size(&self) -> f64 {
        TEXT * self.scale
    }

    /// Width of the colour-bar strip at the picture's right (pixels).
    pub fn strip(&self) -> usize {
        (STRIP * self.scale).round() as usize
    }

    /// Width of the ice's feature lines (pixels); obstacles' are 1.5 times that.
    pub fn line_width(&self) -> f64 {
        LINE * self.scale
    }

    /// A margin: 8 pixels at scale 1.
    pub fn margin(&self) -> f64 {
        8.0 * self.scale
    }

    /// Draws `text` in the overlay's size and ink, its top at `y`.
    pub fn text(&self, picture: &mut Picture, text: &str, x: f64, y: f64, align: Align) {
        draw_text(picture, text, x, y, self.text_size(), align, self.ink);
    }

    /// A vertical colour bar in the strip that starts at `x`, from `top`, `height` pixels
    /// high (`[x, top, height]`): the colour map of `range` (in the field's SI unit), ticks at
    /// round values in a display unit chosen for the range, and the field's name and unit
    /// above it.
    pub fn color_bar(
        &self,
        picture: &mut Picture,
        field: ColorField,
        range: (f64, f64),
        [x, top, height]: [f64; 3],
        colormap: impl Fn(f64) -> Rgb,
    ) {
        let s = self.scale;
        let bar = 16.0 * s;
        let x = x + 12.0 * s;
        let (min, max) = range;
        let rows = height.round().max(2.0) as i64;
        for row in 0..rows {
            let t = 1.0 - row as f64 / (rows - 1) as f64;
            let c = colormap(min + t * (max - min)).map(|k| (k * 255.0).round() as u8);
            let y = top + row as f64;
            picture.fill_rect(x, y, x + bar, y + 1.0, c);
        }
        let stroke = s.max(1.0);
        for (x0, y0, x1, y1) in [
            (x, top, x + bar, top + stroke),
            (x, top + height - stroke, x + bar, top + height),
            (x, top, x + stroke, top + height),
            (x + bar - stroke, top, x + bar, top + height),
        ] {
            picture.fill_rect(x0, y0, x1, y1, self.ink);
        }
        let unit = DisplayUnit::for_range(field, range);
        let size = self.text_size();
        for tick in ticks(min * unit.factor, max * unit.factor) {
            let t = (tick / unit.factor - min) / (max - min);
            let y = top + (1.0 - t) * (height - stroke) + stroke / 2.0;
            picture.fill_rect(
                x + bar,
                y - stroke / 2.0,
                x + bar + 6.0 * s,
                y + stroke / 2.0,
                self.ink,
            );
            // Digits' middle is about 0.36 em above the baseline, 0.44 em below the top.
            let label = tick_label(tick, ticks_step(min * unit.factor, max * unit.factor));
            self.text(
                picture,
                &label,
                x + bar + 9.0 * s,
                y - 0.44 * size,
                Align::Left,
            );
        }
        // Name and unit above the bar, right-aligned on the picture's edge so that a long
        // name reaches left over the scene's margin rather than off the picture.
        let right = picture.width as f64 - self.margin();
        let lines = [field.title(), unit.label.as_str()];
        let line = line_height(size);
        let fits = lines.iter().all(|t| x + text_width(t, size) <= right);
        let (at, align) = if fits {
            (x, Align::Left)
        } else {
            (right, Align::Right)
        };
        for (k, text) in lines.iter().enumerate() {
            let y = top - (lines.len() - k) as f64 * line - 6.0 * s;
            self.text(picture, text, at, y, align);
        }
    }
}

/// The unit the colour bar's ticks are written in: values times `factor`.
struct DisplayUnit {
    factor: f64,
    label: String,
}

impl DisplayUnit {
    /// Stresses in Pa, kPa, MPa or GPa, whichever keeps the range's largest magnitude in
    /// [1, 1000); a dimensionless field as is when it reaches 0.1, else in powers of ten.
    fn for_range(field: ColorField, (min, max): (f64, f64)) -> Self {
        let largest = min.abs().max(max.abs());
        match field {
            ColorField::VonMises | ColorField::Principal => {
                let (factor, prefix) = [(1e-9, "G"), (1e-6, "M"), (1e-3, "k")]
                    .into_iter()
                    .find(|(f, _)| largest * f >= 1.0)
                    .unwrap_or((1.0, ""));
                let note = if field == ColorField::Principal {
                    ", + tension"
                } else {
                    ""
                };
                DisplayUnit {
                    factor,
                    label: format!("({prefix}Pa{note})"),
                }
            }
            ColorField::Plastic if largest > 0.0 && largest < 0.1 => {
                let exponent = largest.log10().floor() as i32;
                DisplayUnit {
                    factor: 10f64.powi(-exponent),
                    label: format!("(×10{})", superscript(exponent)),
                }
            }
            ColorField::Plastic => DisplayUnit {
                factor: 1.0,
                label: "(dimensionless)".into(),
            },
            ColorField::Freeze => DisplayUnit {
                factor: 1.0,
                label: "(0 water, 1 ice)".into(),
            },
            ColorField::Temperature => DisplayUnit {
                factor: 1.0,
                label: "(°C)".into(),
            },
        }
    }
}

/// `n` in superscript digits (and minus sign).
fn superscript(n: i32) -> String {
    const DIGITS: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
    let digits: String = n
        .unsigned_abs()
        .to_string()
        .chars()
        .map(|c| DIGITS[c as usize - '0' as usize])
        .collect();
    format!("{}{digits}", if n < 0 { "⁻" } else { "" })
}

/// The spacing of the ticks on [min, max]: 1, 2 or 5 times a power of ten, the largest that
/// gives at least 4 ticks.
fn ticks_step(min: f64, max: f64) -> f64 {
    let span = (max - min).abs().max(f64::MIN_POSITIVE);
    let power = 10f64.powf((span / 4.0).log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * power)
        .find(|step| span / step >= 4.0 - 1e-9)
        .unwrap_or(power)
}

/// The round values in [min, max] at [`ticks_step`] spacing.
fn ticks(min: f64, max: f64) -> Vec<f64> {
    let step = ticks_step(min, max);
    let tolerance = 1e-9 * step;
    let first = (min / step - 1e-9).ceil() as i64;
    (first..)
        .map(|k| k as f64 * step)
        .take_while(|v| *v <= max + tolerance)
        .collect()
}

/// A tick's label with the decimals its step needs (no "-0").
fn tick_label(value: f64, step: f64) -> String {
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    let text = format!("{value:.decimals$}");
    if text
        .trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        text.trim_start_matches('-').to_string()
    } else {
        text
    }
}

/// A simulation time `t` (s) as a label reads it: seconds under a minute (`decimals` of
/// them), minutes and seconds under an hour ("12 min 05.3 s"), hours and minutes beyond
/// ("2 h 05 min"): an hour-long freezing run's frame reads "t = 2 h 05 min", not
/// "t = 7500.000 s". Rounding never shows 60 of a unit.
pub fn clock_time(t: f64, decimals: usize) -> String {
    let sign = if t < 0.0 { "-" } else { "" };
    let t = t.abs();
    let tenths = |x: f64| (x * 10.0).round() / 10.0;
    if format!("{t:.decimals$}").parse::<f64>().unwrap_or(t) < 60.0 {
        format!("{sign}{t:.decimals$} s")
    } else if tenths(t) < 3600.0 {
        let t = tenths(t);
        let minutes = (t / 60.0).floor();
        format!("{sign}{minutes} min {:04.1} s", t - 60.0 * minutes)
    } else {
        let minutes = (t / 60.0).round();
        let hours = (minutes / 60.0).floor();
        format!("{sign}{hours} h {:02} min", minutes - 60.0 * hours)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_read_in_the_unit_that_fits() {
        assert_eq!(clock_time(0.0, 3), "0.000 s");
        assert_eq!(clock_time(2.5, 1), "2.5 s");
        assert_eq!(clock_time(59.96, 1), "1 min 00.0 s");
        assert_eq!(clock_time(59.96, 2), "59.96 s");
        assert_eq!(clock_time(125.34, 3), "2 min 05.3 s");
        assert_eq!(clock_time(3599.97, 3), "1 h 00 min");
        assert_eq!(clock_time(7500.0, 3), "2 h 05 min");
        assert_eq!(clock_time(7199.0, 1), "2 h 00 min");
        assert_eq!(clock_time(-1.25, 2), "-1.25 s");
    }

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        let close = |a: &[f64], b: &[f64]| {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12)
        };
        assert!(close(&ticks(0.0, 1.0), &[0.0, 0.2, 0.4, 0.6, 0.8, 1.0]));
        assert!(close(
            &ticks(-3.7, 12.2),
            &[-2.0, 0.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0]
        ));
        assert!(close(
            &ticks(0.0, 3.2),
            &[0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0]
        ));
        // Always 4 … 9 ticks, whatever the span.
        for span in [1e-7, 0.013, 1.0, 7.3, 39.9, 40.0, 8e5] {
            let n = ticks(1.0, 1.0 + span).len();
            assert!((4..=9).contains(&n), "span {span}: {n} ticks");
        }
    }

    #[test]
    fn units_suit_the_range() {
        let mpa = DisplayUnit::for_range(ColorField::VonMises, (0.0, 3.2e6));
        assert_eq!((mpa.factor, mpa.label.as_str()), (1e-6, "(MPa)"));
        let pa = DisplayUnit::for_range(ColorField::Principal, (-20.0, 500.0));
        assert_eq!((pa.factor, pa.label.as_str()), (1.0, "(Pa, + tension)"));
        let strain = DisplayUnit::for_range(ColorField::Plastic, (0.0, 4.2e-3));
        assert_eq!((strain.factor, strain.label.as_str()), (1e3, "(×10⁻³)"));
        assert_eq!(tick_label(-0.0001, 0.5), "0.0");
        assert_eq!(tick_label(2.5, 0.5), "2.5");
        assert_eq!(tick_label(40.0, 20.0), "40");
    }
}
