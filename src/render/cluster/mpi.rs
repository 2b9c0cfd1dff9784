//! The frame's MPI side: its communicator (duplicated at commit), the collectives with
//! timeouts, and the two collective renders (data-parallel and replicated).
//!
//! The device joins the MPI the application initialised and never initialises or finalises
//! it. MPI is called only from the thread that calls anariCommitParameters and
//! anariRenderFrame on the frame, never from the render threads: MPI_THREAD_FUNNELED suffices
//! when that is the thread that initialised MPI, MPI_THREAD_SERIALIZED otherwise;
//! MPI_THREAD_SINGLE is reported once and used as FUNNELED.

use std::collections::{HashMap, HashSet};
use std::ffi::c_void;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mpi::ffi;

use super::wavefront::{ClusterError, Exchange, Traffic, composite, resolve};
use super::{
    NO_SAMPLE, PrimaryPass, Replay, SAMPLE_WORDS, TileSplit, UNVISITED, decode_sample,
    encode_sample,
};
use crate::device::Device;
use crate::device::datatype::*;
use crate::device::frame::Frame;
use crate::device::object::Object;
use crate::device::spec::{ParamSpec, SpecValue};
use crate::device::status::*;
use crate::render::frame::{self, FrameState, RenderSetup, TILE_SIZE};

pub const MPI_COMMUNICATOR: ParamSpec = ParamSpec::new(
    "mpiCommunicator",
    &[ANARI_VOID_POINTER],
    "the MPI communicator whose ranks render the frame together (KHR_DATA_PARALLEL_MPI): the \
     MPI_Comm handle itself as the pointer (Open MPI's MPI_Comm is a pointer; mpi4py: \
     MPI._handleof(comm)); duplicated at the frame's commit; default MPI_COMM_WORLD when MPI \
     is initialised",
);

pub const MPI_MODE: ParamSpec = ParamSpec::new(
    "mpiMode",
    &[ANARI_STRING],
    "how the ranks share the frame: 'dataParallel' (each rank holds a part of the world; the \
     image on rank 0 is that of all parts together) or 'replicated' (every rank holds the \
     whole world; the frame's tiles are shared out, balanced by their last cost)",
)
.default(SpecValue::Str("dataParallel"))
.values(&["dataParallel", "replicated"]);

pub const MPI_IMAGE_ON_EVERY_RANK: ParamSpec = ParamSpec::new(
    "mpiImageOnEveryRank",
    &[ANARI_BOOL],
    "whether every rank's frame holds the whole image (else rank 0's only; the others hold \
     what they rendered themselves)",
)
.default(SpecValue::Bool(false));

pub const MPI_TIMEOUT: ParamSpec = ParamSpec::new(
    "mpiTimeout",
    &[ANARI_FLOAT32],
    "seconds a collective step of a render across ranks may wait for the other ranks before \
     the render is given up and reported (a rank exited, failed or stopped rendering)",
)
.default(SpecValue::Float(60.0))
.range(SpecValue::Float(0.01), SpecValue::Float(86400.0));

/// A frame's duplicated communicator.
struct FrameComm {
    /// The MPI_Comm, as an address (Open MPI's handles are pointers).
    comm: usize,
    rank: u32,
    ranks: u32,
    /// Set when a collective timed out or failed: the communicator is no longer usable.
    broken: bool,
    /// Measured cost of each tile of the last replicated render.
    tile_costs: Vec<f64>,
}

/// Frames with a communicator, by (device, frame) handle.
static FRAMES: Mutex<Option<HashMap<(usize, usize), FrameComm>>> = Mutex::new(None);
/// Things said once per process.
static SAID: Mutex<Option<HashSet<String>>> = Mutex::new(None);

fn with_frames<T>(f: impl FnOnce(&mut HashMap<(usize, usize), FrameComm>) -> T) -> T {
    let mut frames = FRAMES.lock().unwrap_or_else(|e| e.into_inner());
    f(frames.get_or_insert_with(HashMap::new))
}

fn say_once(device: &Device, object: &Object, key: &str, text: String) {
    let mut said = SAID.lock().unwrap_or_else(|e| e.into_inner());
    if said
        .get_or_insert_with(HashSet::new)
        .insert(format!("{}:{}:{key}", device.handle, object.handle))
    {
        device.warning(Some(object), text);
    }
}

/// A communicator from its address (Open MPI's MPI_Comm is a pointer).
fn comm_of(address: usize) -> ffi::MPI_Comm {
    ffi::MPI_Comm(address as *mut _)
}

fn mpi_state() -> (bool, bool) {
    let (mut initialized, mut finalized) = (0, 0);
    // SAFETY: MPI_Initialized and MPI_Finalized may be called at any time, even without MPI
    // initialised; each writes one int.
    unsafe {
        ffi::MPI_Initialized(&mut initialized);
        ffi::MPI_Finalized(&mut finalized);
    }
    (initialized != 0, finalized != 0)
}

fn mpi_error(code: i32) -> String {
    let mut text = vec![0u8; 512];
    let mut length = 0;
    // SAFETY: the buffer holds MPI_MAX_ERROR_STRING (256 in Open MPI) characters and more.
    unsafe {
        ffi::MPI_Error_string(code, text.as_mut_ptr() as *mut _, &mut length);
    }
    text.truncate(length.clamp(0, 512) as usize);
    format!("code {code}: {}", String::from_utf8_lossy(&text))
}

/// Frame commit: duplicates the frame's communicator (or MPI_COMM_WORLD) for the frame.
pub fn commit_frame(device: &Device, frame: &Object) {
    let params = frame.committed();
    let given = params.get_pointer("mpiCommunicator", ANARI_VOID_POINTER);
    let key = (device.handle, frame.handle);
    let previous = with_frames(|frames| frames.remove(&key));
    let (initialized, finalized) = mpi_state();
    if let Some(previous) = previous
        && initialized
        && !finalized
        && !previous.broken
    {
        let mut comm = comm_of(previous.comm);
        // SAFETY: this is the frame's own duplicate, freed once; MPI is initialised.
        unsafe {
            ffi::MPI_Comm_free(&mut comm);
        }
    }
    if !initialized || finalized {
        if given.is_some() {
            say_once(
                device,
                frame,
                "no-mpi",
                "anariCommitParameters: frame parameter 'mpiCommunicator' is set but MPI is not \
                 initialised (the application initialises MPI before it commits the frame); \
                 this process renders the frame alone"
                    .into(),
            );
        }
        return;
    }
    check_thread_level(device, frame);
    let source = match given {
        Some(0) | None => {
            // SAFETY: reading an extern constant of the MPI library.
            unsafe { ffi::RSMPI_COMM_WORLD }
        }
        Some(address) => comm_of(address),
    };
    let timeout = timeout_of(&params);
    let mut duplicate = comm_of(0);
    let mut request: ffi::MPI_Request = ffi::MPI_Request(std::ptr::null_mut());
    // SAFETY: `source` is the application's communicator (its handle as the pointer value, as
    // documented) or MPI_COMM_WORLD; MPI writes the new handle and the request.
    let code = unsafe { ffi::MPI_Comm_idup(source, &mut duplicate, &mut request) };
    let result = if code != 0 {
        Err(ClusterError::Mpi(mpi_error(code)))
    } else {
        wait(
            &mut request,
            timeout,
            "duplicating the frame's communicator",
        )
    };
    if let Err(error) = result {
        device.error(
            ANARI_STATUS_UNKNOWN_ERROR,
            Some(frame),
            format!(
                "anariCommitParameters: frame parameter 'mpiCommunicator': {error}; the frame \
                 renders alone"
            ),
        );
        return;
    }
    let (mut rank, mut ranks) = (0, 1);
    // SAFETY: `duplicate` is a valid communicator now; each call writes one int.
    unsafe {
        ffi::MPI_Comm_set_errhandler(duplicate, ffi::RSMPI_ERRORS_RETURN);
        ffi::MPI_Comm_rank(duplicate, &mut rank);
        ffi::MPI_Comm_size(duplicate, &mut ranks);
    }
    if ranks <= 1 && given.is_some() {
        say_once(
            device,
            frame,
            "one-rank",
            "anariCommitParameters: frame parameter 'mpiCommunicator' has one rank; this \
             process renders the frame alone"
                .into(),
        );
    }
    with_frames(|frames| {
        frames.insert(
            key,
            FrameComm {
                comm: duplicate.0 as usize,
                rank: rank.max(0) as u32,
                ranks: ranks.max(1) as u32,
                broken: false,
                tile_costs: Vec::new(),
            },
        )
    });
}

fn check_thread_level(device: &Device, frame: &Object) {
    let mut provided = 0;
    // SAFETY: MPI is initialised; writes one int.
    unsafe {
        ffi::MPI_Query_thread(&mut provided);
    }
    // SAFETY: reading an extern constant of the MPI library.
    let funneled = unsafe { ffi::RSMPI_THREAD_FUNNELED };
    if provided < funneled {
        say_once(
            device,
            frame,
            "thread-level",
            "anariCommitParameters: MPI was initialised with MPI_THREAD_SINGLE; cavetrace calls \
             MPI only from the thread that commits and renders the frame, which needs \
             MPI_THREAD_FUNNELED (that thread being the one that initialised MPI) or \
             MPI_THREAD_SERIALIZED"
                .into(),
        );
    }
}

fn timeout_of(params: &crate::device::params::ParamSet) -> Duration {
    let seconds = params
        .get_f32("mpiTimeout")
        .filter(|s| s.is_finite() && *s > 0.0)
        .unwrap_or(60.0);
    Duration::from_secs_f32(seconds.clamp(0.01, 86400.0))
}

/// Polls a non-blocking MPI operation until it completes, fails or times out. Open MPI moves
/// a large collective on only inside MPI calls, so polls follow each other closely: without
/// sleeping for the first 20 ms, then 50 µs apart (so that a rank waiting long for the others
/// leaves the cores to ranks sharing its node).
fn wait(
    request: &mut ffi::MPI_Request,
    timeout: Duration,
    what: &'static str,
) -> Result<(), ClusterError> {
    let started = Instant::now();
    loop {
        let mut done = 0;
        // SAFETY: `request` is an active request of this thread; MPI_STATUS_IGNORE is valid.
        let code = unsafe { ffi::MPI_Test(request, &mut done, ffi::RSMPI_STATUS_IGNORE) };
        if code != 0 {
            return Err(ClusterError::Mpi(format!("{what}: {}", mpi_error(code))));
        }
        if done != 0 {
            return Ok(());
        }
        if started.elapsed() > timeout {
            return Err(ClusterError::Timeout {
                what,
                seconds: timeout.as_secs_f32(),
            });
        }
        if started.elapsed() < Duration::from_millis(20) {
            std::thread::yield_now();
        } else {
            std::thread::sleep(Duration::from_micros(50));
        }
    }
}

/// The collectives over a frame's communicator. Buffers of an operation that did not complete
/// are leaked: MPI may still write them.
struct MpiExchange {
    comm: ffi::MPI_Comm,
    rank: u32,
    ranks: u32,
    timeout: Duration,
}

impl MpiExchange {
    fn counts(&self, mine: usize, what: &'static str) -> Result<Vec<i32>, ClusterError> {
        let send = vec![mine as i32];
        let mut counts = vec![0i32; self.ranks as usize];
        let mut request: ffi::MPI_Request = ffi::MPI_Request(std::ptr::null_mut());
        // SAFETY: one int sent, one int per rank received, into buffers that outlive the
        // request (leaked below if it does not complete).
        let code = unsafe {
            ffi::MPI_Iallgather(
                send.as_ptr() as *const c_void,
                1,
                ffi::RSMPI_INT32_T,
                counts.as_mut_ptr() as *mut c_void,
                1,
                ffi::RSMPI_INT32_T,
                self.comm,
                &mut request,
            )
        };
        self.finish(code, &mut request, what, (send, counts))
            .map(|(_, counts)| counts)
    }

    /// Waits for `request`, returning `buffers` when it completed and leaking them otherwise.
    fn finish<T>(
        &self,
        code: i32,
        request: &mut ffi::MPI_Request,
        what: &'static str,
        buffers: T,
    ) -> Result<T, ClusterError> {
        if code != 0 {
            return Err(ClusterError::Mpi(format!("{what}: {}", mpi_error(code))));
        }
        match wait(request, self.timeout, what) {
            Ok(()) => Ok(buffers),
            Err(error) => {
                std::mem::forget(buffers);
                Err(error)
            }
        }
    }
}

fn displacements(counts: &[i32]) -> Vec<i32> {
    counts
        .iter()
        .scan(0i32, |offset, count| {
            let start = *offset;
            *offset += count;
            Some(start)
        })
        .collect()
}

fn split(words: Vec<u32>, counts: &[i32]) -> Vec<Vec<u32>> {
    let mut start = 0;
    counts
        .iter()
        .map(|count| {
            let part = words[start..start + *count as usize].to_vec();
            start += *count as usize;
            part
        })
        .collect()
}

impl Exchange for MpiExchange {
    fn rank(&self) -> u32 {
        self.rank
    }

    fn ranks(&self) -> u32 {
        self.ranks
    }

    fn all_gather(&self, mine: &[u32]) -> Result<Vec<Vec<u32>>, ClusterError> {
        let counts = self.counts(mine.len(), "exchanging ray counts")?;
        let displs = displacements(&counts);
        let total: usize = counts.iter().map(|c| *c as usize).sum();
        let send = mine.to_vec();
        let mut all = vec![0u32; total];
        let mut request: ffi::MPI_Request = ffi::MPI_Request(std::ptr::null_mut());
        // SAFETY: counts and displacements describe `all` exactly; the buffers outlive the
        // request (leaked by `finish` if it does not complete).
        let code = unsafe {
            ffi::MPI_Iallgatherv(
                send.as_ptr() as *const c_void,
                send.len() as i32,
                ffi::RSMPI_UINT32_T,
                all.as_mut_ptr() as *mut c_void,
                counts.as_ptr(),
                displs.as_ptr(),
                ffi::RSMPI_UINT32_T,
                self.comm,
                &mut request,
            )
        };
        let (_, all, counts, _) = self.finish(
            code,
            &mut request,
            "exchanging rays",
            (send, all, counts, displs),
        )?;
        Ok(split(all, &counts))
    }

    fn all_min(&self, values: &mut [u64]) -> Result<(), ClusterError> {
        let send = values.to_vec();
        let mut reduced = vec![0u64; values.len()];
        let mut request: ffi::MPI_Request = ffi::MPI_Request(std::ptr::null_mut());
        // SAFETY: both buffers hold values.len() u64; they outlive the request.
        let code = unsafe {
            ffi::MPI_Iallreduce(
                send.as_ptr() as *const c_void,
                reduced.as_mut_ptr() as *mut c_void,
                values.len() as i32,
                ffi::RSMPI_UINT64_T,
                ffi::RSMPI_MIN,
                self.comm,
                &mut request,
            )
        };
        let (_, reduced) = self.finish(
            code,
            &mut request,
            "reducing hits over the ranks",
            (send, reduced),
        )?;
        values.copy_from_slice(&reduced);
        Ok(())
    }

    fn gather_to_root(&self, mine: &[u32]) -> Result<Option<Vec<Vec<u32>>>, ClusterError> {
        let counts = self.counts(mine.len(), "gathering image sizes")?;
        let displs = displacements(&counts);
        let total: usize = counts.iter().map(|c| *c as usize).sum();
        let send = mine.to_vec();
        let mut all = vec![0u32; if self.rank == 0 { total.max(1) } else { 1 }];
        let mut request: ffi::MPI_Request = ffi::MPI_Request(std::ptr::null_mut());
        // SAFETY: on rank 0 counts and displacements describe `all`; elsewhere the receive
        // arguments are ignored; the buffers outlive the request.
        let code = unsafe {
            ffi::MPI_Igatherv(
                send.as_ptr() as *const c_void,
                send.len() as i32,
                ffi::RSMPI_UINT32_T,
                all.as_mut_ptr() as *mut c_void,
                counts.as_ptr(),
                displs.as_ptr(),
                ffi::RSMPI_UINT32_T,
                0,
                self.comm,
                &mut request,
            )
        };
        let (_, all, counts, _) = self.finish(
            code,
            &mut request,
            "gathering the image",
            (send, all, counts, displs),
        )?;
        Ok((self.rank == 0).then(|| split(all, &counts)))
    }
}

/// anariRenderFrame of a frame with a communicator of several ranks: renders collectively and
/// returns `None`; otherwise gives the setup back to render alone.
pub fn render(
    device: &Device,
    frame: &Object,
    state: &Arc<FrameState>,
    mut setup: RenderSetup,
) -> Option<RenderSetup> {
    let key = (device.handle, frame.handle);
    let found = with_frames(|frames| {
        frames
            .get(&key)
            .map(|c| (c.comm, c.rank, c.ranks, c.broken, c.tile_costs.clone()))
    });
    let pixels = u64::from(setup.width) * u64::from(setup.height);
    let Some((comm, rank, ranks, broken, costs)) = found else {
        state.cluster.set(pixels, 0, 0.0);
        return Some(setup);
    };
    if broken {
        device.error(
            ANARI_STATUS_INVALID_OPERATION,
            Some(frame),
            "anariRenderFrame: the frame's MPI communicator failed in an earlier render; this \
             rank renders alone until the frame is committed again"
                .into(),
        );
        state.cluster.set(pixels, 0, 0.0);
        return Some(setup);
    }
    if ranks <= 1 {
        state.cluster.set(pixels, 0, 0.0);
        return Some(setup);
    }
    let params = frame.committed();
    let exchange = MpiExchange {
        comm: comm_of(comm),
        rank,
        ranks,
        timeout: timeout_of(&params),
    };
    if setup.budget.take().is_some() {
        say_once(
            device,
            frame,
            "budget",
            "anariRenderFrame: a frame rendered across MPI ranks ignores 'budget': every pixel \
             is rendered"
                .into(),
        );
    }
    let replicated = params.get_string("mpiMode") == Some("replicated");
    let everywhere = params.get_bool("mpiImageOnEveryRank").unwrap_or(false);
    let result = if replicated {
        render_replicated(device, frame, state, setup, &exchange, costs, everywhere)
    } else {
        render_data_parallel(device, frame, state, setup, &exchange, everywhere)
    };
    if let Err(error) = result {
        device.error(
            ANARI_STATUS_UNKNOWN_ERROR,
            Some(frame),
            format!(
                "anariRenderFrame: rendering across MPI ranks (rank {rank} of {ranks}): \
                 {error}; the frame's image is incomplete"
            ),
        );
        if matches!(error, ClusterError::Timeout { .. } | ClusterError::Mpi(_)) {
            with_frames(|frames| {
                if let Some(c) = frames.get_mut(&key) {
                    c.broken = true;
                }
            });
        }
    }
    None
}

/// A copy of the setup for a pass of its own (no completion callback).
fn pass_of(setup: &RenderSetup) -> RenderSetup {
    RenderSetup {
        width: setup.width,
        height: setup.height,
        scene: Arc::clone(&setup.scene),
        camera: setup.camera.clone(),
        settings: setup.settings.clone(),
        channels: setup.channels.clone(),
        accumulate: setup.accumulate,
        scene_version: setup.scene_version,
        completion: None,
        budget: setup.budget,
        requested: setup.requested,
        tile_split: setup.tile_split.clone(),
        status: setup.status.clone(),
    }
}

/// Every rank learns whether every rank's local part of the render went well.
fn agree(exchange: &dyn Exchange, ok: bool) -> Result<(), ClusterError> {
    let mut failed_rank = [if ok {
        u64::MAX
    } else {
        u64::from(exchange.rank())
    }];
    exchange.all_min(&mut failed_rank)?;
    match failed_rank[0] {
        u64::MAX => Ok(()),
        rank => Err(ClusterError::RankFailed { rank: rank as u32 }),
    }
}

/// Test-only trigger of the fault path (cluster-tests/run.sh): the rank of a frame's
/// communicator named by this environment variable fails its part of every render across
/// ranks as if its buffers could not be allocated.
const TEST_FAIL_RANK: &str = "CAVETRACE_TEST_FAIL_RANK";

fn fails_for_test(rank: u32) -> bool {
    std::env::var(TEST_FAIL_RANK).is_ok_and(|v| v.trim() == rank.to_string())
}

/// Starts this rank's part of a render; false (reported) when it cannot.
fn start(
    device: &Device,
    frame: &Object,
    state: &Arc<FrameState>,
    setup: RenderSetup,
    rank: u32,
) -> bool {
    let (width, height) = (setup.width, setup.height);
    let test_failure = fails_for_test(rank);
    let started = !test_failure && state.start(setup, &device.pool()).is_ok();
    if !started {
        let trigger = if test_failure {
            format!(" ({TEST_FAIL_RANK}, a test-only trigger, names this rank)")
        } else {
            String::new()
        };
        device.error(
            ANARI_STATUS_OUT_OF_MEMORY,
            Some(frame),
            format!(
                "anariRenderFrame: cannot allocate the buffers of a {width}×{height} frame on \
                 rank {rank}{trigger}; nothing is rendered"
            ),
        );
    }
    started
}

type Completion = Option<(frame::ANARIFrameCompletionCallback, usize, usize, usize)>;

/// Calls the application's completion callback of a render whose last step was collective.
fn complete(completion: Completion) {
    if let Some((Some(callback), user, device, frame)) = completion {
        // SAFETY: the application registered this callback for this frame; it is called once
        // per completed render with the values it was registered with.
        unsafe {
            callback(
                user as *const c_void,
                device as *mut c_void,
                frame as *mut c_void,
            )
        }
    }
}

/// Bytes as words for a collective, their count first.
fn pack_bytes(bytes: &[u8]) -> Vec<u32> {
    let mut words = Vec::with_capacity(1 + bytes.len().div_ceil(4));
    words.push(bytes.len() as u32);
    words.extend(
        bytes
            .chunks(4)
            .map(|c| u32::from_ne_bytes(std::array::from_fn(|i| c.get(i).copied().unwrap_or(0)))),
    );
    words
}

/// The bytes [`pack_bytes`] packed.
fn unpack_bytes(words: &[u32]) -> Vec<u8> {
    let length = words.first().copied().unwrap_or(0) as usize;
    words
        .iter()
        .skip(1)
        .flat_map(|w| w.to_ne_bytes())
        .take(length)
        .collect()
}

/// The frame's channels by name, in the order every rank uses.
fn channel_names(output: &frame::Output) -> Vec<&'static str> {
    let mut names: Vec<_> = output.channels.keys().copied().collect();
    names.sort_unstable();
    names
}

/// Sort-last assembly: every pixel's encoded channel bytes come from the rank that owns it
/// (`owner`, the same on every rank), to rank 0 or every rank. Returns the words sent.
fn assemble_pixels(
    state: &Arc<FrameState>,
    exchange: &dyn Exchange,
    owner: &[u32],
    everywhere: bool,
) -> Result<u64, ClusterError> {
    let me = exchange.rank();
    let mut mine: Vec<u8> = Vec::new();
    state.edit_output(|output| {
        for name in channel_names(output) {
            let bytes = &output.channels[name].1;
            let size = bytes.len() / owner.len().max(1);
            for (pixel, _) in owner.iter().enumerate().filter(|(_, o)| **o == me) {
                mine.extend_from_slice(&bytes[pixel * size..(pixel + 1) * size]);
            }
        }
    });
    let words = pack_bytes(&mine);
    let sent = words.len() as u64;
    if let Some(parts) = exchange.gather(&words, everywhere)? {
        state.edit_output(|output| {
            for (rank, part) in parts.iter().enumerate().filter(|(r, _)| *r != me as usize) {
                let bytes = unpack_bytes(part);
                let mut at = 0;
                for name in channel_names(output) {
                    let Some((_, channel)) = output.channels.get_mut(name) else {
                        continue;
                    };
                    let size = channel.len() / owner.len().max(1);
                    let owned = owner.iter().enumerate().filter(|(_, o)| **o == rank as u32);
                    for (pixel, _) in owned {
                        if let Some(source) = bytes.get(at..at + size) {
                            channel[pixel * size..(pixel + 1) * size].copy_from_slice(source);
                        }
                        at += size;
                    }
                }
            }
        });
    }
    Ok(sent)
}

fn render_data_parallel(
    device: &Device,
    frame: &Object,
    state: &Arc<FrameState>,
    mut setup: RenderSetup,
    exchange: &dyn Exchange,
    everywhere: bool,
) -> Result<(), ClusterError> {
    if setup.accumulate {
        say_once(
            device,
            frame,
            "accumulation",
            "anariRenderFrame: a frame rendered across MPI ranks in 'dataParallel' mode does \
             not accumulate: each render is one pass"
                .into(),
        );
        setup.accumulate = false;
    }
    if !setup.scene.volumes.is_empty() {
        say_once(
            device,
            frame,
            "volumes",
            "anariRenderFrame: volumes are not exchanged between MPI ranks in 'dataParallel' \
             mode: each rank's volumes are seen only in the samples it shades"
                .into(),
        );
    }
    let settings = &setup.settings;
    let ambient_occlusion =
        settings.ambient != glam::Vec3::ZERO && settings.ambient_occlusion_distance > 0.0;
    if ambient_occlusion && setup.scene.see_through {
        say_once(
            device,
            frame,
            "ambient occlusion",
            "anariRenderFrame: this rank's world has surfaces that let light through: in \
             'dataParallel' mode its ambient-occlusion rays then see only this rank's part of \
             the scene"
                .into(),
        );
    }
    let me = exchange.rank();
    let (width, height) = (setup.width, setup.height);
    let planes = frame::rays_per_pixel_sample(&setup) * setup.settings.pixel_samples.max(1);
    // The fast renderer's shading asks nothing of the scene: with one ray per pixel every rank
    // shades what it sees, and the rank with the closest hit gives the pixel (sort-last).
    let shade_locally = setup.settings.fast && planes == 1;
    let pass = PrimaryPass::new(width, height, planes, shade_locally).map(Arc::new);
    let completion = setup.completion.take();
    // First pass: the frame's own render records every primary sample and this rank's hit.
    let ok = match &pass {
        None => {
            device.error(
                ANARI_STATUS_OUT_OF_MEMORY,
                Some(frame),
                format!(
                    "anariRenderFrame: cannot allocate the sample arrays of a {width}×{height} \
                     frame of {planes} samples per pixel on rank {me}; nothing is rendered"
                ),
            );
            false
        }
        Some(pass) => {
            match Arc::get_mut(&mut setup.scene) {
                Some(scene) => scene.cluster = Some(Arc::clone(pass) as _),
                None => return Err(ClusterError::Mismatch("the frame's scene is shared".into())),
            }
            let ok = start(device, frame, state, pass_of(&setup), me);
            state.wait();
            ok
        }
    };
    agree(exchange, ok)?;
    let Some(pass) = pass else {
        return Err(ClusterError::RankFailed { rank: me });
    };
    let mut traffic = Traffic::default();
    let owners = composite(exchange, &pass, &mut traffic)?;
    let pixels = pass.pixels();
    let traced = owners[..pixels].iter().filter(|o| **o == me).count() as u64;
    if !shade_locally {
        let max_rounds = 4 * (setup.settings.max_ray_depth + 2) + 16;
        let (owned, samples) = resolve(
            exchange,
            &setup.scene,
            &setup.settings,
            &pass,
            &owners,
            max_rounds,
            &mut traffic,
        )?;
        if planes > 1 {
            // A pixel's samples may be shaded on several ranks: they go to rank 0 (or every
            // rank), each rank's in the order of its slots, and its frame renders them.
            let gather_started = Instant::now();
            let mut mine = Vec::with_capacity(samples.len() * SAMPLE_WORDS);
            samples.iter().for_each(|s| encode_sample(s, &mut mine));
            traffic.words_sent += mine.len() as u64;
            let gathered = exchange.gather(&mine, everywhere)?;
            traffic.exchange_seconds += gather_started.elapsed().as_secs_f64();
            if let Some(parts) = gathered {
                pass.set_replay(replay_of_parts(&pass, &owners, &parts));
                start(device, frame, state, pass_of(&setup), me);
                state.wait();
            }
            state
                .cluster
                .set(traced, traffic.words_sent * 4, traffic.exchange_seconds);
            complete(completion);
            return Ok(());
        }
        // One ray per pixel: this rank's frame renders its own samples, and its pixels'
        // channel bytes are final.
        let mut index = vec![NO_SAMPLE; pass.slots()];
        for (position, slot) in owned.iter().enumerate() {
            index[*slot] = position as u32;
        }
        pass.set_replay(Replay { index, samples });
        let ok = start(device, frame, state, pass_of(&setup), me);
        state.wait();
        agree(exchange, ok)?;
    }
    let assembly_started = Instant::now();
    traffic.words_sent += assemble_pixels(state, exchange, &owners[..pixels], everywhere)?;
    traffic.exchange_seconds += assembly_started.elapsed().as_secs_f64();
    state
        .cluster
        .set(traced, traffic.words_sent * 4, traffic.exchange_seconds);
    complete(completion);
    Ok(())
}

/// A replay of every rank's samples: `parts[r]` holds rank r's, in the order of its slots.
fn replay_of_parts(pass: &PrimaryPass, owners: &[u32], parts: &[Vec<u32>]) -> Replay {
    let mut index = vec![NO_SAMPLE; pass.slots()];
    let mut samples = Vec::new();
    let mut read = vec![0usize; parts.len()];
    for (slot, owner) in owners.iter().enumerate() {
        if pass.local(slot) == UNVISITED {
            continue;
        }
        let rank = *owner as usize;
        let at = read.get(rank).copied().unwrap_or(usize::MAX);
        let words = parts
            .get(rank)
            .and_then(|part| part.get(at * SAMPLE_WORDS..(at + 1) * SAMPLE_WORDS));
        if let Some(words) = words {
            index[slot] = samples.len() as u32;
            samples.push(decode_sample(words));
            read[rank] += 1;
        }
    }
    Replay { index, samples }
}

fn render_replicated(
    device: &Device,
    frame: &Object,
    state: &Arc<FrameState>,
    mut setup: RenderSetup,
    exchange: &MpiExchange,
    costs: Vec<f64>,
    everywhere: bool,
) -> Result<(), ClusterError> {
    let (width, height) = (setup.width, setup.height);
    if frame::interleaved_sets(&setup).is_some() {
        say_once(
            device,
            frame,
            "interleaved",
            "anariRenderFrame: a stereo frame of interleaved eyes is rendered whole on every \
             rank in 'replicated' mode"
                .into(),
        );
        let ok = start(device, frame, state, setup, exchange.rank);
        state.wait();
        state
            .cluster
            .set(u64::from(width) * u64::from(height), 0, 0.0);
        return agree(exchange, ok);
    }
    let tiles_x = width.div_ceil(TILE_SIZE);
    let tiles = (tiles_x * height.div_ceil(TILE_SIZE)) as usize;
    let split = Arc::new(TileSplit::new(
        tiles,
        exchange.ranks,
        exchange.rank,
        Some(&costs),
    ));
    setup.tile_split = Some(Arc::clone(&split));
    let completion = setup.completion.take();
    let ok = start(device, frame, state, setup, exchange.rank);
    state.wait();
    let exchange_started = Instant::now();
    agree(exchange, ok)?;
    // This rank's tiles, channel by channel (in name order), to rank 0.
    let rect = |tile: usize| {
        let (x0, y0) = (
            (tile as u32 % tiles_x) * TILE_SIZE,
            (tile as u32 / tiles_x) * TILE_SIZE,
        );
        (
            x0,
            y0,
            (x0 + TILE_SIZE).min(width),
            (y0 + TILE_SIZE).min(height),
        )
    };
    let mut mine: Vec<u8> = Vec::new();
    let mut traced = 0u64;
    state.edit_output(|output| {
        let names = channel_names(output);
        for tile in (0..tiles).filter(|t| split.owns(*t)) {
            let (x0, y0, x1, y1) = rect(tile);
            traced += u64::from((x1 - x0) * (y1 - y0));
            for name in &names {
                let bytes = &output.channels[name].1;
                let pixel = bytes.len() / (width as usize * height as usize);
                for y in y0..y1 {
                    let row = (y as usize * width as usize) * pixel;
                    mine.extend_from_slice(
                        &bytes[row + x0 as usize * pixel..row + x1 as usize * pixel],
                    );
                }
            }
        }
    });
    let words = pack_bytes(&mine);
    let sent_bytes = words.len() as u64 * 4;
    let gathered = exchange.gather(&words, everywhere)?;
    if let Some(parts) = gathered {
        state.edit_output(|output| {
            let names = channel_names(output);
            let me = exchange.rank as usize;
            for (rank, part) in parts.iter().enumerate().filter(|(r, _)| *r != me) {
                let bytes = unpack_bytes(part);
                let mut at = 0;
                for tile in (0..tiles).filter(|t| split.owner(*t) == rank as u32) {
                    let (x0, y0, x1, y1) = rect(tile);
                    for name in &names {
                        let Some((_, channel)) = output.channels.get_mut(name) else {
                            continue;
                        };
                        let pixel = channel.len() / (width as usize * height as usize);
                        let span = (x1 - x0) as usize * pixel;
                        for y in y0..y1 {
                            let row = (y as usize * width as usize + x0 as usize) * pixel;
                            if let Some(source) = bytes.get(at..at + span) {
                                channel[row..row + span].copy_from_slice(source);
                            }
                            at += span;
                        }
                    }
                }
            }
        });
    }
    // The tiles' measured times, summed over the ranks, balance the next render.
    let times = split.times();
    let mut reduced: Vec<u64> = times.iter().map(|t| u64::MAX - *t as u64).collect();
    exchange.all_min(&mut reduced)?;
    let costs: Vec<f64> = reduced.iter().map(|r| (u64::MAX - r) as f64).collect();
    with_frames(|frames| {
        if let Some(c) = frames.get_mut(&(device.handle, frame.handle)) {
            c.tile_costs = costs;
        }
    });
    state
        .cluster
        .set(traced, sent_bytes, exchange_started.elapsed().as_secs_f64());
    complete(completion);
    Ok(())
}
