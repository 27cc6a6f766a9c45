//! Detection off the UI thread. The Detect panel hands each detection to an [`Offload`] and
//! polls it once a frame, so the window keeps drawing while the networks run: on the desktop
//! the work runs on a thread of its own; in a browser, where the page has one thread, it runs in
//! a web worker that loads the same wasm module (`app/worker.js`), and requests and replies
//! cross as JSON with the pixels transferred, not copied. Either way the same [`Server`] does
//! the work, so the browser and the desktop read the same markers.

mod server;
#[cfg(target_arch = "wasm32")]
pub mod web;

pub use server::{build_detector, shown, written, Server};

use crate::settings::DetectorSettings;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use tagsmith::detect::{Detection, Timings};
use tagsmith::family::FamilySpec;
use tagsmith::geometry::Quad;

/// One image to detect on, with the detector to use.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct DetectRequest {
    /// Built-in families, read with their shipped weights.
    pub families: Vec<String>,
    /// The design being edited and its trained model file (desktop only), or `None` for the
    /// shipped model of its layout.
    pub design: Option<(FamilySpec, Option<PathBuf>)>,
    pub settings: DetectorSettings,
    /// The image's name, for the log line and the detections file.
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// Row-major gray bytes: sent beside the JSON in a browser (a transferred buffer).
    #[serde(skip)]
    pub pixels: Vec<u8>,
}

/// A marker as the panel shows it: the CLI's detection plus what the overlay draws.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Shown {
    pub detection: Detection,
    /// Stage 1's ROI it was read from.
    pub roi: Quad,
    /// The alignment with the rendering moved its keypoints.
    pub refined: bool,
    /// Its pose's axes in the image (origin, x, y, z ends), when posed.
    pub axes: Option<[[f64; 2]; 4]>,
}

/// What the detector found in one image and how long it took.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detected {
    pub markers: Vec<Shown>,
    pub timings: Timings,
    pub time_ms: f64,
    /// The detector's name, as the detections file records it.
    pub detector: String,
}

pub type Reply = Result<Detected, String>;

/// A request's number: the panel keeps only the reply to its latest.
pub type Ticket = u64;

/// Where detections run. At most one is in flight; the panel sends the next when it is back.
pub struct Offload {
    transport: Transport,
    in_flight: Option<Ticket>,
    issued: Ticket,
}

impl Offload {
    /// Starts the background side; `ctx` is asked to repaint when a reply arrives.
    pub fn new(ctx: &egui::Context) -> Self {
        Self {
            transport: Transport::start(ctx.clone()),
            in_flight: None,
            issued: 0,
        }
    }

    pub fn is_busy(&self) -> bool {
        self.in_flight.is_some()
    }

    /// Sends a request and returns its ticket. Call it only when [`Offload::is_busy`] is false.
    pub fn send(&mut self, request: DetectRequest) -> Ticket {
        debug_assert!(self.in_flight.is_none(), "one request at a time");
        self.issued += 1;
        self.in_flight = Some(self.issued);
        self.transport.send(self.issued, request);
        self.issued
    }

    /// The reply to the request in flight, once it is back.
    pub fn poll(&mut self) -> Option<(Ticket, Reply)> {
        let ticket = self.in_flight?;
        let reply = self.transport.poll(ticket)?;
        self.in_flight = None;
        Some((ticket, reply))
    }
}

#[cfg(not(target_arch = "wasm32"))]
use native::Transport;
#[cfg(target_arch = "wasm32")]
use web::Transport;

/// The desktop's side: a thread that owns the [`Server`] and lives as long as the panel.
#[cfg(not(target_arch = "wasm32"))]
mod native {
    use super::{DetectRequest, Reply, Server, Ticket};
    use std::sync::mpsc::{channel, Receiver, Sender};

    pub struct Transport {
        requests: Sender<(Ticket, DetectRequest)>,
        replies: Receiver<(Ticket, Reply)>,
    }

    impl Transport {
        pub fn start(ctx: egui::Context) -> Self {
            let (requests, incoming) = channel::<(Ticket, DetectRequest)>();
            let (outgoing, replies) = channel();
            std::thread::spawn(move || {
                let mut server = Server::default();
                // Ends when the panel drops its side.
                for (ticket, request) in incoming {
                    // A panic is reported as this request's failure; the thread serves on.
                    let reply = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                        server.serve(request)
                    }))
                    .unwrap_or_else(|_| Err("the detection failed unexpectedly (a panic)".into()));
                    if outgoing.send((ticket, reply)).is_err() {
                        break;
                    }
                    ctx.request_repaint();
                }
            });
            Self { requests, replies }
        }

        pub fn send(&mut self, ticket: Ticket, request: DetectRequest) {
            // A send fails only when the thread is gone; poll then reports it.
            let _ = self.requests.send((ticket, request));
        }

        pub fn poll(&mut self, ticket: Ticket) -> Option<Reply> {
            use std::sync::mpsc::TryRecvError;
            loop {
                match self.replies.try_recv() {
                    Ok((t, reply)) if t == ticket => return Some(reply),
                    Ok(_) => continue,
                    Err(TryRecvError::Empty) => return None,
                    Err(TryRecvError::Disconnected) => {
                        return Some(Err("the detection thread stopped unexpectedly".into()))
                    }
                }
            }
        }
    }
}

#[cfg(all(test, not(target_arch = "wasm32")))]
mod tests {
    use super::*;
    use std::time::{Duration, Instant};

    fn wait(offload: &mut Offload) -> (Ticket, Reply) {
        let start = Instant::now();
        loop {
            if let Some(reply) = offload.poll() {
                return reply;
            }
            assert!(start.elapsed() < Duration::from_secs(60), "no reply");
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    fn request(families: &[&str]) -> DetectRequest {
        let (_, bytes) = crate::studio::detect::samples().next().unwrap();
        let image = tagsmith::image::decode(bytes, &Default::default()).unwrap();
        DetectRequest {
            families: families.iter().map(|f| f.to_string()).collect(),
            design: None,
            settings: DetectorSettings::default(),
            name: "sample".into(),
            width: image.width,
            height: image.height,
            pixels: image.pixels.to_vec(),
        }
    }

    /// The reply comes back on the ticket it was asked with, the thread serves the next
    /// request after a refused one, and a reply carries what the detector found.
    #[test]
    fn requests_are_answered_in_the_background_one_at_a_time() {
        let mut offload = Offload::new(&egui::Context::default());
        assert!(!offload.is_busy());
        let first = offload.send(request(&[]));
        assert!(offload.is_busy());
        let (ticket, reply) = wait(&mut offload);
        assert_eq!(ticket, first);
        assert!(reply.unwrap_err().contains("at least one family"));
        assert!(!offload.is_busy());
        let second = offload.send(request(&["aruco-6x6_250"]));
        assert_ne!(second, first);
        let (ticket, reply) = wait(&mut offload);
        assert_eq!(ticket, second);
        let detected = reply.unwrap();
        assert!(!detected.markers.is_empty());
        assert!(
            detected.detector.contains("aruco-6x6_250"),
            "{}",
            detected.detector
        );
        assert!(offload.poll().is_none(), "one reply per request");
    }
}
