//! Category patterns, the local patterns of the family model, as vector paths in cell-local
//! coordinates (the cell is [-0.5, 0.5]², y down).
//!
//! Every primitive shape of the family format becomes one [`Path`], so that SVG, PDF and raster
//! output draw exactly the same geometry.

use super::spec::{Category, Primitive, Role, Shape};
use super::Problem;
use crate::color::Rgb;

/// Path segments with absolute coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Seg {
    Move(f64, f64),
    Line(f64, f64),
    Cubic(f64, f64, f64, f64, f64, f64),
    Close,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct Path(pub Vec<Seg>);

impl Path {
    /// Maps every point through `f`.
    pub fn map(&self, f: impl Fn(f64, f64) -> (f64, f64)) -> Path {
        Path(
            self.0
                .iter()
                .map(|s| match *s {
                    Seg::Move(x, y) => {
                        let (x, y) = f(x, y);
                        Seg::Move(x, y)
                    }
                    Seg::Line(x, y) => {
                        let (x, y) = f(x, y);
                        Seg::Line(x, y)
                    }
                    Seg::Cubic(a, b, c, d, x, y) => {
                        let (a, b) = f(a, b);
                        let (c, d) = f(c, d);
                        let (x, y) = f(x, y);
                        Seg::Cubic(a, b, c, d, x, y)
                    }
                    Seg::Close => Seg::Close,
                })
                .collect(),
        )
    }

    fn polygon(points: &[(f64, f64)]) -> Path {
        let mut segs = Vec::with_capacity(points.len() + 1);
        for (i, &(x, y)) in points.iter().enumerate() {
            segs.push(if i == 0 {
                Seg::Move(x, y)
            } else {
                Seg::Line(x, y)
            });
        }
        segs.push(Seg::Close);
        Path(segs)
    }

    /// A closed circle of four cubic arcs; `clockwise` picks the winding (holes wind the other way).
    fn circle(cx: f64, cy: f64, r: f64, clockwise: bool) -> Vec<Seg> {
        // Control distance for a quarter circle: 4/3·tan(π/8).
        let k = 0.552_284_749_830_793_4 * r;
        let s = if clockwise { 1.0 } else { -1.0 };
        vec![
            Seg::Move(cx + r, cy),
            Seg::Cubic(cx + r, cy + s * k, cx + k, cy + s * r, cx, cy + s * r),
            Seg::Cubic(cx - k, cy + s * r, cx - r, cy + s * k, cx - r, cy),
            Seg::Cubic(cx - r, cy - s * k, cx - k, cy - s * r, cx, cy - s * r),
            Seg::Cubic(cx + k, cy - s * r, cx + r, cy - s * k, cx + r, cy),
            Seg::Close,
        ]
    }
}

/// One drawable item of a pattern.
#[derive(Debug, Clone, PartialEq)]
pub struct PatternItem {
    pub path: Path,
    pub fill: Option<Rgb>,
    /// Colour and width in cell units.
    pub stroke: Option<(Rgb, f64)>,
}

/// A category, parsed and ready to draw.
#[derive(Debug, Clone, PartialEq)]
pub struct CategoryPattern {
    pub name: String,
    pub role: Role,
    pub items: Vec<PatternItem>,
    /// When the first primitive fills the whole cell with one colour (and strokes nothing), that
    /// colour: grid renderers merge such cells into one region per colour so no seams show.
    pub cell_fill: Option<Rgb>,
}

/// Largest coordinate a primitive may reach, in cells: patterns may spill a little over their
/// cell but not draw across the marker.
const MAX_REACH: f64 = 4.0;

/// Most primitives in one category. A cell's pattern is read from a few pixels per feature; more
/// than a few dozen shapes in one cell cannot all be seen, while every one of them is drawn again
/// in every cell of the category (thousands of dots made `sheet` hit usvg's node limit).
pub const MAX_PRIMITIVES: usize = 64;

pub fn parse_category(cat: &Category, path: &str) -> Result<CategoryPattern, Vec<Problem>> {
    if cat.primitives.len() > MAX_PRIMITIVES {
        return Err(vec![Problem::new(
            format!("{path}.primitives"),
            format!(
                "{} primitives is over the limit of {MAX_PRIMITIVES} per category",
                cat.primitives.len()
            ),
        )]);
    }
    let mut problems = Vec::new();
    let mut items = Vec::new();
    for (i, prim) in cat.primitives.iter().enumerate() {
        match parse_primitive(prim) {
            Ok(item) => items.push(item),
            Err((field, msg)) => {
                problems.push(Problem::new(format!("{path}.primitives[{i}]{field}"), msg))
            }
        }
    }
    if !problems.is_empty() {
        return Err(problems);
    }
    let cell_fill = match cat.primitives.first() {
        Some(Primitive {
            shape: Shape::Square { size, x, y },
            fill: Some(_),
            stroke: None,
            ..
        }) if (*size - 1.0).abs() < 1e-12 && *x == 0.0 && *y == 0.0 => items[0].fill,
        _ => None,
    };
    Ok(CategoryPattern {
        name: cat.name.clone(),
        role: cat.role,
        items,
        cell_fill,
    })
}

type FieldError = (String, String);

fn positive(field: &str, v: f64) -> Result<f64, FieldError> {
    if v.is_finite() && v > 0.0 && v <= 2.0 * MAX_REACH {
        Ok(v)
    } else {
        Err((
            format!(".{field}"),
            format!("{v} must be a number in (0, {}]", 2.0 * MAX_REACH),
        ))
    }
}

fn offset(field: &str, v: f64) -> Result<f64, FieldError> {
    if v.is_finite() && v.abs() <= MAX_REACH {
        Ok(v)
    } else {
        Err((
            format!(".{field}"),
            format!("{v} must be within ±{MAX_REACH} cells"),
        ))
    }
}

fn colour(field: &str, v: &Option<String>) -> Result<Option<Rgb>, FieldError> {
    v.as_deref()
        .map(Rgb::parse)
        .transpose()
        .map_err(|e| (format!(".{field}"), e.to_string()))
}

fn parse_primitive(p: &Primitive) -> Result<PatternItem, FieldError> {
    let fill = colour("fill", &p.fill)?;
    let stroke_colour = colour("stroke", &p.stroke)?;
    let stroke = match (stroke_colour, p.stroke_width) {
        (Some(c), Some(w)) => Some((c, positive("stroke_width", w)?)),
        (Some(c), None) => Some((c, 0.05)),
        (None, Some(_)) => {
            return Err((
                ".stroke".into(),
                "stroke_width is set but stroke is not".into(),
            ))
        }
        (None, None) => None,
    };
    if fill.is_none() && stroke.is_none() {
        return Err((
            String::new(),
            "draws nothing: give it a fill or a stroke colour".into(),
        ));
    }
    let path = shape_path(&p.shape)?;
    Ok(PatternItem { path, fill, stroke })
}

fn shape_path(shape: &Shape) -> Result<Path, FieldError> {
    Ok(match *shape {
        Shape::Square { size, x, y } => {
            let (h, x, y) = (
                positive("size", size)? / 2.0,
                offset("x", x)?,
                offset("y", y)?,
            );
            Path::polygon(&[
                (x - h, y - h),
                (x + h, y - h),
                (x + h, y + h),
                (x - h, y + h),
            ])
        }
        Shape::Dot { radius, x, y } => Path(Path::circle(
            offset("x", x)?,
            offset("y", y)?,
            positive("radius", radius)?,
            true,
        )),
        Shape::Ring {
            radius,
            width,
            x,
            y,
        } => {
            let (r, w) = (positive("radius", radius)?, positive("width", width)?);
            if w >= r {
                return Err((
                    ".width".into(),
                    format!("ring width {w} must be less than its radius {r}"),
                ));
            }
            let (x, y) = (offset("x", x)?, offset("y", y)?);
            let mut segs = Path::circle(x, y, r, true);
            segs.extend(Path::circle(x, y, r - w, false));
            Path(segs)
        }
        Shape::Cross { size, width, x, y } => {
            let (s, w) = (positive("size", size)? / 2.0, positive("width", width)?);
            if w >= size {
                return Err((
                    ".width".into(),
                    format!("bar width {w} must be less than the size {size}"),
                ));
            }
            let (x, y) = (offset("x", x)?, offset("y", y)?);
            // Outline of the union of two diagonal bars: a 12-point star, one polygon, no overlap.
            let d = w / std::f64::consts::SQRT_2;
            let pts = [
                (-s, -s + d),
                (-s + d, -s),
                (0.0, -d),
                (s - d, -s),
                (s, -s + d),
                (d, 0.0),
                (s, s - d),
                (s - d, s),
                (0.0, d),
                (-s + d, s),
                (-s, s - d),
                (-d, 0.0),
            ];
            Path::polygon(&pts.map(|(px, py)| (x + px, y + py)))
        }
        Shape::Triangle { size, x, y } => {
            let (h, x, y) = (
                positive("size", size)? / 2.0,
                offset("x", x)?,
                offset("y", y)?,
            );
            Path::polygon(&[(x, y - h), (x + h, y + h), (x - h, y + h)])
        }
        Shape::Bar {
            width,
            height,
            angle_deg,
            x,
            y,
        } => {
            let (hw, hh) = (
                positive("width", width)? / 2.0,
                positive("height", height)? / 2.0,
            );
            if !angle_deg.is_finite() {
                return Err((".angle_deg".into(), "must be a finite number".into()));
            }
            let (x, y) = (offset("x", x)?, offset("y", y)?);
            let (s, c) = angle_deg.to_radians().sin_cos();
            let pts = [(-hw, -hh), (hw, -hh), (hw, hh), (-hw, hh)];
            Path::polygon(&pts.map(|(px, py)| (x + c * px - s * py, y + s * px + c * py)))
        }
        Shape::Path { ref d } => parse_svg_path(d)?,
    })
}

/// Longest path data (`d`) of one `path` primitive, in bytes. Hand-written and exported glyph
/// outlines of a cell's pattern take a few hundred bytes to a few kilobytes; 16 KiB leaves room for
/// detailed ones while bounding parsing and the segment count before anything is built.
pub const MAX_PATH_BYTES: usize = 16 * 1024;

/// Most segments one `path` primitive may have once arcs are split into cubics. A cell is drawn a
/// few hundred pixels wide at most, so 512 segments give more detail than any rendering shows. The
/// rasterizer keeps the edges that cross a scanline in an insertion-sorted list, so its time grows
/// with the square of a path's segments when they pile up: 8000 smooth cubics took 5.4 s, 512
/// take about 0.1 s over every cell of a marker at 300 dpi.
pub const MAX_PATH_SEGMENTS: usize = 512;

/// Largest arc radius in path data, in cells: an arc between points within ±[`MAX_REACH`] that
/// needs a larger radius is a straight line for every purpose, and bounding it keeps the arc
/// arithmetic (squares of radii) far from overflow.
const MAX_ARC_RADIUS: f64 = 1000.0;

fn parse_svg_path(d: &str) -> Result<Path, FieldError> {
    if d.len() > MAX_PATH_BYTES {
        return Err((
            ".d".into(),
            format!(
                "path data is {} bytes, over the limit of {MAX_PATH_BYTES}",
                d.len()
            ),
        ));
    }
    let segs = simplify_path(d, MAX_PATH_SEGMENTS).map_err(|m| (".d".to_string(), m))?;
    if !segs
        .iter()
        .any(|s| matches!(s, Seg::Line(..) | Seg::Cubic(..)))
    {
        return Err((".d".into(), "path data draws nothing".into()));
    }
    Ok(Path(segs))
}

/// SVG path data as absolute moves, lines and cubics, with at most `max_segs` segments.
///
/// svgtypes' `SimplifyingPathParser` is not used: it calls itself once for every command that
/// yields no segment (a repeated `Z`, an arc of zero sweep), so long runs of them overflow the
/// stack, and it splits arcs into as many cubics as the radius asks for. Here one loop handles
/// each command in constant time and an arc becomes at most four cubics.
fn simplify_path(d: &str, max_segs: usize) -> Result<Vec<Seg>, String> {
    use svgtypes::{PathParser, PathSegment as P};
    let mut segs: Vec<Seg> = Vec::new();
    let mut cur = (0.0, 0.0);
    let mut start = (0.0, 0.0);
    // Control points a following `S` or `T` reflects; `None` when the previous command was of
    // another kind.
    let mut last_cubic_ctrl: Option<(f64, f64)> = None;
    let mut last_quad_ctrl: Option<(f64, f64)> = None;
    for seg in PathParser::from(d) {
        let seg = seg.map_err(|e| format!("invalid SVG path data: {e}"))?;
        let closed = matches!(segs.last(), Some(Seg::Close));
        let first_new = segs.len();
        // A drawing command after `Z` starts a new subpath where the closed one began.
        if closed && !matches!(seg, P::MoveTo { .. } | P::ClosePath { .. }) {
            segs.push(Seg::Move(start.0, start.1));
        }
        let rel = |abs: bool, x: f64, y: f64| if abs { (x, y) } else { (cur.0 + x, cur.1 + y) };
        let (mut cubic_ctrl, mut quad_ctrl) = (None, None);
        match seg {
            P::MoveTo { abs, x, y } => {
                let p = rel(abs, x, y);
                segs.push(Seg::Move(p.0, p.1));
                start = p;
            }
            P::LineTo { abs, x, y } => {
                let p = rel(abs, x, y);
                segs.push(Seg::Line(p.0, p.1));
            }
            P::HorizontalLineTo { abs, x } => {
                let x = if abs { x } else { cur.0 + x };
                segs.push(Seg::Line(x, cur.1));
            }
            P::VerticalLineTo { abs, y } => {
                let y = if abs { y } else { cur.1 + y };
                segs.push(Seg::Line(cur.0, y));
            }
            P::CurveTo {
                abs,
                x1,
                y1,
                x2,
                y2,
                x,
                y,
            } => {
                let (c1, c2, p) = (rel(abs, x1, y1), rel(abs, x2, y2), rel(abs, x, y));
                segs.push(Seg::Cubic(c1.0, c1.1, c2.0, c2.1, p.0, p.1));
                cubic_ctrl = Some(c2);
            }
            P::SmoothCurveTo { abs, x2, y2, x, y } => {
                let c1 = reflect(last_cubic_ctrl, cur);
                let (c2, p) = (rel(abs, x2, y2), rel(abs, x, y));
                segs.push(Seg::Cubic(c1.0, c1.1, c2.0, c2.1, p.0, p.1));
                cubic_ctrl = Some(c2);
            }
            P::Quadratic { abs, x1, y1, x, y } => {
                let (c, p) = (rel(abs, x1, y1), rel(abs, x, y));
                segs.push(quadratic(cur, c, p));
                quad_ctrl = Some(c);
            }
            P::SmoothQuadratic { abs, x, y } => {
                let c = reflect(last_quad_ctrl, cur);
                let p = rel(abs, x, y);
                segs.push(quadratic(cur, c, p));
                quad_ctrl = Some(c);
            }
            P::EllipticalArc {
                abs,
                rx,
                ry,
                x_axis_rotation,
                large_arc,
                sweep,
                x,
                y,
            } => {
                let radius_ok = |r: f64| r.is_finite() && r.abs() <= MAX_ARC_RADIUS;
                if !(radius_ok(rx) && radius_ok(ry) && x_axis_rotation.is_finite()) {
                    return Err(format!(
                        "arc radii ({rx}, {ry}) and rotation {x_axis_rotation} must be finite, \
                         radii at most {MAX_ARC_RADIUS} cells"
                    ));
                }
                let p = rel(abs, x, y);
                // Before the arc arithmetic, which needs finite ends.
                check_point(p)?;
                arc(cur, rx, ry, x_axis_rotation, large_arc, sweep, p, &mut segs);
            }
            P::ClosePath { .. } => {
                // Repeated closes add nothing.
                if !closed {
                    segs.push(Seg::Close);
                }
            }
        }
        (last_cubic_ctrl, last_quad_ctrl) = (cubic_ctrl, quad_ctrl);
        for s in &segs[first_new..] {
            match *s {
                Seg::Move(x, y) | Seg::Line(x, y) => check_point((x, y))?,
                Seg::Cubic(a, b, c, d, x, y) => {
                    check_point((a, b))?;
                    check_point((c, d))?;
                    check_point((x, y))?;
                }
                Seg::Close => {}
            }
        }
        cur = match segs.last() {
            Some(Seg::Move(x, y) | Seg::Line(x, y) | Seg::Cubic(.., x, y)) => (*x, *y),
            Some(Seg::Close) => start,
            None => cur,
        };
        if segs.len() > max_segs {
            return Err(format!(
                "path data has over {max_segs} segments (arcs count as up to four), the limit"
            ));
        }
    }
    Ok(segs)
}

fn check_point((x, y): (f64, f64)) -> Result<(), String> {
    if x.is_finite() && y.is_finite() && x.abs() <= MAX_REACH && y.abs() <= MAX_REACH {
        Ok(())
    } else {
        Err(format!("point ({x}, {y}) is outside ±{MAX_REACH} cells"))
    }
}

/// The reflection of `ctrl` about `cur`, or `cur` when there is no control point to reflect.
fn reflect(ctrl: Option<(f64, f64)>, cur: (f64, f64)) -> (f64, f64) {
    ctrl.map_or(cur, |c| (2.0 * cur.0 - c.0, 2.0 * cur.1 - c.1))
}

/// A quadratic Bézier from `p0` as the same curve in cubic form (degree elevation).
fn quadratic(p0: (f64, f64), c: (f64, f64), p: (f64, f64)) -> Seg {
    let t = 2.0 / 3.0;
    Seg::Cubic(
        p0.0 + t * (c.0 - p0.0),
        p0.1 + t * (c.1 - p0.1),
        p.0 + t * (c.0 - p.0),
        p.1 + t * (c.1 - p.1),
        p.0,
        p.1,
    )
}

/// An SVG elliptical arc from `from` to `to` as at most four cubics (one per quarter turn or less),
/// following the endpoint-to-centre conversion of SVG 1.1, appendix F.6.
#[allow(clippy::too_many_arguments)]
fn arc(
    from: (f64, f64),
    rx: f64,
    ry: f64,
    rotation_deg: f64,
    large_arc: bool,
    sweep: bool,
    to: (f64, f64),
    segs: &mut Vec<Seg>,
) {
    use std::f64::consts::{FRAC_PI_2, TAU};
    if from == to {
        // SVG omits an arc that ends where it starts.
        return;
    }
    let (mut rx, mut ry) = (rx.abs(), ry.abs());
    if rx == 0.0 || ry == 0.0 {
        segs.push(Seg::Line(to.0, to.1));
        return;
    }
    let (sin, cos) = rotation_deg.to_radians().sin_cos();
    let (hx, hy) = ((from.0 - to.0) / 2.0, (from.1 - to.1) / 2.0);
    let (x1, y1) = (cos * hx + sin * hy, -sin * hx + cos * hy);
    // Radii too small to join the endpoints are scaled up until they just do.
    let lambda = (x1 / rx).powi(2) + (y1 / ry).powi(2);
    if lambda > 1.0 {
        rx *= lambda.sqrt();
        ry *= lambda.sqrt();
    }
    let (rx2, ry2) = (rx * rx, ry * ry);
    let num = rx2 * ry2 - rx2 * y1 * y1 - ry2 * x1 * x1;
    let den = rx2 * y1 * y1 + ry2 * x1 * x1;
    let sign = if large_arc == sweep { -1.0 } else { 1.0 };
    let coef = sign * (num / den).max(0.0).sqrt();
    let (cx1, cy1) = (coef * rx * y1 / ry, -coef * ry * x1 / rx);
    let (cx, cy) = (
        cos * cx1 - sin * cy1 + (from.0 + to.0) / 2.0,
        sin * cx1 + cos * cy1 + (from.1 + to.1) / 2.0,
    );
    let theta1 = ((y1 - cy1) / ry).atan2((x1 - cx1) / rx);
    let theta2 = ((-y1 - cy1) / ry).atan2((-x1 - cx1) / rx);
    let mut dtheta = theta2 - theta1;
    if sweep && dtheta < 0.0 {
        dtheta += TAU;
    } else if !sweep && dtheta > 0.0 {
        dtheta -= TAU;
    }
    if !dtheta.is_finite() {
        segs.push(Seg::Line(to.0, to.1));
        return;
    }
    let n = (dtheta.abs() / FRAC_PI_2).ceil().clamp(1.0, 4.0);
    let delta = dtheta / n;
    let k = 4.0 / 3.0 * (delta / 4.0).tan();
    let point = |t: f64| {
        let (s, c) = t.sin_cos();
        (
            cx + rx * cos * c - ry * sin * s,
            cy + rx * sin * c + ry * cos * s,
        )
    };
    let tangent = |t: f64| {
        let (s, c) = t.sin_cos();
        (-rx * cos * s - ry * sin * c, -rx * sin * s + ry * cos * c)
    };
    let n = n as usize;
    for i in 0..n {
        let (t1, t2) = (theta1 + i as f64 * delta, theta1 + (i + 1) as f64 * delta);
        let (p1, d1) = (point(t1), tangent(t1));
        let (d2, p2) = (tangent(t2), if i + 1 == n { to } else { point(t2) });
        segs.push(Seg::Cubic(
            p1.0 + k * d1.0,
            p1.1 + k * d1.1,
            p2.0 - k * d2.0,
            p2.1 - k * d2.1,
            p2.0,
            p2.1,
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, Instant};

    /// svgtypes reads decimals a few ulps of f32 off, so ends agree to 1e-7, not to the last bit.
    fn close(a: (f64, f64), b: (f64, f64)) -> bool {
        (a.0 - b.0).abs() < 1e-7 && (a.1 - b.1).abs() < 1e-7
    }

    fn end(s: &Seg) -> (f64, f64) {
        match *s {
            Seg::Move(x, y) | Seg::Line(x, y) | Seg::Cubic(.., x, y) => (x, y),
            Seg::Close => panic!("a close has no end point"),
        }
    }

    /// The segments svgtypes' own simplifier gives, with quadratics raised to cubics as
    /// [`simplify_path`] does.
    fn svgtypes_simplified(d: &str) -> Vec<Seg> {
        use svgtypes::{SimplePathSegment as S, SimplifyingPathParser};
        let mut out = Vec::new();
        let mut last = (0.0, 0.0);
        let mut start = (0.0, 0.0);
        for seg in SimplifyingPathParser::from(d) {
            let s = match seg.unwrap() {
                S::MoveTo { x, y } => {
                    start = (x, y);
                    Seg::Move(x, y)
                }
                S::LineTo { x, y } => Seg::Line(x, y),
                S::CurveTo {
                    x1,
                    y1,
                    x2,
                    y2,
                    x,
                    y,
                } => Seg::Cubic(x1, y1, x2, y2, x, y),
                S::Quadratic { x1, y1, x, y } => quadratic(last, (x1, y1), (x, y)),
                S::ClosePath => Seg::Close,
            };
            last = match s {
                Seg::Close => start,
                ref s => end(s),
            };
            out.push(s);
        }
        out
    }

    #[test]
    fn commands_other_than_arcs_read_as_svgtypes_reads_them() {
        for d in [
            "M 0 0 L 0.1 0.2 H 0.3 V -0.1 h 0.1 v 0.1 l -0.05 0.05 Z",
            "M0 0C.1 .1 .2 .1 .3 0S.4 -.2 .3 -.3s-.1 -.1 -.2 0c.1 .1 .1 .1 0 .2z",
            "M 0 0 Q 0.2 0.2 0.3 0 T 0.4 0.1 t 0.1 0 q 0.1 0.1 0.2 0 Z",
            "M 0 0 L 0.1 0 Z l 0.1 0.1 L 0 0.2 z m 0.1 0.1 l 0.1 0 Z Z M .2 .2 L .3 .3",
            "M 0 0 S 0.1 0.1 0.2 0 T 0.3 0.1 Q 0 0 0.1 0.1 S 0.1 0.2 0 0",
            "m 0.1 0.1 0.1 0 0 0.1 z",
        ] {
            let ours = simplify_path(d, MAX_PATH_SEGMENTS).unwrap();
            let theirs = svgtypes_simplified(d);
            assert_eq!(ours.len(), theirs.len(), "{d}: {ours:?} vs {theirs:?}");
            for (a, b) in ours.iter().zip(&theirs) {
                let same = match (*a, *b) {
                    (Seg::Cubic(a, b, c, d, x, y), Seg::Cubic(a2, b2, c2, d2, x2, y2)) => {
                        close((a, b), (a2, b2))
                            && close((c, d), (c2, d2))
                            && close((x, y), (x2, y2))
                    }
                    (Seg::Close, Seg::Close) => true,
                    (Seg::Move(..), Seg::Move(..)) | (Seg::Line(..), Seg::Line(..)) => {
                        close(end(a), end(b))
                    }
                    _ => false,
                };
                assert!(same, "{d}: {a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn arcs_become_at_most_four_cubics_on_the_ellipse() {
        // Half a circle of radius 0.4, clockwise on screen (y down): over the top.
        let segs = simplify_path("M -0.4 0 A 0.4 0.4 0 0 1 0.4 0", 100).unwrap();
        assert_eq!(segs.len(), 3, "{segs:?}");
        assert!(close(end(&segs[1]), (0.0, -0.4)), "{segs:?}");
        assert!(close(end(&segs[2]), (0.4, 0.0)), "{segs:?}");
        // The other sweep goes under; the large arc of a small chord is nearly a full turn.
        let segs = simplify_path("M -0.4 0 A 0.4 0.4 0 0 0 0.4 0", 100).unwrap();
        assert!(close(end(&segs[1]), (0.0, 0.4)), "{segs:?}");
        let segs = simplify_path("M 0 0 a 0.3 0.3 0 1 1 0.01 0", 100).unwrap();
        assert_eq!(segs.len(), 5, "{segs:?}");
        // Every curve point stays on the circle (cubic midpoints within 0.1 % of the radius).
        let c = (0.005, -(0.09f64 - 0.000025).sqrt());
        let mut from = (0.0, 0.0);
        for s in &segs[1..] {
            let Seg::Cubic(a, b, cx, cy, x, y) = *s else {
                panic!("{s:?}")
            };
            let mid = (
                (from.0 + 3.0 * a + 3.0 * cx + x) / 8.0,
                (from.1 + 3.0 * b + 3.0 * cy + y) / 8.0,
            );
            let r = (mid.0 - c.0).hypot(mid.1 - c.1);
            assert!((r - 0.3).abs() < 3e-4, "radius {r} at {mid:?}");
            from = (x, y);
        }
        // Radii too small to join the ends are scaled up; a zero radius is a line.
        let segs = simplify_path("M -0.4 0 A 0.01 0.01 0 0 1 0.4 0", 100).unwrap();
        assert!(close(end(&segs[1]), (0.0, -0.4)), "{segs:?}");
        let segs = simplify_path("M 0 0 A 0 0.3 0 0 1 0.4 0", 100).unwrap();
        assert_eq!(segs[1], Seg::Line(0.4, 0.0));
    }

    #[test]
    fn arcs_with_huge_radii_or_points_far_out_are_refused() {
        let err = simplify_path("M 0 0 A 1e300 1e300 0 1 1 0.1 0.1", 100).unwrap_err();
        assert!(err.contains("at most 1000 cells"), "{err}");
        // A large arc of radius 3 around a small chord reaches ±6.
        let err = simplify_path("M 0 0 A 3 3 0 1 1 0.1 0", 100).unwrap_err();
        assert!(err.contains("outside ±4 cells"), "{err}");
        let err = simplify_path("M 0 0 C 0 9 0 0 0.1 0", 100).unwrap_err();
        assert!(err.contains("(0, 9) is outside"), "{err}");
    }

    #[test]
    fn long_runs_of_commands_that_draw_nothing_neither_recurse_nor_slow_down() {
        // Without the byte limit: svgtypes' simplifier overflowed the stack on these.
        // The first arc draws (a move and four cubics), the others end where they start.
        for (d, n) in [
            (
                format!("M 0 0 {}", "A 0.2 0.2 0 1 1 0.1 0.1 ".repeat(26_000)),
                5,
            ),
            (format!("M 0 0 L 0.1 0.1 {}", "Z ".repeat(500_000)), 3),
        ] {
            let start = Instant::now();
            let segs = simplify_path(&d, usize::MAX).unwrap();
            assert_eq!(segs.len(), n, "{:?}", &segs[..n.min(segs.len())]);
            assert!(start.elapsed() < Duration::from_secs(2));
        }
        // Smooth cubics: linear time (this step never was the quadratic one; rendering was).
        let d = format!("M 0 0 {}", "S 0.3 0.2 0.1 0.1 ".repeat(200_000));
        let start = Instant::now();
        assert_eq!(simplify_path(&d, usize::MAX).unwrap().len(), 200_001);
        assert!(start.elapsed() < Duration::from_secs(2));
        // With the limit, reading stops at the first segment over it.
        let err = simplify_path(&d, MAX_PATH_SEGMENTS).unwrap_err();
        assert!(err.contains("over 512 segments"), "{err}");
    }
}
