//! Per-sample positions: the sub-pixel offsets and depth-of-field lens points of a pixel's
//! samples, low-discrepancy so that samples and accumulated passes converge.

use glam::Vec2;

use crate::scene::light::radical_inverse;

/// A deterministic sub-pixel offset in [0,1)²: sample 0 of pass 0 is the pixel centre, the rest
/// follow a 2D Halton sequence so that accumulation converges.
pub(super) fn jitter(index: u32) -> Vec2 {
    if index == 0 {
        return Vec2::splat(0.5);
    }
    Vec2::new(radical_inverse(index, 2), radical_inverse(index, 3))
}

/// The depth-of-field lens sample for a sample index: a Halton sequence in bases 5 and 7, so it
/// is independent of the pixel offsets (bases 2 and 3).
pub(super) fn lens_sample(index: u32) -> Vec2 {
    Vec2::new(radical_inverse(index + 1, 5), radical_inverse(index + 1, 7))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_sample_is_the_pixel_centre_and_the_rest_stay_inside() {
        assert_eq!(jitter(0), Vec2::splat(0.5));
        assert_eq!(jitter(1), Vec2::new(0.5, 1.0 / 3.0));
        for i in 1..100 {
            let j = jitter(i);
            assert!(j.x > 0.0 && j.x < 1.0 && j.y > 0.0 && j.y < 1.0);
        }
    }
}
