//! The colour fill of a budgeted render: an untraced pixel blends the traced corners of its
//! lattice cell (bilinear weights), leaving out the corners that show another surface than
//! the nearest corner (another object or instance id, or a jump in depth) so that silhouettes
//! stay sharp. The other channels keep the nearest traced pixel's values (values that exist in
//! the scene).

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
    fn blend(bytes: &[u8], corners: &[usize; 4], weights: [u32; 4], total: u32, out: &mut [u8]);
}

struct Unorm8;
struct Float32;

impl Blend for Unorm8 {
    const BYTES: usize = 4;
    #[inline(always)]
    fn blend(bytes: &[u8], corners: &[usize; 4], weights: [u32; 4], total: u32, out: &mut [u8]) {
        for (c, target) in out.iter_mut().enumerate() {
            let sum: u32 = corners
                .iter()
                .zip(weights)
                .map(|(corner, w)| w * u32::from(bytes[4 * corner + c]))
                .sum();
            *target = ((sum + total / 2) / total) as u8;
        }
    }
}

impl Blend for Float32 {
    const BYTES: usize = 16;
    #[inline(always)]
    fn blend(bytes: &[u8], corners: &[usize; 4], weights: [u32; 4], total: u32, out: &mut [u8]) {
        for (c, target) in out.chunks_exact_mut(4).enumerate() {
            let sum: f32 = corners
                .iter()
                .zip(weights)
                .map(|(corner, w)| {
                    let at = 16 * corner + 4 * c;
                    let value = [bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]];
                    w as f32 * f32::from_ne_bytes(value)
                })
                .sum();
            target.copy_from_slice(&(sum / total as f32).to_ne_bytes());
        }
    }
}

/// Fills viewport `v` of a colour channel (`bytes`, a frame `width` pixels wide) from its
/// lattice of `stride`, every lattice point traced; lattice points keep their values.
pub fn fill_viewport(
    v: &EyeViewport,
    width: u32,
    stride: u32,
    pixels: ColorPixels,
    bytes: &mut [u8],
    guide: &SurfaceGuide,
) {
    match pixels {
        ColorPixels::Unorm8 => fill::<Unorm8>(v, width, stride, bytes, guide),
        ColorPixels::Float32 => fill::<Float32>(v, width, stride, bytes, guide),
    }
}

fn fill<B: Blend>(
    v: &EyeViewport,
    width: u32,
    stride: u32,
    bytes: &mut [u8],
    guide: &SurfaceGuide,
) {
    let w = width as usize;
    let (x_end, y_end) = (v.x + v.width, v.y + v.height);
    // The last lattice column and row: pixels beyond them have no upper corner.
    let last_x = v.x + (v.width - 1) / stride * stride;
    let last_y = v.y + (v.height - 1) / stride * stride;
    let mut out = [0u8; 16];
    for y0 in (v.y..y_end).step_by(stride as usize) {
        let y1 = if y0 < last_y { y0 + stride } else { y0 };
        for x0 in (v.x..x_end).step_by(stride as usize) {
            let x1 = if x0 < last_x { x0 + stride } else { x0 };
            let index = |x: u32, y: u32| y as usize * w + x as usize;
            let corners = [index(x0, y0), index(x1, y0), index(x0, y1), index(x1, y1)];
            let smooth = corners[1..]
                .iter()
                .all(|&corner| guide.same_surface(corners[0], corner));
            for y in y0..(y0 + stride).min(y_end) {
                let dy = y - y0;
                for x in x0..(x0 + stride).min(x_end) {
                    let dx = x - x0;
                    if dx == 0 && dy == 0 {
                        continue;
                    }
                    let (wx, wy) = ([stride - dx, dx], [stride - dy, dy]);
                    let mut weights = [wx[0] * wy[0], wx[1] * wy[0], wx[0] * wy[1], wx[1] * wy[1]];
                    if !smooth {
                        // The nearest corner, as the nearest-pixel fill picks it.
                        let upper_x = 2 * dx > stride && x1 != x0;
                        let upper_y = 2 * dy > stride && y1 != y0;
                        let nearest = corners[usize::from(upper_x) + 2 * usize::from(upper_y)];
                        for (weight, &corner) in weights.iter_mut().zip(&corners) {
                            if !guide.same_surface(nearest, corner) {
                                *weight = 0;
                            }
                        }
                        if weights.iter().all(|w| *w == 0) {
                            weights = corners.map(|c| u32::from(c == nearest));
                        }
                    }
                    let total = weights.iter().sum();
                    let pixel = &mut out[..B::BYTES];
                    B::blend(bytes, &corners, weights, total, pixel);
                    let at = index(x, y) * B::BYTES;
                    if let Some(target) = bytes.get_mut(at..at + B::BYTES) {
                        target.copy_from_slice(pixel);
                    }
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
}
