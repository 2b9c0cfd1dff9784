//! The data-parallel ray exchange: which rank shades each primary sample, and the rounds that
//! answer every rank's shadow and secondary rays from every rank's part.

use std::fmt;
use std::sync::Arc;
use std::time::Instant;

use glam::Vec4;
use rayon::prelude::*;

use super::{
    Answers, KeySet, MISSED, NO_RANK, Pending, PrimaryPass, RayKey, TraceKey, UNVISITED, evaluate,
    key_ray, trace_inputs,
};
use crate::accel::SceneHit;
use crate::render::eye_light;
use crate::render::integrator::{self, Sample};
use crate::render::renderer::RendererSettings;
use crate::scene::world::SceneSnapshot;

/// The collectives a render across ranks needs; every rank calls each in the same order.
pub trait Exchange {
    fn rank(&self) -> u32;
    fn ranks(&self) -> u32;
    /// Every rank's words, by rank.
    fn all_gather(&self, mine: &[u32]) -> Result<Vec<Vec<u32>>, ClusterError>;
    /// Element-wise minimum over the ranks, in place.
    fn all_min(&self, values: &mut [u64]) -> Result<(), ClusterError>;
    /// Every rank's words on rank 0 (`None` on the others).
    fn gather_to_root(&self, mine: &[u32]) -> Result<Option<Vec<Vec<u32>>>, ClusterError>;
    /// Every rank's words on rank 0, or with `everywhere` on every rank.
    fn gather(
        &self,
        mine: &[u32],
        everywhere: bool,
    ) -> Result<Option<Vec<Vec<u32>>>, ClusterError> {
        if everywhere {
            self.all_gather(mine).map(Some)
        } else {
            self.gather_to_root(mine)
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub enum ClusterError {
    /// A collective did not complete in time: a rank is gone or stuck.
    Timeout { what: &'static str, seconds: f32 },
    /// A rank reported that it failed.
    RankFailed { rank: u32 },
    /// The ranks do not render the same frame (camera, size or samples differ).
    Mismatch(String),
    /// MPI returned an error.
    Mpi(String),
}

impl fmt::Display for ClusterError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ClusterError::Timeout { what, seconds } => write!(
                f,
                "{what} did not complete within {seconds} s (mpiTimeout): another rank has \
                 exited, failed or stopped rendering"
            ),
            ClusterError::RankFailed { rank } => write!(f, "rank {rank} reported a failure"),
            ClusterError::Mismatch(text) => write!(f, "{text}"),
            ClusterError::Mpi(text) => write!(f, "MPI error: {text}"),
        }
    }
}

/// What the exchange of one data-parallel render cost this rank.
#[derive(Default, Debug, Clone, Copy)]
pub struct Traffic {
    /// Rounds of shadow and secondary rays (after the primary compositing).
    pub rounds: u32,
    /// Words this rank contributed to collectives (×4 for bytes).
    pub words_sent: u64,
    /// Seconds spent in collectives and in testing other ranks' rays.
    pub exchange_seconds: f64,
}

/// What a rank shades: a primary sample it owns, or a secondary ray another rank (the
/// requester) asked of it.
enum Task {
    Primary,
    Child(Box<(u32, TraceKey)>),
}

/// A task and how far it got, kept in place between rounds.
struct TaskState {
    task: Task,
    /// What its last evaluation lacked (`None`: not evaluated yet, or done).
    pending: Option<Box<Pending>>,
    /// The answers to its shadow rays so far: whether any rank's part blocks them.
    blocked: Vec<(RayKey, bool)>,
    /// A child's radiance from its last evaluation.
    radiance: Vec4,
    done: bool,
    /// Evaluated this round and lacking answers: its rays go out.
    asking: bool,
    /// A child's radiance has gone to its requester.
    sent: bool,
}

impl TaskState {
    fn new(task: Task) -> TaskState {
        TaskState {
            task,
            pending: None,
            blocked: Vec::new(),
            radiance: Vec4::ZERO,
            done: false,
            asking: false,
            sent: false,
        }
    }
}

#[derive(Clone, Copy)]
enum Outcome {
    Sample(Sample),
    Radiance(Vec4),
}

/// Depth compositing of every slot of the pass: per slot the rank whose part holds the
/// closest hit (ties to the lower rank; rank 0 where no part is hit, which shades the
/// background). Checks first that every rank asks for the same samples.
pub fn composite(
    exchange: &dyn Exchange,
    pass: &PrimaryPass,
    traffic: &mut Traffic,
) -> Result<Vec<u32>, ClusterError> {
    let me = exchange.rank();
    let started = Instant::now();
    let (slots, digest) = (pass.slots() as u64, pass.digest());
    let mut check = [slots, !slots, digest, !digest];
    exchange.all_min(&mut check)?;
    if check[0] != !check[1] || check[2] != !check[3] {
        return Err(ClusterError::Mismatch(
            "the ranks' frames ask for different primary rays: every rank must render the same \
             frame (size, camera, renderer's pixelSamples)"
                .into(),
        ));
    }
    let mut winners: Vec<u64> = (0..pass.slots())
        .into_par_iter()
        .map(|slot| match pass.local(slot) {
            UNVISITED | MISSED => u64::MAX,
            local => (u64::from(local - 1) << 32) | u64::from(me),
        })
        .collect();
    exchange.all_min(&mut winners)?;
    traffic.words_sent += 2 * winners.len() as u64 + 8;
    traffic.exchange_seconds += started.elapsed().as_secs_f64();
    Ok(winners
        .into_par_iter()
        .map(|w| if w == u64::MAX { 0 } else { w as u32 })
        .collect())
}

/// Shades the primary samples this rank owns (`owners`, from [`composite`]) in bulk, asking
/// every rank's part what the shading asks of the scene, in rounds. Returns the owned slots in
/// order and their samples.
pub fn resolve(
    exchange: &dyn Exchange,
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    pass: &PrimaryPass,
    owners: &[u32],
    max_rounds: u32,
    traffic: &mut Traffic,
) -> Result<(Vec<usize>, Vec<Sample>), ClusterError> {
    let me = exchange.rank();
    let owned: Vec<usize> = (0..owners.len())
        .into_par_iter()
        .filter(|slot| owners[*slot] == me && pass.local(*slot) != UNVISITED)
        .collect();
    // The primary hits, traced once for every evaluation of their shading.
    let hits: Vec<Option<SceneHit>> = owned
        .par_iter()
        .map(|slot| scene.bvh.intersect(&pass.record(*slot).ray()))
        .collect();
    let mut tasks: Vec<TaskState> = (0..owned.len())
        .map(|_| TaskState::new(Task::Primary))
        .collect();
    let mut samples: Vec<Sample> = vec![
        Sample {
            color: Vec4::ZERO,
            hit: None,
        };
        owned.len()
    ];
    let mut answers = Answers {
        rank: me,
        ..Answers::default()
    };
    let mut requested: KeySet<TraceKey> = KeySet::default();
    let mut children: KeySet<(u32, TraceKey)> = KeySet::default();
    let mut quiet_rounds = 0;
    loop {
        // Shade what can progress, in place: new tasks, and tasks whose every missing answer
        // has come.
        let shared = Arc::new(std::mem::take(&mut answers));
        let step = |index: usize, state: &mut TaskState, sample: Option<&mut Sample>| {
            state.asking = false;
            if state.done {
                return;
            }
            if let Some(pending) = &state.pending {
                match progress(pending, &state.blocked, &shared) {
                    None => return,
                    // Evaluated with the right answers already.
                    Some(Progress::AsAssumed) => {
                        state.done = true;
                        state.pending = None;
                        return;
                    }
                    Some(Progress::Answered) => {}
                }
            }
            let blocked = std::mem::take(&mut state.blocked);
            let (outcome, pending, blocked) = evaluate(&shared, blocked, || {
                shade(&state.task, index, scene, settings, pass, &owned, &hits)
            });
            state.blocked = blocked;
            match (outcome, sample) {
                (Outcome::Sample(shaded), Some(sample)) => *sample = shaded,
                (Outcome::Radiance(radiance), _) => state.radiance = radiance,
                _ => {}
            }
            state.done = !pending.incomplete;
            state.asking = pending.incomplete;
            state.pending = pending.incomplete.then(|| Box::new(pending));
        };
        let (primaries, others) = tasks.split_at_mut(owned.len());
        primaries
            .par_iter_mut()
            .zip(samples.par_iter_mut())
            .enumerate()
            .for_each(|(index, (state, sample))| step(index, state, Some(sample)));
        others
            .par_iter_mut()
            .for_each(|state| step(usize::MAX, state, None));
        answers = Arc::try_unwrap(shared).unwrap_or_else(|shared| (*shared).clone());
        let exchange_started = Instant::now();
        let mut occlusion: Vec<RayKey> = Vec::new();
        let mut closest: Vec<TraceKey> = Vec::new();
        let mut remote: Vec<(TraceKey, u32)> = Vec::new();
        let mut results: Vec<u32> = Vec::new();
        // Which task asked each shadow ray: the answers come back in the same order.
        let mut askers: Vec<u32> = Vec::new();
        for (task, state) in tasks.iter_mut().enumerate() {
            if let (Some(pending), true) = (&state.pending, state.asking) {
                // Rays asked twice are rare (two samples of one pixel); they are answered twice.
                occlusion.extend_from_slice(&pending.occlusion);
                askers.extend(pending.occlusion.iter().map(|_| task as u32));
                closest.extend_from_slice(&pending.closest);
                for (key, owner) in &pending.remote {
                    if requested.insert(*key) {
                        remote.push((*key, *owner));
                    }
                }
            }
            if let (Task::Child(child), true, false) = (&state.task, state.done, state.sent) {
                let (requester, key) = &**child;
                results.push(*requester);
                results.extend_from_slice(key);
                results.extend(state.radiance.to_array().map(f32::to_bits));
                state.sent = true;
            }
        }
        let busy = tasks.iter().any(|t| !t.done);
        let mut message = vec![
            u32::from(busy),
            0,
            occlusion.len() as u32,
            closest.len() as u32,
            remote.len() as u32,
            (results.len() / RESULT_WORDS) as u32,
        ];
        occlusion.iter().for_each(|k| message.extend_from_slice(k));
        closest.iter().for_each(|k| message.extend_from_slice(k));
        for (key, owner) in &remote {
            message.extend_from_slice(key);
            message.push(*owner);
        }
        message.extend_from_slice(&results);
        traffic.words_sent += message.len() as u64;
        let gathered = exchange.all_gather(&message)?;
        let messages: Vec<Message> = gathered.iter().map(|words| Message::parse(words)).collect();
        if let Some(rank) = messages.iter().position(|m| m.failed) {
            return Err(ClusterError::RankFailed { rank: rank as u32 });
        }
        let anything = messages.iter().any(|m| !m.is_empty());
        if !anything && !messages.iter().any(|m| m.busy) {
            traffic.exchange_seconds += exchange_started.elapsed().as_secs_f64();
            break;
        }
        traffic.rounds += 1;
        if traffic.rounds > max_rounds {
            return Err(ClusterError::Mismatch(format!(
                "the ray exchange did not settle within {max_rounds} rounds"
            )));
        }
        quiet_rounds = if anything { 0 } else { quiet_rounds + 1 };
        if quiet_rounds > 2 {
            return Err(ClusterError::Mismatch(
                "the ray exchange stalled: a rank waits for an answer no rank computes".into(),
            ));
        }
        // This rank's answers to every rank's rays, reduced over the ranks.
        let queries: Vec<(&[u32], bool)> = messages
            .iter()
            .flat_map(|m| m.occlusion().map(|k| (k, true)))
            .chain(
                messages
                    .iter()
                    .flat_map(|m| m.closest().map(|k| (k, false))),
            )
            .collect();
        let mut values: Vec<u64> = queries
            .par_iter()
            .map(|(key, shadow)| {
                let ray = key_ray(key);
                if *shadow {
                    u64::from(!scene.bvh.occluded(&ray))
                } else {
                    scene.bvh.intersect(&ray).map_or(u64::MAX, |h| {
                        (u64::from(h.t.max(0.0).to_bits()) << 32) | u64::from(me)
                    })
                }
            })
            .collect();
        exchange.all_min(&mut values)?;
        traffic.words_sent += 2 * values.len() as u64;
        // This rank's shadow rays' answers go to the tasks that asked them.
        let shadow_rays: usize = messages.iter().map(|m| m.counts[0]).sum();
        let before: usize = messages[..me as usize].iter().map(|m| m.counts[0]).sum();
        for ((key, task), value) in occlusion.iter().zip(&askers).zip(&values[before..]) {
            if let Some(state) = tasks.get_mut(*task as usize) {
                state.blocked.push((*key, *value == 0));
            }
        }
        let mut value = values.into_iter().skip(shadow_rays);
        for (rank, m) in messages.iter().enumerate() {
            let rank = rank as u32;
            for key in m.closest() {
                let winner = value.next().unwrap_or(u64::MAX);
                let hit_rank = if winner == u64::MAX {
                    NO_RANK
                } else {
                    winner as u32
                };
                let trace = trace_of(key);
                if rank == me {
                    answers.closest.insert(ray_of(key), hit_rank);
                    if hit_rank != me && hit_rank != NO_RANK {
                        // The hit's rank starts shading it now (below, on that rank).
                        requested.insert(trace);
                    }
                }
                if hit_rank == me {
                    answers.closest.insert(ray_of(key), me);
                    if rank != me && children.insert((rank, trace)) {
                        tasks.push(TaskState::new(Task::Child(Box::new((rank, trace)))));
                    }
                }
            }
            for (key, owner) in m.remote() {
                if owner == me {
                    answers.closest.insert(ray_of(key), me);
                    let trace = trace_of(key);
                    if children.insert((rank, trace)) {
                        tasks.push(TaskState::new(Task::Child(Box::new((rank, trace)))));
                    }
                }
            }
            for result in m.results() {
                if result[0] == me {
                    let colour = std::array::from_fn(|i| f32::from_bits(result[15 + i]));
                    answers
                        .radiance
                        .insert(trace_of(&result[1..15]), Vec4::from_array(colour));
                }
            }
        }
        traffic.exchange_seconds += exchange_started.elapsed().as_secs_f64();
    }
    Ok((owned, samples))
}

/// Words of a result: requester, trace key, colour.
const RESULT_WORDS: usize = 1 + 14 + 4;

fn ray_of(words: &[u32]) -> RayKey {
    std::array::from_fn(|i| words[i])
}

fn trace_of(words: &[u32]) -> TraceKey {
    std::array::from_fn(|i| words[i])
}

/// What the answers an evaluation lacked change, once they have all come.
enum Progress {
    /// Each is what the evaluation assumed (a shadow ray no rank blocks): its result stands,
    /// as shading is a pure function of its answers.
    AsAssumed,
    /// The shading must be evaluated again.
    Answered,
}

/// `None` while an answer the evaluation lacked has not come (`blocked`: the answers to the
/// shading's shadow rays).
fn progress(pending: &Pending, blocked: &[(RayKey, bool)], answers: &Answers) -> Option<Progress> {
    let mut as_assumed = pending.closest.is_empty() && pending.remote.is_empty();
    for key in &pending.occlusion {
        let (_, answer) = blocked.iter().find(|(k, _)| k == key)?;
        as_assumed &= !*answer;
    }
    let answered = pending
        .closest
        .iter()
        .all(|k| answers.closest.contains_key(&ray_of(k)))
        && pending
            .remote
            .iter()
            .all(|(k, _)| answers.radiance.contains_key(k));
    match (answered, as_assumed) {
        (false, _) => None,
        (true, true) => Some(Progress::AsAssumed),
        (true, false) => Some(Progress::Answered),
    }
}

/// Shades a task; `index`: a primary task's position in `owned`.
fn shade(
    task: &Task,
    index: usize,
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    pass: &PrimaryPass,
    owned: &[usize],
    hits: &[Option<SceneHit>],
) -> Outcome {
    match task {
        Task::Primary => {
            let record = pass.record(owned[index]);
            let ray = record.ray();
            let hit = hits[index];
            if record.fast {
                let screen = record.screen().unwrap_or_default();
                Outcome::Sample(eye_light::fast_surface_sample(
                    scene,
                    settings,
                    &ray,
                    hit.as_ref(),
                    || screen,
                    record.cyclopean(),
                ))
            } else {
                Outcome::Sample(integrator::shade_primary_at(
                    scene,
                    settings,
                    &ray,
                    hit,
                    record.screen(),
                    record.cyclopean(),
                    &record.sampling(),
                ))
            }
        }
        Task::Child(child) => {
            let (ray, depth, from_camera, screen, sampling) = trace_inputs(&child.1);
            Outcome::Radiance(integrator::trace_continuing(
                scene,
                settings,
                &ray,
                depth,
                from_camera,
                screen,
                &sampling,
            ))
        }
    }
}

/// One rank's message of a round, read.
struct Message<'a> {
    busy: bool,
    failed: bool,
    counts: [usize; 4],
    words: &'a [u32],
}

const HEADER_WORDS: usize = 6;
const SIZES: [usize; 4] = [8, 14, 15, RESULT_WORDS];

impl<'a> Message<'a> {
    fn parse(words: &'a [u32]) -> Message<'a> {
        if words.len() < HEADER_WORDS {
            return Message {
                busy: false,
                failed: true,
                counts: [0; 4],
                words: &[],
            };
        }
        let counts = std::array::from_fn(|i| words[2 + i] as usize);
        let expected: usize = (0..4).map(|i| counts[i] * SIZES[i]).sum();
        let failed = words[1] != 0 || words.len() != HEADER_WORDS + expected;
        Message {
            busy: words[0] != 0,
            failed,
            counts: if failed { [0; 4] } else { counts },
            words: &words[HEADER_WORDS.min(words.len())..],
        }
    }

    fn is_empty(&self) -> bool {
        self.counts.iter().all(|c| *c == 0)
    }

    fn part(&self, which: usize) -> std::slice::ChunksExact<'a, u32> {
        let start: usize = (0..which).map(|i| self.counts[i] * SIZES[i]).sum();
        let end = start + self.counts[which] * SIZES[which];
        self.words[start..end].chunks_exact(SIZES[which])
    }

    fn occlusion(&self) -> std::slice::ChunksExact<'a, u32> {
        self.part(0)
    }

    fn closest(&self) -> std::slice::ChunksExact<'a, u32> {
        self.part(1)
    }

    fn remote(&self) -> impl Iterator<Item = (&'a [u32], u32)> {
        self.part(2).map(|w| (&w[..14], w[14]))
    }

    fn results(&self) -> std::slice::ChunksExact<'a, u32> {
        self.part(3)
    }
}
