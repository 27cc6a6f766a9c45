//! Inputs from a fuzz campaign against `validate`, `render` and `sheet` that crashed, hung or ate
//! memory: each is now refused by validation with the field named, and quickly.

mod common;
use common::builtin;
use serde_json::{json, Value};
use std::time::{Duration, Instant};
use tagsmith::family::{from_json_str, Family};
use tagsmith::render::{marker_scene, raster, readback, SceneOptions};

/// What every reproducer must be refused (or handled) within, in a debug build on a busy machine.
const FAST: Duration = Duration::from_secs(2);

fn timed<T>(what: &str, f: impl FnOnce() -> T) -> T {
    let start = Instant::now();
    let out = f();
    let took = start.elapsed();
    eprintln!("{what}: {took:?}");
    assert!(took < FAST, "{what} took {took:?}");
    out
}

/// Loads `family` (JSON text built outside the timing) and returns the error text, which must
/// name `path` and contain `phrase`.
fn assert_refused(what: &str, family: &Value, path: &str, phrase: &str) {
    let text = serde_json::to_string(family).unwrap();
    let err = timed(what, || from_json_str(&text))
        .expect_err("the family must be refused")
        .to_string();
    let expected = format!("<family>: {path}: ");
    assert!(
        err.contains(&expected),
        "expected field {path:?} in: {}",
        cut(&err)
    );
    assert!(
        err.contains(phrase),
        "expected {phrase:?} in: {}",
        cut(&err)
    );
    assert!(
        err.lines().all(|l| l.len() < 500),
        "a huge message: {}",
        cut(&err)
    );
}

fn cut(s: &str) -> &str {
    &s[..s.char_indices().nth(500).map_or(s.len(), |(i, _)| i)]
}

/// apriltag-36h11 whose "white" category (symbol 1, drawn at up to 36 cells) draws `primitives`.
fn with_white_primitives(primitives: Vec<Value>) -> Value {
    let mut f = builtin("apriltag-36h11");
    f["categories"][1]["primitives"] = Value::Array(primitives);
    f
}

fn path(d: String) -> Value {
    json!({"shape": "path", "d": d, "fill": "#000000"})
}

/// A path of `segments` segments, the fuzzer's smooth cubics that all end at one point: every
/// scanline crosses all of them, the rasterizer's worst case (its cost grows with the square of
/// the edges on a scanline).
fn piled(segments: usize) -> String {
    format!("M 0 0 {}", "S.3 .2 .1 .1".repeat(segments - 1))
}

fn dots(n: usize) -> Vec<Value> {
    (0..n)
        .map(|i| {
            json!({"shape": "dot", "radius": 0.01, "x": (i % 40) as f64 * 0.02 - 0.4,
                   "y": (i / 40 % 40) as f64 * 0.02 - 0.4, "fill": "#000000"})
        })
        .collect()
}

#[test]
fn arcs_that_draw_nothing_are_refused_without_overflowing_the_stack() {
    // Was SIGABRT (stack overflow) in validate, render and sheet.
    let d = format!("M 0 0 {}", "A 0.2 0.2 0 1 1 0.1 0.1 ".repeat(26_000));
    assert_refused(
        "26 000 arcs",
        &with_white_primitives(vec![path(d)]),
        "categories[1].primitives[0].d",
        "over the limit of 16384",
    );
    // The same under the byte limit draws one arc and is valid.
    let d = format!("M 0 0 {}", "A 0.2 0.2 0 1 1 0.1 0.1 ".repeat(600));
    let f = with_white_primitives(vec![path(d)]);
    timed("600 arcs", || from_json_str(&f.to_string())).expect("a valid path");
}

#[test]
fn long_runs_of_smooth_cubics_are_refused_or_drawn_fast() {
    // 8000 took 5.4 s and 100 000 did not finish.
    for n in [8_000, 100_000] {
        let d = format!("M 0 0 {}", "S 0.3 0.2 0.1 0.1 ".repeat(n));
        assert_refused(
            &format!("{n} smooth cubics"),
            &with_white_primitives(vec![path(d)]),
            "categories[1].primitives[0].d",
            "over the limit",
        );
    }
    // As many as a path may have: validation, the look-alike check and a raster stay fast.
    let f = with_white_primitives(vec![path(piled(512))]);
    let family = timed("512 smooth cubics", || from_json_str(&f.to_string())).unwrap();
    draw_fast(&family);
}

#[test]
fn the_most_a_family_may_draw_is_drawn_fast() {
    // A category no keypoint uses still has its look checked: as many segments as a family may
    // have, in paths as long as allowed.
    let mut f = builtin("apriltag-36h11");
    f["categories"].as_array_mut().unwrap().push(json!({
        "name": "unused", "role": "fixed", "primitives": vec![path(piled(511)); 16]
    }));
    let family = from_json_str(&f.to_string()).expect("8181 segments are within the limit");
    timed("look-alike check of 8176 piled segments", || {
        readback::warnings(&family)
    });
    // A marker with nearly as many segments as allowed (3 × 512 in each of 36 cells).
    let family = from_json_str(&with_white_primitives(vec![path(piled(512)); 3]).to_string())
        .expect("55 436 segments a marker are within the limit");
    draw_fast(&family);
}

/// Renders ID 0 at 300 dpi and runs the look-alike check, all within [`FAST`].
fn draw_fast(family: &Family) {
    timed("look-alike check", || readback::warnings(family));
    let scene = marker_scene(family, 0, SceneOptions::default()).unwrap();
    timed("raster", || {
        raster::rasterize(&scene, 300.0 / 25.4).unwrap()
    });
}

#[test]
fn many_categories_are_refused_and_look_alikes_are_reported_briefly() {
    // 400 fixed categories took 52.6 s to validate and printed 80 200 warnings.
    for n in [400, 1000] {
        let mut f = builtin("apriltag-36h11");
        let cats = f["categories"].as_array_mut().unwrap();
        for i in 0..n {
            cats.push(json!({"name": format!("c{i}"), "role": "fixed", "primitives": []}));
        }
        assert_refused(
            &format!("{n} categories"),
            &f,
            "categories",
            "over the limit of 64",
        );
    }
    // As many as allowed, all alike: every pair is found, a few are named.
    let mut f = builtin("apriltag-36h11");
    let cats = f["categories"].as_array_mut().unwrap();
    for i in 0..62 {
        cats.push(json!({"name": format!("c{i}"), "role": "fixed", "primitives": []}));
    }
    let family = from_json_str(&f.to_string()).unwrap();
    let warnings = timed("look-alike check of 64 categories", || {
        readback::warnings(&family)
    });
    assert_eq!(warnings.len(), readback::MAX_REPORTED_PAIRS + 1);
    // 63 blank categories: 63·62/2 pairs.
    let more = 63 * 62 / 2 - readback::MAX_REPORTED_PAIRS;
    assert!(
        warnings[readback::MAX_REPORTED_PAIRS].contains(&format!("and {more} more pairs")),
        "{warnings:?}"
    );
}

#[test]
fn too_many_primitives_and_segments_are_refused() {
    // 6000 dots: `sheet` failed after 19 s and 1.2 GB; 100 000: render took 43 s and 2 GB.
    for n in [6_000, 100_000] {
        assert_refused(
            &format!("{n} dots"),
            &with_white_primitives(dots(n)),
            "categories[1].primitives",
            "over the limit of 64 per category",
        );
    }
    // A 9 MB path: render used 2.8 GB.
    let d = format!("M 0 0 {}", "L 0.1 0.1 L 0.2 0 ".repeat(9_000_000 / 18));
    assert_refused(
        "9 MB path",
        &with_white_primitives(vec![path(d)]),
        "categories[1].primitives[0].d",
        "bytes, over the limit of 16384",
    );
    // Under the byte limit but with more segments than a path may have.
    let d = format!("M 0 0 {}", "h.1h-.1".repeat(2000));
    assert_refused(
        "4000 short segments",
        &with_white_primitives(vec![path(d)]),
        "categories[1].primitives[0].d",
        "over 512 segments",
    );
    // Each category within the limits, but together more than a family may hold.
    let d = format!("M 0 0 {}", "L 0.1 0.1 L 0 0 ".repeat(255));
    assert_refused(
        "17 paths of 511 segments",
        &with_white_primitives(vec![path(d.clone()); 17]),
        "categories",
        "over the limit of 8192",
    );
    // Within the family's limit, but drawn at every cell of a marker.
    assert_refused(
        "16 paths of 511 segments in 36 cells",
        &with_white_primitives(vec![path(d); 16]),
        "categories[1].primitives",
        "path segments, over the limit of 65536",
    );
    // 64 primitives at each of the 129 slots of a RuneTag.
    let mut f = builtin("runetag");
    f["categories"][1]["primitives"] = Value::Array(dots(64));
    assert_refused(
        "64 dots in 129 slots",
        &f,
        "categories[1].primitives",
        "primitives, over the limit of 8192",
    );
    // The most primitives a category may have is fine.
    let family = from_json_str(&with_white_primitives(dots(64)).to_string()).unwrap();
    draw_fast(&family);
}

#[test]
fn long_texts_are_refused() {
    // A 100 000-character title took 9.6 s to lay out in the PDF; 1 000 000 timed out.
    for n in [101, 100_000, 1_000_000] {
        let mut f = builtin("apriltag-36h11");
        f["title"] = json!("T".repeat(n));
        assert_refused(
            &format!("{n}-character title"),
            &f,
            "title",
            &format!("{n} characters is over the limit of 100"),
        );
    }
    let long = "é".repeat(100_000);
    for (field, limit) in [("description", 4000), ("source", 1000)] {
        let mut f = builtin("apriltag-36h11");
        f[field] = json!(long);
        assert_refused(field, &f, field, &format!("over the limit of {limit}"));
    }
    let mut f = builtin("apriltag-36h11");
    f["codebook"]["source"] = json!(long);
    assert_refused("codebook.source", &f, "codebook.source", "limit of 1000");
    let mut f = builtin("apriltag-36h11");
    f["categories"][1]["name"] = json!(long);
    assert_refused(
        "category name",
        &f,
        "categories[1].name",
        "over the limit of 64 characters",
    );
    // Names that are wrong and long are cut short in the message.
    let mut f = builtin("apriltag-36h11");
    f["name"] = json!(long);
    assert_refused("family name", &f, "name", "must be 1–64 letters");
    let mut f = builtin("apriltag-36h11");
    f["layout"]["legend"]["b"] = json!(long);
    assert_refused("legend", &f, "layout.legend.b", "unknown category");
    // Exactly at the limit is fine.
    let mut f = builtin("apriltag-36h11");
    f["title"] = json!("é".repeat(100));
    from_json_str(&f.to_string()).expect("a title of 100 characters");
}

#[test]
fn many_extra_keypoints_are_refused_fast() {
    // The overlap check compares every pair of keypoints; it waits until their number is known
    // to be within the limit.
    let mut f = builtin("runetag");
    let extra: Vec<Value> = (0..50_000)
        .map(|i| json!({"x": (i % 200) as f64 * 0.01, "y": (i / 200) as f64 * 0.01, "size": 0.01, "category": "."}))
        .collect();
    f["extra"] = Value::Array(extra);
    assert_refused("50 000 extras", &f, "layout", "over the limit of 4096");
}
