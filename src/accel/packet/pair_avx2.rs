//! The triangle test of [`super::group_packet`] for two packets of four at once with AVX2: the
//! eight rays of two neighbouring groups of a frustum packet in one vector, each triangle's
//! coordinates broadcast from the group once for both. Lane by lane the operations of
//! `triangle_packet`, in the same order (no fused multiply-add), so every ray gets the same
//! `t`, barycentrics and normal, and triangles are taken in the same (slot) order per ray.

use super::{RayPacket, triangle_on_edges};
use crate::accel::lanes8::{half, joined, lane_mask, select};
use crate::accel::primitives::TriangleGroup;
use std::arch::x86_64::*;

/// What a test updates per ray, held in registers over a leaf and written back after it.
struct Records {
    t_max: __m256,
    uv: [__m256; 2],
    normal: [__m256; 3],
}

impl Records {
    #[target_feature(enable = "avx2")]
    #[inline]
    fn load(packets: &[RayPacket; 2]) -> Records {
        let [a, b] = packets;
        Records {
            t_max: joined(a.t_max, b.t_max),
            uv: [0, 1].map(|i| joined(a.hit_uv[i], b.hit_uv[i])),
            normal: [0, 1, 2].map(|i| joined(a.hit_normal[i], b.hit_normal[i])),
        }
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    fn store(&self, packets: &mut [RayPacket; 2]) {
        // Field by field (arrays built first are copied with wide loads of narrow stores).
        for (h, packet) in packets.iter_mut().enumerate() {
            packet.t_max = half(self.t_max, h);
            for (uv, lanes) in packet.hit_uv.iter_mut().zip(self.uv) {
                *uv = half(lanes, h);
            }
            for (normal, lanes) in packet.hit_normal.iter_mut().zip(self.normal) {
                *normal = half(lanes, h);
            }
        }
    }
}

/// Tests the triangles of `group` in `triangles` (bit per lane), in lane order, against the
/// `lanes` of two packets that share their shear axes, calling `hit(lane, rays)` with the rays
/// of each packet that hit each triangle.
#[target_feature(enable = "avx2")]
#[inline]
pub(crate) fn group_pair(
    group: &TriangleGroup,
    triangles: u32,
    packets: &mut [RayPacket; 2],
    lanes: [u32; 2],
    mut hit: impl FnMut(usize, [u32; 2]),
) {
    debug_assert_eq!(packets[0].shear_axes, packets[1].shear_axes);
    let [kx, ky, kz] = packets[0].shear_axes;
    let [a, b] = &*packets;
    let shear = [0, 1, 2].map(|i| joined(a.shear[i], b.shear[i]));
    let origin = [0, 1, 2].map(|i| joined(a.permuted_origin[i], b.permuted_origin[i]));
    let t_min = joined(a.t_min, b.t_min);
    let lanes8 = lanes[0] | (lanes[1] << 4);
    let mut records = Records::load(packets);
    let mut changed = false;
    let zero = _mm256_setzero_ps();
    let one = _mm256_set1_ps(1.0);
    for triangle in 0..4 {
        if triangles & (1 << triangle) == 0 {
            continue;
        }
        let vertex = |i: usize| {
            let coordinate = |axis: usize| _mm256_set1_ps(group.vertices[i][axis][triangle]);
            let z = _mm256_sub_ps(coordinate(kz), origin[2]);
            let x = _mm256_sub_ps(
                _mm256_sub_ps(coordinate(kx), origin[0]),
                _mm256_mul_ps(shear[0], z),
            );
            let y = _mm256_sub_ps(
                _mm256_sub_ps(coordinate(ky), origin[1]),
                _mm256_mul_ps(shear[1], z),
            );
            (x, y, z)
        };
        let (x0, y0, z0) = vertex(0);
        let (x1, y1, z1) = vertex(1);
        let (x2, y2, z2) = vertex(2);
        let u = _mm256_sub_ps(_mm256_mul_ps(x2, y1), _mm256_mul_ps(y2, x1));
        let v = _mm256_sub_ps(_mm256_mul_ps(x0, y2), _mm256_mul_ps(y0, x2));
        let w = _mm256_sub_ps(_mm256_mul_ps(x1, y0), _mm256_mul_ps(y1, x0));
        let is_zero = |value| _mm256_cmp_ps::<_CMP_EQ_OQ>(value, zero);
        let on_edge = _mm256_movemask_ps(_mm256_or_ps(
            _mm256_or_ps(is_zero(u), is_zero(v)),
            is_zero(w),
        )) as u32
            & lanes8;
        let (sign_u, sign_v, sign_w) = (
            _mm256_movemask_ps(u) as u32,
            _mm256_movemask_ps(v) as u32,
            _mm256_movemask_ps(w) as u32,
        );
        let candidates = !((sign_u ^ sign_v) | (sign_u ^ sign_w)) & lanes8 & !on_edge;
        let mut hits = 0;
        if candidates != 0 {
            let determinant = _mm256_add_ps(_mm256_add_ps(u, v), w);
            let shear_z = shear[2];
            let scaled_t = _mm256_add_ps(
                _mm256_add_ps(
                    _mm256_mul_ps(u, _mm256_mul_ps(z0, shear_z)),
                    _mm256_mul_ps(v, _mm256_mul_ps(z1, shear_z)),
                ),
                _mm256_mul_ps(w, _mm256_mul_ps(z2, shear_z)),
            );
            let t = _mm256_div_ps(scaled_t, determinant);
            let accepted = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GE_OQ>(t, t_min),
                _mm256_cmp_ps::<_CMP_LE_OQ>(t, records.t_max),
            );
            hits = _mm256_movemask_ps(accepted) as u32 & candidates;
            if hits != 0 {
                changed = true;
                let mask = lane_mask(hits);
                records.t_max = select(mask, t, records.t_max);
                let inverse = _mm256_div_ps(one, determinant);
                records.uv[0] = select(mask, _mm256_mul_ps(v, inverse), records.uv[0]);
                records.uv[1] = select(mask, _mm256_mul_ps(w, inverse), records.uv[1]);
                let normal = group.triangle(triangle).normal();
                for axis in 0..3 {
                    records.normal[axis] =
                        select(mask, _mm256_set1_ps(normal[axis]), records.normal[axis]);
                }
            }
        }
        if on_edge != 0 {
            // The single-ray path per ray, on the packets themselves.
            records.store(packets);
            for (packet, (half, on_edge)) in packets
                .iter_mut()
                .zip([on_edge & 0xf, on_edge >> 4].into_iter().enumerate())
            {
                if on_edge != 0 {
                    hits |= triangle_on_edges(group, triangle, packet, on_edge) << (4 * half);
                }
            }
            records = Records::load(packets);
        }
        hit(triangle, [hits & 0xf, hits >> 4]);
    }
    if changed {
        records.store(packets);
    }
}
