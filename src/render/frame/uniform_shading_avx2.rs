//! The shading of a block whose hits all lie on one uniform surface, with AVX2 (also compiled
//! for AVX-512; chosen at run time, `crate::isa`): shading normals and colours eight lanes per
//! vector, lit along the rays or, for a stereo eye under cyclopean lighting, along each lane's
//! view from its cyclopean point (the views as [`super::cyclopean_views`] computes them four
//! lanes per vector, kept in registers). The scalar operations in the same order and no fused
//! multiply-adds, so every lane is bit for bit the lane-by-lane shading.

use crate::camera::BLOCK_RAYS;

use super::cyclopean_views::{Lanes3, ViewPoints};

/// The views and shading of a block eight lanes per vector.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{Lanes3, ViewPoints};
    use crate::camera::BLOCK_RAYS;
    use std::arch::x86_64::*;

    /// Lanes `first..first + 8` of `values`.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn load(values: &[f32; BLOCK_RAYS], first: usize) -> __m256 {
        let lanes: &[f32; 8] = values[first..first + 8].try_into().expect("eight lanes");
        // SAFETY: `lanes` holds eight floats; the load is unaligned.
        unsafe { _mm256_loadu_ps(lanes.as_ptr()) }
    }

    /// Lanes `first..first + 8` of `lanes` set to `values`.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn store(lanes: &mut [f32; BLOCK_RAYS], first: usize, values: __m256) {
        let lanes: &mut [f32; 8] = (&mut lanes[first..first + 8])
            .try_into()
            .expect("eight lanes");
        // SAFETY: `lanes` holds eight floats; the store is unaligned.
        unsafe { _mm256_storeu_ps(lanes.as_mut_ptr(), values) };
    }

    /// `(a·b)` of three lane vectors, summed as glam's `Vec3::dot`: `(x + y) + z`.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn dot(a: &[__m256; 3], b: &[__m256; 3]) -> __m256 {
        let xy = _mm256_add_ps(_mm256_mul_ps(a[0], b[0]), _mm256_mul_ps(a[1], b[1]));
        _mm256_add_ps(xy, _mm256_mul_ps(a[2], b[2]))
    }

    /// Lanes `first..first + 8` of the views (see [`cyclopean_views_into`]) of rays from
    /// `origin` along `along` to `t`, seen from `viewer`.
    ///
    /// [`cyclopean_views_into`]: super::super::cyclopean_views::cyclopean_views_into
    #[target_feature(enable = "avx2")]
    #[inline]
    fn views(
        origin: [__m256; 3],
        along: &[__m256; 3],
        t: __m256,
        viewer: [__m256; 3],
    ) -> [__m256; 3] {
        let offset = [0, 1, 2].map(|axis| {
            let point = _mm256_add_ps(origin[axis], _mm256_mul_ps(along[axis], t));
            _mm256_sub_ps(point, viewer[axis])
        });
        let scale = _mm256_div_ps(_mm256_set1_ps(1.0), _mm256_sqrt_ps(dot(&offset, &offset)));
        // Finite (|scale| below infinity, NaN failing) and positive, as glam asks.
        let magnitude = _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX));
        let finite = _mm256_cmp_ps::<_CMP_LT_OQ>(
            _mm256_and_ps(scale, magnitude),
            _mm256_set1_ps(f32::INFINITY),
        );
        let positive = _mm256_cmp_ps::<_CMP_GT_OQ>(scale, _mm256_setzero_ps());
        let normalizable = _mm256_and_ps(finite, positive);
        [0, 1, 2].map(|axis| {
            let normalized = _mm256_mul_ps(offset[axis], scale);
            _mm256_blendv_ps(along[axis], normalized, normalizable)
        })
    }

    /// Lanes `first..first + 8` of the shading normals and colours (see
    /// [`super::shade_uniform_avx2`]), seen along the rays or, with `points` (the rays'
    /// origins and the viewers), from the viewers.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn shade_eight(
        lanes: &super::ShadingLanes,
        first: usize,
        points: Option<([__m256; 3], [__m256; 3])>,
        (base, emissive): ([f32; 3], [f32; 3]),
        (normal_out, color_out): (&mut Lanes3, &mut Lanes3),
    ) {
        let sign = _mm256_set1_ps(-0.0);
        let along = [0, 1, 2].map(|axis| load(&lanes.direction[axis], first));
        let view = match points {
            Some((origin, viewer)) => views(origin, &along, load(lanes.t, first), viewer),
            None => along,
        };
        // The normal facing the ray: negated where it points along the ray.
        let normal = [0, 1, 2].map(|axis| load(&lanes.normal[axis], first));
        let back_face = _mm256_cmp_ps::<_CMP_GT_OQ>(dot(&normal, &along), _mm256_setzero_ps());
        let flip = _mm256_and_ps(back_face, sign);
        let normal = normal.map(|n| _mm256_xor_ps(n, flip));
        // Lit from the eye: base · (0.2 + 0.8 · max(−view · normal, 0)) + emission.
        let toward = view.map(|v| _mm256_xor_ps(v, sign));
        let facing = _mm256_max_ps(dot(&toward, &normal), _mm256_setzero_ps());
        let light = _mm256_add_ps(
            _mm256_set1_ps(0.2),
            _mm256_mul_ps(_mm256_set1_ps(0.8), facing),
        );
        for axis in 0..3 {
            let lit = _mm256_mul_ps(_mm256_set1_ps(base[axis]), light);
            let rgb = _mm256_add_ps(lit, _mm256_set1_ps(emissive[axis]));
            store(&mut normal_out[axis], first, normal[axis]);
            store(&mut color_out[axis], first, rgb);
        }
    }

    crate::isa::avx2_and_avx512! {
        /// [`super::shade_uniform_avx2`], compiled for the path.
        pub(super) fn [shade_into_avx2, shade_into_avx512](
            lanes: &super::ShadingLanes,
            surface: ([f32; 3], [f32; 3]),
            normal_out: &mut Lanes3,
            color_out: &mut Lanes3,
        ) {
            let out = (normal_out, color_out);
            match lanes.view_from {
                None => {
                    for first in (0..BLOCK_RAYS).step_by(8) {
                        shade_eight(lanes, first, None, surface, (&mut *out.0, &mut *out.1));
                    }
                }
                // A pinhole eye's block: its origin and cyclopean point in registers once.
                Some(ViewPoints::Shared { origin, viewer }) => {
                    let points = Some((
                        origin.map(|value| _mm256_set1_ps(value)),
                        viewer.map(|value| _mm256_set1_ps(value)),
                    ));
                    for first in (0..BLOCK_RAYS).step_by(8) {
                        shade_eight(lanes, first, points, surface, (&mut *out.0, &mut *out.1));
                    }
                }
                Some(ViewPoints::Lanes { origin, viewer }) => {
                    for first in (0..BLOCK_RAYS).step_by(8) {
                        let origin = [0, 1, 2].map(|axis| load(&origin[axis], first));
                        let viewer = [0, 1, 2].map(|axis| load(&viewer[axis], first));
                        let points = Some((origin, viewer));
                        shade_eight(lanes, first, points, surface, (&mut *out.0, &mut *out.1));
                    }
                }
            }
        }
    }
}

/// The lane arrays the shading of a block's hits on one uniform surface reads: the rays'
/// directions, the hits' ray parameters `t` and geometric normals, and, for a stereo eye
/// under cyclopean lighting, where the rays start and the views look from (else the views look
/// along the rays).
pub(super) struct ShadingLanes<'a> {
    pub view_from: Option<ViewPoints<'a>>,
    pub direction: &'a Lanes3,
    pub t: &'a [f32; BLOCK_RAYS],
    pub normal: &'a Lanes3,
}

/// With AVX2 or AVX-512 (`crate::isa`), per lane the shading normal (`UniformSurface::normal`)
/// and the colour (`UniformSurface::color` of base colour `base` and emission `emissive`) of a
/// block's hit, lit along its ray or its view from the cyclopean point, eight lanes per vector
/// without writing the views out: the same operations in the same order as lane by lane, bit
/// for bit. `false` (nothing written) on the baseline path.
#[inline(always)]
pub(super) fn shade_uniform_avx2(
    lanes: &ShadingLanes,
    (base, emissive): (glam::Vec3, glam::Vec3),
    normal: &mut Lanes3,
    color: &mut Lanes3,
) -> bool {
    #[cfg(target_arch = "x86_64")]
    use crate::isa::Isa;
    use crate::isa::selected;
    let surface = (base.to_array(), emissive.to_array());
    match selected() {
        // SAFETY: a path is selected only on a CPU that has it.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { avx2::shade_into_avx512(lanes, surface, normal, color) },
        // SAFETY: as above.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { avx2::shade_into_avx2(lanes, surface, normal, color) },
        _ => {
            let _ = (lanes, surface, normal, color);
            return false;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::lane_vec3;
    use crate::isa::Isa;
    use crate::render::eye_light::{UniformSurface, eye_light_of};
    use glam::Vec3;

    use super::super::cyclopean_views::tests::{hit_at, lanes, ray, settings, shared_lanes};

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn wide_shading_matches_the_per_lane_shading_bit_for_bit() {
        let paths = crate::isa::test_paths();
        if paths.len() == 1 {
            eprintln!("no AVX2 on this CPU: the AVX2 shading is not run");
        }
        for isa in &paths[1..] {
            let (origin, direction, t, viewer, _) = lanes();
            let points = ViewPoints::Lanes {
                origin: &origin,
                viewer: &viewer,
            };
            shade_and_compare(*isa, Some(points), (&origin, &direction, &t, &viewer));
            shade_and_compare(*isa, None, (&origin, &direction, &t, &viewer));
            let (origin, direction, t, [shared_origin, shared_viewer], _) = shared_lanes();
            let viewer = std::array::from_fn(|axis| [shared_viewer[axis]; BLOCK_RAYS]);
            let points = ViewPoints::Shared {
                origin: shared_origin,
                viewer: shared_viewer,
            };
            shade_and_compare(*isa, Some(points), (&origin, &direction, &t, &viewer));
        }
    }

    /// The shading of path `isa` (AVX2 or AVX-512, one this CPU has) of the rays and hits,
    /// seen from `view_from` (else along the rays), against lane by lane, where the rays'
    /// origins and viewers are the lane arrays given.
    fn shade_and_compare(
        isa: Isa,
        view_from: Option<ViewPoints>,
        (origin, direction, t, viewer): (&Lanes3, &Lanes3, &[f32; BLOCK_RAYS], &Lanes3),
    ) {
        let (origin, direction, t, viewer) = (*origin, *direction, *t, *viewer);
        // Geometric normals facing the ray or away from it, by lane; one lane perpendicular.
        let mut normal_in = [[0.0; BLOCK_RAYS]; 3];
        for lane in 0..BLOCK_RAYS {
            let along = lane_vec3(&direction, lane);
            let tilt = Vec3::new(0.3, -0.2, 0.1) * (lane % 5) as f32;
            let n = if lane % 3 == 0 {
                along + tilt
            } else {
                tilt - along
            };
            for (axis, lanes) in normal_in.iter_mut().enumerate() {
                lanes[lane] = n.normalize_or(Vec3::Z)[axis];
            }
        }
        let perpendicular = lane_vec3(&direction, 9).any_orthonormal_vector();
        for (axis, lanes) in normal_in.iter_mut().enumerate() {
            lanes[9] = perpendicular[axis];
        }
        let (base, emissive) = (Vec3::new(0.8, 0.3, 0.55), Vec3::new(0.01, 0.0, 0.2));
        let inputs = ShadingLanes {
            view_from,
            direction: &direction,
            t: &t,
            normal: &normal_in,
        };
        let (mut normal, mut color) = ([[0.0; BLOCK_RAYS]; 3], [[0.0; BLOCK_RAYS]; 3]);
        let lit = (base.to_array(), emissive.to_array());
        // SAFETY: this CPU has the path (`test_paths`).
        unsafe {
            match isa {
                Isa::Avx512 => avx2::shade_into_avx512(&inputs, lit, &mut normal, &mut color),
                _ => avx2::shade_into_avx2(&inputs, lit, &mut normal, &mut color),
            }
        };
        let mut back_faces = 0;
        for (lane, &t) in t.iter().enumerate() {
            let ray = ray(&origin, &direction, lane);
            let point = UniformSurface::point(&ray, &hit_at(t));
            let view = match view_from {
                Some(_) => settings().view_direction(&ray, point, Some(lane_vec3(&viewer, lane))),
                None => ray.direction,
            };
            let shading = UniformSurface::normal(lane_vec3(&normal_in, lane), ray.direction);
            let rgb = eye_light_of(view, shading, base, emissive);
            let bits = |v: Vec3| v.to_array().map(f32::to_bits);
            let (got_normal, got_color) = (lane_vec3(&normal, lane), lane_vec3(&color, lane));
            assert_eq!(
                bits(got_normal),
                bits(shading),
                "{isa:?} lane {lane}: normal {got_normal}"
            );
            assert_eq!(
                bits(got_color),
                bits(rgb),
                "{isa:?} lane {lane}: colour {got_color} vs {rgb}"
            );
            back_faces += usize::from(shading != lane_vec3(&normal_in, lane));
        }
        assert!(
            (10..BLOCK_RAYS - 10).contains(&back_faces),
            "{back_faces} back faces"
        );
    }
}
