//! Frames: the lifecycle of a render on the device's own threads (start, workers, finish,
//! accumulation, mapping and the completion callback). What the workers do per tile, how
//! channels are encoded, the frame budget, sample sequences and anaglyph compositing live in
//! the submodules.

mod anaglyph;
mod budget;
mod channels;
mod cyclopean_views;
mod eye_groups;
mod fast_block;
mod pixel_work;
mod records;
mod samples;
mod tile;
mod uniform_shading_avx2;
mod workers;

use std::any::Any;
use std::collections::HashMap;
use std::ffi::c_void;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::Instant;

use glam::Vec4;

use crate::camera::{Camera, EyeRays, PixelSet};
use crate::device::datatype::*;
use crate::device::frame::Frame;
use crate::device::memory::{self, TooBig};
use crate::device::property::PropertyValue;
use crate::device::status::{Source, StatusSink};
use crate::render::interleave::lattice_size;
use crate::render::progressive::{ColorPixels, DeadlineControl, Plan, SurfaceGuide, Throughput};
use crate::render::renderer::RendererSettings;
use crate::scene::world::SceneSnapshot;

pub use budget::Budget;
use budget::{BudgetedRun, Refinement, budgeted_run};
pub use channels::CHANNELS;
use channels::{
    Channel, ChannelFormat, ChannelKind, FrameTarget, allocate_channels, new_buffer_bytes,
    value_range,
};
#[doc(hidden)]
pub use pixel_work::PLAIN_PER_PIXEL_PATH;
use pixel_work::PixelWork;
use tile::{TileScratch, render_tile};
pub use workers::FAIL_NEXT_TILE;
use workers::{ActiveWorkers, FailureReport, fail_if_asked};

/// Side of the square tiles the threads share out.
pub const TILE_SIZE: u32 = 32;

/// `ANARIFrameCompletionCallback`: (userData, device, frame).
pub type ANARIFrameCompletionCallback =
    Option<unsafe extern "C" fn(user_data: *const c_void, device: *mut c_void, frame: *mut c_void)>;

/// Everything a render needs, captured when anariRenderFrame is called.
pub struct RenderSetup {
    pub width: u32,
    pub height: u32,
    pub scene: Arc<SceneSnapshot>,
    pub camera: Option<Arc<dyn Camera>>,
    pub settings: RendererSettings,
    /// Requested channel types by channel name.
    pub channels: HashMap<&'static str, ANARIDataType>,
    pub accumulate: bool,
    /// Device-wide commit count: accumulation restarts whenever it changes.
    pub scene_version: u64,
    pub completion: Option<(ANARIFrameCompletionCallback, usize, usize, usize)>,
    /// Frame-time budget (`ANARI_CAVETRACE_FRAME_BUDGET`); `None` renders every pixel.
    pub budget: Option<Budget>,
    /// When anariRenderFrame was called: a budget counts from here.
    pub requested: Instant,
    /// Cluster hook: the tiles this rank traces of a frame shared out among MPI ranks.
    pub tile_split: Option<Arc<crate::render::cluster::TileSplit>>,
    /// Where a render whose worker fails on an internal error says so: the device's status
    /// sink and the frame (`None`: nowhere).
    pub status: Option<(Arc<StatusSink>, Source)>,
}

/// Why a render could not start.
#[derive(Debug, PartialEq, Eq)]
pub enum StartError {
    /// The new buffers are more than the system has available (checked before allocating).
    Exceeds(TooBig),
    /// The allocator refused them.
    OutOfMemory,
}

/// Encoded channels of a finished render; mapped pointers point into these.
pub struct Output {
    pub width: u32,
    pub height: u32,
    pub channels: HashMap<&'static str, (ANARIDataType, Vec<u8>)>,
}

struct Job {
    setup: RenderSetup,
    cancel: AtomicBool,
    next_tile: AtomicUsize,
    tiles_x: u32,
    tile_count: usize,
    /// Interleaved stereo: the two eyes' pixel sets, each traced as a lattice of its own.
    interleave: Option<[PixelSet; 2]>,
    /// Workers at work: the last to leave finishes the render.
    active_workers: ActiveWorkers,
    /// Threads rendering this job.
    workers: usize,
    channels: Mutex<Vec<Channel>>,
    /// `channels`' buffers written by the workers straight from their tiles, in the same
    /// order: only for renders whose tiles are distinct squares of the frame (not budgeted,
    /// not interleaved), each traced once by one worker; `channels` is then not locked until
    /// the last worker has left.
    frame_targets: Option<Vec<FrameTarget>>,
    /// The formats of `channels`, in the same order, readable without the lock.
    formats: Vec<ChannelFormat>,
    /// What every pixel needs done, decided when the render starts.
    pixel_work: PixelWork,
    /// Accumulation pass number (0 = first).
    pass: u32,
    /// Running colour sum over the accumulated passes (accumulation only).
    color_sum: Option<Mutex<Vec<Vec4>>>,
    started: Instant,
    /// A budgeted render: which units it traces (`next_tile` counts from `start`).
    budgeted: Option<BudgetedRun>,
    /// Where a worker stopped by an internal error is reported.
    failure: FailureReport,
}

fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(|e| e.into_inner())
}

#[derive(Default)]
struct Inner {
    /// The render in flight, if any.
    running: Option<Arc<Job>>,
    output: Option<Arc<Output>>,
    /// Mapped outputs by channel (one entry per map call), alive until unmapped.
    mapped: HashMap<String, Vec<Arc<Output>>>,
    /// The render thread running the completion callback, which may query and map the frame
    /// it is told about without waiting for itself.
    callback_thread: Option<std::thread::ThreadId>,
    duration: f32,
    /// Accumulation state: colour sum, passes so far and what they were rendered with.
    accumulation: Option<(Vec<Vec4>, u32, u64, u32, u32)>,
    /// Budgeted renders: how far refinement got, and how fast tracing was.
    refinement: Option<Refinement>,
    throughput: Throughput,
    /// When timed budgeted renders stop tracing, adapted to their overruns.
    deadline: DeadlineControl,
    /// Fraction of the pixels of the last image that were traced (not filled).
    progress: f32,
    /// Smallest and largest value of the last render's parallax channel (NaN without one or
    /// without a hit).
    parallax_range: [f32; 2],
}

impl Inner {
    fn in_callback(&self) -> bool {
        self.callback_thread == Some(std::thread::current().id())
    }
}

#[derive(Default)]
pub struct FrameState {
    inner: Mutex<Inner>,
    finished: Condvar,
    /// Whether the last render was reported as unlit (see
    /// [`crate::render::diagnostics::report_unlit`]).
    reported_unlit: AtomicBool,
    /// Cluster hook: what this rank's last render across MPI ranks traced and exchanged.
    pub cluster: crate::render::cluster::FrameTraffic,
}

impl FrameState {
    fn lock(&self) -> MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Records whether this render is unlit; true only when the one before it was not, so an
    /// unlit frame is reported once however often it renders.
    pub fn first_unlit_render(&self, unlit: bool) -> bool {
        let reported_before = self.reported_unlit.swap(unlit, Ordering::AcqRel);
        unlit && !reported_before
    }

    /// Starts a render. The size was checked by the caller; buffers beyond the memory available
    /// or refused by the allocator are an error, and nothing is rendered.
    pub fn start(
        self: &Arc<Self>,
        setup: RenderSetup,
        pool: &crate::device::pool::WorkerPool,
    ) -> Result<(), StartError> {
        // One render per frame at a time: a second request waits for the first.
        self.wait();
        let pixels = setup.width as usize * setup.height as usize;
        let threads = pool.thread_count();
        let (pass, color_sum, previous_output, budgeted) = {
            let mut inner = self.lock();
            // Everything new is checked against the memory available before any of it is
            // allocated (the allocator alone may promise memory the zero-filling cannot get).
            memory::check(new_buffer_bytes(&setup, &inner)?).map_err(StartError::Exceeds)?;
            let budgeted = budgeted_run(&setup, &mut inner, threads);
            let (pass, sum) = match inner.accumulation.take() {
                Some((sum, passes, version, w, h))
                    if setup.accumulate
                        && version == setup.scene_version
                        && w == setup.width
                        && h == setup.height =>
                {
                    (passes, Some(sum))
                }
                _ if setup.accumulate => {
                    let mut sum = Vec::new();
                    sum.try_reserve_exact(pixels)
                        .map_err(|_| StartError::OutOfMemory)?;
                    sum.resize(pixels, Vec4::ZERO);
                    (0, Some(sum))
                }
                _ => (0, None),
            };
            // The last image's buffers are reused unless the application has them mapped; a
            // render that refines the last image copies them then.
            let continues = budgeted.as_ref().is_some_and(|run| run.start > 0);
            let previous = match inner.output.take().map(Arc::try_unwrap) {
                Some(Ok(output)) => Some(output),
                Some(Err(shared)) => {
                    let copy = continues.then(|| Output {
                        width: shared.width,
                        height: shared.height,
                        channels: shared.channels.clone(),
                    });
                    inner.output = Some(shared);
                    copy
                }
                None => None,
            };
            (pass, sum, previous, budgeted)
        };
        let mut channels = allocate_channels(&setup, previous_output)?;
        let interleave = interleaved_sets(&setup);
        let frame_targets = (budgeted.is_none() && interleave.is_none()).then(|| {
            let width = setup.width;
            channels
                .iter_mut()
                .map(|channel| FrameTarget::of(channel, width))
                .collect()
        });
        // Interleaved eyes are traced as lattices of their own pixels, both of one size.
        let (lattice_width, lattice_height, eyes) = match interleave {
            Some(sets) => {
                let (width, height) = lattice_size(sets[0], setup.width, setup.height);
                (width, height, 2)
            }
            None => (setup.width, setup.height, 1),
        };
        let tiles_x = lattice_width.div_ceil(TILE_SIZE);
        let tiles_y = lattice_height.div_ceil(TILE_SIZE);
        let workers = threads;
        let formats: Vec<ChannelFormat> = channels.iter().map(|c| c.format).collect();
        let pixel_work = PixelWork::of(&setup, &formats);
        let failure = FailureReport::new(setup.status.clone());
        let job = Arc::new(Job {
            pixel_work,
            failure,
            setup,
            cancel: AtomicBool::new(false),
            next_tile: AtomicUsize::new(0),
            tiles_x,
            tile_count: (tiles_x * tiles_y * eyes) as usize,
            interleave,
            active_workers: ActiveWorkers::default(),
            workers,
            formats,
            channels: Mutex::new(channels),
            frame_targets,
            pass,
            color_sum: color_sum.map(Mutex::new),
            started: Instant::now(),
            budgeted,
        });
        self.lock().running = Some(Arc::clone(&job));
        for _ in 0..workers {
            let frame = Arc::clone(self);
            let job = Arc::clone(&job);
            pool.submit(move || frame.work(&job));
        }
        Ok(())
    }

    /// One worker's share: tiles until none are left, then the last worker finishes the frame.
    fn work(&self, job: &Job) {
        if !job.active_workers.join() {
            return;
        }
        // A worker stopped by an internal error still leaves, so that the render finishes
        // (without the tiles left, and says so) and nobody waits for it for ever.
        if let Err(payload) = catch_unwind(AssertUnwindSafe(|| self.trace_tiles(job))) {
            job.cancel.store(true, Ordering::Release);
            job.failure.report(payload.as_ref());
        }
        if job.active_workers.leave() {
            self.finish(job);
        }
    }

    /// Takes tiles and traces them until none are left (or the render is cancelled).
    fn trace_tiles(&self, job: &Job) {
        let eyes = prepare_eyes(&job.setup);
        let mut scratch = TileScratch::default();
        while !job.cancel.load(Ordering::Acquire) {
            fail_if_asked();
            let next = job.next_tile.fetch_add(1, Ordering::AcqRel);
            match &job.budgeted {
                None if next >= job.tile_count => break,
                // Cluster hook: another rank's tile is skipped; this rank's are timed.
                None if job.setup.tile_split.as_ref().is_some_and(|s| !s.owns(next)) => {}
                None => {
                    let started = Instant::now();
                    match job.interleave {
                        Some(sets) => {
                            render_tile(job, &eyes, job.interleaved_tile(next, sets), &mut scratch)
                        }
                        None => render_tile(job, &eyes, job.frame_tile(next), &mut scratch),
                    }
                    if let Some(split) = &job.setup.tile_split {
                        split.record(next, started.elapsed());
                    }
                }
                Some(run) => {
                    let index = run.start + next;
                    if run.declines(index) {
                        run.first_declined.fetch_min(index, Ordering::AcqRel);
                        break;
                    }
                    let started = Instant::now();
                    render_tile(job, &eyes, run.plan.units[index], &mut scratch);
                    run.unit_traced(started.elapsed().as_nanos() as u64);
                }
            }
        }
    }

    fn finish(&self, job: &Job) {
        let setup = &job.setup;
        let mut channels = std::mem::take(&mut *lock(&job.channels));
        let cancelled = job.cancel.load(Ordering::Acquire);
        // How far a budgeted render got, and the untraced pixels filled.
        let refined = job.budgeted.as_ref().map(|run| {
            let done = run.first_declined.load(Ordering::Acquire);
            let threads = job.workers;
            fill_untraced(
                &run.plan,
                setup.width,
                (run.start, done),
                &mut channels,
                threads,
            );
            (run, done)
        });
        let parallax_range = channels
            .iter()
            .find(|channel| channel.format.kind == ChannelKind::Parallax)
            .map_or([f32::NAN; 2], |channel| value_range(&channel.bytes));
        let output = Arc::new(Output {
            width: setup.width,
            height: setup.height,
            channels: channels
                .into_iter()
                .map(|channel| (channel.name, (channel.format.data_type, channel.bytes)))
                .collect(),
        });
        // A pass is complete when every pixel has been traced.
        let complete = refined.is_none_or(|(run, done)| done == run.plan.units.len());
        let accumulation = job.color_sum.as_ref().map(|sum| {
            (
                std::mem::take(&mut *lock(sum)),
                job.pass + u32::from(complete),
                setup.scene_version,
                setup.width,
                setup.height,
            )
        });
        {
            let mut inner = self.lock();
            inner.output = Some(output);
            inner.parallax_range = parallax_range;
            inner.duration = job.started.elapsed().as_secs_f32();
            inner.accumulation = accumulation;
            inner.callback_thread = Some(std::thread::current().id());
            match refined {
                Some((run, done)) => {
                    let pixels = run.plan.traced_pixels(done);
                    inner.progress = pixels as f32 / (setup.width * setup.height) as f32;
                    if done == run.plan.units.len() {
                        inner.progress = 1.0;
                    }
                    let traced_now = pixels - run.plan.traced_pixels(run.start);
                    let thread_seconds = run.tracing_nanos.load(Ordering::Relaxed) as f64 * 1e-9;
                    inner.throughput.record(traced_now, thread_seconds);
                    inner
                        .throughput
                        .record_overhead(run.seconds_after_tracing());
                    inner.refinement = (!cancelled).then_some(Refinement {
                        scene_version: setup.scene_version,
                        width: setup.width,
                        height: setup.height,
                        done,
                        total: run.plan.units.len(),
                    });
                }
                None => {
                    inner.progress = 1.0;
                    inner.refinement = None;
                }
            }
        }
        // The callback runs before the frame counts as ready for other threads, so that an
        // application waiting on the frame knows the callback is done with whatever it touches.
        if let Some((Some(callback), user, device, frame)) = setup.completion {
            // SAFETY: the application registered this callback for this frame; it is called
            // once per completed render with the values it was registered with.
            unsafe {
                callback(
                    user as *const c_void,
                    device as *mut c_void,
                    frame as *mut c_void,
                )
            }
        }
        {
            let mut inner = self.lock();
            // The callback may have started the next render of this frame: leave that one be.
            if inner
                .running
                .as_ref()
                .is_some_and(|running| std::ptr::eq(Arc::as_ptr(running), job))
            {
                inner.running = None;
            }
            inner.callback_thread = None;
            // How late a timed render handed its image over moves the next renders' deadline.
            if let (Some(run), Some(budget)) = (&job.budgeted, setup.budget)
                && budget.pixels.is_none()
                && !cancelled
            {
                let elapsed = run.began.elapsed().as_secs_f64();
                inner.deadline.record(f64::from(budget.seconds), elapsed);
            }
        }
        self.finished.notify_all();
    }
}

impl FrameState {
    /// Cluster hook: changes the last render's channels in place (ranks' parts assembled),
    /// copying them first if the application has them mapped.
    #[cfg_attr(not(feature = "mpi"), allow(dead_code))]
    pub(crate) fn edit_output(&self, edit: impl FnOnce(&mut Output)) {
        self.wait();
        let mut inner = self.lock();
        if let Some(output) = inner.output.as_mut() {
            if Arc::get_mut(output).is_none() {
                *output = Arc::new(Output {
                    width: output.width,
                    height: output.height,
                    channels: output.channels.clone(),
                });
            }
            if let Some(output) = Arc::get_mut(output) {
                edit(output);
            }
        }
    }
}

impl Frame for FrameState {
    fn is_ready(&self) -> bool {
        let inner = self.lock();
        inner.running.is_none() || inner.in_callback()
    }

    /// Blocks until no render is in flight.
    fn wait(&self) {
        let mut inner = self.lock();
        while inner.running.is_some() && !inner.in_callback() {
            inner = self.finished.wait(inner).unwrap_or_else(|e| e.into_inner());
        }
    }

    /// Asks the render in flight to stop after the tiles being rendered now.
    fn discard(&self) {
        if let Some(job) = &self.lock().running {
            job.cancel.store(true, Ordering::Release);
        }
    }

    fn property(&self, name: &str, wait: bool) -> Option<PropertyValue> {
        if wait {
            self.wait();
        }
        match name {
            "duration" => Some(PropertyValue::Float32(self.lock().duration)),
            "progress" => Some(PropertyValue::Float32(self.lock().progress)),
            "parallaxRange" => Some(PropertyValue::Float32Vec2(self.lock().parallax_range)),
            // Cluster hook: the properties of renders across MPI ranks.
            #[cfg(feature = "mpi")]
            _ => self.cluster.property(name),
            #[cfg(not(feature = "mpi"))]
            _ => None,
        }
    }

    /// Waits for the render and returns the channel's pixels (kept alive until unmap).
    fn map(&self, channel: &str) -> Option<(*const c_void, u32, u32, ANARIDataType)> {
        self.wait();
        let mut inner = self.lock();
        let output = inner.output.clone()?;
        let (data_type, bytes) = output.channels.get(channel)?;
        let result = (
            bytes.as_ptr() as *const c_void,
            output.width,
            output.height,
            *data_type,
        );
        // Every map keeps its own reference: mapping twice, or rendering again, never frees
        // pixels the application still holds.
        inner
            .mapped
            .entry(channel.to_owned())
            .or_default()
            .push(Arc::clone(&output));
        Some(result)
    }

    /// Ends the oldest mapping of the channel; false when it is not mapped.
    fn unmap(&self, channel: &str) -> bool {
        let mut inner = self.lock();
        let Some(maps) = inner.mapped.get_mut(channel) else {
            return false;
        };
        maps.remove(0);
        if maps.is_empty() {
            inner.mapped.remove(channel);
        }
        true
    }

    fn into_any(self: Arc<Self>) -> Arc<dyn Any + Send + Sync> {
        self
    }
}

/// The two eyes' pixel sets of an interleaved stereo frame.
pub(crate) fn interleaved_sets(setup: &RenderSetup) -> Option<[PixelSet; 2]> {
    let viewports = setup.camera.as_ref()?.viewports(setup.width, setup.height);
    match viewports.as_slice() {
        [left, right] => match (left.pixels, right.pixels) {
            (PixelSet::All, _) | (PixelSet::Anaglyph, _) => None,
            (left, right) => Some([left, right]),
        },
        _ => None,
    }
}

/// Cluster hook: the rays a pixel's sample traces — both eyes of an anaglyph frame, the three
/// subpixels of a light-field display, else one.
#[cfg_attr(not(feature = "mpi"), allow(dead_code))]
pub(crate) fn rays_per_pixel_sample(setup: &RenderSetup) -> u32 {
    let eyes = prepare_eyes(setup);
    if anaglyph::anaglyph_eyes(&eyes).is_some() {
        2
    } else if eyes
        .first()
        .is_some_and(|(_, rays)| rays.subpixel_channels().is_some())
    {
        3
    } else {
        1
    }
}

/// Per-eye ray generators for the frame's viewports.
fn prepare_eyes(setup: &RenderSetup) -> Vec<(crate::camera::EyeViewport, EyeRays)> {
    match &setup.camera {
        Some(camera) => camera
            .viewports(setup.width, setup.height)
            .into_iter()
            .filter(|v| v.width > 0 && v.height > 0)
            .map(|v| (v, camera.prepare(v.eye, v.width, v.height)))
            .collect(),
        None => Vec::new(),
    }
}

/// Fills the pixels a budgeted render left untraced: colour blended from traced neighbours of
/// the same surface (told apart by the depth and id channels when requested), every other
/// channel copied from the nearest traced pixel.
fn fill_untraced(
    plan: &Plan,
    width: u32,
    units: (usize, usize),
    channels: &mut [Channel],
    threads: usize,
) {
    let color_pixels = |format: &ChannelFormat| match (format.kind, format.data_type) {
        (ChannelKind::Color, ANARI_FLOAT32_VEC4) => Some(ColorPixels::Float32),
        (ChannelKind::Color, _) if format.pixel_bytes == 4 => Some(ColorPixels::Unorm8),
        _ => None,
    };
    for channel in channels.iter_mut() {
        if color_pixels(&channel.format).is_none() {
            let bytes = channel.format.pixel_bytes;
            plan.fill(width, units, bytes, &mut channel.bytes, threads);
        }
    }
    let Some(index) = channels
        .iter()
        .position(|c| color_pixels(&c.format).is_some())
    else {
        return;
    };
    let mut color = std::mem::take(&mut channels[index].bytes);
    let of_kind = |kind: ChannelKind| {
        channels
            .iter()
            .find(|c| c.format.kind == kind)
            .map(|c| c.bytes.as_slice())
    };
    let guide = SurfaceGuide {
        depth: of_kind(ChannelKind::Depth),
        object_id: of_kind(ChannelKind::ObjectId),
        instance_id: of_kind(ChannelKind::InstanceId),
    };
    if let Some(pixels) = color_pixels(&channels[index].format) {
        plan.fill_color(width, units, pixels, &mut color, &guide, threads);
    }
    channels[index].bytes = color;
}
