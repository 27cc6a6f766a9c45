//! The pyramid's networks on the two cores. burn spreads each layer over both cores, but on
//! tensors this small that gains little (at 1280×960 the pyramid took 157 ms on one thread and
//! 110 ms on two); two whole forward passes side by side use both. The levels are unequal (each
//! a quarter of the one above), so the largest is cut into two bands of rows, each with a margin
//! of the network's receptive field on the cut side: an output cell whose receptive field lies
//! inside its band is computed from the same pixels as on the whole level, so the stitched maps
//! are the whole level's. The cut is placed so that each core's band plus its share of the
//! smaller levels is the same work.

use super::group::Maps;
use super::net::receptive_radius;
use super::pipeline::maps_of;
use super::STRIDE;
use crate::detect::plain_net::PlainNet;
use crate::detect::stage2::Contrast;
use crate::image::GrayImage;

/// Where the largest level is cut: band A is its rows `0..cut + margin`, band B its rows
/// `cut - margin..`; A's first `cut / STRIDE` map rows and B's rows from `margin / STRIDE` on
/// are kept.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Cut {
    row: usize,
    margin: usize,
}

/// The maps of every level, in order. `contrasts[i]` normalises level `i` (None: its own).
pub fn pyramid_maps(
    net: &PlainNet,
    levels: &[&GrayImage],
    contrasts: &[Option<Contrast>],
) -> Vec<Maps> {
    let one = |i: usize| maps_of_one(net, levels[i], contrasts[i]);
    let largest = (0..levels.len()).max_by_key(|&i| pixels(levels[i]));
    let (Some(largest), true) = (largest, rayon::current_num_threads() >= 2) else {
        return (0..levels.len()).map(one).collect();
    };
    let width = levels[largest].width as usize;
    // The other levels' work in rows of the largest, dealt out largest first to the lighter core.
    let mut others: Vec<usize> = (0..levels.len()).filter(|&i| i != largest).collect();
    others.sort_by_key(|&i| std::cmp::Reverse(pixels(levels[i])));
    let (mut share_a, mut share_b) = (Vec::new(), Vec::new());
    let (mut rows_a, mut rows_b) = (0usize, 0usize);
    for i in others {
        let rows = pixels(levels[i]) / width;
        if rows_a <= rows_b {
            share_a.push(i);
            rows_a += rows;
        } else {
            share_b.push(i);
            rows_b += rows;
        }
    }
    let Some(cut) = cut_for(
        levels[largest].height as usize,
        rows_a,
        rows_b,
        receptive_radius(),
    ) else {
        return (0..levels.len()).map(one).collect();
    };
    let whole = contrasts[largest].unwrap_or_else(|| Contrast::of(levels[largest]));
    let band = |from: usize, to: usize| {
        let image = levels[largest].crop(0, from as u32, width as u32, (to - from) as u32);
        maps_of_one(net, &image, Some(whole))
    };
    let height = levels[largest].height as usize;
    let run = |first: (usize, usize), share: &[usize]| {
        let band = band(first.0, first.1);
        let rest: Vec<(usize, Maps)> = share.iter().map(|&i| (i, one(i))).collect();
        (band, rest)
    };
    let ((band_a, rest_a), (band_b, rest_b)) = rayon::join(
        || run((0, cut.row + cut.margin), &share_a),
        || run((cut.row - cut.margin, height), &share_b),
    );
    let mut maps: Vec<Option<Maps>> = (0..levels.len()).map(|_| None).collect();
    maps[largest] = Some(stitch(&band_a, &band_b, cut));
    for (i, m) in rest_a.into_iter().chain(rest_b) {
        maps[i] = Some(m);
    }
    maps.into_iter()
        .map(|m| m.expect("every level ran"))
        .collect()
}

/// [`maps_of`] for one image.
fn maps_of_one(net: &PlainNet, image: &GrayImage, contrast: Option<Contrast>) -> Maps {
    maps_of(net, std::slice::from_ref(image), contrast)
        .pop()
        .expect("one image in, one out")
}

fn pixels(image: &GrayImage) -> usize {
    image.width as usize * image.height as usize
}

/// The cut that gives both cores the same rows to run, each band with `radius` rows beyond the
/// cut rounded up to the stride; None when the level is too short for two bands to pay.
fn cut_for(height: usize, rows_a: usize, rows_b: usize, radius: usize) -> Option<Cut> {
    let margin = radius.div_ceil(STRIDE) * STRIDE;
    // Band A's rows + A's share = band B's rows + B's share.
    let balanced = (height + rows_b).saturating_sub(rows_a) / 2;
    let row = (balanced / STRIDE * STRIDE).clamp(margin, height.saturating_sub(margin));
    // Each band must keep rows of its own beyond its margin, or one core does all the work.
    (height >= 4 * margin && row >= 2 * margin && row + 2 * margin <= height)
        .then_some(Cut { row, margin })
}

/// The whole level's maps from its two bands' (see [`Cut`]).
fn stitch(a: &Maps, b: &Maps, cut: Cut) -> Maps {
    let columns = a.columns;
    let top = cut.row / STRIDE;
    let skip = cut.margin / STRIDE;
    let join =
        |x: &[f32], y: &[f32]| -> Vec<f32> { [&x[..top * columns], &y[skip * columns..]].concat() };
    let join2 = |x: &[[f32; 2]], y: &[[f32; 2]]| -> Vec<[f32; 2]> {
        [&x[..top * columns], &y[skip * columns..]].concat()
    };
    Maps {
        columns,
        rows: top + b.rows - skip,
        heat: join(&a.heat, &b.heat),
        offset: join2(&a.offset, &b.offset),
        direction: join2(&a.direction, &b.direction),
        mask: join(&a.mask, &b.mask),
    }
}

#[cfg(test)]
mod tests {
    use super::super::model_file;
    use super::super::pipeline::{pyramid, SHIPPED_STAGE1};
    use super::*;
    use crate::detect::plain_net::largest_difference;
    use burn::tensor::Device;

    #[test]
    fn the_cut_balances_the_cores_and_keeps_each_band_worth_running() {
        // 480 rows, the other levels' 150 rows all on core A: B's band takes the extra rows.
        let cut = cut_for(480, 150, 0, 37).unwrap();
        assert_eq!(cut.margin, 40);
        assert_eq!(cut.row % STRIDE, 0);
        let a = cut.row + cut.margin + 150;
        let b = 480 - cut.row + cut.margin;
        assert!(a.abs_diff(b) <= 2 * STRIDE, "core A {a} rows, core B {b}");
        // Too short for two bands of their own beyond the margins.
        assert_eq!(cut_for(150, 0, 0, 37), None);
        // So lopsided that one band would be all margin.
        assert_eq!(cut_for(480, 600, 0, 37), None);
    }

    /// Every detection's stage 1 runs the banded network: its maps must be the whole level's.
    #[test]
    fn banded_maps_are_the_whole_levels_maps() {
        let device = Device::flex();
        let (net, _) = model_file::from_bytes(SHIPPED_STAGE1, "shipped", &device).unwrap();
        let net = net.plain();
        // A checkerboard marker-like square across where the cut falls, on a textured ground;
        // odd sizes so the bottom and right edges are padded.
        let (w, h) = (203u32, 417u32);
        let mut image = GrayImage::new(w, h, 0);
        for y in 0..h {
            for x in 0..w {
                let inside = (60..140).contains(&x) && (170..250).contains(&y);
                image.pixels[(y * w + x) as usize] = if inside {
                    if (x / 10 + y / 10) % 2 == 0 {
                        20
                    } else {
                        235
                    }
                } else {
                    (150 + (x * 7 + y * 13) % 40) as u8
                };
            }
        }
        let levels = pyramid(&image, 3);
        // Level 1 (103 rows of level 0) on one core, level 2 (25) on the other: a cut at row 168.
        assert!(cut_for(417, 103, 25, receptive_radius()).is_some());
        let refs: Vec<&GrayImage> = levels.iter().map(|(l, _)| l).collect();
        let contrasts = vec![Some(Contrast::of(&image)), None, None];
        let whole: Vec<Maps> = (0..refs.len())
            .map(|i| maps_of_one(&net, refs[i], contrasts[i]))
            .collect();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let banded = pool.install(|| pyramid_maps(&net, &refs, &contrasts));
        assert_eq!(banded.len(), whole.len());
        for (b, w) in banded.iter().zip(&whole) {
            assert_eq!((b.columns, b.rows), (w.columns, w.rows));
            let worst = largest_difference;
            let flat = |v: &[[f32; 2]]| v.iter().flatten().copied().collect::<Vec<f32>>();
            for (name, diff) in [
                ("heat", worst(&b.heat, &w.heat)),
                ("mask", worst(&b.mask, &w.mask)),
                ("offset", worst(&flat(&b.offset), &flat(&w.offset))),
                ("direction", worst(&flat(&b.direction), &flat(&w.direction))),
            ] {
                assert!(diff <= 1e-4, "{name} differs by {diff}");
            }
        }
    }
}
