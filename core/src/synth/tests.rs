use super::*;

fn family(name: &str) -> Family {
    crate::builtin::get(name).unwrap().unwrap()
}

#[test]
fn the_same_seed_gives_the_same_image_and_truth() {
    let f = family("apriltag-36h11");
    for mode in [Mode::Quad, Mode::Patch] {
        let c = SynthConfig::new(mode);
        let (a, b) = (
            synthesize(&f, &c, 11).unwrap(),
            synthesize(&f, &c, 11).unwrap(),
        );
        assert_eq!(a.image, b.image);
        assert_eq!(a.truth, b.truth);
        assert_ne!(synthesize(&f, &c, 12).unwrap().image, a.image);
    }
}

#[test]
fn a_shared_scene_shows_every_family_the_same_poses_light_and_noise() {
    let mut c = SynthConfig::new(Mode::Camera);
    c.markers = [3, 3];
    c.side_m = [0.05, 0.05];
    c.distance_m = [0.3, 0.6];
    c.shared_scene = true;
    let scene = |name: &str| synthesize(&family(name), &c, 7).unwrap().truth;
    let look = |t: &Truth| {
        let poses: Vec<_> = t.markers.iter().map(|m| m.pose.clone()).collect();
        (poses, t.applied.clone())
    };
    let tag = scene("apriltag-36h11");
    assert_eq!(tag.markers.len(), 3);
    for other in ["apriltag-xo-36h11", "aruco-6x6_250"] {
        assert_eq!(look(&scene(other)), look(&tag), "{other}");
    }
}

#[test]
fn in_a_shared_scene_a_still_value_and_a_one_pixel_blur_render_alike() {
    // A motion sweep's still values draw no blur; the rest of the scene must not notice.
    let mut still = SynthConfig::new(Mode::Camera);
    still.markers = [1, 1];
    still.augment.noise_sigma = [4.0, 9.0];
    still.augment.motion_blur_probability = 0.0;
    still.shared_scene = true;
    let mut one_pixel = still.clone();
    one_pixel.augment.motion_blur_probability = 1.0;
    one_pixel.augment.motion_blur_length = [1, 1];
    let f = family("apriltag-36h11");
    let (a, b) = (
        synthesize(&f, &still, 3).unwrap(),
        synthesize(&f, &one_pixel, 3).unwrap(),
    );
    assert_eq!(a.truth.applied.noise_sigma, b.truth.applied.noise_sigma);
    assert!(a.image == b.image, "the noise changed with the blur draw");
}

/// Darkness-weighted centroid of every visible dot of a RuneTag rendered by the camera, against
/// the ground truth: the truth sits on the rendered keypoints, with and without barrel distortion.
fn mean_dot_error(k1: Option<f64>, view_deg: f64) -> (f64, usize) {
    let f = family("runetag");
    let mut c = SynthConfig::new(Mode::Camera);
    c.augment = augment::AugmentRanges::none();
    c.markers = [1, 1];
    c.distance_m = [0.15, 0.2];
    c.side_m = [0.1, 0.1];
    c.view_angle_deg = [0.0, view_deg];
    if let Some(k1) = k1 {
        c.augment.barrel_probability = 1.0;
        c.augment.barrel_k1 = [k1, k1];
    }
    let (mut total, mut count) = (0.0, 0);
    for seed in 0..3 {
        let s = synthesize(&f, &c, seed).unwrap();
        assert_eq!(s.truth.applied.barrel_k1, k1);
        let m = &s.truth.markers[0];
        let img = &s.image;
        let cam = s.truth.camera.unwrap();
        let p = m.pose.as_ref().unwrap();
        let pose = Pose::from(&p.pose);
        let pixel = |u: [f64; 2]| {
            let q = marker_plane_points(&f, p.side_m, &[u])[0];
            cam.project(pose.apply([q[0], q[1], 0.0]))
        };
        for (k, kp) in m.keypoints.iter().zip(f.keypoints()) {
            if k.symbol != Some(1) || !k.visible {
                continue;
            }
            // The dot's radius in pixels; the window covers the dot and part of the gap around it,
            // never a neighbour.
            let edge = pixel([kp.pos[0] + kp.size / 2.0, kp.pos[1]]);
            let centre = pixel(kp.pos);
            let r = 1.25 * (edge[0] - centre[0]).hypot(edge[1] - centre[1]);
            let (mut sw, mut sx, mut sy) = (0.0, 0.0, 0.0);
            for y in (k.y - r).floor() as i64..=(k.y + r).ceil() as i64 {
                for x in (k.x - r).floor() as i64..=(k.x + r).ceil() as i64 {
                    let inside = (x as f64 - k.x).hypot(y as f64 - k.y) <= r;
                    if !inside || x < 0 || y < 0 || x >= img.width as i64 || y >= img.height as i64
                    {
                        continue;
                    }
                    let w = 1.0 - img.get(x as u32, y as u32) as f64 / 255.0;
                    sw += w;
                    sx += w * x as f64;
                    sy += w * y as f64;
                }
            }
            if sw > 1.0 {
                total += (sx / sw - k.x).hypot(sy / sw - k.y);
                count += 1;
            }
        }
    }
    (total / count as f64, count)
}

/// The bound is 0.5 px; these are tighter so that a sub-pixel slip is caught (a raster
/// scale rounded to whole pixels once gave 0.2 px). Facing the camera the centroid is exact; tilted,
/// a large dot's centroid moves slightly off its projected centre (perspective), hence 0.15.
#[test]
fn rendered_keypoints_sit_where_the_truth_says() {
    for (k1, view, bound) in [
        (None, 0.0, 0.05),
        (None, 40.0, 0.15),
        (Some(-0.2), 40.0, 0.15),
    ] {
        let (error, n) = mean_dot_error(k1, view);
        eprintln!("barrel {k1:?}, view ≤ {view}°: mean keypoint error {error:.3} px over {n} dots");
        assert!(n > 100, "{n} dots measured");
        assert!(
            error < bound,
            "mean error {error} px (barrel {k1:?}, view ≤ {view}°)"
        );
    }
}

#[test]
fn patches_map_the_roi_to_a_random_quad_near_the_template() {
    let f = family("apriltag-xo-36h11");
    let c = SynthConfig::new(Mode::Patch);
    for seed in 0..20 {
        let s = synthesize(&f, &c, seed).unwrap();
        let roi = &s.truth.markers[0].roi;
        let w = c.width as f64;
        let inside = |v: f64, lo: f64, hi: f64| v >= lo * w - 1e-6 && v <= hi * w + 1e-6;
        assert!(
            inside(roi[0][0], 0.05, 0.25) && inside(roi[0][1], 0.05, 0.25),
            "{roi:?}"
        );
        assert!(
            inside(roi[2][0], 0.75, 0.95) && inside(roi[2][1], 0.75, 0.95),
            "{roi:?}"
        );
        assert_eq!(s.truth.markers[0].keypoints.len(), 64);
    }
}

#[test]
fn camera_mode_records_the_pose_that_projects_the_roi() {
    let f = family("apriltag-36h11");
    let mut c = SynthConfig::new(Mode::Camera);
    c.augment = augment::AugmentRanges::none();
    let s = synthesize(&f, &c, 5).unwrap();
    let cam = s.truth.camera.unwrap();
    for m in &s.truth.markers {
        let p = m.pose.as_ref().unwrap();
        let pose = Pose::from(&p.pose);
        let plane = marker_plane_points(&f, p.side_m, &f.roi_points()[..4]);
        for (q, truth) in plane.iter().zip(&m.roi) {
            let px = cam.project(pose.apply([q[0], q[1], 0.0]));
            assert!((px[0] - truth[0]).abs() < 1e-6 && (px[1] - truth[1]).abs() < 1e-6);
        }
    }
}

#[test]
fn a_moving_marker_is_blurred_alone() {
    let f = family("apriltag-36h11");
    let mut c = SynthConfig::new(Mode::Quad);
    c.augment = augment::AugmentRanges::none();
    c.markers = [2, 2];
    let still = synthesize(&f, &c, 21).unwrap();
    c.augment.marker_motion_blur_probability = 1.0;
    c.augment.motion_blur_length = [9, 9];
    let moving = synthesize(&f, &c, 21).unwrap();
    assert_eq!(
        moving.truth.applied.marker_motion_blur.len(),
        moving.truth.markers.len()
    );
    assert_eq!(still.truth.markers, moving.truth.markers);
    // Inside a marker the pixels change; a pixel far from every marker does not.
    assert_ne!(still.image, moving.image);
    let far = (0..still.image.pixels.len()).find(|&i| {
        let (x, y) = ((i % 320) as f64, (i / 320) as f64);
        moving.truth.markers.iter().all(|m| {
            x < m.bbox[0] - 20.0
                || x > m.bbox[2] + 20.0
                || y < m.bbox[1] - 20.0
                || y > m.bbox[3] + 20.0
        })
    });
    let far = far.expect("some pixel lies away from the markers");
    assert_eq!(still.image.pixels[far], moving.image.pixels[far]);
}

#[test]
fn impossible_configs_name_the_value() {
    let f = family("apriltag-36h11");
    let mut c = SynthConfig::new(Mode::Quad);
    c.width = 8;
    assert!(matches!(
        synthesize(&f, &c, 1),
        Err(SynthError::ImageSize {
            width: 8,
            height: _
        })
    ));
    let mut c = SynthConfig::new(Mode::Camera);
    c.fov_deg = 200.0;
    assert!(matches!(
        synthesize(&f, &c, 1),
        Err(SynthError::Geometry(GeometryError::BadCamera(_)))
    ));
}

/// A steep view off the image's centre must still show the camera the marker's printed side:
/// turned 65–75° from the optical axis, 4 of the 65 Difficult views of the development sets and
/// 1 of the harness's faced away (drawn mirrored — a view no camera gets, counted as a miss for
/// every detector). The turn from the axis stays the one asked for.
#[test]
fn steep_views_face_the_camera_along_their_line_of_sight() {
    let camera = Camera::from_diagonal_fov(1280, 960, 70.0).unwrap();
    let min_cos = MAX_LINE_OF_SIGHT_DEG.to_radians().cos();
    for seed in 0..400 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let view = 75f64.to_radians();
        let pose = random_pose(&mut rng, &camera, 0.5, view);
        let normal = pose.rotation * Vector3::z();
        let sight = -pose.translation.normalize();
        assert!(normal.dot(&sight) >= min_cos - 1e-9, "seed {seed}");
        let from_axis = (-normal.z).clamp(-1.0, 1.0).acos();
        assert!((from_axis - view).abs() < 1e-9, "seed {seed}");
    }
}
