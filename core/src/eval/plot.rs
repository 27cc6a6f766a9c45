//! Minimal SVG line charts for the evaluation report (no plotting dependency for a few curves).

use crate::render::svg::num;
use svg::node::element::{Line, Polyline, Text};
use svg::Document;

pub fn line_chart(
    title: &str,
    x_label: &str,
    y_label: &str,
    points: &[(f64, f64)],
    y_max: f64,
) -> String {
    let (w, h, left, bottom, top, right) = (480.0, 300.0, 56.0, 44.0, 30.0, 16.0);
    let x_min = points.iter().map(|p| p.0).fold(f64::MAX, f64::min);
    let x_max = points
        .iter()
        .map(|p| p.0)
        .fold(f64::MIN, f64::max)
        .max(x_min + 1e-9);
    let sx = |x: f64| left + (x - x_min) / (x_max - x_min) * (w - left - right);
    let sy = |y: f64| h - bottom - y / y_max * (h - bottom - top);
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
        doc = doc
            .add(text(8.0, sy(y) + 4.0, &format!("{y:.0}"), 10.0))
            .add(axis(left - 4.0, sy(y), left, sy(y)));
    }
    for &(x, _) in points {
        doc = doc.add(text(sx(x) - 6.0, h - bottom + 14.0, &format!("{x}"), 9.0));
    }
    let line: Vec<String> = points
        .iter()
        .map(|&(x, y)| format!("{},{}", num(sx(x)), num(sy(y))))
        .collect();
    doc = doc.add(
        Polyline::new()
            .set("points", line.join(" "))
            .set("fill", "none")
            .set("stroke", "#1f5fbf")
            .set("stroke-width", 2),
    );
    doc.to_string()
}
