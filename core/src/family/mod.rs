//! Marker families: the file format ([`spec`]), loading with validation ([`load`]), and the
//! validated [`Family`] with everything derived from a spec — keypoints in canonical order, the
//! rotations the layout admits, and the parsed codebook.

mod decode;
pub mod designs;
pub mod edit;
mod error;
mod geometry;
mod load;
pub mod pattern;
pub mod spec;
mod validate;

pub use decode::{decode, decode_soft, Decoded};
pub use error::{FamilyError, Problem};
pub use geometry::{Extent, Keypoint, Rotation};
pub use load::{from_json_str, load_file, schema_json, to_json_string};
pub use spec::FamilySpec;
pub use validate::{name_problem, MAX_MARKER_SIDE_MM, MIN_MARKER_SIDE_MM};

use crate::codebook::{Codebook, GenerateParams};
use crate::color::Rgb;
use crate::family::pattern::CategoryPattern;

/// What a keypoint carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Assignment {
    /// Always drawn with this category (border, orientation, non-coding).
    Fixed(usize),
    /// Carries code symbol number `n` (position in the code).
    Symbol(usize),
}

/// A validated family, ready to render, print and decode.
#[derive(Debug, Clone)]
pub struct Family {
    spec: FamilySpec,
    background: Rgb,
    categories: Vec<CategoryPattern>,
    /// Symbol value → category index.
    symbol_categories: Vec<usize>,
    keypoints: Vec<Keypoint>,
    /// Code position → keypoint index.
    code_keypoints: Vec<usize>,
    /// Geometric symmetries of the keypoint layout; index 0 is the identity.
    rotations: Vec<Rotation>,
    extent: Extent,
    quiet_zone: f64,
    codebook: Codebook,
}

impl Family {
    /// Validates a spec and derives the family; every problem found is reported, each with its
    /// JSON path.
    pub fn from_spec(spec: FamilySpec) -> Result<Self, FamilyError> {
        validate::build(spec)
    }

    pub fn spec(&self) -> &FamilySpec {
        &self.spec
    }
    pub fn name(&self) -> &str {
        &self.spec.name
    }
    /// The title, or the name when the family has none.
    pub fn title(&self) -> &str {
        if self.spec.title.is_empty() {
            &self.spec.name
        } else {
            &self.spec.title
        }
    }
    pub fn background(&self) -> Rgb {
        self.background
    }
    pub fn categories(&self) -> &[CategoryPattern] {
        &self.categories
    }
    /// Number of symbol categories (the codebook's alphabet size).
    pub fn q(&self) -> usize {
        self.symbol_categories.len()
    }
    /// The category that draws symbol value `s`.
    pub fn symbol_category(&self, symbol: u8) -> usize {
        self.symbol_categories[symbol as usize]
    }
    /// The symbol value a category stands for, if it is a symbol category.
    pub fn category_symbol(&self, category: usize) -> Option<u8> {
        match self.spec.categories.get(category)?.role {
            spec::Role::Symbol(s) => Some(s),
            spec::Role::Fixed => None,
        }
    }
    pub fn keypoints(&self) -> &[Keypoint] {
        &self.keypoints
    }
    pub fn code_len(&self) -> usize {
        self.code_keypoints.len()
    }
    /// Keypoint index of each code position.
    pub fn code_keypoints(&self) -> &[usize] {
        &self.code_keypoints
    }
    pub fn rotations(&self) -> &[Rotation] {
        &self.rotations
    }
    /// Rotations under which the fixed pattern looks the same, so only the code tells them apart
    /// (identity excluded): the codebook's minimum distance is taken over these.
    pub fn ambiguous_rotations(&self) -> impl Iterator<Item = &Rotation> {
        self.rotations
            .iter()
            .skip(1)
            .filter(|r| r.code_perm.is_some() && r.preserves_fixed)
    }
    pub fn codebook(&self) -> &Codebook {
        &self.codebook
    }
    /// The marker's drawn area in marker units, quiet zone excluded.
    pub fn extent(&self) -> Extent {
        self.extent
    }
    /// White margin around the extent, in marker units.
    pub fn quiet_zone(&self) -> f64 {
        self.quiet_zone
    }
    /// ROI points in marker units.
    pub fn roi_points(&self) -> &[[f64; 2]] {
        &self.spec.roi.points
    }
    /// The marker size in marker units: the distance between ROI points 0 and 1.
    pub fn roi_side(&self) -> f64 {
        let [a, b] = [self.spec.roi.points[0], self.spec.roi.points[1]];
        (b[0] - a[0]).hypot(b[1] - a[1])
    }
    /// The distance between the two closest keypoints, in marker units (a grid's cell pitch).
    pub fn keypoint_pitch(&self) -> f64 {
        let kps = &self.keypoints;
        kps.iter()
            .enumerate()
            .flat_map(|(i, a)| {
                kps[i + 1..]
                    .iter()
                    .map(move |b| (a.pos[0] - b.pos[0]).hypot(a.pos[1] - b.pos[1]))
            })
            .fold(f64::INFINITY, f64::min)
    }
    /// The size of one cell in marker units (grids: 1; otherwise the largest keypoint cell).
    pub fn cell_size(&self) -> f64 {
        self.keypoints.iter().map(|k| k.size).fold(0.0, f64::max)
    }
    /// Whether a quiet zone (marker units) is thinner than one cell: detectors need a light
    /// margin at least that wide.
    pub fn quiet_zone_is_thin(&self, quiet_zone: f64) -> bool {
        quiet_zone < self.cell_size() - 1e-9
    }

    pub fn is_grid(&self) -> bool {
        matches!(self.spec.layout, spec::Layout::Grid(_))
    }

    /// A ring layout whose every slot shift is a rotation (RuneTag): nothing but its code tells
    /// one turn of it from another, so a ring search may give its ROI at any turn.
    pub fn is_cyclic_ring(&self) -> bool {
        !self.is_grid() && self.rotations().len() > 1
    }

    /// A ring layout with one rotation (RuneTag+): its orientation marks on the ROI's corners
    /// fix its turn only up to which mark comes first.
    pub fn is_ring_turned_by_marks(&self) -> bool {
        !self.is_grid() && self.rotations().len() == 1
    }

    /// The category drawn at every keypoint for code `id`.
    pub fn keypoint_categories(&self, id: usize) -> Option<Vec<usize>> {
        let code = self.codebook.code(id)?;
        Some(
            self.keypoints
                .iter()
                .map(|k| match k.assignment {
                    Assignment::Fixed(c) => c,
                    Assignment::Symbol(n) => self.symbol_categories[code[n] as usize],
                })
                .collect(),
        )
    }

    /// Indices of the keypoints the detector regresses.
    pub fn regressed_keypoints(&self) -> Vec<usize> {
        geometry::regressed_keypoints(self)
    }

    /// Codebook generation parameters for this layout: its code length, alphabet and rotations.
    pub fn generate_params(&self, min_distance: u32) -> GenerateParams {
        let mut p = GenerateParams::new(self.q(), self.code_len(), min_distance);
        p.rotations = self
            .ambiguous_rotations()
            .filter_map(|r| r.code_perm.clone())
            .collect();
        p.symmetry_rotations = self
            .rotations()
            .iter()
            .skip(1)
            .filter_map(|r| r.code_perm.clone())
            .collect();
        p
    }

    /// Non-fatal remarks about the design that the model alone can tell (printing and decoding
    /// risks); `render::readback::warnings` adds those that need the rendering.
    pub fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        if self.quiet_zone_is_thin(self.quiet_zone) {
            out.push(format!(
                "{}: the quiet zone ({:.2} units) is thinner than one cell ({:.2}); detectors need a \
                 light margin around the marker",
                self.name(),
                self.quiet_zone,
                self.cell_size()
            ));
        }
        if let Some(d) = self.spec.codebook.min_distance {
            let limit = self.codebook.max_correction() as u32;
            if d > 0 && 2 * limit >= d {
                out.push(format!(
                    "{}: correcting {limit} errors with a minimum distance of {d} can decode a \
                     marker as the wrong ID (safe limit: {})",
                    self.name(),
                    (d - 1) / 2
                ));
            }
        }
        out
    }
}

/// Marker-unit points (y down) → metric marker-plane points (x right, y up, origin at the ROI
/// square's centre), for a marker printed `side_m` metres corner to corner.
pub fn marker_plane_points(family: &Family, side_m: f64, points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let roi = &family.roi_points()[..4];
    let c = roi
        .iter()
        .fold([0.0, 0.0], |a, p| [a[0] + p[0] / 4.0, a[1] + p[1] / 4.0]);
    let s = side_m / family.roi_side();
    points
        .iter()
        .map(|p| [(p[0] - c[0]) * s, -(p[1] - c[1]) * s])
        .collect()
}
