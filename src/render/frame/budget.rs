//! The frame budget: which units of the progressive plan a budgeted render traces, and how
//! far the renders of an unchanged frame got.

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use crate::render::progressive::{FIXED_FIRST_STRIDE, Plan};

use super::{Inner, RenderSetup};

/// A budgeted render traces a subset of the pixels (see [`crate::render::progressive`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Budget {
    /// Wall-clock seconds a render should take.
    pub seconds: f32,
    /// Pixels to trace per render instead of what the measured speed allows (`budgetPixels`),
    /// for reproducible progressive renders.
    pub pixels: Option<u32>,
}

/// What a budgeted render traces: units `start..` of its plan, as far as time allows.
pub(super) struct BudgetedRun {
    pub(super) plan: Plan,
    /// Units traced by earlier renders of the unchanged frame.
    pub(super) start: usize,
    /// Units traced whatever the time: the coarsest level of a timed render; every level
    /// down to stride 16 with a fixed pixel count (reproducible captures).
    pub(super) mandatory: usize,
    /// Units the measured speed allows (the mandatory units, and at least one more than
    /// `start` so that refinement always progresses, are traced whatever the time).
    pub(super) planned_end: usize,
    pub(super) deadline: Option<Instant>,
    /// Measured seconds of one thread's tracing per traced point: a unit that would end
    /// after the deadline is not started.
    pub(super) seconds_per_point: Option<f64>,
    /// The first unit a worker declined: units `start..first_declined` are traced.
    pub(super) first_declined: AtomicUsize,
    /// Nanoseconds the threads spent tracing units, summed.
    pub(super) tracing_nanos: AtomicU64,
    /// When the render was asked for: its deadline and overhead count from here.
    pub(super) began: Instant,
    /// Nanoseconds from `began` until the last traced unit ended.
    pub(super) tracing_end_nanos: AtomicU64,
}

impl BudgetedRun {
    /// Whether unit `index` is not traced in this render. Monotonic in `index` and in time, so
    /// the traced units always form a prefix.
    pub(super) fn declines(&self, index: usize) -> bool {
        let Some(unit) = self.plan.units.get(index) else {
            return true;
        };
        let late = |deadline: Instant| {
            let expected = self
                .seconds_per_point
                .map_or(0.0, |seconds| seconds * unit.traced_count() as f64);
            Instant::now() + Duration::from_secs_f64(expected) >= deadline
        };
        index >= self.mandatory.max(self.start + 1)
            && (index >= self.planned_end || self.deadline.is_some_and(late))
    }

    /// Records that a unit ended now, after `nanos` of tracing.
    pub(super) fn unit_traced(&self, nanos: u64) {
        self.tracing_nanos.fetch_add(nanos, Ordering::Relaxed);
        let end = self.began.elapsed().as_nanos() as u64;
        self.tracing_end_nanos.fetch_max(end, Ordering::Relaxed);
    }

    /// Seconds of the render (so far) after its last unit was traced: the fill and finish.
    pub(super) fn seconds_after_tracing(&self) -> f64 {
        let end = self.tracing_end_nanos.load(Ordering::Relaxed) as f64 * 1e-9;
        (self.began.elapsed().as_secs_f64() - end).max(0.0)
    }
}

/// How far the budgeted renders of an unchanged frame got.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Refinement {
    pub(super) scene_version: u64,
    pub(super) width: u32,
    pub(super) height: u32,
    /// Units traced so far.
    pub(super) done: usize,
    pub(super) total: usize,
}

/// The budgeted part of a render, if it has a budget: where refinement of the unchanged frame
/// goes on, and how many units the measured speed allows. `None` renders every pixel (no
/// budget, no camera, or an image already complete that accumulation refines further).
pub(super) fn budgeted_run(
    setup: &RenderSetup,
    inner: &mut Inner,
    threads: usize,
) -> Option<BudgetedRun> {
    let began = setup.requested;
    let budget = setup.budget?;
    let camera = setup.camera.as_ref()?;
    let plan = Plan::new(&camera.viewports(setup.width, setup.height));
    let start = inner
        .refinement
        .filter(|r| {
            r.scene_version == setup.scene_version
                && r.width == setup.width
                && r.height == setup.height
                && r.total == plan.units.len()
                && inner.output.is_some()
        })
        .map_or(0, |r| r.done);
    if start == plan.units.len() && setup.accumulate {
        return None;
    }
    // Tracing stops in time for the fill (as long as it took last time), the hand-over, and
    // the margin the frame's recent overruns call for.
    let tracing_seconds = inner
        .deadline
        .tracing_seconds(f64::from(budget.seconds), inner.throughput.overhead_seconds);
    let planned_pixels = match budget.pixels {
        Some(pixels) => f64::from(pixels),
        None => {
            let primitives = setup
                .scene
                .instances
                .iter()
                .flat_map(|instance| &instance.surfaces)
                .map(|surface| surface.geometry.bvh.primitive_count())
                .sum();
            inner
                .throughput
                .pixels_for(tracing_seconds, primitives, setup.settings.fast, threads)
        }
    };
    // Units after `start` until their pixels reach the plan.
    let mut planned_end = start;
    let mut pixels = 0.0;
    while planned_end < plan.units.len() && pixels < planned_pixels {
        pixels += plan.units[planned_end].pixel_count() as f64;
        planned_end += 1;
    }
    let deadline = budget
        .pixels
        .is_none()
        .then(|| began + Duration::from_secs_f64(tracing_seconds));
    // A timed render that falls behind stops at whatever level it reached; one with a fixed
    // pixel count always traces as far as stride 16, as its captures must not depend on time.
    let mandatory = match budget.pixels {
        Some(_) => plan.units_through_stride(FIXED_FIRST_STRIDE),
        None => plan.mandatory_units(),
    };
    Some(BudgetedRun {
        first_declined: AtomicUsize::new(plan.units.len()),
        tracing_nanos: AtomicU64::new(0),
        began,
        tracing_end_nanos: AtomicU64::new(0),
        mandatory,
        seconds_per_point: inner
            .throughput
            .pixels_per_thread_second
            .map(|rate| 1.0 / rate),
        plan,
        start,
        planned_end,
        deadline,
    })
}
