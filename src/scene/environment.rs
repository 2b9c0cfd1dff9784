//! The `hdri` light's environment map: an equirectangular radiance image around the scene,
//! sampled in proportion to its luminance (times each texel's solid angle), so that bright
//! regions such as a sun get most of the shadow rays.
//!
//! Layout (documented in the README): image column u ∈ [0, 1) is the azimuth φ = 2π(u − ½)
//! measured from `direction` towards `direction × up`; image row v ∈ [0, 1) (the array's first
//! row is v = 0) is the polar angle θ = πv from `up`. So the image's centre lies along
//! `direction` and its first row around `up`. Texels are piecewise constant. The map works in
//! its own frame, (x, y, z) = (`direction`, `up`, `direction × up`); the light turns that into
//! world directions, so an instance transform only changes the light's axes.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

/// Radiance per texel with the distribution that samples it.
#[derive(Debug, PartialEq)]
pub struct EnvironmentMap {
    width: usize,
    height: usize,
    /// Radiance (colour and scale included), row by row, first row at θ = 0.
    texels: Vec<Vec3>,
    /// Per row, the cumulative sums of that row's texel weights (the last is the row's total).
    row_cdf: Vec<f32>,
    /// The cumulative sums of the row totals (the last is the whole map's total).
    marginal_cdf: Vec<f32>,
}

/// One sampled direction (in the map's frame): where the light comes from and its radiance
/// over the sample's density per solid angle.
pub struct EnvironmentSample {
    pub direction: Vec3,
    pub radiance: Vec3,
}

impl EnvironmentMap {
    /// `texels` (`width`×`height`, first row around up); `None` when the image is empty or
    /// nothing emits.
    pub fn new(texels: Vec<Vec3>, width: usize, height: usize) -> Option<EnvironmentMap> {
        if width == 0 || height == 0 || texels.len() != width * height {
            return None;
        }
        let mut row_cdf = Vec::with_capacity(width * height);
        let mut marginal_cdf = Vec::with_capacity(height);
        let mut total = 0.0f32;
        for (row, texels) in texels.chunks_exact(width).enumerate() {
            let solid_angle = texel_solid_angle(row, width, height);
            let mut sum = 0.0f32;
            for texel in texels {
                let weight = luminance(*texel).max(0.0) * solid_angle;
                sum += if weight.is_finite() { weight } else { 0.0 };
                row_cdf.push(sum);
            }
            total += sum;
            marginal_cdf.push(total);
        }
        (total > 0.0).then_some(EnvironmentMap {
            width,
            height,
            texels,
            row_cdf,
            marginal_cdf,
        })
    }

    /// The radiance arriving from `direction` (unit, towards the light, in the map's frame).
    pub fn radiance(&self, direction: Vec3) -> Vec3 {
        let (column, row) = self.texel_of(direction);
        self.texels[row * self.width + column]
    }

    /// The density per solid angle with which [`EnvironmentMap::sample`] picks `direction`
    /// (unit, in the map's frame).
    pub fn pdf(&self, direction: Vec3) -> f32 {
        let (column, row) = self.texel_of(direction);
        let cdf = &self.row_cdf[row * self.width..(row + 1) * self.width];
        let weight = cdf[column] - if column == 0 { 0.0 } else { cdf[column - 1] };
        let total = self.marginal_cdf[self.height - 1];
        weight / (total * texel_solid_angle(row, self.width, self.height))
    }

    /// A direction for `u` in [0, 1)², chosen in proportion to luminance × solid angle: a
    /// texel by its weight, then a point of it uniform in solid angle (uniform in azimuth and
    /// in cos θ), so that radiance over density is the same anywhere in the texel.
    pub fn sample(&self, u: Vec2) -> Option<EnvironmentSample> {
        let total = *self.marginal_cdf.last()?;
        let row = pick(&self.marginal_cdf, u.y * total);
        let row_start = if row == 0 {
            0.0
        } else {
            self.marginal_cdf[row - 1]
        };
        let row_total = self.marginal_cdf[row] - row_start;
        let cdf = &self.row_cdf[row * self.width..(row + 1) * self.width];
        let row_sum = cdf[self.width - 1];
        let column = pick(cdf, u.x * row_sum);
        let column_start = if column == 0 { 0.0 } else { cdf[column - 1] };
        let weight = cdf[column] - column_start;
        if weight <= 0.0 || row_total <= 0.0 {
            return None;
        }
        // The rest of each coordinate places the point inside the texel.
        let within_row = ((u.y * total - row_start) / row_total).clamp(0.0, 1.0);
        let within_column = ((u.x * row_sum - column_start) / weight).clamp(0.0, 1.0);
        let (cos_top, cos_bottom) = row_cos_bounds(row, self.height);
        let cos_theta = cos_top - within_row * (cos_top - cos_bottom);
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let phi = 2.0 * PI * ((column as f32 + within_column) / self.width as f32 - 0.5);
        let direction = Vec3::new(sin_theta * phi.cos(), cos_theta, sin_theta * phi.sin());
        // Density per solid angle: the texel's probability over its solid angle.
        let solid_angle = texel_solid_angle(row, self.width, self.height);
        let radiance = self.texels[row * self.width + column];
        Some(EnvironmentSample {
            direction,
            radiance: radiance * (solid_angle * total / weight),
        })
    }

    /// The texel (column, row) a direction falls in.
    fn texel_of(&self, direction: Vec3) -> (usize, usize) {
        let theta = direction.y.clamp(-1.0, 1.0).acos();
        let phi = direction.z.atan2(direction.x);
        let s = phi / (2.0 * PI) + 0.5;
        let t = theta / PI;
        let column = ((s * self.width as f32) as usize).min(self.width - 1);
        let row = ((t * self.height as f32) as usize).min(self.height - 1);
        (column, row)
    }
}

/// cos θ at the top and the bottom edge of image row `row` of `height`.
fn row_cos_bounds(row: usize, height: usize) -> (f32, f32) {
    let theta = |edge: usize| PI * edge as f32 / height as f32;
    (theta(row).cos(), theta(row + 1).cos())
}

/// Solid angle of one texel of row `row` of a `width`×`height` image.
fn texel_solid_angle(row: usize, width: usize, height: usize) -> f32 {
    let (top, bottom) = row_cos_bounds(row, height);
    2.0 * PI / width as f32 * (top - bottom)
}

/// Rec. 709 luminance.
fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// The first index whose cumulative value exceeds `value` (the last one at most).
fn pick(cdf: &[f32], value: f32) -> usize {
    cdf.partition_point(|&c| c <= value).min(cdf.len() - 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_uniform_map_is_sampled_uniformly_over_the_sphere() {
        let map = EnvironmentMap::new(vec![Vec3::splat(2.0); 8 * 4], 8, 4).unwrap();
        // Radiance over density is 2 × 4π wherever the sample falls, and the directions
        // cover the sphere evenly (their mean is the centre).
        let mut mean = Vec3::ZERO;
        for i in 0..32 {
            for j in 0..32 {
                let u = Vec2::new((i as f32 + 0.5) / 32.0, (j as f32 + 0.5) / 32.0);
                let sample = map.sample(u).unwrap();
                assert!((sample.direction.length() - 1.0).abs() < 1e-5);
                let expected = 2.0 * 4.0 * PI;
                assert!(
                    (sample.radiance.x - expected).abs() < 1e-4 * expected,
                    "{u}: {}",
                    sample.radiance.x
                );
                mean += sample.direction / 1024.0;
            }
        }
        assert!(mean.length() < 0.01, "{mean}");
        // The density is 1/4π everywhere.
        for direction in [Vec3::X, Vec3::NEG_Y, Vec3::new(0.3, 0.4, -0.5).normalize()] {
            assert!((map.pdf(direction) * 4.0 * PI - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn the_density_is_the_radiance_over_the_sample_estimate() {
        let (width, height) = (8, 4);
        let texels = (0..width * height)
            .map(|k| Vec3::splat(1.0 + (k % 5) as f32))
            .collect();
        let map = EnvironmentMap::new(texels, width, height).unwrap();
        for k in 0..64 {
            let u = Vec2::new((k as f32 * 0.618).fract(), (k as f32 * 0.381 + 0.1).fract());
            let sample = map.sample(u).unwrap();
            let radiance = map.radiance(sample.direction);
            let pdf = map.pdf(sample.direction);
            assert!(
                (sample.radiance.x * pdf - radiance.x).abs() < 1e-4 * radiance.x,
                "{u}: {} × {pdf} vs {}",
                sample.radiance.x,
                radiance.x
            );
        }
    }

    #[test]
    fn the_centre_of_the_image_lies_along_x_and_its_first_row_around_y() {
        let (width, height) = (16, 8);
        let mut texels = vec![Vec3::ZERO; width * height];
        texels[(height / 2) * width + width / 2] = Vec3::ONE;
        texels[1] = Vec3::splat(3.0);
        // The map's frame: x = direction, y = up, z = direction × up.
        let map = EnvironmentMap::new(texels, width, height).unwrap();
        // Just below the horizon, just beside `direction` towards direction × up (+z here).
        let towards =
            (Vec3::X + Vec3::new(0.0, -0.05, 0.0) + Vec3::X.cross(Vec3::Y) * 0.05).normalize();
        assert_eq!(map.radiance(towards), Vec3::ONE);
        // Texel 1 of the first row: θ in [0, π/8], φ in [-157.5°, -135°].
        let (theta, phi) = (0.2f32, (-146.0f32).to_radians());
        let near_up =
            Vec3::Y * theta.cos() + (Vec3::X * phi.cos() + Vec3::Z * phi.sin()) * theta.sin();
        assert_eq!(map.radiance(near_up), Vec3::splat(3.0));
        assert_eq!(map.radiance(-Vec3::X), Vec3::ZERO);
        // Every sample lands in a texel that emits.
        for k in 0..64 {
            let u = Vec2::new((k as f32 * 0.618).fract(), (k as f32 * 0.381 + 0.1).fract());
            let sample = map.sample(u).unwrap();
            assert!(map.radiance(sample.direction) != Vec3::ZERO, "{u}");
        }
    }
}
