//! The pyramid's networks on the two cores, in memory that does not grow with the photograph.
//!
//! burn spreads each layer over both cores, but on tensors this small that gains little (at
//! 1280×960 the pyramid took 157 ms on one thread and 110 ms on two); two whole forward passes
//! side by side use both. The levels are unequal (each a quarter of the one above), so the
//! largest is cut into two bands of rows, each with a margin of the network's receptive field on
//! the cut side: an output cell whose receptive field lies inside its band is computed from the
//! same pixels as on the whole level, so the stitched maps are the whole level's. The cut is
//! placed so that each core's band plus its share of the smaller levels is the same work.
//!
//! A level larger than [`TILED_ABOVE_PIXELS`] is cut the same way into square tiles instead
//! (margins on every cut side), run a row of tiles at a time on all cores: a pass holds the
//! activations of one tile per core whatever the level's size, so a 24-megapixel photograph costs
//! the network no more working memory than a 4-megapixel one, and the maps, a few bytes a pixel,
//! are all that grows.

use super::group::Maps;
use super::net::receptive_radius;
use super::pipeline::maps_of;
use super::STRIDE;
use crate::detect::blocks::Contrast;
use crate::detect::plain_net::PlainNet;
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
    if levels.iter().any(|l| pixels(l) > TILED_ABOVE_PIXELS) {
        return (levels.iter().zip(contrasts))
            .map(|(level, contrast)| {
                let contrast = contrast.unwrap_or_else(|| Contrast::of(level));
                tiled_maps(net, level, contrast, TILE_SIDE)
            })
            .collect();
    }
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

/// Levels over this many pixels are run in tiles ([`tiled_maps`]); below it the two-band cut
/// keeps both cores busy with less margin recomputed.
pub const TILED_ABOVE_PIXELS: usize = 4 << 20;

/// A tile's side, margins included: a pass holds its activations, some tens of MB per core.
pub const TILE_SIDE: usize = 1024;

/// One axis of a level cut for tiling: the pixels `from..to` go through the network and the map
/// cells of `keep_from..keep_to` are taken from it (both in level pixels, the keep bounds
/// multiples of [`STRIDE`] but for the level's end).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Span {
    from: usize,
    to: usize,
    keep_from: usize,
    keep_to: usize,
}

/// `len` pixels cut into spans of at most `side` pixels, `margin` beyond every inner cut.
fn spans(len: usize, side: usize, margin: usize) -> Vec<Span> {
    let core = (side.saturating_sub(2 * margin) / STRIDE * STRIDE).max(STRIDE);
    let mut out = Vec::new();
    let mut start = 0;
    while start < len {
        let end = (start + core).min(len);
        out.push(Span {
            from: start.saturating_sub(margin),
            to: (end + margin).min(len),
            keep_from: start,
            keep_to: end,
        });
        start = end;
    }
    out
}

/// The maps of `level` computed tile by tile (tiles of at most `side` pixels a side, margins
/// included), normalised by the whole level's `contrast`: the whole level's maps.
fn tiled_maps(net: &PlainNet, level: &GrayImage, contrast: Contrast, side: usize) -> Maps {
    use rayon::prelude::*;
    let margin = receptive_radius().div_ceil(STRIDE) * STRIDE;
    let (width, height) = (level.width as usize, level.height as usize);
    let (columns, rows) = (width.div_ceil(STRIDE), height.div_ceil(STRIDE));
    let cells = columns * rows;
    let mut whole = Maps {
        columns,
        rows,
        heat: vec![0.0; cells],
        offset: vec![[0.0; 2]; cells],
        direction: vec![[0.0; 2]; cells],
        mask: vec![0.0; cells],
    };
    let across = spans(width, side, margin);
    for down in spans(height, side, margin) {
        let row_of_tiles: Vec<(Span, Maps)> = (across.par_iter())
            .with_max_len(1)
            .map(|&x| {
                let crop = level.crop(
                    x.from as u32,
                    down.from as u32,
                    (x.to - x.from) as u32,
                    (down.to - down.from) as u32,
                );
                (x, maps_of_one(net, &crop, Some(contrast)))
            })
            .collect();
        for (x, tile) in row_of_tiles {
            let first_row = (down.keep_from - down.from) / STRIDE;
            let end_row = (down.keep_to - down.from).div_ceil(STRIDE);
            let first_column = (x.keep_from - x.from) / STRIDE;
            let end_column = (x.keep_to - x.from).div_ceil(STRIDE);
            for tile_row in first_row..end_row {
                let row = down.from / STRIDE + tile_row;
                let src = tile_row * tile.columns;
                let dst = row * columns + x.from / STRIDE;
                let range = |base: usize| base + first_column..base + end_column;
                whole.heat[range(dst)].copy_from_slice(&tile.heat[range(src)]);
                whole.offset[range(dst)].copy_from_slice(&tile.offset[range(src)]);
                whole.direction[range(dst)].copy_from_slice(&tile.direction[range(src)]);
                whole.mask[range(dst)].copy_from_slice(&tile.mask[range(src)]);
            }
        }
    }
    whole
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
    // Each band must keep rows of its own beyond its margin, or one core does all the work.
    if height < 4 * margin {
        return None;
    }
    // Band A's rows + A's share = band B's rows + B's share.
    let balanced = (height + rows_b).saturating_sub(rows_a) / 2;
    let row = (balanced / STRIDE * STRIDE).clamp(margin, height - margin);
    (row >= 2 * margin && row + 2 * margin <= height).then_some(Cut { row, margin })
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
    use super::super::pipeline::{pyramid, shipped_stage1};
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
        // Too short for two bands of their own beyond the margins, down to no rows at all
        // (shorter than two margins, the cut's range was empty and `clamp` panicked).
        assert_eq!(cut_for(150, 0, 0, 37), None);
        for height in [0, 1, 2, 79, 80, 159] {
            assert_eq!(cut_for(height, 0, 0, 37), None, "{height} rows");
        }
        // So lopsided that one band would be all margin.
        assert_eq!(cut_for(480, 600, 0, 37), None);
    }

    #[test]
    fn spans_cover_the_axis_once_with_margins_at_inner_cuts() {
        for len in [1, 4, 5, 100, 944, 945, 1024, 3001] {
            let spans = spans(len, 200, 40);
            assert_eq!(spans.first().unwrap().keep_from, 0);
            assert_eq!(spans.last().unwrap().keep_to, len);
            for pair in spans.windows(2) {
                assert_eq!(pair[0].keep_to, pair[1].keep_from, "{len}");
                assert_eq!(pair[1].keep_from % STRIDE, 0);
                assert_eq!(pair[1].keep_from - pair[1].from, 40);
                assert_eq!(pair[0].to - pair[0].keep_to, 40.min(len - pair[0].keep_to));
            }
            assert!(spans.iter().all(|s| s.to - s.from <= 200), "{len}");
        }
        assert!(spans(0, 200, 40).is_empty());
    }

    /// Large photographs' levels run in tiles: their maps must be the whole level's, also where
    /// the tiles' edges fall on a marker and the level's size is not a multiple of the stride.
    #[test]
    fn tiled_maps_are_the_whole_levels_maps() {
        let device = Device::flex();
        let (net, _) = model_file::from_bytes(shipped_stage1(), "shipped", &device).unwrap();
        let net = net.plain();
        let image = textured_with_marker(301, 222, (90, 60), 80);
        let contrast = Contrast::of(&image);
        let whole = maps_of_one(&net, &image, Some(contrast));
        // Tiles of 160: a core of 80 pixels, so the marker spans several tiles each way.
        let tiled = tiled_maps(&net, &image, contrast, 160);
        assert_same_maps(&tiled, &whole);
    }

    fn textured_with_marker(w: u32, h: u32, at: (u32, u32), side: u32) -> GrayImage {
        let mut image = GrayImage::new(w, h, 0);
        for y in 0..h {
            for x in 0..w {
                let inside = (at.0..at.0 + side).contains(&x) && (at.1..at.1 + side).contains(&y);
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
        image
    }

    fn assert_same_maps(b: &Maps, w: &Maps) {
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

    /// Every detection's stage 1 runs the banded network: its maps must be the whole level's.
    #[test]
    fn banded_maps_are_the_whole_levels_maps() {
        let device = Device::flex();
        let (net, _) = model_file::from_bytes(shipped_stage1(), "shipped", &device).unwrap();
        let net = net.plain();
        // A checkerboard marker-like square across where the cut falls, on a textured ground;
        // odd sizes so the bottom and right edges are padded.
        let image = textured_with_marker(203, 417, (60, 170), 80);
        let levels = pyramid(&image, 3);
        // Level 1 (103 rows of level 0) on one core, level 2 (25) on the other: a cut at row 168.
        assert!(cut_for(417, 103, 25, receptive_radius()).is_some());
        let refs: Vec<&GrayImage> = levels.iter().map(|(l, _)| l.as_ref()).collect();
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
            assert_same_maps(b, w);
        }
    }
}
