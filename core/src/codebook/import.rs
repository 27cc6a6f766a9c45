//! Importing standard code tables (the JSON dumps in `shared/codebooks/`) into Tagsmith's
//! convention.
//!
//! **Tagsmith's convention is OpenCV's**: codes are read row-major from the top-left cell of the
//! grid, most significant bit first, 1 = white; a rendering of an ID equals OpenCV's
//! `generateImageMarker` cell for cell. The AprilTag library draws the same ID turned 180°
//! (its `tag36h11` ID k is OpenCV's `DICT_APRILTAG_36h11` ID k rotated by a half turn), so tables
//! in the AprilTag library's own layout (`bit_x`/`bit_y`) are turned 180° on import. The IDs are
//! the same either way; corner order and pose frame follow OpenCV's.

use serde::Deserialize;

/// A code table that cannot be imported; each names the table, bit or code that failed.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    #[error("not a JSON table: {0}")]
    NotJson(serde_json::Error),
    /// JSON, but not the fields of the table format it was read as.
    #[error("{0}")]
    Fields(serde_json::Error),
    #[error("neither an OpenCV dictionary (bits_per_side) nor an AprilTag 3 table (bit_x)")]
    UnknownFormat,
    #[error("{table}: bit_x/bit_y must list {nbits} cells")]
    BitCells { table: String, nbits: usize },
    #[error("{table}: implausible widths")]
    Widths { table: String },
    #[error("{table}: bit {bit} lies outside the {width}×{width} tag")]
    BitOutside {
        table: String,
        bit: usize,
        width: i64,
    },
    #[error("{table}: two bits share a cell")]
    SharedCell { table: String },
    #[error("{code:?} is not hexadecimal")]
    NotHex { code: String },
    #[error("{code:?} has more than {len} bits")]
    TooLong { code: String, len: usize },
    #[error("table {table} has {bits}-bit codes but this design has {code_len} code cells")]
    CodeLength {
        table: String,
        bits: usize,
        code_len: usize,
    },
}

/// A table dumped from OpenCV's predefined `cv2.aruco` dictionaries.
#[derive(Debug, Clone, Deserialize)]
pub struct OpenCvTable {
    pub name: String,
    #[serde(default)]
    pub source: String,
    pub bits_per_side: usize,
    pub codes: Vec<String>,
    #[serde(default)]
    pub min_hamming_distance_with_rotations: Option<u32>,
    #[serde(default)]
    pub opencv_max_correction_bits: Option<u32>,
}

impl OpenCvTable {
    pub fn parse(json: &str) -> Result<Self, ImportError> {
        serde_json::from_str(json).map_err(ImportError::Fields)
    }

    /// Codes as bits (row-major over the data cells, 1 = white).
    pub fn bits(&self) -> Result<Vec<Vec<u8>>, ImportError> {
        let len = self.bits_per_side * self.bits_per_side;
        self.codes.iter().map(|c| hex_bits(c, len)).collect()
    }
}

/// A family table of the AprilTag 3 library.
#[derive(Debug, Clone, Deserialize)]
pub struct AprilTag3Table {
    pub name: String,
    #[serde(default)]
    pub source: String,
    pub nbits: usize,
    pub h: u32,
    pub width_at_border: i64,
    pub total_width: i64,
    pub reversed_border: bool,
    /// Stored as unsigned 32-bit in the dump; negative offsets wrap.
    pub bit_x: Vec<u32>,
    pub bit_y: Vec<u32>,
    pub codes: Vec<String>,
}

/// An AprilTag 3 family in Tagsmith's grid form: a cell map and row-major codes.
#[derive(Debug, Clone, PartialEq)]
pub struct GridTable {
    /// `total_width` rows: `.` data, `b` black, `w` white, `-` not part of the tag.
    pub cells: Vec<String>,
    pub codes: Vec<Vec<u8>>,
    /// The `width_at_border` square (AprilTag's tag size) as (first cell, cells per side).
    pub border_square: (usize, usize),
}

impl AprilTag3Table {
    pub fn parse(json: &str) -> Result<Self, ImportError> {
        let t: Self = serde_json::from_str(json).map_err(ImportError::Fields)?;
        if t.bit_x.len() != t.nbits || t.bit_y.len() != t.nbits {
            return Err(ImportError::BitCells {
                table: t.name,
                nbits: t.nbits,
            });
        }
        if !(1..=32).contains(&t.total_width) || t.width_at_border > t.total_width {
            return Err(ImportError::Widths { table: t.name });
        }
        Ok(t)
    }

    /// Converts to Tagsmith's convention: the AprilTag layout turned 180°, codes read row-major.
    pub fn to_grid(&self) -> Result<GridTable, ImportError> {
        let w = self.total_width;
        let start = (w - self.width_at_border) / 2;
        let mut grid = vec![vec![b'-'; w as usize]; w as usize];
        let mut ring = |side: i64, colour: u8| {
            let s = (w - side) / 2;
            for i in 0..side {
                for (x, y) in [
                    (s + i, s),
                    (s + i, s + side - 1),
                    (s, s + i),
                    (s + side - 1, s + i),
                ] {
                    grid[y as usize][x as usize] = colour;
                }
            }
        };
        // AprilTag draws the white frame, then the black one, then the data bits over both.
        let (white, black) = if self.reversed_border {
            (self.width_at_border, self.width_at_border + 2)
        } else {
            (self.width_at_border + 2, self.width_at_border)
        };
        ring(white, b'w');
        ring(black, b'b');
        let cell_of_bit: Vec<(usize, usize)> = (0..self.nbits)
            .map(|i| {
                let (x, y) = (
                    self.bit_x[i] as i32 as i64 + start,
                    self.bit_y[i] as i32 as i64 + start,
                );
                if !(0..w).contains(&x) || !(0..w).contains(&y) {
                    return Err(ImportError::BitOutside {
                        table: self.name.clone(),
                        bit: i,
                        width: w,
                    });
                }
                // Half turn into OpenCV's orientation.
                Ok(((w - 1 - x) as usize, (w - 1 - y) as usize))
            })
            .collect::<Result<_, _>>()?;
        for &(x, y) in &cell_of_bit {
            grid[y][x] = b'.';
        }
        // Row-major code position of every data cell.
        let mut order: Vec<(usize, usize)> = cell_of_bit.clone();
        order.sort_by_key(|&(x, y)| (y, x));
        order.dedup();
        if order.len() != self.nbits {
            return Err(ImportError::SharedCell {
                table: self.name.clone(),
            });
        }
        let position =
            |cell: (usize, usize)| order.binary_search_by_key(&(cell.1, cell.0), |&(x, y)| (y, x));
        let codes = self
            .codes
            .iter()
            .map(|c| {
                let bits = hex_bits(c.trim_start_matches("0x"), self.nbits)?;
                let mut out = vec![0u8; self.nbits];
                for (i, &b) in bits.iter().enumerate() {
                    out[position(cell_of_bit[i]).expect("every bit's cell is in the order")] = b;
                }
                Ok(out)
            })
            .collect::<Result<_, ImportError>>()?;
        Ok(GridTable {
            cells: grid
                .into_iter()
                .map(|r| String::from_utf8(r).expect("ASCII"))
                .collect(),
            codes,
            border_square: (start as usize, self.width_at_border as usize),
        })
    }
}

/// The low `len` bits of a hex number, most significant first.
/// A standard table read for a design whose code has `code_len` binary symbols.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportedTable {
    pub name: String,
    pub source: String,
    pub codes: Vec<Vec<u8>>,
    pub min_distance: Option<u32>,
}

/// Reads either table format (OpenCV dictionary dump or AprilTag 3 family) and checks that its
/// codes fit a design with `code_len` binary code cells. The codes stay in Tagsmith's row-major
/// order, so they are only meaningful when the design's data cells sit where the table's do
/// (a square block of data cells, for OpenCV tables).
pub fn import_table(json: &str, code_len: usize) -> Result<ImportedTable, ImportError> {
    let value: serde_json::Value = serde_json::from_str(json).map_err(ImportError::NotJson)?;
    let table = if value.get("bits_per_side").is_some() {
        let t = OpenCvTable::parse(json)?;
        ImportedTable {
            codes: t.bits()?,
            min_distance: t.min_hamming_distance_with_rotations,
            source: format!("{} ({})", t.name, t.source),
            name: t.name,
        }
    } else if value.get("bit_x").is_some() {
        let t = AprilTag3Table::parse(json)?;
        ImportedTable {
            codes: t.to_grid()?.codes,
            min_distance: Some(t.h),
            source: format!(
                "{} ({}), turned 180° into OpenCV's convention",
                t.name, t.source
            ),
            name: t.name,
        }
    } else {
        return Err(ImportError::UnknownFormat);
    };
    let bits = table.codes.first().map_or(0, Vec::len);
    if bits != code_len {
        return Err(ImportError::CodeLength {
            table: table.name,
            bits,
            code_len,
        });
    }
    Ok(table)
}

fn hex_bits(text: &str, len: usize) -> Result<Vec<u8>, ImportError> {
    let mut bits = Vec::with_capacity(text.len() * 4);
    for c in text.chars() {
        let v = c
            .to_digit(16)
            .ok_or_else(|| ImportError::NotHex { code: text.into() })?;
        bits.extend((0..4).rev().map(|b| ((v >> b) & 1) as u8));
    }
    if bits.len() < len {
        let mut padded = vec![0; len - bits.len()];
        padded.extend(bits);
        return Ok(padded);
    }
    let extra = bits.len() - len;
    if bits[..extra].contains(&1) {
        return Err(ImportError::TooLong {
            code: text.into(),
            len,
        });
    }
    Ok(bits[extra..].to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(name: &str) -> String {
        let dir =
            std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/codebooks");
        std::fs::read_to_string(dir.join(name)).expect("the shared code tables")
    }

    #[test]
    fn both_table_formats_import_and_agree_on_36h11() {
        let opencv = import_table(&table("apriltag_36h11.json"), 36).unwrap();
        let april = import_table(&table("apriltag3/tag36h11.json"), 36).unwrap();
        assert_eq!(opencv.codes.len(), 587);
        assert_eq!(
            opencv.codes, april.codes,
            "AprilTag's table, turned, is OpenCV's"
        );
        assert_eq!(april.min_distance, Some(11));
    }

    #[test]
    fn a_table_that_does_not_fit_the_design_is_refused_by_name() {
        let e = import_table(&table("4x4_50.json"), 36).unwrap_err();
        assert!(
            matches!(
                &e,
                ImportError::CodeLength {
                    bits: 16,
                    code_len: 36,
                    ..
                }
            ),
            "{e}"
        );
        assert!(
            e.to_string().contains("16-bit codes") && e.to_string().contains("36 code cells"),
            "{e}"
        );
        let e = import_table("{\"codes\": []}", 36).unwrap_err();
        assert!(e.to_string().contains("neither"), "{e}");
        assert!(matches!(
            import_table("not json", 36),
            Err(ImportError::NotJson(_))
        ));
        let e = import_table(r#"{"name": "t", "bits_per_side": 2, "codes": ["1g"]}"#, 4);
        assert!(matches!(e, Err(ImportError::NotHex { code }) if code == "1g"));
    }
}
