//! The Detect panel on a video: frames played, paused or stepped through with the detector's
//! tracking (stage 2 alone on the markers it follows, the whole detector on the first frame,
//! every few frames and after a loss), each frame's time shown. The frames are the opened image
//! moved along a smooth camera path, so that any photograph (or sample) plays as a sequence on
//! the desktop and in the browser alike.

use tagsmith::detect::{Detector, Frame, TrackParams, Tracker};
use tagsmith::geometry::{warp_bilinear, Homography};
use tagsmith::image::GrayImage;

/// Frames of a sequence made from one photograph.
pub const FRAMES: usize = 60;

pub struct Sequence {
    pub name: String,
    pub frames: Vec<GrayImage>,
    /// The frame shown last (`None` before the first step).
    pub shown: Option<usize>,
    pub playing: bool,
    tracker: Tracker,
    /// Each frame's detection time so far, in milliseconds, and whether the whole detector ran.
    pub times: Vec<(f64, bool)>,
}

impl Sequence {
    /// `photo` moved along a camera path: drifting, turning, zooming and tilting slowly, as a
    /// hand-held camera does, over `count` frames of the photograph's size.
    pub fn moving(name: &str, photo: &GrayImage, count: usize) -> Self {
        let frames = (0..count)
            .map(|k| {
                let t = k as f64 / (count.max(2) - 1) as f64 * std::f64::consts::TAU;
                warp_bilinear(
                    photo,
                    &camera_path(photo.width, photo.height, t),
                    photo.width,
                    photo.height,
                    128,
                )
            })
            .collect();
        Self {
            name: name.to_string(),
            frames,
            shown: None,
            playing: true,
            tracker: Tracker::new(TrackParams::default()),
            times: Vec::new(),
        }
    }

    /// The next frame's index, or `None` at the end.
    pub fn next_index(&self) -> Option<usize> {
        let next = self.shown.map_or(0, |i| i + 1);
        (next < self.frames.len()).then_some(next)
    }

    /// Detects on the next frame (through the tracker): its index and what it gave, or `None`
    /// at the end (playing stops there).
    pub fn step(&mut self, detector: &Detector) -> Option<(usize, Frame, f64)> {
        let Some(index) = self.next_index() else {
            self.playing = false;
            return None;
        };
        let clock = tagsmith::io::Stopwatch::start();
        let frame = self.tracker.next(detector, &self.frames[index], None);
        let ms = clock.ms();
        self.times.push((ms, frame.full));
        self.shown = Some(index);
        Some((index, frame, ms))
    }

    /// Median frame time so far, and the same over the frames the tracker alone read.
    pub fn medians(&self) -> (Option<f64>, Option<f64>) {
        let median = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            (!v.is_empty()).then(|| v[v.len() / 2])
        };
        let all = median(self.times.iter().map(|(ms, _)| *ms).collect());
        let tracked = median(
            (self.times.iter())
                .filter(|(_, full)| !full)
                .map(|(ms, _)| *ms)
                .collect(),
        );
        (all, tracked)
    }
}

/// Frame pixel → photograph pixel at phase `t` (0 to 2π) of the path: the photograph's corners
/// turned, scaled, shifted and tilted about its centre.
fn camera_path(width: u32, height: u32, t: f64) -> Homography {
    let (cx, cy) = (width as f64 / 2.0, height as f64 / 2.0);
    let angle = 0.08 * t.sin();
    let scale = 1.0 + 0.06 * (2.0 * t).sin();
    let (dx, dy) = (25.0 * t.sin(), 15.0 * (1.5 * t).sin());
    let (tilt_x, tilt_y) = (2e-5 * t.sin(), 1e-5 * t.cos());
    let (c, s) = (angle.cos() * scale, angle.sin() * scale);
    let moved = |[x, y]: [f64; 2]| {
        let (u, v) = (x - cx, y - cy);
        let w = 1.0 + tilt_x * u + tilt_y * v;
        [(c * u - s * v) / w + cx + dx, (s * u + c * v) / w + cy + dy]
    };
    let (w, h) = (width as f64, height as f64);
    let corners = [[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]];
    let photo = corners.map(moved);
    Homography::from_points(&corners, &photo).unwrap_or_else(|_| {
        Homography::from_points(&corners, &corners).expect("the identity on a rectangle")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_path_starts_where_the_photograph_is_and_stays_near_it() {
        let h = camera_path(640, 480, 0.0);
        let p = h.apply([320.0, 240.0]);
        assert!(
            (p[0] - 320.0).abs() < 1e-6 && (p[1] - 240.0).abs() < 1e-6,
            "{p:?}"
        );
        for k in 0..20 {
            let q = camera_path(640, 480, k as f64 * 0.3).apply([320.0, 240.0]);
            assert!(
                (q[0] - 320.0).abs() < 40.0 && (q[1] - 240.0).abs() < 30.0,
                "{q:?}"
            );
        }
    }
}
