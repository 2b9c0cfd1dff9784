//! Tile tracing: a worker turns one tile (or one unit of a budgeted plan) into encoded pixels,
//! tracing 8×8 blocks of primary rays as packets and shading their hits.

use glam::{Vec2, Vec3, Vec4};

use crate::accel::{PacketScratch, Ray, RayArrays};
use crate::camera::{BLOCK_RAYS, BlockRays, CameraRay, EyeRays, PixelSet, lane_vec3};
use crate::render::block_shadows::BlockShadows;
use crate::render::cluster;
use crate::render::eye_light::{fast_surface_color, fast_surface_sample};
use crate::render::integrator::shade_primary_at;
use crate::render::interleave::{InterleavedTile, lattice_size};
use crate::render::progressive::{FrameTile, SINGLE_RAY_STRIDE, TileMap};
use crate::scene::light::LightSampling;

use super::anaglyph::{anaglyph, anaglyph_eyes};
use super::channels::PackedRows;
use super::eye_groups::EyeGroups;
use super::fast_block::FastBlock;
use super::records::TileRecords;
use super::samples::{jitter, lens_sample};
use super::{Job, TILE_SIZE, lock};

impl Job {
    /// Tile `tile` of an unbudgeted interleaved render: the eyes' lattice tiles alternate.
    pub(super) fn interleaved_tile(&self, tile: usize, sets: [PixelSet; 2]) -> InterleavedTile {
        let set = sets[tile % 2];
        let (width, height) = lattice_size(set, self.setup.width, self.setup.height);
        let tile = tile as u32 / 2;
        let (s0, t0) = (
            (tile % self.tiles_x) * TILE_SIZE,
            (tile / self.tiles_x) * TILE_SIZE,
        );
        let end = ((s0 + TILE_SIZE).min(width), (t0 + TILE_SIZE).min(height));
        let frame = (self.setup.width, self.setup.height);
        InterleavedTile::new(set, (s0, t0), end, frame)
    }

    /// Tile `tile` of an unbudgeted render: a square of the whole frame.
    pub(super) fn frame_tile(&self, tile: usize) -> FrameTile {
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

/// Side of the pixel blocks traced together as one coherent packet of primary rays.
pub(super) const PACKET_SIDE: u32 = 8;

/// Pixel offsets of an 8×8 block in the order packet traversal expects: sixteen 2×2 quads of
/// four consecutive rays, quads in row order.
pub(super) const PACKET_ORDER: [(u32, u32); 64] = {
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
pub(super) const NO_RAY: Ray = Ray {
    origin: Vec3::ZERO,
    direction: Vec3::ZERO,
    t_min: 0.0,
    t_max: 0.0,
};

/// What a block's `rays` hold in debug builds when the block is shaded from its arrays and no
/// one reads them: a NaN origin, so any reader fails loudly.
#[cfg(debug_assertions)]
const UNFILLED_RAY: Ray = Ray {
    origin: Vec3::NAN,
    direction: Vec3::ZERO,
    t_min: 0.0,
    t_max: 0.0,
};

/// Pixels in a full tile.
pub(super) const TILE_PIXELS: usize = (TILE_SIZE * TILE_SIZE) as usize;

/// The ray to trace for a camera ray.
#[inline]
pub(super) fn traced(camera_ray: &CameraRay) -> Ray {
    Ray {
        origin: camera_ray.origin,
        direction: camera_ray.direction,
        t_min: camera_ray.t_min,
        t_max: camera_ray.t_max,
    }
}

/// The ray to trace for lane `lane` of a block: [`traced`] of its camera ray, read straight
/// from the block's arrays.
#[inline(always)]
pub(super) fn traced_lane(block: &BlockRays, lane: usize) -> Ray {
    Ray {
        origin: lane_vec3(&block.origin, lane),
        direction: lane_vec3(&block.direction, lane),
        t_min: block.t_min[lane],
        t_max: block.t_max[lane],
    }
}

/// A block's viewport coordinates by lane from those of its pixel columns (for its even and
/// its odd rows) and rows, quad by quad ([`PACKET_ORDER`]'s 2×2 quads of consecutive lanes).
#[inline(always)]
fn fill_block_lanes(
    [even, odd]: [&[f32; PACKET_SIDE as usize]; 2],
    rows: &[f32; PACKET_SIDE as usize],
    s_lanes: &mut [f32; BLOCK_RAYS],
    t_lanes: &mut [f32; BLOCK_RAYS],
) {
    let quads = s_lanes.chunks_exact_mut(4).zip(t_lanes.chunks_exact_mut(4));
    for (quad, (s4, t4)) in quads.enumerate() {
        // Quads start on even rows.
        let (c, r) = PACKET_ORDER[4 * quad];
        let (c, r) = (c as usize, r as usize);
        s4.copy_from_slice(&[even[c], even[c + 1], odd[c], odd[c + 1]]);
        t4.copy_from_slice(&[rows[r], rows[r], rows[r + 1], rows[r + 1]]);
    }
}

/// A worker's working memory, kept from one tile to the next.
#[derive(Default)]
pub(super) struct TileScratch {
    packets: PacketScratch,
    /// The default renderer's shadow-ray answers for the block being shaded.
    shadows: BlockShadows,
    /// Per pixel of a tile, the requested channels' values from its first hit.
    records: TileRecords,
    /// One channel's pixels of a tile, encoded.
    encoded: Vec<u8>,
    /// A light-field tile's subpixel rays, traced grouped by eye.
    eye_groups: EyeGroups,
}

pub(super) fn render_tile(
    job: &Job,
    eyes: &[(crate::camera::EyeViewport, EyeRays)],
    map: impl TileMap,
    scratch: &mut TileScratch,
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
    scratch
        .records
        .reset(&job.pixel_work.hit_channels, pixel_count);
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
                0,
                Grouping::Off,
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
                1,
                Grouping::Off,
            );
            for (color, right) in colors[..pixel_count].iter_mut().zip(&right_colors) {
                *color = anaglyph(*color, *right);
            }
        }
        (None, Some(channels)) => {
            // A light-field display: a ray per subpixel, each giving its colour channel; alpha
            // and the other channels come from the green subpixel's ray. Where eight rays can
            // be walked together, the three passes' rays are made first and traced grouped by
            // eye (`EyeGroups`), then shaded pass by pass.
            let mut passes = [[Vec4::ZERO; TILE_PIXELS]; 3];
            let mut groups = std::mem::take(&mut scratch.eye_groups);
            let grouped = setup.scene.bvh.walks_eights_together();
            // Subpixel pass `k` of the tile (`green`: its hits give the other channels).
            let mut pass_blocks = |k: usize, pass: &mut _, green: bool, grouping: Grouping| {
                let rays = PixelRays::Subpixel(k as u32);
                let variant = k as u32;
                trace_blocks(
                    job,
                    eyes,
                    map,
                    scratch,
                    pass,
                    &mut covered,
                    green,
                    rays,
                    variant,
                    grouping,
                );
            };
            if grouped {
                groups.clear();
                for (k, pass) in passes.iter_mut().enumerate() {
                    pass_blocks(k, pass, false, Grouping::Collect(&mut groups));
                }
                groups.trace(&setup.scene.bvh);
            }
            for (k, pass) in passes.iter_mut().enumerate() {
                let grouping = if grouped {
                    Grouping::Replay(&mut groups)
                } else {
                    Grouping::Off
                };
                pass_blocks(k, pass, channels[k] == 1, grouping);
            }
            scratch.eye_groups = groups;
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
                0,
                Grouping::Off,
            );
        }
    }
    let passes = (job.pass + 1) as f32;
    // Final colours: the samples' mean (the background where no eye looks), then the running
    // mean over the passes when accumulating.
    let mut color_sum = job.color_sum.as_ref().map(lock);
    // Walked row by row: a division per pixel for its lattice point cost a tenth of this loop.
    let (s0, s1) = (area.s0, area.s1);
    let lattice_points = (area.t0..area.t1).flat_map(|sy| (s0..s1).map(move |sx| (sx, sy)));
    // One sample of every pixel, not accumulated: the sums are the colours already. The
    // coverage is folded without an early exit, so that it is checked many pixels per
    // instruction (an exit per pixel costs five instructions per pixel).
    let final_already = samples == 1
        && color_sum.is_none()
        && covered[..pixel_count]
            .iter()
            .fold(true, |all, covered| all & *covered);
    let pixels_to_finish = if final_already { 0 } else { pixel_count };
    for (k, (color, (sx, sy))) in colors[..pixels_to_finish]
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
    let row_pixels = (area.s1 - area.s0) as usize;
    if let Some(targets) = &job.frame_targets {
        // Encoded straight into the frame's rows: no tile buffer, no copy, no lock.
        let (x0, y0) = map
            .rectangle_origin()
            .expect("a render with frame targets traces squares of the frame");
        for (format, target) in job.formats.iter().zip(targets) {
            // SAFETY: a render has frame targets only when its tiles are distinct squares of
            // the frame, each taken by one worker once, and nothing else touches the channels
            // until the last worker has left (`Job::frame_targets`).
            let mut rows = unsafe { target.tile(x0, y0, area.s1 - area.s0, area.t1 - area.t0) };
            format.encode(
                &colors[..pixel_count],
                &scratch.records,
                row_pixels,
                &mut rows,
            );
        }
        return;
    }
    // Encoded outside the lock; the lock is held only to copy the rows in.
    for (index, format) in job.formats.iter().enumerate() {
        let encoded = &mut scratch.encoded;
        let bytes = pixel_count * format.pixel_bytes;
        encoded.resize(bytes, 0);
        let mut rows = PackedRows {
            bytes: encoded,
            row_bytes: bytes,
        };
        format.encode(
            &colors[..pixel_count],
            &scratch.records,
            pixel_count,
            &mut rows,
        );
        if let Some(channel) = lock(&job.channels).get_mut(index) {
            channel.write_area(&map, setup.width, encoded);
        }
    }
}

/// Which ray of a pixel a pass traces: the pixel's own, or (light-field displays) the ray of
/// its subpixel k (0, 1, 2 from the left).
#[derive(Clone, Copy)]
pub(super) enum PixelRays {
    All,
    Subpixel(u32),
}

impl PixelRays {
    /// The viewport coordinate s of column `x`'s ray in `viewport` (`offset`: the sample's
    /// offset within the pixel).
    #[inline(always)]
    fn viewport_s(self, x: u32, viewport: &crate::camera::EyeViewport, offset: f32) -> f32 {
        match self {
            PixelRays::All => ((x - viewport.x) as f32 + offset) / viewport.width as f32,
            // The subpixel as a pixel of a frame three times as wide.
            PixelRays::Subpixel(k) => {
                ((3 * (x - viewport.x) + k) as f32 + offset) / (3 * viewport.width) as f32
            }
        }
    }
}

/// Whether [`trace_blocks`] traces as it goes, or takes part in tracing a light-field tile's
/// rays grouped by eye ([`EyeGroups`]).
pub(super) enum Grouping<'a> {
    /// Each block traced as it is made.
    Off,
    /// Only makes the blocks whose rays are made together and stores them (nothing traced or
    /// shaded; other blocks are left to the replay).
    Collect(&'a mut EyeGroups),
    /// The same blocks in the same order: the stored ones shaded from their stored rays and
    /// hits, the others made, traced and shaded as with `Off`.
    Replay(&'a mut EyeGroups),
}

/// An eye's viewport with its ray generator for the frame.
pub(super) type PreparedEye = (crate::camera::EyeViewport, EyeRays);

/// Traces the tile's pixels from `eyes`, summing each pixel's samples into `colors` and
/// marking it `covered`; with `record_hits` (and a frame that keeps hits), each pixel's first
/// hit's channel values go into `scratch.records`. `variant` numbers the frame's rays of a
/// pixel's sample (the eye of an anaglyph, a subpixel), as [`super::rays_per_pixel_sample`]
/// counts them. `grouping`: see [`Grouping`].
#[allow(clippy::too_many_arguments)]
pub(super) fn trace_blocks(
    job: &Job,
    eyes: &[(crate::camera::EyeViewport, EyeRays)],
    map: impl TileMap,
    scratch: &mut TileScratch,
    colors: &mut [Vec4; TILE_PIXELS],
    covered: &mut [bool; TILE_PIXELS],
    record_hits: bool,
    pixel_rays: PixelRays,
    variant: u32,
    mut grouping: Grouping,
) {
    let setup = &job.setup;
    let area = map.area();
    let (tx, ty, x_end, y_end) = (area.s0, area.t0, area.s1, area.t1);
    let tile_width = x_end - tx;
    let samples = setup.settings.pixel_samples;
    let work = &job.pixel_work;
    let keeps_hits = work.hit_channels.any() && record_hits;
    let clustered = setup.scene.cluster.is_some();
    let (width, height) = (setup.width as usize, setup.height as usize);
    let records = &mut scratch.records;
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
            let batched =
                block_eye.filter(|(_, eye_rays)| !work.plain_pixels && eye_rays.batches_rays());
            if batched.is_some() {
                batch = [None; 64];
            }
            // A whole block of pixels seen from one lensless pinhole (or from several viewers'
            // blended positions, or a light-field display's subpixels of one pass): its rays
            // are made together, lane by lane.
            let whole_block =
                !work.plain_pixels && bx_end - bx == PACKET_SIDE && by_end - by == PACKET_SIDE;
            let block_maker =
                block_eye.filter(|(_, eye_rays)| whole_block && eye_rays.makes_block_rays());
            for s in 0..samples {
                let index = job.pass * samples + s;
                let offset = jitter(index);
                let lens = lens_sample(index);
                // A block stored by `Grouping::Collect` comes back with its rays and hits;
                // `Grouping::Collect` makes the block where it is stored.
                let (replayed_index, made_into) = match &mut grouping {
                    Grouping::Replay(groups) => (groups.replay(), &mut block),
                    Grouping::Collect(groups) => (None, groups.next_block()),
                    Grouping::Off => (None, &mut block),
                };
                let replayed = replayed_index.is_some();
                let made = block_maker
                    .filter(|_| !replayed)
                    .and_then(|(viewport, eye_rays)| {
                        let mut s_lanes = [0.0; BLOCK_RAYS];
                        let mut t_lanes = [0.0; BLOCK_RAYS];
                        let height = viewport.height as f32;
                        // As below, ray by ray.
                        let s_of = |x: u32| pixel_rays.viewport_s(x, viewport, offset.x);
                        let t_of = |y: u32| ((y - viewport.y) as f32 + offset.y) / height;
                        if let Some(pixels) = map.block_pixels(bx, by) {
                            // s depends on a point's column (and in an interleaved lattice on its
                            // row's parity), t on its row: 16 divisions for the block's 64 rays
                            // (24 where the parities differ).
                            let [even_columns, odd_columns] = pixels.columns;
                            let even = even_columns.map(s_of);
                            let odd = if odd_columns == even_columns {
                                even
                            } else {
                                odd_columns.map(s_of)
                            };
                            let rows = pixels.rows.map(t_of);
                            fill_block_lanes([&even, &odd], &rows, &mut s_lanes, &mut t_lanes);
                        } else {
                            for (lane, (dx, dy)) in PACKET_ORDER.iter().enumerate() {
                                let (sx, sy) = (bx + dx, by + dy);
                                if map.skips(sx, sy) {
                                    return None;
                                }
                                let (x, y) = map.pixel(sx, sy);
                                s_lanes[lane] = s_of(x);
                                t_lanes[lane] = t_of(y);
                            }
                        }
                        if !eye_rays.block_rays(&s_lanes, &t_lanes, made_into) {
                            return None;
                        }
                        Some(eye_rays)
                    });
                let block_rays = if replayed {
                    block_maker.map(|(_, eye_rays)| eye_rays)
                } else {
                    made
                };
                if let Grouping::Collect(groups) = &mut grouping {
                    groups.commit(block_rays.is_some());
                    continue;
                }
                let subpixels = matches!(pixel_rays, PixelRays::Subpixel(_));
                let coherent = map.stride() < SINGLE_RAY_STRIDE && !subpixels;
                let one_by_one = !coherent || work.plain_pixels;
                // The fast renderer shades a whole block from its arrays, and a coherent one is
                // traced from them; everything else reads the block's rays one by one.
                let shaded_from_arrays = block_rays.is_some() && work.fast_surfaces && !clustered;
                // A replayed block is traced already.
                let traced_here = one_by_one && !replayed;
                let reads_rays = traced_here || !shaded_from_arrays || work.block_shadows;
                // The block's rays: made here, or replayed.
                let stored = match (&grouping, replayed_index) {
                    (Grouping::Replay(groups), Some(index)) => Some(groups.stored(index)),
                    _ => None,
                };
                let (stored_block, stored_hits) = stored.unzip();
                let block = stored_block.unwrap_or(&block);
                if block_rays.is_some() && reads_rays {
                    for (lane, ray) in rays.iter_mut().enumerate() {
                        *ray = traced_lane(block, lane);
                    }
                } else if block_rays.is_some() {
                    // Unfilled: a reader added later must not silently get the previous
                    // block's rays, so debug builds (tests) poison them.
                    #[cfg(debug_assertions)]
                    rays.fill(UNFILLED_RAY);
                }
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
                    let u = pixel_rays.viewport_s(x, viewport, offset.x);
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
                if replayed {
                    // Traced already, grouped by eye.
                } else if one_by_one {
                    // Sparse lattices make incoherent packets, and a light field's neighbouring
                    // subpixels look from eyes centimetres apart: ray by ray is cheaper there.
                    for (hit, ray) in hits.iter_mut().zip(&rays) {
                        setup.scene.bvh.intersect_into(ray, hit);
                    }
                } else if block_rays.is_some() {
                    // The packet is filled straight from the block's lanes.
                    let arrays = RayArrays {
                        origin: &block.origin,
                        direction: &block.direction,
                        t_min: &block.t_min,
                        t_max: &block.t_max,
                    };
                    setup
                        .scene
                        .bvh
                        .intersect_arrays_with(&mut scratch.packets, &arrays, &mut hits);
                } else {
                    setup
                        .scene
                        .bvh
                        .intersect_packet_with(&mut scratch.packets, &rays, &mut hits);
                }
                // The block's hits: traced here, or replayed.
                let hits = stored_hits.unwrap_or(&hits);
                let block_shadows = coherent && work.block_shadows;
                if block_shadows {
                    scratch.shadows.trace(
                        &setup.scene,
                        &mut scratch.packets,
                        &rays,
                        hits,
                        |lane| {
                            let (dx, dy) = PACKET_ORDER[lane];
                            let (x, y) = map.pixel(bx + dx, by + dy);
                            LightSampling::for_pixel(index, x, y)
                        },
                    );
                }
                if let Some(eye_rays) = block_rays.filter(|_| shaded_from_arrays) {
                    // A whole block from one eye: shaded from the block's arrays.
                    let fast = FastBlock {
                        scene: &setup.scene,
                        settings: &setup.settings,
                        hits,
                        block,
                        eye: eye_rays,
                        first: ((by - ty) * tile_width + bx - tx) as usize,
                        row_stride: tile_width as usize,
                    };
                    let screen = |lane: usize| {
                        let (dx, dy) = PACKET_ORDER[lane];
                        let (x, y) = map.pixel(bx + dx, by + dy);
                        Vec2::new(
                            (x as f32 + offset.x) / setup.width as f32,
                            (y as f32 + offset.y) / setup.height as f32,
                        )
                    };
                    let records = (s == 0 && keeps_hits).then_some(&mut *records);
                    fast.shade(screen, colors, covered, records);
                    continue;
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
                    if clustered {
                        // Cluster hook: which of the frame's primary samples this is.
                        let plane = (variant * samples + s) as usize;
                        cluster::at_slot((plane * height + y as usize) * width + x as usize);
                    }
                    if work.fast_surfaces {
                        let (scene, settings) = (&setup.scene, &setup.settings);
                        let (ray, hit) = (&rays[lane], hits[lane].as_ref());
                        if s == 0 && keeps_hits {
                            let sample = fast_surface_sample(
                                scene,
                                settings,
                                ray,
                                hit,
                                screen,
                                camera_ray.cyclopean,
                            );
                            colors[k] += sample.color;
                            let depth = |t| eye_rays.depth(&camera_ray, t);
                            records.record(k, sample.hit.as_ref(), || camera_ray, depth, eye_rays);
                        } else {
                            colors[k] += fast_surface_color(
                                scene,
                                settings,
                                ray,
                                hit,
                                screen,
                                camera_ray.cyclopean,
                            );
                        }
                        continue;
                    }
                    let shade = || {
                        shade_primary_at(
                            &setup.scene,
                            &setup.settings,
                            &rays[lane],
                            hits[lane],
                            Some(screen()),
                            camera_ray.cyclopean,
                            &LightSampling::for_pixel(index, x, y),
                        )
                    };
                    let sample = if block_shadows {
                        scratch.shadows.shading(lane, shade)
                    } else {
                        shade()
                    };
                    colors[k] += sample.color;
                    if s == 0 && keeps_hits {
                        let depth = |t| eye_rays.depth(&camera_ray, t);
                        records.record(k, sample.hit.as_ref(), || camera_ray, depth, eye_rays);
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
    fn packet_lanes_are_2x2_quads_of_consecutive_lanes() {
        // The block's viewport coordinates are filled quad by quad on this layout.
        for (lane, &(x, y)) in PACKET_ORDER.iter().enumerate() {
            let (x0, y0) = PACKET_ORDER[lane & !3];
            assert_eq!(
                (x, y),
                (x0 + lane as u32 % 2, y0 + lane as u32 / 2 % 2),
                "{lane}"
            );
        }
    }

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
}
