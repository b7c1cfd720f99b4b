//! A small SVG plot writer for reports: log- or linear-scaled axes, labelled series of points
//! (markers, optionally joined) and a legend. Plain text, no dependencies.

use std::fmt::Write;

/// One series of a plot.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// `(x, y)` points.
    pub points: Vec<(f64, f64)>,
    /// Optional label per point (e.g. the order), drawn beside the marker.
    pub point_labels: Vec<String>,
    /// Join the points with a line.
    pub joined: bool,
    /// Draw the line dashed (so that a series drawn under it shows through).
    pub dashed: bool,
}

/// A plot.
#[derive(Clone, Debug)]
pub struct Plot {
    /// Title.
    pub title: String,
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// Logarithmic x axis.
    pub log_x: bool,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// The series.
    pub series: Vec<Series>,
}

const WIDTH: f64 = 760.0;
const HEIGHT: f64 = 480.0;
const LEFT: f64 = 80.0;
const RIGHT: f64 = 200.0;
const TOP: f64 = 40.0;
const BOTTOM: f64 = 60.0;
const COLOURS: [&str; 8] = [
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf",
];

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Data range of one axis, padded; in log10 units for log axes.
fn axis_range(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let mapped: Vec<f64> = values
        .filter(|v| v.is_finite() && (!log || *v > 0.0))
        .map(|v| if log { v.log10() } else { v })
        .collect();
    let (lo, hi) = mapped
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if log {
        (lo.floor(), hi.ceil().max(lo.floor() + 1.0))
    } else {
        let pad = ((hi - lo) * 0.05).max(1e-12);
        (lo - pad, hi + pad)
    }
}

fn format_tick(value: f64, log: bool) -> String {
    if log {
        format!("1e{}", value.round() as i64)
    } else {
        format!("{value:.3}")
    }
}

impl Plot {
    /// The plot as SVG text.
    pub fn to_svg(&self) -> String {
        let all = || self.series.iter().flat_map(|s| s.points.iter());
        let (x0, x1) = axis_range(all().map(|p| p.0), self.log_x);
        let (y0, y1) = axis_range(all().map(|p| p.1), self.log_y);
        let plot_w = WIDTH - LEFT - RIGHT;
        let plot_h = HEIGHT - TOP - BOTTOM;
        let map_x = |x: f64| {
            let v = if self.log_x { x.log10() } else { x };
            LEFT + (v - x0) / (x1 - x0) * plot_w
        };
        let map_y = |y: f64| {
            let v = if self.log_y { y.log10() } else { y };
            TOP + plot_h - (v - y0) / (y1 - y0) * plot_h
        };
        let mut svg = String::new();
        let _ = writeln!(
            svg,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" font-family="sans-serif" font-size="12">"#
        );
        let _ = writeln!(svg, r#"<rect width="100%" height="100%" fill="white"/>"#);
        let _ = writeln!(
            svg,
            r#"<text x="{}" y="22" font-size="15" text-anchor="middle">{}</text>"#,
            LEFT + plot_w / 2.0,
            escape(&self.title)
        );
        let _ = writeln!(
            svg,
            r#"<rect x="{LEFT}" y="{TOP}" width="{plot_w}" height="{plot_h}" fill="none" stroke="black"/>"#
        );
        // Ticks: decades on log axes, five steps on linear ones.
        let ticks = |lo: f64, hi: f64, log: bool| -> Vec<f64> {
            if log {
                ((lo.round() as i64)..=(hi.round() as i64))
                    .map(|e| e as f64)
                    .collect()
            } else {
                (0..=5).map(|i| lo + (hi - lo) * i as f64 / 5.0).collect()
            }
        };
        for t in ticks(x0, x1, self.log_x) {
            let x = LEFT + (t - x0) / (x1 - x0) * plot_w;
            let _ = writeln!(
                svg,
                r##"<line x1="{x}" y1="{TOP}" x2="{x}" y2="{}" stroke="#ddd"/>"##,
                TOP + plot_h
            );
            let _ = writeln!(
                svg,
                r#"<text x="{x}" y="{}" text-anchor="middle">{}</text>"#,
                TOP + plot_h + 18.0,
                format_tick(t, self.log_x)
            );
        }
        for t in ticks(y0, y1, self.log_y) {
            let y = TOP + plot_h - (t - y0) / (y1 - y0) * plot_h;
            let _ = writeln!(
                svg,
                r##"<line x1="{LEFT}" y1="{y}" x2="{}" y2="{y}" stroke="#ddd"/>"##,
                LEFT + plot_w
            );
            let _ = writeln!(
                svg,
                r#"<text x="{}" y="{}" text-anchor="end">{}</text>"#,
                LEFT - 6.0,
                y + 4.0,
                format_tick(t, self.log_y)
            );
        }
        let _ = writeln!(
            svg,
            r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
            LEFT + plot_w / 2.0,
            HEIGHT - 15.0,
            escape(&self.x_label)
        );
        let _ = writeln!(
            svg,
            r#"<text x="18" y="{}" text-anchor="middle" transform="rotate(-90 18 {})">{}</text>"#,
            TOP + plot_h / 2.0,
            TOP + plot_h / 2.0,
            escape(&self.y_label)
        );
        for (i, series) in self.series.iter().enumerate() {
            let colour = COLOURS[i % COLOURS.len()];
            let visible: Vec<(usize, (f64, f64))> = series
                .points
                .iter()
                .copied()
                .enumerate()
                .filter(|(_, (x, y))| {
                    x.is_finite()
                        && y.is_finite()
                        && (!self.log_x || *x > 0.0)
                        && (!self.log_y || *y > 0.0)
                })
                .collect();
            if series.joined && visible.len() > 1 {
                let path: Vec<String> = visible
                    .iter()
                    .map(|(_, (x, y))| format!("{:.2},{:.2}", map_x(*x), map_y(*y)))
                    .collect();
                let dash = if series.dashed {
                    r#" stroke-dasharray="6 4""#
                } else {
                    ""
                };
                let _ = writeln!(
                    svg,
                    r#"<polyline points="{}" fill="none" stroke="{colour}" stroke-width="1.5"{dash}/>"#,
                    path.join(" ")
                );
            }
            if !series.joined || visible.len() < 60 {
                for (k, (x, y)) in &visible {
                    let (px, py) = (map_x(*x), map_y(*y));
                    let _ = writeln!(
                        svg,
                        r#"<circle cx="{px:.2}" cy="{py:.2}" r="3.5" fill="{colour}"/>"#
                    );
                    if let Some(label) = series.point_labels.get(*k).filter(|l| !l.is_empty()) {
                        let _ = writeln!(
                            svg,
                            r#"<text x="{:.2}" y="{:.2}" fill="{colour}">{}</text>"#,
                            px + 5.0,
                            py - 5.0,
                            escape(label)
                        );
                    }
                }
            }
            let ly = TOP + 14.0 + 18.0 * i as f64;
            let lx = LEFT + plot_w + 14.0;
            let _ = writeln!(
                svg,
                r#"<rect x="{lx}" y="{}" width="12" height="12" fill="{colour}"/>"#,
                ly - 10.0
            );
            let _ = writeln!(
                svg,
                r#"<text x="{}" y="{ly}">{}</text>"#,
                lx + 18.0,
                escape(&series.label)
            );
        }
        svg.push_str("</svg>\n");
        svg
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn svg_has_every_series_and_escapes_text() {
        let plot = Plot {
            title: "error <vs> time".to_string(),
            x_label: "wall time (s)".to_string(),
            y_label: "error".to_string(),
            log_x: true,
            log_y: true,
            series: vec![
                Series {
                    label: "a".into(),
                    points: vec![(0.1, 1e-3), (1.0, 1e-5)],
                    point_labels: vec!["k=2".into(), "k=4".into()],
                    joined: true,
                    dashed: false,
                },
                Series {
                    label: "b & c".into(),
                    points: vec![(0.5, 0.0), (2.0, 1e-2)],
                    point_labels: vec![],
                    joined: false,
                    dashed: false,
                },
            ],
        };
        let svg = plot.to_svg();
        assert!(svg.starts_with("<svg") && svg.ends_with("</svg>\n"));
        assert!(
            svg.contains("error &lt;vs&gt; time")
                && svg.contains("b &amp; c")
                && svg.contains("k=4")
        );
        assert_eq!(svg.matches("<polyline").count(), 1);
        // The zero-error point cannot sit on a log axis and is left out, not drawn at -inf.
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
    }
}
