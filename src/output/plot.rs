//! Report plots drawn with `plotters` (docs/mcap.md §7), each as SVG text and as PNG bytes:
//! [`TimePlot`] (an output over time: shaded bands, lines, dashed lines) and [`ScatterPlot`]
//! (labelled points on linear or logarithmic axes, e.g. error against wall time).
//!
//! Text is laid out and, in PNGs, drawn with a subset of DejaVu Sans embedded in the binary
//! (`assets/fonts/`, Bitstream Vera licence), so the plots look the same on every machine; the
//! SVGs name the family `sans-serif`. Nothing here writes files: callers pass the bytes to
//! [`crate::output::write_atomically`].

mod legend_corner;

use legend_corner::{Corner, Ink, PixelBox};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::sync::OnceLock;

/// The y-axis label of an output: `name [unit]`.
pub fn axis_label(name: &str, unit: &str) -> String {
    if unit.is_empty() {
        name.to_string()
    } else {
        format!("{name} [{unit}]")
    }
}

/// The embedded font (DejaVu Sans, subset to Latin, Greek and the symbols of our labels and units).
const FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans-ribbon-subset.ttf");
/// The family name plots ask for.
const FONT_FAMILY: &str = "sans-serif";
/// Plot size, pixels (SVG user units).
pub const PLOT_SIZE: (u32, u32) = (900, 460);
/// Relative margin added above and below the data of a linear y axis, so that lines at the
/// extremes stay off the frame.
const Y_MARGIN: f64 = 0.06;
/// Half-height given to a y range whose data are constant, relative to the value (or absolute
/// when the value is 0): a flat line is then drawn mid-plot instead of an empty range.
const FLAT_RANGE_RELATIVE: f64 = 1e-3;
/// Smallest half-height of a flat y range at 0.
const FLAT_RANGE_ABSOLUTE: f64 = 1e-9;
/// Below this ratio of tick step to the largest tick magnitude, ticks would need more than five
/// significant digits in fixed notation: they switch to scientific notation.
const SCIENTIFIC_STEP_RATIO: f64 = 1e-5;

/// A colour as `#rrggbb`.
pub type HexColour = &'static str;

/// Why a plot could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The embedded font did not load.
    #[error("the embedded plot font did not load")]
    Font,
    /// A plot with no finite point.
    #[error("plot '{0}' has no finite data to draw")]
    NoData(String),
    /// plotters failed while drawing.
    #[error("drawing plot '{title}' failed: {message}")]
    Draw {
        /// The plot's title.
        title: String,
        /// plotters' message.
        message: String,
    },
    /// The PNG encoder failed.
    #[error("encoding plot '{title}' as PNG failed: {message}")]
    Png {
        /// The plot's title.
        title: String,
        /// The encoder's message.
        message: String,
    },
}

/// How a [`Layer::Line`] is stroked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stroke {
    /// A continuous line.
    Solid,
    /// Dashes of [`DASH_LENGTH`] pixels, [`DASH_GAP`] apart.
    Dashed,
    /// Dots of [`DOT_LENGTH`] pixels, [`DOT_GAP`] apart.
    Dotted,
}

/// Length of a dash of a [`Stroke::Dashed`] line, pixels.
pub const DASH_LENGTH: u32 = 8;
/// Gap between dashes, pixels.
pub const DASH_GAP: u32 = 5;
/// Length of a dot of a [`Stroke::Dotted`] line, pixels (its width at 3 px: a square dot).
pub const DOT_LENGTH: u32 = 3;
/// Gap between dots, pixels.
pub const DOT_GAP: u32 = 3;

/// One thing drawn on a [`TimePlot`], in drawing order.
#[derive(Clone, Debug)]
pub enum Layer<'a> {
    /// The region between two series, filled (alpha 0.25) and edged by thin lines.
    Band {
        /// Legend label.
        label: String,
        /// Lower edge, one value per time.
        lower: &'a [f64],
        /// Upper edge, one value per time.
        upper: &'a [f64],
        /// Fill and edge colour.
        colour: HexColour,
    },
    /// A series as a line.
    Line {
        /// Legend label.
        label: String,
        /// One value per time.
        values: &'a [f64],
        /// Colour.
        colour: HexColour,
        /// Stroke width, pixels.
        width: u32,
        /// Solid, dashed or dotted.
        stroke: Stroke,
    },
    /// Single values as dots, `(time, value)`.
    Points {
        /// Legend label.
        label: String,
        /// The dots.
        points: &'a [(f64, f64)],
        /// Colour.
        colour: HexColour,
    },
}

/// An output over time.
#[derive(Clone, Debug)]
pub struct TimePlot<'a> {
    /// Title (above the plot).
    pub title: String,
    /// y-axis label, with its unit (`frame.tool0.z [m]`).
    pub y_label: String,
    /// Times, s; the x axis.
    pub times: &'a [f64],
    /// What is drawn, in order; legend entries in the same order.
    pub layers: Vec<Layer<'a>>,
    /// Where the y axis is set rather than fitted to every layer: its range, and every layer is
    /// clipped to it (a value beyond it is drawn on the frame, a dot beyond it is left out);
    /// `None`: the axis spans every layer's data, padded.
    pub y_limits: Option<(f64, f64)>,
    /// A line of text drawn inside the plot at its lower left, on a white box (e.g. what the
    /// clipping hides); empty for none.
    pub note: String,
}

/// One labelled series of a [`ScatterPlot`].
#[derive(Clone, Debug)]
pub struct ScatterSeries {
    /// Legend label.
    pub label: String,
    /// `(x, y)` points, in drawing order; joined by a line when more than one.
    pub points: Vec<(f64, f64)>,
    /// A label per point drawn beside its marker (may be empty).
    pub point_labels: Vec<String>,
    /// Colour.
    pub colour: HexColour,
}

/// Points against two axes.
#[derive(Clone, Debug)]
pub struct ScatterPlot {
    /// Title.
    pub title: String,
    /// x-axis label with unit.
    pub x_label: String,
    /// y-axis label with unit.
    pub y_label: String,
    /// Logarithmic x axis (non-positive values are left out).
    pub log_x: bool,
    /// Logarithmic y axis (non-positive values are left out).
    pub log_y: bool,
    /// The series.
    pub series: Vec<ScatterSeries>,
}

/// A qualitative palette for series without a meaning of their own (Okabe–Ito, then greys).
pub const PALETTE: [HexColour; 8] = [
    "#0072b2", "#d55e00", "#009e73", "#cc79a7", "#e69f00", "#56b4e9", "#000000", "#999999",
];

/// Registers the embedded font once.
fn ensure_font() -> Result<(), PlotError> {
    static LOADED: OnceLock<bool> = OnceLock::new();
    let ok = *LOADED.get_or_init(|| {
        plotters::style::register_font(FONT_FAMILY, FontStyle::Normal, FONT_BYTES).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(PlotError::Font)
    }
}

fn rgb(colour: HexColour) -> RGBColor {
    let value = u32::from_str_radix(colour.trim_start_matches('#'), 16).unwrap_or(0);
    RGBColor((value >> 16) as u8, (value >> 8) as u8, value as u8)
}

fn draw_error(title: &str, error: impl std::fmt::Display) -> PlotError {
    PlotError::Draw {
        title: title.to_string(),
        message: error.to_string(),
    }
}

/// Tick label of `value` on an axis whose ticks are about `step` apart: as many decimals as the
/// step needs, scientific notation when fixed notation would need more than five significant
/// digits or the values are large.
pub fn tick_label(value: f64, step: f64, largest: f64) -> String {
    if value == 0.0 {
        return "0".to_string();
    }
    let step = step.abs().max(f64::MIN_POSITIVE);
    if largest >= 1e5 || (largest > 0.0 && step / largest < SCIENTIFIC_STEP_RATIO) || largest < 1e-3
    {
        let digits = ((largest / step).log10().ceil().max(1.0) as usize).min(8);
        return format!(
            "{value:.digits$e}",
            digits = digits.saturating_sub(1).max(1)
        );
    }
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    format!("{value:.decimals$}")
}

/// Smallest and largest finite value; `None` when there is none.
pub(super) fn finite_span(values: impl IntoIterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    (lo <= hi).then_some((lo, hi))
}

/// y range of the data, padded; a flat range is widened around its value.
fn linear_range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = finite_span(values)?;
    let span = hi - lo;
    let half = if span > FLAT_RANGE_RELATIVE * lo.abs().max(hi.abs()) {
        0.5 * span * (1.0 + 2.0 * Y_MARGIN)
    } else {
        (FLAT_RANGE_RELATIVE * lo.abs().max(hi.abs())).max(FLAT_RANGE_ABSOLUTE) + 0.5 * span
    };
    let mid = 0.5 * (lo + hi);
    Some((mid - half, mid + half))
}

/// Decade-aligned range of the positive data, for a log axis.
fn log_range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = finite_span(values.filter(|v| *v > 0.0))?;
    let lo = 10f64.powf(lo.log10().floor());
    let hi = 10f64.powf(hi.log10().ceil()).max(lo * 10.0);
    Some((lo, hi))
}

/// About how far apart plotters puts `count` ticks over `range` (its steps are 1, 2, 5 × 10^k).
fn tick_step(range: (f64, f64), count: usize) -> f64 {
    let raw = (range.1 - range.0).abs() / count.max(1) as f64;
    if raw <= 0.0 || !raw.is_finite() {
        return 1.0;
    }
    let decade = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * decade)
}

/// Encodes an RGB buffer as PNG.
fn encode_png(title: &str, rgb_pixels: &[u8], (w, h): (u32, u32)) -> Result<Vec<u8>, PlotError> {
    let png_error = |e: png::EncodingError| PlotError::Png {
        title: title.to_string(),
        message: e.to_string(),
    };
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, w, h);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(png_error)?;
    writer.write_image_data(rgb_pixels).map_err(png_error)?;
    writer.finish().map_err(png_error)?;
    Ok(bytes)
}

/// Renders `draw` to SVG text.
fn render_svg<F>(title: &str, draw: F) -> Result<String, PlotError>
where
    F: FnOnce(DrawingArea<SVGBackend, Shift>) -> Result<(), PlotError>,
{
    ensure_font()?;
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, PLOT_SIZE).into_drawing_area();
        draw(root)?;
    }
    if text.is_empty() {
        return Err(draw_error(title, "the SVG backend produced nothing"));
    }
    Ok(text)
}

/// Renders `draw` to PNG bytes.
fn render_png<F>(title: &str, draw: F) -> Result<Vec<u8>, PlotError>
where
    F: FnOnce(DrawingArea<BitMapBackend, Shift>) -> Result<(), PlotError>,
{
    ensure_font()?;
    let (w, h) = PLOT_SIZE;
    let mut pixels = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, PLOT_SIZE).into_drawing_area();
        draw(root)?;
    }
    encode_png(title, &pixels, PLOT_SIZE)
}

impl TimePlot<'_> {
    fn y_values(&self) -> Vec<f64> {
        let mut values = Vec::new();
        for layer in &self.layers {
            match layer {
                Layer::Band { lower, upper, .. } => {
                    values.extend_from_slice(lower);
                    values.extend_from_slice(upper);
                }
                Layer::Line { values: line, .. } => values.extend_from_slice(line),
                Layer::Points { points, .. } => values.extend(points.iter().map(|&(_, y)| y)),
            }
        }
        values
    }

    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let title = self.title.as_str();
        let fail = |e: DrawingAreaErrorKind<DB::ErrorType>| draw_error(title, e);
        let (t0, t1) = linear_range(self.times.iter().copied())
            .map(|_| {
                let first = self.times.first().copied().unwrap_or(0.0);
                let last = self.times.last().copied().unwrap_or(1.0);
                if last > first {
                    (first, last)
                } else {
                    (first, first + 1.0)
                }
            })
            .ok_or_else(|| PlotError::NoData(self.title.clone()))?;
        let (y0, y1) = match self.y_limits {
            Some((lo, hi)) if lo.is_finite() && hi.is_finite() && hi > lo => (lo, hi),
            _ => linear_range(self.y_values().into_iter())
                .ok_or_else(|| PlotError::NoData(self.title.clone()))?,
        };
        // Within the axis every value is drawn as it is; beyond it, on the frame.
        let clip = |v: f64| {
            if self.y_limits.is_some() {
                v.clamp(y0, y1)
            } else {
                v
            }
        };
        root.fill(&WHITE).map_err(fail)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, (FONT_FAMILY, 20))
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(96)
            .build_cartesian_2d(t0..t1, y0..y1)
            .map_err(fail)?;
        let y_step = tick_step((y0, y1), 6);
        let y_largest = y0.abs().max(y1.abs());
        let x_step = tick_step((t0, t1), 10);
        let x_formatter = |v: &f64| tick_label(*v, x_step, t0.abs().max(t1.abs()));
        let y_formatter = |v: &f64| tick_label(*v, y_step, y_largest);
        chart
            .configure_mesh()
            .x_desc("t [s]")
            .y_desc(self.y_label.as_str())
            .x_labels(10)
            .y_labels(6)
            .x_label_formatter(&x_formatter)
            .y_label_formatter(&y_formatter)
            .label_style((FONT_FAMILY, 14))
            .axis_desc_style((FONT_FAMILY, 15))
            .light_line_style(RGBColor(235, 235, 235))
            .bold_line_style(RGBColor(205, 205, 205))
            .draw()
            .map_err(fail)?;
        let times = self.times;
        for layer in &self.layers {
            match layer {
                Layer::Band {
                    label,
                    lower,
                    upper,
                    colour,
                } => {
                    let colour = rgb(colour);
                    let outline: Vec<(f64, f64)> = times
                        .iter()
                        .zip(lower.iter())
                        .map(|(t, v)| (*t, clip(*v)))
                        .chain(
                            times
                                .iter()
                                .zip(upper.iter())
                                .rev()
                                .map(|(t, v)| (*t, clip(*v))),
                        )
                        .filter(|(_, v)| v.is_finite())
                        .collect();
                    chart
                        .draw_series(std::iter::once(Polygon::new(
                            outline,
                            colour.mix(0.25).filled(),
                        )))
                        .map_err(fail)?
                        .label(label.as_str())
                        .legend(move |(x, y)| {
                            Rectangle::new([(x, y - 6), (x + 20, y + 6)], colour.mix(0.25).filled())
                        });
                    for edge in [lower, upper] {
                        chart
                            .draw_series(LineSeries::new(
                                times.iter().copied().zip(edge.iter().map(|v| clip(*v))),
                                colour.stroke_width(1),
                            ))
                            .map_err(fail)?;
                    }
                }
                Layer::Line {
                    label,
                    values,
                    colour,
                    width,
                    stroke,
                } => {
                    let style = rgb(colour).stroke_width(*width);
                    let points = times.iter().copied().zip(values.iter().map(|v| clip(*v)));
                    let drawn = match stroke {
                        Stroke::Solid => chart
                            .draw_series(LineSeries::new(points, style))
                            .map_err(fail)?,
                        Stroke::Dashed => chart
                            .draw_series(DashedLineSeries::new(
                                points,
                                DASH_LENGTH,
                                DASH_GAP,
                                style,
                            ))
                            .map_err(fail)?,
                        Stroke::Dotted => chart
                            .draw_series(DashedLineSeries::new(points, DOT_LENGTH, DOT_GAP, style))
                            .map_err(fail)?,
                    };
                    // An empty label (the second edge of a dashed bound) gets no legend entry.
                    if !label.is_empty() {
                        let drawn = drawn.label(label.as_str());
                        match stroke {
                            // Four dots, so the pattern shows.
                            Stroke::Dotted => {
                                let dot = move |k: i32| {
                                    let from = k * (DOT_LENGTH + DOT_GAP) as i32;
                                    PathElement::new(
                                        vec![(from, 0), (from + DOT_LENGTH as i32, 0)],
                                        style,
                                    )
                                };
                                drawn.legend(move |(x, y)| {
                                    EmptyElement::at((x, y)) + dot(0) + dot(1) + dot(2) + dot(3)
                                });
                            }
                            Stroke::Solid | Stroke::Dashed => {
                                let length = if *stroke == Stroke::Dashed {
                                    DASH_LENGTH as i32
                                } else {
                                    20
                                };
                                drawn.legend(move |(x, y)| {
                                    PathElement::new(vec![(x, y), (x + length, y)], style)
                                });
                            }
                        }
                    }
                }
                Layer::Points {
                    label,
                    points,
                    colour,
                } => {
                    let colour = rgb(colour);
                    chart
                        .draw_series(
                            points
                                .iter()
                                .filter(|(t, y)| {
                                    t.is_finite() && y.is_finite() && (y0..=y1).contains(y)
                                })
                                .map(|&p| Circle::new(p, 2, colour.filled())),
                        )
                        .map_err(fail)?
                        .label(label.as_str())
                        .legend(move |(x, y)| Circle::new((x + 10, y), 3, colour.filled()));
                }
            }
        }
        let note = if self.note.is_empty() {
            None
        } else {
            Some(note_frame(chart.plotting_area(), &self.note).map_err(fail)?)
        };
        let corner = self.legend_corner(
            |t, v| area_pixel(&chart, (t, v)),
            clip,
            (y0, y1),
            chart.plotting_area(),
            note,
        );
        chart
            .configure_series_labels()
            .label_font((FONT_FAMILY, LEGEND_FONT_SIZE))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .position(series_label_position(corner))
            .draw()
            .map_err(fail)?;
        if let Some(frame) = note {
            draw_note(chart.plotting_area(), &self.note, frame).map_err(fail)?;
        }
        root.present().map_err(fail)
    }

    /// The legend entries' labels, in drawing order (what `plotters` lists: every band and dot
    /// layer, the lines with a label).
    fn legend_labels(&self) -> Vec<&str> {
        self.layers
            .iter()
            .filter_map(|layer| match layer {
                Layer::Band { label, .. } | Layer::Points { label, .. } => Some(label.as_str()),
                Layer::Line { label, .. } => (!label.is_empty()).then_some(label.as_str()),
            })
            .collect()
    }

    /// The corner whose legend box hides the least of the layers (`legend_corner`), given the
    /// data-to-pixel map of the plotting area, the clip of values to the axis, the axis range
    /// and the note's frame to keep clear. Upper right when the legend's text cannot be measured
    /// (drawing it then reports the font error).
    fn legend_corner<DB: DrawingBackend, CT: plotters::coord::CoordTranslate>(
        &self,
        pixel: impl Fn(f64, f64) -> (f64, f64),
        clip: impl Fn(f64) -> f64,
        (y0, y1): (f64, f64),
        area: &DrawingArea<DB, CT>,
        note: Option<[(i32, i32); 2]>,
    ) -> Corner {
        let Some(size) = legend_box_size(&self.legend_labels()) else {
            return Corner::UpperRight;
        };
        let (area_w, area_h) = area.dim_in_pixel();
        let times = self.times;
        let mut ink = Ink::default();
        let curve = |values: &[f64]| -> Vec<(f64, f64)> {
            times
                .iter()
                .zip(values)
                .filter(|(t, v)| t.is_finite() && v.is_finite())
                .map(|(&t, &v)| pixel(t, clip(v)))
                .collect()
        };
        for layer in &self.layers {
            match layer {
                Layer::Band { lower, upper, .. } => {
                    let (low, high) = (curve(lower), curve(upper));
                    ink.fill(
                        times
                            .iter()
                            .zip(lower.iter().zip(upper.iter()))
                            .filter(|(t, (a, b))| t.is_finite() && a.is_finite() && b.is_finite())
                            .map(|(&t, (&a, &b))| {
                                let ((x, ya), (_, yb)) = (pixel(t, clip(a)), pixel(t, clip(b)));
                                (x, ya, yb)
                            }),
                    );
                    ink.line(low);
                    ink.line(high);
                }
                Layer::Line { values, .. } => ink.line(curve(values)),
                Layer::Points { points, .. } => {
                    for &(t, v) in points.iter() {
                        if t.is_finite() && v.is_finite() && (y0..=y1).contains(&v) {
                            ink.dot(pixel(t, v));
                        }
                    }
                }
            }
        }
        let keep_clear = note.map(|[(left, top), (right, bottom)]| PixelBox {
            left: f64::from(left),
            top: f64::from(top),
            right: f64::from(right),
            bottom: f64::from(bottom),
        });
        legend_corner::least_hiding_corner(
            &ink,
            size,
            (f64::from(area_w), f64::from(area_h)),
            keep_clear,
        )
    }

    /// The plot as SVG text.
    pub fn svg(&self) -> Result<String, PlotError> {
        render_svg(&self.title, |root| self.draw(root))
    }

    /// The plot as PNG bytes.
    pub fn png(&self) -> Result<Vec<u8>, PlotError> {
        render_png(&self.title, |root| self.draw(root))
    }
}

/// Font size of a plot's legend, pixels.
const LEGEND_FONT_SIZE: u32 = 14;
/// Width `plotters` gives a legend entry's symbol, and its margin around the entries, pixels (its
/// `legend_area_size` and `margin` defaults, which the legend is drawn with): with the text's size
/// they make the legend box's.
const LEGEND_SYMBOL_WIDTH: i32 = 30;
/// See [`LEGEND_SYMBOL_WIDTH`].
const LEGEND_MARGIN: i32 = 10;
/// Font size of a scatter plot's point labels (`k=4`, `N=300`), pixels.
const POINT_LABEL_FONT_SIZE: u32 = 12;
/// Where a point's label starts (its text's upper left), relative to the point, pixels: above
/// right, or else below right (where above would overlap a label already placed).
const POINT_LABEL_OFFSETS: [(i32, i32); 2] = [(6, -16), (6, 4)];
/// Font size of a plot's note, pixels.
const NOTE_FONT_SIZE: u32 = 14;
/// Space between a note's box and the plotting area's frame, and around its text, pixels.
const NOTE_PADDING: i32 = 6;

/// The size of the legend box `plotters` draws for `labels` (one entry each, in the legend's font,
/// with its symbol width and margin), pixels; `None` when the text cannot be measured.
fn legend_box_size(labels: &[&str]) -> Option<(f64, f64)> {
    let font = TextStyle::from((FONT_FAMILY, LEGEND_FONT_SIZE).into_font());
    let mut text = MultiLineText::<_, &str>::new((0, 0), &font);
    for &label in labels {
        text.push_line(label);
    }
    let (text_w, text_h) = text.estimate_dimension().ok()?;
    Some((
        f64::from(text_w + LEGEND_SYMBOL_WIDTH + 2 * LEGEND_MARGIN),
        f64::from(text_h + 2 * LEGEND_MARGIN),
    ))
}

/// Where `chart` draws the data point `p`: pixels from its plotting area's upper left (the frame
/// the legend's corner is chosen in, `legend_corner`).
fn area_pixel<DB: DrawingBackend, X: Ranged<ValueType = f64>, Y: Ranged<ValueType = f64>>(
    chart: &ChartContext<'_, DB, Cartesian2d<X, Y>>,
    p: (f64, f64),
) -> (f64, f64) {
    let (base_x, base_y) = chart.plotting_area().get_base_pixel();
    let (x, y) = chart.backend_coord(&p);
    (f64::from(x - base_x), f64::from(y - base_y))
}

/// The `plotters` position of a legend corner.
fn series_label_position(corner: Corner) -> SeriesLabelPosition {
    match corner {
        Corner::UpperRight => SeriesLabelPosition::UpperRight,
        Corner::UpperLeft => SeriesLabelPosition::UpperLeft,
        Corner::LowerRight => SeriesLabelPosition::LowerRight,
        Corner::LowerLeft => SeriesLabelPosition::LowerLeft,
    }
}

/// The frame of `note`'s box at the lower left of `area` (its pixels), as [`draw_note`] draws it.
fn note_frame<DB: DrawingBackend, CT: plotters::coord::CoordTranslate>(
    area: &DrawingArea<DB, CT>,
    note: &str,
) -> Result<[(i32, i32); 2], DrawingAreaErrorKind<DB::ErrorType>> {
    let font = TextStyle::from((FONT_FAMILY, NOTE_FONT_SIZE).into_font());
    let (text_w, text_h) = area.estimate_text_size(note, &font)?;
    let (_, height) = area.dim_in_pixel();
    let (w, h) = (
        text_w as i32 + 2 * NOTE_PADDING,
        text_h as i32 + 2 * NOTE_PADDING,
    );
    let top = height as i32 - NOTE_PADDING - h;
    let origin = (NOTE_PADDING, top);
    Ok([origin, (origin.0 + w, origin.1 + h)])
}

/// Draws `note` at the lower left of `area` (the plotting area), on a white box edged grey in
/// `frame` ([`note_frame`]).
fn draw_note<DB: DrawingBackend, CT: plotters::coord::CoordTranslate>(
    area: &DrawingArea<DB, CT>,
    note: &str,
    frame: [(i32, i32); 2],
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let font = TextStyle::from((FONT_FAMILY, NOTE_FONT_SIZE).into_font());
    let origin = frame[0];
    let plain = area.strip_coord_spec();
    plain.draw(&Rectangle::new(frame, WHITE.mix(0.9).filled()))?;
    plain.draw(&Rectangle::new(
        frame,
        RGBColor(160, 160, 160).stroke_width(1),
    ))?;
    plain.draw(&Text::new(
        note.to_string(),
        (origin.0 + NOTE_PADDING, origin.1 + NOTE_PADDING),
        font,
    ))
}

impl ScatterPlot {
    fn draw<DB: DrawingBackend>(&self, root: DrawingArea<DB, Shift>) -> Result<(), PlotError> {
        let title = self.title.as_str();
        let fail = |e: DrawingAreaErrorKind<DB::ErrorType>| draw_error(title, e);
        let usable = |(x, y): &(f64, f64)| {
            x.is_finite() && y.is_finite() && (!self.log_x || *x > 0.0) && (!self.log_y || *y > 0.0)
        };
        let xs = self
            .series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|p| usable(p));
        let ys = xs.clone().map(|p| p.1);
        let xs = xs.map(|p| p.0);
        let no_data = || PlotError::NoData(self.title.clone());
        let x_range = if self.log_x {
            log_range(xs)
        } else {
            linear_range(xs)
        }
        .ok_or_else(no_data)?;
        let y_range = if self.log_y {
            log_range(ys)
        } else {
            linear_range(ys)
        }
        .ok_or_else(no_data)?;
        root.fill(&WHITE).map_err(fail)?;
        let mut builder = ChartBuilder::on(&root);
        builder
            .caption(title, (FONT_FAMILY, 20))
            .margin(12)
            .x_label_area_size(44)
            .y_label_area_size(96);
        // Four axis combinations are four coordinate types in plotters; one generic body draws all.
        macro_rules! body {
            ($chart:expr) => {{
                let mut chart = $chart;
                let x_step = tick_step(x_range, 8);
                let y_step = tick_step(y_range, 6);
                let x_largest = x_range.0.abs().max(x_range.1.abs());
                let y_largest = y_range.0.abs().max(y_range.1.abs());
                let x_formatter = |v: &f64| {
                    if self.log_x {
                        log_tick_label(*v)
                    } else {
                        tick_label(*v, x_step, x_largest)
                    }
                };
                let y_formatter = |v: &f64| {
                    if self.log_y {
                        log_tick_label(*v)
                    } else {
                        tick_label(*v, y_step, y_largest)
                    }
                };
                chart
                    .configure_mesh()
                    .x_desc(self.x_label.as_str())
                    .y_desc(self.y_label.as_str())
                    .x_label_formatter(&x_formatter)
                    .y_label_formatter(&y_formatter)
                    .label_style((FONT_FAMILY, 14))
                    .axis_desc_style((FONT_FAMILY, 15))
                    .light_line_style(RGBColor(235, 235, 235))
                    .bold_line_style(RGBColor(205, 205, 205))
                    .draw()
                    .map_err(fail)?;
                let label_font = TextStyle::from((FONT_FAMILY, POINT_LABEL_FONT_SIZE).into_font());
                // What the legend could hide, in the plotting area's pixels: each series' line
                // and dots, and its labels as lines along their text's middle.
                let mut ink = Ink::default();
                // Each point's label, in drawing order: above right of the point, or below right
                // where that would overlap a label already placed, or left out where both would
                // (the series' line still orders its points): (series, point, offset, its box).
                let mut placed: Vec<(usize, usize, (i32, i32), PixelBox)> = Vec::new();
                for (k, series) in self.series.iter().enumerate() {
                    let pixels: Vec<(f64, f64)> = series
                        .points
                        .iter()
                        .filter(|p| usable(p))
                        .map(|&p| area_pixel(&chart, p))
                        .collect();
                    ink.line(pixels.iter().copied());
                    for &p in &pixels {
                        ink.dot(p);
                    }
                    for (i, (p, label)) in
                        series.points.iter().zip(&series.point_labels).enumerate()
                    {
                        if !usable(p) || label.is_empty() {
                            continue;
                        }
                        let (x, y) = area_pixel(&chart, *p);
                        let (w, h) = chart
                            .plotting_area()
                            .estimate_text_size(label, &label_font)
                            .map_err(fail)?;
                        let spot = POINT_LABEL_OFFSETS.iter().find_map(|&offset| {
                            let left = x + f64::from(offset.0);
                            let top = y + f64::from(offset.1);
                            let text = PixelBox {
                                left,
                                top,
                                right: left + f64::from(w),
                                bottom: top + f64::from(h),
                            };
                            let free = placed.iter().all(|(.., other)| !other.overlaps(&text));
                            free.then_some((offset, text))
                        });
                        if let Some((offset, text)) = spot {
                            let middle = 0.5 * (text.top + text.bottom);
                            ink.line([(text.left, middle), (text.right, middle)]);
                            placed.push((k, i, offset, text));
                        }
                    }
                }
                for (k, series) in self.series.iter().enumerate() {
                    let colour = rgb(series.colour);
                    let points: Vec<(f64, f64)> = series
                        .points
                        .iter()
                        .copied()
                        .filter(|p| usable(p))
                        .collect();
                    if points.len() > 1 {
                        chart
                            .draw_series(LineSeries::new(
                                points.iter().copied(),
                                colour.stroke_width(1),
                            ))
                            .map_err(fail)?;
                    }
                    chart
                        .draw_series(points.iter().map(|p| Circle::new(*p, 4, colour.filled())))
                        .map_err(fail)?
                        .label(series.label.as_str())
                        .legend(move |(x, y)| Circle::new((x + 8, y), 4, colour.filled()));
                    let labelled = placed
                        .iter()
                        .filter(|(series_index, ..)| *series_index == k);
                    chart
                        .draw_series(labelled.map(|&(_, i, offset, _)| {
                            EmptyElement::at(series.points[i])
                                + Text::new(
                                    series.point_labels[i].clone(),
                                    offset,
                                    (FONT_FAMILY, POINT_LABEL_FONT_SIZE).into_font(),
                                )
                        }))
                        .map_err(fail)?;
                }
                // The legend's corner: the one hiding the least of the ink (as the time plots
                // choose theirs).
                let corner = {
                    let labels: Vec<&str> = self.series.iter().map(|s| s.label.as_str()).collect();
                    let (area_w, area_h) = chart.plotting_area().dim_in_pixel();
                    legend_box_size(&labels).map_or(Corner::UpperRight, |size| {
                        legend_corner::least_hiding_corner(
                            &ink,
                            size,
                            (f64::from(area_w), f64::from(area_h)),
                            None,
                        )
                    })
                };
                chart
                    .configure_series_labels()
                    .label_font((FONT_FAMILY, LEGEND_FONT_SIZE))
                    .background_style(WHITE.mix(0.85))
                    .border_style(RGBColor(160, 160, 160))
                    .position(series_label_position(corner))
                    .draw()
                    .map_err(fail)?;
            }};
        }
        let (x0, x1) = x_range;
        let (y0, y1) = y_range;
        match (self.log_x, self.log_y) {
            (true, true) => body!(builder
                .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
                .map_err(fail)?),
            (true, false) => {
                body!(builder
                    .build_cartesian_2d((x0..x1).log_scale(), y0..y1)
                    .map_err(fail)?)
            }
            (false, true) => {
                body!(builder
                    .build_cartesian_2d(x0..x1, (y0..y1).log_scale())
                    .map_err(fail)?)
            }
            (false, false) => body!(builder.build_cartesian_2d(x0..x1, y0..y1).map_err(fail)?),
        }
        root.present().map_err(fail)
    }

    /// The plot as SVG text.
    pub fn svg(&self) -> Result<String, PlotError> {
        render_svg(&self.title, |root| self.draw(root))
    }

    /// The plot as PNG bytes.
    pub fn png(&self) -> Result<Vec<u8>, PlotError> {
        render_png(&self.title, |root| self.draw(root))
    }
}

/// Tick label on a log axis: `1e-3`, `0.01`, `0.1`, `1`, `10`, `100`, `1e3`; other ticks (plotters
/// adds 2×, 5× between decades) the same way with their mantissa.
fn log_tick_label(value: f64) -> String {
    if !(value.is_finite() && value > 0.0) {
        return String::new();
    }
    let exponent = value.log10().floor();
    let mantissa = value / 10f64.powf(exponent);
    let mantissa = (mantissa * 10.0).round() / 10.0;
    if (-2.0..=2.0).contains(&exponent) {
        let decimals = (-exponent).max(0.0) as usize;
        format!("{value:.decimals$}")
    } else if (mantissa - 1.0).abs() < 1e-9 {
        format!("1e{exponent}")
    } else {
        format!("{mantissa}e{exponent}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_embedded_font_has_every_glyph_of_our_labels() {
        use ab_glyph::Font;
        let font = ab_glyph::FontRef::try_from_slice(FONT_BYTES).expect("the font parses");
        let text = "0123456789 abcdefghijklmnopqrstuvwxyz ABCDEFGHIJKLMNOPQRSTUVWXYZ .,:;()[]{}+-=/_%<>|#*'\" −×·²≤≥±…λξΔσµ°";
        let missing: Vec<char> = text
            .chars()
            .filter(|c| !c.is_whitespace() && font.glyph_id(*c).0 == 0)
            .collect();
        assert!(
            missing.is_empty(),
            "glyphs missing from the font: {missing:?}"
        );
        ensure_font().expect("plotters registers it");
    }

    #[test]
    fn tick_labels_have_the_decimals_the_step_needs() {
        assert_eq!(tick_label(0.25, 0.05, 1.0), "0.25");
        assert_eq!(tick_label(1.0, 0.5, 2.0), "1.0");
        assert_eq!(tick_label(120.0, 20.0, 200.0), "120");
        assert_eq!(tick_label(0.0, 0.1, 1.0), "0");
        // Ticks 1e-6 apart around 0.47 need scientific notation only past five digits.
        assert_eq!(tick_label(0.4741, 1e-4, 0.48), "0.4741");
        assert!(tick_label(0.47400001, 1e-8, 0.48).contains('e'));
        assert!(tick_label(2e-6, 1e-6, 5e-6).contains('e'));
        assert_eq!(log_tick_label(0.01), "0.01");
        assert_eq!(log_tick_label(1e-5), "1e-5");
        assert_eq!(log_tick_label(100.0), "100");
    }

    #[test]
    fn flat_and_empty_ranges() {
        let (lo, hi) = linear_range([2.0, 2.0].into_iter()).unwrap();
        assert!(lo < 2.0 && hi > 2.0);
        let (lo, hi) = linear_range([0.0].into_iter()).unwrap();
        assert!(lo < 0.0 && hi > 0.0);
        assert!(linear_range([f64::NAN].into_iter()).is_none());
        assert_eq!(log_range([0.02, 3.0].into_iter()), Some((0.01, 10.0)));
    }

    /// The legend box of a time plot's SVG (the `<rect` edged `#A0A0A0`): `(x, y, width, height)`.
    fn legend_box(svg: &str) -> (f64, f64, f64, f64) {
        let end = svg.find("stroke=\"#A0A0A0\"").expect("a legend box");
        let start = svg[..end].rfind("<rect").expect("its rect");
        let attribute = |name: &str| -> f64 {
            let at = svg[start..end].find(&format!(" {name}=\"")).expect(name) + name.len() + 3;
            let rest = &svg[start + at..];
            rest[..rest.find('"').unwrap()].parse().unwrap()
        };
        (
            attribute("x"),
            attribute("y"),
            attribute("width"),
            attribute("height"),
        )
    }

    #[test]
    fn the_legend_goes_where_it_hides_the_least_of_the_band() {
        // A joint sagging to a new rest high in the plot, the band and the nominal up there from
        // a tenth of the run on: the lower right is empty, the upper right full.
        let times: Vec<f64> = (0..=150).map(|k| k as f64 * 0.01).collect();
        let settle = |t: f64, rest: f64| rest * (1.0 - (-t / 0.05).exp());
        let lower: Vec<f64> = times.iter().map(|&t| settle(t, 0.0073)).collect();
        let nominal: Vec<f64> = times.iter().map(|&t| settle(t, 0.0078)).collect();
        let upper: Vec<f64> = times.iter().map(|&t| settle(t, 0.0083)).collect();
        let plot = |lower: &[f64], nominal: &[f64], upper: &[f64]| {
            TimePlot {
                title: "q.panda_joint2".to_string(),
                y_label: "q.panda_joint2 [rad]".to_string(),
                times: &times,
                layers: vec![
                    Layer::Band {
                        label: "lower – upper (inner bound)".to_string(),
                        lower,
                        upper,
                        colour: PALETTE[0],
                    },
                    Layer::Line {
                        label: "nominal".to_string(),
                        values: nominal,
                        colour: PALETTE[2],
                        width: 2,
                        stroke: Stroke::Solid,
                    },
                ],
                y_limits: None,
                note: String::new(),
            }
            .svg()
            .unwrap()
        };
        let (x, y, width, height) = legend_box(&plot(&lower, &nominal, &upper));
        let (plot_w, plot_h) = (f64::from(PLOT_SIZE.0), f64::from(PLOT_SIZE.1));
        assert!(
            x > plot_w / 2.0 && y > plot_h / 2.0,
            "the legend at ({x}, {y}) size {width} × {height}: not in the lower right"
        );
        // Mirrored (settling low), the upper right is free again and keeps it.
        let flip = |v: &[f64]| -> Vec<f64> { v.iter().map(|x| -x).collect() };
        let (x, y, ..) = legend_box(&plot(&flip(&upper), &flip(&nominal), &flip(&lower)));
        assert!(
            x > plot_w / 2.0 && y < plot_h / 4.0,
            "the legend at ({x}, {y}): not in the upper right"
        );
    }

    /// Compare's error-vs-time plot of `series` (log-log) as SVG.
    fn error_vs_time_svg(series: Vec<ScatterSeries>) -> String {
        ScatterPlot {
            title: "error vs wall time".to_string(),
            x_label: "wall time [s]".to_string(),
            y_label: "max envelope error".to_string(),
            log_x: true,
            log_y: true,
            series,
        }
        .svg()
        .unwrap()
    }

    #[test]
    fn a_scatter_plots_legend_leaves_its_points_alone() {
        // Monte Carlo's points climbing into the upper right of a log-log plot: its legend goes
        // elsewhere; the same points in the lower left leave the upper right free.
        let series = |points: Vec<(f64, f64)>| ScatterSeries {
            label: "monte-carlo (inner)".to_string(),
            point_labels: points.iter().map(|p| format!("N={}", p.0)).collect(),
            points,
            colour: PALETTE[5],
        };
        let plot = |points: Vec<(f64, f64)>| {
            error_vs_time_svg(vec![
                series(points),
                ScatterSeries {
                    label: "legendre-scan (inner)".to_string(),
                    points: vec![(0.01, 1e-4), (0.02, 1e-5)],
                    point_labels: vec!["k=2".to_string(), "k=3".to_string()],
                    colour: PALETTE[0],
                },
            ])
        };
        let (plot_w, plot_h) = (f64::from(PLOT_SIZE.0), f64::from(PLOT_SIZE.1));
        let climbing: Vec<(f64, f64)> = (1..=8)
            .map(|k| (k as f64 * 0.125, 0.05 * k as f64))
            .collect();
        let (x, y, ..) = legend_box(&plot(climbing));
        assert!(
            !(x > plot_w / 2.0 && y < plot_h / 4.0),
            "the legend at ({x}, {y}) covers the upper right's points"
        );
        let (x, y, ..) = legend_box(&plot(vec![(0.01, 1e-3), (0.02, 1e-3)]));
        assert!(
            x > plot_w / 2.0 && y < plot_h / 4.0,
            "the legend at ({x}, {y}): not in the free upper right"
        );
    }

    /// The texts of an SVG with their anchors: `(x, y, text)`.
    fn svg_texts(svg: &str) -> Vec<(f64, f64, String)> {
        svg.split("<text ")
            .skip(1)
            .map(|element| {
                let attribute = |name: &str| -> f64 {
                    let at = element.find(&format!("{name}=\"")).expect(name) + name.len() + 2;
                    let rest = &element[at..];
                    rest[..rest.find('"').unwrap()].parse().unwrap()
                };
                let body = &element[element.find('>').unwrap() + 1..];
                let text = body[..body.find('<').unwrap()].trim().to_string();
                (attribute("x"), attribute("y"), text)
            })
            .collect()
    }

    #[test]
    fn a_scatter_plots_point_labels_do_not_overlap() {
        // Two series whose orders finished within milliseconds of each other: their labels
        // would sit on one another; each is placed above, below or left out instead.
        let series = |label: &str, y: f64, colour| ScatterSeries {
            label: label.to_string(),
            points: (2..=5).map(|k| (0.0130 + 0.0015 * k as f64, y)).collect(),
            point_labels: (2..=5).map(|k| format!("k={k}")).collect(),
            colour,
        };
        let svg = error_vs_time_svg(vec![
            series("legendre-scan (inner)", 6e-5, PALETTE[0]),
            series("chebyshev-scan (inner)", 6.2e-5, PALETTE[2]),
            ScatterSeries {
                label: "monte-carlo (inner)".to_string(),
                points: vec![(0.1, 0.1), (1.0, 0.05)],
                point_labels: vec!["N=30".to_string(), "N=100".to_string()],
                colour: PALETTE[5],
            },
        ]);
        let labels: Vec<(f64, f64, String)> = svg_texts(&svg)
            .into_iter()
            .filter(|(.., text)| text.starts_with("k=") || text.starts_with("N="))
            .collect();
        assert!(labels.len() >= 6, "{labels:?}");
        assert!(labels.iter().any(|(.., text)| text == "N=100"));
        // At 12 px a character of these labels is at most 7 px wide and a line 12 px tall.
        for (i, a) in labels.iter().enumerate() {
            for b in &labels[i + 1..] {
                let (left, right) = if a.0 <= b.0 { (a, b) } else { (b, a) };
                let width = 7.0 * left.2.chars().count() as f64;
                assert!(
                    right.0 - left.0 >= width || (a.1 - b.1).abs() >= 12.0,
                    "labels {a:?} and {b:?} overlap"
                );
            }
        }
    }

    #[test]
    fn a_band_plot_renders_to_svg_and_png() {
        let times: Vec<f64> = (0..50).map(|k| k as f64 * 0.02).collect();
        let nominal: Vec<f64> = times.iter().map(|t| (3.0 * t).sin()).collect();
        let lower: Vec<f64> = nominal.iter().map(|v| v - 0.1).collect();
        let upper: Vec<f64> = nominal.iter().map(|v| v + 0.1).collect();
        let plot = TimePlot {
            title: "q.j1".to_string(),
            y_label: "q.j1 [rad]".to_string(),
            times: &times,
            layers: vec![
                Layer::Band {
                    label: "inner bound".to_string(),
                    lower: &lower,
                    upper: &upper,
                    colour: PALETTE[0],
                },
                Layer::Line {
                    label: "nominal".to_string(),
                    values: &nominal,
                    colour: PALETTE[2],
                    width: 2,
                    stroke: Stroke::Solid,
                },
            ],
            y_limits: None,
            note: String::new(),
        };
        let svg = plot.svg().unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("q.j1 [rad]") && svg.contains("<polygon"));
        let png = plot.png().unwrap();
        assert_eq!(&png[1..4], b"PNG");
        let empty = TimePlot {
            title: "none".to_string(),
            y_label: String::new(),
            times: &[],
            layers: vec![],
            y_limits: None,
            note: String::new(),
        };
        assert!(matches!(empty.svg(), Err(PlotError::NoData(_))));
    }
}
