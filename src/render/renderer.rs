//! Renderers. "default": direct lighting from directional, point and spot lights with hard
//! shadows, ambient light, mirror reflections and transparency. "fast": primary rays only with
//! eye-light shading, for head-tracked interactivity.

use glam::{Vec3, Vec4};

use crate::accel::{Ray, SceneHit, surface_epsilon};
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};
use crate::scene::attributes::{ATTRIBUTE_DEFAULT, Interpolation};
use crate::scene::material::MaterialKind;
use crate::scene::world::SceneSnapshot;

const BACKGROUND: ParamSpec = ParamSpec::new(
    "background",
    &[ANARI_FLOAT32_VEC4],
    "colour of pixels where no surface is hit (linear RGBA)",
)
.default(SpecValue::Floats(&[0.0, 0.0, 0.0, 1.0]));
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
const PIXEL_SAMPLES: ParamSpec = ParamSpec::new(
    "pixelSamples",
    &[ANARI_INT32, ANARI_UINT32],
    "samples per pixel per frame, jittered deterministically",
)
.default(SpecValue::Int(1))
.range(SpecValue::Int(1), SpecValue::Int(1024));

pub const DEFAULT: ObjectSpec = ObjectSpec::new(
    ANARI_RENDERER,
    "default",
    "direct lighting with hard shadows, ambient light, mirror reflections and transparency",
    &[
        BACKGROUND,
        AMBIENT_COLOR,
        AMBIENT_RADIANCE,
        PIXEL_SAMPLES,
        ParamSpec::new(
            "maxRayDepth",
            &[ANARI_INT32, ANARI_UINT32],
            "maximum number of reflection and transparency bounces",
        )
        .default(SpecValue::Int(5))
        .range(SpecValue::Int(0), SpecValue::Int(64)),
        ParamSpec::new("shadows", &[ANARI_BOOL], "whether lights cast hard shadows")
            .default(SpecValue::Bool(true)),
    ],
)
.extensions(&[
    "ANARI_KHR_RENDERER_AMBIENT_LIGHT",
    "ANARI_KHR_RENDERER_BACKGROUND_COLOR",
]);

pub const FAST: ObjectSpec = ObjectSpec::new(
    ANARI_RENDERER,
    "fast",
    "for head-tracked interactivity: primary rays only, shaded by a light at the eye (no \
     shadows, reflections or scene lights)",
    &[BACKGROUND, PIXEL_SAMPLES],
);

#[derive(Clone, Debug, PartialEq)]
pub struct RendererSettings {
    pub fast: bool,
    pub background: Vec4,
    pub ambient: Vec3,
    pub pixel_samples: u32,
    pub max_ray_depth: u32,
    pub shadows: bool,
}

impl Default for RendererSettings {
    fn default() -> Self {
        RendererSettings {
            fast: false,
            background: Vec4::new(0.0, 0.0, 0.0, 1.0),
            ambient: Vec3::ZERO,
            pixel_samples: 1,
            max_ray_depth: 5,
            shadows: true,
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
            ambient: p.get_vec3("ambientColor").unwrap_or(Vec3::ONE)
                * p.get_f32("ambientRadiance").unwrap_or(0.0),
            pixel_samples: int("pixelSamples", 1).clamp(1, 1024),
            max_ray_depth: int("maxRayDepth", 5).min(64),
            shadows: p.get_bool("shadows").unwrap_or(true),
        }
    }
}

/// What one primary sample produced.
#[derive(Clone, Copy, Debug)]
pub struct Sample {
    pub color: Vec4,
    pub hit: Option<PrimaryHit>,
}

/// Per-hit values for the auxiliary channels.
#[derive(Clone, Copy, Debug)]
pub struct PrimaryHit {
    pub t: f32,
    pub point: Vec3,
    pub primitive_id: u32,
    pub object_id: u32,
    pub instance_id: u32,
    pub albedo: Vec3,
    pub normal: Vec3,
}

struct ShadingPoint {
    point: Vec3,
    normal: Vec3,
    base_color: Vec3,
    opacity: f32,
    metallic: f32,
    roughness: f32,
    emissive: Vec3,
    primitive_id: u32,
    object_id: u32,
    instance_id: u32,
}

fn shading_point(scene: &SceneSnapshot, ray: &Ray, hit: &SceneHit) -> ShadingPoint {
    let instance = &scene.instances[hit.instance as usize];
    let surface = &instance.surfaces[hit.geometry as usize];
    let geometry = &surface.geometry;
    let material = &surface.material;
    let point = ray.origin + ray.direction * hit.t;

    let at: Interpolation = geometry.interpolation(hit.primitive, hit.uv);
    let primitive_id = geometry.primitive_id(hit.primitive);
    let object_normal = geometry.shading_normal(&at, hit.object_normal);
    let mut normal = (instance.normal_transform * object_normal)
        .try_normalize()
        .unwrap_or(hit.normal);
    // Shade the side the ray arrives from.
    if normal.dot(ray.direction) > 0.0 {
        normal = -normal;
    }

    let attributes: [Option<Vec4>; 5] = if material.uses_attributes() {
        std::array::from_fn(|slot| {
            geometry.attributes[slot]
                .evaluate(primitive_id, &at)
                .or(instance.attributes[slot])
        })
    } else {
        [None; 5]
    };
    let scalar = |input: &crate::scene::material::Input, default: f32| {
        input.evaluate(&attributes).map_or(default, |v| v.x)
    };
    let base = material
        .base_color
        .evaluate(&attributes)
        .unwrap_or(ATTRIBUTE_DEFAULT);
    let is_matte = material.kind == MaterialKind::Matte;
    ShadingPoint {
        point,
        normal,
        base_color: base.truncate(),
        opacity: material
            .alpha
            .apply(scalar(&material.opacity, 1.0) * base.w),
        metallic: if is_matte {
            0.0
        } else {
            scalar(&material.metallic, 1.0).clamp(0.0, 1.0)
        },
        roughness: if is_matte {
            1.0
        } else {
            scalar(&material.roughness, 1.0).clamp(0.0, 1.0)
        },
        emissive: material
            .emissive
            .evaluate(&attributes)
            .map_or(Vec3::ZERO, |v| v.truncate()),
        primitive_id,
        object_id: surface.id,
        instance_id: instance.id,
    }
}

fn offset_ray(origin: Vec3, direction: Vec3, t_max: f32) -> Ray {
    Ray {
        origin,
        direction,
        t_min: surface_epsilon(origin),
        t_max,
    }
}

/// Direct light from the scene's lights at a point.
fn direct_light(scene: &SceneSnapshot, settings: &RendererSettings, sp: &ShadingPoint) -> Vec3 {
    let mut sum = Vec3::ZERO;
    for light in &scene.lights {
        let Some(incoming) = light.incoming(sp.point) else {
            continue;
        };
        let cos = sp.normal.dot(incoming.to_light);
        if cos <= 0.0 {
            continue;
        }
        if settings.shadows {
            let t_max = if incoming.distance.is_finite() {
                let light_point = sp.point + incoming.to_light * incoming.distance;
                incoming.distance - surface_epsilon(light_point)
            } else {
                f32::INFINITY
            };
            if scene
                .bvh
                .occluded(&offset_ray(sp.point, incoming.to_light, t_max))
            {
                continue;
            }
        }
        sum += incoming.radiance * cos;
    }
    sum
}

/// Radiance along a ray (the default renderer).
pub fn trace(scene: &SceneSnapshot, settings: &RendererSettings, ray: &Ray, depth: u32) -> Vec4 {
    let Some(hit) = scene.bvh.intersect(ray) else {
        return settings.background;
    };
    let sp = shading_point(scene, ray, &hit);
    shade(scene, settings, ray, &sp, depth).extend(1.0)
}

fn shade(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    sp: &ShadingPoint,
    depth: u32,
) -> Vec3 {
    let diffuse_weight = 1.0 - sp.metallic;
    // Ambient light is radiance from every direction: it arrives as irradiance π·L.
    let light = direct_light(scene, settings, sp) + settings.ambient * std::f32::consts::PI;
    // Lambertian: albedo/π × irradiance.
    let mut color = sp.base_color * std::f32::consts::FRAC_1_PI * light * diffuse_weight;
    color += sp.emissive;
    if sp.metallic > 0.0 && depth < settings.max_ray_depth {
        // Smooth metals reflect the scene; rough ones fall back to their diffuse look.
        let reflectivity = sp.metallic * (1.0 - sp.roughness);
        if reflectivity > 0.0 {
            let reflected = ray.direction - 2.0 * ray.direction.dot(sp.normal) * sp.normal;
            let incoming = trace(
                scene,
                settings,
                &offset_ray(sp.point, reflected, f32::INFINITY),
                depth + 1,
            );
            color += sp.base_color * incoming.truncate() * reflectivity;
        }
        let rough_metal = sp.metallic * sp.roughness;
        color += sp.base_color * std::f32::consts::FRAC_1_PI * light * rough_metal;
    }
    if sp.opacity < 1.0 && depth < settings.max_ray_depth {
        let behind = trace(
            scene,
            settings,
            &offset_ray(sp.point, ray.direction, f32::INFINITY),
            depth + 1,
        );
        color = color * sp.opacity + behind.truncate() * (1.0 - sp.opacity);
    }
    color
}

/// One primary sample: colour plus the auxiliary channel values.
pub fn primary_sample(scene: &SceneSnapshot, settings: &RendererSettings, ray: &Ray) -> Sample {
    shade_primary(scene, settings, ray, scene.bvh.intersect(ray))
}

/// A primary sample whose closest hit is already known (e.g. traced in a packet).
pub fn shade_primary(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    hit: Option<SceneHit>,
) -> Sample {
    let Some(hit) = hit else {
        return Sample {
            color: settings.background,
            hit: None,
        };
    };
    let sp = shading_point(scene, ray, &hit);
    let color = if settings.fast {
        // Eye light: a light at the camera, so what faces the viewer is brightest.
        let facing = (-ray.direction).dot(sp.normal).max(0.0);
        sp.base_color * (0.2 + 0.8 * facing) + sp.emissive
    } else {
        shade(scene, settings, ray, &sp, 0)
    };
    Sample {
        color: color.extend(1.0),
        hit: Some(PrimaryHit {
            t: hit.t,
            point: sp.point,
            primitive_id: sp.primitive_id,
            object_id: sp.object_id,
            instance_id: sp.instance_id,
            albedo: sp.base_color,
            normal: sp.normal,
        }),
    }
}
