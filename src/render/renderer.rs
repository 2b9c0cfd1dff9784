//! Renderers. "default": direct lighting from directional, point and spot lights with shadows
//! (soft from lights with extent), ambient light, mirror and glossy reflections and
//! transparency. "fast": primary rays only with eye-light shading, for head-tracked
//! interactivity.

use std::sync::Arc;

use glam::{Vec2, Vec3, Vec4};

use crate::accel::{Ray, SceneHit, surface_epsilon};
use crate::device::Device;
use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};
use crate::device::status::ANARI_STATUS_INVALID_ARGUMENT;
use crate::render::bsdf::{
    clearcoat_fresnel, dielectric_f0, fallback_tangent, ggx_distribution, microfacet_albedo,
    microfacet_alpha, multiple_scattering, sample_glossy, schlick, sheen_albedo, sheen_brdf,
    smith_visibility, thin_film_fresnel,
};
use crate::render::surface_model::{HitInputs, SurfaceModel, evaluate_input};
use crate::scene::attributes::{
    ATTRIBUTE_DEFAULT, Interpolation, VALUE_ELEMENT_TYPES, read_values,
};
use crate::scene::geometry::Geometry;
use crate::scene::light::LightSampling;
use crate::scene::material::{Input, Material, MaterialKind};
use crate::scene::sampler::{Image, Wrap};
use crate::scene::volume::{VolumeIntegral, integrate};
use crate::scene::world::{InstanceData, SceneSnapshot};

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
    "direct lighting with shadows (soft from lights with extent), ambient light, mirror \
     reflections and transparency",
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
    fn view_direction(&self, ray: &Ray, point: Vec3, cyclopean: Option<Vec3>) -> Vec3 {
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
    fn background_for(&self, screen: Option<Vec2>) -> Vec4 {
        screen.map_or(self.background, |screen| self.background_at(screen))
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

struct ShadingPoint<'a> {
    point: Vec3,
    normal: Vec3,
    base_color: Vec3,
    opacity: f32,
    metallic: f32,
    roughness: f32,
    emissive: Vec3,
    /// Whether the ray arrived on the back of the surface (leaving a closed volume).
    back_face: bool,
    primitive_id: u32,
    object_id: u32,
    instance_id: u32,
    /// What the default renderer evaluates the material's other inputs from.
    material: &'a Material,
    attributes: [Option<Vec4>; 5],
    instance: &'a InstanceData,
    geometry: &'a Geometry,
    at: Option<Interpolation>,
}

#[inline(always)]
fn shading_point<'a>(scene: &'a SceneSnapshot, ray: &Ray, hit: &SceneHit) -> ShadingPoint<'a> {
    let instance = &scene.instances[hit.instance as usize];
    let surface = &instance.surfaces[hit.geometry as usize];
    let geometry = &surface.geometry;
    let material = &surface.material;
    let point = ray.origin + ray.direction * hit.t;

    let uses_attributes = material.uses_attributes;
    // Vertex weights only when something is interpolated (their index lookup is a likely
    // cache miss on large meshes).
    let at: Option<Interpolation> = (uses_attributes || geometry.has_shading_normals())
        .then(|| geometry.interpolation(hit.primitive, hit.uv));
    let primitive_id = geometry.primitive_id(hit.primitive);
    // Without shading normals the hit's world normal is already the one to shade with.
    let mut normal = match at.as_ref().filter(|_| geometry.has_shading_normals()) {
        Some(at) => (instance.normal_transform * geometry.shading_normal(at, hit.object_normal))
            .try_normalize()
            .unwrap_or(hit.normal),
        None => hit.normal,
    };
    // Shade the side the ray arrives from.
    let back_face = normal.dot(ray.direction) > 0.0;
    if back_face {
        normal = -normal;
    }

    let attributes: [Option<Vec4>; 5] = if let Some(at) = at.as_ref().filter(|_| uses_attributes) {
        std::array::from_fn(|slot| {
            geometry.attributes[slot]
                .evaluate(primitive_id, at)
                .or(instance.attributes[slot])
        })
    } else {
        [None; 5]
    };
    let scalar = |input: &Input, default: f32| {
        evaluate_input(input, &attributes, primitive_id).map_or(default, |v| v.x)
    };
    let base = evaluate_input(&material.base_color, &attributes, primitive_id)
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
        emissive: evaluate_input(&material.emissive, &attributes, primitive_id)
            .map_or(Vec3::ZERO, |v| v.truncate()),
        back_face,
        primitive_id,
        object_id: surface.id,
        instance_id: instance.id,
        material,
        attributes,
        instance,
        geometry,
        at,
    }
}

impl ShadingPoint<'_> {
    /// The material's layers at this point (the default renderer's; see [`SurfaceModel`]).
    fn surface_model(&self) -> SurfaceModel {
        let inputs = HitInputs {
            attributes: &self.attributes,
            primitive: self.primitive_id,
            normal: self.normal,
        };
        SurfaceModel::evaluate(self.material, &inputs, || {
            let linear = self.instance.transform.matrix3;
            let given = self.at.as_ref().and_then(|at| self.geometry.tangent(at));
            match given {
                Some(t) => (linear * t.truncate()).extend(t.w),
                None => fallback_tangent(self.normal, linear.x_axis.into(), linear.y_axis.into()),
            }
        })
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

/// Direct irradiance from the scene's lights at `point` on a surface of unit `normal`; lights
/// with extent are sampled at `sampling`'s point (one shadow ray each), so their soft shadows
/// converge over samples. `each` sees every unshadowed light's direction and irradiance.
fn direct_light(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    point: Vec3,
    normal: Vec3,
    sampling: &LightSampling,
    mut each: impl FnMut(Vec3, Vec3),
) -> Vec3 {
    let mut sum = Vec3::ZERO;
    for light in &scene.lights {
        let Some(incoming) = light.incoming_sampled(point, sampling) else {
            continue;
        };
        let cos = normal.dot(incoming.to_light);
        if cos <= 0.0 {
            continue;
        }
        if settings.shadows {
            let t_max = if incoming.distance.is_finite() {
                let light_point = point + incoming.to_light * incoming.distance;
                incoming.distance - surface_epsilon(light_point)
            } else {
                f32::INFINITY
            };
            // Cluster hook: shadow rays are tested on every rank.
            if crate::render::cluster::occluded(scene, &offset_ray(point, incoming.to_light, t_max))
            {
                continue;
            }
        }
        let irradiance = incoming.radiance * cos;
        each(incoming.to_light, irradiance);
        sum += irradiance;
    }
    sum
}

/// Radiance along a ray (the default renderer) of the pixel sample at `screen` (see
/// [`RendererSettings::background_at`]).
pub fn trace(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    depth: u32,
    screen: Option<Vec2>,
    sampling: &LightSampling,
) -> Vec4 {
    trace_seeing(
        scene,
        settings,
        ray,
        depth,
        screen,
        sampling,
        |background| background,
    )
}

/// [`trace`], where a ray that leaves the scene sees `beyond` of the background.
fn trace_seeing(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    depth: u32,
    screen: Option<Vec2>,
    sampling: &LightSampling,
    beyond: impl FnOnce(Vec4) -> Vec4,
) -> Vec4 {
    // Cluster hook: the closest hit of every rank; another rank's hit is shaded there.
    let hit = match crate::render::cluster::closest(scene, ray, depth, screen, sampling) {
        Ok(hit) => hit,
        Err(radiance) => return radiance,
    };
    let volume = volumes_in_front(scene, ray, hit.as_ref());
    if let Some(volume) = volume.filter(|v| v.transmittance == 0.0) {
        return volume.over(Vec4::ZERO);
    }
    let behind = match hit {
        None => beyond(settings.background_for(screen)),
        Some(hit) => {
            let sp = shading_point(scene, ray, &hit);
            shade(
                scene,
                settings,
                ray,
                ray.direction,
                &sp,
                depth,
                screen,
                sampling,
            )
            .extend(1.0)
        }
    };
    volume.map_or(behind, |v| v.over(behind))
}

/// The volumes between the ray's start and its surface hit (or its end).
fn volumes_in_front(
    scene: &SceneSnapshot,
    ray: &Ray,
    hit: Option<&SceneHit>,
) -> Option<VolumeIntegral> {
    let t_end = hit.map_or(ray.t_max, |h| h.t);
    integrate(&scene.volumes, ray.origin, ray.direction, ray.t_min, t_end)
}

/// The default renderer's shading, glTF's layering (glTF 2.0 Appendix B and the
/// KHR_materials_* extensions): a metal and a dielectric mixed by metallic, the dielectric a
/// diffuse base under a Fresnel-weighted reflection (specular, specularColor, ior) or, by
/// transmission, glass; sheen over that, emission, and a clearcoat over everything. Each
/// layer passes on to those below what it does not reflect, so no surface returns more light
/// than arrives. Reflection lobes are GGX microfacet lobes (α = roughness²): F·D·V per light,
/// and one reflection drawn from the visible normals per sample (a mirror at roughness 0).
/// `view`: the unit direction view-dependent terms look along (see
/// [`RendererSettings::view_direction`]).
#[allow(clippy::too_many_arguments)]
fn shade(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    view: Vec3,
    sp: &ShadingPoint,
    depth: u32,
    screen: Option<Vec2>,
    sampling: &LightSampling,
) -> Vec3 {
    let model = sp.surface_model();
    let normal = model.normal;
    let to_viewer = -view;
    let cos_view = to_viewer.dot(normal).clamp(0.0, 1.0);
    let can_trace = depth < settings.max_ray_depth;
    // Ambient light is radiance from every direction: it arrives as irradiance π·L, where the
    // occlusion map lets it.
    let ambient = settings.ambient * model.occlusion;
    let sheen_on = model.sheen_color != Vec3::ZERO;
    // Non-metallic: a diffuse base under a reflection, or by `transmission` a clear dielectric.
    let dielectric_share = 1.0 - sp.metallic;
    let opaque = dielectric_share * (1.0 - model.transmission);
    let specular_on = opaque > 0.0 && model.specular > 0.0;
    let metal_on = sp.metallic > 0.0;
    let f0 = dielectric_f0(model.ior, model.specular_color);
    // KHR_materials_specular's fresnel_mix: the reflection's share at v·h = `cos`.
    let dielectric_fresnel =
        |cos: f32| model.specular * iridescent(&model, schlick(f0, 1.0, cos), f0, cos);
    // glTF's conductor_fresnel: Schlick towards white from the base colour.
    let metal_fresnel =
        |cos: f32| iridescent(&model, schlick(sp.base_color, 1.0, cos), sp.base_color, cos);
    let alpha = microfacet_alpha(sp.roughness);
    // Only a reflecting lobe needs the microfacet terms (a matte surface has none).
    let glossy = sp.roughness > 0.0 && (specular_on || metal_on);
    let coat_on = model.clearcoat > 0.0;
    let coat_alpha = microfacet_alpha(model.clearcoat_roughness);
    let coat_glossy = coat_on && model.clearcoat_roughness > 0.0;
    let coat_shares_normal = model.coat_normal == normal;
    // Single scattering's albedo E of each lobe seen from here, and the compensation that
    // restores what it drops (see `multiple_scattering`): the reflection's and the coat's
    // lobes are scaled to albedo 1 (their Fresnel term is their mixing weight), the metal's by
    // its colour.
    let albedo = if glossy {
        microfacet_albedo(cos_view, sp.roughness)
    } else {
        1.0
    };
    let metal_compensation = if glossy {
        multiple_scattering(albedo, sp.base_color)
    } else {
        Vec3::ONE
    };
    // What needs each light's direction; the diffuse base alone does not (`direct_light` sums
    // its irradiance).
    let lobes_per_light =
        sheen_on || specular_on || metal_on || (coat_glossy && coat_shares_normal);
    let coat_albedo = if coat_glossy {
        microfacet_albedo(
            to_viewer.dot(model.coat_normal).clamp(0.0, 1.0),
            model.clearcoat_roughness,
        )
    } else {
        1.0
    };

    // Direct light, per light: the diffuse base keeps what the dielectric's reflection at that
    // light's half vector leaves, the microfacet lobes add F·D·V·(n·l)·E (glTF Appendix B).
    let mut sheen = Vec3::ZERO;
    let mut diffuse_irradiance = Vec3::ZERO;
    let mut specular_direct = Vec3::ZERO;
    let mut metal_direct = Vec3::ZERO;
    let mut coat_direct = Vec3::ZERO;
    let direct = direct_light(
        scene,
        settings,
        sp.point,
        normal,
        sampling,
        |to_light, irradiance| {
            if !lobes_per_light {
                return;
            }
            let cos_light = to_light.dot(normal);
            let half = (to_light + to_viewer).normalize_or(normal);
            let cos_half = half.dot(normal);
            let cos_view_half = to_viewer.dot(half).clamp(0.0, 1.0);
            if sheen_on {
                sheen +=
                    irradiance * sheen_brdf(model.sheen_roughness, cos_view, cos_light, cos_half);
            }
            let microfacet = if glossy {
                ggx_distribution(alpha, cos_half) * smith_visibility(alpha, cos_light, cos_view)
                    / albedo
            } else {
                0.0
            };
            if specular_on {
                let fresnel = dielectric_fresnel(cos_view_half);
                diffuse_irradiance += irradiance * (1.0 - fresnel.max_element());
                specular_direct += irradiance * fresnel * microfacet;
            }
            if metal_on && glossy {
                metal_direct += irradiance
                    * metal_fresnel(cos_view_half)
                    * (microfacet * albedo)
                    * metal_compensation;
            }
            if coat_glossy && coat_shares_normal {
                coat_direct += irradiance
                    * ggx_distribution(coat_alpha, cos_half)
                    * smith_visibility(coat_alpha, cos_light, cos_view)
                    / coat_albedo;
            }
        },
    );

    // Indirect light: one reflection, drawn from the lobe (a mirror at roughness 0), serves
    // the metal and the dielectric's reflection alike.
    let u = sampling.reflection_point(depth);
    let reflect = |normal: Vec3, roughness: f32, alpha: f32| {
        reflection(
            scene, settings, sp, view, normal, roughness, alpha, ambient, depth, screen, sampling,
            u,
        )
    };
    let base_reflection = if can_trace && (specular_on || metal_on) {
        reflect(normal, sp.roughness, alpha)
    } else {
        None
    };
    // Uniform light (ambient, and what the reflection sees) meets the microfacet the
    // reflection sampled: the normal itself at roughness 0.
    let cos_sampled = base_reflection.map_or(cos_view, |r| to_viewer.dot(r.half).clamp(0.0, 1.0));

    let mut color = Vec3::ZERO;
    if opaque > 0.0 {
        // Lambertian: albedo/π × irradiance.
        let lambert = sp.base_color * std::f32::consts::FRAC_1_PI;
        if specular_on {
            let fresnel = dielectric_fresnel(cos_sampled);
            let keep = 1.0 - fresnel.max_element();
            let diffuse =
                keep * (lambert * (ambient * std::f32::consts::PI)) + lambert * diffuse_irradiance;
            let reflected = base_reflection.map_or(Vec3::ZERO, |r| fresnel * r.radiance);
            color += opaque * (diffuse + specular_direct + reflected);
        } else {
            color += opaque * (lambert * (direct + ambient * std::f32::consts::PI));
        }
    }
    if metal_on {
        let reflected = base_reflection.map_or(Vec3::ZERO, |r| {
            metal_fresnel(cos_sampled) * (albedo * metal_compensation) * r.radiance
        });
        color += sp.metallic * (metal_direct + reflected);
    }
    let clear = dielectric_share * model.transmission;
    if clear > 0.0 && can_trace {
        color += clear
            * dielectric(
                scene, settings, ray, view, sp, &model, depth, screen, sampling,
            );
    }
    if sheen_on {
        // KHR_materials_sheen: the sheen reflects E of uniform light; what lies below loses
        // max(sheenColor)·E.
        let albedo = sheen_albedo(cos_view, model.sheen_roughness);
        color = color * (1.0 - model.sheen_color.max_element() * albedo)
            + model.sheen_color * (sheen + albedo * ambient);
    }
    color += sp.emissive;
    if coat_on {
        // KHR_materials_clearcoat: a dielectric of index 1.5 over everything (emission
        // included), along its own normal; its Fresnel term at n_c·v weighs the layering
        // (the extension's fresnel_coat), its lobe is D·V.
        let coat_normal = model.coat_normal;
        let cos_coat = to_viewer.dot(coat_normal).clamp(0.0, 1.0);
        let reflected = model.clearcoat * clearcoat_fresnel(cos_coat);
        if coat_glossy && !coat_shares_normal {
            let cos_coat_view = to_viewer.dot(coat_normal);
            direct_light(
                scene,
                settings,
                sp.point,
                coat_normal,
                sampling,
                |to_light, irradiance| {
                    let half = (to_light + to_viewer).normalize_or(coat_normal);
                    coat_direct += irradiance
                        * ggx_distribution(coat_alpha, half.dot(coat_normal))
                        * smith_visibility(coat_alpha, to_light.dot(coat_normal), cos_coat_view)
                        / coat_albedo;
                },
            );
        }
        let mut coat = coat_direct;
        if can_trace {
            let same_lobe = coat_shares_normal
                && model.clearcoat_roughness == sp.roughness
                && base_reflection.is_some();
            let image = if same_lobe {
                base_reflection
            } else {
                reflect(coat_normal, model.clearcoat_roughness, coat_alpha)
            };
            if let Some(image) = image {
                coat += image.radiance;
            }
        }
        color = color * (1.0 - reflected) + coat * reflected;
    }
    if model.volume && sp.back_face && model.log_attenuation != Vec3::ZERO {
        // What comes back along this ray crossed the volume from `ray`'s start to here.
        let travelled = (sp.point - ray.origin).length();
        color *= (model.log_attenuation * travelled).exp();
    }
    if sp.opacity < 1.0 && can_trace {
        let behind = traced_from(
            scene,
            settings,
            sp.point,
            ray.direction,
            depth,
            screen,
            sampling,
        );
        color = color * sp.opacity + behind * (1.0 - sp.opacity);
    }
    color
}

/// KHR_materials_iridescence: the Fresnel term `fresnel` of a base of normal-incidence
/// reflectance `f0`, mixed by the iridescence factor with that of the base under the thin film.
fn iridescent(model: &SurfaceModel, fresnel: Vec3, f0: Vec3, cos_view: f32) -> Vec3 {
    if model.iridescence <= 0.0 {
        return fresnel;
    }
    let film = thin_film_fresnel(
        model.iridescence_ior,
        model.iridescence_thickness,
        cos_view,
        f0,
    );
    fresnel.lerp(film, model.iridescence)
}

/// A reflection traced from a lobe: the microfacet normal it reflects off and the radiance
/// arriving along it. Drawn in proportion to the lobe (see
/// [`crate::render::bsdf::sample_glossy`]), it stands for the lobe's whole albedo.
#[derive(Clone, Copy)]
struct Reflection {
    half: Vec3,
    radiance: Vec3,
}

/// The reflection of the lobe of `roughness` (α = `alpha`) around `normal` at `sp`, seen along
/// `view`, drawn at `u` (then from `sampling`'s further numbers) and traced one bounce
/// deeper. Roughness 0 is the exact mirror. A rough reflection that leaves the scene sees the
/// background and, by the roughness, the ambient light (where the mirror sees only the
/// background and the diffuse base only the ambient light), so a white background and
/// ambient light of the same radiance are one uniform surrounding. None where no reflection
/// was drawn.
#[allow(clippy::too_many_arguments)]
fn reflection(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    sp: &ShadingPoint,
    view: Vec3,
    normal: Vec3,
    roughness: f32,
    alpha: f32,
    ambient: Vec3,
    depth: u32,
    screen: Option<Vec2>,
    sampling: &LightSampling,
    u: Vec2,
) -> Option<Reflection> {
    if roughness <= 0.0 {
        let reflected = view - 2.0 * view.dot(normal) * normal;
        return Some(Reflection {
            half: normal,
            radiance: traced_from(
                scene, settings, sp.point, reflected, depth, screen, sampling,
            ),
        });
    }
    let sample = sample_glossy(normal, -view, alpha, u, sampling.reflection_numbers(depth))?;
    let ray = offset_ray(sp.point, sample.direction, f32::INFINITY);
    let beyond = |background: Vec4| {
        (background.truncate() * (1.0 - roughness) + ambient * roughness).extend(background.w)
    };
    let radiance = trace_seeing(scene, settings, &ray, depth + 1, screen, sampling, beyond);
    Some(Reflection {
        half: sample.half,
        radiance: radiance.truncate(),
    })
}

/// Radiance arriving at `point` from `direction` (a secondary ray one bounce deeper).
fn traced_from(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    point: Vec3,
    direction: Vec3,
    depth: u32,
    screen: Option<Vec2>,
    sampling: &LightSampling,
) -> Vec3 {
    let ray = offset_ray(point, direction, f32::INFINITY);
    trace(scene, settings, &ray, depth + 1, screen, sampling).truncate()
}

/// Radiance from a clear dielectric surface: Fresnel-weighted reflection (along `view`, so
/// cyclopean lighting applies to it) and transmission (along the ray's own direction, refracted
/// where the surface bounds a volume, straight through a thin wall; tinted by the base colour),
/// total internal reflection where refraction is impossible.
#[allow(clippy::too_many_arguments)]
fn dielectric(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    view: Vec3,
    sp: &ShadingPoint,
    model: &SurfaceModel,
    depth: u32,
    screen: Option<Vec2>,
    sampling: &LightSampling,
) -> Vec3 {
    // Relative index across the surface, in the direction the ray travels.
    let eta = if model.volume && sp.back_face {
        model.ior
    } else {
        1.0 / model.ior
    };
    let normal = model.normal;
    let cos_in = (-ray.direction.dot(normal)).clamp(0.0, 1.0);
    let (reflectance, refracted) = fresnel_refraction(ray.direction, normal, cos_in, eta);
    let reflected = view - 2.0 * view.dot(normal) * normal;
    let mut color = Vec3::ZERO;
    let incoming = |direction| {
        traced_from(
            scene, settings, sp.point, direction, depth, screen, sampling,
        )
    };
    if reflectance > 0.0 {
        color += reflectance * incoming(reflected);
    }
    if reflectance < 1.0 {
        let through = if model.volume {
            refracted
        } else {
            ray.direction
        };
        color += (1.0 - reflectance) * sp.base_color * incoming(through);
    }
    color
}

/// The exact Fresnel reflectance of unpolarised light arriving along `direction` at a surface
/// of normal `normal` (facing the ray; `cos_in` = −direction·normal) with relative index `eta`
/// (n₁/n₂), and the refracted direction (any, when the reflectance is 1: total internal
/// reflection).
fn fresnel_refraction(direction: Vec3, normal: Vec3, cos_in: f32, eta: f32) -> (f32, Vec3) {
    let sin2_out = eta * eta * (1.0 - cos_in * cos_in);
    if sin2_out >= 1.0 {
        return (1.0, direction);
    }
    let cos_out = (1.0 - sin2_out).sqrt();
    let s = (eta * cos_in - cos_out) / (eta * cos_in + cos_out);
    let p = (cos_in - eta * cos_out) / (cos_in + eta * cos_out);
    let refracted = (direction * eta + normal * (eta * cos_in - cos_out)).normalize_or(direction);
    (0.5 * (s * s + p * p), refracted)
}

/// One primary sample: colour plus the auxiliary channel values.
pub fn primary_sample(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    sampling: &LightSampling,
) -> Sample {
    shade_primary(scene, settings, ray, scene.bvh.intersect(ray), sampling)
}

/// A primary sample whose closest hit is already known (e.g. traced in a packet), with the
/// background colour (not the background image) where nothing is hit.
pub fn shade_primary(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    hit: Option<SceneHit>,
    sampling: &LightSampling,
) -> Sample {
    shade_primary_at(scene, settings, ray, hit, None, None, sampling)
}

/// A primary sample whose closest hit is already known. `screen` is the sample's position in
/// the frame (see `RendererSettings::background_at`), which picks the background image's
/// colour; without it the background colour is used. `sampling` picks the points of lights
/// with extent. `cyclopean`: the camera ray's point midway between its stereo pair's eyes.
pub fn shade_primary_at(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    hit: Option<SceneHit>,
    screen: Option<Vec2>,
    cyclopean: Option<Vec3>,
    sampling: &LightSampling,
) -> Sample {
    // Cluster hook: a primary sample of a render across MPI ranks is shaded by its hit's rank.
    if let Some(sample) =
        crate::render::cluster::primary(scene, ray, hit.as_ref(), screen, cyclopean, sampling)
    {
        return sample;
    }
    let Some(volume) = volumes_in_front(scene, ray, hit.as_ref()) else {
        return shade_surface_primary(scene, settings, ray, hit, screen, cyclopean, sampling);
    };
    // What lies behind matters only if light from there gets through.
    let behind = if volume.transmittance > 0.0 {
        shade_surface_primary(scene, settings, ray, hit, screen, cyclopean, sampling)
    } else {
        Sample {
            color: Vec4::ZERO,
            hit: None,
        }
    };
    // The channels describe the first thing seen: the volume where it absorbs anything.
    let first = volume.first.map(|v| PrimaryHit {
        t: v.t,
        point: ray.origin + ray.direction * v.t,
        primitive_id: u32::MAX,
        object_id: v.object_id,
        instance_id: v.instance_id,
        albedo: v.color,
        normal: Vec3::ZERO,
    });
    Sample {
        color: volume.over(behind.color),
        hit: first.or(behind.hit),
    }
}

/// The fast renderer's shading: a light at the camera, so what faces the viewer is brightest.
/// `view`: the unit direction the light (and the viewer) looks along.
#[inline(always)]
fn eye_light(view: Vec3, sp: &ShadingPoint) -> Vec3 {
    let facing = (-view).dot(sp.normal).max(0.0);
    sp.base_color * (0.2 + 0.8 * facing) + sp.emissive
}

/// The fast renderer's colour for a primary ray whose closest surface hit is known, when the
/// scene has no volumes and no channel needs the hit's details: what [`shade_primary_at`]
/// gives then, without building the details.
pub fn fast_surface_color(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    hit: Option<&SceneHit>,
    screen: impl FnOnce() -> Vec2,
    cyclopean: Option<Vec3>,
) -> Vec4 {
    debug_assert!(settings.fast && scene.volumes.is_empty());
    // Cluster hook: as in `shade_primary_at`.
    let screen = match crate::render::cluster::fast_primary(scene, ray, hit, screen, cyclopean) {
        Ok(screen) => screen,
        Err(color) => return color,
    };
    match hit {
        Some(hit) => {
            let sp = shading_point(scene, ray, hit);
            eye_light(settings.view_direction(ray, sp.point, cyclopean), &sp).extend(1.0)
        }
        None => settings.background_for(Some(screen())),
    }
}

/// The surface (or background) part of a primary sample.
fn shade_surface_primary(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    hit: Option<SceneHit>,
    screen: Option<Vec2>,
    cyclopean: Option<Vec3>,
    sampling: &LightSampling,
) -> Sample {
    let Some(hit) = hit else {
        return Sample {
            color: settings.background_for(screen),
            hit: None,
        };
    };
    let sp = shading_point(scene, ray, &hit);
    let view = settings.view_direction(ray, sp.point, cyclopean);
    let color = if settings.fast {
        eye_light(view, &sp)
    } else {
        shade(scene, settings, ray, view, &sp, 0, screen, sampling)
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

#[cfg(test)]
mod tests {
    use super::*;

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
