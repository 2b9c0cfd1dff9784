//! Rendering across MPI ranks (docs/cluster.md). This part holds what needs no MPI: the hooks
//! the renderer and frame call, the exact data-parallel ray exchange over an abstract
//! [`Exchange`], and the replicated mode's tile split. `mpi` (the cargo feature) binds them to
//! a communicator.
//!
//! Data-parallel renders index every primary sample by its slot (plane × pixels + pixel): every
//! rank traces every primary ray against its own part and the closest hit of all ranks wins
//! (ties go to the lower rank); the winning rank shades it. The fast renderer's shading asks
//! nothing of the scene, so each rank shades its own hits at once and the closest rank's pixel
//! is the image's (sort-last). Otherwise whatever the shading asks of the scene — shadow rays,
//! reflection and transparency rays — is asked of every rank in rounds: shadow rays are
//! OR-reduced, secondary rays min-reduced, and a secondary hit on another rank is shaded there
//! and its radiance sent back. A shading that lacks an answer is evaluated again, whole, once
//! the round has brought it (unless every answer is what it assumed); shading is a pure
//! function of the answers, so the result is what one device holding every part computes.

#[cfg(feature = "mpi")]
mod mpi;
mod wavefront;

#[cfg(feature = "mpi")]
pub use self::mpi::{
    MPI_COMMUNICATOR, MPI_IMAGE_ON_EVERY_RANK, MPI_MODE, MPI_TIMEOUT, commit_frame, render,
};
pub use wavefront::{ClusterError, Exchange, Traffic, composite, resolve};

use std::cell::{Cell, RefCell};
use std::collections::{HashMap, HashSet};
use std::hash::{BuildHasherDefault, Hasher};
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::Duration;

use glam::{Vec2, Vec3, Vec4};

use crate::accel::{Ray, SceneHit};
use crate::render::integrator::{PrimaryHit, Sample};
use crate::scene::light::LightSampling;
use crate::scene::world::SceneSnapshot;

/// A ray as bits: origin, direction, t_min, t_max.
pub type RayKey = [u32; 8];
/// A radiance query: the ray, its depth, the sample's screen position and its light sampling.
pub type TraceKey = [u32; 14];
/// A primary sample: the ray, screen position, cyclopean point and light sampling.
pub type PrimaryKey = [u32; 16];

/// Bits standing for "none" in an optional value of a key.
const ABSENT: u32 = u32::MAX;

pub fn ray_key(ray: &Ray) -> RayKey {
    let (o, d) = (ray.origin, ray.direction);
    [o.x, o.y, o.z, d.x, d.y, d.z, ray.t_min, ray.t_max].map(f32::to_bits)
}

pub fn key_ray(key: &[u32]) -> Ray {
    let f = |i: usize| f32::from_bits(key[i]);
    Ray {
        origin: Vec3::new(f(0), f(1), f(2)),
        direction: Vec3::new(f(3), f(4), f(5)),
        t_min: f(6),
        t_max: f(7),
    }
}

fn screen_bits(screen: Option<Vec2>) -> [u32; 2] {
    screen.map_or([ABSENT; 2], |s| [s.x.to_bits(), s.y.to_bits()])
}

fn screen_of(bits: &[u32]) -> Option<Vec2> {
    (bits[0] != ABSENT || bits[1] != ABSENT)
        .then(|| Vec2::new(f32::from_bits(bits[0]), f32::from_bits(bits[1])))
}

fn sampling_bits(sampling: &LightSampling) -> [u32; 3] {
    [
        sampling.index,
        sampling.scramble.x.to_bits(),
        sampling.scramble.y.to_bits(),
    ]
}

fn sampling_of(bits: &[u32]) -> LightSampling {
    LightSampling {
        index: bits[0],
        scramble: Vec2::new(f32::from_bits(bits[1]), f32::from_bits(bits[2])),
    }
}

/// The bit of a trace key's depth word saying the ray goes on straight from a camera ray.
const FROM_CAMERA: u32 = 1 << 31;

pub fn trace_key(
    ray: &Ray,
    depth: u32,
    from_camera: bool,
    screen: Option<Vec2>,
    sampling: &LightSampling,
) -> TraceKey {
    let mut key = [0; 14];
    key[..8].copy_from_slice(&ray_key(ray));
    key[8] = depth | if from_camera { FROM_CAMERA } else { 0 };
    key[9..11].copy_from_slice(&screen_bits(screen));
    key[11..14].copy_from_slice(&sampling_bits(sampling));
    key
}

/// The inputs of `integrator::trace_continuing` a trace key stands for.
pub fn trace_inputs(key: &TraceKey) -> (Ray, u32, bool, Option<Vec2>, LightSampling) {
    (
        key_ray(key),
        key[8] & !FROM_CAMERA,
        key[8] & FROM_CAMERA != 0,
        screen_of(&key[9..11]),
        sampling_of(&key[11..14]),
    )
}

fn primary_key(
    ray: &Ray,
    screen: Option<Vec2>,
    cyclopean: Option<Vec3>,
    sampling: Option<&LightSampling>,
) -> PrimaryKey {
    let mut key = [0; 16];
    key[..8].copy_from_slice(&ray_key(ray));
    key[8..10].copy_from_slice(&screen_bits(screen));
    key[10..13].copy_from_slice(&cyclopean.map_or([ABSENT; 3], |c| c.to_array().map(f32::to_bits)));
    key[13..16].copy_from_slice(&sampling.map_or([ABSENT; 3], sampling_bits));
    key
}

/// A primary sample's inputs, kept for shading it after the compositing.
#[derive(Clone, Copy, Debug)]
pub struct PrimaryRecord {
    pub key: PrimaryKey,
    /// Asked through `fast_surface_color` (colour only) rather than `shade_primary_at`.
    pub fast: bool,
}

impl PrimaryRecord {
    pub fn ray(&self) -> Ray {
        key_ray(&self.key)
    }
    pub fn screen(&self) -> Option<Vec2> {
        screen_of(&self.key[8..10])
    }
    pub fn cyclopean(&self) -> Option<Vec3> {
        (self.key[10] != ABSENT).then(|| {
            Vec3::new(
                f32::from_bits(self.key[10]),
                f32::from_bits(self.key[11]),
                f32::from_bits(self.key[12]),
            )
        })
    }
    pub fn sampling(&self) -> LightSampling {
        sampling_of(&self.key[13..16])
    }
}

/// A slot's local word: not asked for by this rank's frame.
pub(crate) const UNVISITED: u32 = 0;
/// A slot's local word: this rank's part has no hit.
pub(crate) const MISSED: u32 = u32::MAX;
/// Words of a slot's kept inputs: the key, then whether it was a fast sample.
const INPUT_WORDS: usize = 17;

/// What a frame render of a data-parallel frame does with its primary samples, indexed by
/// slot: plane (ray of the pixel × sample of the pixel) by pixel. The first pass records this
/// rank's closest hit of each (and shades it at once when `shade_locally`); a later pass gives
/// back what the ranks computed.
pub struct PrimaryPass {
    pixels: usize,
    slots: usize,
    /// The first pass shades its samples as one device would (nothing it does asks other
    /// ranks): the fast renderer.
    shade_locally: bool,
    /// Per slot: [`UNVISITED`], [`MISSED`], or this rank's closest hit's `t` bits + 1
    /// (non-negative floats order as their bits do).
    local: Vec<AtomicU32>,
    /// Per slot: a hash of the sample's inputs (ranks rendering different frames differ).
    input_hash: Vec<AtomicU32>,
    /// Per slot, when shading waits for the compositing: the sample's inputs.
    inputs: Vec<[AtomicU32; INPUT_WORDS]>,
    replay: OnceLock<Replay>,
}

/// The samples of a later pass: per slot an index into `samples` (or [`NO_SAMPLE`]).
pub struct Replay {
    pub index: Vec<u32>,
    pub samples: Vec<Sample>,
}

/// A slot without a sample in a replay: its rank's part is blank in this rank's frame.
#[cfg_attr(not(feature = "mpi"), allow(dead_code))]
pub(crate) const NO_SAMPLE: u32 = u32::MAX;

const BLANK: Sample = Sample {
    color: Vec4::ZERO,
    hit: None,
};

impl PrimaryPass {
    /// A pass over `planes` samples per pixel of a `width`×`height` frame; `None` when its
    /// arrays cannot be allocated.
    pub fn new(width: u32, height: u32, planes: u32, shade_locally: bool) -> Option<PrimaryPass> {
        let pixels = width as usize * height as usize;
        let slots = pixels.checked_mul(planes as usize)?;
        let words = |count: usize| -> Option<Vec<AtomicU32>> {
            let mut v = Vec::new();
            v.try_reserve_exact(count).ok()?;
            v.extend((0..count).map(|_| AtomicU32::new(0)));
            Some(v)
        };
        let mut inputs = Vec::new();
        if !shade_locally {
            inputs.try_reserve_exact(slots).ok()?;
            inputs.extend((0..slots).map(|_| std::array::from_fn(|_| AtomicU32::new(0))));
        }
        Some(PrimaryPass {
            pixels,
            slots,
            shade_locally,
            local: words(slots)?,
            input_hash: words(slots)?,
            inputs,
            replay: OnceLock::new(),
        })
    }

    pub fn slots(&self) -> usize {
        self.slots
    }

    pub fn pixels(&self) -> usize {
        self.pixels
    }

    pub fn shades_locally(&self) -> bool {
        self.shade_locally
    }

    /// The slot's local word (see `local`).
    pub fn local(&self, slot: usize) -> u32 {
        self.local[slot].load(Ordering::Relaxed)
    }

    /// A digest of every visited slot's inputs, the same on ranks rendering the same frame.
    pub fn digest(&self) -> u64 {
        self.input_hash
            .iter()
            .enumerate()
            .fold(0xcbf2_9ce4_8422_2325u64, |h, (slot, hash)| {
                match hash.load(Ordering::Relaxed) {
                    0 => h,
                    hash => (h ^ (((slot as u64) << 32) | u64::from(hash)))
                        .wrapping_mul(0x100_0000_01b3),
                }
            })
    }

    /// The inputs this rank kept of a slot (none when shading locally).
    pub fn record(&self, slot: usize) -> PrimaryRecord {
        let words = &self.inputs[slot];
        PrimaryRecord {
            key: std::array::from_fn(|i| words[i].load(Ordering::Relaxed)),
            fast: words[16].load(Ordering::Relaxed) != 0,
        }
    }

    pub fn set_replay(&self, replay: Replay) {
        let _ = self.replay.set(replay);
    }

    fn replayed(&self, slot: usize) -> Sample {
        self.replay
            .get()
            .and_then(|replay| {
                let index = *replay.index.get(slot)?;
                replay.samples.get(index as usize).copied()
            })
            .unwrap_or(BLANK)
    }

    fn note(&self, slot: usize, key: &PrimaryKey, hit: Option<&SceneHit>, fast: bool) {
        if slot >= self.slots {
            return;
        }
        let local = hit.map_or(MISSED, |h| h.t.max(0.0).to_bits().saturating_add(1));
        self.local[slot].store(local, Ordering::Relaxed);
        let hash = key
            .iter()
            .fold(0x811c_9dc5u32, |h, w| (h ^ w).wrapping_mul(0x0100_0193));
        self.input_hash[slot].store(hash | 1, Ordering::Relaxed);
        if let Some(words) = self.inputs.get(slot) {
            for (word, value) in words.iter().zip(key) {
                word.store(*value, Ordering::Relaxed);
            }
            words[16].store(u32::from(fast), Ordering::Relaxed);
        }
    }
}

fn primary_pass(scene: &SceneSnapshot) -> Option<&PrimaryPass> {
    scene.cluster.as_ref()?.downcast_ref::<PrimaryPass>()
}

thread_local! {
    /// The slot of the primary sample the frame is about to shade on this thread.
    static SLOT: Cell<Option<usize>> = const { Cell::new(None) };
}

/// Frame hook: the next primary sample shaded on this thread is slot `slot` of a data-parallel
/// frame (`plane` × pixels + pixel).
pub fn at_slot(slot: usize) {
    SLOT.with(|s| s.set(Some(slot)));
}

/// The slot of the sample being shaded, for a frame pass of a data-parallel frame.
fn sample_slot(scene: &SceneSnapshot) -> Option<(&PrimaryPass, usize)> {
    let pass = primary_pass(scene).filter(|_| !evaluating())?;
    Some((pass, SLOT.with(Cell::take)?))
}

/// Hook of `shade_primary_at`: in a data-parallel frame's passes, records the sample or gives
/// back its result; `None` shades as usual.
#[inline(always)]
pub fn primary(
    scene: &SceneSnapshot,
    ray: &Ray,
    hit: Option<&SceneHit>,
    screen: Option<Vec2>,
    cyclopean: Option<Vec3>,
    sampling: &LightSampling,
) -> Option<Sample> {
    // Every pixel of a frame asks: the answer for a frame that is no cluster pass stays inline.
    scene.cluster.as_ref()?;
    primary_in_pass(scene, ray, hit, screen, cyclopean, sampling)
}

#[inline(never)]
fn primary_in_pass(
    scene: &SceneSnapshot,
    ray: &Ray,
    hit: Option<&SceneHit>,
    screen: Option<Vec2>,
    cyclopean: Option<Vec3>,
    sampling: &LightSampling,
) -> Option<Sample> {
    let (pass, slot) = sample_slot(scene)?;
    if pass.replay.get().is_some() {
        return Some(pass.replayed(slot));
    }
    let key = primary_key(ray, screen, cyclopean, Some(sampling));
    pass.note(slot, &key, hit, false);
    (!pass.shade_locally).then_some(BLANK)
}

/// Hook of the fast renderer's primary sample (`fast_surface_color` and `fast_surface_sample`),
/// as [`primary`]: `Err` holds the sample to use.
#[inline(always)]
pub fn fast_primary_sample<F: FnOnce() -> Vec2>(
    scene: &SceneSnapshot,
    ray: &Ray,
    hit: Option<&SceneHit>,
    screen: F,
    cyclopean: Option<Vec3>,
) -> Result<F, Sample> {
    if scene.cluster.is_none() {
        return Ok(screen);
    }
    fast_primary_sample_in_pass(scene, ray, hit, screen, cyclopean)
}

#[inline(never)]
fn fast_primary_sample_in_pass<F: FnOnce() -> Vec2>(
    scene: &SceneSnapshot,
    ray: &Ray,
    hit: Option<&SceneHit>,
    screen: F,
    cyclopean: Option<Vec3>,
) -> Result<F, Sample> {
    let Some((pass, slot)) = sample_slot(scene) else {
        return Ok(screen);
    };
    if pass.replay.get().is_some() {
        return Err(pass.replayed(slot));
    }
    if pass.shade_locally {
        // The screen position only places the background image: the hash goes without it.
        let key = primary_key(ray, None, cyclopean, None);
        pass.note(slot, &key, hit, true);
        return Ok(screen);
    }
    let key = primary_key(ray, Some(screen()), cyclopean, None);
    pass.note(slot, &key, hit, true);
    Err(BLANK)
}

/// A hasher for ray keys: their bits are already well spread, so a multiply per word does
/// (SipHash made the maps of a 1600×1600 frame's rays the larger part of a render).
#[derive(Default, Clone, Copy)]
pub struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0 ^ (self.0 >> 29)
    }

    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.write_u64(u64::from_le_bytes(word));
        }
    }

    fn write_u64(&mut self, value: u64) {
        self.0 = (self.0.rotate_left(23) ^ value).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }

    fn write_u32(&mut self, value: u32) {
        self.write_u64(u64::from(value));
    }

    fn write_usize(&mut self, value: usize) {
        self.write_u64(value as u64);
    }
}

pub type KeyMap<K, V> = HashMap<K, V, BuildHasherDefault<KeyHasher>>;
pub type KeySet<K> = HashSet<K, BuildHasherDefault<KeyHasher>>;

/// What a rank knows of the other ranks' parts while it shades.
#[derive(Default, Clone)]
pub struct Answers {
    pub rank: u32,
    /// Secondary rays: the rank whose part holds the closest hit ([`NO_RANK`] on a miss).
    pub closest: KeyMap<RayKey, u32>,
    /// Radiance along secondary rays shaded by other ranks.
    pub radiance: KeyMap<TraceKey, Vec4>,
}

/// No rank: a ray that misses every part.
pub(crate) const NO_RANK: u32 = u32::MAX;

/// What one evaluation of a shading lacked.
#[derive(Default, Debug)]
pub struct Pending {
    pub occlusion: Vec<RayKey>,
    /// Secondary rays whose closest hit is unknown, with the inputs to shade them.
    pub closest: Vec<TraceKey>,
    /// Secondary rays another rank (the `u32`) must shade.
    pub remote: Vec<(TraceKey, u32)>,
    /// Whether the result is incomplete.
    pub incomplete: bool,
}

struct Evaluation {
    answers: Arc<Answers>,
    /// The shading's shadow rays answered so far: whether any rank's part blocks them.
    blocked: Vec<(RayKey, bool)>,
    pending: Pending,
}

thread_local! {
    static EVALUATION: RefCell<Option<Evaluation>> = const { RefCell::new(None) };
}

fn evaluating() -> bool {
    EVALUATION.with(|e| e.borrow().is_some())
}

/// Runs `shading` with the rank's answers and the answers to this shading's own shadow rays
/// (`blocked`, given back): every scene query it makes goes through the hooks below; returns
/// its result and what it lacked.
pub fn evaluate<T>(
    answers: &Arc<Answers>,
    blocked: Vec<(RayKey, bool)>,
    shading: impl FnOnce() -> T,
) -> (T, Pending, Vec<(RayKey, bool)>) {
    EVALUATION.with(|e| {
        *e.borrow_mut() = Some(Evaluation {
            answers: Arc::clone(answers),
            blocked,
            pending: Pending::default(),
        })
    });
    let result = shading();
    let (pending, blocked) = EVALUATION
        .with(|e| e.borrow_mut().take())
        .map_or_else(Default::default, |e| (e.pending, e.blocked));
    (result, pending, blocked)
}

/// Hook of the shadow-ray test: while a rank shades, the answer of every rank.
pub fn occluded(scene: &SceneSnapshot, ray: &Ray) -> bool {
    if scene.cluster.is_none() {
        return scene.bvh.occluded(ray);
    }
    EVALUATION.with(|e| {
        let mut e = e.borrow_mut();
        let Some(evaluation) = e.as_mut() else {
            return scene.bvh.occluded(ray);
        };
        let key = ray_key(ray);
        match evaluation.blocked.iter().find(|(k, _)| *k == key) {
            Some((_, answer)) => *answer,
            None => {
                evaluation.pending.occlusion.push(key);
                evaluation.pending.incomplete = true;
                // Assumed unblocked: when every rank agrees, this evaluation stands.
                false
            }
        }
    })
}

/// Hook of the closest-hit query of secondary rays: while a rank shades, `Ok` with this
/// rank's hit when it is the closest of all ranks' (or none on a miss of all), else `Err`
/// with the radiance the hit's rank shaded (black while it is not known).
pub fn closest(
    scene: &SceneSnapshot,
    ray: &Ray,
    depth: u32,
    from_camera: bool,
    screen: Option<Vec2>,
    sampling: &LightSampling,
) -> Result<Option<SceneHit>, Vec4> {
    if scene.cluster.is_none() {
        return Ok(scene.bvh.intersect(ray));
    }
    EVALUATION.with(|e| {
        let mut e = e.borrow_mut();
        let Some(evaluation) = e.as_mut() else {
            return Ok(scene.bvh.intersect(ray));
        };
        let answers = &evaluation.answers;
        let pending = &mut evaluation.pending;
        let key = trace_key(ray, depth, from_camera, screen, sampling);
        match answers.closest.get(&ray_key(ray)).copied() {
            None => {
                pending.closest.push(key);
                pending.incomplete = true;
                Err(Vec4::ZERO)
            }
            Some(NO_RANK) => Ok(None),
            Some(owner) if owner == answers.rank => Ok(scene.bvh.intersect(ray)),
            Some(owner) => match answers.radiance.get(&key) {
                Some(radiance) => Err(*radiance),
                None => {
                    pending.remote.push((key, owner));
                    pending.incomplete = true;
                    Err(Vec4::ZERO)
                }
            },
        }
    })
}

/// A frame's tiles shared out among the ranks of a replicated render, and what each tile of
/// this rank took.
pub struct TileSplit {
    owner: Vec<u32>,
    rank: u32,
    nanos: Vec<AtomicU64>,
}

impl TileSplit {
    /// Tiles by estimated cost (`costs`, any unit; `None`: unknown, dealt out in turn), each
    /// given to the rank with the least work so far, the costliest first.
    pub fn new(tiles: usize, ranks: u32, rank: u32, costs: Option<&[f64]>) -> TileSplit {
        let mut owner = vec![0; tiles];
        match costs.filter(|c| c.len() == tiles && c.iter().any(|v| *v > 0.0)) {
            None => {
                for (tile, owner) in owner.iter_mut().enumerate() {
                    *owner = (tile % ranks as usize) as u32;
                }
            }
            Some(costs) => {
                let mut order: Vec<usize> = (0..tiles).collect();
                order.sort_by(|a, b| costs[*b].total_cmp(&costs[*a]).then(a.cmp(b)));
                let mut load = vec![0.0f64; ranks as usize];
                for tile in order {
                    let (least, _) = load
                        .iter()
                        .enumerate()
                        .min_by(|a, b| a.1.total_cmp(b.1).then(a.0.cmp(&b.0)))
                        .unwrap_or((0, &0.0));
                    owner[tile] = least as u32;
                    load[least] += costs[tile].max(1e-9);
                }
            }
        }
        TileSplit {
            owner,
            rank,
            nanos: (0..tiles).map(|_| AtomicU64::new(0)).collect(),
        }
    }

    pub fn owns(&self, tile: usize) -> bool {
        self.owner.get(tile) == Some(&self.rank)
    }

    pub fn owner(&self, tile: usize) -> u32 {
        self.owner[tile]
    }

    pub fn record(&self, tile: usize, took: Duration) {
        if let Some(nanos) = self.nanos.get(tile) {
            nanos.store(took.as_nanos() as u64, Ordering::Relaxed);
        }
    }

    /// Nanoseconds each tile took on this rank (0 for other ranks' tiles).
    pub fn times(&self) -> Vec<f64> {
        self.nanos
            .iter()
            .map(|n| n.load(Ordering::Relaxed) as f64)
            .collect()
    }
}

/// What a rank's last render across MPI ranks traced and exchanged (frame properties).
#[derive(Default)]
pub struct FrameTraffic {
    pub pixels_traced: AtomicU64,
    pub bytes_sent: AtomicU64,
    pub exchange_nanos: AtomicU64,
}

impl FrameTraffic {
    pub fn set(&self, pixels: u64, bytes: u64, exchange_seconds: f64) {
        self.pixels_traced.store(pixels, Ordering::Release);
        self.bytes_sent.store(bytes, Ordering::Release);
        self.exchange_nanos
            .store((exchange_seconds * 1e9) as u64, Ordering::Release);
    }

    #[cfg(feature = "mpi")]
    pub fn property(&self, name: &str) -> Option<crate::device::property::PropertyValue> {
        use crate::device::property::PropertyValue;
        match name {
            "pixelsTraced" => Some(PropertyValue::UInt64(
                self.pixels_traced.load(Ordering::Acquire),
            )),
            "mpiBytesSent" => Some(PropertyValue::UInt64(
                self.bytes_sent.load(Ordering::Acquire),
            )),
            "mpiExchangeTime" => Some(PropertyValue::Float32(
                self.exchange_nanos.load(Ordering::Acquire) as f32 * 1e-9,
            )),
            _ => None,
        }
    }
}

/// A sample as 18 words: colour, then (hit flag, t, point, ids, albedo, normal).
#[cfg_attr(not(feature = "mpi"), allow(dead_code))]
pub(crate) const SAMPLE_WORDS: usize = 18;

pub fn encode_sample(sample: &Sample, out: &mut Vec<u32>) {
    out.extend(sample.color.to_array().map(f32::to_bits));
    match &sample.hit {
        None => out.extend([0; 14]),
        Some(hit) => {
            out.push(1);
            out.push(hit.t.to_bits());
            out.extend(hit.point.to_array().map(f32::to_bits));
            out.extend([hit.primitive_id, hit.object_id, hit.instance_id]);
            out.extend(hit.albedo.to_array().map(f32::to_bits));
            out.extend(hit.normal.to_array().map(f32::to_bits));
        }
    }
}

pub fn decode_sample(words: &[u32]) -> Sample {
    let f = |i: usize| f32::from_bits(words[i]);
    let v3 = |i: usize| Vec3::new(f(i), f(i + 1), f(i + 2));
    Sample {
        color: Vec4::new(f(0), f(1), f(2), f(3)),
        hit: (words[4] == 1).then(|| PrimaryHit {
            t: f(5),
            point: v3(6),
            primitive_id: words[9],
            object_id: words[10],
            instance_id: words[11],
            albedo: v3(12),
            normal: v3(15),
        }),
    }
}

#[cfg(test)]
mod tests;
