//! Minimal SVG line charts for the evaluation report (no plotting dependency for a few curves).

use crate::render::svg::num;
use svg::node::element::{Line, Polyline, Text};
use svg::Document;

/// One line of a chart.
pub struct Series<'a> {
    pub name: &'a str,
    pub points: Vec<(f64, f64)>,
    /// Which colour (families keep theirs across charts).
    pub colour: usize,
    /// Dashed (a tail percentile beside its median).
    pub dashed: bool,
}

/// Colours of series, told apart in gray print as well; the studio's Compare panel draws each
/// design in the same colour as these charts.
pub const COLOURS: [[u8; 3]; 6] = [
    [0x1f, 0x5f, 0xbf],
    [0xd9, 0x48, 0x0f],
    [0x2b, 0x8a, 0x3e],
    [0x86, 0x2e, 0x9c],
    [0x49, 0x50, 0x57],
    [0xe8, 0x59, 0x0c],
];

pub fn line_chart(
    title: &str,
    x_label: &str,
    y_label: &str,
    points: &[(f64, f64)],
    y_max: f64,
) -> String {
    let series = [Series {
        name: "",
        points: points.to_vec(),
        colour: 0,
        dashed: false,
    }];
    chart(title, x_label, y_label, &series, y_max)
}

/// Several series on one pair of axes, with a legend for the named ones. `y_max` of 0 or less
/// fits the axis to the data.
pub fn chart(title: &str, x_label: &str, y_label: &str, series: &[Series], y_max: f64) -> String {
    let all = || series.iter().flat_map(|s| s.points.iter());
    let y_max = if y_max > 0.0 {
        y_max
    } else {
        nice_ceiling(
            all()
                .map(|p| p.1)
                .filter(|y| y.is_finite())
                .fold(0.0, f64::max),
        )
    };
    let (w, h, left, bottom, top, right) = (480.0, 300.0, 56.0, 44.0, 30.0, 16.0);
    let x_min = all().map(|p| p.0).fold(f64::MAX, f64::min);
    let x_max = all()
        .map(|p| p.0)
        .fold(f64::MIN, f64::max)
        .max(x_min + 1e-9);
    let sx = |x: f64| left + (x - x_min) / (x_max - x_min) * (w - left - right);
    let sy = |y: f64| h - bottom - y.min(y_max) / y_max * (h - bottom - top);
    let text = |x: f64, y: f64, s: &str, size: f64| {
        Text::new(s.to_string())
            .set("x", num(x))
            .set("y", num(y))
            .set("font-size", num(size))
            .set("font-family", "DejaVu Sans")
    };
    let axis = |x1: f64, y1: f64, x2: f64, y2: f64| {
        Line::new()
            .set("x1", num(x1))
            .set("y1", num(y1))
            .set("x2", num(x2))
            .set("y2", num(y2))
            .set("stroke", "#000")
    };
    let mut doc = Document::new()
        .set("width", w)
        .set("height", h)
        .set("viewBox", format!("0 0 {w} {h}"))
        .add(
            svg::node::element::Rectangle::new()
                .set("width", w)
                .set("height", h)
                .set("fill", "#fff"),
        )
        .add(text(left, 18.0, title, 13.0))
        .add(axis(left, h - bottom, w - right, h - bottom))
        .add(axis(left, top, left, h - bottom))
        .add(text(w / 2.0 - 40.0, h - 8.0, x_label, 11.0))
        .add(text(4.0, top - 8.0, y_label, 11.0));
    for i in 0..=4 {
        let y = y_max * i as f64 / 4.0;
        let label = if y_max < 4.0 {
            format!("{y:.2}")
        } else {
            format!("{y:.0}")
        };
        doc =
            doc.add(text(8.0, sy(y) + 4.0, &label, 10.0))
                .add(axis(left - 4.0, sy(y), left, sy(y)));
    }
    let mut xs: Vec<f64> = all().map(|p| p.0).collect();
    xs.sort_by(f64::total_cmp);
    xs.dedup();
    for x in xs {
        doc = doc.add(text(sx(x) - 6.0, h - bottom + 14.0, &format!("{x}"), 9.0));
    }
    let mut legend_y = top + 4.0;
    for s in series {
        let [r, g, b] = COLOURS[s.colour % COLOURS.len()];
        let colour = format!("#{r:02x}{g:02x}{b:02x}");
        // A missing value (no marker read) breaks the line rather than dropping to zero.
        for run in s.points.split(|p| !p.1.is_finite()) {
            let line: Vec<String> = run
                .iter()
                .map(|&(x, y)| format!("{},{}", num(sx(x)), num(sy(y))))
                .collect();
            let mut polyline = Polyline::new()
                .set("points", line.join(" "))
                .set("fill", "none")
                .set("stroke", colour.as_str())
                .set("stroke-width", 2);
            if s.dashed {
                polyline = polyline.set("stroke-dasharray", "5 3");
            }
            doc = doc.add(polyline);
        }
        if !s.name.is_empty() {
            let mut key = Line::new()
                .set("x1", num(w - right - 150.0))
                .set("y1", num(legend_y))
                .set("x2", num(w - right - 132.0))
                .set("y2", num(legend_y))
                .set("stroke", colour)
                .set("stroke-width", 2);
            if s.dashed {
                key = key.set("stroke-dasharray", "5 3");
            }
            doc = doc
                .add(key)
                .add(text(w - right - 128.0, legend_y + 3.0, s.name, 9.0));
            legend_y += 12.0;
        }
    }
    doc.to_string()
}

/// The smallest of 1, 2 or 5 times a power of ten at or above `v` (an axis end).
fn nice_ceiling(v: f64) -> f64 {
    if !(v.is_finite() && v > 0.0) {
        return 1.0;
    }
    let power = 10f64.powf(v.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * power)
        .find(|&c| c >= v)
        .unwrap_or(10.0 * power)
}
