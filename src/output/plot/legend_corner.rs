//! Which corner of a plot's plotting area ([`super::TimePlot`], [`super::ScatterPlot`]) its legend
//! box goes in: the one where the box hides the least of what is drawn. A fixed upper-right
//! legend covered the band and both bounds of every output that rises and settles high (a Panda
//! joint sagging to a new rest, the upper hull line of an untrusted study late in its run), while
//! the lower right stood empty.
//!
//! Everything here is in the plotting area's pixels (x from its left edge, y down from its top),
//! so it can be tested without drawing. What is drawn is scored by how much of it a box hides:
//! the length of every line under it (bounds, band edges, dotted hull lines), a dot as
//! [`DOT_INK`] pixels of line, and a band's faint fill by its area under the box times
//! [`FILL_INK_PER_PIXEL`].
//!
//! Does not: draw the legend or measure its text (the plots' `draw` do both with the plot's font
//! and hand the box's size here).

/// A dot (check runs at the predicted extremes) counts as this many pixels of line: about its
/// diameter and a margin, so a few dots weigh like a short stretch of a bound.
const DOT_INK: f64 = 6.0;

/// A band's fill (alpha 0.25) counts this much per pixel of area under the box: covering a band's
/// interior hides little, but among corners that all hide no line the one over the least band
/// wins.
const FILL_INK_PER_PIXEL: f64 = 0.01;

/// Gap between the legend box and the plotting area's edge, pixels (as `plotters` lays out its
/// series labels).
const EDGE_GAP: f64 = 5.0;

/// A rectangle in the plotting area's pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct PixelBox {
    /// Left edge.
    pub left: f64,
    /// Top edge.
    pub top: f64,
    /// Right edge.
    pub right: f64,
    /// Bottom edge.
    pub bottom: f64,
}

impl PixelBox {
    pub(super) fn overlaps(&self, other: &PixelBox) -> bool {
        self.left < other.right
            && other.left < self.right
            && self.top < other.bottom
            && other.top < self.bottom
    }

    fn contains(&self, (x, y): (f64, f64)) -> bool {
        (self.left..=self.right).contains(&x) && (self.top..=self.bottom).contains(&y)
    }

    /// The length of segment `a`–`b` inside the box (Liang–Barsky clipping).
    fn clipped_length(&self, a: (f64, f64), b: (f64, f64)) -> f64 {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let (mut enter, mut leave) = (0.0_f64, 1.0_f64);
        for (p, q) in [
            (-dx, a.0 - self.left),
            (dx, self.right - a.0),
            (-dy, a.1 - self.top),
            (dy, self.bottom - a.1),
        ] {
            if p == 0.0 {
                if q < 0.0 {
                    return 0.0;
                }
            } else {
                let r = q / p;
                if p < 0.0 {
                    enter = enter.max(r);
                } else {
                    leave = leave.min(r);
                }
            }
        }
        if enter < leave {
            (leave - enter) * dx.hypot(dy)
        } else {
            0.0
        }
    }
}

/// The corners a legend may take, in the order a tie is settled (upper right first: where it
/// always was).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Corner {
    /// Upper right.
    UpperRight,
    /// Upper left.
    UpperLeft,
    /// Lower right.
    LowerRight,
    /// Lower left.
    LowerLeft,
}

impl Corner {
    const ALL: [Corner; 4] = [
        Corner::UpperRight,
        Corner::UpperLeft,
        Corner::LowerRight,
        Corner::LowerLeft,
    ];

    /// The box of size `size` in this corner of an area of size `area` (pixels).
    pub(super) fn place(self, size: (f64, f64), area: (f64, f64)) -> PixelBox {
        let left = match self {
            Corner::UpperLeft | Corner::LowerLeft => EDGE_GAP,
            Corner::UpperRight | Corner::LowerRight => area.0 - size.0 - EDGE_GAP,
        };
        let top = match self {
            Corner::UpperLeft | Corner::UpperRight => EDGE_GAP,
            Corner::LowerLeft | Corner::LowerRight => area.1 - size.1 - EDGE_GAP,
        };
        PixelBox {
            left,
            top,
            right: left + size.0,
            bottom: top + size.1,
        }
    }
}

/// What a plot draws, in the plotting area's pixels, as far as a legend box can hide it (a scatter
/// plot's point labels enter as lines along their text).
#[derive(Debug, Default)]
pub(super) struct Ink {
    /// Polylines (bounds, band edges, hull lines): consecutive points are joined.
    lines: Vec<Vec<(f64, f64)>>,
    /// Filled bands: per x, the top and bottom pixel of the fill.
    fills: Vec<Vec<(f64, f64, f64)>>,
    /// Single dots.
    dots: Vec<(f64, f64)>,
}

impl Ink {
    /// A polyline; non-finite points break it.
    pub(super) fn line(&mut self, points: impl IntoIterator<Item = (f64, f64)>) {
        let mut run = Vec::new();
        for p in points {
            if p.0.is_finite() && p.1.is_finite() {
                run.push(p);
            } else if !run.is_empty() {
                self.lines.push(std::mem::take(&mut run));
            }
        }
        if !run.is_empty() {
            self.lines.push(run);
        }
    }

    /// A band's fill from `(x, y_a, y_b)` columns in increasing x (either edge may be the upper);
    /// non-finite columns are left out.
    pub(super) fn fill(&mut self, columns: impl IntoIterator<Item = (f64, f64, f64)>) {
        self.fills.push(
            columns
                .into_iter()
                .filter(|(x, a, b)| x.is_finite() && a.is_finite() && b.is_finite())
                .map(|(x, a, b)| (x, a.min(b), a.max(b)))
                .collect(),
        );
    }

    /// A dot; a non-finite one is left out.
    pub(super) fn dot(&mut self, at: (f64, f64)) {
        if at.0.is_finite() && at.1.is_finite() {
            self.dots.push(at);
        }
    }

    /// How much of the ink `area` hides (module docs).
    pub(super) fn hidden_by(&self, area: &PixelBox) -> f64 {
        let lines: f64 = self
            .lines
            .iter()
            .flat_map(|line| line.windows(2))
            .map(|pair| area.clipped_length(pair[0], pair[1]))
            .sum();
        let fills: f64 = self
            .fills
            .iter()
            .flat_map(|fill| fill.windows(2))
            .map(|pair| {
                let ((x0, top0, bottom0), (x1, top1, bottom1)) = (pair[0], pair[1]);
                let width = x1.min(area.right) - x0.max(area.left);
                let top = (0.5 * (top0 + top1)).max(area.top);
                let bottom = (0.5 * (bottom0 + bottom1)).min(area.bottom);
                if width > 0.0 && bottom > top {
                    width * (bottom - top)
                } else {
                    0.0
                }
            })
            .sum();
        let dots = self.dots.iter().filter(|&&p| area.contains(p)).count() as f64;
        lines + FILL_INK_PER_PIXEL * fills + DOT_INK * dots
    }
}

/// The corner for a legend of size `size` in an area of size `area` that hides the least of
/// `ink` (the first of equal ones in [`Corner::ALL`]'s order), leaving out corners whose box
/// would overlap `keep_clear` (a note already drawn there).
pub(super) fn least_hiding_corner(
    ink: &Ink,
    size: (f64, f64),
    area: (f64, f64),
    keep_clear: Option<PixelBox>,
) -> Corner {
    let mut best: Option<(Corner, f64)> = None;
    for corner in Corner::ALL {
        let placed = corner.place(size, area);
        if keep_clear.is_some_and(|clear| clear.overlaps(&placed)) {
            continue;
        }
        let hidden = ink.hidden_by(&placed);
        if best.is_none_or(|(_, least)| hidden < least) {
            best = Some((corner, hidden));
        }
    }
    best.map_or(Corner::UpperRight, |(corner, _)| corner)
}

#[cfg(test)]
mod tests {
    use super::*;

    const AREA: (f64, f64) = (780.0, 360.0);
    const LEGEND: (f64, f64) = (240.0, 90.0);

    /// A response that rises to the upper part of the plot and stays there: the upper right is
    /// where it settles, the lower right is empty.
    fn settling_high() -> Ink {
        let mut ink = Ink::default();
        let xs: Vec<f64> = (0..=150).map(|i| i as f64 * AREA.0 / 150.0).collect();
        let settle = |x: f64, level: f64| AREA.1 - (AREA.1 - level) * (1.0 - (-x / 60.0).exp());
        ink.line(xs.iter().map(|&x| (x, settle(x, 60.0))));
        ink.line(xs.iter().map(|&x| (x, settle(x, 100.0))));
        ink.fill(xs.iter().map(|&x| (x, settle(x, 60.0), settle(x, 100.0))));
        ink
    }

    #[test]
    fn a_response_settling_high_gets_its_legend_in_the_lower_right() {
        let ink = settling_high();
        // The bound settling at y = 60 runs right across the upper-right box (y 5 … 95).
        let upper_right = ink.hidden_by(&Corner::UpperRight.place(LEGEND, AREA));
        assert!(upper_right >= LEGEND.0, "{upper_right}");
        assert_eq!(
            least_hiding_corner(&ink, LEGEND, AREA, None),
            Corner::LowerRight
        );
    }

    #[test]
    fn an_empty_upper_right_keeps_the_legend_there() {
        let mut ink = Ink::default();
        // A line along the bottom: every upper corner is free, the upper right comes first.
        ink.line([(0.0, 350.0), (780.0, 350.0)]);
        assert_eq!(
            least_hiding_corner(&ink, LEGEND, AREA, None),
            Corner::UpperRight
        );
    }

    #[test]
    fn a_note_keeps_the_legend_out_of_its_corner() {
        let mut ink = Ink::default();
        // Lines across the top and along the right-hand half of the bottom: the lower left
        // is the only free corner, but a note sits there.
        ink.line([(0.0, 20.0), (780.0, 20.0)]);
        ink.line([(400.0, 340.0), (780.0, 340.0)]);
        assert_eq!(
            least_hiding_corner(&ink, LEGEND, AREA, None),
            Corner::LowerLeft
        );
        let note = PixelBox {
            left: 5.0,
            top: 320.0,
            right: 300.0,
            bottom: 355.0,
        };
        assert_ne!(
            least_hiding_corner(&ink, LEGEND, AREA, Some(note)),
            Corner::LowerLeft
        );
    }

    #[test]
    fn a_line_counts_by_its_length_under_the_box() {
        let area = PixelBox {
            left: 10.0,
            top: 10.0,
            right: 20.0,
            bottom: 20.0,
        };
        // Horizontal through the box: 10 px; diagonal corner to corner: 10√2; outside: 0.
        assert!((area.clipped_length((0.0, 15.0), (30.0, 15.0)) - 10.0).abs() < 1e-12);
        assert!((area.clipped_length((0.0, 0.0), (30.0, 30.0)) - 200.0_f64.sqrt()).abs() < 1e-12);
        assert_eq!(area.clipped_length((0.0, 25.0), (30.0, 25.0)), 0.0);
        // A vertical segment inside counts its part inside.
        assert!((area.clipped_length((15.0, 12.0), (15.0, 40.0)) - 8.0).abs() < 1e-12);
    }

    #[test]
    fn dots_and_fills_count_too_and_non_finite_points_break_lines() {
        let area = Corner::UpperRight.place(LEGEND, AREA);
        let mut dots = Ink::default();
        dots.dot((area.left + 1.0, area.top + 1.0));
        dots.dot((f64::NAN, area.top + 1.0));
        assert_eq!(dots.hidden_by(&area), DOT_INK);
        let mut fill = Ink::default();
        fill.fill([(0.0, 0.0, AREA.1), (AREA.0, AREA.1, 0.0)]);
        let covered = LEGEND.0 * LEGEND.1 * FILL_INK_PER_PIXEL;
        assert!((fill.hidden_by(&area) - covered).abs() < 1e-9);
        let mut broken = Ink::default();
        broken.line([
            (area.left, area.top + 1.0),
            (f64::NAN, 0.0),
            (area.right, area.top + 1.0),
        ]);
        assert_eq!(broken.hidden_by(&area), 0.0);
    }
}
