//! Codebook generation as a background [`Job`]. A browser runs it inline, so there it gets a
//! smaller candidate budget.

use super::job::{Job, Progress};
use tagsmith::codebook::{generate, GenerateParams, GenerateReport};

pub struct CodegenJob {
    job: Job<Result<GenerateReport, String>>,
    /// The design revision the job was started for; a result for an older layout is dropped.
    pub revision: u64,
}

impl CodegenJob {
    pub fn start(params: GenerateParams, revision: u64) -> Self {
        let budget = params.max_candidates.max(1);
        let job = Job::start(move |r| {
            // The core's search has no stop hook, so a cancelled job runs to its budget unseen;
            // at least a job cancelled before it began costs nothing.
            if r.is_cancelled() {
                return Err("cancelled".into());
            }
            generate(&params, &mut |tried, kept| {
                r.progress(
                    tried as f32 / budget as f32,
                    format!("{kept} codes, {tried} candidates"),
                );
            })
            .map_err(|e| e.to_string())
        });
        Self { job, revision }
    }

    pub fn progress(&self) -> Progress {
        self.job.progress()
    }

    /// Stops waiting for the job: its result will be dropped.
    pub fn cancel(&self) {
        self.job.cancel();
    }

    /// The result, once: `None` while the job runs.
    pub fn take_result(&mut self) -> Option<Result<GenerateReport, String>> {
        self.job
            .take()
            .map(|outcome| outcome.and_then(|report| report))
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
