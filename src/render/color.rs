//! Colour encoding for frame channels.

/// sRGB transfer function: linear [0,1] → encoded [0,1].
pub fn linear_to_srgb(linear: f32) -> f32 {
    let c = linear.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// Quantises [0,1] to a byte, rounding to nearest.
pub fn to_unorm8(value: f32) -> u8 {
    (value.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// Quantises [−1,1] to a signed 16-bit fixed-point value (FIXED16: v·32767, rounding to
/// nearest), as for normals.
pub fn to_snorm16(value: f32) -> i16 {
    let v = if value.is_nan() { 0.0 } else { value };
    (v.clamp(-1.0, 1.0) * 32767.0).round() as i16
}

/// Steps of the linear → sRGB byte table: fine enough that every table entry rounds like the
/// exact formula except within 1/2¹⁶ of a byte boundary.
const SRGB_TABLE_STEPS: usize = 1 << 16;

/// Slots of the table: a power of two above [`SRGB_TABLE_STEPS`], so that an index masked
/// with `SRGB_TABLE_SLOTS - 1` is in bounds without a check (indices of clamped values are at
/// most `SRGB_TABLE_STEPS`, which the mask leaves alone; the slots past it are never read).
const SRGB_TABLE_SLOTS: usize = 2 * SRGB_TABLE_STEPS;

fn srgb_table() -> &'static [u8; SRGB_TABLE_SLOTS] {
    static TABLE: std::sync::OnceLock<Box<[u8; SRGB_TABLE_SLOTS]>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let mut table: Box<[u8; SRGB_TABLE_SLOTS]> = vec![u8::MAX; SRGB_TABLE_SLOTS]
            .into_boxed_slice()
            .try_into()
            .expect("a slice of SRGB_TABLE_SLOTS bytes");
        for (i, slot) in table[..=SRGB_TABLE_STEPS].iter_mut().enumerate() {
            *slot = to_unorm8(linear_to_srgb(i as f32 / SRGB_TABLE_STEPS as f32));
        }
        table
    })
}

/// Table slot `index` (at most [`SRGB_TABLE_STEPS`]) of `table`.
#[inline(always)]
fn slot(table: &[u8; SRGB_TABLE_SLOTS], index: usize) -> u8 {
    table[index & (SRGB_TABLE_SLOTS - 1)]
}

/// Linear [0,1] → sRGB byte. A table lookup: this runs for every pixel of every frame, and
/// `powf` per channel cost a sizeable share of a frame.
pub fn encode_srgb8(linear: f32) -> u8 {
    srgb8_encoder()(linear)
}

/// [`encode_srgb8`] with the table looked up once, for loops over many pixels.
pub fn srgb8_encoder() -> impl Fn(f32) -> u8 + Copy {
    let table = srgb_table();
    move |linear: f32| {
        slot(
            table,
            (linear.clamp(0.0, 1.0) * SRGB_TABLE_STEPS as f32 + 0.5) as usize,
        )
    }
}

/// A linear RGBA colour → sRGB bytes of R, G, B and a linear alpha byte: what
/// [`srgb8_encoder`] and [`to_unorm8`] give channel by channel (NaN → 0 as there), with the
/// clamping and scaling done on the four channels at once.
pub fn srgb8_rgba_encoder() -> impl Fn(glam::Vec4) -> [u8; 4] + Copy {
    let table = srgb_table();
    let scale = glam::Vec4::new(
        SRGB_TABLE_STEPS as f32,
        SRGB_TABLE_STEPS as f32,
        SRGB_TABLE_STEPS as f32,
        255.0,
    );
    move |linear: glam::Vec4| {
        // max(NaN, 0) is 0, as `NaN.clamp(0, 1) as usize` is.
        let clamped = linear.max(glam::Vec4::ZERO).min(glam::Vec4::ONE);
        let index = truncate4(clamped * scale + glam::Vec4::splat(0.5));
        [
            slot(table, index[0] as u32 as usize),
            slot(table, index[1] as u32 as usize),
            slot(table, index[2] as u32 as usize),
            index[3] as u8,
        ]
    }
}

/// Four non-negative values below 2³¹ truncated to integers, as `as` truncates them. One SSE2
/// instruction on x86-64: `as` saturates and maps NaN to 0 lane by lane, which cost a sixth of
/// the time a fast frame spends after tracing.
#[inline(always)]
fn truncate4(values: glam::Vec4) -> [i32; 4] {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__m128, _mm_cvtsi128_si32, _mm_cvttps_epi32, _mm_shuffle_epi32};
        // SAFETY: SSE2 is part of every x86-64 CPU (the baseline this crate is built for);
        // the intrinsics only compute on registers.
        unsafe {
            let truncated = _mm_cvttps_epi32(__m128::from(values));
            [
                _mm_cvtsi128_si32(truncated),
                _mm_cvtsi128_si32(_mm_shuffle_epi32::<1>(truncated)),
                _mm_cvtsi128_si32(_mm_shuffle_epi32::<2>(truncated)),
                _mm_cvtsi128_si32(_mm_shuffle_epi32::<3>(truncated)),
            ]
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        values.as_ivec4().to_array()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::array::srgb_to_linear;

    #[test]
    fn known_values_encode_to_the_right_bytes() {
        assert_eq!(encode_srgb8(0.0), 0);
        assert_eq!(encode_srgb8(1.0), 255);
        // 0.5 linear is 0.7354 encoded → 188.
        assert_eq!(encode_srgb8(0.5), 188);
        // 0.2140 linear encodes to 0.49995 → 127.49 → 127; 0.2159 encodes to 128/255.
        assert_eq!(encode_srgb8(0.214), 127);
        assert_eq!(encode_srgb8(0.2159), 128);
        // The linear segment: 0.002 × 12.92 × 255 = 6.59 → 7.
        assert_eq!(encode_srgb8(0.002), 7);
        assert_eq!(to_unorm8(0.5), 128);
        assert_eq!(encode_srgb8(-1.0), 0);
        assert_eq!(encode_srgb8(7.0), 255);
    }

    #[test]
    fn the_four_channel_encoder_encodes_each_channel_as_the_single_ones() {
        let rgba = srgb8_rgba_encoder();
        let srgb = srgb8_encoder();
        let mut values = vec![f32::NAN, -0.0, -1.0, 2.0, f32::INFINITY, f32::NEG_INFINITY];
        values.extend((0..=70_000).map(|i| i as f32 / 65_536.0));
        for (i, &v) in values.iter().enumerate() {
            let w = values[(i * 7919) % values.len()];
            let bytes = rgba(glam::Vec4::new(v, w, 0.25 * v, w));
            assert_eq!(
                bytes,
                [srgb(v), srgb(w), srgb(0.25 * v), to_unorm8(w)],
                "{v} {w}"
            );
        }
    }

    #[test]
    fn signed_fixed16_covers_minus_one_to_one() {
        assert_eq!(to_snorm16(1.0), 32767);
        assert_eq!(to_snorm16(-1.0), -32767);
        assert_eq!(to_snorm16(0.0), 0);
        assert_eq!(to_snorm16(0.5), 16384);
        assert_eq!(to_snorm16(-0.25), -8192);
        assert_eq!(to_snorm16(3.0), 32767);
        assert_eq!(to_snorm16(f32::NAN), 0);
    }

    #[test]
    fn the_table_agrees_with_the_formula_almost_everywhere() {
        let mut off_by_one = 0;
        for i in 0..=100_000 {
            let v = i as f32 / 100_000.0;
            let exact = to_unorm8(linear_to_srgb(v)) as i32;
            let table = encode_srgb8(v) as i32;
            assert!((exact - table).abs() <= 1, "{v}: {exact} vs {table}");
            off_by_one += (exact != table) as u32;
        }
        assert!(off_by_one < 100, "{off_by_one}");
    }

    #[test]
    fn round_trip() {
        for i in 0..=100 {
            let v = i as f32 / 100.0;
            assert!((srgb_to_linear(linear_to_srgb(v)) - v).abs() < 1e-5);
        }
    }
}
