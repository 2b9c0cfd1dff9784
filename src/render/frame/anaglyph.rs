//! Anaglyph compositing: both eyes' colours of a pixel mixed into one red-cyan colour.

use glam::Vec4;

use crate::camera::PixelSet;

use super::tile::PreparedEye;

/// Dubois' least-squares red-cyan anaglyph matrices (rows: output red, green, blue), applied to
/// linear RGB.
pub(super) const ANAGLYPH_LEFT: [[f32; 3]; 3] = [
    [0.437, 0.449, 0.164],
    [-0.062, -0.062, -0.024],
    [-0.048, -0.050, -0.017],
];
pub(super) const ANAGLYPH_RIGHT: [[f32; 3]; 3] = [
    [-0.011, -0.032, -0.007],
    [0.377, 0.761, 0.009],
    [-0.026, -0.093, 1.234],
];

/// One anaglyph colour from the two eyes' colours, clamped to [0, 1]; the left eye's alpha.
pub(super) fn anaglyph(left: Vec4, right: Vec4) -> Vec4 {
    let row = |k: usize| {
        let l = ANAGLYPH_LEFT[k];
        let r = ANAGLYPH_RIGHT[k];
        (l[0] * left.x
            + l[1] * left.y
            + l[2] * left.z
            + r[0] * right.x
            + r[1] * right.y
            + r[2] * right.z)
            .clamp(0.0, 1.0)
    };
    Vec4::new(row(0), row(1), row(2), left.w)
}

/// Both eyes of an anaglyph frame (each renders every pixel), as one-eye slices.
pub(super) fn anaglyph_eyes(eyes: &[PreparedEye]) -> Option<(&[PreparedEye], &[PreparedEye])> {
    match eyes {
        [(left, _), (right, _)]
            if left.pixels == PixelSet::Anaglyph && right.pixels == PixelSet::Anaglyph =>
        {
            Some((&eyes[..1], &eyes[1..]))
        }
        _ => None,
    }
}
