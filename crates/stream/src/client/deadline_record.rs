//! Deadline record: how often the predictor's deadlines came true (a tile predicted to enter the
//! view at t entered within a prediction step of t; an entry nobody foresaw counts against it).

use std::collections::{HashMap, VecDeque};

/// Outcomes kept: the record reflects the predictor's recent seconds, not the whole session.
const WINDOW: usize = 64;

/// Outcomes needed before the record says anything (a cold record trusts no deadline).
const MIN_OUTCOMES: usize = 16;

/// Share of recent outcomes that must have come true for the client to act on a deadline alone
/// (set aside a prefetch that cannot be on time behind the ones that can): nine in ten, set
/// before measuring and not swept on the evaluation traces.
pub(super) const TRUSTED_SHARE: f64 = 0.9;

/// The predictor's track record on deadlines (see the module docs).
#[derive(Debug, Default)]
pub(super) struct DeadlineRecord {
    /// Tile -> the absolute time it was first predicted to enter the view (while pending).
    pending: HashMap<usize, f64>,
    /// Most recent outcomes, oldest first: `true` when the deadline came true.
    outcomes: VecDeque<bool>,
    /// The last plan had a prediction (an entry no deadline foresaw is then a miss).
    predicting: bool,
}

impl DeadlineRecord {
    /// Whether the plan just made had a prediction (not reactive, not in the fallback period).
    pub(super) fn set_predicting(&mut self, on: bool) {
        self.predicting = on;
    }

    /// A prediction made now: `tile` (not in view) enters at absolute time `due`. The first
    /// prediction of a pending tile is the one judged; later revisions do not replace it.
    pub(super) fn predicted(&mut self, tile: usize, due: f64) {
        if due.is_finite() {
            self.pending.entry(tile).or_insert(due);
        }
    }

    /// `tile` entered the view at `now`. A deadline is the predicted sample before the first
    /// one that sees the tile, so a right prediction enters within `(due, due + step]`; it came
    /// true when `now` is within one more `step` of that interval (the prediction's resolution).
    /// An entry while predicting that no pending deadline foresaw is a miss as well: a predictor
    /// that foresees few of the tiles that come is not one to act on.
    pub(super) fn entered(&mut self, tile: usize, now: f64, step: f64) {
        let Some(due) = self.pending.remove(&tile) else {
            if self.predicting {
                self.push(false);
            }
            return;
        };
        let step = step.max(0.0);
        let d = now - due;
        self.push(d >= -step - 1e-9 && d <= 2.0 * step + 1e-9);
    }

    /// Deadlines passed by more than `2 step` without the tile entering: they did not come true.
    pub(super) fn expire(&mut self, now: f64, step: f64) {
        let mut missed = 0;
        self.pending.retain(|_, due| {
            let keep = now - *due <= 2.0 * step.max(0.0) + 1e-9;
            if !keep {
                missed += 1;
            }
            keep
        });
        for _ in 0..missed {
            self.push(false);
        }
    }

    fn push(&mut self, hit: bool) {
        if self.outcomes.len() == WINDOW {
            self.outcomes.pop_front();
        }
        self.outcomes.push_back(hit);
    }

    /// Share of the recent outcomes that came true; `None` before `MIN_OUTCOMES` outcomes.
    pub(super) fn share(&self) -> Option<f64> {
        (self.outcomes.len() >= MIN_OUTCOMES).then(|| {
            self.outcomes.iter().filter(|&&h| h).count() as f64 / self.outcomes.len() as f64
        })
    }

    /// Whether the recent deadlines came true often enough to act on one alone.
    pub(super) fn trusted(&self) -> bool {
        self.share().is_some_and(|s| s >= TRUSTED_SHARE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cold_record_trusts_nothing_and_kept_deadlines_earn_trust() {
        let mut r = DeadlineRecord::default();
        r.set_predicting(true);
        assert!(!r.trusted());
        for k in 0..MIN_OUTCOMES {
            let due = k as f64;
            r.predicted(k, due);
            // A later revision does not replace the first prediction.
            r.predicted(k, due + 5.0);
            // Within (due, due + step]: the sample that saw it.
            r.entered(k, due + 0.5, 0.5);
        }
        assert_eq!(r.share(), Some(1.0));
        assert!(r.trusted());
    }

    #[test]
    fn wrong_deadlines_unforeseen_entries_and_tiles_that_never_came_lose_trust() {
        let mut r = DeadlineRecord::default();
        r.set_predicting(true);
        for k in 0..WINDOW {
            r.predicted(k, 1.0);
            r.entered(k, 1.9, 0.5);
        }
        assert!(r.trusted());
        // Ten entries 1.2 s after their deadline (more than 2 steps), ten predicted tiles that
        // never enter.
        for k in 0..10 {
            r.predicted(1000 + k, 10.0);
            r.entered(1000 + k, 11.2, 0.5);
            r.predicted(2000 + k, 10.0);
        }
        r.expire(10.9, 0.5);
        assert_eq!(r.share(), Some(54.0 / 64.0));
        r.expire(11.1, 0.5);
        assert_eq!(r.share(), Some(44.0 / 64.0));
        assert!(!r.trusted());
        // An entry no prediction foresaw counts against the record while predicting...
        r.entered(5, 11.0, 0.5);
        assert_eq!(r.share(), Some(43.0 / 64.0));
        // ...and not when there was no prediction (reactive, fallback).
        r.set_predicting(false);
        r.entered(6, 11.0, 0.5);
        assert_eq!(r.share(), Some(43.0 / 64.0));
        // Non-finite times are ignored, not panicked on.
        r.predicted(7, f64::NAN);
        r.expire(f64::INFINITY, f64::NAN);
        assert!(r.share().is_some_and(|s| s.is_finite()));
    }

    #[test]
    fn an_early_entry_within_a_step_counts_and_one_earlier_does_not() {
        let mut r = DeadlineRecord::default();
        for k in 0..MIN_OUTCOMES {
            r.predicted(k, 5.0);
            r.entered(k, 4.6, 0.5);
        }
        assert_eq!(r.share(), Some(1.0));
        for k in 0..MIN_OUTCOMES {
            r.predicted(100 + k, 5.0);
            r.entered(100 + k, 4.4, 0.5);
        }
        assert_eq!(r.share(), Some(0.5));
    }
}
