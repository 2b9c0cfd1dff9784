//! The colour fill of a budgeted render: an untraced pixel blends the traced corners of its
//! lattice cell (bilinear weights), leaving out the corners that show another surface than
//! the nearest corner (another object or instance id, or a jump in depth) so that silhouettes
//! stay sharp. The other channels keep the nearest traced pixel's values (values that exist in
//! the scene).

use super::PARALLEL_FILL_PIXELS;
use crate::camera::EyeViewport;

/// What tells surfaces apart at the traced pixels: the frame's channels, where requested.
#[derive(Clone, Copy, Default)]
pub struct SurfaceGuide<'a> {
    /// FLOAT32 distances from the eye, native-endian.
    pub depth: Option<&'a [u8]>,
    /// UINT32 object ids, native-endian.
    pub object_id: Option<&'a [u8]>,
    /// UINT32 instance ids, native-endian.
    pub instance_id: Option<&'a [u8]>,
}

/// Depths further apart than this fraction of the nearer one belong to different surfaces.
const DEPTH_JUMP: f32 = 0.3;

impl SurfaceGuide<'_> {
    fn value(bytes: Option<&[u8]>, pixel: usize) -> Option<[u8; 4]> {
        bytes?.get(4 * pixel..4 * pixel + 4)?.try_into().ok()
    }

    /// Whether traced pixels `a` and `b` show the same surface, as far as the guide tells.
    fn same_surface(&self, a: usize, b: usize) -> bool {
        let same = |ids: Option<&[u8]>| Self::value(ids, a) == Self::value(ids, b);
        if !same(self.object_id) || !same(self.instance_id) {
            return false;
        }
        match (Self::value(self.depth, a), Self::value(self.depth, b)) {
            (Some(a), Some(b)) => {
                let (a, b) = (f32::from_ne_bytes(a), f32::from_ne_bytes(b));
                // Equal covers two misses (infinite depth).
                a == b || (a - b).abs() <= DEPTH_JUMP * a.min(b)
            }
            _ => true,
        }
    }
}

/// How the colour channel stores a pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColorPixels {
    /// Four 8-bit values (sRGB or linear: blended as stored).
    Unorm8,
    /// Four FLOAT32 values.
    Float32,
}

/// Blends up to four pixels of a colour channel with integer weights.
trait Blend: Sized {
    const BYTES: usize;
    fn blend(corners: [&[u8]; 4], weights: [u32; 4], total: u32, out: &mut [u8]);

    /// Pixels `dx` = `first`, `first` + 1, … of row `dy` of a cell `stride` pixels wide whose
    /// four corners all count (bilinear weights), into `out` (one pixel after another).
    fn blend_run(corners: [&[u8]; 4], stride: u32, dy: u32, first: u32, out: &mut [u8]) {
        for (dx, pixel) in (first..).zip(out.chunks_exact_mut(Self::BYTES)) {
            let weights = bilinear(stride, dx, dy);
            Self::blend(corners, weights, stride * stride, pixel);
        }
    }
}

/// The bilinear weights of a cell's corners (lower left, lower right, upper left, upper
/// right) at `(dx, dy)` from its lower-left corner; they sum to `stride`².
#[inline(always)]
fn bilinear(stride: u32, dx: u32, dy: u32) -> [u32; 4] {
    let (wx, wy) = ([stride - dx, dx], [stride - dy, dy]);
    [wx[0] * wy[0], wx[1] * wy[0], wx[0] * wy[1], wx[1] * wy[1]]
}

struct Unorm8;
struct Float32;

impl Blend for Unorm8 {
    const BYTES: usize = 4;
    #[inline(always)]
    fn blend(corners: [&[u8]; 4], weights: [u32; 4], total: u32, out: &mut [u8]) {
        for (c, target) in out.iter_mut().enumerate() {
            let sum: u32 = corners
                .iter()
                .zip(weights)
                .map(|(corner, w)| w * u32::from(corner[c]))
                .sum();
            *target = ((sum + total / 2) / total) as u8;
        }
    }

    /// The same values as [`Unorm8::blend`] per pixel: along a row the weighted sum is
    /// `(stride − dx)·L + dx·R` with L and R the row's blends of the left and right corners,
    /// so it grows by `R − L` per pixel, and `stride`² (a power of two) divides by a shift.
    fn blend_run(corners: [&[u8]; 4], stride: u32, dy: u32, first: u32, out: &mut [u8]) {
        let total = stride * stride;
        if !total.is_power_of_two() {
            for (dx, pixel) in (first..).zip(out.chunks_exact_mut(4)) {
                Self::blend(corners, bilinear(stride, dx, dy), total, pixel);
            }
            return;
        }
        let shift = total.trailing_zeros();
        let [a, b, c, d] = corners;
        let (wy0, wy1) = ((stride - dy) as i32, dy as i32);
        let column = |low: &[u8], high: &[u8]| -> [i32; 4] {
            std::array::from_fn(|k| wy0 * i32::from(low[k]) + wy1 * i32::from(high[k]))
        };
        let (left, right) = (column(a, c), column(b, d));
        let step: [i32; 4] = std::array::from_fn(|k| right[k] - left[k]);
        let half = (total / 2) as i32;
        let sum: [i32; 4] = std::array::from_fn(|k| {
            (stride - first) as i32 * left[k] + first as i32 * right[k] + half
        });
        shifted_run(sum, step, shift, out);
    }
}

/// Writes `sum >> shift` (four lanes, each in 0..=255 after the shift) as one pixel of `out`
/// after another, adding `step` to `sum` between pixels. On x86-64 a pixel is a few SSE2
/// instructions (the plain loop took about 2 ns per pixel, most of a budgeted frame's fill).
#[inline(always)]
fn shifted_run(sum: [i32; 4], step: [i32; 4], shift: u32, out: &mut [u8]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{
            _mm_add_epi32, _mm_cvtsi32_si128, _mm_cvtsi128_si32, _mm_packs_epi32, _mm_packus_epi16,
            _mm_setr_epi32, _mm_sra_epi32,
        };
        // SAFETY: SSE2 is part of every x86-64 CPU (the baseline this crate is built for);
        // the intrinsics only compute on registers.
        unsafe {
            let step = _mm_setr_epi32(step[0], step[1], step[2], step[3]);
            let count = _mm_cvtsi32_si128(shift as i32);
            let mut sum = _mm_setr_epi32(sum[0], sum[1], sum[2], sum[3]);
            for pixel in out.chunks_exact_mut(4) {
                let lanes = _mm_sra_epi32(sum, count);
                let words = _mm_packs_epi32(lanes, lanes);
                let bytes = _mm_packus_epi16(words, words);
                pixel.copy_from_slice(&_mm_cvtsi128_si32(bytes).to_le_bytes());
                sum = _mm_add_epi32(sum, step);
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let mut sum = sum;
        for pixel in out.chunks_exact_mut(4) {
            for k in 0..4 {
                pixel[k] = (sum[k] >> shift) as u8;
                sum[k] += step[k];
            }
        }
    }
}

impl Blend for Float32 {
    const BYTES: usize = 16;
    #[inline(always)]
    fn blend(corners: [&[u8]; 4], weights: [u32; 4], total: u32, out: &mut [u8]) {
        for (c, target) in out.chunks_exact_mut(4).enumerate() {
            let sum: f32 = corners
                .iter()
                .zip(weights)
                .map(|(corner, w)| {
                    let at = 4 * c;
                    let value = [corner[at], corner[at + 1], corner[at + 2], corner[at + 3]];
                    w as f32 * f32::from_ne_bytes(value)
                })
                .sum();
            target.copy_from_slice(&(sum / total as f32).to_ne_bytes());
        }
    }
}

/// Fills viewport `v` of a colour channel (`bytes`, a frame `width` pixels wide) from its
/// lattice of `stride`, every lattice point traced; lattice points keep their values. Bands
/// of cell rows are filled on up to `threads` threads.
pub fn fill_viewport(
    v: &EyeViewport,
    width: u32,
    stride: u32,
    pixels: ColorPixels,
    bytes: &mut [u8],
    guide: &SurfaceGuide,
    threads: usize,
) {
    match pixels {
        ColorPixels::Unorm8 => fill::<Unorm8>(v, width, stride, bytes, guide, threads),
        ColorPixels::Float32 => fill::<Float32>(v, width, stride, bytes, guide, threads),
    }
}

/// A viewport's lattice of one stride: where it lies, and its points' values copied out
/// (bands read them while writing the rows between).
struct LatticeValues {
    v: EyeViewport,
    width: u32,
    stride: u32,
    columns: u32,
    rows: u32,
    values: Vec<u8>,
}

impl LatticeValues {
    fn of<B: Blend>(v: &EyeViewport, width: u32, stride: u32, bytes: &[u8]) -> LatticeValues {
        let columns = (v.width - 1) / stride + 1;
        let rows = (v.height - 1) / stride + 1;
        let mut values = Vec::with_capacity((columns * rows) as usize * B::BYTES);
        for j in 0..rows {
            for i in 0..columns {
                let at = Self::frame_index(v, width, stride, i, j) * B::BYTES;
                values.extend_from_slice(&bytes[at..at + B::BYTES]);
            }
        }
        LatticeValues {
            v: *v,
            width,
            stride,
            columns,
            rows,
            values,
        }
    }

    #[inline]
    fn frame_index(v: &EyeViewport, width: u32, stride: u32, i: u32, j: u32) -> usize {
        (v.y + j * stride) as usize * width as usize + (v.x + i * stride) as usize
    }

    /// Lattice point (i, j): its frame pixel index and its value.
    #[inline]
    fn point<B: Blend>(&self, i: u32, j: u32) -> (usize, &[u8]) {
        let at = (j * self.columns + i) as usize * B::BYTES;
        (
            Self::frame_index(&self.v, self.width, self.stride, i, j),
            &self.values[at..at + B::BYTES],
        )
    }
}

/// A cell corner: its frame pixel index and its value.
type Corner<'a> = (usize, &'a [u8]);

fn fill<B: Blend>(
    v: &EyeViewport,
    width: u32,
    stride: u32,
    bytes: &mut [u8],
    guide: &SurfaceGuide,
    threads: usize,
) {
    if v.width == 0 || v.height == 0 {
        return;
    }
    let lattice = LatticeValues::of::<B>(v, width, stride, bytes);
    let row_bytes = width as usize * B::BYTES;
    let rows = &mut bytes[v.y as usize * row_bytes..(v.y + v.height) as usize * row_bytes];
    let pixels = u64::from(v.width) * u64::from(v.height);
    let bands = if pixels < PARALLEL_FILL_PIXELS {
        1
    } else {
        threads.clamp(1, lattice.rows as usize)
    };
    // Whole cell rows per band, so that each band writes only its own rows.
    let band_rows = (lattice.rows as usize).div_ceil(bands) * stride as usize;
    let lattice = &lattice;
    std::thread::scope(|scope| {
        let mut chunks = rows.chunks_mut(band_rows * row_bytes).enumerate();
        let first = chunks.next();
        for (band, chunk) in chunks {
            let first_row = (band * band_rows) as u32;
            scope.spawn(move || fill_band::<B>(lattice, guide, first_row, chunk));
        }
        if let Some((_, chunk)) = first {
            fill_band::<B>(lattice, guide, 0, chunk);
        }
    });
}

/// Fills the viewport rows `first_row..` (from its bottom; a whole number of cell rows) held
/// by `rows`, whole frame rows from the viewport's first row `first_row`.
fn fill_band<B: Blend>(
    lattice: &LatticeValues,
    guide: &SurfaceGuide,
    first_row: u32,
    rows: &mut [u8],
) {
    let LatticeValues { v, stride, .. } = *lattice;
    let row_bytes = lattice.width as usize * B::BYTES;
    let band_height = (rows.len() / row_bytes) as u32;
    let (last_i, last_j) = (lattice.columns - 1, lattice.rows - 1);
    let mut out = [0u8; 16];
    for j in first_row / stride..(first_row + band_height).div_ceil(stride) {
        let j1 = (j + 1).min(last_j);
        // Per cell of the row: its corners, and whether they all show one surface.
        let cells: Vec<([Corner; 4], bool)> = (0..lattice.columns)
            .map(|i| {
                let i1 = (i + 1).min(last_i);
                let corners = [
                    lattice.point::<B>(i, j),
                    lattice.point::<B>(i1, j),
                    lattice.point::<B>(i, j1),
                    lattice.point::<B>(i1, j1),
                ];
                let smooth = corners[1..]
                    .iter()
                    .all(|corner| guide.same_surface(corners[0].0, corner.0));
                (corners, smooth)
            })
            .collect();
        let y_end = ((j + 1) * stride).min(v.height);
        for y in j * stride..y_end {
            let dy = y - j * stride;
            let row_start = (y - first_row) as usize * row_bytes;
            let row = &mut rows[row_start..row_start + row_bytes];
            for (i, (corners, smooth)) in cells.iter().enumerate() {
                let x0 = v.x + i as u32 * stride;
                let x_end = (x0 + stride).min(v.x + v.width);
                // The lattice point itself keeps its value.
                let first = u32::from(dy == 0);
                let first_x = x0 + first;
                if first_x >= x_end {
                    continue;
                }
                let target = &mut row[first_x as usize * B::BYTES..x_end as usize * B::BYTES];
                let values = corners.map(|(_, value)| value);
                if *smooth {
                    B::blend_run(values, stride, dy, first, target);
                    continue;
                }
                let (i1, j1_differs) = (corners[1].0 != corners[0].0, j1 != j);
                for (dx, pixel) in (first..).zip(target.chunks_exact_mut(B::BYTES)) {
                    let mut weights = bilinear(stride, dx, dy);
                    // The nearest corner, as the nearest-pixel fill picks it.
                    let upper_x = 2 * dx > stride && i1;
                    let upper_y = 2 * dy > stride && j1_differs;
                    let nearest = corners[usize::from(upper_x) + 2 * usize::from(upper_y)].0;
                    for (weight, corner) in weights.iter_mut().zip(corners) {
                        if !guide.same_surface(nearest, corner.0) {
                            *weight = 0;
                        }
                    }
                    if weights.iter().all(|w| *w == 0) {
                        weights = corners.map(|c| u32::from(c.0 == nearest));
                    }
                    let total = weights.iter().sum();
                    let blended = &mut out[..B::BYTES];
                    B::blend(values, weights, total, blended);
                    pixel.copy_from_slice(blended);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::StereoMode;

    const WIDTH: u32 = 90;
    const HEIGHT: u32 = 70;

    /// A side-by-side frame's colours (one byte per channel, all four equal) with only the
    /// stride-16 lattice of each eye set, from `value(eye, x)`; 0 elsewhere.
    fn lattice_frame(value: impl Fn(usize, u32) -> u8) -> (Vec<EyeViewport>, Vec<u8>) {
        let viewports = StereoMode::SideBySide.viewports(WIDTH, HEIGHT).to_vec();
        let mut bytes = vec![0u8; (WIDTH * HEIGHT * 4) as usize];
        for (eye, v) in viewports.iter().enumerate() {
            for y in (v.y..v.y + v.height).step_by(16) {
                for x in (v.x..v.x + v.width).step_by(16) {
                    let at = ((y * WIDTH + x) * 4) as usize;
                    bytes[at..at + 4].fill(value(eye, x - v.x));
                }
            }
        }
        (viewports, bytes)
    }

    #[test]
    fn colour_is_bilinear_within_each_eye_and_never_crosses_a_surface() {
        // A gradient across the left eye, a flat right eye: the left eye's pixels between
        // lattice columns get the gradient's exact values, beyond the last column its value
        // there; the right eye's stay flat (nothing comes from the other eye).
        let (viewports, mut bytes) =
            lattice_frame(|eye, x| if eye == 0 { 10 + x as u8 } else { 200 });
        for v in &viewports {
            fill_viewport(
                v,
                WIDTH,
                16,
                ColorPixels::Unorm8,
                &mut bytes,
                &SurfaceGuide::default(),
                1,
            );
        }
        for y in 0..HEIGHT {
            for x in 0..WIDTH {
                let value = bytes[((y * WIDTH + x) * 4) as usize];
                let expected = if x < 45 { 10 + x.min(32) as u8 } else { 200 };
                assert_eq!(value, expected, "({x}, {y})");
            }
        }
        // Two objects in the left eye (columns below 20 and the rest): each pixel takes the
        // colour of its nearest traced pixel's object, never a blend of both.
        let object = |x: u32| if x < 20 { 1u32 } else { 2 };
        let ids: Vec<u8> = (0..WIDTH * HEIGHT)
            .flat_map(|k| object(k % WIDTH).to_ne_bytes())
            .collect();
        let guide = SurfaceGuide {
            object_id: Some(&ids),
            ..SurfaceGuide::default()
        };
        let (viewports, mut bytes) = lattice_frame(|_, x| if x < 20 { 50 } else { 150 });
        fill_viewport(
            &viewports[0],
            WIDTH,
            16,
            ColorPixels::Unorm8,
            &mut bytes,
            &guide,
            1,
        );
        for y in 0..HEIGHT {
            for x in 0..45 {
                let value = bytes[((y * WIDTH + x) * 4) as usize];
                // The nearest lattice column: 0, 16 or 32 (the lower one on ties).
                let nearest = (x + 7) / 16 * 16;
                let expected = if object(nearest) == 1 { 50 } else { 150 };
                assert_eq!(value, expected, "({x}, {y})");
            }
        }
    }

    /// The fill as defined, pixel by pixel: bilinear weights over the cell's corners, leaving
    /// out those of another surface than the nearest corner's.
    fn reference_fill(
        v: &EyeViewport,
        width: u32,
        stride: u32,
        bytes: &mut [u8],
        guide: &SurfaceGuide,
    ) {
        let w = width as usize;
        let last_x = v.x + (v.width - 1) / stride * stride;
        let last_y = v.y + (v.height - 1) / stride * stride;
        let source = bytes.to_vec();
        let value = |k: usize| &source[4 * k..4 * k + 4];
        for y in v.y..v.y + v.height {
            for x in v.x..v.x + v.width {
                let (x0, y0) = (x - (x - v.x) % stride, y - (y - v.y) % stride);
                let (dx, dy) = (x - x0, y - y0);
                if dx == 0 && dy == 0 {
                    continue;
                }
                let x1 = if x0 < last_x { x0 + stride } else { x0 };
                let y1 = if y0 < last_y { y0 + stride } else { y0 };
                let index = |x: u32, y: u32| y as usize * w + x as usize;
                let corners = [index(x0, y0), index(x1, y0), index(x0, y1), index(x1, y1)];
                let upper_x = 2 * dx > stride && x1 != x0;
                let upper_y = 2 * dy > stride && y1 != y0;
                let nearest = corners[usize::from(upper_x) + 2 * usize::from(upper_y)];
                let mut weights = bilinear(stride, dx, dy);
                for (weight, &corner) in weights.iter_mut().zip(&corners) {
                    if !guide.same_surface(nearest, corner) {
                        *weight = 0;
                    }
                }
                if weights.iter().all(|w| *w == 0) {
                    weights = corners.map(|c| u32::from(c == nearest));
                }
                let total = weights.iter().sum();
                let at = index(x, y) * 4;
                Unorm8::blend(corners.map(value), weights, total, &mut bytes[at..at + 4]);
            }
        }
    }

    #[test]
    fn rows_blended_at_once_and_in_bands_equal_the_pixel_by_pixel_fill() {
        // A frame large enough to be filled in bands, with pseudo-random lattice colours and
        // two objects, so that both smooth cells and silhouettes occur.
        let (width, height) = (330u32, 260u32);
        let mut state = 7u32;
        let mut random = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        };
        let bytes: Vec<u8> = (0..width * height * 4).map(|_| random() as u8).collect();
        let ids: Vec<u8> = (0..width * height)
            .flat_map(|k| u32::from((k % width) * (k / width) % 97 < 30).to_ne_bytes())
            .collect();
        for guide in [
            SurfaceGuide::default(),
            SurfaceGuide {
                object_id: Some(&ids),
                ..SurfaceGuide::default()
            },
        ] {
            for (mode, stride) in [
                (StereoMode::None, 64),
                (StereoMode::None, 16),
                (StereoMode::SideBySide, 8),
                (StereoMode::TopBottom, 2),
            ] {
                let mut expected = bytes.clone();
                for v in mode.viewports(width, height) {
                    reference_fill(&v, width, stride, &mut expected, &guide);
                }
                for threads in [1, 3] {
                    let mut filled = bytes.clone();
                    for v in mode.viewports(width, height) {
                        let pixels = ColorPixels::Unorm8;
                        fill_viewport(&v, width, stride, pixels, &mut filled, &guide, threads);
                    }
                    let first_difference = (0..filled.len()).find(|&i| filled[i] != expected[i]);
                    assert_eq!(
                        first_difference,
                        None,
                        "{mode:?}, stride {stride}, {threads} threads, ids {}",
                        guide.object_id.is_some()
                    );
                }
            }
        }
    }
}
