use super::*;
use crate::codebook::generate;
use crate::family::Family;

fn spec(name: &str) -> FamilySpec {
    crate::builtin::get(name).unwrap().unwrap().spec().clone()
}

fn generate_codes(s: &FamilySpec, d: u32, count: usize) -> CodebookSpec {
    let family = Family::from_spec(s.clone()).unwrap();
    let mut p = family.generate_params(d);
    p.max_codes = count;
    let r = generate(&p, &mut |_, _| {}).unwrap();
    r.codebook.to_spec(r.achieved_min_distance, "test")
}

/// The scenario at the model level: start from a built-in, change the grid size, add a
/// cross-shaped category and use it, generate a codebook — the result validates and renders.
#[test]
fn a_new_design_from_a_builtin_validates_after_each_step() {
    let mut h = History::new(spec("apriltag-36h11"));
    h.apply(&Edit::SetName("my-tag".into())).unwrap();
    h.apply(&Edit::SetGrid {
        size: 7,
        border: 1,
        frame: "black".into(),
    })
    .unwrap();
    // 25 data cells now: the 36-bit codes were replaced by a placeholder, and it validates.
    let f = Family::from_spec(h.current().clone()).unwrap();
    assert_eq!((f.code_len(), f.codebook().len()), (25, 1));
    assert_eq!(f.roi_points()[2], [7.0, 7.0]);

    let cross = Primitive {
        shape: Shape::Cross {
            size: 0.8,
            width: 0.2,
            x: 0.0,
            y: 0.0,
        },
        fill: Some("#000000".into()),
        stroke: None,
        stroke_width: None,
    };
    h.apply(&Edit::AddCategory {
        name: "corner-x".into(),
        role: Role::Fixed,
    })
    .unwrap();
    h.apply(&Edit::SetPrimitives {
        category: "corner-x".into(),
        primitives: vec![cross],
    })
    .unwrap();
    h.apply(&Edit::SetCell {
        row: 1,
        col: 1,
        value: CellValue::Fixed("corner-x".into()),
    })
    .unwrap();
    let f = Family::from_spec(h.current().clone()).unwrap();
    assert_eq!(f.code_len(), 24);
    // The cross breaks the symmetry: no rotation is ambiguous any more.
    assert_eq!(f.ambiguous_rotations().count(), 0);

    let codes = generate_codes(h.current(), 6, 40);
    h.apply(&Edit::SetCodebook(codes)).unwrap();
    let f = Family::from_spec(h.current().clone()).unwrap();
    assert_eq!(f.codebook().len(), 40);
    crate::render::marker_scene(&f, 39, Default::default()).unwrap();
}

#[test]
fn undo_and_redo_walk_the_edits_and_keep_fifty() {
    let start = spec("aruco-4x4_50");
    let mut h = History::new(start.clone());
    for i in 0..60 {
        h.apply(&Edit::SetMarkerSide(10.0 + i as f64)).unwrap();
    }
    assert_eq!(h.can_undo(), 50);
    while h.undo() {}
    assert_eq!(
        h.current().print.marker_side_mm,
        19.0,
        "the 10 oldest edits fell off"
    );
    assert!(h.redo());
    assert_eq!(h.current().print.marker_side_mm, 20.0);
    // A new edit after undo drops the redo list.
    h.apply(&Edit::SetTitle("x".into())).unwrap();
    assert!(!h.redo());
    // An edit that changes nothing is not an undo step.
    let before = h.can_undo();
    h.apply(&Edit::SetTitle("x".into())).unwrap();
    assert_eq!(h.can_undo(), before);
}

#[test]
fn renaming_follows_every_use_and_removing_a_used_category_is_refused() {
    let s = spec("runetag-plus");
    let renamed = apply(
        &s,
        &Edit::RenameCategory {
            from: "corner-ring".into(),
            to: "north".into(),
        },
    )
    .unwrap();
    assert!(renamed.extra.iter().any(|e| e.category == "north"));
    Family::from_spec(renamed.clone()).unwrap();
    assert_eq!(
        apply(&renamed, &Edit::RemoveCategory("north".into())),
        Err(EditError::InUse {
            name: "north".into(),
            uses: 1
        })
    );
    let grid = apply(
        &spec("apriltag-xo-36h11"),
        &Edit::RenameCategory {
            from: "frame".into(),
            to: "border".into(),
        },
    )
    .unwrap();
    let Layout::Grid(g) = &grid.layout else {
        panic!()
    };
    assert_eq!(g.legend.get("b").map(String::as_str), Some("border"));
    Family::from_spec(grid).unwrap();
    assert!(matches!(
        apply(
            &spec("runetag"),
            &Edit::RenameCategory {
                from: "dot".into(),
                to: "empty".into()
            }
        ),
        Err(EditError::Exists(_))
    ));
}

#[test]
fn impossible_edits_are_errors_and_change_nothing() {
    let s = spec("apriltag-16h5");
    let mut h = History::new(s.clone());
    assert!(h
        .apply(&Edit::SetGrid {
            size: 4,
            border: 2,
            frame: "black".into()
        })
        .is_err());
    assert!(h
        .apply(&Edit::SetCell {
            row: 9,
            col: 0,
            value: CellValue::Symbol
        })
        .is_err());
    assert!(h
        .apply(&Edit::SetCell {
            row: 0,
            col: 0,
            value: CellValue::Fixed("nope".into())
        })
        .is_err());
    assert!(h.apply(&Edit::RemoveExtra(0)).is_err());
    assert_eq!(h.current(), &s);
    assert_eq!(h.can_undo(), 0);
    // An edit that leaves an invalid design is applied; validation says what is wrong and where.
    h.apply(&Edit::SetRoi(vec![
        [0.0, 0.0],
        [6.0, 0.0],
        [12.0, 0.0],
        [0.0, 6.0],
    ]))
    .unwrap();
    let err = Family::from_spec(h.current().clone())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("roi.points") && err.contains("collinear"),
        "{err}"
    );
    h.undo();
    Family::from_spec(h.current().clone()).unwrap();
}

#[test]
fn a_dragged_slider_is_one_undo_step() {
    let mut h = History::new(spec("aruco-4x4_50"));
    for mm in [41.0, 42.0, 43.0, 44.0] {
        h.apply_grouped(&Edit::SetMarkerSide(mm), "side").unwrap();
    }
    h.end_group();
    h.apply_grouped(&Edit::SetMarkerSide(50.0), "side").unwrap();
    assert_eq!(h.can_undo(), 2, "two gestures, two undo steps");
    assert!(h.undo());
    assert_eq!(h.current().print.marker_side_mm, 44.0);
    assert!(h.undo());
    assert_eq!(h.current().print.marker_side_mm, 40.0);
}

#[test]
fn switching_a_grid_design_to_rings_gives_a_valid_ring_family() {
    let mut h = History::new(spec("runetag"));
    h.apply(&Edit::SetRings {
        radii: vec![0.5, 0.75, 1.0],
        slots: 20,
        dot_radius_ratio: 0.08,
        start_angle_deg: -90.0,
    })
    .unwrap();
    let f = Family::from_spec(h.current().clone()).unwrap();
    assert_eq!(f.code_len(), 60, "3 rings × 20 slots");
    assert!(
        h.apply(&Edit::SetRings {
            radii: vec![],
            slots: 20,
            dot_radius_ratio: 0.08,
            start_angle_deg: 0.0,
        })
        .is_err(),
        "no rings is refused"
    );
    // From a grid: the ROI becomes the outer ring's square.
    let mut g = History::new(spec("aruco-4x4_50"));
    g.apply(&Edit::SetRings {
        radii: vec![1.0],
        slots: 16,
        dot_radius_ratio: 0.1,
        start_angle_deg: -90.0,
    })
    .unwrap();
    assert_eq!(g.current().roi.points[0], [-1.0, -1.0]);
}
