//! Device-level benchmark: prints figures, asserts nothing.
//!
//!     cargo bench --bench render            (full size: 1M triangles at 1600×1600)
//!     CAVETRACE_BENCH_QUICK=1 cargo bench --bench render   (small, for a smoke run)
//!     CAVETRACE_BENCH_FRAMES=25 cargo bench --bench render  (frames per case, 7 by default)
//!     cargo bench --bench render -- fast    (only (a) and the same-rays comparison)
//!     cargo bench --bench render -- budget  (frame-time budgets: frame times, pixels traced,
//!                                            renders to convergence, image error)
//!     cargo bench --bench render -- viewers (several viewers on the offAxis camera and the
//!                                            matrix camera against one viewer, same view)
//!     cargo bench --bench render -- stereo  (sideBySide, topBottom, interleaved and anaglyph
//!                                            frames against mono, both renderers, both scenes)
//!     cargo bench --bench render -- lightfield (lightField frames against a mono frame;
//!                                            CAVETRACE_BENCH_RENDERER=default for that renderer;
//!                                            CAVETRACE_BENCH_PLACEMENTS=quarters|instances|spheres
//!                                            for a world of several placements)
//!     cargo bench --bench render -- depth (fast frames with colour + depth and with every
//!                                            channel against colour alone, 968 and 1M triangles)
//!     cargo bench --bench render -- depth default (the same with the default renderer,
//!                                            one directional light and shadows)
//!
//! Scenes: a height field of ~1M triangles seen by a tracked head (the camera moves every
//! frame), rendered (a) by the "fast" renderer and (b) by the "default" renderer with one
//! directional light and shadows; and a cloud of 100k spheres. Printed: Mrays/s (primary rays),
//! median frame ms, BVH build ms, first-frame latency (commit to image), bytes per triangle.
//!
//! The device's overhead is shown on the same rays in the same run: for one head position the
//! camera's own primary rays (as the frame generates them: pixel centres, 8×8 packets) are
//! traced (1) by raw obvhs (`ray_traverse` over an obvhs CWBVH of the same triangles, ray by
//! ray), (2) by cavetrace's packet traversal alone, and (3) rendered as a whole frame by the
//! fast renderer at that head position (rays, traversal, shading, encoding to sRGB bytes).

#[path = "../tests/common/mod.rs"]
mod common;
use common::*;
use glam::{Vec3, Vec3A};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use cavetrace::accel::{PacketScratch, Ray};

/// Runs `work` `runs` times; medians of (wall ms, CPU ms) and the last result.
fn timed<T>(runs: u32, mut work: impl FnMut() -> T) -> (f64, f64, T) {
    let mut wall = Vec::new();
    let mut cpu = Vec::new();
    let mut last = None;
    for _ in 0..runs {
        let (start, cpu_start) = (Instant::now(), cpu_seconds());
        last = Some(work());
        wall.push(start.elapsed().as_secs_f64() * 1e3);
        cpu.push((cpu_seconds() - cpu_start) * 1e3);
    }
    (median(wall), median(cpu), last.expect("at least one run"))
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

struct Setup {
    dev: ANARIDevice,
    camera: ANARICamera,
    renderer: ANARIRenderer,
    frame: ANARIFrame,
    world: ANARIWorld,
}

/// The height field's triangles as vertex triples (for the raw obvhs comparison).
type Triangles = Vec<[[f32; 3]; 3]>;

fn height_field(dev: ANARIDevice, cells: u32) -> (ANARIGeometry, Triangles) {
    grid_geometry(dev, cells, |i, j| {
        let x = i as f32 / cells as f32 * 2.0 - 1.0;
        let z = j as f32 / cells as f32 * 2.0 - 1.0;
        let y = 0.05 * (x * 9.0).sin() * (z * 7.0).cos();
        [x, y, z]
    })
}

fn sphere_cloud(dev: ANARIDevice, count: usize) -> ANARIGeometry {
    let mut state = 12345u32;
    let mut random = move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state as f32 / u32::MAX as f32
    };
    let centers: Vec<[f32; 3]> = (0..count)
        .map(|_| [random() * 2.0 - 1.0, random() * 0.5, random() * 2.0 - 1.0])
        .collect();
    let g = anariNewGeometry(dev, c("sphere").as_ptr());
    let p = array1d(dev, ANARI_FLOAT32_VEC3, &centers);
    set_object(dev, g, "vertex.position", ANARI_ARRAY1D, p);
    set(dev, g, "radius", ANARI_FLOAT32, &0.01f32);
    anariRelease(dev, p);
    g
}

fn setup(dev: ANARIDevice, geometry: ANARIGeometry, renderer_type: &str, size: u32) -> Setup {
    let surface = matte_surface(dev, geometry, [0.7, 0.7, 0.7]);
    let world = world_of(dev, &[surface]);
    anariRelease(dev, surface);
    setup_in(dev, world, renderer_type, size)
}

/// [`setup`] for a world already made (the setup keeps its reference).
fn setup_in(dev: ANARIDevice, world: ANARIWorld, renderer_type: &str, size: u32) -> Setup {
    if renderer_type == "default" {
        let light = anariNewLight(dev, c("directional").as_ptr());
        set(
            dev,
            light,
            "direction",
            ANARI_FLOAT32_VEC3,
            &[-0.3f32, -1.0, -0.4],
        );
        set(dev, light, "irradiance", ANARI_FLOAT32, &3.0f32);
        commit(dev, light);
        let lights = object_array(dev, ANARI_LIGHT, &[light]);
        set_object(dev, world, "light", ANARI_ARRAY1D, lights);
        commit(dev, world);
        anariRelease(dev, light);
        anariRelease(dev, lights);
    }
    let camera = anariNewCamera(dev, c("perspective").as_ptr());
    let renderer = anariNewRenderer(dev, c(renderer_type).as_ptr());
    commit(dev, renderer);
    let frame = square_frame(dev, size, world, camera, renderer);
    Setup {
        dev,
        camera,
        renderer,
        frame,
        world,
    }
}

/// Moves the tracked head a little and commits the camera, as a VR application does per frame.
fn track_head(s: &Setup, step: u32) {
    let t = step as f32 * 0.05;
    let eye = [0.1 * t.sin(), 1.2 + 0.02 * t.cos(), 1.6];
    let target = [0.0f32, 0.0, 0.0];
    let dir = [target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]];
    set(s.dev, s.camera, "position", ANARI_FLOAT32_VEC3, &eye);
    set(s.dev, s.camera, "direction", ANARI_FLOAT32_VEC3, &dir);
    set(s.dev, s.camera, "fovy", ANARI_FLOAT32, &0.9f32);
    commit(s.dev, s.camera);
}

fn render_once(s: &Setup) -> f64 {
    let start = Instant::now();
    anariRenderFrame(s.dev, s.frame);
    anariFrameReady(s.dev, s.frame, ANARI_WAIT);
    start.elapsed().as_secs_f64() * 1e3
}

fn run(label: &str, s: &Setup, size: u32, frames: u32) {
    let mut step = 0;
    let (wall, cpu, _) = timed(frames, || {
        step += 1;
        track_head(s, step);
        render_once(s)
    });
    let rays = size as f64 * size as f64;
    println!(
        "{label}: median frame {wall:.1} ms, {:.2} Mrays/s ({cpu:.0} ms CPU, {:.2} Mrays/CPU-s; \
         primary rays, {size}x{size}, {frames} frames)",
        rays / (wall * 1e3),
        rays / (cpu * 1e3)
    );
}

/// Traces `rays` in 64-ray chunks on `threads` threads; returns (wall ms, hits).
fn trace_rays(
    rays: &[Ray],
    threads: usize,
    trace_chunk: impl Fn(&[Ray]) -> usize + Sync,
) -> (f64, usize) {
    let next = AtomicUsize::new(0);
    let chunks = rays.len().div_ceil(64);
    let start = Instant::now();
    let hits: usize = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| {
                    let mut hits = 0;
                    loop {
                        // 16 chunks (1024 rays, one 32×32 tile) at a time, like the frame.
                        let first = next.fetch_add(16, Ordering::Relaxed);
                        if first >= chunks {
                            break hits;
                        }
                        for chunk in first..(first + 16).min(chunks) {
                            let end = ((chunk + 1) * 64).min(rays.len());
                            hits += trace_chunk(&rays[chunk * 64..end]);
                        }
                    }
                })
            })
            .collect();
        workers.into_iter().map(|w| w.join().unwrap()).sum()
    });
    (start.elapsed().as_secs_f64() * 1e3, hits)
}

/// Raw obvhs, cavetrace's traversal alone and the whole device frame on the same rays.
fn same_rays(s: &Setup, geometry: ANARIGeometry, triangles: &Triangles, size: u32, frames: u32) {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    track_head(s, 1);
    let rays = camera_rays(s.dev, s.camera, size);
    let mrays = |ms: f64| rays.len() as f64 / (ms * 1e3);

    let obvhs_triangles: Vec<obvhs::triangle::Triangle> = triangles
        .iter()
        .map(|t| obvhs::triangle::Triangle {
            v0: Vec3A::from_array(t[0]),
            v1: Vec3A::from_array(t[1]),
            v2: Vec3A::from_array(t[2]),
        })
        .collect();
    let start = Instant::now();
    let raw_bvh = obvhs::cwbvh::builder::build_cwbvh_from_tris(
        &obvhs_triangles,
        obvhs::BvhBuildParams::fast_build(),
        &mut Duration::default(),
    );
    let raw_build_ms = start.elapsed().as_secs_f64() * 1e3;
    let ordered: Vec<obvhs::triangle::Triangle> = raw_bvh
        .primitive_indices
        .iter()
        .map(|&i| obvhs_triangles[i as usize])
        .collect();
    let raw = timed(frames, || {
        trace_rays(&rays, threads, |chunk| {
            chunk
                .iter()
                .filter(|r| {
                    let ray = obvhs::ray::Ray::new(
                        Vec3A::from(r.origin),
                        Vec3A::from(r.direction),
                        r.t_min,
                        r.t_max,
                    );
                    let mut hit = obvhs::ray::RayHit::none();
                    raw_bvh.ray_traverse(ray, &mut hit, |ray, id| ordered[id].intersect(ray))
                })
                .count()
        })
    });

    let scene = geometry_scene(s.dev, geometry);
    thread_local! {
        // Packet working memory kept from one chunk to the next, as the frame keeps it.
        static SCRATCH: std::cell::RefCell<PacketScratch> =
            std::cell::RefCell::new(PacketScratch::new());
    }
    let packets = timed(frames, || {
        trace_rays(&rays, threads, |chunk| {
            let mut hits = [None; 64];
            SCRATCH.with_borrow_mut(|scratch| {
                scene.intersect_packet_with(scratch, chunk, &mut hits);
            });
            hits.iter().filter(|h| h.is_some()).count()
        })
    });
    let frame = timed(frames, || render_once(s));
    println!(
        "same rays ({} primary rays of one head position, {threads} threads, medians of {frames}):",
        rays.len()
    );
    let row = |label: &str, (wall, cpu): (f64, f64)| {
        println!(
            "  {label}: {wall:.1} ms, {:.2} Mrays/s ({cpu:.0} ms CPU, {:.2} Mrays/CPU-s)",
            mrays(wall),
            mrays(cpu)
        );
    };
    row(
        &format!(
            "raw obvhs ray_traverse, ray by ray ({} hits; CWBVH fast_build {raw_build_ms:.0} ms)",
            raw.2.1
        ),
        (raw.0, raw.1),
    );
    row(
        &format!("cavetrace packet traversal alone ({} hits)", packets.2.1),
        (packets.0, packets.1),
    );
    row("device frame, fast renderer", (frame.0, frame.1));
    println!(
        "  device overhead in CPU time: {:+.0}% over raw obvhs traversal, {:+.0}% over its own traversal",
        (frame.1 / raw.1 - 1.0) * 100.0,
        (frame.1 / packets.1 - 1.0) * 100.0
    );
}

fn release(s: Setup) {
    for o in [s.camera, s.renderer, s.frame, s.world] {
        anariRelease(s.dev, o);
    }
}

/// Frame-time budgets (`cargo bench --bench render -- budget`): with the head moving every
/// frame, per budget the median and 95th-percentile frame time and the fraction of pixels
/// traced; with the head still, the renders until the image is complete; and the image error
/// of the first (coarsest) budgeted frame against the full frame.
fn budget_section(dev: ANARIDevice, geometry: ANARIGeometry, size: u32, frames: u32) {
    let progress = |s: &Setup| {
        let mut value = 0.0f32;
        anariGetProperty(
            s.dev,
            s.frame,
            c("progress").as_ptr(),
            ANARI_FLOAT32,
            (&mut value as *mut f32).cast(),
            4,
            ANARI_WAIT,
        );
        value
    };
    let colors = |s: &Setup| read_channel::<[u8; 4]>(s.dev, s.frame, "channel.color").0;
    for renderer in ["fast", "default"] {
        let s = setup(dev, geometry, renderer, size);
        track_head(&s, 0);
        let full_ms = render_once(&s);
        let full_ms = full_ms.min(render_once(&s));
        let full = colors(&s);
        // The cheapest complete image: the first level alone (one pixel per 8×8 block).
        set(s.dev, s.frame, "budget", ANARI_FLOAT32, &10.0f32);
        set(s.dev, s.frame, "budgetPixels", ANARI_UINT32, &1u32);
        commit(s.dev, s.frame);
        let (coarsest_ms, _, _) = timed(5, || {
            commit(s.dev, s.frame);
            render_once(&s)
        });
        set(s.dev, s.frame, "budgetPixels", ANARI_UINT32, &0u32);
        println!(
            "budget, {renderer} renderer: full frame {full_ms:.1} ms; first level alone (1/256 \
             of the pixels traced, the rest filled) {coarsest_ms:.1} ms"
        );
        // `CAVETRACE_BENCH_BUDGETS=16,33` measures only those budgets (ms).
        let budgets: Vec<f32> = std::env::var("CAVETRACE_BENCH_BUDGETS")
            .ok()
            .map(|list| {
                list.split(',')
                    .filter_map(|b| b.trim().parse().ok())
                    .collect()
            })
            .unwrap_or_else(|| vec![16.0, 33.0, 50.0]);
        for budget_ms in budgets {
            set(s.dev, s.frame, "budget", ANARI_FLOAT32, &(budget_ms / 1e3));
            commit(s.dev, s.frame);
            let mut times = Vec::new();
            let mut traced = Vec::new();
            // A few frames to measure the speed, then the moving head.
            for step in 1..=frames + 5 {
                track_head(&s, step);
                let ms = render_once(&s);
                if step > 5 {
                    times.push(ms);
                    traced.push(f64::from(progress(&s)));
                }
            }
            times.sort_by(|a, b| a.partial_cmp(b).unwrap());
            let p95 = times[((times.len() as f64 * 0.95).ceil() as usize).min(times.len()) - 1];
            let median_ms = times[times.len() / 2];
            let mean_traced = traced.iter().sum::<f64>() / traced.len() as f64;
            // The same head pose as the full frame: the error of a first, partial frame.
            track_head(&s, 0);
            render_once(&s);
            let first_traced = progress(&s);
            let partial = colors(&s);
            let error = full
                .iter()
                .zip(&partial)
                .map(|(a, b)| {
                    (0..3)
                        .map(|i| (a[i] as f64 - b[i] as f64).abs())
                        .sum::<f64>()
                })
                .sum::<f64>()
                / (3.0 * full.len() as f64);
            // Head still: renders until the image is complete.
            let (mut renders, mut still_ms) = (1, 0.0);
            while progress(&s) < 1.0 && renders < 1000 {
                still_ms += render_once(&s);
                renders += 1;
            }
            let converged_error = full.iter().zip(&colors(&s)).filter(|(a, b)| a != b).count();
            println!(
                "  budget {budget_ms:.0} ms, moving head: p50 {median_ms:.1} ms ({:.2}× budget), \
                 p95 {p95:.1} ms ({:.2}× budget), {:.1} % of pixels traced (load average {}); \
                 first frame of a pose: {:.1} % traced, mean |colour error| {error:.2}/255; head \
                 still: complete after {renders} renders ({still_ms:.0} ms more), \
                 {converged_error} pixels differ from the full frame",
                median_ms / f64::from(budget_ms),
                p95 / f64::from(budget_ms),
                100.0 * mean_traced,
                load_average(),
                100.0 * first_traced,
            );
        }
        release(s);
    }
}

/// The machine's one-minute load average (Linux), to say how busy it was during a figure.
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|text| text.split_whitespace().next().map(str::to_owned))
        .unwrap_or_else(|| "unknown".to_owned())
}

/// A screen 1 m in front of the benchmark's head, filling its 0.9 rad field of view: the
/// offAxis camera then sees what the perspective camera of (a) sees.
struct BenchScreen {
    corners: [[f32; 3]; 3],
    x: Vec3,
    y: Vec3,
    centre: Vec3,
}

fn bench_screen() -> BenchScreen {
    let eye = Vec3::new(0.0, 1.2, 1.6);
    let forward = (-eye).normalize();
    let x = forward.cross(Vec3::Y).normalize();
    let y = x.cross(forward);
    let centre = eye + forward;
    let half = 0.45f32.tan();
    let corner = |a: f32, b: f32| (centre + x * (a * half) + y * (b * half)).to_array();
    BenchScreen {
        corners: [corner(-1.0, -1.0), corner(1.0, -1.0), corner(1.0, 1.0)],
        x,
        y,
        centre,
    }
}

/// The tracked head of frame `step` (as `track_head` moves it).
fn head_at(step: u32) -> Vec3 {
    let t = step as f32 * 0.05;
    Vec3::new(0.1 * t.sin(), 1.2 + 0.02 * t.cos(), 1.6)
}

/// Renders `setups` in turn, `frames` rounds (`prepare(k, round)` runs before each render, outside
/// the timing): per setup the median (wall ms, CPU ms), and the median over rounds of its CPU time
/// over the first setup's in the same round. Cases take turns frame by frame, so that drift on a
/// shared machine hits them alike; the paired ratio also cancels drift slower than a round.
fn alternating_medians(
    setups: &[Setup],
    frames: u32,
    mut prepare: impl FnMut(usize, u32),
) -> Vec<(f64, f64, f64)> {
    let mut wall = vec![Vec::new(); setups.len()];
    let mut cpu: Vec<Vec<f64>> = vec![Vec::new(); setups.len()];
    for round in 0..frames {
        for (k, s) in setups.iter().enumerate() {
            prepare(k, round);
            let cpu_start = cpu_seconds();
            wall[k].push(render_once(s));
            cpu[k].push((cpu_seconds() - cpu_start) * 1e3);
        }
    }
    let paired: Vec<f64> = cpu
        .iter()
        .map(|times| {
            median(
                times
                    .iter()
                    .zip(&cpu[0])
                    .map(|(t, first)| t / first)
                    .collect(),
            )
        })
        .collect();
    wall.into_iter()
        .zip(cpu)
        .zip(paired)
        .map(|((w, c), p)| (median(w), median(c), p))
        .collect()
}

/// Viewer cameras of the `viewers` section: `setup` commits the camera for frame `step`.
enum ViewerCase {
    OneViewer,
    Matrix,
    Viewers {
        count: usize,
        mode: &'static str,
        cutoff: f32,
    },
}

fn viewers_section(dev: ANARIDevice, geometry: ANARIGeometry, size: u32, frames: u32) {
    let screen = bench_screen();
    let commit_camera = |s: &Setup, case: &ViewerCase, step: u32| {
        let head = head_at(step);
        let [ll, lr, ur] = screen.corners;
        match case {
            ViewerCase::Matrix => {
                let (mut view, mut proj) = ([0f32; 16], [0f32; 16]);
                let status = cavetrace::capi::offaxis::cavetraceOffAxisMatrices(
                    ll.as_ptr(),
                    lr.as_ptr(),
                    ur.as_ptr(),
                    head.to_array().as_ptr(),
                    0.01,
                    100.0,
                    view.as_mut_ptr(),
                    proj.as_mut_ptr(),
                );
                assert_eq!(status, ANARI_STATUS_NO_ERROR);
                set(s.dev, s.camera, "view", ANARI_FLOAT32_MAT4, &view);
                set(s.dev, s.camera, "proj", ANARI_FLOAT32_MAT4, &proj);
            }
            ViewerCase::OneViewer | ViewerCase::Viewers { .. } => {
                set(s.dev, s.camera, "screen.lowerLeft", ANARI_FLOAT32_VEC3, &ll);
                set(
                    s.dev,
                    s.camera,
                    "screen.lowerRight",
                    ANARI_FLOAT32_VEC3,
                    &lr,
                );
                set(
                    s.dev,
                    s.camera,
                    "screen.upperRight",
                    ANARI_FLOAT32_VEC3,
                    &ur,
                );
                set(
                    s.dev,
                    s.camera,
                    "position",
                    ANARI_FLOAT32_VEC3,
                    &head.to_array(),
                );
            }
        }
        if let ViewerCase::Viewers {
            count,
            mode,
            cutoff,
        } = case
        {
            // Heads 0.5 m apart around the tracked one, each looking at its own part of the
            // screen.
            let offsets = [(-1.0, -0.5), (1.0, -0.5), (-1.0, 0.5), (1.0, 0.5)];
            let (mut heads, mut gazes) = (Vec::new(), Vec::new());
            for (a, b) in &offsets[..*count] {
                let h = head + screen.x * (0.25 * a) + screen.y * (0.15 * b);
                let target = screen.centre + screen.x * (0.25 * a) + screen.y * (0.2 * b);
                heads.push(h.to_array());
                gazes.push((target - h).to_array());
            }
            let positions = array1d(s.dev, ANARI_FLOAT32_VEC3, &heads);
            let directions = array1d(s.dev, ANARI_FLOAT32_VEC3, &gazes);
            set_object(s.dev, s.camera, "viewer.position", ANARI_ARRAY1D, positions);
            set_object(
                s.dev,
                s.camera,
                "viewer.direction",
                ANARI_ARRAY1D,
                directions,
            );
            set_string(s.dev, s.camera, "viewerMode", mode);
            set(s.dev, s.camera, "viewerCutoffAngle", ANARI_FLOAT32, cutoff);
            anariRelease(s.dev, positions);
            anariRelease(s.dev, directions);
        }
        commit(s.dev, s.camera);
    };
    // The default cutoff (π/4): every viewer's cone covers the 0.97 m screen 1 m away, so every
    // pixel blends all of them. Narrow cones (0.3 rad, 0.3 m on the screen) overlap only in the
    // middle, where the camera position then moves fast from pixel to pixel: the hard case.
    let viewers = |count, mode, cutoff| ViewerCase::Viewers {
        count,
        mode,
        cutoff,
    };
    let (wide, narrow) = (std::f32::consts::FRAC_PI_4, 0.3);
    let cases = [
        ("one viewer (offAxis)", ViewerCase::OneViewer),
        ("matrix camera, same view", ViewerCase::Matrix),
        ("2 viewers, perPixel", viewers(2, "perPixel", wide)),
        ("4 viewers, perPixel", viewers(4, "perPixel", wide)),
        ("4 viewers, tiles 8x8", viewers(4, "tiles", wide)),
        ("4 viewers, zones", viewers(4, "zones", wide)),
        ("2 narrow cones, perPixel", viewers(2, "perPixel", narrow)),
        ("4 narrow cones, perPixel", viewers(4, "perPixel", narrow)),
        ("4 narrow cones, zones", viewers(4, "zones", narrow)),
        ("2 viewers, tiles 8x8", viewers(2, "tiles", wide)),
    ];
    // `CAVETRACE_BENCH_VIEWER_CASE=<index>` runs one case alone (for profiling).
    let only: Option<usize> = std::env::var("CAVETRACE_BENCH_VIEWER_CASE")
        .ok()
        .and_then(|v| v.parse().ok());
    let cases: Vec<_> = cases
        .into_iter()
        .enumerate()
        .filter(|(k, _)| only.is_none_or(|only| only == *k))
        .map(|(_, case)| case)
        .collect();
    // `CAVETRACE_BENCH_RENDERER=fast` (or `default`) runs one renderer alone.
    let renderer_only = std::env::var("CAVETRACE_BENCH_RENDERER").ok();
    for renderer in ["fast", "default"] {
        if renderer_only
            .as_deref()
            .is_some_and(|only| only != renderer)
        {
            continue;
        }
        let base = setup(dev, geometry, renderer, size);
        let mut setups: Vec<Setup> = cases
            .iter()
            .map(|(_, case)| {
                let subtype = match case {
                    ViewerCase::Matrix => "matrix",
                    _ => "offAxis",
                };
                let camera = anariNewCamera(dev, c(subtype).as_ptr());
                let frame = square_frame(dev, size, base.world, camera, base.renderer);
                anariRetain(dev, base.world);
                anariRetain(dev, base.renderer);
                Setup {
                    dev,
                    camera,
                    renderer: base.renderer,
                    frame,
                    world: base.world,
                }
            })
            .collect();
        let medians = alternating_medians(&setups, frames, |k, step| {
            commit_camera(&setups[k], &cases[k].1, step)
        });
        let (base_wall, base_cpu, _) = medians[0];
        println!("several viewers, {renderer} renderer, {size}x{size}, {frames} frames each:");
        for (k, (label, _)) in cases.iter().enumerate() {
            let (w, c, paired) = medians[k];
            println!(
                "  {label:<26} median frame {w:6.1} ms ({:.2}x), {c:6.0} ms CPU ({:.2}x; \
                 paired {paired:.2}x)",
                w / base_wall,
                c / base_cpu
            );
        }
        for s in setups.drain(..) {
            release(s);
        }
        release(base);
    }
}

/// Stereo against mono (`cargo bench --bench render -- stereo`): per renderer and scene, the
/// median frame time of a mono frame, of sideBySide and topBottom frames of the same per-eye
/// size, and of rowInterleaved, checkerboard and anaglyph frames of the mono frame's size (the
/// cases alternate frame by frame, so machine drift hits them alike), and the ratios.
fn stereo_section(dev: ANARIDevice, scenes: &[(&str, ANARIGeometry)], size: u32, frames: u32) {
    let cases = [
        ("mono", "none", [size, size]),
        ("sideBySide", "sideBySide", [2 * size, size]),
        ("topBottom", "topBottom", [size, 2 * size]),
        ("rowInterleaved", "rowInterleaved", [size, size]),
        ("columnInterleaved", "columnInterleaved", [size, size]),
        ("checkerboard", "checkerboard", [size, size]),
        ("anaglyph", "anaglyph", [size, size]),
    ];
    // `CAVETRACE_BENCH_STEREO_CASES=rowInterleaved,checkerboard` runs those beside mono (for
    // profiling and quicker runs); `CAVETRACE_BENCH_RENDERER` and `CAVETRACE_BENCH_SCENE`
    // (0 height field, 1 spheres, 2 the 968-triangle height field) pick one renderer and one
    // scene.
    let chosen = std::env::var("CAVETRACE_BENCH_STEREO_CASES").ok();
    let cases: Vec<_> = cases
        .into_iter()
        .filter(|(label, _, _)| {
            *label == "mono"
                || chosen
                    .as_deref()
                    .is_none_or(|list| list.split(',').any(|c| c == *label))
        })
        .collect();
    let renderer_only = std::env::var("CAVETRACE_BENCH_RENDERER").ok();
    let scene_only: Option<usize> = std::env::var("CAVETRACE_BENCH_SCENE")
        .ok()
        .and_then(|v| v.parse().ok());
    for (index, (scene, geometry)) in scenes.iter().enumerate() {
        if scene_only.is_some_and(|only| only != index) {
            continue;
        }
        for renderer in ["fast", "default"] {
            if renderer_only
                .as_deref()
                .is_some_and(|only| only != renderer)
            {
                continue;
            }
            let setups: Vec<Setup> = cases
                .iter()
                .map(|(_, mode, frame_size)| {
                    let s = setup(dev, *geometry, renderer, size);
                    set_string(s.dev, s.camera, "stereoMode", mode);
                    set(s.dev, s.frame, "size", ANARI_UINT32_VEC2, frame_size);
                    commit(s.dev, s.frame);
                    track_head(&s, 0);
                    render_once(&s);
                    s
                })
                .collect();
            let medians =
                alternating_medians(&setups, frames, |k, step| track_head(&setups[k], step));
            println!(
                "stereo, {scene}, {renderer} renderer, {size}x{size} per eye, {frames} frames each:"
            );
            for (k, (label, _, _)) in cases.iter().enumerate() {
                let (wall, cpu, paired) = medians[k];
                println!(
                    "  {label}: {wall:.1} ms ({cpu:.0} ms CPU), {:.2}x mono ({:.2}x in CPU \
                     time; paired {paired:.2}x)",
                    wall / medians[0].0,
                    cpu / medians[0].1
                );
            }
            setups.into_iter().for_each(release);
        }
    }
}

/// Light-field frames against a mono frame of the same size
/// (`cargo bench --bench render -- lightfield`): the height field through the benchmark's
/// screen, seen by one offAxis eye 1 m in front, and by the lightField camera (sample
/// calibration, views 1 m in front) with 45 snapped views and with continuous ones, and its
/// quilt of 45 views with as many rays. Cases alternate frame by frame. The `fast` renderer, or
/// the one `CAVETRACE_BENCH_RENDERER` names; the world `CAVETRACE_BENCH_PLACEMENTS` names
/// ([`placements_world`]; `cells`: the height field's cells per side).
fn light_field_section(
    dev: ANARIDevice,
    geometry: ANARIGeometry,
    cells: u32,
    size: u32,
    frames: u32,
) {
    let renderer = std::env::var("CAVETRACE_BENCH_RENDERER").unwrap_or_else(|_| "fast".into());
    let placements = std::env::var("CAVETRACE_BENCH_PLACEMENTS")
        .ok()
        .filter(|name| !name.is_empty());
    let world = placements_world(dev, geometry, cells, placements.as_deref());
    let screen = bench_screen();
    let eye = head_at(0).to_array();
    // The quilt has as many rays as a light-field frame: 9 × 5 views on a frame three times as
    // wide.
    let cases: [(&str, &str, Option<u32>); 4] = [
        ("offAxis, one eye", "offAxis", None),
        ("lightField, 45 views", "lightField", Some(45)),
        ("lightField, continuous views", "lightField", Some(0)),
        ("quilt of 9x5 views, 3x the pixels", "quilt", Some(45)),
    ];
    let setups: Vec<Setup> = cases
        .iter()
        .map(|(_, subtype, views)| {
            anariRetain(dev, world);
            let s = setup_in(dev, world, &renderer, size);
            let quilt = *subtype == "quilt";
            let subtype = if quilt { "lightField" } else { subtype };
            let camera = anariNewCamera(dev, c(subtype).as_ptr());
            if quilt {
                set(dev, camera, "quilt", ANARI_UINT32_VEC2, &[9u32, 5]);
                set(dev, s.frame, "size", ANARI_UINT32_VEC2, &[3 * size, size]);
            }
            let [ll, lr, ur] = screen.corners;
            set(dev, camera, "screen.lowerLeft", ANARI_FLOAT32_VEC3, &ll);
            set(dev, camera, "screen.lowerRight", ANARI_FLOAT32_VEC3, &lr);
            set(dev, camera, "screen.upperRight", ANARI_FLOAT32_VEC3, &ur);
            match views {
                None => set(dev, camera, "position", ANARI_FLOAT32_VEC3, &eye),
                Some(views) => {
                    set(dev, camera, "views", ANARI_UINT32, views);
                    set(dev, camera, "viewingDistance", ANARI_FLOAT32, &1.0f32);
                }
            }
            commit(dev, camera);
            set_object(dev, s.frame, "camera", ANARI_CAMERA, camera);
            commit(dev, s.frame);
            anariRelease(dev, s.camera);
            let s = Setup { camera, ..s };
            render_once(&s);
            s
        })
        .collect();
    anariRelease(dev, world);
    let medians = alternating_medians(&setups, frames, |_, _| {});
    let scene = placements.as_deref().unwrap_or("one surface");
    println!(
        "light field, height field ({scene}), {renderer} renderer, {size}x{size}, {frames} frames each:"
    );
    for (k, (label, _, _)) in cases.iter().enumerate() {
        let (wall, cpu, paired) = medians[k];
        println!(
            "  {label}: {wall:.1} ms ({cpu:.0} ms CPU), {:.2}x the mono frame ({:.2}x in CPU \
             time; paired {paired:.2}x)",
            wall / medians[0].0,
            cpu / medians[0].1
        );
    }
    setups.into_iter().for_each(release);
}

/// The light-field section's world: the height field of `cells` cells per side as one surface
/// (`None`), as four surfaces of a quarter each (`quarters`), as one quarter's mesh placed four
/// times by translated instances (`instances`), or beside a cloud of 10k spheres (`spheres`: a
/// triangle and a sphere placement).
fn placements_world(
    dev: ANARIDevice,
    geometry: ANARIGeometry,
    cells: u32,
    placements: Option<&str>,
) -> ANARIWorld {
    let half = cells / 2;
    // Quarter (qi, qj) of the height field, in its place.
    let quarter = |qi: u32, qj: u32| {
        let quarter = grid_geometry(dev, half, |i, j| {
            let x = (qi * half + i) as f32 / cells as f32 * 2.0 - 1.0;
            let z = (qj * half + j) as f32 / cells as f32 * 2.0 - 1.0;
            let y = 0.05 * (x * 9.0).sin() * (z * 7.0).cos();
            [x, y, z]
        })
        .0;
        commit(dev, quarter);
        quarter
    };
    let surfaces_world = |geometries: &[ANARIGeometry]| {
        let surfaces: Vec<ANARISurface> = geometries
            .iter()
            .map(|&g| matte_surface(dev, g, [0.7, 0.7, 0.7]))
            .collect();
        let world = world_of(dev, &surfaces);
        surfaces.into_iter().for_each(|s| anariRelease(dev, s));
        world
    };
    match placements {
        None => surfaces_world(&[geometry]),
        Some("quarters") => {
            let quarters = [quarter(0, 0), quarter(1, 0), quarter(0, 1), quarter(1, 1)];
            let world = surfaces_world(&quarters);
            quarters.into_iter().for_each(|g| anariRelease(dev, g));
            world
        }
        Some("instances") => {
            let mesh = quarter(0, 0);
            let surface = matte_surface(dev, mesh, [0.7, 0.7, 0.7]);
            let group = anariNewGroup(dev);
            let group_surfaces = object_array(dev, ANARI_SURFACE, &[surface]);
            set_object(dev, group, "surface", ANARI_ARRAY1D, group_surfaces);
            commit(dev, group);
            let step = 2.0 * half as f32 / cells as f32;
            let instances: Vec<ANARIInstance> =
                [(0.0, 0.0), (step, 0.0), (0.0, step), (step, step)]
                    .iter()
                    .map(|&(dx, dz)| {
                        let instance = anariNewInstance(dev, c("transform").as_ptr());
                        set_object(dev, instance, "group", ANARI_GROUP, group);
                        #[rustfmt::skip]
                    let transform: [f32; 16] = [
                        1.0, 0.0, 0.0, 0.0,
                        0.0, 1.0, 0.0, 0.0,
                        0.0, 0.0, 1.0, 0.0,
                        dx, 0.0, dz, 1.0,
                    ];
                        set(dev, instance, "transform", ANARI_FLOAT32_MAT4, &transform);
                        commit(dev, instance);
                        instance
                    })
                    .collect();
            let world = anariNewWorld(dev);
            let array = object_array(dev, ANARI_INSTANCE, &instances);
            set_object(dev, world, "instance", ANARI_ARRAY1D, array);
            commit(dev, world);
            for object in [array, group_surfaces, group, surface, mesh]
                .into_iter()
                .chain(instances)
            {
                anariRelease(dev, object);
            }
            world
        }
        Some("spheres") => {
            let cloud = sphere_cloud(dev, 10_000);
            commit(dev, cloud);
            let world = surfaces_world(&[geometry, cloud]);
            anariRelease(dev, cloud);
            world
        }
        Some(other) => panic!("CAVETRACE_BENCH_PLACEMENTS={other}: quarters, instances or spheres"),
    }
}

/// Channels beside colour (`cargo bench --bench render -- depth`): the `fast` renderer's frame
/// with colour + depth, and with every channel, against the same frame with colour alone, at
/// 968 triangles and at the benchmark's height field; frames alternate, medians printed.
fn depth_section(
    dev: ANARIDevice,
    geometry: ANARIGeometry,
    renderer: &str,
    size: u32,
    frames: u32,
) {
    let small = height_field(dev, 22).0;
    commit(dev, small);
    for (label, scene) in [("968 triangles", small), ("height field", geometry)] {
        let extra: [&[(&str, ANARIDataType)]; 3] = [
            &[],
            &[("channel.depth", ANARI_FLOAT32)],
            &[
                ("channel.depth", ANARI_FLOAT32),
                ("channel.windowDepth", ANARI_FLOAT32),
                ("channel.primitiveId", ANARI_UINT32),
                ("channel.objectId", ANARI_UINT32),
                ("channel.instanceId", ANARI_UINT32),
                ("channel.normal", ANARI_FLOAT32_VEC3),
                ("channel.albedo", ANARI_FLOAT32_VEC3),
            ],
        ];
        let setups: Vec<Setup> = extra
            .iter()
            .map(|channels| {
                let s = setup(dev, scene, renderer, size);
                for (name, data_type) in channels.iter() {
                    set(dev, s.frame, name, ANARI_DATA_TYPE, data_type);
                }
                commit(dev, s.frame);
                track_head(&s, 0);
                render_once(&s);
                s
            })
            .collect();
        let medians = alternating_medians(&setups, frames, |k, round| {
            track_head(&setups[k], round + 1)
        });
        println!("{label}, {renderer} renderer, {size}x{size}, {frames} frames each (medians):");
        for (k, name) in ["colour", "colour + depth", "every channel"]
            .iter()
            .enumerate()
        {
            let (wall, cpu, paired) = medians[k];
            println!(
                "  {name}: {wall:.1} ms ({cpu:.0} ms CPU), {:.3}x colour alone ({:.3}x in CPU \
                 time; paired {paired:.3}x)",
                wall / medians[0].0,
                cpu / medians[0].1
            );
        }
        setups.into_iter().for_each(release);
    }
    anariRelease(dev, small);
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    let quick = std::env::var_os("CAVETRACE_BENCH_QUICK").is_some();
    // `cargo bench --bench render -- fast` stops after (a) and the same-rays comparison (for
    // profiling the fast path alone).
    let fast_only = std::env::args().skip(1).any(|a| a == "fast");
    let (cells, size, spheres, frames) = if quick {
        (100, 256, 5_000, 3)
    } else {
        (708, 1600, 100_000, 7)
    };
    // `CAVETRACE_BENCH_FRAMES=n` renders n frames per case in every section (medians steadier
    // on a busy machine).
    let frames_or = |default: u32| -> u32 {
        std::env::var("CAVETRACE_BENCH_FRAMES")
            .ok()
            .and_then(|n| n.parse().ok())
            .unwrap_or(default)
    };
    let frames = frames_or(frames);
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);

    let (geometry, triangle_list) = height_field(dev, cells);
    let triangles = triangle_list.len();
    let start = Instant::now();
    commit(dev, geometry);
    let build_ms = start.elapsed().as_secs_f64() * 1e3;
    let bytes = cavetrace::device::registry::device(dev as usize)
        .and_then(|d| d.lookup(geometry as usize))
        .and_then(|o| o.derived_as::<cavetrace::scene::geometry::Geometry>())
        .map(|g| g.memory_bytes())
        .unwrap_or(0);
    println!(
        "height field: {triangles} triangles, BVH build (commit) {build_ms:.0} ms, {:.1} bytes/triangle",
        bytes as f64 / triangles as f64
    );

    // The sections run alone, on the height field.
    let section = |name: &str| std::env::args().skip(1).any(|a| a == name);
    // `CAVETRACE_BENCH_SCENE=2` runs the viewers and light-field sections on the 968-triangle
    // height field (the stereo section's scene 2): its BVH stays in the caches, and the camera's
    // share of a frame is largest there.
    let small_field = || {
        (std::env::var("CAVETRACE_BENCH_SCENE").as_deref() == Ok("2")).then(|| {
            let small = height_field(dev, 22).0;
            commit(dev, small);
            println!("on the 968-triangle height field");
            small
        })
    };
    let on_scene = |run: &dyn Fn(ANARIGeometry, u32)| {
        let small = small_field();
        run(
            small.unwrap_or(geometry),
            if small.is_some() { 22 } else { cells },
        );
        if let Some(small) = small {
            anariRelease(dev, small);
        }
    };
    let section_run = if section("viewers") {
        on_scene(&|scene, _| {
            viewers_section(dev, scene, size, frames_or(if quick { 4 } else { 15 }))
        });
        true
    } else if section("lightfield") {
        on_scene(&|scene, cells| {
            light_field_section(
                dev,
                scene,
                cells,
                size,
                frames_or(if quick { 3 } else { 7 }),
            )
        });
        true
    } else if section("depth") {
        // `-- depth default`: the same frames with the default renderer.
        let renderer = if section("default") {
            "default"
        } else {
            "fast"
        };
        depth_section(
            dev,
            geometry,
            renderer,
            size,
            frames_or(if quick { 3 } else { 9 }),
        );
        true
    } else if section("budget") {
        budget_section(dev, geometry, size, frames_or(if quick { 10 } else { 60 }));
        true
    } else {
        false
    };
    if section_run {
        anariRelease(dev, geometry);
        anariRelease(dev, dev);
        anariUnloadLibrary(lib);
        return;
    }
    if section("stereo") {
        let cloud = sphere_cloud(dev, spheres);
        commit(dev, cloud);
        let small = height_field(dev, 22).0;
        commit(dev, small);
        let scenes = [
            ("1M-triangle height field", geometry),
            ("100k spheres", cloud),
            ("968-triangle height field", small),
        ];
        stereo_section(dev, &scenes, size, frames_or(if quick { 3 } else { 7 }));
        anariRelease(dev, small);
        anariRelease(dev, cloud);
        anariRelease(dev, geometry);
        anariRelease(dev, dev);
        anariUnloadLibrary(lib);
        return;
    }
    let fast = setup(dev, geometry, "fast", size);
    track_head(&fast, 0);
    let first = render_once(&fast);
    println!(
        "first frame (scene already committed): {first:.1} ms; commit + first frame: {:.1} ms",
        build_ms + first
    );
    run("(a) fast renderer, moving head", &fast, size, frames);
    same_rays(&fast, geometry, &triangle_list, size, frames);
    drop(triangle_list);
    release(fast);
    if fast_only {
        anariRelease(dev, geometry);
        anariRelease(dev, dev);
        anariUnloadLibrary(lib);
        return;
    }
    let shaded = setup(dev, geometry, "default", size);
    track_head(&shaded, 0);
    run(
        "(b) default renderer, 1 directional light + shadows, moving head",
        &shaded,
        size,
        frames,
    );
    release(shaded);
    anariRelease(dev, geometry);

    let cloud = sphere_cloud(dev, spheres);
    let start = Instant::now();
    commit(dev, cloud);
    println!(
        "sphere cloud: {spheres} spheres, BVH build {:.0} ms",
        start.elapsed().as_secs_f64() * 1e3
    );
    let s = setup(dev, cloud, "fast", size);
    track_head(&s, 0);
    run("(c) 100k spheres, fast renderer", &s, size, frames);
    release(s);
    anariRelease(dev, cloud);
    anariRelease(dev, dev);
    anariUnloadLibrary(lib);
    let errors = log.errors();
    if !errors.is_empty() {
        println!("status errors during the benchmark: {errors:?}");
    }
}
