//! Frames: asynchronous, tile-parallel rendering on the device's own threads, channel
//! encoding, accumulation, mapping and the completion callback.

use std::collections::HashMap;
use std::ffi::c_void;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::Instant;

use glam::{Vec2, Vec3, Vec4};

use crate::accel::{PacketScratch, Ray};
use crate::camera::{BLOCK_RAYS, BlockRays, Camera, CameraRay, EyeRays, PixelSet};
use crate::device::datatype::*;
use crate::device::memory::{self, TooBig};
use crate::device::property::PropertyValue;
use crate::render::color::{srgb8_encoder, srgb8_rgba_encoder, to_snorm16, to_unorm8};
use crate::render::interleave::{InterleavedTile, lattice_size};
use crate::render::progressive::{FrameTile, Plan, Throughput, TileMap};
use crate::render::renderer::{PrimaryHit, RendererSettings, fast_surface_color, shade_primary_at};
use crate::scene::light::LightSampling;
use crate::scene::world::SceneSnapshot;

/// Side of the square tiles the threads share out.
pub const TILE_SIZE: u32 = 32;

/// `ANARIFrameCompletionCallback`: (userData, device, frame).
pub type ANARIFrameCompletionCallback =
    Option<unsafe extern "C" fn(user_data: *const c_void, device: *mut c_void, frame: *mut c_void)>;

/// The channels a frame can produce and the types each may be mapped as.
pub const CHANNELS: &[(&str, &[ANARIDataType])] = &[
    (
        "channel.color",
        &[
            ANARI_UFIXED8_RGBA_SRGB,
            ANARI_UFIXED8_VEC4,
            ANARI_FLOAT32_VEC4,
        ],
    ),
    ("channel.depth", &[ANARI_FLOAT32]),
    ("channel.primitiveId", &[ANARI_UINT32]),
    ("channel.objectId", &[ANARI_UINT32]),
    ("channel.instanceId", &[ANARI_UINT32]),
    (
        "channel.albedo",
        &[
            ANARI_UFIXED8_VEC3,
            ANARI_UFIXED8_RGB_SRGB,
            ANARI_FLOAT32_VEC3,
        ],
    ),
    ("channel.normal", &[ANARI_FLOAT32_VEC3, ANARI_FIXED16_VEC3]),
    ("channel.windowDepth", &[ANARI_FLOAT32]),
    ("channel.parallax", &[ANARI_FLOAT32]),
];

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
    /// Cluster hook: the tiles this rank traces of a frame shared out among MPI ranks.
    pub tile_split: Option<Arc<crate::render::cluster::TileSplit>>,
}

/// A budgeted render traces a subset of the pixels (see [`crate::render::progressive`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Budget {
    /// Wall-clock seconds a render should take.
    pub seconds: f32,
    /// Pixels to trace per render instead of what the measured speed allows (`budgetPixels`),
    /// for reproducible progressive renders.
    pub pixels: Option<u32>,
}

/// What a channel holds.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum ChannelKind {
    Color,
    Depth,
    WindowDepth,
    PrimitiveId,
    ObjectId,
    InstanceId,
    Albedo,
    Normal,
    Parallax,
}

impl ChannelKind {
    fn of(name: &str) -> Option<ChannelKind> {
        Some(match name {
            "channel.color" => ChannelKind::Color,
            "channel.depth" => ChannelKind::Depth,
            "channel.windowDepth" => ChannelKind::WindowDepth,
            "channel.primitiveId" => ChannelKind::PrimitiveId,
            "channel.objectId" => ChannelKind::ObjectId,
            "channel.instanceId" => ChannelKind::InstanceId,
            "channel.albedo" => ChannelKind::Albedo,
            "channel.normal" => ChannelKind::Normal,
            "channel.parallax" => ChannelKind::Parallax,
            _ => return None,
        })
    }
}

/// How one requested channel is encoded: what it holds, as which type.
#[derive(Clone, Copy, Debug)]
struct ChannelFormat {
    kind: ChannelKind,
    data_type: ANARIDataType,
    pixel_bytes: usize,
}

/// What the channels other than colour read for a pixel: its first sample's hit with the
/// camera ray and eye, `None` where nothing was hit.
type PixelHit<'a> = Option<(&'a PrimaryHit, &'a CameraRay, &'a EyeRays)>;

/// `values` as native-endian bytes (`B` = 4·`N`).
#[inline(always)]
fn f32_bytes<const N: usize, const B: usize>(values: [f32; N]) -> [u8; B] {
    let mut bytes = [0; B];
    for (chunk, value) in bytes.chunks_exact_mut(4).zip(values) {
        chunk.copy_from_slice(&value.to_ne_bytes());
    }
    bytes
}

impl ChannelFormat {
    /// Writes `pixel(k)` as pixel `k` of `out` (N bytes each, which must be the type's size).
    #[inline(always)]
    fn encode_pixels<const N: usize>(&self, out: &mut [u8], pixel: impl Fn(usize) -> [u8; N]) {
        debug_assert_eq!(N, self.pixel_bytes, "pixel size of {:?}", self.data_type);
        for (k, chunk) in out.chunks_exact_mut(N).enumerate() {
            chunk.copy_from_slice(&pixel(k));
        }
    }

    /// Encodes the pixels of a tile into `out` (`pixel_bytes` each, in the order of `colors`):
    /// `colors` are their final colours, `hit(k)` pixel `k`'s first hit. The match on the type
    /// is made once per tile, not per pixel.
    fn encode<'a>(&self, colors: &[Vec4], hit: impl Fn(usize) -> PixelHit<'a>, out: &mut [u8]) {
        let out = &mut out[..colors.len() * self.pixel_bytes];
        let color = |k: usize| colors[k];
        let id = |k: usize, of: fn(&PrimaryHit) -> u32| {
            hit(k).map_or(u32::MAX, |(h, _, _)| of(h)).to_ne_bytes()
        };
        match (self.kind, self.data_type) {
            (ChannelKind::Color, ANARI_UFIXED8_RGBA_SRGB) => {
                let srgba = srgb8_rgba_encoder();
                self.encode_pixels(out, |k| srgba(color(k)))
            }
            (ChannelKind::Color, ANARI_UFIXED8_VEC4) => {
                self.encode_pixels(out, |k| color(k).to_array().map(to_unorm8))
            }
            (ChannelKind::Color, _) => {
                self.encode_pixels(out, |k| f32_bytes::<4, 16>(color(k).to_array()))
            }
            (ChannelKind::Depth, _) => self.encode_pixels(out, |k| {
                f32_bytes::<1, 4>([
                    hit(k).map_or(f32::INFINITY, |(h, ray, eye)| eye.depth(ray, h.t))
                ])
            }),
            (ChannelKind::WindowDepth, _) => self.encode_pixels(out, |k| {
                f32_bytes::<1, 4>([
                    hit(k).map_or(1.0, |(h, ray, eye)| eye.window_depth(ray, h.point))
                ])
            }),
            (ChannelKind::Parallax, _) => self.encode_pixels(out, |k| {
                f32_bytes::<1, 4>([
                    hit(k).map_or(f32::NAN, |(h, ray, eye)| eye.parallax(ray, h.point))
                ])
            }),
            (ChannelKind::PrimitiveId, _) => self.encode_pixels(out, |k| id(k, |h| h.primitive_id)),
            (ChannelKind::ObjectId, _) => self.encode_pixels(out, |k| id(k, |h| h.object_id)),
            (ChannelKind::InstanceId, _) => self.encode_pixels(out, |k| id(k, |h| h.instance_id)),
            (ChannelKind::Albedo, data_type) => {
                let albedo = |k: usize| hit(k).map_or(Vec3::ZERO, |(h, _, _)| h.albedo).to_array();
                match data_type {
                    ANARI_UFIXED8_RGB_SRGB => {
                        let srgb = srgb8_encoder();
                        self.encode_pixels(out, |k| albedo(k).map(srgb))
                    }
                    ANARI_UFIXED8_VEC3 => self.encode_pixels(out, |k| albedo(k).map(to_unorm8)),
                    _ => self.encode_pixels(out, |k| f32_bytes::<3, 12>(albedo(k))),
                }
            }
            (ChannelKind::Normal, data_type) => {
                let normal = |k: usize| hit(k).map_or(Vec3::ZERO, |(h, _, _)| h.normal).to_array();
                match data_type {
                    ANARI_FIXED16_VEC3 => self.encode_pixels(out, |k| {
                        let [x, y, z] = normal(k).map(|v| to_snorm16(v).to_ne_bytes());
                        [x[0], x[1], y[0], y[1], z[0], z[1]]
                    }),
                    _ => self.encode_pixels(out, |k| f32_bytes::<3, 12>(normal(k))),
                }
            }
        }
    }
}

/// One requested channel of a render with its pixels. Tiles are encoded by the threads that
/// render them and copied in row by row, so a finished render needs no encoding pass.
struct Channel {
    name: &'static str,
    format: ChannelFormat,
    bytes: Vec<u8>,
}

impl Channel {
    /// Copies the encoded pixels of `map`'s tile (in its order) to their places in a frame
    /// `frame_width` pixels wide.
    fn write_area(&mut self, map: &impl TileMap, frame_width: u32, tile: &[u8]) {
        let area = map.area();
        if let Some((x0, y0)) = map.rectangle_origin() {
            self.write_tile(x0, y0, area.s1 - area.s0, frame_width, tile);
            return;
        }
        let bytes = self.format.pixel_bytes;
        let width = (area.s1 - area.s0) as usize;
        for (k, source) in tile.chunks_exact(bytes).enumerate() {
            let s = area.s0 + (k % width) as u32;
            let t = area.t0 + (k / width) as u32;
            if map.skips(s, t) {
                continue;
            }
            let (x, y) = map.pixel(s, t);
            let start = (y as usize * frame_width as usize + x as usize) * bytes;
            if let Some(target) = self.bytes.get_mut(start..start + bytes) {
                target.copy_from_slice(source);
            }
        }
    }

    /// Copies a tile encoded by [`ChannelFormat::encode`] (`tile_width` pixels per row, rows
    /// from `y0` up) to its place in a frame `frame_width` pixels wide.
    fn write_tile(&mut self, x0: u32, y0: u32, tile_width: u32, frame_width: u32, tile: &[u8]) {
        let row_bytes = tile_width as usize * self.format.pixel_bytes;
        for (row, source) in tile.chunks_exact(row_bytes).enumerate() {
            let start = ((y0 as usize + row) * frame_width as usize + x0 as usize)
                * self.format.pixel_bytes;
            if let Some(target) = self.bytes.get_mut(start..start + row_bytes) {
                target.copy_from_slice(source);
            }
        }
    }
}

/// Why a render could not start.
#[derive(Debug, PartialEq, Eq)]
pub enum StartError {
    /// The new buffers are more than the system has available (checked before allocating).
    Exceeds(TooBig),
    /// The allocator refused them.
    OutOfMemory,
}

/// Bytes of `pixels` pixels of `pixel_bytes` bytes, or OutOfMemory when that overflows.
fn buffer_bytes(pixels: usize, pixel_bytes: usize) -> Result<usize, StartError> {
    pixels
        .checked_mul(pixel_bytes)
        .ok_or(StartError::OutOfMemory)
}

/// Bytes a render will allocate: its channels and accumulation sum, less the buffers of the
/// last render it can reuse (same size and type).
fn new_buffer_bytes(setup: &RenderSetup, inner: &Inner) -> Result<u64, StartError> {
    let pixels = setup.width as usize * setup.height as usize;
    let same_size = |w: u32, h: u32| w == setup.width && h == setup.height;
    let previous = inner
        .output
        .as_ref()
        .filter(|o| same_size(o.width, o.height));
    let mut bytes = 0u64;
    for (&name, &data_type) in &setup.channels {
        let reused = previous
            .and_then(|o| o.channels.get(name))
            .is_some_and(|(t, _)| *t == data_type);
        if !reused {
            let pixel_bytes = element_size(data_type).unwrap_or(0);
            bytes = bytes.saturating_add(buffer_bytes(pixels, pixel_bytes)? as u64);
        }
    }
    let sum_reused = matches!(&inner.accumulation, Some((_, _, _, w, h)) if same_size(*w, *h));
    if setup.accumulate && !sum_reused {
        let sum = buffer_bytes(pixels, std::mem::size_of::<Vec4>())?;
        bytes = bytes.saturating_add(sum as u64);
    }
    Ok(bytes)
}

/// The channels of a render: the previous render's buffers when nobody has them mapped and
/// they fit (a head-tracked application renders the same frame again and again), otherwise
/// new ones.
fn allocate_channels(
    setup: &RenderSetup,
    previous: Option<Output>,
) -> Result<Vec<Channel>, StartError> {
    let pixels = setup.width as usize * setup.height as usize;
    let mut reusable = match previous {
        Some(output) if output.width == setup.width && output.height == setup.height => {
            output.channels
        }
        _ => HashMap::new(),
    };
    let mut channels = Vec::new();
    for (&name, &data_type) in &setup.channels {
        let (Some(kind), Some(pixel_bytes)) = (ChannelKind::of(name), element_size(data_type))
        else {
            continue;
        };
        let bytes = match reusable.remove(name) {
            Some((previous_type, bytes)) if previous_type == data_type => bytes,
            _ => {
                let length = buffer_bytes(pixels, pixel_bytes)?;
                let mut bytes = Vec::new();
                bytes
                    .try_reserve_exact(length)
                    .map_err(|_| StartError::OutOfMemory)?;
                bytes.resize(length, 0);
                bytes
            }
        };
        channels.push(Channel {
            name,
            format: ChannelFormat {
                kind,
                data_type,
                pixel_bytes,
            },
            bytes,
        });
    }
    Ok(channels)
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
    workers_left: AtomicUsize,
    /// Threads rendering this job.
    workers: usize,
    channels: Mutex<Vec<Channel>>,
    /// The formats of `channels`, in the same order, readable without the lock.
    formats: Vec<ChannelFormat>,
    /// Whether a channel other than colour needs each pixel's first hit.
    keeps_hits: bool,
    /// Accumulation pass number (0 = first).
    pass: u32,
    /// Running colour sum over the accumulated passes (accumulation only).
    color_sum: Option<Mutex<Vec<Vec4>>>,
    started: Instant,
    /// A budgeted render: which units it traces (`next_tile` counts from `start`).
    budgeted: Option<BudgetedRun>,
}

/// What a budgeted render traces: units `start..` of its plan, as far as time allows.
struct BudgetedRun {
    plan: Plan,
    /// Units traced by earlier renders of the unchanged frame.
    start: usize,
    /// Units the measured speed allows (the mandatory units, and at least one more than
    /// `start` so that refinement always progresses, are traced whatever the time).
    planned_end: usize,
    deadline: Option<Instant>,
    /// The first unit a worker declined: units `start..first_declined` are traced.
    first_declined: AtomicUsize,
    /// Nanoseconds the threads spent tracing units, summed.
    tracing_nanos: AtomicU64,
}

impl BudgetedRun {
    /// Whether unit `index` is not traced in this render. Monotonic in `index` and in time, so
    /// the traced units always form a prefix.
    fn declines(&self, index: usize) -> bool {
        index >= self.plan.units.len()
            || (index >= self.plan.mandatory_units().max(self.start + 1)
                && (index >= self.planned_end
                    || self
                        .deadline
                        .is_some_and(|deadline| Instant::now() >= deadline)))
    }
}

/// How far the budgeted renders of an unchanged frame got.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Refinement {
    scene_version: u64,
    width: u32,
    height: u32,
    /// Units traced so far.
    done: usize,
    total: usize,
}

impl Job {
    /// Tile `tile` of an unbudgeted interleaved render: the eyes' lattice tiles alternate.
    fn interleaved_tile(&self, tile: usize, sets: [PixelSet; 2]) -> InterleavedTile {
        let set = sets[tile % 2];
        let (width, height) = lattice_size(set, self.setup.width, self.setup.height);
        let tile = tile as u32 / 2;
        let (s0, t0) = (
            (tile % self.tiles_x) * TILE_SIZE,
            (tile / self.tiles_x) * TILE_SIZE,
        );
        InterleavedTile {
            set,
            s0,
            t0,
            s1: (s0 + TILE_SIZE).min(width),
            t1: (t0 + TILE_SIZE).min(height),
            width: self.setup.width,
            height: self.setup.height,
        }
    }

    /// Tile `tile` of an unbudgeted render: a square of the whole frame.
    fn frame_tile(&self, tile: usize) -> FrameTile {
        let x0 = (tile as u32 % self.tiles_x) * TILE_SIZE;
        let y0 = (tile as u32 / self.tiles_x) * TILE_SIZE;
        FrameTile {
            x0,
            y0,
            x1: (x0 + TILE_SIZE).min(self.setup.width),
            y1: (y0 + TILE_SIZE).min(self.setup.height),
        }
    }
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
    /// Cluster hook: what this rank's last render across MPI ranks traced and exchanged.
    pub cluster: crate::render::cluster::FrameTraffic,
}

impl FrameState {
    fn lock(&self) -> MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub fn is_ready(&self) -> bool {
        let inner = self.lock();
        inner.running.is_none() || inner.in_callback()
    }

    /// Blocks until no render is in flight.
    pub fn wait(&self) {
        let mut inner = self.lock();
        while inner.running.is_some() && !inner.in_callback() {
            inner = self.finished.wait(inner).unwrap_or_else(|e| e.into_inner());
        }
    }

    /// Asks the render in flight to stop after the tiles being rendered now.
    pub fn discard(&self) {
        if let Some(job) = &self.lock().running {
            job.cancel.store(true, Ordering::Release);
        }
    }

    pub fn property(&self, name: &str, wait: bool) -> Option<PropertyValue> {
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
        let channels = allocate_channels(&setup, previous_output)?;
        let interleave = interleaved_sets(&setup);
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
        let job = Arc::new(Job {
            setup,
            cancel: AtomicBool::new(false),
            next_tile: AtomicUsize::new(0),
            tiles_x,
            tile_count: (tiles_x * tiles_y * eyes) as usize,
            interleave,
            workers_left: AtomicUsize::new(workers),
            workers,
            keeps_hits: channels.iter().any(|c| c.format.kind != ChannelKind::Color),
            formats: channels.iter().map(|c| c.format).collect(),
            channels: Mutex::new(channels),
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
        let eyes = prepare_eyes(&job.setup);
        let mut scratch = TileScratch::default();
        while !job.cancel.load(Ordering::Acquire) {
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
                    let nanos = started.elapsed().as_nanos() as u64;
                    run.tracing_nanos.fetch_add(nanos, Ordering::Relaxed);
                }
            }
        }
        if job.workers_left.fetch_sub(1, Ordering::AcqRel) == 1 {
            self.finish(job);
        }
    }

    fn finish(&self, job: &Job) {
        let setup = &job.setup;
        let mut channels = std::mem::take(&mut *lock(&job.channels));
        let cancelled = job.cancel.load(Ordering::Acquire);
        // How far a budgeted render got, and the untraced pixels filled.
        let refined = job.budgeted.as_ref().map(|run| {
            let done = run.first_declined.load(Ordering::Acquire);
            for channel in channels.iter_mut() {
                let bytes = channel.format.pixel_bytes;
                run.plan
                    .fill(setup.width, run.start, done, bytes, &mut channel.bytes);
            }
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
                    // What the render took beyond its threads' tracing time.
                    let threads = job.workers as f64;
                    inner.throughput.overhead_seconds =
                        (job.started.elapsed().as_secs_f64() - thread_seconds / threads).max(0.0);
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
        }
        self.finished.notify_all();
    }

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

    /// Waits for the render and returns the channel's pixels (kept alive until unmap).
    pub fn map(&self, channel: &str) -> Option<(*const c_void, u32, u32, ANARIDataType)> {
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
    pub fn unmap(&self, channel: &str) -> bool {
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
}

/// The budgeted part of a render, if it has a budget: where refinement of the unchanged frame
/// goes on, and how many units the measured speed allows. `None` renders every pixel (no
/// budget, no camera, or an image already complete that accumulation refines further).
fn budgeted_run(setup: &RenderSetup, inner: &mut Inner, threads: usize) -> Option<BudgetedRun> {
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
            inner.throughput.pixels_for(
                f64::from(budget.seconds),
                primitives,
                setup.settings.fast,
                threads,
            )
        }
    };
    // Units after `start` until their pixels reach the plan.
    let mut planned_end = start;
    let mut pixels = 0.0;
    while planned_end < plan.units.len() && pixels < planned_pixels {
        pixels += plan.units[planned_end].pixel_count() as f64;
        planned_end += 1;
    }
    // Tracing stops in time for the fill (as long as it took last time) and the rest.
    let deadline = budget.pixels.is_none().then(|| {
        let tracing = 0.85 * f64::from(budget.seconds) - inner.throughput.overhead_seconds;
        Instant::now() + std::time::Duration::from_secs_f64(tracing.max(0.0))
    });
    Some(BudgetedRun {
        first_declined: AtomicUsize::new(plan.units.len()),
        tracing_nanos: AtomicU64::new(0),
        plan,
        start,
        planned_end,
        deadline,
    })
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

/// A deterministic sub-pixel offset in [0,1)²: sample 0 of pass 0 is the pixel centre, the rest
/// follow a 2D Halton sequence so that accumulation converges.
fn jitter(index: u32) -> Vec2 {
    if index == 0 {
        return Vec2::splat(0.5);
    }
    Vec2::new(radical_inverse(index, 2), radical_inverse(index, 3))
}

/// The depth-of-field lens sample for a sample index: a Halton sequence in bases 5 and 7, so it
/// is independent of the pixel offsets (bases 2 and 3).
fn lens_sample(index: u32) -> Vec2 {
    Vec2::new(radical_inverse(index + 1, 5), radical_inverse(index + 1, 7))
}

fn radical_inverse(mut i: u32, base: u32) -> f32 {
    let (mut result, mut f) = (0.0f32, 1.0f32 / base as f32);
    while i > 0 {
        result += f * (i % base) as f32;
        i /= base;
        f /= base as f32;
    }
    result
}

/// Side of the pixel blocks traced together as one coherent packet of primary rays.
const PACKET_SIDE: u32 = 8;

/// Pixel offsets of an 8×8 block in the order packet traversal expects: sixteen 2×2 quads of
/// four consecutive rays, quads in row order.
const PACKET_ORDER: [(u32, u32); 64] = {
    let mut order = [(0, 0); 64];
    let mut i = 0;
    while i < 64 {
        let quad = i / 4;
        let lane = i % 4;
        order[i] = (
            (quad % 4) as u32 * 2 + (lane % 2) as u32,
            (quad / 4) as u32 * 2 + (lane / 2) as u32,
        );
        i += 1;
    }
    order
};

/// A ray that hits nothing (zero direction): fills packet lanes outside the frame or any eye.
const NO_RAY: Ray = Ray {
    origin: Vec3::ZERO,
    direction: Vec3::ZERO,
    t_min: 0.0,
    t_max: 0.0,
};

/// Pixels in a full tile.
const TILE_PIXELS: usize = (TILE_SIZE * TILE_SIZE) as usize;

/// A pixel's first sample's hit with the camera ray and eye that saw it, kept for the channels
/// other than colour.
type FirstHit<'a> = (PrimaryHit, CameraRay, &'a EyeRays);

/// The ray to trace for a camera ray.
#[inline]
fn traced(camera_ray: &CameraRay) -> Ray {
    Ray {
        origin: camera_ray.origin,
        direction: camera_ray.direction,
        t_min: camera_ray.t_min,
        t_max: camera_ray.t_max,
    }
}

/// Smallest and largest of native-endian FLOAT32 pixels, NaNs (no hit) left out; NaN for both
/// when every pixel is NaN.
fn value_range(bytes: &[u8]) -> [f32; 2] {
    let (low, high) = bytes
        .chunks_exact(4)
        .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))
        .filter(|v| !v.is_nan())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(low, high), v| {
            (low.min(v), high.max(v))
        });
    if low > high {
        [f32::NAN; 2]
    } else {
        [low, high]
    }
}

/// A worker's working memory, kept from one tile to the next.
#[derive(Default)]
struct TileScratch<'a> {
    packets: PacketScratch,
    /// Per pixel of a tile, its first hit (only when a channel other than colour needs it).
    first_hits: Vec<Option<FirstHit<'a>>>,
    /// One channel's pixels of a tile, encoded.
    encoded: Vec<u8>,
}

/// Lattices this sparse are traced ray by ray: their packets are too incoherent to pay
/// (measured on the 1M-triangle benchmark: the coarsest level 32 → 22 ms at stride ≥ 4, no
/// better at stride 2).
const SINGLE_RAY_STRIDE: u32 = 4;

fn render_tile<'a>(
    job: &Job,
    eyes: &'a [(crate::camera::EyeViewport, EyeRays)],
    map: impl TileMap,
    scratch: &mut TileScratch<'a>,
) {
    let setup = &job.setup;
    // The tile's pixels are lattice points (sx, sy) of [s0, s1) × [t0, t1); for a tile
    // of the whole frame they are plain pixel coordinates.
    let area = map.area();
    let pixel_count = area.pixel_count();
    let samples = setup.settings.pixel_samples;
    // Colour summed over the samples, and whether any eye covers the pixel.
    let mut colors = [Vec4::ZERO; TILE_PIXELS];
    let mut covered = [false; TILE_PIXELS];
    scratch.first_hits.clear();
    if job.keeps_hits {
        scratch.first_hits.resize(pixel_count, None);
    }
    let subpixel_channels = eyes.first().and_then(|(_, rays)| rays.subpixel_channels());
    match (anaglyph_eyes(eyes), subpixel_channels) {
        (Some((left, right)), _) => {
            // Both eyes for every pixel; the channels other than colour are the left eye's.
            let all = PixelRays::All;
            trace_blocks(
                job,
                left,
                map,
                scratch,
                &mut colors,
                &mut covered,
                true,
                all,
            );
            let mut right_colors = [Vec4::ZERO; TILE_PIXELS];
            trace_blocks(
                job,
                right,
                map,
                scratch,
                &mut right_colors,
                &mut covered,
                false,
                all,
            );
            for (color, right) in colors[..pixel_count].iter_mut().zip(&right_colors) {
                *color = anaglyph(*color, *right);
            }
        }
        (None, Some(channels)) => {
            // A light-field display: a ray per subpixel, each giving its colour channel; alpha
            // and the other channels come from the green subpixel's ray.
            let mut passes = [[Vec4::ZERO; TILE_PIXELS]; 3];
            for (k, pass) in passes.iter_mut().enumerate() {
                let green = channels[k] == 1;
                let rays = PixelRays::Subpixel(k as u32);
                trace_blocks(job, eyes, map, scratch, pass, &mut covered, green, rays);
            }
            let green = channels.iter().position(|c| *c == 1).unwrap_or(1);
            for (index, color) in colors[..pixel_count].iter_mut().enumerate() {
                *color = passes[green][index];
                for (k, channel) in channels.iter().enumerate() {
                    color[*channel] = passes[k][index][*channel];
                }
            }
        }
        (None, None) => {
            let all = PixelRays::All;
            trace_blocks(
                job,
                eyes,
                map,
                scratch,
                &mut colors,
                &mut covered,
                true,
                all,
            );
        }
    }
    let first_hits = &scratch.first_hits;
    let passes = (job.pass + 1) as f32;
    // Final colours: the samples' mean (the background where no eye looks), then the running
    // mean over the passes when accumulating.
    let mut color_sum = job.color_sum.as_ref().map(lock);
    // Walked row by row: a division per pixel for its lattice point cost a tenth of this loop.
    let (s0, s1) = (area.s0, area.s1);
    let lattice_points = (area.t0..area.t1).flat_map(|sy| (s0..s1).map(move |sx| (sx, sy)));
    for (k, (color, (sx, sy))) in colors[..pixel_count]
        .iter_mut()
        .zip(lattice_points)
        .enumerate()
    {
        if map.skips(sx, sy) {
            continue;
        }
        let (x, y) = map.pixel(sx, sy);
        *color = if covered[k] {
            // x / 1 is x: one sample (the usual case) needs no division.
            if samples == 1 {
                *color
            } else {
                *color / samples as f32
            }
        } else {
            setup.settings.background_at(Vec2::new(
                (x as f32 + 0.5) / setup.width as f32,
                (y as f32 + 0.5) / setup.height as f32,
            ))
        };
        if let Some(sum) = color_sum.as_deref_mut()
            && let Some(total) = sum.get_mut((y * setup.width + x) as usize)
        {
            *total += *color;
            *color = *total / passes;
        }
    }
    drop(color_sum);
    let hit = |k: usize| {
        first_hits
            .get(k)
            .and_then(Option::as_ref)
            .map(|(hit, camera_ray, eye_rays)| (hit, camera_ray, *eye_rays))
    };
    // Encoded outside the lock; the lock is held only to copy the rows in.
    for (index, format) in job.formats.iter().enumerate() {
        let encoded = &mut scratch.encoded;
        encoded.resize(pixel_count * format.pixel_bytes, 0);
        format.encode(&colors[..pixel_count], hit, encoded);
        if let Some(channel) = lock(&job.channels).get_mut(index) {
            channel.write_area(&map, setup.width, encoded);
        }
    }
}

/// Which ray of a pixel a pass traces: the pixel's own, or (light-field displays) the ray of
/// its subpixel k (0, 1, 2 from the left).
#[derive(Clone, Copy)]
enum PixelRays {
    All,
    Subpixel(u32),
}

/// An eye's viewport with its ray generator for the frame.
type PreparedEye = (crate::camera::EyeViewport, EyeRays);

/// Dubois' least-squares red-cyan anaglyph matrices (rows: output red, green, blue), applied to
/// linear RGB.
const ANAGLYPH_LEFT: [[f32; 3]; 3] = [
    [0.437, 0.449, 0.164],
    [-0.062, -0.062, -0.024],
    [-0.048, -0.050, -0.017],
];
const ANAGLYPH_RIGHT: [[f32; 3]; 3] = [
    [-0.011, -0.032, -0.007],
    [0.377, 0.761, 0.009],
    [-0.026, -0.093, 1.234],
];

/// One anaglyph colour from the two eyes' colours, clamped to [0, 1]; the left eye's alpha.
pub(crate) fn anaglyph(left: Vec4, right: Vec4) -> Vec4 {
    let row = |k: usize| {
        let l = ANAGLYPH_LEFT[k];
        let r = ANAGLYPH_RIGHT[k];
        (l[0] * left.x
            + l[1] * left.y
            + l[2] * left.z
            + r[0] * right.x
            + r[1] * right.y
            + r[2] * right.z)
            .clamp(0.0, 1.0)
    };
    Vec4::new(row(0), row(1), row(2), left.w)
}

/// Both eyes of an anaglyph frame (each renders every pixel), as one-eye slices.
fn anaglyph_eyes(eyes: &[PreparedEye]) -> Option<(&[PreparedEye], &[PreparedEye])> {
    match eyes {
        [(left, _), (right, _)]
            if left.pixels == PixelSet::Anaglyph && right.pixels == PixelSet::Anaglyph =>
        {
            Some((&eyes[..1], &eyes[1..]))
        }
        _ => None,
    }
}

/// Traces the tile's pixels from `eyes`, summing each pixel's samples into `colors` and
/// marking it `covered`; with `record_hits` (and a frame that keeps hits), each pixel's first
/// hit goes into `scratch.first_hits`.
#[allow(clippy::too_many_arguments)]
fn trace_blocks<'a>(
    job: &Job,
    eyes: &'a [(crate::camera::EyeViewport, EyeRays)],
    map: impl TileMap,
    scratch: &mut TileScratch<'a>,
    colors: &mut [Vec4; TILE_PIXELS],
    covered: &mut [bool; TILE_PIXELS],
    record_hits: bool,
    pixel_rays: PixelRays,
) {
    let setup = &job.setup;
    let area = map.area();
    let (tx, ty, x_end, y_end) = (area.s0, area.t0, area.s1, area.t1);
    let tile_width = x_end - tx;
    let samples = setup.settings.pixel_samples;
    // The fast renderer's lean path: nothing but colour to compute.
    let colour_only_fast = setup.settings.fast && !job.keeps_hits && setup.scene.volumes.is_empty();
    let keeps_hits = job.keeps_hits && record_hits;
    let first_hits = &mut scratch.first_hits;
    let mut rays = [NO_RAY; 64];
    // Viewport coordinates of a block's rays, for cameras that make them four at a time.
    let mut batch: [Option<(f32, f32)>; 64] = [None; 64];
    let mut camera_rays = [None; 64];
    let mut hits = [None; 64];
    let mut block = BlockRays::default();
    for by in (ty..y_end).step_by(PACKET_SIDE as usize) {
        for bx in (tx..x_end).step_by(PACKET_SIDE as usize) {
            let (bx_end, by_end) = ((bx + PACKET_SIDE).min(x_end), (by + PACKET_SIDE).min(y_end));
            let (x0, y0) = map.pixel(bx, by);
            let (x1, y1) = map.pixel(bx_end - 1, by_end - 1);
            // Usually one eye's viewport holds the whole block; otherwise look per pixel.
            let block_eye = eyes
                .iter()
                .find(|(viewport, _)| viewport.holds_block(x0, y0, x1 + 1, y1 + 1, map.pixels()));
            // Cameras that blend several viewers make their rays four at a time.
            let batched = block_eye.filter(|(_, eye_rays)| eye_rays.batches_rays());
            if batched.is_some() {
                batch = [None; 64];
            }
            // A whole block of pixels seen from one lensless pinhole (or from several viewers'
            // blended positions): its rays are made together, lane by lane.
            let whole_block = matches!(pixel_rays, PixelRays::All)
                && bx_end - bx == PACKET_SIDE
                && by_end - by == PACKET_SIDE;
            let block_maker =
                block_eye.filter(|(_, eye_rays)| whole_block && eye_rays.makes_block_rays());
            for s in 0..samples {
                let index = job.pass * samples + s;
                let offset = jitter(index);
                let lens = lens_sample(index);
                let block_rays = block_maker.and_then(|(viewport, eye_rays)| {
                    let (width, height) = (viewport.width as f32, viewport.height as f32);
                    let mut s_lanes = [0.0; BLOCK_RAYS];
                    let mut t_lanes = [0.0; BLOCK_RAYS];
                    for (lane, (dx, dy)) in PACKET_ORDER.iter().enumerate() {
                        let (sx, sy) = (bx + dx, by + dy);
                        if map.skips(sx, sy) {
                            return None;
                        }
                        // As below, ray by ray.
                        let (x, y) = map.pixel(sx, sy);
                        s_lanes[lane] = ((x - viewport.x) as f32 + offset.x) / width;
                        t_lanes[lane] = ((y - viewport.y) as f32 + offset.y) / height;
                    }
                    if !eye_rays.block_rays(&s_lanes, &t_lanes, &mut block) {
                        return None;
                    }
                    for (lane, ray) in rays.iter_mut().enumerate() {
                        *ray = traced(&block.ray(lane));
                    }
                    Some(eye_rays)
                });
                // Otherwise ray by ray.
                let per_lane = if block_rays.is_some() {
                    &[][..]
                } else {
                    &PACKET_ORDER[..]
                };
                for (lane, (dx, dy)) in per_lane.iter().enumerate() {
                    let (sx, sy) = (bx + dx, by + dy);
                    rays[lane] = NO_RAY;
                    camera_rays[lane] = None;
                    if sx >= x_end || sy >= y_end || map.skips(sx, sy) {
                        continue;
                    }
                    let (x, y) = map.pixel(sx, sy);
                    let eye = block_eye.or_else(|| {
                        eyes.iter()
                            .find(|(viewport, _)| viewport.holds(x, y, x + 1, y + 1))
                    });
                    let Some((viewport, eye_rays)) = eye else {
                        continue;
                    };
                    let u = match pixel_rays {
                        PixelRays::All => {
                            ((x - viewport.x) as f32 + offset.x) / viewport.width as f32
                        }
                        // The subpixel as a pixel of a frame three times as wide.
                        PixelRays::Subpixel(k) => {
                            ((3 * (x - viewport.x) + k) as f32 + offset.x)
                                / (3 * viewport.width) as f32
                        }
                    };
                    let v = ((y - viewport.y) as f32 + offset.y) / viewport.height as f32;
                    if batched.is_some() {
                        batch[lane] = Some((u, v));
                        continue;
                    }
                    let camera_ray = eye_rays.ray(u, v, lens);
                    rays[lane] = traced(&camera_ray);
                    camera_rays[lane] = Some((camera_ray, eye_rays));
                }
                if let Some((_, eye_rays)) = batched.filter(|_| block_rays.is_none()) {
                    for (group, points) in batch.chunks_exact(4).enumerate() {
                        if points.iter().all(Option::is_none) {
                            continue;
                        }
                        let coordinate =
                            |i: usize, of: fn((f32, f32)) -> f32| points[i].map_or(0.5, of);
                        let generated = eye_rays.rays4(
                            std::array::from_fn(|i| coordinate(i, |uv| uv.0)),
                            std::array::from_fn(|i| coordinate(i, |uv| uv.1)),
                            lens,
                        );
                        for (i, camera_ray) in generated.into_iter().enumerate() {
                            let lane = group * 4 + i;
                            if points[i].is_some() {
                                rays[lane] = traced(&camera_ray);
                                camera_rays[lane] = Some((camera_ray, eye_rays));
                            }
                        }
                    }
                }
                let subpixels = matches!(pixel_rays, PixelRays::Subpixel(_));
                if map.stride() >= SINGLE_RAY_STRIDE || subpixels {
                    // Sparse lattices make incoherent packets, and a light field's neighbouring
                    // subpixels look from eyes centimetres apart: ray by ray is cheaper there.
                    for (hit, ray) in hits.iter_mut().zip(&rays) {
                        *hit = setup.scene.bvh.intersect(ray);
                    }
                } else {
                    setup
                        .scene
                        .bvh
                        .intersect_packet_with(&mut scratch.packets, &rays, &mut hits);
                }
                for (lane, (dx, dy)) in PACKET_ORDER.iter().enumerate() {
                    let camera = match block_rays {
                        Some(eye_rays) => Some((block.ray(lane), eye_rays)),
                        None => camera_rays[lane],
                    };
                    let Some((camera_ray, eye_rays)) = camera else {
                        continue;
                    };
                    let (sx, sy) = (bx + dx, by + dy);
                    let (x, y) = map.pixel(sx, sy);
                    // The sample's position in the frame places the background image.
                    let screen = || {
                        Vec2::new(
                            (x as f32 + offset.x) / setup.width as f32,
                            (y as f32 + offset.y) / setup.height as f32,
                        )
                    };
                    let k = ((sy - ty) * tile_width + sx - tx) as usize;
                    covered[k] = true;
                    if colour_only_fast {
                        colors[k] += fast_surface_color(
                            &setup.scene,
                            &setup.settings,
                            &rays[lane],
                            hits[lane].as_ref(),
                            screen,
                            camera_ray.cyclopean,
                        );
                        continue;
                    }
                    let sample = shade_primary_at(
                        &setup.scene,
                        &setup.settings,
                        &rays[lane],
                        hits[lane],
                        Some(screen()),
                        camera_ray.cyclopean,
                        &LightSampling::for_pixel(index, x, y),
                    );
                    colors[k] += sample.color;
                    if s == 0 && keeps_hits {
                        first_hits[k] = sample.hit.map(|hit| (hit, camera_ray, eye_rays));
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packet_quadrants_are_4x4_pixel_blocks() {
        // Frustum packets cull leaves per quadrant of groups; that pays only if each quadrant
        // is a compact 4x4 block of the 8x8 block's pixels.
        for groups in crate::accel::QUADRANT_GROUPS {
            let pixels: Vec<(u32, u32)> = groups
                .iter()
                .flat_map(|group| PACKET_ORDER[4 * group..4 * group + 4].iter().copied())
                .collect();
            let (x0, y0) = (pixels[0].0 / 4 * 4, pixels[0].1 / 4 * 4);
            let mut expected: Vec<(u32, u32)> = (0..16).map(|i| (x0 + i % 4, y0 + i / 4)).collect();
            let mut sorted = pixels.clone();
            sorted.sort();
            expected.sort();
            assert_eq!(sorted, expected, "{groups:?}");
        }
    }

    #[test]
    fn first_sample_is_the_pixel_centre_and_the_rest_stay_inside() {
        assert_eq!(jitter(0), Vec2::splat(0.5));
        assert_eq!(jitter(1), Vec2::new(0.5, 1.0 / 3.0));
        for i in 1..100 {
            let j = jitter(i);
            assert!(j.x > 0.0 && j.x < 1.0 && j.y > 0.0 && j.y < 1.0);
        }
    }
}
