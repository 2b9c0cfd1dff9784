//! When a budgeted render stops tracing: the budget, less the time its fill and hand-over are
//! predicted to take, less a margin learnt from how late the frame's recent renders ended.

/// Share of the budget tracing may use before the time after tracing is taken off: timing
/// noise and the last unit in flight.
const TRACING_SHARE: f64 = 0.85;

/// Share of the budget the margin shrinks by after a render on time. An overrun grows it by
/// the overrun, so it settles where overruns times their size balance this: with overruns of
/// a fifth of the budget, about one render in twenty overruns.
const ON_TIME_DECAY: f64 = 0.01;

/// Largest margin, as a share of the budget: the coarsest level is traced whatever the time.
const MAX_MARGIN: f64 = 0.5;

/// The tracing deadline of a frame's budgeted renders, adapted to their overruns (a feedback
/// controller on lateness, one per frame).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeadlineControl {
    /// Seconds taken off every render's tracing time, learnt from overruns.
    pub margin_seconds: f64,
}

impl DeadlineControl {
    /// Seconds from the request after which a render of `budget` seconds starts no unit, when
    /// the time after its tracing (fill, hand-over) is predicted to be `after_tracing`.
    pub fn tracing_seconds(&self, budget: f64, after_tracing: f64) -> f64 {
        (TRACING_SHARE * budget - after_tracing - self.margin_seconds).max(0.0)
    }

    /// Records that a render of `budget` seconds took `elapsed` seconds from its request until
    /// its image was handed over.
    pub fn record(&mut self, budget: f64, elapsed: f64) {
        let overrun = elapsed - budget;
        let margin = if overrun > 0.0 {
            self.margin_seconds + overrun
        } else {
            self.margin_seconds - ON_TIME_DECAY * budget
        };
        self.margin_seconds = margin.clamp(0.0, MAX_MARGIN * budget);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overruns_move_the_deadline_earlier_and_renders_on_time_move_it_back() {
        let mut control = DeadlineControl::default();
        let budget = 0.016;
        let nominal = control.tracing_seconds(budget, 0.002);
        assert!((nominal - (0.85 * 0.016 - 0.002)).abs() < 1e-12);
        // Two renders 3 ms late: tracing ends 6 ms earlier.
        control.record(budget, 0.019);
        control.record(budget, 0.019);
        let after_overruns = control.tracing_seconds(budget, 0.002);
        assert!(
            (nominal - after_overruns - 0.006).abs() < 1e-9,
            "{after_overruns}"
        );
        // Renders on time give the time back, 0.16 ms each, until the margin is gone.
        control.record(budget, 0.012);
        let recovering = control.tracing_seconds(budget, 0.002);
        assert!(
            (recovering - after_overruns - 0.00016).abs() < 1e-9,
            "{recovering}"
        );
        for _ in 0..100 {
            control.record(budget, 0.012);
        }
        assert_eq!(control.margin_seconds, 0.0);
        assert_eq!(control.tracing_seconds(budget, 0.002), nominal);
    }

    #[test]
    fn the_margin_is_bounded_and_tracing_time_never_negative() {
        let mut control = DeadlineControl::default();
        for _ in 0..10 {
            control.record(0.016, 0.5);
        }
        assert!((control.margin_seconds - 0.008).abs() < 1e-12);
        assert_eq!(control.tracing_seconds(0.016, 0.010), 0.0);
        // A render exactly on its budget does not count as late.
        let mut on_time = DeadlineControl::default();
        on_time.record(0.033, 0.033);
        assert_eq!(on_time.margin_seconds, 0.0);
    }
}
