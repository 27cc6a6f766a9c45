//! Training samples synthesised on the fly in worker threads ahead of the optimiser, for any
//! stage. Sample `i` of a run is a pure function of (run seed, i), and batches are handed out
//! strictly in sample order whatever thread made them, so a run resumed at step s sees exactly
//! the batches an uninterrupted run would have seen: the data stream's "random state" is the
//! next sample index.

use crate::synth::image_seed;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Makes the sample of a seed (called from worker threads).
pub type MakeSample<S> = Arc<dyn Fn(u64) -> Result<S, String> + Send + Sync>;

/// Worker threads synthesising samples `first, first + 1, …` of a run, delivered in order.
pub struct Loader<S> {
    rx: Option<Receiver<(u64, Result<S, String>)>>,
    next: u64,
    pending: BTreeMap<u64, Result<S, String>>,
    stop: Arc<AtomicBool>,
    workers: Vec<JoinHandle<()>>,
    /// Time spent blocked waiting for samples.
    pub waited: Duration,
}

impl<S: Send + 'static> Loader<S> {
    pub fn start(make: MakeSample<S>, seed: u64, first: u64, threads: usize, ahead: usize) -> Self {
        let (tx, rx) = sync_channel(ahead.max(1));
        let counter = Arc::new(AtomicU64::new(first));
        let stop = Arc::new(AtomicBool::new(false));
        let workers = (0..threads.max(1))
            .map(|_| {
                let (tx, counter, stop, make) =
                    (tx.clone(), counter.clone(), stop.clone(), make.clone());
                std::thread::spawn(move || {
                    while !stop.load(Ordering::Relaxed) {
                        let i = counter.fetch_add(1, Ordering::Relaxed);
                        let sample = make(image_seed(seed, i));
                        if tx.send((i, sample)).is_err() {
                            break;
                        }
                    }
                })
            })
            .collect();
        Self {
            rx: Some(rx),
            next: first,
            pending: BTreeMap::new(),
            stop,
            workers,
            waited: Duration::ZERO,
        }
    }

    /// The next `n` samples in order.
    pub fn batch(&mut self, n: usize) -> Result<Vec<S>, String> {
        let mut out = Vec::with_capacity(n);
        while out.len() < n {
            if let Some(s) = self.pending.remove(&self.next) {
                out.push(s?);
                self.next += 1;
                continue;
            }
            let start = Instant::now();
            let (i, s) = self
                .rx
                .as_ref()
                .and_then(|rx| rx.recv().ok())
                .ok_or("the data workers stopped")?;
            self.waited += start.elapsed();
            self.pending.insert(i, s);
        }
        Ok(out)
    }
}

impl<S> Drop for Loader<S> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Dropping the receiver fails the workers' pending sends, so they stop.
        self.rx = None;
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}
