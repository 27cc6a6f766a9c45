//! Constructors of the built-in family designs. `examples/build_families.rs` writes them to
//! `families/*.json`; the studio uses them as starting points for new designs.

use super::spec::*;
use crate::codebook::import::{AprilTag3Table, ImportError, OpenCvTable};
use crate::codebook::{generate, Codebook, GenerateError};
use crate::family::{Family, FamilyError};
use std::collections::BTreeMap;

/// A built-in design that cannot be built: its table, its codebook generation or the family it
/// makes.
#[derive(Debug, thiserror::Error)]
pub enum DesignError {
    #[error(transparent)]
    Import(#[from] ImportError),
    #[error(transparent)]
    Generate(#[from] GenerateError),
    #[error(transparent)]
    Family(#[from] FamilyError),
}

const BLACK: &str = "#000000";
const WHITE: &str = "#ffffff";

fn prim(shape: Shape, colour: &str) -> Primitive {
    Primitive {
        shape,
        fill: Some(colour.into()),
        stroke: None,
        stroke_width: None,
    }
}

fn full_cell(colour: &str) -> Primitive {
    prim(
        Shape::Square {
            size: 1.0,
            x: 0.0,
            y: 0.0,
        },
        colour,
    )
}

fn category(name: &str, role: Role, primitives: Vec<Primitive>) -> Category {
    Category {
        name: name.into(),
        role,
        primitives,
    }
}

/// Black cell = symbol 0, white cell (the background) = symbol 1: OpenCV's and AprilTag's bits.
fn black_white() -> Vec<Category> {
    vec![
        category("black", Role::Symbol(0), vec![full_cell(BLACK)]),
        category("white", Role::Symbol(1), vec![]),
    ]
}

/// An n×n grid with a one-cell frame of `frame` around (n−2)² code cells.
pub fn framed_cells(n: usize, frame: char) -> Vec<String> {
    (0..n)
        .map(|r| {
            (0..n)
                .map(|c| {
                    if r == 0 || c == 0 || r == n - 1 || c == n - 1 {
                        frame
                    } else {
                        '.'
                    }
                })
                .collect()
        })
        .collect()
}

fn square_roi(first: f64, side: f64) -> Roi {
    let (a, b) = (first, first + side);
    Roi {
        points: vec![[a, a], [b, a], [b, b], [a, b]],
        margin: 0.15,
    }
}

fn legend(pairs: &[(&str, &str)]) -> BTreeMap<String, String> {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn grid_spec(
    name: &str,
    title: &str,
    description: &str,
    source: &str,
    cells: Vec<String>,
    legend: BTreeMap<String, String>,
    categories: Vec<Category>,
    roi: Roi,
    codebook: CodebookSpec,
) -> FamilySpec {
    FamilySpec {
        format: FORMAT_VERSION,
        name: name.into(),
        title: title.into(),
        description: description.into(),
        source: source.into(),
        background: WHITE.into(),
        layout: Layout::Grid(GridLayout {
            size: cells.len() as u32,
            cells,
            legend,
            quiet_zone: 1.0,
        }),
        extra: vec![],
        categories,
        keypoint_set: KeypointSet::All,
        roi,
        codebook,
        print: PrintDefaults::default(),
    }
}

fn table_codebook(codes: &[Vec<u8>], min_distance: Option<u32>, source: &str) -> CodebookSpec {
    Codebook::from_codes(
        2,
        codes.first().map_or(0, |c| c.len()),
        codes.to_vec(),
        min_distance,
        None,
    )
    .to_spec(min_distance, source)
}

/// A family from an OpenCV dictionary dump (ArUco or OpenCV's AprilTag tables).
pub fn opencv_family(
    name: &str,
    title: &str,
    table: &OpenCvTable,
) -> Result<FamilySpec, DesignError> {
    let g = table.bits_per_side;
    let bits = table.bits()?;
    let source = format!(
        "Codes: {}. Rendered in OpenCV's convention (generateImageMarker, cell for cell).",
        table.source
    );
    Ok(grid_spec(
        name,
        title,
        &format!(
            "{g}×{g} data cells inside a one-cell black border; every cell centre is a keypoint."
        ),
        &source,
        framed_cells(g + 2, 'b'),
        legend(&[("b", "black")]),
        black_white(),
        square_roi(0.0, (g + 2) as f64),
        table_codebook(
            &bits,
            table.min_hamming_distance_with_rotations,
            &table.source,
        ),
    ))
}

/// A family from an AprilTag 3 table, turned 180° into OpenCV's convention (see
/// [`crate::codebook::import`]). Data cells may lie outside the black border.
pub fn apriltag3_family(
    name: &str,
    title: &str,
    table: &AprilTag3Table,
) -> Result<FamilySpec, DesignError> {
    let grid = table.to_grid()?;
    let (first, side) = grid.border_square;
    let mut roi = square_roi(first as f64, side as f64);
    if side < grid.cells.len() {
        roi.margin = OUTER_CELLS_MARGIN;
    }
    let source = format!(
        "Codes and layout: AprilTag 3 library, {} (BSD 2-clause), turned 180° into OpenCV's convention.",
        table.name
    );
    Ok(grid_spec(
        name,
        title,
        &format!(
            "AprilTag 3 layout: data cells inside and outside the border. The tag size (ROI) is \
             AprilTag's: the {side}-cell square where the black frame meets the white one."
        ),
        &source,
        grid.cells,
        legend(&[("b", "black"), ("w", "white")]),
        black_white(),
        roi,
        table_codebook(&grid.codes, Some(table.h), &source),
    ))
}

/// The template margin of a ROI with data cells outside it: stage 2's patch then holds the whole
/// drawing (41h12's 9 cells round a ROI of 5 span 0.72 of it).
const OUTER_CELLS_MARGIN: f64 = 0.3;

/// AprilTag 36h11 codes drawn with two shapes on a light background inside a black frame:
/// `zero` for bit 0 and `one` for bit 1 (DeepTag's AprilTag-XO / XA idea).
pub fn shaped_36h11(
    name: &str,
    title: &str,
    table: &OpenCvTable,
    zero: (&str, Vec<Primitive>),
    one: (&str, Vec<Primitive>),
) -> Result<FamilySpec, DesignError> {
    let mut spec = opencv_family(name, title, table)?;
    spec.description = format!(
        "AprilTag 36h11 codes, bit 0 drawn as {} and bit 1 as {} on a light background; the black \
         frame cells are a category of their own.",
        zero.0, one.0
    );
    spec.source = format!(
        "Design after DeepTag (Zhang et al., TPAMI 2023). {}",
        spec.source
    );
    spec.categories = vec![
        category("frame", Role::Fixed, vec![full_cell(BLACK)]),
        category(zero.0, Role::Symbol(0), zero.1),
        category(one.0, Role::Symbol(1), one.1),
    ];
    if let Layout::Grid(GridLayout { legend: l, .. }) = &mut spec.layout {
        *l = legend(&[("b", "frame")]);
    }
    Ok(spec)
}

pub fn cross() -> Vec<Primitive> {
    vec![prim(
        Shape::Cross {
            size: 0.72,
            width: 0.17,
            x: 0.0,
            y: 0.0,
        },
        BLACK,
    )]
}
pub fn ring() -> Vec<Primitive> {
    vec![prim(
        Shape::Ring {
            radius: 0.36,
            width: 0.13,
            x: 0.0,
            y: 0.0,
        },
        BLACK,
    )]
}
pub fn triangle() -> Vec<Primitive> {
    vec![prim(
        Shape::Triangle {
            size: 0.72,
            x: 0.0,
            y: 0.04,
        },
        BLACK,
    )]
}

/// A random square design for training stage 1 on markers no built-in family draws: an n × n
/// grid (n in 4..=9) inside a one-cell frame, bit 0 drawn as a black cell or one of the glyphs
/// above, bit 1 as white or another glyph, 64 random codes (no minimum distance: stage 1 only
/// has to find the marker). `pick(k)` is a random number below k.
pub fn random_square(index: usize, pick: &mut dyn FnMut(usize) -> usize) -> FamilySpec {
    let n = 4 + pick(6);
    let glyph = |k: usize| match k {
        0 => vec![full_cell(BLACK)],
        1 => cross(),
        2 => ring(),
        _ => triangle(),
    };
    let zero = pick(4);
    // White (no primitive) most of the time; otherwise a glyph other than bit 0's.
    let one = if pick(3) == 0 {
        Some((zero + 1 + pick(3)) % 4)
    } else {
        None
    };
    let categories = vec![
        category("frame", Role::Fixed, vec![full_cell(BLACK)]),
        category("zero", Role::Symbol(0), glyph(zero)),
        category("one", Role::Symbol(1), one.map(glyph).unwrap_or_default()),
    ];
    let bits = n * n;
    let codes: Vec<Vec<u8>> = (0..64)
        .map(|_| (0..bits).map(|_| pick(2) as u8).collect())
        .collect();
    grid_spec(
        &format!("random-square-{index}"),
        "Random square design",
        "A random design for training stage 1.",
        "Generated at random by Tagsmith.",
        framed_cells(n + 2, 'b'),
        legend(&[("b", "frame")]),
        categories,
        square_roi(0.0, (n + 2) as f64),
        Codebook::from_codes(2, bits, codes, None, None).to_spec(None, ""),
    )
}

/// Generates a codebook for a spec's layout and stores it in the spec.
pub fn fill_codebook(
    spec: &mut FamilySpec,
    min_distance: u32,
    max_codes: usize,
    seed: u64,
    start_with_zero: bool,
) -> Result<(), DesignError> {
    let family = Family::from_spec(spec.clone())?;
    let mut params = family.generate_params(min_distance);
    params.max_codes = max_codes;
    params.seed = seed;
    params.start_with_zero = start_with_zero;
    let report = generate(&params, &mut |_, _| {})?;
    spec.codebook = report.codebook.to_spec(
        report.achieved_min_distance,
        &format!(
            "Generated by Tagsmith's codebook generator (requested minimum distance {min_distance}, \
             seed {seed}, at most {max_codes} codes); min_distance is the achieved value."
        ),
    );
    Ok(())
}

/// A placeholder one-code codebook used while a layout is designed (all symbols 0).
fn provisional_codebook(q: usize, len: usize) -> CodebookSpec {
    Codebook::from_codes(q, len, vec![vec![0; len]], None, None).to_spec(None, "")
}

/// Four cell shapes as symbols 0–3 and a distinct orientation corner, so codes need no rotational
/// asymmetry (the all-zero code is ID 0).
pub fn quaternary_6x6() -> Result<FamilySpec, DesignError> {
    let mut cells = framed_cells(8, 'b');
    cells[0].replace_range(0..1, "o");
    let categories = vec![
        category("solid", Role::Symbol(0), vec![full_cell(BLACK)]),
        category("blank", Role::Symbol(1), vec![]),
        category(
            "dot",
            Role::Symbol(2),
            vec![prim(
                Shape::Dot {
                    radius: 0.3,
                    x: 0.0,
                    y: 0.0,
                },
                BLACK,
            )],
        ),
        category(
            "window",
            Role::Symbol(3),
            vec![
                full_cell(BLACK),
                prim(
                    Shape::Square {
                        size: 0.46,
                        x: 0.0,
                        y: 0.0,
                    },
                    WHITE,
                ),
            ],
        ),
        category(
            "orientation",
            Role::Fixed,
            vec![
                full_cell(BLACK),
                prim(
                    Shape::Triangle {
                        size: 0.62,
                        x: 0.0,
                        y: 0.04,
                    },
                    WHITE,
                ),
            ],
        ),
    ];
    let mut spec = grid_spec(
        "quaternary-6x6",
        "Quaternary 6×6",
        "36 quaternary cells (solid, blank, dot, window) in a black frame; the top-left frame cell \
         carries a white triangle that fixes the orientation, so every code is admissible, the \
         all-zero one included; that one (ID 0, every cell solid) prints but is not detected: a \
         dark square of clutter would read as it.",
        "Design after DeepTag's quaternary markers (Zhang et al., TPAMI 2023).",
        cells,
        legend(&[("b", "solid"), ("o", "orientation")]),
        categories,
        square_roi(0.0, 8.0),
        provisional_codebook(4, 36),
    );
    fill_codebook(&mut spec, 14, 1000, 1, true)?;
    Ok(spec)
}

fn runetag_layout() -> Layout {
    Layout::Rings(RingsLayout {
        radii: vec![2.0 / 3.0, 5.0 / 6.0, 1.0],
        slots: 43,
        dot_radius_ratio: 1.0 / 17.8,
        start_angle_deg: -90.0,
        quiet_zone: 0.2,
    })
}

/// RuneTag-like rings: 43 slots × 3 rings, dot = 1, no dot = 0, every slot a keypoint.
pub fn runetag() -> Result<FamilySpec, DesignError> {
    let mut spec = FamilySpec {
        format: FORMAT_VERSION,
        name: "runetag".into(),
        title: "RuneTag-style rings".into(),
        description: "Three concentric rings of 43 dot slots (radii 2/3, 5/6 and 1 of the outer ring, dot \
                      radius = ring radius / 17.8). A dot is a 1, an empty slot a 0; all 129 slots are \
                      keypoints, and any cyclic slot shift is a rotation. The tag size (ROI) is the side of \
                      the outer ring's bounding square, i.e. the outer ring's diameter through the dot centres."
            .into(),
        source: "Geometry after RuneTag (Bergamasco et al.) as used by DeepTag; codes generated by Tagsmith.".into(),
        background: WHITE.into(),
        layout: runetag_layout(),
        extra: vec![],
        categories: vec![
            category("empty", Role::Symbol(0), vec![]),
            category("dot", Role::Symbol(1), vec![prim(Shape::Dot { radius: 0.5, x: 0.0, y: 0.0 }, BLACK)]),
        ],
        keypoint_set: KeypointSet::All,
        roi: Roi {
            points: vec![[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]],
            margin: 0.15,
        },
        codebook: provisional_codebook(2, 129),
        print: PrintDefaults::default(),
    };
    fill_codebook(&mut spec, 32, 1000, 3, false)?;
    Ok(spec)
}

/// RuneTag plus four orientation dots at the corners of the ROI square; the bottom-right one is a
/// ring, which fixes the orientation.
pub fn runetag_plus(runetag: &FamilySpec) -> Result<FamilySpec, DesignError> {
    let mut spec = runetag.clone();
    spec.name = "runetag-plus".into();
    spec.title = "RuneTag+ (rings + orientation dots)".into();
    spec.description = "Three concentric rings of 43 dot slots as in runetag (a dot is a 1, an empty slot a 0; all \
                        129 slots are keypoints), plus four orientation marks of their own categories on the ROI \
                        corners: crosses, and a ring at the bottom-right. The marks fix the orientation, so no slot \
                        shift is a rotation of this layout. The tag size (ROI) is the side of the outer ring's \
                        bounding square."
        .into();
    // A cross, not a dot: at its own cell's scale a corner dot would look exactly like a slot dot,
    // and categories must be told apart by their look alone.
    spec.categories.push(category(
        "corner-cross",
        Role::Fixed,
        vec![prim(
            Shape::Cross {
                size: 1.0,
                width: 0.3,
                x: 0.0,
                y: 0.0,
            },
            BLACK,
        )],
    ));
    spec.categories.push(category(
        "corner-ring",
        Role::Fixed,
        vec![prim(
            Shape::Ring {
                radius: 0.5,
                width: 0.25,
                x: 0.0,
                y: 0.0,
            },
            BLACK,
        )],
    ));
    spec.extra = [
        (-1.0, -1.0, "corner-cross"),
        (1.0, -1.0, "corner-cross"),
        (1.0, 1.0, "corner-ring"),
        (-1.0, 1.0, "corner-cross"),
    ]
    .iter()
    .map(|&(x, y, c)| ExtraKeypoint {
        x,
        y,
        size: 0.2,
        category: c.into(),
    })
    .collect();
    // No rotation maps the corner dots onto themselves, so the distance is over the codes alone.
    let family = Family::from_spec(spec.clone())?;
    let d = family.codebook().min_distance(&[]);
    spec.codebook.min_distance = d;
    spec.codebook.source = format!("{} Same codes as runetag.", runetag.codebook.source);
    Ok(spec)
}

/// TopoTag-like: a black 9×9 square whose 16 vertex cells carry a white disc (0) or a white ring
/// (1); the other 65 cells are non-coding keypoints.
pub fn topotag_like() -> Result<FamilySpec, DesignError> {
    let cells: Vec<String> = (0..9)
        .map(|r| {
            (0..9)
                .map(|c| if r % 2 == 1 && c % 2 == 1 { '.' } else { 'g' })
                .collect()
        })
        .collect();
    let categories = vec![
        category("ground", Role::Fixed, vec![full_cell(BLACK)]),
        category(
            "disc",
            Role::Symbol(0),
            vec![
                full_cell(BLACK),
                prim(
                    Shape::Dot {
                        radius: 0.34,
                        x: 0.0,
                        y: 0.0,
                    },
                    WHITE,
                ),
            ],
        ),
        category(
            "ring",
            Role::Symbol(1),
            vec![
                full_cell(BLACK),
                prim(
                    Shape::Ring {
                        radius: 0.4,
                        width: 0.16,
                        x: 0.0,
                        y: 0.0,
                    },
                    WHITE,
                ),
            ],
        ),
    ];
    let mut spec = grid_spec(
        "topotag-like",
        "TopoTag-style",
        "A black square of 9×9 keypoints: 16 vertex cells carry a white disc (0) or ring (1), the \
         other 65 are non-coding ground keypoints (three categories in all).",
        "Design after TopoTag (Yu et al.) as read by DeepTag's 3-class keypoint grid; codes generated by Tagsmith.",
        cells,
        legend(&[("g", "ground")]),
        categories,
        square_roi(0.0, 9.0),
        provisional_codebook(2, 16),
    );
    fill_codebook(&mut spec, 5, 1000, 5, false)?;
    Ok(spec)
}
