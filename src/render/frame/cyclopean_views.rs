//! A stereo block's views from its eye's cyclopean point (cyclopean lighting), over lane
//! arrays: per lane [`RendererSettings::view_direction`] of the lane's hit, bit for bit, four
//! lanes per vector, with the scalar operations in the same order and no fused multiply-adds.
//! The AVX2 shading pass that computes these views in registers is
//! [`super::uniform_shading_avx2`].
//!
//! [`RendererSettings::view_direction`]: crate::render::renderer::RendererSettings::view_direction

use glam::Vec4;

use crate::camera::{BLOCK_RAYS, BlockCyclopean, BlockRays};

/// x, y and z lane arrays of a block.
pub(super) type Lanes3 = [[f32; BLOCK_RAYS]; 3];

/// Where a stereo block's rays start and its shading looks from (the cyclopean points).
#[derive(Clone, Copy)]
pub(super) enum ViewPoints<'a> {
    /// One origin and one cyclopean point for every lane (a pinhole eye's block): each is
    /// loaded once, not once per lane.
    Shared { origin: [f32; 3], viewer: [f32; 3] },
    /// Lane by lane (several viewers' blended heads).
    Lanes {
        origin: &'a Lanes3,
        viewer: &'a Lanes3,
    },
}

impl<'a> ViewPoints<'a> {
    /// The points of `block`'s rays, `None` for rays without cyclopean points.
    #[inline(always)]
    pub(super) fn of(block: &'a BlockRays) -> Option<ViewPoints<'a>> {
        match &block.cyclopean {
            BlockCyclopean::None => None,
            &BlockCyclopean::Shared(viewer) => Some(ViewPoints::Shared {
                origin: block.origin.map(|axis| axis[0]),
                viewer,
            }),
            BlockCyclopean::Lanes(viewer) => Some(ViewPoints::Lanes {
                origin: &block.origin,
                viewer,
            }),
        }
    }
}

/// Per lane, the view of the hit at ray parameter `t` seen from the cyclopean point `viewer`
/// (of `points`):
/// `(point − viewer).try_normalize()`, else the ray's direction (lanes without a hit get a
/// view that is not used). The hit point is `origin + direction · t` as
/// `UniformSurface::point` has it; glam's `try_normalize` is a length, its reciprocal and a
/// product, kept where the reciprocal is finite and positive. Written without its branch, which
/// keeps the compiler from vectorizing.
#[inline(always)]
pub(super) fn cyclopean_views_into(
    points: ViewPoints,
    direction: &Lanes3,
    t: &[f32; BLOCK_RAYS],
    views: &mut Lanes3,
) {
    for first in (0..BLOCK_RAYS).step_by(4) {
        let lanes = first..first + 4;
        let load = |values: &[f32; BLOCK_RAYS]| Vec4::from_slice(&values[lanes.clone()]);
        let t = load(t);
        let along = direction.each_ref().map(load);
        let (origin, viewer): ([Vec4; 3], [Vec4; 3]) = match points {
            ViewPoints::Shared { origin, viewer } => {
                (origin.map(Vec4::splat), viewer.map(Vec4::splat))
            }
            ViewPoints::Lanes { origin, viewer } => {
                (origin.each_ref().map(load), viewer.each_ref().map(load))
            }
        };
        let offset: [Vec4; 3] =
            std::array::from_fn(|axis| (origin[axis] + along[axis] * t) - viewer[axis]);
        let length_squared = offset[0] * offset[0] + offset[1] * offset[1] + offset[2] * offset[2];
        let scale = Vec4::ONE / length_squared.sqrt();
        let normalizable = scale.is_finite_mask() & scale.cmpgt(Vec4::ZERO);
        for axis in 0..3 {
            Vec4::select(normalizable, offset[axis] * scale, along[axis])
                .write_to_slice(&mut views[axis][lanes.clone()]);
        }
    }
}

/// The lanes here also test [`super::super::uniform_shading_avx2`].
#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::accel::{Ray, SceneHit};
    use crate::camera::lane_vec3;
    use crate::render::eye_light::UniformSurface;
    use crate::render::renderer::RendererSettings;
    use glam::{Vec2, Vec3};

    /// A hit at ray parameter `t` (only `t` places the hit point).
    pub(in crate::render::frame) fn hit_at(t: f32) -> SceneHit {
        SceneHit {
            t,
            instance: 0,
            geometry: 0,
            primitive: 0,
            uv: Vec2::ZERO,
            normal: Vec3::Z,
            object_normal: Vec3::Z,
        }
    }

    /// Ordinary lanes from a fixed pseudo-random sequence, and lanes where normalizing fails
    /// spread over every position of a vector of four and of eight: the hit point on the
    /// viewer, an offset whose square underflows to zero, one whose square overflows, NaN and
    /// huge hit points.
    pub(in crate::render::frame) fn lanes() -> (Lanes3, Lanes3, [f32; BLOCK_RAYS], Lanes3, usize) {
        let mut origin = [[0.0; BLOCK_RAYS]; 3];
        let mut direction = [[0.0; BLOCK_RAYS]; 3];
        let mut t = [0.0; BLOCK_RAYS];
        let mut viewer = [[0.0; BLOCK_RAYS]; 3];
        let mut state = 0x2545_f491_u32;
        let mut next = || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1 << 24) as f32 * 8.0 - 4.0
        };
        for lane in 0..BLOCK_RAYS {
            let along = Vec3::new(next(), next(), next()).normalize_or(Vec3::Z);
            for axis in 0..3 {
                origin[axis][lane] = next();
                direction[axis][lane] = along[axis];
                viewer[axis][lane] = next() * 0.1;
            }
            t[lane] = next().abs() * 3.0;
        }
        let hit_point = |origin: &Lanes3, direction: &Lanes3, lane| {
            lane_vec3(origin, lane) + lane_vec3(direction, lane) * t[lane]
        };
        let mut place_viewer = |lane: usize, offset: Vec3| {
            let point = hit_point(&origin, &direction, lane);
            for axis in 0..3 {
                viewer[axis][lane] = point[axis] - offset[axis];
            }
        };
        place_viewer(0, Vec3::ZERO);
        place_viewer(5, Vec3::new(1e-25, 0.0, 0.0));
        place_viewer(10, Vec3::new(0.0, -1e-25, 1e-25));
        place_viewer(15, Vec3::new(0.0, 0.0, 1e25));
        place_viewer(17, Vec3::new(-1e25, 1e25, 0.0));
        place_viewer(44, Vec3::new(0.0, 1e-30, 0.0));
        t[22] = f32::NAN;
        origin[1][27] = f32::NAN;
        for (axis, lanes) in origin.iter_mut().enumerate() {
            lanes[33] = 1e30 * (axis as f32 + 1.0);
        }
        (origin, direction, t, viewer, 9)
    }

    pub(in crate::render::frame) fn settings() -> RendererSettings {
        RendererSettings {
            cyclopean_lighting: true,
            ..RendererSettings::default()
        }
    }

    /// Lane `lane`'s ray.
    pub(in crate::render::frame) fn ray(origin: &Lanes3, direction: &Lanes3, lane: usize) -> Ray {
        Ray {
            origin: lane_vec3(origin, lane),
            direction: lane_vec3(direction, lane),
            t_min: 0.0,
            t_max: f32::INFINITY,
        }
    }

    /// A pinhole eye's block: [`lanes`]' directions from one origin seen from one cyclopean
    /// point, with lanes whose view cannot be normalized (hit points on the viewer, at a
    /// NaN or overflowing distance); the lane arrays, the shared points and how many lanes
    /// fall back.
    #[allow(clippy::type_complexity)]
    pub(in crate::render::frame) fn shared_lanes()
    -> (Lanes3, Lanes3, [f32; BLOCK_RAYS], [[f32; 3]; 2], usize) {
        let (_, direction, mut t, _, _) = lanes();
        let (origin, viewer) = ([0.4f32, 1.7, -0.2], [0.43f32, 1.7, -0.2]);
        let points = origin.map(|value| [value; BLOCK_RAYS]);
        let mut direction = direction;
        // Lane 7 hits the viewer itself: along +x by exactly the offset.
        for (axis, value) in [1.0, 0.0, 0.0].into_iter().enumerate() {
            direction[axis][7] = value;
        }
        t[7] = viewer[0] - origin[0];
        t[22] = f32::NAN;
        t[41] = 1e30;
        (points, direction, t, [origin, viewer], 3)
    }

    #[test]
    fn cyclopean_views_match_the_per_ray_view_direction_bit_for_bit() {
        let (origin, direction, t, viewer, special) = lanes();
        let points = ViewPoints::Lanes {
            origin: &origin,
            viewer: &viewer,
        };
        compare_views(points, (&origin, &direction, &t, &viewer), special);
        let (origin, direction, t, [shared_origin, shared_viewer], special) = shared_lanes();
        let viewer = std::array::from_fn(|axis| [shared_viewer[axis]; BLOCK_RAYS]);
        let points = ViewPoints::Shared {
            origin: shared_origin,
            viewer: shared_viewer,
        };
        compare_views(points, (&origin, &direction, &t, &viewer), special);
    }

    /// The views of `points` against the per-ray view of the rays and viewers as lane arrays;
    /// `special` lanes fall back to the ray's direction.
    fn compare_views(
        points: ViewPoints,
        (origin, direction, t, viewer): (&Lanes3, &Lanes3, &[f32; BLOCK_RAYS], &Lanes3),
        special: usize,
    ) {
        let mut views = [[0.0; BLOCK_RAYS]; 3];
        cyclopean_views_into(points, direction, t, &mut views);
        let mut fallbacks = 0;
        for (lane, &t) in t.iter().enumerate() {
            let ray = ray(origin, direction, lane);
            let point = UniformSurface::point(&ray, &hit_at(t));
            let expected = settings().view_direction(&ray, point, Some(lane_vec3(viewer, lane)));
            let got = lane_vec3(&views, lane);
            assert_eq!(
                got.to_array().map(f32::to_bits),
                expected.to_array().map(f32::to_bits),
                "lane {lane}: {got} vs {expected}"
            );
            fallbacks += usize::from(expected == ray.direction);
        }
        // The special lanes did take the fallback.
        assert_eq!(
            fallbacks, special,
            "{fallbacks} lanes fell back to the ray's direction"
        );
    }
}
