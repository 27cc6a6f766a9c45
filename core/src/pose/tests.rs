use super::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// 8×8 cell centres of a 40 mm AprilTag 36h11 (all 64 keypoints), and its 4 outer corners.
fn tag_points() -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
    let f = crate::builtin::get("apriltag-36h11").unwrap().unwrap();
    let kps: Vec<[f64; 2]> = f.keypoints().iter().map(|k| k.pos).collect();
    (
        marker_plane_points(&f, 0.04, &kps),
        marker_plane_points(&f, 0.04, &f.roi_points()[..4]),
    )
}

fn random_pose(rng: &mut ChaCha8Rng) -> Pose {
    // Marker facing the camera, tilted up to 60°, turned in-plane at random, 20–50 cm away.
    let tilt = rng.random_range(0.0..60f64).to_radians();
    let axis_angle = rng.random_range(0.0..std::f64::consts::TAU);
    let spin = rng.random_range(0.0..std::f64::consts::TAU);
    let facing = Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    let tilt = Rotation3::new(Vector3::new(axis_angle.cos(), axis_angle.sin(), 0.0) * tilt);
    let spin = Rotation3::from_axis_angle(&Vector3::z_axis(), spin);
    Pose {
        rotation: tilt * facing * spin,
        translation: Vector3::new(
            rng.random_range(-0.05..0.05),
            rng.random_range(-0.05..0.05),
            rng.random_range(0.2..0.5),
        ),
    }
}

fn camera() -> Camera {
    let mut c = Camera::from_diagonal_fov(1280, 960, 98.0).unwrap();
    c.distortion = [-0.05, 0.01, 0.0002, -0.0001, 0.0];
    c
}

fn project(c: &Camera, pose: &Pose, pts: &[[f64; 2]]) -> Vec<[f64; 2]> {
    pts.iter()
        .map(|p| c.project(pose.apply([p[0], p[1], 0.0])))
        .collect()
}

#[test]
fn exact_points_give_the_pose_to_1e_6() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let (kps, _) = tag_points();
    let c = camera();
    for _ in 0..20 {
        let truth = random_pose(&mut rng);
        let sol = solve_planar(&c, &kps, &project(&c, &truth, &kps)).unwrap();
        assert!(
            sol.pose.rotation_error_deg(&truth).to_radians() < 1e-6,
            "{}",
            sol.pose.rotation_error_deg(&truth)
        );
        assert!(sol.pose.position_error(&truth) < 1e-6 * truth.translation.norm());
        assert!(sol.rms_px < 1e-6);
    }
}

#[test]
fn sixty_four_keypoints_beat_four_corners_under_half_a_pixel_of_noise() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let (kps, corners) = tag_points();
    let c = camera();
    let noise = |rng: &mut ChaCha8Rng, pts: Vec<[f64; 2]>| -> Vec<[f64; 2]> {
        pts.into_iter()
            .map(|p| {
                // Box–Muller: σ = 0.5 px per coordinate.
                let (u1, u2): (f64, f64) = (rng.random_range(1e-12..1.0), rng.random());
                let r = 0.5 * (-2.0 * u1.ln()).sqrt();
                let a = std::f64::consts::TAU * u2;
                [p[0] + r * a.cos(), p[1] + r * a.sin()]
            })
            .collect()
    };
    let (mut err64, mut err4) = (0.0, 0.0);
    let trials = 200;
    for _ in 0..trials {
        let truth = random_pose(&mut rng);
        let obs64 = noise(&mut rng, project(&c, &truth, &kps));
        let obs4 = noise(&mut rng, project(&c, &truth, &corners));
        err64 += solve_planar(&c, &kps, &obs64)
            .unwrap()
            .pose
            .rotation_error_deg(&truth);
        err4 += solve_planar(&c, &corners, &obs4)
            .unwrap()
            .pose
            .rotation_error_deg(&truth);
    }
    let (m64, m4) = (err64 / trials as f64, err4 / trials as f64);
    eprintln!("mean rotation error: 64 keypoints {m64:.4}°, 4 corners {m4:.4}°");
    assert!(m64 < 0.5 * m4, "64 keypoints {m64}° vs 4 corners {m4}°");
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let c = camera();
    let (kps, corners) = tag_points();
    let img = project(
        &c,
        &random_pose(&mut ChaCha8Rng::seed_from_u64(3)),
        &corners,
    );
    assert!(matches!(
        solve_planar(&c, &corners[..3], &img[..3]),
        Err(GeometryError::TooFewPoints(3, 4))
    ));
    assert!(matches!(
        solve_planar(&c, &kps, &img),
        Err(GeometryError::Mismatch(64, 4))
    ));
    let mut nan = img.clone();
    nan[1][0] = f64::NAN;
    assert!(matches!(
        solve_planar(&c, &corners, &nan),
        Err(GeometryError::NotFinite)
    ));
    let line = [[0.0, 0.0], [0.01, 0.0], [0.02, 0.0], [0.03, 0.0]];
    assert!(solve_planar(&c, &line, &img).is_err());
    // Corners a detections file may hold: refused before any SVD, which never returned on them.
    let started = std::time::Instant::now();
    let tiny = [[0.0, 0.0], [5e-324, 0.0], [5e-324, 5e-324], [0.0, 5e-324]];
    assert_eq!(
        solve_planar(&c, &corners, &tiny).unwrap_err(),
        GeometryError::Subnormal(5e-324)
    );
    let far = [[0.0, 0.0], [1e300, 0.0], [1e300, 1e300], [0.0, 1e300]];
    assert_eq!(
        solve_planar(&c, &corners, &far).unwrap_err(),
        GeometryError::TooLarge(1e300)
    );
    assert!(started.elapsed().as_secs_f64() < 1.0);
    let mut bad = c;
    bad.fx = 0.0;
    assert!(matches!(
        solve_planar(&bad, &corners, &img),
        Err(GeometryError::BadCamera(_))
    ));
}

#[test]
fn a_steep_view_picks_the_right_of_two_planar_solutions_and_reports_the_other() {
    // Few, noisy points on a small far marker: the classic flip case. Started from the mirrored
    // pose, the solver must still return the true one (both are tried).
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (kps, _) = tag_points();
    let c = camera();
    let mut ratios = Vec::new();
    for _ in 0..30 {
        let truth = random_pose(&mut rng);
        let pixels = project(&c, &truth, &kps);
        let sol = solve_planar(&c, &kps, &pixels).unwrap();
        assert!(sol.pose.rotation_error_deg(&truth) < 1e-4);
        let flipped = mirrored(&truth);
        let from_flip = refine(&c, &kps, &pixels, flipped).unwrap();
        // The mirrored start is a different local minimum (or falls back to the truth).
        assert!(from_flip.rms_px >= sol.rms_px - 1e-12);
        if let Some(r) = sol.ambiguity_ratio {
            assert!(r >= 1.0, "{r}");
            ratios.push(r);
        }
    }
    assert!(!ratios.is_empty(), "some views have a second minimum");
}

#[test]
fn the_reported_uncertainty_matches_the_scatter_of_noisy_solutions() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let (kps, _) = tag_points();
    let c = camera();
    let truth = random_pose(&mut rng);
    let exact = project(&c, &truth, &kps);
    let (mut errors, mut predicted) = (Vec::new(), Vec::new());
    for _ in 0..200 {
        let noisy: Vec<[f64; 2]> = exact
            .iter()
            .map(|p| {
                let (u1, u2): (f64, f64) = (rng.random_range(1e-12..1.0), rng.random());
                let r = 0.5 * (-2.0 * u1.ln()).sqrt();
                [
                    p[0] + r * (std::f64::consts::TAU * u2).cos(),
                    p[1] + r * (std::f64::consts::TAU * u2).sin(),
                ]
            })
            .collect();
        let sol = solve_planar(&c, &kps, &noisy).unwrap();
        errors.push((sol.pose.translation - truth.translation)[2]);
        predicted.push(sol.covariance.unwrap()[(5, 5)].sqrt());
    }
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    let mean_predicted = predicted.iter().sum::<f64>() / predicted.len() as f64;
    // The depth's scatter over 200 draws against the Jacobian's prediction: within 25 %.
    assert!(
        (rms / mean_predicted - 1.0).abs() < 0.25,
        "scatter {rms:.2e} m, predicted {mean_predicted:.2e} m"
    );
}

/// A marker square to the camera, 1 m ahead: its axes drawn from the principal point, x to the
/// right and y up in the image (the marker frame's y is up, the image's down), z along the line
/// of sight (a point), each 0.1 m long → f × 0.1 px.
#[test]
fn axes_of_a_facing_marker_point_right_up_and_at_the_camera() {
    let camera = Camera {
        width: 640,
        height: 480,
        fx: 500.0,
        fy: 500.0,
        cx: 320.0,
        cy: 240.0,
        distortion: [0.0; 5],
    };
    // Facing the camera: the marker's z (out of its face) points back along the camera's -z.
    let pose = Pose {
        rotation: Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI),
        translation: Vector3::new(0.0, 0.0, 1.0),
    };
    let [origin, x, y, z] = axes_in_image(&pose, &camera, 0.1);
    let near = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]) < 1e-9;
    assert!(near(origin, [320.0, 240.0]), "{origin:?}");
    assert!(near(x, [370.0, 240.0]), "{x:?}");
    assert!(near(y, [320.0, 190.0]), "{y:?}");
    assert!(near(z, [320.0, 240.0]), "{z:?}");
}
