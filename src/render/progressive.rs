//! Frame-time budgets (`ANARI_CAVETRACE_FRAME_BUDGET`): which pixels a budgeted render traces,
//! in which order, and how the pixels it did not trace are filled.
//!
//! Each eye's viewport is refined in seven levels: the lattice of every 64th pixel in both
//! directions (one pixel per 64×64 block), then every 32nd, 16th, 8th, 4th, 2nd and every
//! pixel, each level tracing only the points the previous ones did not. Each level's lattice
//! is traced in tiles like a small frame — the *units* of work; the last level is the ordinary
//! full-resolution tiling, so converging costs little more than one full frame (sparse
//! lattices make incoherent packets — measured about 6× the cost per ray at stride 8 — so the
//! frame traces their rays one by one). A budgeted render traces a prefix of the units (at
//! least the whole first level, so that every pixel has a traced neighbour; with a fixed pixel
//! count every level down to stride 16) and the next render of an unchanged frame goes on
//! where the last one stopped. A render that falls behind its time (a loaded machine) thus
//! stops at a coarser lattice rather than overrunning. Both eyes of a stereo frame get the
//! same pixels: the lattices start at each eye's viewport corner and the eyes' units
//! alternate.
//!
//! Untraced pixels copy the channels other than colour from the nearest pixel traced so far
//! (never blended: ids and depths stay values that exist in the scene); colour is interpolated
//! between traced neighbours of the same surface ([`interpolate`]), in bands on several
//! threads.

mod deadline;
mod interpolate;

pub use deadline::DeadlineControl;
pub use interpolate::{ColorPixels, SurfaceGuide};

use crate::camera::{EyeViewport, PixelSet};

/// Side, in lattice points, of one unit's tile.
const UNIT_TILE: u32 = 32;

/// Lattices this sparse are traced ray by ray: their packets are too incoherent to pay
/// (measured on the 1M-triangle benchmark: the coarsest level 32 → 22 ms at stride ≥ 4, no
/// better at stride 2).
pub(crate) const SINGLE_RAY_STRIDE: u32 = 4;

/// Side of the units of lattices traced ray by ray (stride 4 and more): a ray there costs
/// several times a packet's, and a unit still in flight when time is up should end soon.
const SPARSE_UNIT_TILE: u32 = 16;

/// Pixels below which a fill stays on the calling thread (a thread costs tens of µs).
const PARALLEL_FILL_PIXELS: u64 = 1 << 16;

/// The pixels `origin + stride·(s, t)` of a frame: a whole frame (stride 1), or one
/// refinement level of a viewport (strides 8, 4, 2, 1 from the viewport's corner).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Lattice {
    pub origin_x: u32,
    pub origin_y: u32,
    pub stride: u32,
}

impl Lattice {
    pub const WHOLE_FRAME: Lattice = Lattice {
        origin_x: 0,
        origin_y: 0,
        stride: 1,
    };

    #[inline]
    pub fn pixel(&self, s: u32, t: u32) -> (u32, u32) {
        (
            self.origin_x + self.stride * s,
            self.origin_y + self.stride * t,
        )
    }
}

/// A rectangle of a lattice's sub-image, `[s0, s1) × [t0, t1)`: one tile of work. With
/// `skips_coarser`, the points that also lie on the lattice of twice the stride (traced by
/// the previous level) are left as they are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Area {
    pub lattice: Lattice,
    pub s0: u32,
    pub t0: u32,
    pub s1: u32,
    pub t1: u32,
    pub skips_coarser: bool,
}

impl Area {
    /// Points of the rectangle, skipped ones included.
    pub fn pixel_count(&self) -> usize {
        ((self.s1 - self.s0) * (self.t1 - self.t0)) as usize
    }

    /// Whether lattice point (s, t) is left alone (the previous level traced it).
    #[inline]
    pub fn skips(&self, s: u32, t: u32) -> bool {
        self.skips_coarser && s.is_multiple_of(2) && t.is_multiple_of(2)
    }

    /// Points this area traces.
    pub fn traced_count(&self) -> usize {
        if !self.skips_coarser {
            return self.pixel_count();
        }
        let evens = |a: u32, b: u32| (b.div_ceil(2) - a.div_ceil(2)) as usize;
        self.pixel_count() - evens(self.s0, self.s1) * evens(self.t0, self.t1)
    }
}

/// How the lattice points of a tile of work map to frame pixels. Generic, so that the
/// ordinary whole-frame tiling (identity, nothing skipped) compiles to the plain pixel loops.
pub trait TileMap: Copy {
    /// The tile's rectangle of lattice points.
    fn area(&self) -> Area;
    fn pixel(&self, s: u32, t: u32) -> (u32, u32);
    fn skips(&self, s: u32, t: u32) -> bool;
    fn stride(&self) -> u32;
    /// The frame pixel of the tile's first point when its points are a plain rectangle of
    /// pixels (written row by row), `None` otherwise.
    fn rectangle_origin(&self) -> Option<(u32, u32)>;
    /// The pixels the tile's points are drawn from: an interleaved eye's, or all.
    fn pixels(&self) -> PixelSet {
        PixelSet::All
    }
    /// The pixels of the tile's row `t` of points as a run of consecutive pixels of one frame
    /// row, when the map says so (then the row is written in one copy).
    #[inline]
    fn point_row(&self, t: u32) -> Option<PointRow> {
        let _ = t;
        None
    }
    /// The pixels of the N×N block of points from (s, t) by column and row, when a point's
    /// pixel column depends only on its s and the parity of its t, and its pixel row only on
    /// its t: the columns of points (s + i, t) and (s + i, t + 1), and the rows of points
    /// (s, t + j). `None` when the map does not say so or skips a point of the block (then
    /// the block is mapped point by point). Here: a plain rectangle's blocks (both parities'
    /// columns the same), else `None`.
    #[inline]
    fn block_pixels<const N: usize>(&self, s: u32, t: u32) -> Option<BlockPixels<N>> {
        self.rectangle_origin()?;
        let columns = std::array::from_fn(|i| self.pixel(s + i as u32, t).0);
        let rows = std::array::from_fn(|j| self.pixel(s, t + j as u32).1);
        Some(BlockPixels {
            columns: [columns; 2],
            rows,
        })
    }
}

/// [`TileMap::point_row`]: the first `count` points of a row of points are the consecutive
/// pixels x, x + 1, … of frame row y; the row's other points are skipped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PointRow {
    pub x: u32,
    pub y: u32,
    pub count: u32,
}

/// [`TileMap::block_pixels`]: a block's pixel columns for its even and odd rows (counted from
/// its first), and its pixel rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockPixels<const N: usize> {
    pub columns: [[u32; N]; 2],
    pub rows: [u32; N],
}

impl TileMap for Area {
    fn area(&self) -> Area {
        *self
    }
    #[inline]
    fn pixel(&self, s: u32, t: u32) -> (u32, u32) {
        self.lattice.pixel(s, t)
    }
    #[inline]
    fn skips(&self, s: u32, t: u32) -> bool {
        Area::skips(self, s, t)
    }
    fn stride(&self) -> u32 {
        self.lattice.stride
    }
    fn rectangle_origin(&self) -> Option<(u32, u32)> {
        (self.lattice.stride == 1 && !self.skips_coarser)
            .then(|| self.lattice.pixel(self.s0, self.t0))
    }
}

/// A tile of the whole-frame tiling: its lattice points are its pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameTile {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl TileMap for FrameTile {
    fn area(&self) -> Area {
        Area {
            lattice: Lattice::WHOLE_FRAME,
            s0: self.x0,
            t0: self.y0,
            s1: self.x1,
            t1: self.y1,
            skips_coarser: false,
        }
    }
    #[inline]
    fn pixel(&self, s: u32, t: u32) -> (u32, u32) {
        (s, t)
    }
    #[inline]
    fn skips(&self, _: u32, _: u32) -> bool {
        false
    }
    fn stride(&self) -> u32 {
        1
    }
    fn rectangle_origin(&self) -> Option<(u32, u32)> {
        Some((self.x0, self.y0))
    }
}

/// Strides of the refinement levels, coarsest first; each halves the one before, so a level's
/// lattice holds the previous one. A timed render must trace only the coarsest; the levels
/// of strides 64 and 32 together trace what one level of stride 16 would, so where time
/// allows the image is the same, and where it does not (a loaded machine) the render stops
/// at a coarser lattice instead of overrunning its budget.
const LEVELS: [u32; 7] = [64, 32, 16, 8, 4, 2, 1];

/// The stride of the first level a render with a fixed pixel count (`budgetPixels`) traces
/// whole: one pixel per 16×16 block.
pub(crate) const FIXED_FIRST_STRIDE: u32 = 16;

/// The units of a budgeted render of `viewports`, in tracing order: level by level, each
/// level's lattice of every viewport cut into tiles (the eyes' tiles alternating, so a render
/// that stops early has traced as much of each eye).
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    pub units: Vec<Area>,
    /// Index of the first unit of each level, and the total at the end.
    pub first_unit: [usize; LEVELS.len() + 1],
    pub viewports: Vec<EyeViewport>,
}

impl Plan {
    pub fn new(viewports: &[EyeViewport]) -> Plan {
        let viewports: Vec<EyeViewport> = viewports
            .iter()
            .copied()
            .filter(|v| v.width > 0 && v.height > 0)
            .collect();
        // Interleaved eyes share one rectangle: its lattices are traced once, each point by
        // the eye that holds it.
        let mut viewports = viewports;
        viewports.dedup_by(|a, b| (a.x, a.y, a.width, a.height) == (b.x, b.y, b.width, b.height));
        let mut units = Vec::new();
        let mut first_unit = [0; LEVELS.len() + 1];
        for (level, &stride) in LEVELS.iter().enumerate() {
            first_unit[level] = units.len();
            // Per eye: the lattice, its size, and its tiles per row and column.
            let lattices: Vec<(Lattice, u32, u32, u32, u32)> = viewports
                .iter()
                .map(|v| {
                    let lattice = Lattice {
                        origin_x: v.x,
                        origin_y: v.y,
                        stride,
                    };
                    let (width, height) = (v.width.div_ceil(stride), v.height.div_ceil(stride));
                    let side = unit_side(stride);
                    let tiles = (width.div_ceil(side), height.div_ceil(side));
                    (lattice, width, height, tiles.0, tiles.1)
                })
                .collect();
            let most = lattices.iter().map(|l| l.3 * l.4).max().unwrap_or(0);
            for tile in 0..most {
                for &(lattice, width, height, tiles_x, tiles_y) in &lattices {
                    if tile >= tiles_x * tiles_y {
                        continue;
                    }
                    let (tx, ty) = (tile % tiles_x, tile / tiles_x);
                    let side = unit_side(stride);
                    units.push(Area {
                        lattice,
                        s0: tx * side,
                        t0: ty * side,
                        s1: ((tx + 1) * side).min(width),
                        t1: ((ty + 1) * side).min(height),
                        skips_coarser: level > 0,
                    });
                }
            }
        }
        first_unit[LEVELS.len()] = units.len();
        Plan {
            units,
            first_unit,
            viewports,
        }
    }

    /// Units that must be traced before an image can be filled: the coarsest level.
    pub fn mandatory_units(&self) -> usize {
        self.first_unit[1]
    }

    /// Units of the levels down to stride `stride` (at least the coarsest level).
    pub fn units_through_stride(&self, stride: u32) -> usize {
        let levels = LEVELS.iter().take_while(|&&s| s >= stride).count().max(1);
        self.first_unit[levels]
    }

    /// Pixels traced by the first `done` units.
    pub fn traced_pixels(&self, done: usize) -> usize {
        self.units[..done.min(self.units.len())]
            .iter()
            .map(Area::traced_count)
            .sum()
    }

    /// Fills every untraced pixel after the first `done` units (at least
    /// [`Plan::mandatory_units`]) of `bytes` (a frame `width` pixels wide, `pixel_bytes` per
    /// pixel) with a copy of the nearest traced pixel of its viewport on the lattice of the
    /// last complete level: per axis the nearer lattice line, the lower one on ties and where
    /// the upper one lies beyond the viewport. A render that went on from `start` units
    /// without completing a level leaves the fill of the last render as it is: it came from
    /// the same lattice.
    pub fn fill(
        &self,
        width: u32,
        (start, done): (usize, usize),
        pixel_bytes: usize,
        bytes: &mut [u8],
        threads: usize,
    ) {
        self.fill_with(
            width,
            start,
            done,
            pixel_bytes,
            bytes,
            |stride, bytes| match pixel_bytes {
                4 => self.fill_pixels::<4>(width, stride, bytes, threads),
                6 => self.fill_pixels::<6>(width, stride, bytes, threads),
                12 => self.fill_pixels::<12>(width, stride, bytes, threads),
                16 => self.fill_pixels::<16>(width, stride, bytes, threads),
                3 => self.fill_pixels::<3>(width, stride, bytes, threads),
                _ => debug_assert!(false, "no channel has {pixel_bytes}-byte pixels"),
            },
        );
    }

    /// [`Plan::fill`] for the colour channel: untraced pixels blend the traced corners of
    /// their lattice cell that show the nearest corner's surface (as `guide` tells).
    pub fn fill_color(
        &self,
        width: u32,
        (start, done): (usize, usize),
        pixels: ColorPixels,
        bytes: &mut [u8],
        guide: &SurfaceGuide,
        threads: usize,
    ) {
        let pixel_bytes = match pixels {
            ColorPixels::Unorm8 => 4,
            ColorPixels::Float32 => 16,
        };
        self.fill_with(width, start, done, pixel_bytes, bytes, |stride, bytes| {
            for viewport in &self.viewports {
                interpolate::fill_viewport(viewport, width, stride, pixels, bytes, guide, threads);
            }
        });
    }

    /// Runs `fill(stride, bytes)` with the stride of the finest complete level when the
    /// render completed a level (the pixels of a level in progress kept as traced).
    fn fill_with(
        &self,
        width: u32,
        start: usize,
        done: usize,
        pixel_bytes: usize,
        bytes: &mut [u8],
        fill: impl FnOnce(u32, &mut [u8]),
    ) {
        let levels = self.complete_levels(done);
        if levels == 0
            || levels == LEVELS.len()
            || (start > 0 && self.complete_levels(start) == levels)
        {
            return;
        }
        // The pixels of the level the render stopped in the middle of (all traced by this
        // render, as it completed the level before) are exact: kept aside while the rows
        // are filled from the complete level, then put back.
        let partial = &self.units[self.first_unit[levels]..done];
        let mut kept = Vec::new();
        for unit in partial {
            for (start, length) in byte_runs(unit, width, pixel_bytes) {
                kept.extend_from_slice(&bytes[start..start + length]);
            }
        }
        fill(LEVELS[levels - 1], bytes);
        let mut offset = 0;
        for unit in partial {
            for (start, length) in byte_runs(unit, width, pixel_bytes) {
                bytes[start..start + length].copy_from_slice(&kept[offset..offset + length]);
                offset += length;
            }
        }
    }

    /// Levels complete after the first `done` units.
    fn complete_levels(&self, done: usize) -> usize {
        self.first_unit[1..]
            .iter()
            .take_while(|&&f| f <= done)
            .count()
    }

    /// [`Plan::fill`] for `N`-byte pixels (a fixed size makes each copy a few moves). Each
    /// lattice row is first filled along itself; every other row is then a copy of its
    /// nearest lattice row, in bands of rows on up to `threads` threads.
    fn fill_pixels<const N: usize>(
        &self,
        width: u32,
        stride: u32,
        bytes: &mut [u8],
        threads: usize,
    ) {
        let nearest = |p: u32, start: u32, extent: u32| {
            let d = (p - start) % stride;
            let lower = p - d;
            if d > stride / 2 && lower + stride < start + extent {
                lower + stride
            } else {
                lower
            }
        };
        let row_bytes = width as usize * N;
        for v in &self.viewports {
            let columns: Vec<u32> = (v.x..v.x + v.width)
                .map(|x| nearest(x, v.x, v.width))
                .collect();
            let (x0, x1) = (v.x as usize * N, (v.x + v.width) as usize * N);
            // The lattice rows, filled along themselves and copied out for the bands to read.
            let lattice_row_bytes = x1 - x0;
            let mut lattice_rows =
                Vec::with_capacity(v.height.div_ceil(stride) as usize * lattice_row_bytes);
            for y in (v.y..v.y + v.height).step_by(stride as usize) {
                let row = &mut bytes[y as usize * row_bytes..][..row_bytes];
                for (x, &source_column) in (v.x..v.x + v.width).zip(&columns) {
                    if source_column != x {
                        let (source, target) = (source_column as usize * N, x as usize * N);
                        row.copy_within(source..source + N, target);
                    }
                }
                lattice_rows.extend_from_slice(&row[x0..x1]);
            }
            let rows = &mut bytes[v.y as usize * row_bytes..(v.y + v.height) as usize * row_bytes];
            let pixels = u64::from(v.width) * u64::from(v.height);
            let bands = if pixels < PARALLEL_FILL_PIXELS {
                1
            } else {
                threads.clamp(1, v.height as usize)
            };
            let band_rows = (v.height as usize).div_ceil(bands);
            let fill_band = |first_row: usize, band: &mut [u8]| {
                for (k, row) in band.chunks_exact_mut(row_bytes).enumerate() {
                    let y = v.y + (first_row + k) as u32;
                    if !(y - v.y).is_multiple_of(stride) {
                        let source = (nearest(y, v.y, v.height) - v.y) / stride;
                        let source = source as usize * lattice_row_bytes;
                        row[x0..x1].copy_from_slice(&lattice_rows[source..][..lattice_row_bytes]);
                    }
                }
            };
            let fill_band = &fill_band;
            std::thread::scope(|scope| {
                let mut chunks = rows.chunks_mut(band_rows * row_bytes).enumerate();
                let first = chunks.next();
                for (band, chunk) in chunks {
                    scope.spawn(move || fill_band(band * band_rows, chunk));
                }
                if let Some((_, chunk)) = first {
                    fill_band(0, chunk);
                }
            });
        }
    }
}

/// Side, in lattice points, of the units of the lattice of `stride`.
fn unit_side(stride: u32) -> u32 {
    if stride >= SINGLE_RAY_STRIDE {
        SPARSE_UNIT_TILE
    } else {
        UNIT_TILE
    }
}

/// The bytes of the pixels `area` covers in a frame `width` pixels wide, as (start, length)
/// runs: a run per row at stride 1, a run per pixel otherwise (points a level skips are
/// included: the previous level traced them, so they hold exact values too).
fn byte_runs(area: &Area, width: u32, pixel_bytes: usize) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    for t in area.t0..area.t1 {
        if area.lattice.stride == 1 {
            let (x, y) = area.lattice.pixel(area.s0, t);
            let start = (y as usize * width as usize + x as usize) * pixel_bytes;
            runs.push((start, (area.s1 - area.s0) as usize * pixel_bytes));
            continue;
        }
        for s in area.s0..area.s1 {
            let (x, y) = area.lattice.pixel(s, t);
            runs.push((
                (y as usize * width as usize + x as usize) * pixel_bytes,
                pixel_bytes,
            ));
        }
    }
    runs
}

/// How fast budgeted renders of a frame traced, measured on the earlier ones.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Throughput {
    /// Traced pixels per second of one thread's tracing time, if measured.
    pub pixels_per_thread_second: Option<f64>,
    /// Seconds of the last render spent other than tracing (set-up, fill, finish).
    pub overhead_seconds: f64,
}

impl Throughput {
    /// Blends in a measurement: `pixels` traced in `thread_seconds` of tracing summed over
    /// the threads (the newest counts most: head motion changes the view).
    pub fn record(&mut self, pixels: usize, thread_seconds: f64) {
        if pixels < 256 || thread_seconds <= 0.0 {
            return;
        }
        let rate = pixels as f64 / thread_seconds;
        self.pixels_per_thread_second = Some(match self.pixels_per_thread_second {
            Some(old) => 0.5 * old + 0.5 * rate,
            None => rate,
        });
    }

    /// Records the seconds a render took after its tracing (fill, finish). A slower render
    /// counts at once, a faster one half: a loaded machine's spikes must not overrun the next
    /// renders' budgets.
    pub fn record_overhead(&mut self, seconds: f64) {
        self.overhead_seconds = seconds.max(0.5 * (self.overhead_seconds + seconds));
    }

    /// Pixels to trace within `tracing_seconds` on `threads` threads. Before any measurement
    /// the guess is from the scene's size: a primary ray through a BVH of n primitives costs
    /// about (60 + 8·log2 n) ns with the fast renderer, three times that with the default
    /// renderer (shading, shadows), on the development machine.
    pub fn pixels_for(
        &self,
        tracing_seconds: f64,
        primitives: usize,
        fast: bool,
        threads: usize,
    ) -> f64 {
        let rate = self.pixels_per_thread_second.unwrap_or_else(|| {
            let per_ray = (60.0 + 8.0 * ((primitives + 1) as f64).log2()) * 1e-9;
            if fast {
                1.0 / per_ray
            } else {
                1.0 / (3.0 * per_ray)
            }
        });
        // A margin for timing noise and the cost differences between levels.
        (PLANNED_SHARE * rate * threads.max(1) as f64 * tracing_seconds).max(0.0)
    }
}

/// Share of the tracing time the planned pixels fill; the deadline stops the rest.
const PLANNED_SHARE: f64 = 0.94;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Eye, StereoMode};

    #[test]
    fn units_cover_every_pixel_of_every_viewport_exactly_once() {
        for (width, height, mode) in [
            (37, 21, StereoMode::None),
            (100, 40, StereoMode::SideBySide),
            (64, 31, StereoMode::TopBottom),
        ] {
            let plan = Plan::new(&mode.viewports(width, height));
            let mut count = vec![0u32; (width * height) as usize];
            for unit in &plan.units {
                for t in unit.t0..unit.t1 {
                    for s in unit.s0..unit.s1 {
                        if unit.skips(s, t) {
                            continue;
                        }
                        let (x, y) = unit.lattice.pixel(s, t);
                        assert!(x < width && y < height, "{unit:?}");
                        count[(y * width + x) as usize] += 1;
                    }
                }
            }
            assert!(count.iter().all(|&c| c == 1), "{width}×{height} {mode:?}");
            assert_eq!(
                plan.traced_pixels(plan.units.len()),
                (width * height) as usize
            );
        }
    }

    #[test]
    fn fill_copies_only_from_traced_pixels_of_the_same_eye_for_every_prefix() {
        let viewports = StereoMode::SideBySide.viewports(90, 70);
        let plan = Plan::new(&viewports);
        // Per eye (45×70): one tile at strides 64 to 8, 1×2 at strides 4 (tiles of 16 lattice
        // points) and 2, 2×3 at stride 1.
        assert_eq!(plan.units.len(), 2 * (4 + 2 + 2 + 6));
        for done in plan.mandatory_units()..plan.units.len() {
            let mut traced = vec![false; 90 * 70];
            for unit in &plan.units[..done] {
                for t in unit.t0..unit.t1 {
                    for s in unit.s0..unit.s1 {
                        if unit.skips(s, t) {
                            continue;
                        }
                        let (x, y) = unit.lattice.pixel(s, t);
                        traced[(y * 90 + x) as usize] = true;
                    }
                }
            }
            // Traced pixels hold their own index, the others a marker.
            let mut pixels: Vec<u8> = (0..90 * 70u32)
                .flat_map(|k| if traced[k as usize] { k } else { u32::MAX }.to_ne_bytes())
                .collect();
            plan.fill(90, (0, done), 4, &mut pixels, 1);
            for (k, value) in pixels.chunks_exact(4).enumerate() {
                let source = u32::from_ne_bytes(value.try_into().unwrap()) as usize;
                assert!(source < 90 * 70 && traced[source], "pixel {k}, done {done}");
                if traced[k] {
                    assert_eq!(source, k);
                }
                // Same eye (side by side halves are 45 pixels wide), and near.
                assert_eq!(k % 90 < 45, source % 90 < 45, "pixel {k} from {source}");
                let (dx, dy) = (
                    (k % 90).abs_diff(source % 90),
                    (k / 90).abs_diff(source / 90),
                );
                let stride = LEVELS[plan.complete_levels(done) - 1] as usize;
                assert!(dx < stride && dy < stride, "pixel {k} from {source}");
            }
        }
    }

    #[test]
    fn channels_filled_in_bands_copy_the_nearest_lattice_pixel() {
        // Viewports above the size filled on one thread, so that three threads fill in bands.
        for (width, height, mode) in [
            (300, 230, StereoMode::None),
            (600, 230, StereoMode::SideBySide),
        ] {
            let plan = Plan::new(&mode.viewports(width, height));
            let (mandatory, stride_16) = (plan.mandatory_units(), plan.units_through_stride(16));
            for done in [mandatory, stride_16 - 1, stride_16, stride_16 + 3] {
                let mut traced = vec![false; (width * height) as usize];
                for unit in &plan.units[..done] {
                    for t in unit.t0..unit.t1 {
                        for s in unit.s0..unit.s1 {
                            let (x, y) = unit.lattice.pixel(s, t);
                            traced[(y * width + x) as usize] = true;
                        }
                    }
                }
                let stride = LEVELS[plan.complete_levels(done) - 1];
                let nearest = |p: u32, start: u32, extent: u32| {
                    let d = (p - start) % stride;
                    let upper = p - d + stride;
                    if d > stride / 2 && upper < start + extent {
                        upper
                    } else {
                        p - d
                    }
                };
                let pixels: Vec<u8> = (0..width * height)
                    .flat_map(|k| if traced[k as usize] { k } else { u32::MAX }.to_ne_bytes())
                    .collect();
                for threads in [1, 3] {
                    let mut filled = pixels.clone();
                    plan.fill(width, (0, done), 4, &mut filled, threads);
                    for (k, value) in filled.chunks_exact(4).enumerate() {
                        let source = u32::from_ne_bytes(value.try_into().unwrap());
                        let (x, y) = (k as u32 % width, k as u32 / width);
                        let v = plan
                            .viewports
                            .iter()
                            .find(|v| x >= v.x && x < v.x + v.width);
                        let v = v.unwrap();
                        let expected = if traced[k] {
                            k as u32
                        } else {
                            nearest(y, v.y, v.height) * width + nearest(x, v.x, v.width)
                        };
                        assert_eq!(
                            source, expected,
                            "{mode:?} done {done}, {threads} threads, pixel ({x}, {y})"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn each_eye_gets_the_same_pixel_positions() {
        let plan = Plan::new(&StereoMode::SideBySide.viewports(128, 16));
        let eyes: Vec<Eye> = plan.viewports.iter().map(|v| v.eye).collect();
        assert_eq!(eyes, vec![Eye::Left, Eye::Right]);
        // Units alternate between the eyes, at the same place relative to each viewport.
        for pair in plan.units.chunks(2) {
            let [left, right] = pair else { panic!() };
            assert_eq!(right.lattice.origin_x - left.lattice.origin_x, 64);
            assert_eq!(right.lattice.origin_y, left.lattice.origin_y);
            assert_eq!(
                (left.s0, left.t0, left.s1, left.t1),
                (right.s0, right.t0, right.s1, right.t1)
            );
        }
    }
}
