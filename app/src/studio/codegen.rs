//! Codebook generation without freezing the window: a worker thread on the desktop, reporting
//! progress through atomics. A browser has no threads here, so there it runs in one go with a
//! smaller candidate budget.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use tagsmith::codebook::{generate, GenerateParams, GenerateReport};

pub struct CodegenJob {
    tried: Arc<AtomicU64>,
    kept: Arc<AtomicU64>,
    pub budget: u64,
    result: Arc<Mutex<Option<Result<GenerateReport, String>>>>,
    /// The design revision the job was started for; a result for an older layout is dropped.
    pub revision: u64,
}

impl CodegenJob {
    pub fn start(params: GenerateParams, revision: u64) -> Self {
        let job = Self {
            tried: Arc::default(),
            kept: Arc::default(),
            budget: params.max_candidates,
            result: Arc::default(),
            revision,
        };
        let (tried, kept, result) = (job.tried.clone(), job.kept.clone(), job.result.clone());
        let work = move || {
            let report = generate(&params, &mut |t, k| {
                tried.store(t, Ordering::Relaxed);
                kept.store(k as u64, Ordering::Relaxed);
            })
            .map_err(|e| e.to_string());
            *result.lock().expect("only this job writes the result") = Some(report);
        };
        #[cfg(not(target_arch = "wasm32"))]
        std::thread::spawn(work);
        #[cfg(target_arch = "wasm32")]
        work();
        job
    }

    /// (candidates tried, codes kept so far).
    pub fn progress(&self) -> (u64, u64) {
        (
            self.tried.load(Ordering::Relaxed),
            self.kept.load(Ordering::Relaxed),
        )
    }

    /// The result, once: `None` while the job runs.
    pub fn take_result(&self) -> Option<Result<GenerateReport, String>> {
        self.result.lock().ok()?.take()
    }
}

/// The candidate budget a generation gets on this platform.
pub fn default_budget() -> u64 {
    if cfg!(target_arch = "wasm32") {
        1_000_000
    } else {
        20_000_000
    }
}
