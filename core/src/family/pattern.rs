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

pub fn parse_category(cat: &Category, path: &str) -> Result<CategoryPattern, Vec<Problem>> {
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

fn parse_svg_path(d: &str) -> Result<Path, FieldError> {
    use svgtypes::{SimplePathSegment as S, SimplifyingPathParser};
    let err = |m: String| (".d".to_string(), m);
    let mut segs = Vec::new();
    let mut last = (0.0, 0.0);
    for seg in SimplifyingPathParser::from(d) {
        let seg = seg.map_err(|e| err(format!("invalid SVG path data: {e}")))?;
        let s = match seg {
            S::MoveTo { x, y } => Seg::Move(x, y),
            S::LineTo { x, y } => Seg::Line(x, y),
            S::CurveTo {
                x1,
                y1,
                x2,
                y2,
                x,
                y,
            } => Seg::Cubic(x1, y1, x2, y2, x, y),
            S::Quadratic { x1, y1, x, y } => {
                // Degree elevation: the same curve as a cubic.
                let (c1x, c1y) = (
                    last.0 + 2.0 / 3.0 * (x1 - last.0),
                    last.1 + 2.0 / 3.0 * (y1 - last.1),
                );
                let (c2x, c2y) = (x + 2.0 / 3.0 * (x1 - x), y + 2.0 / 3.0 * (y1 - y));
                Seg::Cubic(c1x, c1y, c2x, c2y, x, y)
            }
            S::ClosePath => Seg::Close,
        };
        if let Seg::Move(x, y) | Seg::Line(x, y) | Seg::Cubic(.., x, y) = s {
            if !(x.is_finite() && y.is_finite() && x.abs() <= MAX_REACH && y.abs() <= MAX_REACH) {
                return Err(err(format!(
                    "point ({x}, {y}) is outside ±{MAX_REACH} cells"
                )));
            }
            last = (x, y);
        }
        segs.push(s);
    }
    if !segs
        .iter()
        .any(|s| matches!(s, Seg::Line(..) | Seg::Cubic(..)))
    {
        return Err(err("path data draws nothing".into()));
    }
    Ok(Path(segs))
}
