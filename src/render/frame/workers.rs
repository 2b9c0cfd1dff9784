//! Which of a render's workers finishes it: the last one to leave of those that started. A
//! worker the pool starts only after the work is gone (a loaded machine schedules it late)
//! neither waits for nor delays the finish.

use std::sync::atomic::{AtomicUsize, Ordering};

/// Set once the render is finished: a worker that starts later has nothing to do.
const CLOSED: usize = 1 << (usize::BITS - 1);

/// The workers of a render that started and have not yet left.
#[derive(Default)]
pub(super) struct ActiveWorkers(AtomicUsize);

impl ActiveWorkers {
    /// Counts a starting worker in; false when the render is already finished.
    pub(super) fn join(&self) -> bool {
        self.0
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |n| {
                (n & CLOSED == 0).then_some(n + 1)
            })
            .is_ok()
    }

    /// Counts out a joined worker that found no work left to take; true for the last one,
    /// which closes the render to later workers and must finish it.
    pub(super) fn leave(&self) -> bool {
        let previous = self
            .0
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |n| {
                Some(if n == 1 { CLOSED } else { n - 1 })
            })
            .unwrap_or(0);
        previous == 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_last_worker_to_leave_finishes_and_later_workers_find_the_render_closed() {
        let workers = ActiveWorkers::default();
        assert!(workers.join());
        assert!(workers.join());
        assert!(!workers.leave());
        // A third worker starting while one is still at work joins it.
        assert!(workers.join());
        assert!(!workers.leave());
        assert!(workers.leave());
        // The render is finished: a worker the pool starts only now has nothing to do.
        assert!(!workers.join());
        assert!(!workers.join());
    }

    #[test]
    fn exactly_one_of_many_racing_workers_finishes() {
        for _ in 0..200 {
            let workers = ActiveWorkers::default();
            let finishers = AtomicUsize::new(0);
            std::thread::scope(|scope| {
                for _ in 0..4 {
                    scope.spawn(|| {
                        if workers.join() && workers.leave() {
                            finishers.fetch_add(1, Ordering::Relaxed);
                        }
                    });
                }
            });
            assert_eq!(finishers.load(Ordering::Relaxed), 1);
        }
    }
}
