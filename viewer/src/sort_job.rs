//! Depth-sort jobs of the renderer: back-to-front keys for every resident batch (tile-local
//! positions through each tile's camera-z row), sorted on a worker thread natively, inline on wasm.

use std::sync::Arc;

use crate::sort::{RadixSorter, back_to_front_key};

/// The CPU copy kept per uploaded batch: tile-local positions and their slots (for depth keys).
#[derive(Debug)]
pub(crate) struct Chunk {
    pub(crate) positions: Vec<[f32; 3]>,
    pub(crate) slots: Vec<u32>,
}

/// A depth-sort request: batches with the depth row (camera z of the tile frame) to apply.
pub(crate) struct SortJob {
    pub(crate) generation: u64,
    pub(crate) chunks: Vec<(Arc<Chunk>, [f32; 4])>,
}

/// A finished sort: the slots back to front, for the job of `generation`.
pub(crate) struct SortResult {
    pub(crate) generation: u64,
    pub(crate) order: Vec<u32>,
    pub(crate) ms: f64,
}

/// Computes back-to-front keys for every splat of the job and sorts the slots.
pub(crate) fn run_sort(
    job: &SortJob,
    sorter: &mut RadixSorter,
    pairs: &mut Vec<u64>,
) -> SortResult {
    let t0 = crate::clock::now_ms();
    pairs.clear();
    for (chunk, r) in &job.chunks {
        pairs.extend(chunk.positions.iter().zip(&chunk.slots).map(|(p, &slot)| {
            let z = r[0] * p[0] + r[1] * p[1] + r[2] * p[2] + r[3];
            ((back_to_front_key(z) as u64) << 32) | slot as u64
        }));
    }
    sorter.sort_packed(pairs);
    let order = pairs.iter().map(|&p| p as u32).collect();
    SortResult {
        generation: job.generation,
        order,
        ms: crate::clock::now_ms() - t0,
    }
}

/// Runs sorts on a worker thread (native) or inline (wasm).
pub(crate) struct Sorter {
    #[cfg(not(target_arch = "wasm32"))]
    tx: Option<std::sync::mpsc::Sender<SortJob>>,
    #[cfg(not(target_arch = "wasm32"))]
    rx: std::sync::mpsc::Receiver<SortResult>,
    #[cfg(not(target_arch = "wasm32"))]
    worker: Option<std::thread::JoinHandle<()>>,
    /// Inline sorter (wasm, or native when the worker could not start).
    inline: RadixSorter,
    inline_pairs: Vec<u64>,
    inline_result: Option<SortResult>,
    /// A job was submitted and its result not yet taken.
    pub(crate) in_flight: bool,
}

impl Sorter {
    #[cfg(not(target_arch = "wasm32"))]
    pub(crate) fn new() -> Self {
        let (tx, job_rx) = std::sync::mpsc::channel::<SortJob>();
        let (res_tx, rx) = std::sync::mpsc::channel::<SortResult>();
        let worker = std::thread::Builder::new()
            .name("splat-sort".into())
            .spawn(move || {
                let mut sorter = RadixSorter::new();
                let mut pairs = Vec::new();
                while let Ok(mut job) = job_rx.recv() {
                    // Only the newest request matters.
                    while let Ok(newer) = job_rx.try_recv() {
                        job = newer;
                    }
                    if res_tx
                        .send(run_sort(&job, &mut sorter, &mut pairs))
                        .is_err()
                    {
                        break;
                    }
                }
            })
            .ok();
        let tx = worker.as_ref().map(|_| tx);
        Sorter {
            tx,
            rx,
            worker,
            inline: RadixSorter::new(),
            inline_pairs: Vec::new(),
            inline_result: None,
            in_flight: false,
        }
    }

    #[cfg(target_arch = "wasm32")]
    pub(crate) fn new() -> Self {
        Sorter {
            inline: RadixSorter::new(),
            inline_pairs: Vec::new(),
            inline_result: None,
            in_flight: false,
        }
    }

    pub(crate) fn submit(&mut self, job: SortJob) {
        self.in_flight = true;
        #[cfg(not(target_arch = "wasm32"))]
        if let Some(tx) = &self.tx {
            match tx.send(job) {
                Ok(()) => return,
                Err(e) => {
                    self.tx = None;
                    self.inline_result =
                        Some(run_sort(&e.0, &mut self.inline, &mut self.inline_pairs));
                    return;
                }
            }
        }
        self.inline_result = Some(run_sort(&job, &mut self.inline, &mut self.inline_pairs));
    }

    /// The finished result, if any; blocks for it when `wait`.
    pub(crate) fn poll(&mut self, wait: bool) -> Option<SortResult> {
        if !self.in_flight {
            return None;
        }
        if let Some(r) = self.inline_result.take() {
            self.in_flight = false;
            return Some(r);
        }
        self.poll_worker(wait)
    }

    #[cfg(not(target_arch = "wasm32"))]
    fn poll_worker(&mut self, wait: bool) -> Option<SortResult> {
        let got = if wait {
            self.rx.recv().ok()
        } else {
            self.rx.try_recv().ok()
        };
        if got.is_some() {
            self.in_flight = false;
        } else if wait {
            // The worker is gone: nothing will arrive.
            self.in_flight = false;
            self.tx = None;
        }
        got
    }

    #[cfg(target_arch = "wasm32")]
    fn poll_worker(&mut self, _wait: bool) -> Option<SortResult> {
        // Sorts run inline on wasm: nothing can be pending here.
        self.in_flight = false;
        None
    }

    pub(crate) fn bytes(&self) -> usize {
        self.inline.bytes() + self.inline_pairs.capacity() * 8
    }
}

impl Drop for Sorter {
    fn drop(&mut self) {
        #[cfg(not(target_arch = "wasm32"))]
        {
            self.tx = None;
            if let Some(w) = self.worker.take() {
                let _ = w.join();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sort_job_orders_back_to_front_over_tiles() {
        let a = Arc::new(Chunk {
            positions: vec![[0.0, 0.0, 1.0], [0.0, 0.0, 5.0]],
            slots: vec![10, 11],
        });
        let b = Arc::new(Chunk {
            positions: vec![[0.0, 0.0, 3.0]],
            slots: vec![20],
        });
        // Tile b is shifted 10 m farther along the camera's z.
        let job = SortJob {
            generation: 7,
            chunks: vec![(a, [0.0, 0.0, 1.0, 0.0]), (b, [0.0, 0.0, 1.0, 10.0])],
        };
        let r = run_sort(&job, &mut RadixSorter::new(), &mut Vec::new());
        assert_eq!(r.order, vec![20, 11, 10]);
        assert_eq!(r.generation, 7);
    }
}
