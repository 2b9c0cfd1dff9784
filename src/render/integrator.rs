//! The shading integrator: radiance along primary and secondary rays for the renderers'
//! settings, direct light with shadows, layered glTF materials, reflections, transmission
//! and volumes (the fast renderer's eye light: `eye_light`).

use glam::{Vec2, Vec3, Vec4};

use crate::accel::{Ray, SceneHit, surface_epsilon};
use crate::render::ambient::reaches_ambient;
use crate::render::bsdf::{
    clearcoat_fresnel, dielectric_f0, fallback_tangent, ggx_distribution, microfacet_albedo,
    microfacet_alpha, multiple_scattering, sample_glossy, schlick, sheen_albedo, sheen_brdf,
    smith_visibility, thin_film_fresnel,
};
use crate::render::eye_light::eye_light;
use crate::render::renderer::RendererSettings;
use crate::render::surface_model::{HitInputs, SurfaceModel, evaluate_input};
use crate::render::volume_lighting::{lit_volumes, shadow_transmittance};
use crate::render::{block_shadows, cluster};
use crate::scene::attributes::{ATTRIBUTE_DEFAULT, Interpolation};
use crate::scene::geometry::Geometry;
use crate::scene::light::{Incoming, Light, LightSampling};
use crate::scene::material::{Input, Material, MaterialKind};
use crate::scene::volume::{VolumeIntegral, integrate};
use crate::scene::world::{InstanceData, SceneSnapshot};

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

pub(super) struct ShadingPoint<'a> {
    pub(super) point: Vec3,
    pub(super) normal: Vec3,
    pub(super) base_color: Vec3,
    opacity: f32,
    metallic: f32,
    roughness: f32,
    pub(super) emissive: Vec3,
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
pub(super) fn shading_point<'a>(
    scene: &'a SceneSnapshot,
    ray: &Ray,
    hit: &SceneHit,
) -> ShadingPoint<'a> {
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
    let normal = match at.as_ref().filter(|_| geometry.has_shading_normals()) {
        Some(at) => (instance.normal_transform * geometry.shading_normal(at, hit.object_normal))
            .try_normalize()
            .unwrap_or(hit.normal),
        None => hit.normal,
    };
    let (normal, back_face) = facing_ray(normal, ray.direction);

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

/// `normal` turned to the side a ray along `direction` arrives from, and whether it was
/// turned (the ray arrived on the back of the surface).
#[inline(always)]
pub(super) fn facing_ray(normal: Vec3, direction: Vec3) -> (Vec3, bool) {
    let back_face = normal.dot(direction) > 0.0;
    (if back_face { -normal } else { normal }, back_face)
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

/// The shadow ray from `point` on a surface towards a light's sample `incoming`.
pub(crate) fn shadow_ray(point: Vec3, incoming: &Incoming) -> Ray {
    let t_max = if incoming.distance.is_finite() {
        let light_point = point + incoming.to_light * incoming.distance;
        incoming.distance - surface_epsilon(light_point)
    } else {
        f32::INFINITY
    };
    offset_ray(point, incoming.to_light, t_max)
}

/// Direct irradiance from the scene's lights at `point` on a surface of unit `normal`; lights
/// with extent are sampled at `sampling`'s point (one shadow ray each), so their soft shadows
/// converge over samples. `each` sees every unshadowed light's direction and irradiance, and
/// for an environment the density its sample was drawn with (see [`Lobe`]).
fn direct_light(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    point: Vec3,
    normal: Vec3,
    sampling: &LightSampling,
    mut each: impl FnMut(Vec3, Vec3, Option<f32>),
) -> Vec3 {
    let mut sum = Vec3::ZERO;
    for (index, light) in scene.lights.iter().enumerate() {
        let Some(incoming) = light.incoming_sampled(point, sampling) else {
            continue;
        };
        let cos = normal.dot(incoming.to_light);
        if cos <= 0.0 {
            continue;
        }
        let mut visibility = 1.0;
        if settings.shadows {
            let shadow = shadow_ray(point, &incoming);
            // The answer traced with the block's packets, or (cluster hook) every rank's; volumes
            // are then marched here.
            if block_shadows::occluded(scene, index, &shadow) {
                continue;
            }
            let (t_min, direction, t_max) = (shadow.t_min, incoming.to_light, shadow.t_max);
            visibility = shadow_transmittance(scene, point, direction, t_min, t_max, sampling);
        }
        let irradiance = incoming.radiance * cos * visibility;
        each(incoming.to_light, irradiance, incoming.pdf);
        sum += irradiance;
    }
    sum
}

/// The share of the ambient light that reaches `point` on a surface of unit `normal`: one
/// ray, drawn in proportion to the cosine (as a diffuse surface gathers uniform light), that
/// either leaves unoccluded within the renderer's `ambientOcclusionDistance` (the volumes'
/// transmittance on the way) or meets an opaque surface (0), so the mean over samples is the
/// cosine-weighted share of the hemisphere's light that gets through.
fn ambient_visibility(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    point: Vec3,
    normal: Vec3,
    depth: u32,
    sampling: &LightSampling,
) -> f32 {
    let reach = settings.ambient_occlusion_distance;
    if settings.ambient == Vec3::ZERO || reach <= 0.0 {
        return 1.0;
    }
    let u = sampling.ambient_point(depth);
    let radius = u.x.sqrt();
    let angle = std::f32::consts::TAU * u.y;
    let (tangent, bitangent) = normal.any_orthonormal_pair();
    let direction = (tangent * (radius * angle.cos())
        + bitangent * (radius * angle.sin())
        + normal * (1.0 - u.x).max(0.0).sqrt())
    .normalize_or(normal);
    let ray = offset_ray(point, direction, reach);
    if !reaches_ambient(scene, &ray) {
        return 0.0;
    }
    shadow_transmittance(scene, point, direction, ray.t_min, reach, sampling)
}

/// A glossy lobe that drew a reflection: GGX of `alpha` around `normal`, seen from
/// `to_viewer`, whose draws are distributed as D·V·(n·l) / E (see
/// [`crate::render::bsdf::sample_glossy`]). An environment is reached both by its light
/// samples and by such reflections; each estimate is weighed by the power heuristic
/// (multiple importance sampling), so a near-mirror (whose lobe finds the light better) and a
/// rough surface (whose light samples do) both converge without fireflies.
#[derive(Clone, Copy)]
struct Lobe {
    normal: Vec3,
    to_viewer: Vec3,
    alpha: f32,
    albedo: f32,
}

impl Lobe {
    /// The density per solid angle of a reflection towards unit `to_light`.
    fn pdf(&self, to_light: Vec3) -> f32 {
        let cos_light = to_light.dot(self.normal);
        // As the lobe is sampled: a view below the horizon is seen from just above.
        let cos_view = self.to_viewer.dot(self.normal).max(1e-4);
        if cos_light <= 0.0 {
            return 0.0;
        }
        let half = (to_light + self.to_viewer).normalize_or(self.normal);
        ggx_distribution(self.alpha, half.dot(self.normal))
            * smith_visibility(self.alpha, cos_light, cos_view)
            * cos_light
            / self.albedo.max(1e-3)
    }

    /// The weight of a light sample of density `light_pdf` (None: a light no reflection can
    /// reach) towards `to_light`, against this lobe.
    fn light_weight(lobe: Option<&Lobe>, to_light: Vec3, light_pdf: Option<f32>) -> f32 {
        match (lobe, light_pdf) {
            (Some(lobe), Some(pdf)) => power_heuristic(pdf, lobe.pdf(to_light)),
            _ => 1.0,
        }
    }
}

/// The power heuristic (β = 2): the weight of an estimate of density `a` combined with one of
/// density `b`.
fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2.is_infinite() {
        1.0
    } else if a2 + b2 > 0.0 {
        a2 / (a2 + b2)
    } else {
        0.0
    }
}

/// How a ray started, which decides which lights it sees: where it leaves the scene, and the
/// lights with extent it meets on the way.
#[derive(Clone, Copy)]
enum Leaving {
    /// A camera ray, or one that continues it straight through a transparent surface: the
    /// lights that are `visible`, environments in the background's place.
    Camera,
    /// A mirror reflection or a refraction: every light, environments in the background's
    /// place.
    Mirror,
    /// A reflection drawn from a glossy lobe: as a mirror's, each environment light weighed
    /// against its light samples; no light with extent (its light samples stand for it).
    Lobe(Lobe),
}

/// What a ray along unit `direction` sees where it leaves the scene: the environment lights,
/// or where none is there (no hdri light, no disk in that direction) the background (through
/// `beyond`).
fn leaving_scene(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    direction: Vec3,
    screen: Option<Vec2>,
    leaving: Leaving,
    beyond: impl FnOnce(Vec4) -> Vec4,
) -> Vec4 {
    let seen = |light: &Light| !matches!(leaving, Leaving::Camera) || light.visible();
    let mut radiance = Vec3::ZERO;
    let mut replaced = false;
    for light in scene.lights.iter().filter(|light| seen(light)) {
        replaced |= light.is_hdri();
        if let Some(environment) = light.environment(direction) {
            replaced = true;
            let weight = match &leaving {
                Leaving::Lobe(lobe) => power_heuristic(lobe.pdf(direction), environment.pdf),
                _ => 1.0,
            };
            radiance += environment.radiance * weight;
        }
    }
    if replaced {
        radiance.extend(1.0)
    } else {
        beyond(settings.background_for(screen))
    }
}

/// The radiance of the nearest light with extent in the scene (a sphere, quad or ring light)
/// that a ray started as `leaving` says meets before `t_end`: a camera ray sees the `visible`
/// ones, a mirror reflection or refraction every one (for a delta lobe this is the light's only
/// way in, as light samples cannot reach it), a glossy reflection none (its light samples
/// already count these lights, see [`Lobe`]).
fn light_in_front(scene: &SceneSnapshot, ray: &Ray, t_end: f32, leaving: &Leaving) -> Option<Vec3> {
    let seen = |light: &&Light| match leaving {
        Leaving::Camera => light.visible(),
        Leaving::Mirror => true,
        Leaving::Lobe(_) => false,
    };
    let mut nearest: Option<(f32, Vec3)> = None;
    for light in scene.lights.iter().filter(seen) {
        let t_max = nearest.map_or(t_end, |(t, _)| t);
        if let Some(found) = light.hit_by(ray.origin, ray.direction, t_max) {
            nearest = Some(found);
        }
    }
    nearest.map(|(_, radiance)| radiance)
}

/// Radiance along a ray (the default renderer) of the pixel sample at `screen` (see
/// [`RendererSettings::background_at`]), a mirror reflection or refraction.
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
        Leaving::Mirror,
        |background| background,
    )
}

/// [`trace`] of a ray that goes on straight from a camera ray (`from_camera`) or not: what
/// another rank asks of a closest hit of this rank (render::cluster).
#[cfg_attr(not(feature = "mpi"), allow(dead_code))]
pub(crate) fn trace_continuing(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    depth: u32,
    from_camera: bool,
    screen: Option<Vec2>,
    sampling: &LightSampling,
) -> Vec4 {
    let leaving = if from_camera {
        Leaving::Camera
    } else {
        Leaving::Mirror
    };
    trace_seeing(
        scene,
        settings,
        ray,
        depth,
        screen,
        sampling,
        leaving,
        |background| background,
    )
}

/// [`trace`] for a ray started as `leaving` says, where a ray that leaves the scene sees
/// `beyond` of the background.
#[allow(clippy::too_many_arguments)]
fn trace_seeing(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    depth: u32,
    screen: Option<Vec2>,
    sampling: &LightSampling,
    leaving: Leaving,
    beyond: impl FnOnce(Vec4) -> Vec4,
) -> Vec4 {
    // Cluster hook: the closest hit of every rank; another rank's hit is shaded there.
    let from_camera = matches!(leaving, Leaving::Camera);
    let hit = match cluster::closest(scene, ray, depth, from_camera, screen, sampling) {
        Ok(hit) => hit,
        Err(radiance) => return radiance,
    };
    let volume = volumes_in_front(scene, settings, ray, hit.as_ref(), sampling);
    if let Some(volume) = volume.filter(|v| v.transmittance == 0.0) {
        return volume.over(Vec4::ZERO);
    }
    let light = light_in_front(
        scene,
        ray,
        hit.as_ref().map_or(ray.t_max, |h| h.t),
        &leaving,
    );
    let behind = match (light, hit) {
        (Some(radiance), _) => radiance.extend(1.0),
        (None, None) => leaving_scene(scene, settings, ray.direction, screen, leaving, beyond),
        (None, Some(hit)) => {
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
                from_camera,
            )
            .extend(1.0)
        }
    };
    volume.map_or(behind, |v| v.over(behind))
}

/// The volumes between the ray's start and its surface hit (or its end): lit by the scene
/// under the default renderer, emitting their colour under the fast one.
fn volumes_in_front(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    hit: Option<&SceneHit>,
    sampling: &LightSampling,
) -> Option<VolumeIntegral> {
    let t_end = hit.map_or(ray.t_max, |h| h.t);
    if settings.fast {
        integrate(&scene.volumes, ray.origin, ray.direction, ray.t_min, t_end)
    } else {
        lit_volumes(scene, settings, ray, t_end, sampling)
    }
}

/// The default renderer's shading, glTF's layering (glTF 2.0 Appendix B and the
/// KHR_materials_* extensions): a metal and a dielectric mixed by metallic, the dielectric a
/// diffuse base under a Fresnel-weighted reflection (specular, specularColor, ior) or, by
/// transmission, glass; sheen over that, emission, and a clearcoat over everything. Each
/// layer passes on to those below what it does not reflect, so no surface returns more light
/// than arrives. Reflection lobes are GGX microfacet lobes (α = roughness²): F·D·V per light,
/// and one reflection drawn from the visible normals per sample (a mirror at roughness 0).
/// `view`: the unit direction view-dependent terms look along (see
/// [`RendererSettings::view_direction`]). `from_camera`: `ray` is a camera ray (or continues
/// one straight through transparent surfaces), so what it passes on to sees only visible
/// lights.
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
    from_camera: bool,
) -> Vec3 {
    let model = sp.surface_model();
    let normal = model.normal;
    let to_viewer = -view;
    let cos_view = to_viewer.dot(normal).clamp(0.0, 1.0);
    let can_trace = depth < settings.max_ray_depth;
    // Ambient light is radiance from every direction: it arrives as irradiance π·L, where the
    // occlusion map lets it. Reflections find it themselves; what gathers it over the
    // hemisphere (the diffuse base, the sheen) sees it where the scene does not occlude it.
    let ambient = settings.ambient * model.occlusion;
    let gathered_ambient =
        ambient * ambient_visibility(scene, settings, sp.point, normal, depth, sampling);
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

    // The reflections that will be drawn, which environment light samples are weighed
    // against.
    let base_lobe = (can_trace && glossy).then_some(Lobe {
        normal,
        to_viewer,
        alpha,
        albedo,
    });
    let coat_lobe = (can_trace && coat_glossy).then_some(Lobe {
        normal: model.coat_normal,
        to_viewer,
        alpha: coat_alpha,
        albedo: coat_albedo,
    });

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
        |to_light, irradiance, light_pdf| {
            if !lobes_per_light {
                return;
            }
            let base_weight = Lobe::light_weight(base_lobe.as_ref(), to_light, light_pdf);
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
                specular_direct += irradiance * fresnel * (microfacet * base_weight);
            }
            if metal_on && glossy {
                metal_direct += irradiance
                    * metal_fresnel(cos_view_half)
                    * (microfacet * albedo * base_weight)
                    * metal_compensation;
            }
            if coat_glossy && coat_shares_normal {
                coat_direct += irradiance
                    * ggx_distribution(coat_alpha, cos_half)
                    * smith_visibility(coat_alpha, cos_light, cos_view)
                    * Lobe::light_weight(coat_lobe.as_ref(), to_light, light_pdf)
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
            let diffuse = keep * (lambert * (gathered_ambient * std::f32::consts::PI))
                + lambert * diffuse_irradiance;
            let reflected = base_reflection.map_or(Vec3::ZERO, |r| fresnel * r.radiance);
            color += opaque * (diffuse + specular_direct + reflected);
        } else {
            color += opaque * (lambert * (direct + gathered_ambient * std::f32::consts::PI));
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
                scene,
                settings,
                ray,
                view,
                sp,
                &model,
                depth,
                screen,
                sampling,
                from_camera,
            );
    }
    if sheen_on {
        // KHR_materials_sheen: the sheen reflects E of uniform light; what lies below loses
        // max(sheenColor)·E.
        let albedo = sheen_albedo(cos_view, model.sheen_roughness);
        color = color * (1.0 - model.sheen_color.max_element() * albedo)
            + model.sheen_color * (sheen + albedo * gathered_ambient);
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
                |to_light, irradiance, light_pdf| {
                    let half = (to_light + to_viewer).normalize_or(coat_normal);
                    coat_direct += irradiance
                        * ggx_distribution(coat_alpha, half.dot(coat_normal))
                        * smith_visibility(coat_alpha, to_light.dot(coat_normal), cos_coat_view)
                        * Lobe::light_weight(coat_lobe.as_ref(), to_light, light_pdf)
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
            straight_on(from_camera),
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
                scene,
                settings,
                sp.point,
                reflected,
                depth,
                screen,
                sampling,
                Leaving::Mirror,
            ),
        });
    }
    let sample = sample_glossy(normal, -view, alpha, u, sampling.reflection_numbers(depth))?;
    let ray = offset_ray(sp.point, sample.direction, f32::INFINITY);
    let beyond = |background: Vec4| {
        (background.truncate() * (1.0 - roughness) + ambient * roughness).extend(background.w)
    };
    let lobe = Lobe {
        normal,
        to_viewer: -view,
        alpha,
        albedo: microfacet_albedo(to_viewer_cos(view, normal), roughness),
    };
    let radiance = trace_seeing(
        scene,
        settings,
        &ray,
        depth + 1,
        screen,
        sampling,
        Leaving::Lobe(lobe),
        beyond,
    );
    Some(Reflection {
        half: sample.half,
        radiance: radiance.truncate(),
    })
}

/// cos between the viewer and `normal` for a view along `view`, as the lobe sees it.
fn to_viewer_cos(view: Vec3, normal: Vec3) -> f32 {
    (-view).dot(normal).clamp(0.0, 1.0)
}

/// How a ray that goes on straight from one started as a camera ray (`from_camera`) or not
/// leaves the scene.
fn straight_on(from_camera: bool) -> Leaving {
    if from_camera {
        Leaving::Camera
    } else {
        Leaving::Mirror
    }
}

/// Radiance arriving at `point` from `direction` (a secondary ray one bounce deeper, started
/// as `leaving` says).
#[allow(clippy::too_many_arguments)]
fn traced_from(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    point: Vec3,
    direction: Vec3,
    depth: u32,
    screen: Option<Vec2>,
    sampling: &LightSampling,
    leaving: Leaving,
) -> Vec3 {
    let ray = offset_ray(point, direction, f32::INFINITY);
    trace_seeing(
        scene,
        settings,
        &ray,
        depth + 1,
        screen,
        sampling,
        leaving,
        |background| background,
    )
    .truncate()
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
    from_camera: bool,
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
    let incoming = |direction, leaving| {
        traced_from(
            scene, settings, sp.point, direction, depth, screen, sampling, leaving,
        )
    };
    if reflectance > 0.0 {
        color += reflectance * incoming(reflected, Leaving::Mirror);
    }
    if reflectance < 1.0 {
        // A thin wall passes the ray on straight: a camera ray stays one.
        let (through, leaving) = if model.volume {
            (refracted, Leaving::Mirror)
        } else {
            (ray.direction, straight_on(from_camera))
        };
        color += (1.0 - reflectance) * sp.base_color * incoming(through, leaving);
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
    if let Some(sample) = cluster::primary(scene, ray, hit.as_ref(), screen, cyclopean, sampling) {
        return sample;
    }
    let Some(volume) = volumes_in_front(scene, settings, ray, hit.as_ref(), sampling) else {
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

/// What the channels other than colour keep of a surface hit.
#[inline(always)]
pub(super) fn primary_hit(hit: &SceneHit, sp: &ShadingPoint) -> PrimaryHit {
    PrimaryHit {
        t: hit.t,
        point: sp.point,
        primitive_id: sp.primitive_id,
        object_id: sp.object_id,
        instance_id: sp.instance_id,
        albedo: sp.base_color,
        normal: sp.normal,
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
    // A visible light with extent in front of the surface shows instead (no channel
    // describes it, as none describes the background).
    if !settings.fast
        && let Some(radiance) = light_in_front(
            scene,
            ray,
            hit.as_ref().map_or(ray.t_max, |h| h.t),
            &Leaving::Camera,
        )
    {
        return Sample {
            color: radiance.extend(1.0),
            hit: None,
        };
    }
    let Some(hit) = hit else {
        let color = if settings.fast {
            settings.background_for(screen)
        } else {
            leaving_scene(
                scene,
                settings,
                ray.direction,
                screen,
                Leaving::Camera,
                |background| background,
            )
        };
        return Sample { color, hit: None };
    };
    let sp = shading_point(scene, ray, &hit);
    let view = settings.view_direction(ray, sp.point, cyclopean);
    let color = if settings.fast {
        eye_light(view, &sp)
    } else {
        shade(scene, settings, ray, view, &sp, 0, screen, sampling, true)
    };
    Sample {
        color: color.extend(1.0),
        hit: Some(primary_hit(&hit, &sp)),
    }
}
