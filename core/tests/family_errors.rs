//! Bad family files give errors that name the file and the field (random input: `fuzz.rs`).

mod common;
use common::builtin;
use serde_json::{json, Value};
use tagsmith::family::{from_json_str, load_file};

/// Loads a mutated family from a file and returns the error text.
fn error_of(family: &Value) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad-family.json");
    std::fs::write(&path, serde_json::to_string_pretty(family).unwrap()).unwrap();
    let err = load_file(&path)
        .expect_err("the family must be rejected")
        .to_string();
    assert!(err.contains("bad-family.json: "), "no file name in: {err}");
    err
}

fn assert_error(family: &Value, path: &str, phrase: &str) {
    let err = error_of(family);
    let expected = format!("bad-family.json: {path}: ");
    assert!(err.contains(&expected), "expected field {path:?} in: {err}");
    assert!(err.contains(phrase), "expected {phrase:?} in: {err}");
}

#[test]
fn unknown_category_name() {
    let mut f = builtin("apriltag-36h11");
    f["layout"]["legend"]["b"] = json!("blak");
    assert_error(&f, "layout.legend.b", "unknown category \"blak\"");
    let mut f = builtin("runetag-plus");
    f["extra"][2]["category"] = json!("corner-rng");
    assert_error(&f, "extra[2].category", "unknown category \"corner-rng\"");
}

#[test]
fn code_length_does_not_match_the_symbol_keypoints() {
    let mut f = builtin("apriltag-36h11");
    f["codebook"]["codes"][3] = json!("21a146bab0");
    assert_error(&f, "codebook.codes[3]", "36 symbol keypoints");
    let mut f = builtin("quaternary-6x6");
    f["codebook"]["codes"][2] = json!("0123");
    assert_error(
        &f,
        "codebook.codes[2]",
        "4 symbols, but the layout has 36 symbol keypoints",
    );
}

#[test]
fn symbol_value_out_of_range() {
    let mut f = builtin("apriltag-36h11");
    f["categories"][1]["role"] = json!({"symbol": 2});
    assert_error(
        &f,
        "categories[1].role.symbol",
        "symbol value 2 is ≥ the number of symbol categories (2)",
    );
    let mut f = builtin("quaternary-6x6");
    let mut code: Vec<char> = f["codebook"]["codes"][5]
        .as_str()
        .unwrap()
        .chars()
        .collect();
    code[7] = '4';
    f["codebook"]["codes"][5] = json!(code.into_iter().collect::<String>());
    assert_error(
        &f,
        "codebook.codes[5]",
        "symbol 4 at position 7 is ≥ the number of symbol categories (4)",
    );
}

#[test]
fn roi_with_too_few_or_collinear_or_reversed_points() {
    let mut f = builtin("apriltag-36h11");
    f["roi"]["points"] = json!([[0, 0], [8, 0], [8, 8]]);
    assert_error(&f, "roi.points", "at least 4 points");
    f["roi"]["points"] = json!([[0, 0], [4, 0], [8, 0], [0, 8]]);
    assert_error(&f, "roi.points", "collinear");
    f["roi"]["points"] = json!([[0, 0], [0, 8], [8, 8], [8, 0]]);
    assert_error(&f, "roi.points", "counter-clockwise");
}

#[test]
fn grid_over_32_cells() {
    let mut f = builtin("apriltag-36h11");
    f["layout"]["size"] = json!(40);
    assert_error(&f, "layout.size", "40×40 cells is outside 1×1 to 32×32");
}

#[test]
fn duplicate_ids_also_under_rotation() {
    let mut f = builtin("apriltag-36h11");
    let first = f["codebook"]["codes"][0].clone();
    f["codebook"]["codes"][9] = first;
    assert_error(
        &f,
        "codebook.codes[9]",
        "duplicate ID: the same code as ID 0",
    );

    // ID 1 turned a quarter: a 6×6 grid read row-major.
    let mut f = builtin("apriltag-36h11");
    let hex = f["codebook"]["codes"][1].as_str().unwrap();
    let bits: Vec<u8> = (0..36)
        .map(|i| ((u64::from_str_radix(hex, 16).unwrap() >> (35 - i)) & 1) as u8)
        .collect();
    let turned: Vec<u8> = (0..36).map(|i| bits[(5 - i % 6) * 6 + i / 6]).collect();
    let value = turned.iter().fold(0u64, |acc, &b| acc << 1 | b as u64);
    f["codebook"]["codes"][20] = json!(format!("{value:09x}"));
    assert_error(
        &f,
        "codebook.codes[20]",
        "duplicate ID: the code of ID 1 rotated",
    );
}

#[test]
fn typos_and_wrong_types_name_the_field() {
    let mut f = builtin("apriltag-36h11");
    f["roi"]["marign"] = json!(0.1);
    assert_error(&f, "roi.marign", "unknown field `marign`");
    let mut f = builtin("apriltag-36h11");
    f["print"]["marker_side_mm"] = json!("forty");
    assert_error(&f, "print.marker_side_mm", "invalid type: string \"forty\"");
    let mut f = builtin("apriltag-36h11");
    f["layout"]["size"] = json!("eight");
    assert_error(
        &f,
        "layout.size",
        "invalid type: string \"eight\", expected u32",
    );
    let mut f = builtin("runetag");
    f["layout"]["slots"] = json!(-3);
    assert_error(&f, "layout.slots", "invalid value: integer `-3`");
    let mut f = builtin("runetag");
    f["layout"]["type"] = json!("spiral");
    assert_error(&f, "layout.type", "unknown variant `spiral`");
    let mut f = builtin("apriltag-36h11");
    f["format"] = json!(2);
    assert_error(&f, "format", "unsupported format 2");
    let mut f = builtin("apriltag-36h11");
    f["categories"][0]["primitives"][0]["fill"] = json!("black");
    assert_error(
        &f,
        "categories[0].primitives[0].fill",
        "must start with '#'",
    );
}

#[test]
fn impossible_ring_layouts_are_rejected() {
    let mut f = builtin("runetag");
    f["layout"]["slots"] = json!(200);
    assert_error(&f, "layout.radii[0]", "overlap");
    let mut f = builtin("runetag");
    f["layout"]["radii"] = json!([0.9, 0.8, 1.0]);
    assert_error(&f, "layout.radii[1]", "radii must increase");
}

#[test]
fn malformed_json_gives_line_and_column() {
    let err = from_json_str("{\"format\": 1, \"name\": ")
        .unwrap_err()
        .to_string();
    assert!(err.contains("line 1"), "{err}");
}
