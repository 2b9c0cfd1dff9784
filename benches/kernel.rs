//! The ray kernel against Embree's (`cargo bench --bench kernel`): the scene and camera of the
//! Embree probe `embree_rays` (a GRID×GRID height field over [-1,1]², 2·GRID² triangles; an
//! orbiting perspective camera, fovy 60°, 1600×1600 pixel centres), for GRID 22, 71, 224, 708 and
//! 1414 (968 to 4M triangles). Per size it prints, as medians of frames 1..FRAMES (frame 0 warms
//! up), the kernel alone (the frame's own primary rays, made beforehand, traced by the packet
//! traversal on every core, no shading) and the whole `fast` frame through the device as a VR
//! application asks for it (rays, traversal, shading, sRGB colour and depth). The hit checksum
//! (sum of primitive index + 1 over hits) is the probe's, so equal checksums mean the same hits
//! up to rays that graze an edge.
//!
//! `CAVETRACE_EMBREE_PROBE=/path/to/embree_rays` (built by `../shared/tools/embree4.sh`) runs
//! the probe with the same arguments (`GRID SIZE SIZE FRAMES THREADS`) before and after each
//! size's frames and prints cavetrace's wall times as ratios to Embree's faster run:
//! one by one against `rtcIntersect1`, packets and the whole frame against the better of
//! `rtcIntersect8` and `rtcIntersect16`.
//!
//! Beside the packets of primary rays it times the same rays traced one by one (the path of
//! light-field, shadow and secondary rays), and every instruction-set path this CPU has
//! (baseline SSE2; AVX2; AVX-512), alternating frame by frame.
//! `CAVETRACE_BENCH_QUICK=1`: two sizes at 256×256, 3 frames. `CAVETRACE_BENCH_GRIDS=22,708`:
//! only those sizes (for profiling one). `CAVETRACE_BENCH_PARTS=packets,frame`: only those of
//! `packets`, `single`, `frame` (a part left out prints 0). `CAVETRACE_BENCH_ISAS=avx2,avx512`:
//! only those instruction-set paths. `--features kernel-counters`: also prints, per size, the inner
//! nodes, leaves and triangles per ray of both walks (`accel::counters`; the single-ray times
//! are then those of the counting generic walk, not the real one), and with
//! `CAVETRACE_TREE_STATISTICS=1` each tree's shape and surface-area costs.
//! `CAVETRACE_BENCH_LATTICE=rows|columns|checker`: trace one eye of an interleaved stereo frame
//! instead (half the rays, each 64-ray packet spanning 8×16 or 16×8 pixels; the Embree probe
//! still traces the whole frame, so its ratios do not apply). `stride-N`: the points a budgeted
//! render's refinement level of stride N traces (N = 64, 32, 16, 8, 4, 2; in 8×8 blocks of
//! lattice points, skipped points as rays that hit nothing). `CAVETRACE_BENCH_REPEAT=n`: the
//! rays n times over (for the small sparse levels). `CAVETRACE_BENCH_SHAPE=Q,K,G` (lattices):
//! blocks of other shapes, `Q` quadrants, `K` groups per quadrant and `G` lanes per group
//! across (`2,2,2`: the renderer's 8×8 points of 2×2 quads; `4,1,4`: 16×4 points, groups of
//! 4×1). `CAVETRACE_BENCH_CHUNK=n`: packets of n rays instead of 64.
//! `CAVETRACE_BENCH_PARTS=...,eights` (only when named): the same 64-ray chunks also as eight
//! eights through `SceneBvh::intersect8_with`, grouped 4×2 points (two quads side by side) or,
//! for `columns` and `checker`, 2×4 (`CAVETRACE_BENCH_EIGHTS=4x2|2x4` to choose; `packed`: a
//! chunk's rays that can hit, in lane order, eight at a time), subtrees
//! that at most `CAVETRACE_BENCH_SINGLE_UP_TO` (default 1) lanes reach walked ray by ray.

#[path = "../tests/common/mod.rs"]
mod common;
use common::*;
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use cavetrace::accel::counters::{self, TraversalCounts};
use cavetrace::accel::isa::{self, Isa};
use cavetrace::accel::{PacketScratch, Ray, SceneBvh};

/// CPU milliseconds used by this process so far (all threads).
fn cpu_ms() -> f64 {
    cpu_seconds() * 1e3
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The probe's height field: vertex (i, j) at x = −1 + 2i/G, y = −1 + 2j/G,
/// z = 0.08 sin(9x) cos(7y) + 0.05 sin(23xy); cell triangles (a, b, d), (a, d, c).
fn height_field(dev: ANARIDevice, grid: u32) -> ANARIGeometry {
    let (geometry, _) = grid_geometry(dev, grid, |i, j| {
        let x = -1.0 + 2.0 * i as f32 / grid as f32;
        let y = -1.0 + 2.0 * j as f32 / grid as f32;
        let z = 0.08 * (9.0 * x).sin() * (7.0 * y).cos() + 0.05 * (23.0 * x * y).sin();
        [x, y, z]
    });
    commit(dev, geometry);
    geometry
}

/// The probe's camera of frame f: position (2.2 cos a, 2.2 sin a, 1.3), a = 0.02 f, looking at
/// −position + (0, 0, 0.1), up +z, fovy 60°.
fn place_camera(dev: ANARIDevice, camera: ANARICamera, frame: u32) {
    let a = 0.02 * frame as f32;
    let eye = [2.2 * a.cos(), 2.2 * a.sin(), 1.3f32];
    let direction = [-eye[0], -eye[1], -eye[2] + 0.1];
    set(dev, camera, "position", ANARI_FLOAT32_VEC3, &eye);
    set(dev, camera, "direction", ANARI_FLOAT32_VEC3, &direction);
    set(dev, camera, "up", ANARI_FLOAT32_VEC3, &[0.0f32, 0.0, 1.0]);
    set(
        dev,
        camera,
        "fovy",
        ANARI_FLOAT32,
        &std::f32::consts::FRAC_PI_3,
    );
    set(dev, camera, "aspect", ANARI_FLOAT32, &1.0f32);
    commit(dev, camera);
}

/// How `trace` hands each chunk of 64 rays to the kernel.
#[derive(Clone, Copy)]
enum Walk {
    /// One frustum packet (`intersect_packet_with`).
    Packet,
    /// Ray by ray (`intersect_into`).
    OneByOne,
    /// Eight eights (`intersect8_with`, lanes of `EIGHTS[grouping]`), subtrees that at most
    /// `single_up_to` lanes reach walked ray by ray.
    Eights { grouping: usize, single_up_to: u32 },
}

/// The lanes of a 64-ray chunk (sixteen 2×2 quads, four quads a row) grouped as eight eights:
/// `[0]` 4×2 points (two quads side by side), `[1]` 2×4 points (two quads one above the
/// other).
const EIGHTS: [[[usize; 8]; 8]; 2] = {
    let mut groups = [[[0; 8]; 8]; 2];
    let mut eight = 0;
    while eight < 8 {
        // 4×2: quads 2e, 2e + 1 are lanes 8e..8e + 8.
        let mut i = 0;
        while i < 8 {
            groups[0][eight][i] = 8 * eight + i;
            i += 1;
        }
        // 2×4: quads q and q + 4, q = 0, 1, 2, 3, 8, 9, 10, 11.
        let quad = eight % 4 + 8 * (eight / 4);
        let mut i = 0;
        while i < 4 {
            groups[1][eight][i] = 4 * quad + i;
            groups[1][eight][4 + i] = 4 * (quad + 4) + i;
            i += 1;
        }
        eight += 1;
    }
    groups
};

/// `Walk::Eights` grouping: the chunk's rays that can hit (nonzero direction), in lane order,
/// eight at a time.
const PACKED: usize = 2;

/// A ray that hits nothing (zero direction): the render's filler for points a lattice skips.
const NO_RAY: Ray = Ray {
    origin: glam::Vec3::ZERO,
    direction: glam::Vec3::ZERO,
    t_min: 0.0,
    t_max: 0.0,
};

/// The hits of a chunk of up to 64 rays as eights (`Walk::Eights`): 4×2 eights of a full chunk
/// walked in place, other groupings through copies of the rays and hits (copied 4×2 eights cost
/// 3–9 % more at 1M triangles, about 13 % at 968).
fn trace_eights(
    scene: &SceneBvh,
    chunk: &[Ray],
    hits: &mut [Option<cavetrace::accel::SceneHit>; 64],
    grouping: usize,
    single_up_to: u32,
) {
    if grouping == 0 && chunk.len() == 64 {
        for (eight, found) in chunk.chunks_exact(8).zip(hits.chunks_exact_mut(8)) {
            let (eight, found) = (eight.try_into().unwrap(), found.try_into().unwrap());
            scene.intersect8_with(eight, found, single_up_to);
        }
        return;
    }
    if grouping == PACKED {
        hits.fill(None);
    }
    let mut walk_eight = |lanes: &[usize]| {
        let eight = std::array::from_fn(|i| lanes.get(i).and_then(|&l| chunk.get(l)).copied());
        let eight = eight.map(|ray| ray.unwrap_or(NO_RAY));
        let mut found = [None; 8];
        scene.intersect8_with(&eight, &mut found, single_up_to);
        for (lane, hit) in lanes.iter().zip(found) {
            hits[*lane] = hit;
        }
    };
    if grouping == PACKED {
        // The chunk's rays that can hit, eight at a time.
        let packed: Vec<usize> = (0..chunk.len())
            .filter(|&lane| chunk[lane].direction != glam::Vec3::ZERO)
            .collect();
        packed.chunks(8).for_each(walk_eight);
    } else {
        EIGHTS[grouping].iter().for_each(|lanes| walk_eight(lanes));
    }
}

/// Traces `rays` in 64-ray chunks as `walk` says on `threads` threads, 16 chunks at a time;
/// (wall ms, CPU ms, hit checksum); with `--features kernel-counters` the walks' counts are
/// added to `counts`.
fn trace(
    scene: &SceneBvh,
    rays: &[Ray],
    threads: usize,
    walk: Walk,
    counts: &mut TraversalCounts,
) -> (f64, f64, u64) {
    let next = AtomicUsize::new(0);
    let chunk_rays: usize = std::env::var("CAVETRACE_BENCH_CHUNK")
        .ok()
        .map_or(64, |n| n.parse().expect("CAVETRACE_BENCH_CHUNK: a number"));
    let packets = rays.len().div_ceil(chunk_rays);
    let (start, cpu_start) = (Instant::now(), cpu_ms());
    let checksum = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| {
                    counters::take();
                    let mut scratch = PacketScratch::new();
                    let mut hits = [None; 64];
                    let mut checksum = 0u64;
                    loop {
                        let first = next.fetch_add(16, Ordering::Relaxed);
                        if first >= packets {
                            break (checksum, counters::take());
                        }
                        for packet in first..(first + 16).min(packets) {
                            let chunk = &rays
                                [packet * chunk_rays..((packet + 1) * chunk_rays).min(rays.len())];
                            match walk {
                                Walk::OneByOne => {
                                    for (hit, ray) in hits.iter_mut().zip(chunk) {
                                        scene.intersect_into(ray, hit);
                                    }
                                }
                                Walk::Packet => {
                                    scene.intersect_packet_with(&mut scratch, chunk, &mut hits)
                                }
                                Walk::Eights {
                                    grouping,
                                    single_up_to,
                                } => trace_eights(scene, chunk, &mut hits, grouping, single_up_to),
                            }
                            checksum += hits[..chunk.len()]
                                .iter()
                                .flatten()
                                .map(|hit| u64::from(hit.primitive) + 1)
                                .sum::<u64>();
                        }
                    }
                })
            })
            .collect();
        let mut checksum = 0;
        for worker in workers {
            let (sum, worker_counts) = worker.join().unwrap();
            checksum += sum;
            *counts += worker_counts;
        }
        checksum
    });
    (
        start.elapsed().as_secs_f64() * 1e3,
        cpu_ms() - cpu_start,
        checksum,
    )
}

/// With `CAVETRACE_BENCH_HITS=PREFIX`, writes every ray's hit of frame 1, ray by ray then by
/// packets, to `PREFIX-GRID.hits`: per ray the primitive and the bits of `t` (little-endian
/// u32 each; `u32::MAX` twice for a miss), to compare two builds' trees hit by hit.
fn write_hits(scene: &SceneBvh, rays: &[Ray], grid: u32) {
    let Some(prefix) = std::env::var_os("CAVETRACE_BENCH_HITS") else {
        return;
    };
    let mut bytes = Vec::with_capacity(rays.len() * 16);
    let mut push = |hit: &Option<cavetrace::accel::SceneHit>| {
        let (primitive, t) =
            hit.map_or((u32::MAX, u32::MAX), |hit| (hit.primitive, hit.t.to_bits()));
        bytes.extend(primitive.to_le_bytes());
        bytes.extend(t.to_le_bytes());
    };
    let mut hit = None;
    for ray in rays {
        scene.intersect_into(ray, &mut hit);
        push(&hit);
    }
    let mut scratch = PacketScratch::new();
    let mut hits = [None; 64];
    for chunk in rays.chunks(64) {
        scene.intersect_packet_with(&mut scratch, chunk, &mut hits);
        hits[..chunk.len()].iter().for_each(&mut push);
    }
    let mut path = prefix;
    path.push(format!("-{grid}.hits"));
    std::fs::write(&path, bytes).expect("writing the hits");
}

/// Per ray: the walks' inner nodes, leaves and triangles (`--features kernel-counters`).
fn print_counts(triangles: u32, [packets, single]: &[TraversalCounts; 2]) {
    let per = |value: u64, rays: u64| value as f64 / rays.max(1) as f64;
    println!(
        "  {triangles:>9} counts per ray: one by one {:.3} nodes, {:.3} leaves, {:.3} triangles \
         ({} rays); frustum packets {:.4} nodes (per packet {:.2}), {:.3} leaves, {:.3} \
         triangles, {:.4} leaf tests of 4 rays ({} packets, {} rays; {} rays one by one)",
        per(single.nodes, single.rays),
        per(single.leaves, single.rays),
        per(single.triangles, single.rays),
        single.rays,
        per(packets.packet_nodes, packets.packet_rays),
        per(packets.packet_nodes, packets.packets),
        per(packets.packet_leaf_rays, packets.packet_rays),
        per(packets.packet_triangle_rays, packets.packet_rays),
        per(packets.packet_leaf_groups, packets.packet_rays),
        packets.packets,
        packets.packet_rays,
        packets.rays,
    );
}

/// Ray `i` of a 64-ray block's point within the block: sixteen 2×2 quads, four quads a row,
/// as the renderer packs a block.
fn block_point(i: u32) -> (u32, u32) {
    let (quad, lane) = (i / 4, i % 4);
    ((quad % 4) * 2 + lane % 2, (quad / 4) * 2 + lane / 2)
}

/// Ray `i` of a block at another point (`CAVETRACE_BENCH_SHAPE=Q,K,G`, lattices only): the
/// packet's four quadrants (`QUADRANT_GROUPS`) lie `Q` across, a quadrant's four groups `K`
/// across, a group's four lanes `G` across (the rest of each of the three 4s down); the block
/// is then `Q·K·G` points across. `2,2,2` is [`block_point`].
fn shaped_block_point(
    i: u32,
    (quadrants_across, groups_across, lanes_across): Shape,
) -> (u32, u32) {
    const QUADRANT_GROUPS: [[u32; 4]; 4] =
        [[0, 1, 4, 5], [2, 3, 6, 7], [8, 9, 12, 13], [10, 11, 14, 15]];
    let (group, lane) = (i / 4, i % 4);
    let (quadrant, k) = (0..4)
        .find_map(|q| {
            let at = QUADRANT_GROUPS[q as usize].iter().position(|&g| g == group);
            at.map(|k| (q, k as u32))
        })
        .expect("every group is in a quadrant");
    let (group_width, group_height) = (lanes_across, 4 / lanes_across);
    let quadrant_width = groups_across * group_width;
    let quadrant_height = (4 / groups_across) * group_height;
    (
        (quadrant % quadrants_across) * quadrant_width
            + (k % groups_across) * group_width
            + lane % lanes_across,
        (quadrant / quadrants_across) * quadrant_height
            + (k / groups_across) * group_height
            + lane / lanes_across,
    )
}

/// Quadrants, groups and lanes across (`shaped_block_point`).
type Shape = (u32, u32, u32);

fn bench_shape() -> Option<Shape> {
    let shape = std::env::var("CAVETRACE_BENCH_SHAPE").ok()?;
    let across: Vec<u32> = shape
        .split(',')
        .map(|n| {
            n.trim()
                .parse()
                .expect("CAVETRACE_BENCH_SHAPE=Q,K,G: numbers")
        })
        .collect();
    match across[..] {
        [q, k, g] if [q, k, g].iter().all(|n| [1, 2, 4].contains(n)) => Some((q, k, g)),
        _ => panic!("CAVETRACE_BENCH_SHAPE={shape}: three of 1, 2, 4"),
    }
}

/// The rays of an interleaved stereo frame's eyes (`CAVETRACE_BENCH_LATTICE`), each eye's
/// pixels as a lattice of 8×8 blocks of 2×2 quads, as the renderer packs them: `rows` (every
/// other row), `columns` (every other column), `checker` (x + y even): one eye, half the rays,
/// each 64-ray packet spanning 8×16 or 16×8 pixels; `rows-both`: both eyes of rows, one eye's
/// whole lattice after the other's; `rows-pairs`: both eyes, the other eye's block right after
/// each block of the same pixels. `mono` (default): all `rays` (already in blocks) unchanged.
fn lattice_rays(rays: Vec<((u32, u32), Ray)>, size: u32, lattice: &str) -> Vec<Ray> {
    if let Some(stride) = lattice.strip_prefix("stride-") {
        let stride = stride
            .parse()
            .expect("CAVETRACE_BENCH_LATTICE=stride-N: a number");
        return level_rays(rays, size, stride);
    }
    type Pixel = fn(u32, u32, u32) -> (u32, u32);
    let rows: Pixel = |x, y, eye| (x, 2 * y + eye);
    let (pixel, eyes, pairs): (Pixel, u32, bool) = match lattice {
        "mono" => return rays.into_iter().map(|(_, ray)| ray).collect(),
        "rows" => (rows, 1, false),
        "rows-both" => (rows, 2, false),
        "rows-pairs" => (rows, 2, true),
        "columns" => (|x, y, eye| (2 * x + eye, y), 1, false),
        "checker" => (|x, y, eye| (2 * x + ((y + eye) & 1), y), 1, false),
        other => panic!(
            "CAVETRACE_BENCH_LATTICE={other}: mono, rows, rows-both, rows-pairs, columns or \
             checker"
        ),
    };
    let (width, height) = match lattice {
        "rows" | "rows-both" | "rows-pairs" => (size, size / 2),
        _ => (size / 2, size),
    };
    let mut by_pixel = vec![None; (size * size) as usize];
    for ((x, y), ray) in rays {
        by_pixel[(y * size + x) as usize] = Some(ray);
    }
    let shape = bench_shape();
    let (block_width, block_height) =
        shape.map_or((8, 8), |(q, k, g)| (q * k * g, 64 / (q * k * g)));
    let blocks: Vec<(u32, u32)> = (0..height)
        .step_by(block_height as usize)
        .flat_map(|by| {
            (0..width)
                .step_by(block_width as usize)
                .map(move |bx| (bx, by))
        })
        .collect();
    let order: Vec<(u32, (u32, u32))> = match pairs {
        true => blocks
            .iter()
            .flat_map(|block| (0..eyes).map(move |eye| (eye, *block)))
            .collect(),
        false => (0..eyes)
            .flat_map(|eye| blocks.iter().map(move |block| (eye, *block)))
            .collect(),
    };
    let mut lattice_rays = Vec::with_capacity(order.len() * 64);
    for (eye, (bx, by)) in order {
        for i in 0..64 {
            let (dx, dy) = shape.map_or(block_point(i), |shape| shaped_block_point(i, shape));
            let (x, y) = pixel(bx + dx, by + dy, eye);
            lattice_rays.push(by_pixel[(y * size + x) as usize].expect("a pixel's ray"));
        }
    }
    lattice_rays
}

/// The rays of a budgeted render's refinement level of `stride` (`CAVETRACE_BENCH_LATTICE=
/// stride-N`): pixels (stride·s, stride·t) in 8×8 blocks of lattice points, as the renderer
/// packs them, the points of the coarser level (s and t even; none at the coarsest stride 64)
/// and those beyond the frame as rays that hit nothing.
fn level_rays(rays: Vec<((u32, u32), Ray)>, size: u32, stride: u32) -> Vec<Ray> {
    let mut by_pixel = vec![NO_RAY; (size * size) as usize];
    for ((x, y), ray) in rays {
        by_pixel[(y * size + x) as usize] = ray;
    }
    let points = size.div_ceil(stride);
    let mut level = Vec::new();
    for by in (0..points).step_by(8) {
        for bx in (0..points).step_by(8) {
            for i in 0..64 {
                let (ds, dt) = block_point(i);
                let (s, t) = (bx + ds, by + dt);
                let skipped = stride < 64 && s % 2 == 0 && t % 2 == 0;
                level.push(if s >= points || t >= points || skipped {
                    NO_RAY
                } else {
                    by_pixel[(stride * t * size + stride * s) as usize]
                });
            }
        }
    }
    level
}

/// One run of the Embree probe: its median wall ms per mode and its hit checksum.
struct EmbreeRun {
    single_ms: f64,
    packet8_ms: f64,
    packet16_ms: f64,
    checksum: u64,
}

impl EmbreeRun {
    fn best_packet_ms(&self) -> f64 {
        self.packet8_ms.min(self.packet16_ms)
    }

    /// Each mode's faster time of two runs (the comparison in Embree's favour).
    fn faster_of(&self, other: &EmbreeRun) -> EmbreeRun {
        EmbreeRun {
            single_ms: self.single_ms.min(other.single_ms),
            packet8_ms: self.packet8_ms.min(other.packet8_ms),
            packet16_ms: self.packet16_ms.min(other.packet16_ms),
            checksum: self.checksum,
        }
    }
}

/// Runs the probe and reads its lines `mode=NAME median_ms=MS ... checksum=SUM`.
fn run_probe(probe: &str, args: &[String]) -> EmbreeRun {
    let output = Command::new(probe)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("CAVETRACE_EMBREE_PROBE={probe} could not run: {e}"));
    let text = String::from_utf8_lossy(&output.stdout);
    let field = |line: &str, key: &str| -> Option<String> {
        line.split_whitespace()
            .find_map(|word| word.strip_prefix(key)?.strip_prefix('='))
            .map(str::to_owned)
    };
    let median_of = |mode: &str| -> f64 {
        text.lines()
            .find(|line| field(line, "mode").as_deref() == Some(mode))
            .and_then(|line| field(line, "median_ms")?.parse().ok())
            .unwrap_or_else(|| panic!("{probe} printed no median for {mode}:\n{text}"))
    };
    EmbreeRun {
        single_ms: median_of("rtcIntersect1"),
        packet8_ms: median_of("rtcIntersect8"),
        packet16_ms: median_of("rtcIntersect16"),
        checksum: text
            .lines()
            .find_map(|line| field(line, "checksum")?.parse().ok())
            .unwrap_or(0),
    }
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let quick = std::env::var_os("CAVETRACE_BENCH_QUICK").is_some();
    let (grids, size, frames): (&[u32], u32, u32) = if quick {
        (&[22, 224], 256, 3)
    } else {
        (&[22, 71, 224, 708, 1414], 1600, 7)
    };
    let chosen: Option<Vec<u32>> = std::env::var("CAVETRACE_BENCH_GRIDS").ok().map(|list| {
        list.split(',')
            .filter_map(|g| g.trim().parse().ok())
            .collect()
    });
    let grids = chosen.as_deref().unwrap_or(grids);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let embree_probe = std::env::var("CAVETRACE_EMBREE_PROBE").ok();
    let parts = std::env::var("CAVETRACE_BENCH_PARTS").ok();
    let runs = |part: &str| {
        parts
            .as_deref()
            .is_none_or(|list| list.split(',').any(|p| p.trim() == part))
    };
    let (run_packets, run_single, run_frame) = (runs("packets"), runs("single"), runs("frame"));
    let run_eights = parts
        .as_deref()
        .is_some_and(|list| list.split(',').any(|p| p.trim() == "eights"));
    let lattice = std::env::var("CAVETRACE_BENCH_LATTICE").ok();
    let lattice = lattice.as_deref().unwrap_or("mono");
    // Eights of the points closest together: 2×4 where a lattice's points lie two pixels apart
    // across, 4×2 otherwise.
    let grouping = match std::env::var("CAVETRACE_BENCH_EIGHTS").ok().as_deref() {
        Some("4x2") => 0,
        Some("2x4") => 1,
        Some("packed") => PACKED,
        Some(other) => panic!("CAVETRACE_BENCH_EIGHTS={other}: 4x2, 2x4 or packed"),
        None => usize::from(matches!(lattice, "columns" | "checker")),
    };
    let single_up_to = std::env::var("CAVETRACE_BENCH_SINGLE_UP_TO")
        .ok()
        .map_or(1, |n| {
            n.parse().expect("CAVETRACE_BENCH_SINGLE_UP_TO: a number")
        });
    let repeat = std::env::var("CAVETRACE_BENCH_REPEAT")
        .ok()
        .map_or(1, |n| n.parse().expect("CAVETRACE_BENCH_REPEAT: a number"));
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let chosen_isas = std::env::var("CAVETRACE_BENCH_ISAS").ok();
    let isas: Vec<Isa> = Isa::all()
        .into_iter()
        .filter(|isa| isa.supported())
        .filter(|isa| {
            chosen_isas
                .as_deref()
                .is_none_or(|list| list.split(',').any(|name| name.trim() == isa.name()))
        })
        .collect();
    println!(
        "kernel: the embree_rays scene, {size}x{size}, {threads} threads, medians of frames \
         1..{frames}"
    );
    for &grid in grids {
        let geometry = height_field(dev, grid);
        let geometry_bytes = cavetrace::device::registry::device(dev as usize)
            .and_then(|d| d.lookup(geometry as usize))
            .and_then(|o| o.derived_as::<cavetrace::scene::geometry::Geometry>())
            .map_or(0, |g| g.memory_bytes());
        println!(
            "  {:>9} triangles: geometry memory (BVH, packed triangles, ids, indices) {:.1} bytes \
             per triangle",
            2 * grid * grid,
            geometry_bytes as f64 / f64::from(2 * grid * grid)
        );
        let scene = geometry_scene(dev, geometry);
        let surface = matte_surface(dev, geometry, [0.7, 0.7, 0.7]);
        let world = world_of(dev, &[surface]);
        let camera = anariNewCamera(dev, c("perspective").as_ptr());
        let renderer = anariNewRenderer(dev, c("fast").as_ptr());
        commit(dev, renderer);
        let frame = square_frame(dev, size, world, camera, renderer);
        set(dev, frame, "channel.depth", ANARI_DATA_TYPE, &ANARI_FLOAT32);
        commit(dev, frame);
        let probe_args = [grid, size, size, frames, threads as u32].map(|n| n.to_string());
        let embree_before = embree_probe.as_deref().map(|p| run_probe(p, &probe_args));
        // Per path: packets, single rays, whole frame (wall and CPU each); paths alternate
        // frame by frame.
        let mut figures = vec![[(); 8].map(|_| Vec::new()); isas.len()];
        let mut checksums = vec![[0; 3]; isas.len()];
        // Walk counts of the first path (every path walks the same nodes): packets, one by one.
        let mut counts = [TraversalCounts::default(); 2];
        for f in 0..=frames {
            place_camera(dev, camera, f);
            let rays = lattice_rays(camera_rays_with_pixels(dev, camera, size), size, lattice)
                .repeat(repeat);
            for (k, isa) in isas.iter().enumerate() {
                set_string(dev, dev, "isa", isa.name());
                commit(dev, dev);
                assert_eq!(isa::selected(), *isa);
                let skipped = (0.0, 0.0, 0);
                let mut walks = [TraversalCounts::default(); 3];
                let (packet_ms, packet_cpu, packet_sum) = match run_packets {
                    true => trace(&scene, &rays, threads, Walk::Packet, &mut walks[0]),
                    false => skipped,
                };
                let (single_ms, single_cpu, single_sum) = match run_single {
                    true => trace(&scene, &rays, threads, Walk::OneByOne, &mut walks[1]),
                    false => skipped,
                };
                let eights = Walk::Eights {
                    grouping,
                    single_up_to,
                };
                let (eights_ms, eights_cpu, eights_sum) = match run_eights {
                    true => trace(&scene, &rays, threads, eights, &mut walks[2]),
                    false => skipped,
                };
                if k == 0 {
                    counts[0] += walks[0];
                    counts[1] += walks[1];
                }
                let (start, cpu_start) = (Instant::now(), cpu_ms());
                if run_frame {
                    anariRenderFrame(dev, frame);
                    anariFrameReady(dev, frame, ANARI_WAIT);
                }
                let frame_ms = start.elapsed().as_secs_f64() * 1e3;
                let frame_cpu = cpu_ms() - cpu_start;
                if f == 1 {
                    checksums[k] = [packet_sum, single_sum, eights_sum];
                    if k == 0 {
                        write_hits(&scene, &rays, grid);
                    }
                }
                if f > 0 {
                    let values = [
                        packet_ms, packet_cpu, single_ms, single_cpu, frame_ms, frame_cpu,
                        eights_ms, eights_cpu,
                    ];
                    for (list, value) in figures[k].iter_mut().zip(values) {
                        list.push(value);
                    }
                }
            }
        }
        if counters::ENABLED {
            print_counts(2 * grid * grid, &counts);
        }
        let embree_after = embree_probe.as_deref().map(|p| run_probe(p, &probe_args));
        let embree = embree_before.zip(embree_after).map(|(before, after)| {
            println!(
                "  {:>9} Embree (runs before / after): rtcIntersect1 {:.1} / {:.1} ms, \
                 rtcIntersect8 {:.1} / {:.1} ms, rtcIntersect16 {:.1} / {:.1} ms; checksum {}",
                "",
                before.single_ms,
                after.single_ms,
                before.packet8_ms,
                after.packet8_ms,
                before.packet16_ms,
                after.packet16_ms,
                before.checksum
            );
            before.faster_of(&after)
        });
        for (k, isa) in isas.iter().enumerate() {
            let [
                packets,
                packets_cpu,
                single,
                single_cpu,
                whole,
                whole_cpu,
                eights,
                eights_cpu,
            ] = figures[k].clone().map(median);
            println!(
                "  {:>9} triangles, {:<8}: packets {packets:6.1} ms ({packets_cpu:5.1} ms CPU), \
                 one by one {single:6.1} ms ({single_cpu:5.1} ms CPU), whole fast frame with \
                 depth {whole:6.1} ms ({whole_cpu:4.0} ms CPU); checksums {} {}",
                2 * grid * grid,
                isa.name(),
                checksums[k][0],
                checksums[k][1]
            );
            if run_eights {
                println!(
                    "  {:>9} eights ({}, single up to {single_up_to}): {eights:6.1} ms \
                     ({eights_cpu:5.1} ms CPU); checksum {}",
                    "",
                    ["4x2", "2x4", "packed"][grouping],
                    checksums[k][2]
                );
            }
            if let Some(embree) = &embree {
                println!(
                    "  {:>9} × Embree ({:<8}): one by one {:.2}× rtcIntersect1, packets {:.2}× \
                     and whole frame {:.2}× its best packet cast",
                    "",
                    isa.name(),
                    single / embree.single_ms,
                    packets / embree.best_packet_ms(),
                    whole / embree.best_packet_ms()
                );
            }
        }
        release_all(dev, &[frame, renderer, camera, world, surface, geometry]);
    }
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}
