//! Long work (codebook generation; later training and benchmarks) without freezing the window.
//! On the desktop the work runs on its own thread; a browser build has no threads here, so there
//! it runs inline when started. Either way the UI polls the [`Job`] each frame for its progress
//! and, once, its result.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

/// How far a job has got.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Progress {
    /// 0 to 1.
    pub fraction: f32,
    pub message: String,
}

/// The work's side of a job: where it reports progress and learns that it was cancelled.
pub struct Reporter {
    shared: Arc<Shared>,
}

impl Reporter {
    pub fn progress(&self, fraction: f32, message: impl Into<String>) {
        *lock(&self.shared.progress) = Progress {
            fraction: fraction.clamp(0.0, 1.0),
            message: message.into(),
        };
    }

    /// Work checks this between steps and stops early when it is set; what it returns then is
    /// dropped.
    pub fn is_cancelled(&self) -> bool {
        self.shared.cancelled.load(Ordering::Relaxed)
    }
}

struct Shared {
    progress: Mutex<Progress>,
    cancelled: AtomicBool,
}

/// The result of a job's work, or why there is none.
type Outcome<T> = Result<T, String>;

/// A piece of work running in the background, owned by the UI.
pub struct Job<T> {
    shared: Arc<Shared>,
    result: Arc<Mutex<Option<Outcome<T>>>>,
    taken: bool,
}

impl<T: Send + 'static> Job<T> {
    /// Starts `work`, which reports through the [`Reporter`] it is given.
    pub fn start(work: impl FnOnce(&Reporter) -> T + Send + 'static) -> Self {
        let shared = Arc::new(Shared {
            progress: Mutex::default(),
            cancelled: AtomicBool::new(false),
        });
        let result = Arc::new(Mutex::new(None));
        let reporter = Reporter {
            shared: shared.clone(),
        };
        let slot = result.clone();
        let run = move || {
            // A panic in the work would otherwise leave the UI waiting for a result forever.
            let outcome =
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| work(&reporter)))
                    .map_err(|panic| panic_message(&*panic));
            *lock(&slot) = Some(outcome);
        };
        #[cfg(not(target_arch = "wasm32"))]
        std::thread::spawn(run);
        #[cfg(target_arch = "wasm32")]
        run();
        Self {
            shared,
            result,
            taken: false,
        }
    }
}

impl<T> Job<T> {
    pub fn progress(&self) -> Progress {
        lock(&self.shared.progress).clone()
    }

    /// Asks the work to stop. Its result, if it still produces one, is never handed out.
    pub fn cancel(&self) {
        self.shared.cancelled.store(true, Ordering::Relaxed);
    }

    pub fn is_cancelled(&self) -> bool {
        self.shared.cancelled.load(Ordering::Relaxed)
    }

    /// The result, exactly once: `None` while the work runs, after it was taken, and for a
    /// cancelled job. `Err` says why the work stopped without one (it panicked).
    pub fn take(&mut self) -> Option<Outcome<T>> {
        if self.taken || self.is_cancelled() {
            return None;
        }
        let outcome = lock(&self.result).take()?;
        self.taken = true;
        Some(outcome)
    }

    /// Whether the work has stopped (whether or not its result was taken).
    pub fn is_finished(&self) -> bool {
        self.taken || lock(&self.result).is_some()
    }
}

/// A poisoned lock only means the other side panicked while holding it; the data is still whole.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

fn panic_message(panic: &(dyn std::any::Any + Send)) -> String {
    let text = panic
        .downcast_ref::<&str>()
        .copied()
        .or_else(|| panic.downcast_ref::<String>().map(String::as_str))
        .unwrap_or("no message");
    format!("the background work failed: {text}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc;
    use std::time::{Duration, Instant};

    fn wait_until<T>(job: &mut Job<T>, what: &str) -> Outcome<T> {
        let start = Instant::now();
        loop {
            if let Some(r) = job.take() {
                return r;
            }
            assert!(
                start.elapsed() < Duration::from_secs(20),
                "timed out: {what}"
            );
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    #[test]
    fn progress_arrives_while_the_work_runs_and_the_result_once() {
        // The work waits for the test at each step, so the test sees every step's progress.
        let (go, wait) = mpsc::channel::<()>();
        let mut job = Job::start(move |r| {
            for step in 1..=4 {
                wait.recv().unwrap();
                r.progress(step as f32 / 4.0, format!("step {step}"));
            }
            wait.recv().unwrap();
            "done"
        });
        for step in 1..=4 {
            go.send(()).unwrap();
            let start = Instant::now();
            while job.progress().message != format!("step {step}") {
                assert!(
                    start.elapsed() < Duration::from_secs(20),
                    "no progress {step}"
                );
                std::thread::sleep(Duration::from_millis(1));
            }
            assert_eq!(job.progress().fraction, step as f32 / 4.0);
            assert!(job.take().is_none(), "no result before the work returns");
            assert!(!job.is_finished());
        }
        go.send(()).unwrap();
        assert_eq!(wait_until(&mut job, "the result"), Ok("done"));
        assert!(job.is_finished());
        assert!(job.take().is_none(), "the result is handed out once");
    }

    #[test]
    fn cancel_stops_the_work_and_drops_its_result() {
        let steps = Arc::new(std::sync::atomic::AtomicUsize::new(0));
        let counted = steps.clone();
        let mut job = Job::start(move |r| {
            while !r.is_cancelled() {
                counted.fetch_add(1, Ordering::Relaxed);
                std::thread::sleep(Duration::from_millis(1));
            }
            "stopped"
        });
        let start = Instant::now();
        while steps.load(Ordering::Relaxed) == 0 {
            assert!(start.elapsed() < Duration::from_secs(20), "never started");
            std::thread::sleep(Duration::from_millis(1));
        }
        job.cancel();
        let start = Instant::now();
        while !job.is_finished() {
            assert!(
                start.elapsed() < Duration::from_secs(20),
                "cancel did not stop it"
            );
            std::thread::sleep(Duration::from_millis(1));
        }
        let after = steps.load(Ordering::Relaxed);
        std::thread::sleep(Duration::from_millis(20));
        assert_eq!(
            steps.load(Ordering::Relaxed),
            after,
            "no work after stopping"
        );
        assert!(job.take().is_none(), "a cancelled job hands out nothing");
    }

    #[test]
    fn a_panic_in_the_work_is_reported_instead_of_waiting_forever() {
        let mut job: Job<()> = Job::start(|_| panic!("out of cheese"));
        let e = wait_until(&mut job, "the failure").unwrap_err();
        assert!(e.contains("out of cheese"), "{e}");
    }
}
