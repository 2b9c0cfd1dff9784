//! Which of a render's workers finishes it: the last one to leave of those that started. A
//! worker the pool starts only after the work is gone (a loaded machine schedules it late)
//! neither waits for nor delays the finish. A worker stopped by an internal error still leaves,
//! and the render says through the status callback that its image is incomplete.

use std::any::Any;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use crate::device::status::{
    ANARI_SEVERITY_ERROR, ANARI_STATUS_UNKNOWN_ERROR, Source, StatusMessage, StatusSink, panic_text,
};

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

/// Makes the next tile any render takes fail with a panic, once: for the test that a render
/// losing a worker still finishes and says why. Never set by the device.
#[doc(hidden)]
pub static FAIL_NEXT_TILE: AtomicBool = AtomicBool::new(false);

/// Panics when a test asked the next tile to fail ([`FAIL_NEXT_TILE`]).
#[inline]
pub(super) fn fail_if_asked() {
    if FAIL_NEXT_TILE.load(Ordering::Relaxed) && FAIL_NEXT_TILE.swap(false, Ordering::AcqRel) {
        panic!("a tile failure injected by a test (FAIL_NEXT_TILE)");
    }
}

/// Where a render's workers report an internal error: the device's status sink and the frame
/// (`None`: nowhere). Reported once per render, however many workers fail.
pub(super) struct FailureReport {
    target: Option<(Arc<StatusSink>, Source)>,
    reported: AtomicBool,
}

impl FailureReport {
    pub(super) fn new(target: Option<(Arc<StatusSink>, Source)>) -> FailureReport {
        FailureReport {
            target,
            reported: AtomicBool::new(false),
        }
    }

    /// Reports the panic `payload` that stopped a worker (the first one only).
    pub(super) fn report(&self, payload: &(dyn Any + Send)) {
        if self.reported.swap(true, Ordering::AcqRel) {
            return;
        }
        if let Some((sink, frame)) = &self.target {
            sink.report(&StatusMessage {
                severity: ANARI_SEVERITY_ERROR,
                code: ANARI_STATUS_UNKNOWN_ERROR,
                source: *frame,
                text: format!(
                    "anariRenderFrame: a render thread stopped on an internal error ({}); the \
                     frame is finished without the tiles it had left, so its image is incomplete",
                    panic_text(payload)
                ),
            });
        }
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
