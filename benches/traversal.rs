//! Traversal benchmark: prints build times, memory and primary-ray throughput.
//!
//! Run with `cargo bench --bench traversal` (options: `--runs N`, `--triangles`, `--spheres`,
//! `--combined`). Every figure is the median of several runs; each run traces all 1600x1600
//! primary rays of a pinhole camera, generated in 8x8 tiles of 2x2 blocks (the order
//! `intersect_packet` wants; the single-ray rows use the same order). Workers take rows of
//! tiles from a shared counter (`std::thread::scope`). Besides wall-clock Mrays/s every row
//! prints Mrays per CPU second of the tracing threads (from /proc/thread-self/schedstat),
//! which stays meaningful on a shared machine; the percentage compares that figure with the
//! first row of its block (raw obvhs traversal where there is one).

use cavetrace::accel::{GeometryBvh, GeometryPrims, InstanceDesc, Ray, SceneBvh};
use glam::{Affine3A, UVec3, Vec3, Vec3A, vec3};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::{build_cwbvh, build_cwbvh_from_tris};
use obvhs::ray::RayHit;
use obvhs::triangle::Triangle;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

const WIDTH: usize = 1600;
const HEIGHT: usize = 1600;
const GRID_CELLS: u32 = 708;
const SPHERES: usize = 100_000;
/// Square tiles in which rays are generated and traced (one 64-ray packet each).
const TILE: usize = 8;
/// Tile rows handed to a worker at a time (rays are stored tile by tile).
const ROW_CHUNK: usize = TILE;

/// Median wall-clock milliseconds of `GeometryBvh::build` inside a rayon pool of `threads`.
fn build_ms(prims: &GeometryPrims, threads: usize, runs: usize) -> (f64, GeometryBvh) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool");
    let mut times = Vec::new();
    let mut built = None;
    for _ in 0..runs {
        let input = prims.clone();
        let start = Instant::now();
        built = Some(pool.install(|| GeometryBvh::build(input)));
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    (median(times), built.expect("at least one run"))
}

fn median(mut samples: Vec<f64>) -> f64 {
    samples.sort_by(f64::total_cmp);
    samples[samples.len() / 2]
}

/// Deterministic xorshift generator.
struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// 708x708 cells of gentle sine bumps, two triangles per cell (1,002,528 triangles).
fn height_field() -> GeometryPrims {
    let height = |x: f32, y: f32| {
        6.0 * (x * 0.031).sin() * (y * 0.027).cos() + 2.0 * (x * 0.11 + y * 0.07).sin()
    };
    let mut positions = Vec::with_capacity(((GRID_CELLS + 1) * (GRID_CELLS + 1)) as usize);
    for y in 0..=GRID_CELLS {
        for x in 0..=GRID_CELLS {
            let (fx, fy) = (x as f32, y as f32);
            positions.push(vec3(fx, fy, height(fx, fy)));
        }
    }
    let corner = |x: u32, y: u32| y * (GRID_CELLS + 1) + x;
    let mut indices = Vec::with_capacity((GRID_CELLS * GRID_CELLS * 2) as usize);
    for y in 0..GRID_CELLS {
        for x in 0..GRID_CELLS {
            indices.push(UVec3::new(
                corner(x, y),
                corner(x + 1, y),
                corner(x + 1, y + 1),
            ));
            indices.push(UVec3::new(
                corner(x, y),
                corner(x + 1, y + 1),
                corner(x, y + 1),
            ));
        }
    }
    GeometryPrims::Triangles { positions, indices }
}

/// 100k spheres in a 200-unit cube.
fn sphere_cloud() -> GeometryPrims {
    let mut rng = Rng(0x2545_F491_4F6C_DD1D);
    let mut centers = Vec::with_capacity(SPHERES);
    let mut radii = Vec::with_capacity(SPHERES);
    for _ in 0..SPHERES {
        centers.push(vec3(rng.unit(), rng.unit(), rng.unit()) * 200.0 - Vec3::splat(100.0));
        radii.push(0.4 + 1.2 * rng.unit());
    }
    GeometryPrims::Spheres { centers, radii }
}

/// Pinhole camera rays, row-major.
fn primary_rays(eye: Vec3, target: Vec3, vertical_fov_degrees: f32) -> Vec<Ray> {
    let forward = (target - eye).normalize();
    let right = forward.cross(Vec3::Z).normalize();
    let up = right.cross(forward);
    let half_height = (vertical_fov_degrees.to_radians() * 0.5).tan();
    let half_width = half_height * WIDTH as f32 / HEIGHT as f32;
    let mut rays = Vec::with_capacity(WIDTH * HEIGHT);
    // Tile order, as a renderer traces them, and inside a tile 2x2 pixel blocks, so that each
    // group of four consecutive rays can be traced as a packet.
    for tile_row in (0..HEIGHT).step_by(TILE) {
        for tile_column in (0..WIDTH).step_by(TILE) {
            for block_row in (tile_row..tile_row + TILE).step_by(2) {
                for block_column in (tile_column..tile_column + TILE).step_by(2) {
                    for (row, column) in [
                        (block_row, block_column),
                        (block_row, block_column + 1),
                        (block_row + 1, block_column),
                        (block_row + 1, block_column + 1),
                    ] {
                        let u = ((column as f32 + 0.5) / WIDTH as f32 * 2.0 - 1.0) * half_width;
                        let v = (1.0 - (row as f32 + 0.5) / HEIGHT as f32 * 2.0) * half_height;
                        let direction = (forward + right * u + up * v).normalize();
                        rays.push(Ray::new(eye, direction, 0.0, f32::INFINITY));
                    }
                }
            }
        }
    }
    rays
}

/// CPU time this thread has run, from the Linux scheduler (0 elsewhere). The bench machine is
/// shared, so rates per CPU second are printed next to wall-clock rates.
fn thread_cpu_seconds() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|text| text.split_whitespace().next()?.parse::<f64>().ok())
        .map_or(0.0, |nanoseconds| nanoseconds * 1e-9)
}

/// Traces all rays with `threads` workers taking row chunks; returns (wall seconds, CPU
/// seconds summed over workers, hits).
fn trace<F>(rays: &[Ray], threads: usize, trace_chunk: F) -> (f64, f64, usize)
where
    F: Fn(&[Ray]) -> usize + Sync,
{
    let next_chunk = AtomicUsize::new(0);
    let chunk_rays = ROW_CHUNK * WIDTH;
    let chunk_count = rays.len().div_ceil(chunk_rays);
    let start = Instant::now();
    let (cpu, hits) = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| {
                    let cpu_start = thread_cpu_seconds();
                    let mut hits = 0;
                    loop {
                        let chunk = next_chunk.fetch_add(1, Ordering::Relaxed);
                        if chunk >= chunk_count {
                            break (thread_cpu_seconds() - cpu_start, hits);
                        }
                        let end = ((chunk + 1) * chunk_rays).min(rays.len());
                        hits += trace_chunk(&rays[chunk * chunk_rays..end]);
                    }
                })
            })
            .collect();
        workers
            .into_iter()
            .map(|worker| worker.join().unwrap())
            .fold((0.0, 0), |(cpu, hits), (c, h)| (cpu + c, hits + h))
    });
    (start.elapsed().as_secs_f64(), cpu, hits)
}

/// Median wall-clock Mrays/s and median Mrays per CPU second over `runs`; also checks that
/// all runs agree on the hit count.
fn throughput<F>(rays: &[Ray], threads: usize, runs: usize, trace_chunk: F) -> (f64, f64, usize)
where
    F: Fn(&[Ray]) -> usize + Sync,
{
    let mut rates = Vec::new();
    let mut cpu_rates = Vec::new();
    let mut hit_count = None;
    for _ in 0..runs {
        let (seconds, cpu_seconds, hits) = trace(rays, threads, &trace_chunk);
        assert!(hit_count.is_none_or(|previous| previous == hits));
        hit_count = Some(hits);
        rates.push(rays.len() as f64 / seconds / 1.0e6);
        cpu_rates.push(rays.len() as f64 / cpu_seconds / 1.0e6);
    }
    (median(rates), median(cpu_rates), hit_count.unwrap())
}

/// Adapts a per-ray function to whole chunks.
fn each_ray(trace_one: impl Fn(&Ray) -> bool + Sync) -> impl Fn(&[Ray]) -> usize + Sync {
    move |rays| rays.iter().filter(|ray| trace_one(ray)).count()
}

/// Traces a chunk through `intersect_packet`-style calls, one 8x8 tile at a time.
fn in_packets<H: Copy>(
    trace_block: impl Fn(&[Ray], &mut [Option<H>]) + Sync,
) -> impl Fn(&[Ray]) -> usize + Sync {
    move |rays| {
        let mut hits = [None; 64];
        rays.chunks(64)
            .map(|block| {
                let hits = &mut hits[..block.len()];
                trace_block(block, hits);
                hits.iter().filter(|hit| hit.is_some()).count()
            })
            .sum()
    }
}

fn obvhs_ray(ray: &Ray) -> obvhs::ray::Ray {
    obvhs::ray::Ray::new(
        Vec3A::from(ray.origin),
        Vec3A::from(ray.direction),
        ray.t_min,
        ray.t_max,
    )
}

#[derive(Clone, Copy)]
struct Row {
    label: &'static str,
    threads: usize,
    mrays: f64,
    mrays_per_cpu_second: f64,
    hits: usize,
}

fn print_rows(rows: &[Row], baseline: f64) {
    for row in rows {
        let overhead = (baseline / row.mrays_per_cpu_second - 1.0) * 100.0;
        println!(
            "  {:<46} {} thread{} {:>6.2} Mrays/s wall {:>6.2} Mrays/CPU-s ({:+5.1}% CPU time vs first row) hits {}",
            row.label,
            row.threads,
            if row.threads == 1 { " " } else { "s" },
            row.mrays,
            row.mrays_per_cpu_second,
            overhead,
            row.hits
        );
    }
}

/// Prints the rows of each thread count, compared with the first row of that count.
fn print_by_threads(rows: &[Row]) {
    for threads in [1, 2] {
        let selected: Vec<Row> = rows
            .iter()
            .filter(|row| row.threads == threads)
            .copied()
            .collect();
        print_rows(&selected, selected[0].mrays_per_cpu_second);
    }
}

/// One row: `trace_chunk` over all rays with `threads` workers, medians of `runs`.
fn measure<F>(label: &'static str, rays: &[Ray], threads: usize, runs: usize, trace_chunk: F) -> Row
where
    F: Fn(&[Ray]) -> usize + Sync,
{
    let (mrays, mrays_per_cpu_second, hits) = throughput(rays, threads, runs, trace_chunk);
    Row {
        label,
        threads,
        mrays,
        mrays_per_cpu_second,
        hits,
    }
}

/// cavetrace's four ways of tracing one geometry: single rays and 8x8 packets, through the
/// geometry's own BVH and through a scene of one identity instance.
fn cavetrace_rows(
    geometry: &GeometryBvh,
    scene: &SceneBvh,
    rays: &[Ray],
    threads: usize,
    runs: usize,
) -> [Row; 4] {
    [
        measure(
            "GeometryBvh::intersect",
            rays,
            threads,
            runs,
            each_ray(|ray| geometry.intersect(ray).is_some()),
        ),
        measure(
            "SceneBvh::intersect (1 identity instance)",
            rays,
            threads,
            runs,
            each_ray(|ray| scene.intersect(ray).is_some()),
        ),
        measure(
            "GeometryBvh::intersect_packet (8x8 tiles)",
            rays,
            threads,
            runs,
            in_packets(|block, hits| geometry.intersect_packet(block, hits)),
        ),
        measure(
            "SceneBvh::intersect_packet (8x8 tiles)",
            rays,
            threads,
            runs,
            in_packets(|block, hits| scene.intersect_packet(block, hits)),
        ),
    ]
}

fn bench_triangles(runs: usize) {
    println!("== height field: {GRID_CELLS}x{GRID_CELLS} cells, 2 triangles per cell");
    let prims = height_field();
    let GeometryPrims::Triangles { positions, indices } = &prims else {
        unreachable!()
    };
    let triangle_list: Vec<Triangle> = indices
        .iter()
        .map(|c| Triangle {
            v0: positions[c.x as usize].into(),
            v1: positions[c.y as usize].into(),
            v2: positions[c.z as usize].into(),
        })
        .collect();

    let (build_one, _) = build_ms(&prims, 1, runs);
    let (build_two, geometry) = build_ms(&prims, 2, runs);
    let geometry = Arc::new(geometry);
    let mut raw_build_ms = Vec::new();
    let mut raw_bvh = None;
    for _ in 0..runs.min(3) {
        let start = Instant::now();
        raw_bvh = Some(build_cwbvh_from_tris(
            &triangle_list,
            BvhBuildParams::fast_build(),
            &mut Duration::default(),
        ));
        raw_build_ms.push(start.elapsed().as_secs_f64() * 1e3);
    }
    let raw_bvh = raw_bvh.unwrap();
    let raw_triangles: Vec<Triangle> = raw_bvh
        .primitive_indices
        .iter()
        .map(|&i| triangle_list[i as usize])
        .collect();
    let triangles = geometry.primitive_count();
    println!(
        "  triangles {triangles}, GeometryBvh::build {build_one:.0} ms in a 1-thread pool, \
         {build_two:.0} ms in a 2-thread pool, {:.1} bytes/triangle",
        geometry.memory_bytes() as f64 / triangles as f64
    );
    println!(
        "  (raw obvhs build_cwbvh_from_tris fast_build: {:.0} ms, nodes {})",
        median(raw_build_ms),
        raw_bvh.nodes.len()
    );

    let scene = SceneBvh::build(vec![InstanceDesc {
        transform: Affine3A::IDENTITY,
        geometries: vec![geometry.clone()],
    }]);
    let rays = primary_rays(vec3(354.0, -180.0, 260.0), vec3(354.0, 330.0, 0.0), 60.0);
    let mut rows = Vec::new();
    for threads in [1, 2] {
        rows.push(measure(
            "raw obvhs ray_traverse + Triangle::intersect",
            &rays,
            threads,
            runs,
            each_ray(|ray| {
                let mut hit = RayHit::none();
                raw_bvh.ray_traverse(obvhs_ray(ray), &mut hit, |r, id| {
                    raw_triangles[id].intersect(r)
                })
            }),
        ));
        rows.extend(cavetrace_rows(&geometry, &scene, &rays, threads, runs));
    }
    print_by_threads(&rows);
}

fn bench_spheres(runs: usize) {
    println!("== sphere cloud: {SPHERES} spheres");
    let prims = sphere_cloud();
    let (build_one, _) = build_ms(&prims, 1, runs);
    let (build_two, geometry) = build_ms(&prims, 2, runs);
    let geometry = Arc::new(geometry);
    println!(
        "  GeometryBvh::build {build_one:.0} ms in a 1-thread pool, {build_two:.0} ms in a \
         2-thread pool, {:.1} bytes/sphere",
        geometry.memory_bytes() as f64 / geometry.primitive_count() as f64
    );
    // Raw obvhs over the same spheres with a plain f32 sphere test.
    let GeometryPrims::Spheres { centers, radii } = &prims else {
        unreachable!()
    };
    let sphere_boxes: Vec<Aabb> = centers
        .iter()
        .zip(radii)
        .map(|(c, r)| Aabb::new((*c - Vec3::splat(*r)).into(), (*c + Vec3::splat(*r)).into()))
        .collect();
    let raw_bvh = build_cwbvh(
        &sphere_boxes,
        BvhBuildParams::fast_build(),
        &mut Duration::default(),
    );
    let raw_spheres: Vec<(Vec3A, f32)> = raw_bvh
        .primitive_indices
        .iter()
        .map(|&i| (Vec3A::from(centers[i as usize]), radii[i as usize]))
        .collect();
    let raw_sphere_t = |ray: &obvhs::ray::Ray, id: usize| {
        let (center, radius) = raw_spheres[id];
        let offset = ray.origin - center;
        let b = offset.dot(ray.direction);
        let c = offset.length_squared() - radius * radius;
        let disc = b * b - c;
        if disc < 0.0 {
            return f32::INFINITY;
        }
        let root = disc.sqrt();
        for t in [-b - root, -b + root] {
            if t >= ray.tmin && t <= ray.tmax {
                return t;
            }
        }
        f32::INFINITY
    };
    let scene = SceneBvh::build(vec![InstanceDesc {
        transform: Affine3A::IDENTITY,
        geometries: vec![geometry.clone()],
    }]);
    let rays = primary_rays(vec3(0.0, -320.0, 60.0), Vec3::ZERO, 45.0);
    let mut rows = Vec::new();
    for threads in [1, 2] {
        rows.push(measure(
            "raw obvhs ray_traverse + f32 sphere closure",
            &rays,
            threads,
            runs,
            each_ray(|ray| {
                let mut hit = RayHit::none();
                raw_bvh.ray_traverse(obvhs_ray(ray), &mut hit, raw_sphere_t)
            }),
        ));
        rows.extend(cavetrace_rows(&geometry, &scene, &rays, threads, runs));
    }
    print_by_threads(&rows);
}

/// Terrain plus four transformed copies of the sphere cloud floating above it: the top level
/// has five placements, so its traversal and the object-space transforms are measured too.
fn bench_combined(runs: usize) {
    println!("== combined scene: height field + 4 rotated/scaled sphere-cloud instances");
    let terrain = Arc::new(GeometryBvh::build(height_field()));
    let cloud = Arc::new(GeometryBvh::build(sphere_cloud()));
    let mut instances = vec![InstanceDesc {
        transform: Affine3A::IDENTITY,
        geometries: vec![terrain],
    }];
    for (i, corner) in [
        (150.0, 150.0),
        (550.0, 150.0),
        (150.0, 550.0),
        (550.0, 550.0),
    ]
    .into_iter()
    .enumerate()
    {
        instances.push(InstanceDesc {
            transform: Affine3A::from_scale_rotation_translation(
                Vec3::new(0.6, 0.8, 0.3 + 0.1 * i as f32),
                glam::Quat::from_rotation_z(0.5 * i as f32),
                vec3(corner.0, corner.1, 60.0),
            ),
            geometries: vec![cloud.clone()],
        });
    }
    let start = Instant::now();
    let scene = SceneBvh::build(instances);
    println!(
        "  SceneBvh::build {:.3} ms (no geometry rebuilt)",
        start.elapsed().as_secs_f64() * 1e3
    );
    let rays = primary_rays(vec3(354.0, -180.0, 260.0), vec3(354.0, 330.0, 0.0), 60.0);
    let mut rows = Vec::new();
    for threads in [1, 2] {
        rows.push(measure(
            "SceneBvh::intersect (5 instances)",
            &rays,
            threads,
            runs,
            each_ray(|ray| scene.intersect(ray).is_some()),
        ));
        rows.push(measure(
            "SceneBvh::intersect_packet (5 instances)",
            &rays,
            threads,
            runs,
            in_packets(|block, hits| scene.intersect_packet(block, hits)),
        ));
    }
    print_by_threads(&rows);
}

fn main() {
    let mut args = std::env::args().skip(1);
    let mut runs = 5;
    let mut only = None;
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--runs" => runs = args.next().and_then(|n| n.parse().ok()).unwrap_or(5).max(1),
            "--triangles" => only = Some("triangles"),
            "--spheres" => only = Some("spheres"),
            "--combined" => only = Some("combined"),
            _ => {}
        }
    }
    println!("cavetrace accel benchmark: {WIDTH}x{HEIGHT} primary rays, median of {runs} runs");
    if only.is_none() || only == Some("triangles") {
        bench_triangles(runs);
    }
    if only.is_none() || only == Some("spheres") {
        bench_spheres(runs);
    }
    if only.is_none() || only == Some("combined") {
        bench_combined(runs);
    }
}
