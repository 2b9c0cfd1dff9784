//! Renderer objects. "default": direct lighting from directional, point and spot lights with
//! shadows (soft from lights with extent), ambient light occluded by the scene, an environment
//! seen and reflected, mirror and glossy reflections and transparency. "fast": primary rays only with eye-light shading, for head-tracked
//! interactivity. This file holds their parameters and committed settings; the shading itself
//! is [`crate::render::integrator`].

use std::sync::Arc;

use glam::{Vec2, Vec3, Vec4};

use crate::accel::Ray;
use crate::device::Device;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};
use crate::device::status::ANARI_STATUS_INVALID_ARGUMENT;
use crate::scene::attributes::{VALUE_ELEMENT_TYPES, read_values};
use crate::scene::sampler::{Image, Wrap};

const BACKGROUND: ParamSpec = ParamSpec::new(
    "background",
    &[ANARI_FLOAT32_VEC4, ANARI_ARRAY2D],
    "what shows where no surface is hit: a colour (linear RGBA) or an image stretched over \
     the frame (its first row along the frame's first row)",
)
.default(SpecValue::Floats(&[0.0, 0.0, 0.0, 1.0]))
.elements(VALUE_ELEMENT_TYPES);
const AMBIENT_COLOR: ParamSpec = ParamSpec::new(
    "ambientColor",
    &[ANARI_FLOAT32_VEC3],
    "colour of the ambient light",
)
.default(SpecValue::Floats(&[1.0, 1.0, 1.0]));
const AMBIENT_RADIANCE: ParamSpec = ParamSpec::new(
    "ambientRadiance",
    &[ANARI_FLOAT32],
    "radiance of the ambient light",
)
.default(SpecValue::Float(0.0));
const AMBIENT_OCCLUSION_DISTANCE: ParamSpec = ParamSpec::new(
    "ambientOcclusionDistance",
    &[ANARI_FLOAT32],
    "how far surfaces shadow the ambient light: a point's ambient light is occluded only by \
     surfaces nearer than this (infinite: every surface; 0: no ambient occlusion)",
)
.default(SpecValue::Float(f32::INFINITY))
.range(SpecValue::Float(0.0), SpecValue::None);
const PIXEL_SAMPLES: ParamSpec = ParamSpec::new(
    "pixelSamples",
    &[ANARI_INT32, ANARI_UINT32],
    "samples per pixel per frame, jittered deterministically",
)
.default(SpecValue::Int(1))
.range(SpecValue::Int(1), SpecValue::Int(1024));

const STEREO_LIGHTING: ParamSpec = ParamSpec::new(
    "stereoLighting",
    &[ANARI_STRING],
    "where view-dependent shading (the fast renderer's eye light, mirror reflections) looks \
     from in stereo: 'cyclopean' (midway between the eyes: both eyes see a highlight or \
     reflection at the same place on a surface) or 'perEye' (each eye from itself); mono \
     frames are the same either way",
)
.default(SpecValue::Str("cyclopean"))
.values(&["cyclopean", "perEye"]);

pub const DEFAULT: ObjectSpec = ObjectSpec::new(
    ANARI_RENDERER,
    "default",
    "direct lighting with shadows (soft from lights with extent), ambient light with ambient \
     occlusion, an environment seen, reflected and refracted, mirror and glossy reflections \
     and transparency",
    &[
        BACKGROUND,
        AMBIENT_COLOR,
        AMBIENT_RADIANCE,
        AMBIENT_OCCLUSION_DISTANCE,
        PIXEL_SAMPLES,
        ParamSpec::new(
            "maxRayDepth",
            &[ANARI_INT32, ANARI_UINT32],
            "maximum number of reflection and transparency bounces",
        )
        .default(SpecValue::Int(5))
        .range(SpecValue::Int(0), SpecValue::Int(64)),
        ParamSpec::new("shadows", &[ANARI_BOOL], "whether lights cast shadows")
            .default(SpecValue::Bool(true)),
        STEREO_LIGHTING,
    ],
)
.extensions(&[
    "ANARI_CAVETRACE_RENDERER_STEREO_LIGHTING",
    "ANARI_KHR_RENDERER_AMBIENT_LIGHT",
    "ANARI_KHR_RENDERER_BACKGROUND_COLOR",
    "ANARI_KHR_RENDERER_BACKGROUND_IMAGE",
]);

pub const FAST: ObjectSpec = ObjectSpec::new(
    ANARI_RENDERER,
    "fast",
    "for head-tracked interactivity: primary rays only, shaded by a light at the eye (no \
     shadows, reflections or scene lights)",
    &[BACKGROUND, PIXEL_SAMPLES, STEREO_LIGHTING],
)
.extensions(&["ANARI_CAVETRACE_RENDERER_STEREO_LIGHTING"]);

#[derive(Clone, Debug, PartialEq)]
pub struct RendererSettings {
    pub fast: bool,
    /// Background colour, where no background image is set.
    pub background: Vec4,
    /// Background image stretched over the frame (KHR_RENDERER_BACKGROUND_IMAGE).
    pub background_image: Option<Arc<Image>>,
    pub ambient: Vec3,
    /// Surfaces farther than this from a point do not occlude its ambient light.
    pub ambient_occlusion_distance: f32,
    pub pixel_samples: u32,
    pub max_ray_depth: u32,
    pub shadows: bool,
    /// `stereoLighting` 'cyclopean': the eyes of a stereo pair shade view-dependent terms
    /// from the point midway between them.
    pub cyclopean_lighting: bool,
}

impl Default for RendererSettings {
    fn default() -> Self {
        RendererSettings {
            fast: false,
            background: Vec4::new(0.0, 0.0, 0.0, 1.0),
            background_image: None,
            ambient: Vec3::ZERO,
            ambient_occlusion_distance: f32::INFINITY,
            pixel_samples: 1,
            max_ray_depth: 5,
            shadows: true,
            cyclopean_lighting: true,
        }
    }
}

impl RendererSettings {
    pub fn from_object(object: &Object) -> RendererSettings {
        let p = object.committed();
        let int = |name: &str, default: u32| {
            p.get_i32(name)
                .map(|v| v.max(0) as u32)
                .or_else(|| p.get_u32(name))
                .unwrap_or(default)
        };
        RendererSettings {
            fast: object.subtype == "fast",
            background: p
                .get_vec4("background")
                .unwrap_or(Vec4::new(0.0, 0.0, 0.0, 1.0)),
            background_image: background_image(object),
            ambient: p.get_vec3("ambientColor").unwrap_or(Vec3::ONE)
                * p.get_f32("ambientRadiance").unwrap_or(0.0),
            ambient_occlusion_distance: p
                .get_f32("ambientOcclusionDistance")
                .filter(|d| *d >= 0.0)
                .unwrap_or(f32::INFINITY),
            pixel_samples: int("pixelSamples", 1).clamp(1, 1024),
            max_ray_depth: int("maxRayDepth", 5).min(64),
            shadows: p.get_bool("shadows").unwrap_or(true),
            cyclopean_lighting: p.get_string("stereoLighting") != Some("perEye"),
        }
    }
}

/// Settings from a committed renderer, reporting a background image that cannot be used.
pub fn commit(device: &Device, object: &Object) -> RendererSettings {
    let settings = RendererSettings::from_object(object);
    if settings.background_image.is_none()
        && let Some(array) = object.committed().get_object("background")
    {
        device.error(
            ANARI_STATUS_INVALID_ARGUMENT,
            Some(object),
            format!(
                "anariCommitParameters: {} parameter 'background': {} holds no texels; the \
                 background is black",
                object.describe(),
                array.describe()
            ),
        );
    }
    if let Some(distance) = object.committed().get_f32("ambientOcclusionDistance")
        && (distance.is_nan() || distance < 0.0)
    {
        device.error(
            ANARI_STATUS_INVALID_ARGUMENT,
            Some(object),
            format!(
                "anariCommitParameters: {} parameter 'ambientOcclusionDistance': expected a \
                 distance ≥ 0, got {distance}; using infinity (every surface occludes)",
                object.describe()
            ),
        );
    }
    if let Some(value) = object.committed().get_string("stereoLighting")
        && value != "cyclopean"
        && value != "perEye"
    {
        device.error(
            ANARI_STATUS_INVALID_ARGUMENT,
            Some(object),
            format!(
                "anariCommitParameters: {} parameter 'stereoLighting': expected 'cyclopean' or \
                 'perEye', got '{value}'; using 'cyclopean'",
                object.describe()
            ),
        );
    }
    settings
}

impl RendererSettings {
    /// The direction view-dependent shading of a primary hit at `point` looks along: from the
    /// cyclopean eye under cyclopean lighting when the ray belongs to a stereo eye, otherwise
    /// the ray's own.
    #[inline(always)]
    pub(crate) fn view_direction(&self, ray: &Ray, point: Vec3, cyclopean: Option<Vec3>) -> Vec3 {
        match cyclopean.filter(|_| self.cyclopean_lighting) {
            Some(viewer) => (point - viewer).try_normalize().unwrap_or(ray.direction),
            None => ray.direction,
        }
    }
}

/// The renderer's `background` when it is an ARRAY2D: bilinear between texel centres and clamped
/// at the edges, so the image's texels stretch evenly over the frame.
fn background_image(renderer: &Object) -> Option<Arc<Image>> {
    let params = renderer.committed();
    let array = params
        .get_object("background")
        .filter(|a| a.kind == ANARI_ARRAY2D)?;
    let store = array.array.as_ref()?;
    let size = [store.dims[0] as usize, store.dims[1] as usize, 1];
    let image = Image::new(read_values(store)?, size, true, [Wrap::ClampToEdge; 3])?;
    Some(Arc::new(image))
}

impl RendererSettings {
    /// The background at `screen`, the position in the frame from (0, 0) at the corner of the
    /// first pixel (bottom left) to (1, 1) at the far corner of the last: the image's first
    /// row lies along the frame's first row.
    pub fn background_at(&self, screen: Vec2) -> Vec4 {
        match &self.background_image {
            Some(image) => image.sample(screen.extend(0.0)),
            None => self.background,
        }
    }

    /// The background a ray of the sample at `screen` sees (the background colour without a
    /// screen position): secondary rays see the image where their primary sample lies.
    pub(crate) fn background_for(&self, screen: Option<Vec2>) -> Vec4 {
        screen.map_or(self.background, |screen| self.background_at(screen))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::integrator::{shade_primary, shade_primary_at};
    use crate::scene::light::LightSampling;
    use crate::scene::world::SceneSnapshot;

    /// Settings whose background is a 2×2 image: red, green along the first row (bottom of the
    /// frame), blue, white along the second.
    fn four_colour_background() -> RendererSettings {
        let texels = vec![
            Vec4::new(1.0, 0.0, 0.0, 1.0),
            Vec4::new(0.0, 1.0, 0.0, 1.0),
            Vec4::new(0.0, 0.0, 1.0, 1.0),
            Vec4::new(1.0, 1.0, 1.0, 0.5),
        ];
        let image = Image::new(texels, [2, 2, 1], true, [Wrap::ClampToEdge; 3]).unwrap();
        RendererSettings {
            background: Vec4::new(0.1, 0.2, 0.3, 1.0),
            background_image: Some(Arc::new(image)),
            ..RendererSettings::default()
        }
    }

    #[test]
    fn the_background_image_stretches_over_the_frame() {
        let settings = four_colour_background();
        let at = |x: f32, y: f32| settings.background_at(Vec2::new(x, y));
        // Corners and texel centres show one texel each; the centre blends all four.
        assert_eq!(at(0.0, 0.0), Vec4::new(1.0, 0.0, 0.0, 1.0));
        assert_eq!(at(0.25, 0.25), Vec4::new(1.0, 0.0, 0.0, 1.0));
        assert_eq!(at(1.0, 0.0), Vec4::new(0.0, 1.0, 0.0, 1.0));
        assert_eq!(at(0.0, 1.0), Vec4::new(0.0, 0.0, 1.0, 1.0));
        assert_eq!(at(1.0, 1.0), Vec4::new(1.0, 1.0, 1.0, 0.5));
        assert_eq!(at(0.5, 0.5), Vec4::new(0.5, 0.5, 0.5, 0.875));
        // Halfway along the bottom edge: red and green in equal parts.
        assert_eq!(at(0.5, 0.0), Vec4::new(0.5, 0.5, 0.0, 1.0));
        let plain = RendererSettings::default();
        assert_eq!(
            plain.background_at(Vec2::new(0.3, 0.7)),
            Vec4::new(0.0, 0.0, 0.0, 1.0)
        );
    }

    #[test]
    fn a_missed_primary_ray_shows_the_background_at_its_screen_position() {
        let settings = four_colour_background();
        let scene = SceneSnapshot::empty();
        let ray = Ray {
            origin: Vec3::ZERO,
            direction: Vec3::NEG_Z,
            t_min: 0.0,
            t_max: f32::INFINITY,
        };
        let sample = shade_primary_at(
            &scene,
            &settings,
            &ray,
            None,
            Some(Vec2::new(0.9, 0.1)),
            None,
            &LightSampling::default(),
        );
        assert_eq!(sample.color, Vec4::new(0.0, 1.0, 0.0, 1.0));
        assert!(sample.hit.is_none());
        // Without a screen position only the colour is known.
        let sample = shade_primary(&scene, &settings, &ray, None, &LightSampling::default());
        assert_eq!(sample.color, Vec4::new(0.1, 0.2, 0.3, 1.0));
    }
}
