//! SVG output with millimetre units: `width="40mm"` and a viewBox in mm, so one user unit is 1 mm.

use super::scene::{Item, MarkerScene};
use crate::family::pattern::{Path, Seg};
use std::fmt::Write;
use svg::node::element::{Group, Path as SvgPath};
use svg::Document;

/// Shortest exact-enough decimal: 4 decimals (0.1 µm) are far below any printer's resolution.
pub(crate) fn num(v: f64) -> String {
    let s = format!("{v:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.into()
    }
}

/// SVG path data of a path shifted by (dx, dy).
pub(crate) fn path_data(path: &Path, dx: f64, dy: f64) -> String {
    let mut d = String::new();
    for s in &path.0 {
        let _ = match *s {
            Seg::Move(x, y) => write!(d, "M{} {}", num(x + dx), num(y + dy)),
            Seg::Line(x, y) => write!(d, "L{} {}", num(x + dx), num(y + dy)),
            Seg::Cubic(a, b, c, e, x, y) => write!(
                d,
                "C{} {} {} {} {} {}",
                num(a + dx),
                num(b + dy),
                num(c + dx),
                num(e + dy),
                num(x + dx),
                num(y + dy)
            ),
            Seg::Close => write!(d, "Z"),
        };
    }
    d
}

pub(crate) fn item_node(item: &Item, dx: f64, dy: f64) -> SvgPath {
    let mut p = SvgPath::new().set("d", path_data(&item.path, dx, dy));
    p = match item.fill {
        Some(c) => p.set("fill", c.to_string()),
        None => p.set("fill", "none"),
    };
    if let Some((c, w)) = item.stroke {
        p = p.set("stroke", c.to_string()).set("stroke-width", num(w));
    }
    p
}

/// The marker as a group of paths placed at (x, y) mm.
pub(crate) fn marker_group(scene: &MarkerScene, x: f64, y: f64) -> Group {
    scene
        .items
        .iter()
        .fold(Group::new(), |g, item| g.add(item_node(item, x, y)))
}

/// A standalone SVG document of one marker, sized in mm.
pub fn marker_svg(scene: &MarkerScene) -> String {
    let doc = Document::new()
        .set("width", format!("{}mm", num(scene.width_mm)))
        .set("height", format!("{}mm", num(scene.height_mm)))
        .set(
            "viewBox",
            format!("0 0 {} {}", num(scene.width_mm), num(scene.height_mm)),
        )
        .add(marker_group(scene, 0.0, 0.0).set("class", "marker"));
    doc.to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_short_and_exact_to_a_tenth_of_a_micron() {
        assert_eq!(num(40.0), "40");
        assert_eq!(num(12.34567), "12.3457");
        assert_eq!(num(-0.00001), "0");
        assert_eq!(num(0.5), "0.5");
    }
}
