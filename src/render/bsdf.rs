//! The formulas of the physically based material, after the glTF 2.0 specification (Appendix
//! B, "BRDF Implementation") and its extensions KHR_materials_specular, _clearcoat, _sheen and
//! _iridescence: Fresnel terms, the GGX microfacet lobe and its sampling, thin-film
//! interference, the sheen lobe and its directional albedo, and tangent-space normal maps. The
//! renderer gathers the light and layers these.

use std::f32::consts::{FRAC_1_PI, PI, TAU};
use std::sync::OnceLock;

use glam::{Mat3, Vec2, Vec3, Vec4};

/// Schlick's Fresnel approximation between `f0` at normal incidence and `f90` at grazing.
pub fn schlick(f0: Vec3, f90: f32, cos: f32) -> Vec3 {
    let m = (1.0 - cos.clamp(0.0, 1.0)).powi(5);
    f0 + (Vec3::splat(f90) - f0) * m
}

/// The smallest microfacet α (roughness²) used: below it the GGX formulas lose precision in
/// f32. Roughness 0 itself is a mirror and never reaches them.
const MIN_ALPHA: f32 = 1e-4;

/// glTF Appendix B's α for a perceptual `roughness`: roughness², kept above [`MIN_ALPHA`].
pub fn microfacet_alpha(roughness: f32) -> f32 {
    (roughness * roughness).max(MIN_ALPHA)
}

/// The GGX (Trowbridge–Reitz) distribution of microfacet normals, glTF Appendix B:
/// D = α² / (π ((n·h)² (α² − 1) + 1)²), `cos_h` = n·h.
pub fn ggx_distribution(alpha: f32, cos_h: f32) -> f32 {
    if cos_h <= 0.0 {
        return 0.0;
    }
    let alpha2 = alpha * alpha;
    let denominator = cos_h * cos_h * (alpha2 - 1.0) + 1.0;
    alpha2 / (PI * denominator * denominator)
}

/// √(α² + (1 − α²) cos²): the term Smith's masking shares between its forms.
fn smith_root(alpha: f32, cos: f32) -> f32 {
    let alpha2 = alpha * alpha;
    (alpha2 + (1.0 - alpha2) * cos * cos).sqrt()
}

/// glTF Appendix B's visibility V = G₂ / (4 n·l n·v), Smith's height-correlated masking and
/// shadowing for GGX: 0.5 / (n·l √(…n·v…) + n·v √(…n·l…)). Zero below either horizon.
pub fn smith_visibility(alpha: f32, cos_l: f32, cos_v: f32) -> f32 {
    if cos_l <= 0.0 || cos_v <= 0.0 {
        return 0.0;
    }
    0.5 / (cos_l * smith_root(alpha, cos_v) + cos_v * smith_root(alpha, cos_l))
}

/// What a reflection sampled from the visible normals carries: the lobe's f·cos/pdf without
/// its Fresnel term, which is G₂(l, v) / G₁(v) (height-correlated G₂); at most 1.
pub fn visible_normal_weight(alpha: f32, cos_l: f32, cos_v: f32) -> f32 {
    if cos_l <= 0.0 || cos_v <= 0.0 {
        return 0.0;
    }
    let (root_l, root_v) = (smith_root(alpha, cos_l), smith_root(alpha, cos_v));
    cos_l * (cos_v + root_v) / (cos_v * root_l + cos_l * root_v)
}

/// A microfacet normal drawn from the GGX distribution of normals visible from `view` (unit,
/// towards the viewer, in a frame whose z axis is the surface normal) for `u` in [0,1)²:
/// Heitz, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4), 2018. The view is
/// stretched so the microfacets become a hemisphere, a point of the disk facing it is
/// projected onto the hemisphere (its hidden half squeezed away) and the normal there is
/// stretched back.
pub fn sample_visible_normal(alpha: f32, view: Vec3, u: Vec2) -> Vec3 {
    let stretched = Vec3::new(alpha * view.x, alpha * view.y, view.z).normalize();
    let across = stretched.x * stretched.x + stretched.y * stretched.y;
    let t1 = if across > 0.0 {
        Vec3::new(-stretched.y, stretched.x, 0.0) / across.sqrt()
    } else {
        Vec3::X
    };
    let t2 = stretched.cross(t1);
    let radius = u.x.sqrt();
    let angle = TAU * u.y;
    let p1 = radius * angle.cos();
    let visible = 0.5 * (1.0 + stretched.z);
    let p2 = (1.0 - visible) * (1.0 - p1 * p1).max(0.0).sqrt() + visible * radius * angle.sin();
    let up = (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
    let on_hemisphere = t1 * p1 + t2 * p2 + stretched * up;
    Vec3::new(
        alpha * on_hemisphere.x,
        alpha * on_hemisphere.y,
        on_hemisphere.z.max(1e-6),
    )
    .normalize()
}

/// A reflection drawn from a GGX lobe: the direction it leaves along and the microfacet normal
/// it reflects off.
#[derive(Clone, Copy, Debug)]
pub struct GlossySample {
    pub direction: Vec3,
    pub half: Vec3,
}

/// Most draws [`sample_glossy`] makes before it gives up (then the lobe loses the sample: at
/// most (1 − E)¹⁶ of its light, under 0.4 % at roughness 1).
const MAX_DRAWS: u32 = 16;

/// A reflection of the lobe of `alpha` around the unit `normal`, seen from `to_viewer` (unit,
/// away from the surface), distributed as D·V·(n·l), so that it carries the lobe's albedo E
/// with no further weight: microfacet normals are drawn from the visible normals
/// ([`sample_visible_normal`], the first at `u`) and the reflection is kept with probability
/// G₂/G₁ (at most 1, on average E); `next` gives further numbers in [0,1) for the acceptance
/// and the redraws.
pub fn sample_glossy(
    normal: Vec3,
    to_viewer: Vec3,
    alpha: f32,
    u: Vec2,
    mut next: impl FnMut() -> f32,
) -> Option<GlossySample> {
    let (tangent, bitangent) = normal.any_orthonormal_pair();
    // A view on or below the horizon (a shading normal turned away) is seen from just above.
    let local = Vec3::new(
        to_viewer.dot(tangent),
        to_viewer.dot(bitangent),
        to_viewer.dot(normal).max(1e-4),
    )
    .normalize();
    let mut u = u;
    for _ in 0..MAX_DRAWS {
        let m = sample_visible_normal(alpha, local, u);
        let half = (tangent * m.x + bitangent * m.y + normal * m.z).normalize();
        let direction = 2.0 * to_viewer.dot(half) * half - to_viewer;
        let kept = visible_normal_weight(alpha, direction.dot(normal), local.z);
        if next() < kept {
            return Some(GlossySample { direction, half });
        }
        u = Vec2::new(next(), next());
    }
    None
}

/// Table size of the microfacet albedo along cos_v and roughness.
const GGX_ALBEDO_STEPS: usize = 32;

/// The GGX lobe's single-scattering albedo E = ∫ D V (n·l) dω (Fresnel 1) at `cos_v` and
/// `roughness`: what one reflection off the microfacets returns of uniform light; the rest
/// is scattered again among them, which single scattering drops (at roughness 1 and normal
/// incidence E = 1 − ln 2). Bilinear in a table integrated on first use.
pub fn microfacet_albedo(cos_v: f32, roughness: f32) -> f32 {
    static TABLE: OnceLock<Vec<f32>> = OnceLock::new();
    let last = (GGX_ALBEDO_STEPS - 1) as f32;
    let table = TABLE.get_or_init(|| {
        let mut table = Vec::with_capacity(GGX_ALBEDO_STEPS * GGX_ALBEDO_STEPS);
        for r in 0..GGX_ALBEDO_STEPS {
            for c in 0..GGX_ALBEDO_STEPS {
                let cos_v = (c as f32 / last).max(1e-3);
                let roughness = r as f32 / last;
                table.push(integrate_microfacet_albedo(
                    cos_v,
                    microfacet_alpha(roughness),
                ));
            }
        }
        table
    });
    let position = |value: f32| {
        let x = value.clamp(0.0, 1.0) * last;
        let i = (x.floor() as usize).min(GGX_ALBEDO_STEPS - 2);
        (i, x - i as f32)
    };
    let (c, fc) = position(cos_v);
    let (r, fr) = position(roughness);
    let at = |c: usize, r: usize| table[r * GGX_ALBEDO_STEPS + c];
    let low = at(c, r) * (1.0 - fc) + at(c + 1, r) * fc;
    let high = at(c, r + 1) * (1.0 - fc) + at(c + 1, r + 1) * fc;
    low * (1.0 - fr) + high * fr
}

/// E at one grid point: the mean weight G₂/G₁ of reflections off visible normals drawn on a
/// stratified grid (each visible normal's share of the view is its probability).
fn integrate_microfacet_albedo(cos_v: f32, alpha: f32) -> f32 {
    let view = Vec3::new((1.0 - cos_v * cos_v).sqrt(), 0.0, cos_v);
    let n = 24;
    let mut sum = 0.0;
    for i in 0..n {
        for j in 0..n {
            let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
            let m = sample_visible_normal(alpha, view, u);
            let light = 2.0 * view.dot(m) * m - view;
            sum += visible_normal_weight(alpha, light.z, cos_v);
        }
    }
    sum / (n * n) as f32
}

/// Multiple-scattering compensation (Turquin, "Practical multiple scattering compensation for
/// microfacet models", 2019): the single-scattering lobe of albedo `albedo` scaled by
/// 1 + F0 (1 − E)/E, so that a lobe of Fresnel 1 returns all uniform light and a coloured
/// one loses by its F0 what every further bounce absorbs. Layers whose Fresnel term is their
/// mixing weight (the dielectric's reflection, the clearcoat) use F0 = 1.
pub fn multiple_scattering(albedo: f32, f0: Vec3) -> Vec3 {
    Vec3::ONE + f0 * ((1.0 - albedo) / albedo.max(1e-3))
}

/// Reflectance at normal incidence of an interface between indices `a` and `b`.
fn ior_to_f0(a: f32, b: f32) -> f32 {
    ((a - b) / (a + b)).powi(2)
}

/// KHR_materials_specular: the dielectric's reflectance at normal incidence,
/// min(((ior − 1)/(ior + 1))² · specularColor, 1).
pub fn dielectric_f0(ior: f32, specular_color: Vec3) -> Vec3 {
    (ior_to_f0(ior, 1.0) * specular_color).min(Vec3::ONE)
}

/// KHR_materials_clearcoat: the coat is a dielectric of index 1.5 (F0 = 0.04).
pub fn clearcoat_fresnel(cos: f32) -> f32 {
    schlick(Vec3::splat(0.04), 1.0, cos).x
}

/// KHR_materials_iridescence: the Fresnel reflectance of a base of normal-incidence
/// reflectance `base_f0` under a thin film of index `film_ior` and `thickness_nm`, seen at
/// `cos` from outside (index 1). Airy summation of the film's first reflections with the
/// phase shifts turned into colour by Gaussian fits of the CIE matching functions (Belcour and
/// Barla 2017, as the extension specifies). The film fades in over its first 30 nm from the
/// base's own Schlick reflectance, so a film of thickness 0 leaves the base as it is. Clamped
/// to [0, 1].
pub fn thin_film_fresnel(film_ior: f32, thickness_nm: f32, cos: f32, base_f0: Vec3) -> Vec3 {
    let fade = smoothstep(0.0, 30.0, thickness_nm);
    let base = schlick(base_f0, 1.0, cos);
    if fade <= 0.0 {
        return base;
    }
    base.lerp(film_fresnel(film_ior, thickness_nm, cos, base_f0), fade)
}

fn film_fresnel(film: f32, thickness_nm: f32, cos: f32, base_f0: Vec3) -> Vec3 {
    let outside = 1.0;
    let cos1 = cos.clamp(0.0, 1.0);
    let cos2_squared = 1.0 - (outside / film).powi(2) * (1.0 - cos1 * cos1);
    if cos2_squared <= 0.0 {
        return Vec3::ONE;
    }
    let cos2 = cos2_squared.sqrt();
    // Outside → film.
    let r12 = schlick(Vec3::splat(ior_to_f0(film, outside)), 1.0, cos1).x;
    let t121 = 1.0 - r12;
    let phi21 = if film < outside { 0.0 } else { PI };
    // Film → base, the base's index recovered from its F0.
    let root = base_f0.clamp(Vec3::ZERO, Vec3::splat(0.9999)).powf(0.5);
    let base_ior = (Vec3::ONE + root) / (Vec3::ONE - root);
    let r23 = schlick(
        Vec3::from_array(base_ior.to_array().map(|n| ior_to_f0(n, film))),
        1.0,
        cos2,
    );
    let phi23 = Vec3::from_array(base_ior.to_array().map(|n| if n < film { PI } else { 0.0 }));
    let path_difference = 2.0 * film * thickness_nm * cos2;
    let phase = Vec3::splat(phi21) + phi23;
    let r123 = (r12 * r23).clamp(Vec3::splat(1e-5), Vec3::splat(0.9999));
    let amplitude = r123.powf(0.5);
    let rs = t121 * t121 * r23 / (Vec3::ONE - r123);
    let mut reflectance = Vec3::splat(r12) + rs;
    let mut coefficient = rs - Vec3::splat(t121);
    for m in 1..=2 {
        coefficient *= amplitude;
        let m = m as f32;
        reflectance += coefficient * 2.0 * spectral_sensitivity(m * path_difference, m * phase);
    }
    reflectance.clamp(Vec3::ZERO, Vec3::ONE)
}

fn smoothstep(edge0: f32, edge1: f32, x: f32) -> f32 {
    let t = ((x - edge0) / (edge1 - edge0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Linear Rec. 709 response to a phase shift of `path_nm` of optical path plus `shift`, from
/// Gaussian fits of the CIE 1931 matching functions (constants of the iridescence extension).
fn spectral_sensitivity(path_nm: f32, shift: Vec3) -> Vec3 {
    let phase = TAU * path_nm * 1e-9;
    let gaussian = |value: f32, position: f32, variance: f32, shift: f32| {
        value
            * (TAU * variance).sqrt()
            * (position * phase + shift).cos()
            * (-phase * phase * variance).exp()
    };
    let x = gaussian(5.4856e-13, 1.6810e6, 4.3278e9, shift.x)
        + gaussian(9.7470e-14, 2.2399e6, 4.5282e9, shift.x);
    let y = gaussian(4.4201e-13, 1.7953e6, 9.3046e9, shift.y);
    let z = gaussian(5.2481e-13, 2.2084e6, 6.6121e9, shift.z);
    let xyz = Vec3::new(x, y, z) / 1.0685e-7;
    // CIE XYZ to linear Rec. 709, columns.
    let to_rec709 = Mat3::from_cols(
        Vec3::new(3.240_454_2, -0.969_266, 0.055_643_4),
        Vec3::new(-1.537_138_5, 1.876_010_8, -0.204_025_9),
        Vec3::new(-0.498_531_4, 0.041_556, 1.057_225_2),
    );
    to_rec709 * xyz
}

/// The sheen roughness below which the Charlie lobe is too sharp to integrate on the albedo
/// table's grid; rougher values are used as they are.
const MIN_SHEEN_ROUGHNESS: f32 = 0.07;

/// KHR_materials_sheen's BRDF (without the sheen colour): the Charlie distribution
/// D = (2 + 1/α) sin^(1/α)θh / 2π with α = roughness², and Ashikhmin's visibility
/// 1 / (4 (cos_l + cos_v − cos_l cos_v)) as the extension allows.
pub fn sheen_brdf(roughness: f32, cos_v: f32, cos_l: f32, cos_h: f32) -> f32 {
    if cos_v <= 0.0 || cos_l <= 0.0 {
        return 0.0;
    }
    let alpha = roughness.clamp(MIN_SHEEN_ROUGHNESS, 1.0).powi(2);
    let inverse = 1.0 / alpha;
    let sin_h = (1.0 - cos_h * cos_h).max(0.0).sqrt();
    let distribution = (2.0 + inverse) * sin_h.powf(inverse) * 0.5 * FRAC_1_PI;
    let visibility = 0.25 / (cos_l + cos_v - cos_l * cos_v);
    distribution * visibility
}

/// Table size of the sheen albedo along cos_v and roughness.
const ALBEDO_STEPS: usize = 16;

/// The sheen lobe's directional albedo ∫ sheen_brdf cos_l dω at `cos_v` and `roughness`, at most
/// 1: what the sheen reflects of uniform light and so what the layers below it lose
/// (KHR_materials_sheen's albedo scaling). Bilinear in a table integrated on first use.
pub fn sheen_albedo(cos_v: f32, roughness: f32) -> f32 {
    static TABLE: OnceLock<Vec<f32>> = OnceLock::new();
    let table = TABLE.get_or_init(|| {
        let mut table = Vec::with_capacity(ALBEDO_STEPS * ALBEDO_STEPS);
        for r in 0..ALBEDO_STEPS {
            for c in 0..ALBEDO_STEPS {
                let (cos_v, roughness) = albedo_grid_point(c, r);
                table.push(integrate_sheen(cos_v, roughness).min(1.0));
            }
        }
        table
    });
    let position = |value: f32, low: f32| {
        let x = ((value - low) / (1.0 - low)).clamp(0.0, 1.0) * (ALBEDO_STEPS - 1) as f32;
        let i = (x.floor() as usize).min(ALBEDO_STEPS - 2);
        (i, x - i as f32)
    };
    let (c, fc) = position(cos_v, 0.0);
    let (r, fr) = position(roughness, MIN_SHEEN_ROUGHNESS);
    let at = |c: usize, r: usize| table[r * ALBEDO_STEPS + c];
    let low = at(c, r) * (1.0 - fc) + at(c + 1, r) * fc;
    let high = at(c, r + 1) * (1.0 - fc) + at(c + 1, r + 1) * fc;
    low * (1.0 - fr) + high * fr
}

fn albedo_grid_point(c: usize, r: usize) -> (f32, f32) {
    let step = 1.0 / (ALBEDO_STEPS - 1) as f32;
    (
        (c as f32 * step).max(1e-3),
        MIN_SHEEN_ROUGHNESS + (1.0 - MIN_SHEEN_ROUGHNESS) * r as f32 * step,
    )
}

/// ∫ sheen_brdf cos_l dω over the hemisphere.
fn integrate_sheen(cos_v: f32, roughness: f32) -> f32 {
    hemisphere_integral(cos_v, 64, |cos_l, cos_h| {
        f64::from(sheen_brdf(roughness, cos_v, cos_l, cos_h) * cos_l)
    }) as f32
}

/// ∫ f(cos θ_l, cos θ_h) dω_l over the hemisphere of light directions around the normal +z,
/// seen from the direction at `cos_v` (θ_h: the half vector's angle to the normal); midpoint
/// rule on `steps` × `steps` cells of (cos θ_l, φ), where dω = d(cos θ) dφ.
pub(crate) fn hemisphere_integral(
    cos_v: f32,
    steps: u32,
    integrand: impl Fn(f32, f32) -> f64,
) -> f64 {
    let view = Vec3::new((1.0 - cos_v * cos_v).sqrt(), 0.0, cos_v);
    let mut sum = 0.0f64;
    for i in 0..steps {
        let cos_l = (i as f32 + 0.5) / steps as f32;
        let sin_l = (1.0 - cos_l * cos_l).sqrt();
        for j in 0..steps {
            let phi = TAU * (j as f32 + 0.5) / steps as f32;
            let light = Vec3::new(sin_l * phi.cos(), sin_l * phi.sin(), cos_l);
            sum += integrand(cos_l, (view + light).normalize().z);
        }
    }
    sum / f64::from(steps) * std::f64::consts::TAU / f64::from(steps)
}

/// glTF normal maps: the texel's components map to a tangent-space normal as 2·value − 1, in
/// the frame of the unit `normal`, the `tangent` (xyz, made perpendicular to the normal) and
/// the bitangent normal × tangent times the handedness in `tangent.w`. Falls back to `normal`
/// where the map or the frame is degenerate.
pub fn mapped_normal(normal: Vec3, tangent: Vec4, texel: Vec4) -> Vec3 {
    let local = texel.truncate() * 2.0 - Vec3::ONE;
    let Some(t) = (tangent.truncate() - normal * normal.dot(tangent.truncate())).try_normalize()
    else {
        return normal;
    };
    let handedness = if tangent.w < 0.0 { -1.0 } else { 1.0 };
    let b = normal.cross(t) * handedness;
    (t * local.x + b * local.y + normal * local.z)
        .try_normalize()
        .unwrap_or(normal)
}

/// A tangent where the geometry gives none: the object's x axis, made perpendicular to the
/// normal (its y axis where x is along the normal), so a plane facing +z maps x right, y up.
pub fn fallback_tangent(normal: Vec3, x_axis: Vec3, y_axis: Vec3) -> Vec4 {
    let along = |axis: Vec3| (axis - normal * normal.dot(axis)).try_normalize();
    along(x_axis)
        .or_else(|| along(y_axis))
        .unwrap_or(Vec3::X)
        .extend(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schlick_runs_from_f0_at_normal_incidence_to_f90_at_grazing() {
        let f0 = Vec3::new(0.04, 0.5, 1.0);
        assert_eq!(schlick(f0, 1.0, 1.0), f0);
        assert_eq!(schlick(f0, 1.0, 0.0), Vec3::ONE);
        let half = schlick(f0, 1.0, 0.5);
        assert!((half.x - (0.04 + 0.96 / 32.0)).abs() < 1e-6);
    }

    /// ∫ D(h) (n·h) dω_h over the hemisphere, midpoint rule in (cos θ, φ); isotropic, so φ
    /// gives 2π.
    fn projected_distribution_integral(alpha: f32) -> f64 {
        let rings = 200_000;
        (0..rings)
            .map(|i| {
                let cos = (i as f64 + 0.5) / rings as f64;
                f64::from(ggx_distribution(alpha, cos as f32)) * cos
            })
            .sum::<f64>()
            / rings as f64
            * std::f64::consts::TAU
    }

    /// The single-scattering albedo ∫ D V (n·l) dω_l (F = 1) of the lobe seen at `cos_v`, by
    /// quadrature over light directions.
    fn albedo_by_quadrature(alpha: f32, cos_v: f32) -> f64 {
        hemisphere_integral(cos_v, 600, |cos_l, cos_h| {
            let f = ggx_distribution(alpha, cos_h) * smith_visibility(alpha, cos_l, cos_v);
            f64::from(f * cos_l)
        })
    }

    #[test]
    fn the_ggx_distribution_is_normalised_over_projected_area() {
        for alpha in [0.05, 0.2, 0.5, 1.0] {
            let integral = projected_distribution_integral(alpha);
            assert!((integral - 1.0).abs() < 2e-3, "alpha {alpha}: {integral}");
        }
    }

    #[test]
    fn the_albedo_table_matches_quadrature_and_the_closed_form() {
        // The table's estimate (the visible normals' mean weight G₂/G₁) against ∫ D V (n·l) dω
        // by quadrature over light directions: the sampling's density is the one the weight
        // assumes.
        for (roughness, cos_v) in [(0.3f32, 0.9f32), (0.5, 0.5), (1.0, 1.0), (1.0, 0.3)] {
            let table = microfacet_albedo(cos_v, roughness);
            let expected = albedo_by_quadrature(microfacet_alpha(roughness), cos_v);
            assert!(
                (f64::from(table) - expected).abs() < 0.01,
                "roughness {roughness} cos_v {cos_v}: table {table}, quadrature {expected}"
            );
        }
        // α = 1 facing: D = 1/π, V = 1/(2(cos_l + 1)), so E = ∫₀¹ c/(1 + c) dc = 1 − ln 2.
        assert!((microfacet_albedo(1.0, 1.0) - (1.0 - std::f32::consts::LN_2)).abs() < 0.01);
        assert!(microfacet_albedo(0.7, 0.0) > 0.999);
    }

    #[test]
    fn glossy_samples_follow_the_lobe() {
        // Kept reflections are distributed as D V (n·l) / E: the mean of any function over
        // them is its lobe-weighted mean. Here cos_l, against quadrature.
        let (alpha, cos_v) = (0.25f32, 0.6f32);
        let to_viewer = Vec3::new((1.0 - cos_v * cos_v).sqrt(), 0.0, cos_v);
        let mut state = 0x1234_5678u32;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            (state >> 8) as f32 / (1u32 << 24) as f32
        };
        let (mut sum, mut count) = (0.0f64, 0);
        for _ in 0..200_000 {
            let u = Vec2::new(next(), next());
            if let Some(sample) = sample_glossy(Vec3::Z, to_viewer, alpha, u, &mut next) {
                assert!((sample.direction.length() - 1.0).abs() < 1e-4);
                assert!(sample.direction.z > 0.0);
                sum += f64::from(sample.direction.z);
                count += 1;
            }
        }
        let sampled = sum / f64::from(count);
        let lobe = |cos_l: f32, cos_h: f32| {
            f64::from(
                ggx_distribution(alpha, cos_h) * smith_visibility(alpha, cos_l, cos_v) * cos_l,
            )
        };
        let weighted = hemisphere_integral(cos_v, 600, |cos_l, cos_h| {
            lobe(cos_l, cos_h) * f64::from(cos_l)
        });
        let expected = weighted / hemisphere_integral(cos_v, 600, lobe);
        assert!(
            (sampled - expected).abs() < 0.005,
            "mean cos_l: sampled {sampled}, lobe {expected}"
        );
    }

    #[test]
    fn the_visibility_is_g2_over_4_cos_cos() {
        // α = 1: G₂ = 2 cos_l cos_v / (cos_v + cos_l), so V = 1 / (2 (cos_l + cos_v)).
        let v = smith_visibility(1.0, 0.3, 0.8);
        assert!((v - 1.0 / (2.0 * 1.1)).abs() < 1e-6, "{v}");
        // Mirror-like α: V → 1 / (4 cos_l cos_v).
        let v = smith_visibility(1e-4, 0.5, 0.5);
        assert!((v - 1.0).abs() < 1e-3, "{v}");
    }

    #[test]
    fn the_dielectric_f0_follows_the_index_and_the_specular_colour() {
        let f0 = dielectric_f0(1.5, Vec3::new(1.0, 0.5, 100.0));
        assert!((f0.x - 0.04).abs() < 1e-6 && (f0.y - 0.02).abs() < 1e-6);
        // Capped at 1.
        assert_eq!(f0.z, 1.0);
    }

    #[test]
    fn a_film_of_no_thickness_or_the_base_index_leaves_the_base_reflectance() {
        let base = Vec3::splat(0.04);
        for cos in [1.0, 0.7, 0.3] {
            let plain = schlick(base, 1.0, cos);
            let thin = thin_film_fresnel(1.3, 0.0, cos, base);
            assert!((thin - plain).abs().max_element() < 0.01, "{thin} {plain}");
        }
    }

    #[test]
    fn a_thin_film_colours_the_reflection_by_its_thickness() {
        // A soap-like film (n 1.33) over glass: reflectance coloured, different per thickness.
        let base = Vec3::splat(0.04);
        let a = thin_film_fresnel(1.33, 300.0, 1.0, base);
        let b = thin_film_fresnel(1.33, 500.0, 1.0, base);
        let coloured = |v: Vec3| v.max_element() > 2.0 * v.min_element();
        assert!(coloured(a) && coloured(b), "{a} {b}");
        assert!((a - b).abs().max_element() > 0.01, "{a} {b}");
        assert!(a.min_element() >= 0.0 && a.max_element() <= 1.0);
    }

    #[test]
    fn the_sheen_albedo_stays_within_one_and_grows_with_roughness() {
        for r in [0.1, 0.3, 0.6, 1.0] {
            for c in [0.05, 0.3, 0.7, 1.0] {
                let e = sheen_albedo(c, r);
                assert!((0.0..=1.0).contains(&e), "{c} {r}: {e}");
            }
        }
        // Facing the viewer a rougher sheen reflects more.
        assert!(sheen_albedo(1.0, 1.0) > sheen_albedo(1.0, 0.2));
        // The table matches direct integration between its grid points.
        let direct = integrate_sheen(0.55, 0.5).min(1.0);
        assert!((sheen_albedo(0.55, 0.5) - direct).abs() < 0.02);
    }

    #[test]
    fn a_normal_map_tilts_the_normal_in_the_tangent_frame() {
        let n = Vec3::Z;
        let tangent = Vec4::new(1.0, 0.0, 0.0, 1.0);
        // (0.5, 0.5, 1): straight up.
        let flat = mapped_normal(n, tangent, Vec4::new(0.5, 0.5, 1.0, 1.0));
        assert!((flat - n).length() < 1e-6);
        // Towards the tangent by 45 degrees.
        let s = 0.5 + 0.5 * std::f32::consts::FRAC_1_SQRT_2;
        let tilted = mapped_normal(n, tangent, Vec4::new(s, 0.5, s, 1.0));
        assert!((tilted - Vec3::new(1.0, 0.0, 1.0).normalize()).length() < 1e-5);
        // Negative handedness flips the bitangent.
        let up = mapped_normal(
            n,
            Vec4::new(1.0, 0.0, 0.0, -1.0),
            Vec4::new(0.5, 1.0, 0.5, 1.0),
        );
        assert!((up - Vec3::NEG_Y).length() < 1e-5);
    }
}
