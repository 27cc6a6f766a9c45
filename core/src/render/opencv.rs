//! Export of binary grid families to OpenCV's ArUco dictionary file (`cv2.aruco.Dictionary`
//! `readDictionary` / `aruco::Dictionary::readDictionary`), so that a printed family can be
//! detected with OpenCV as well.

use super::readback::Reader;
use crate::family::{Assignment, Family};
use std::fmt::Write;

/// A family that OpenCV's ArUco detector cannot read, and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{family} cannot be read by OpenCV's ArUco detector: {reason}")]
pub struct OpenCvError {
    pub family: String,
    pub reason: Unreadable,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Unreadable {
    #[error("it is not a grid family")]
    NotAGrid,
    #[error("it has {q} symbols; OpenCV reads binary cells")]
    Symbols { q: usize },
    #[error("its two symbols are not a dark and a light cell")]
    NotDarkAndLight,
    #[error(
        "OpenCV needs a one-cell dark border around {inner}×{inner} data cells; the cell at \
         column {column}, row {row} does not fit that"
    )]
    Cell { inner: usize, column: f64, row: f64 },
    #[error("the grid has cells without keypoints or extra keypoints")]
    Keypoints,
}

/// The YAML text of an OpenCV dictionary: `nmarkers`, `markersize`, `maxCorrectionBits` and one
/// `marker_i` string of `markersize²` bits (row-major, 1 = white) per ID.
///
/// OpenCV reads black and white cells inside a one-cell black border, so the family must be a
/// grid of that shape whose two symbols are a dark and a light cell.
pub fn dictionary_yaml(family: &Family) -> Result<String, OpenCvError> {
    let not_readable = |reason: Unreadable| OpenCvError {
        family: family.name().into(),
        reason,
    };
    if !family.is_grid() {
        return Err(not_readable(Unreadable::NotAGrid));
    }
    if family.q() != 2 {
        return Err(not_readable(Unreadable::Symbols { q: family.q() }));
    }
    let reader = Reader::new(family);
    let dark = |cat: usize| reader.mean_gray(cat) < 96.0;
    let light = |cat: usize| reader.mean_gray(cat) > 160.0;
    let (s0, s1) = (family.symbol_category(0), family.symbol_category(1));
    let one_is_white = match (dark(s0) && light(s1), light(s0) && dark(s1)) {
        (true, _) => true,
        (_, true) => false,
        _ => return Err(not_readable(Unreadable::NotDarkAndLight)),
    };
    let n = (family.extent().width().round() as usize).max(1);
    let inner = n.saturating_sub(2);
    let kps = family.keypoints();
    for k in kps {
        let (x, y) = (k.pos[0] - 0.5, k.pos[1] - 0.5);
        let on_border = x < 0.5 || y < 0.5 || x > n as f64 - 1.5 || y > n as f64 - 1.5;
        let ok = match k.assignment {
            Assignment::Fixed(c) => on_border && dark(c),
            Assignment::Symbol(_) => !on_border,
        };
        if !ok || k.size != 1.0 {
            return Err(not_readable(Unreadable::Cell {
                inner,
                column: x,
                row: y,
            }));
        }
    }
    if kps.len() != n * n || family.code_len() != inner * inner {
        return Err(not_readable(Unreadable::Keypoints));
    }
    let mut out = String::from("%YAML:1.0\n---\n");
    let cb = family.codebook();
    let _ = writeln!(out, "nmarkers: {}", cb.len());
    let _ = writeln!(out, "markersize: {inner}");
    let _ = writeln!(out, "maxCorrectionBits: {}", cb.max_correction());
    for (id, code) in cb.codes().iter().enumerate() {
        let bits: String = code
            .iter()
            .map(|&s| if (s == 1) == one_is_white { '1' } else { '0' })
            .collect();
        let _ = writeln!(out, "marker_{id}: \"{bits}\"");
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unreadable_families_say_why() {
        let family = |name: &str| crate::builtin::get(name).unwrap().unwrap();
        assert!(dictionary_yaml(&family("apriltag-36h11")).is_ok());
        let e = dictionary_yaml(&family("runetag")).unwrap_err();
        assert_eq!(e.reason, Unreadable::NotAGrid);
        assert_eq!(
            e.to_string(),
            "runetag cannot be read by OpenCV's ArUco detector: it is not a grid family"
        );
        let e = dictionary_yaml(&family("quaternary-6x6")).unwrap_err();
        assert_eq!(e.reason, Unreadable::Symbols { q: 4 });
    }
}
