//! Sorting found keypoints to the family's template: the template is placed by the template
//! head's corners, then refined by a homography fitted to its own matches, so the sort survives
//! ROI errors larger than a cell (a quad with a_i up to 0.25 moves corners by 13 px in a 128 px
//! patch; a cell is 11 px there).

use super::anchors::Found;
use crate::family::{Assignment, Family};
use crate::geometry::{squared_distance, Homography, Quad};

/// Found keypoints in template order.
#[derive(Debug, Clone)]
pub struct Sorted {
    /// Per family keypoint (in the order the marker is seen, before decoding its rotation): the
    /// index of the found keypoint matched to it.
    pub slots: Vec<Option<usize>>,
    /// Marker units (as seen) → patch pixels, fitted to the matches.
    pub to_patch: Homography,
}

impl Sorted {
    pub fn matched(&self) -> usize {
        self.slots.iter().flatten().count()
    }
}

/// Refinement rounds of match → fit; the count stops growing after two or three.
const ROUNDS: usize = 4;

/// Places the template by `corners` (where the family's 4 ROI points are in the patch, in the
/// patch's TL, TR, BR, BL order), then matches each regressed keypoint to the nearest unused
/// found keypoint within half its cell pitch. None when fewer than 4 match.
pub fn sort_to_template(family: &Family, found: &[Found], corners: &Quad) -> Option<Sorted> {
    let roi = &family.roi_points()[..4];
    let mut h = Homography::from_points(roi, &corners[..]).ok()?;
    let regressed = family.regressed_keypoints();
    let kps = family.keypoints();
    let mut best: Option<Sorted> = None;
    for _ in 0..ROUNDS {
        let slots = match_once(family, &regressed, found, &h);
        let count = slots.iter().flatten().count();
        if count < 4 || best.as_ref().is_some_and(|b| b.matched() >= count) {
            break;
        }
        let (src, dst): (Vec<[f64; 2]>, Vec<[f64; 2]>) = slots
            .iter()
            .enumerate()
            .filter_map(|(k, s)| s.map(|f| (kps[k].pos, found[f].pos)))
            .unzip();
        let fitted = Homography::from_points(&src, &dst).ok()?;
        best = Some(Sorted {
            slots,
            to_patch: fitted,
        });
        h = fitted;
    }
    best
}

fn match_once(
    family: &Family,
    regressed: &[usize],
    found: &[Found],
    h: &Homography,
) -> Vec<Option<usize>> {
    let kps = family.keypoints();
    // Pairs by squared distance: only compared, and this runs for every keypoint against every
    // point found, several times per patch.
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for &k in regressed {
        let p = h.apply(kps[k].pos);
        let q = h.apply([kps[k].pos[0] + kps[k].size, kps[k].pos[1]]);
        let radius_squared = 0.25 * squared_distance(q, p);
        for (f, kp) in found.iter().enumerate() {
            let d = squared_distance(kp.pos, p);
            if d < radius_squared {
                pairs.push((d, k, f));
            }
        }
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut slots = vec![None; kps.len()];
    let mut taken = vec![false; found.len()];
    for (_, k, f) in pairs {
        if slots[k].is_none() && !taken[f] {
            slots[k] = Some(f);
            taken[f] = true;
        }
    }
    slots
}

/// The categories that can appear at each template slot whichever way the marker is turned: a
/// fixed keypoint's own category, or any symbol category at a symbol keypoint (the union over
/// the layout's rotations). On a square grid the frame is the same under every turn, so a frame
/// slot admits only the frame's category and a data slot only symbols.
pub fn slot_categories(family: &Family) -> Vec<Vec<usize>> {
    let kps = family.keypoints();
    let symbols: Vec<usize> = (0..family.q())
        .map(|s| family.symbol_category(s as u8))
        .collect();
    let mut slots = vec![Vec::new(); kps.len()];
    for rotation in family.rotations() {
        for (i, &slot) in rotation.keypoint_perm.iter().enumerate() {
            let allowed = match kps[i].assignment {
                Assignment::Fixed(c) => std::slice::from_ref(&c).to_vec(),
                Assignment::Symbol(_) => symbols.clone(),
            };
            for c in allowed {
                if !slots[slot].contains(&c) {
                    slots[slot].push(c);
                }
            }
        }
    }
    slots
}

/// The category read at every family keypoint (None where nothing matched), for
/// [`crate::family::decode`]: the most voted category among those the slot admits, so a data
/// cell is read as the more likely of the symbols even when the network finds it closer to the
/// frame's look.
pub fn observed(family: &Family, sorted: &Sorted, found: &[Found]) -> Vec<Option<usize>> {
    read_slots(family, sorted, found).0
}

/// [`observed`] and, per slot, the read category's share of the votes of the categories the slot
/// admits (0 where nothing matched): the reliability [`crate::family::decode_soft`] erases by.
pub fn read_slots(
    family: &Family,
    sorted: &Sorted,
    found: &[Found],
) -> (Vec<Option<usize>>, Vec<f64>) {
    let admitted = slot_categories(family);
    let absent = absent_category(family);
    sorted
        .slots
        .iter()
        .zip(&admitted)
        .map(|(s, allowed)| {
            let Some(f) = *s else {
                return match absent.filter(|c| allowed.contains(c)) {
                    Some(c) => (Some(c), ABSENT_RELIABILITY),
                    None => (None, 0.0),
                };
            };
            let votes = &found[f].votes;
            let Some(best) = allowed
                .iter()
                .copied()
                .max_by(|&a, &b| votes[a].total_cmp(&votes[b]))
            else {
                return (Some(found[f].category), 0.0);
            };
            let total: f64 = allowed.iter().map(|&c| votes[c]).sum();
            let share = if total > 0.0 {
                votes[best] / total
            } else {
                0.0
            };
            (Some(best), share)
        })
        .unzip()
}

/// How sure a ring slot where no keypoint was found is read as empty (see [`absent_category`]):
/// more than a coin flip, so that a dot the network missed costs the decoder less than a
/// whole error.
pub const ABSENT_RELIABILITY: f64 = 0.75;

/// The category a slot of a rings layout shows by having nothing in it (RuneTag's empty slot),
/// if the family has one. The network is trained to place such keypoints too, but there is
/// nothing to see at them but the spacing of the dots around; where it places none, the
/// template still says where the slot is, and an empty slot is what the image shows there.
/// A grid's light cell is seen against its dark neighbours and is left to the network.
pub fn absent_category(family: &Family) -> Option<usize> {
    if family.is_grid() {
        return None;
    }
    (family.spec().categories.iter()).position(|c| {
        c.primitives.is_empty() && matches!(c.role, crate::family::spec::Role::Symbol(_))
    })
}
