//! The family file format (`"format": 1`): plain serde types, exactly what a family JSON file holds.
//!
//! Nothing here is validated; [`super::Family::from_spec`] checks a spec and derives the keypoints,
//! rotations and packed codebook from it. The JSON Schema in `families/schema.json` is generated from
//! these types.

pub use crate::codebook::spec::{CodeEncoding, CodebookSpec};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The only file format version this build reads and writes.
pub const FORMAT_VERSION: u32 = 1;

/// A marker family: layout, pattern categories, ROI, codebook and print defaults.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FamilySpec {
    /// File format version; must be 1.
    pub format: u32,
    /// Short unique name (letters, digits, `-`, `_`, `.`), used on the command line and in labels.
    pub name: String,
    /// Human-readable title, e.g. "AprilTag 36h11".
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub title: String,
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    /// Where the design and the codes come from, with their licence.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub source: String,
    /// Colour of the marker's own area (quiet zone included) behind every pattern, `#rrggbb`.
    #[serde(default = "default_background")]
    pub background: String,
    pub layout: Layout,
    /// Keypoints at explicit positions, in addition to the layout's (e.g. orientation dots).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub extra: Vec<ExtraKeypoint>,
    /// The local patterns. Category index = position in this list = the detector's class.
    pub categories: Vec<Category>,
    /// Which keypoints the detector regresses.
    #[serde(default)]
    pub keypoint_set: KeypointSet,
    pub roi: Roi,
    pub codebook: CodebookSpec,
    #[serde(default)]
    pub print: PrintDefaults,
}

fn default_background() -> String {
    "#ffffff".to_string()
}

/// Where the keypoints are. Positions are in *marker units*: cells for `grid` (origin at the grid's
/// top-left corner, y down), outer-ring radii for `rings` (origin at the centre, y down).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Layout {
    Grid(GridLayout),
    Rings(RingsLayout),
}

/// N×N square cells; every cell centre that is not `-` is a keypoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GridLayout {
    /// Cells per side (1–32).
    pub size: u32,
    /// One string per row, one character per cell: `.` = a code symbol (row-major code order),
    /// `-` = no keypoint (nothing drawn), any other character = the fixed category named in
    /// `legend`.
    pub cells: Vec<String>,
    /// Character → category name for fixed cells.
    #[serde(default)]
    pub legend: BTreeMap<String, String>,
    /// White margin around the grid, in cells.
    #[serde(default = "default_quiet_zone")]
    pub quiet_zone: f64,
}

/// Concentric rings of dot slots (RuneTag-like). Every slot is a code symbol keypoint; code order
/// is slot-major (keypoint k = slot × rings + ring, inner ring first), slots clockwise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RingsLayout {
    /// Ring radii in outer-ring units, inner first; the largest should be 1.
    pub radii: Vec<f64>,
    /// Slots per ring (the same on every ring, so that a cyclic slot shift is a rotation).
    pub slots: u32,
    /// Dot radius as a fraction of its ring's radius (RuneTag: 1/17.8).
    pub dot_radius_ratio: f64,
    /// Angle of slot 0, degrees clockwise from +x (y down): -90 = top.
    #[serde(default = "default_start_angle")]
    pub start_angle_deg: f64,
    /// Margin around the outermost dots, in outer-ring radii.
    #[serde(default = "default_ring_quiet_zone")]
    pub quiet_zone: f64,
}

fn default_quiet_zone() -> f64 {
    1.0
}
fn default_ring_quiet_zone() -> f64 {
    0.2
}
fn default_start_angle() -> f64 {
    -90.0
}

/// A keypoint at an explicit position.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ExtraKeypoint {
    /// Position in marker units.
    pub x: f64,
    pub y: f64,
    /// Side of the keypoint's cell in marker units (its category's patterns are drawn in it).
    pub size: f64,
    /// A category name (fixed keypoint), or `"."` for a code symbol after the layout's symbols.
    pub category: String,
}

/// A pattern category: a named local pattern drawn in a keypoint's cell.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Category {
    pub name: String,
    pub role: Role,
    /// Drawn in order, in cell-local coordinates: the cell is the square [-0.5, 0.5]² centred on
    /// the keypoint (y down), scaled by the keypoint's cell size.
    #[serde(default)]
    pub primitives: Vec<Primitive>,
}

/// What a category means to the codebook.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// Carries the code symbol with this value (0 ≤ k < number of symbol categories).
    Symbol(u8),
    /// Carries no symbol (border, orientation, non-coding).
    Fixed,
}

/// A vector primitive in cell-local coordinates.
// No `deny_unknown_fields` here: serde cannot combine it with `flatten`. The shape variants deny
// unknown fields instead, which catches the same typos.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Primitive {
    #[serde(flatten)]
    pub shape: Shape,
    /// Fill colour `#rrggbb`; none = not filled.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fill: Option<String>,
    /// Stroke colour `#rrggbb`; none = not stroked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stroke: Option<String>,
    /// Stroke width in cell units.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stroke_width: Option<f64>,
}

/// Primitive shapes. All are centred on (`x`, `y`) (default: the cell centre).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "shape", rename_all = "snake_case", deny_unknown_fields)]
pub enum Shape {
    /// Axis-aligned square of side `size` (1 = the whole cell).
    Square {
        size: f64,
        #[serde(default)]
        x: f64,
        #[serde(default)]
        y: f64,
    },
    /// Filled disc of radius `radius`.
    Dot {
        radius: f64,
        #[serde(default)]
        x: f64,
        #[serde(default)]
        y: f64,
    },
    /// Annulus ("O"): outer radius `radius`, ring thickness `width`.
    Ring {
        radius: f64,
        width: f64,
        #[serde(default)]
        x: f64,
        #[serde(default)]
        y: f64,
    },
    /// Two diagonal bars ("X") spanning a `size` square, bar thickness `width`.
    Cross {
        size: f64,
        width: f64,
        #[serde(default)]
        x: f64,
        #[serde(default)]
        y: f64,
    },
    /// Upward isosceles triangle ("A") in a `size` square.
    Triangle {
        size: f64,
        #[serde(default)]
        x: f64,
        #[serde(default)]
        y: f64,
    },
    /// Rectangle `width` × `height` rotated by `angle_deg` clockwise.
    Bar {
        width: f64,
        height: f64,
        #[serde(default)]
        angle_deg: f64,
        #[serde(default)]
        x: f64,
        #[serde(default)]
        y: f64,
    },
    /// SVG path data in cell-local coordinates (absolute or relative commands).
    Path { d: String },
}

/// Which keypoints the detector regresses.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum KeypointSet {
    /// Every keypoint.
    #[default]
    All,
    /// Keypoints on the outer boundary (grid: first/last row and column; rings: the outer ring).
    Boundary,
    /// The four corner cells of a grid.
    Corners,
    /// Explicit keypoint indices (layout keypoints in order, then extras).
    Custom(Vec<u32>),
}

/// The rectifying ROI.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Roi {
    /// ≥ 4 points in marker units; the first four are the template square's corners in order
    /// TL, TR, BR, BL (clockwise, y down). The distance from point 0 to point 1 is the marker size.
    pub points: Vec<[f64; 2]>,
    /// Template margin a: the ROI maps to ((a,a), (1−a,a), (1−a,1−a), (a,1−a)) in the patch.
    #[serde(default = "default_margin")]
    pub margin: f64,
}

fn default_margin() -> f64 {
    0.15
}

/// Defaults for printing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PrintDefaults {
    /// Marker size in mm: the distance between ROI points 0 and 1 (for square tags the side of the
    /// outer black square, corner to corner).
    #[serde(default = "default_side")]
    pub marker_side_mm: f64,
    /// Print the family and ID under each marker.
    #[serde(default = "default_true")]
    pub labels: bool,
}

fn default_side() -> f64 {
    40.0
}
fn default_true() -> bool {
    true
}

impl Default for PrintDefaults {
    fn default() -> Self {
        Self {
            marker_side_mm: default_side(),
            labels: true,
        }
    }
}
