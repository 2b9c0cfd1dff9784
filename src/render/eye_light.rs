//! The fast renderer's shading: one light at the camera (the eye light), and the runs of a
//! block's hits on a uniform surface whose values are looked up once.

use glam::{Vec2, Vec3, Vec4};

use crate::accel::{Ray, SceneHit};
use crate::render::cluster;
use crate::render::integrator::{
    PrimaryHit, Sample, ShadingPoint, facing_ray, primary_hit, shading_point,
};
use crate::render::renderer::RendererSettings;
use crate::scene::geometry::Geometry;
use crate::scene::material::Input;
use crate::scene::world::SceneSnapshot;

/// The fast renderer's shading: a light at the camera, so what faces the viewer is brightest.
/// `view`: the unit direction the light (and the viewer) looks along.
#[inline(always)]
pub(super) fn eye_light(view: Vec3, sp: &ShadingPoint) -> Vec3 {
    eye_light_of(view, sp.normal, sp.base_color, sp.emissive)
}

/// [`eye_light`] of a surface point's shading `normal`, base colour and emission.
#[inline(always)]
pub(crate) fn eye_light_of(view: Vec3, normal: Vec3, base_color: Vec3, emissive: Vec3) -> Vec3 {
    let facing = (-view).dot(normal).max(0.0);
    base_color * (0.2 + 0.8 * facing) + emissive
}

/// A surface the fast renderer shades alike at every point but for its normal: a constant base
/// colour and emission, and no shading normals. Its values are looked up once for the run of
/// a block's hits on it instead of per hit, and a hit's sample is bit for bit
/// [`fast_surface_sample`]'s.
#[derive(Clone, Copy)]
pub struct UniformSurface<'a> {
    /// The hit's instance and geometry indices, to tell whether the next hit is on it.
    instance: u32,
    geometry_index: u32,
    geometry: &'a Geometry,
    base_color: Vec3,
    emissive: Vec3,
    object_id: u32,
    instance_id: u32,
}

impl<'a> UniformSurface<'a> {
    /// The surface `hit` lies on, when it is uniform.
    pub fn of(scene: &'a SceneSnapshot, hit: &SceneHit) -> Option<UniformSurface<'a>> {
        let instance = scene.instances.get(hit.instance as usize)?;
        let surface = instance.surfaces.get(hit.geometry as usize)?;
        let material = &surface.material;
        let (Input::Constant(base), Input::Constant(emissive)) =
            (&material.base_color, &material.emissive)
        else {
            return None;
        };
        (!surface.geometry.has_shading_normals()).then_some(UniformSurface {
            instance: hit.instance,
            geometry_index: hit.geometry,
            geometry: &surface.geometry,
            base_color: base.truncate(),
            emissive: emissive.truncate(),
            object_id: surface.id,
            instance_id: instance.id,
        })
    }

    /// Whether `hit` lies on this surface.
    #[inline(always)]
    pub fn holds(&self, hit: &SceneHit) -> bool {
        self.instance == hit.instance && self.geometry_index == hit.geometry
    }

    /// The shading normal of a hit of geometric normal `normal` seen along `direction`.
    #[inline(always)]
    pub fn normal(normal: Vec3, direction: Vec3) -> Vec3 {
        facing_ray(normal, direction).0
    }

    /// The hit point of `hit` along `ray`.
    #[inline(always)]
    pub fn point(ray: &Ray, hit: &SceneHit) -> Vec3 {
        ray.origin + ray.direction * hit.t
    }

    /// The constant base colour and emission [`Self::color`] lights.
    #[inline(always)]
    pub fn base_and_emissive(&self) -> (Vec3, Vec3) {
        (self.base_color, self.emissive)
    }

    /// The colour of a hit of shading `normal` lit along `view`.
    #[inline(always)]
    pub fn color(&self, view: Vec3, normal: Vec3) -> Vec4 {
        eye_light_of(view, normal, self.base_color, self.emissive).extend(1.0)
    }

    /// What the channels other than colour keep of `hit` at `point` with shading `normal`.
    #[inline(always)]
    pub fn primary_hit(&self, hit: &SceneHit, point: Vec3, normal: Vec3) -> PrimaryHit {
        PrimaryHit {
            t: hit.t,
            point,
            primitive_id: self.geometry.primitive_id(hit.primitive),
            object_id: self.object_id,
            instance_id: self.instance_id,
            albedo: self.base_color,
            normal,
        }
    }
}

/// The fast renderer's colour for a primary ray whose closest surface hit is known, when the
/// scene has no volumes and no channel needs the hit's details: what
/// [`shade_primary_at`](super::integrator::shade_primary_at) gives then, without building the
/// details.
pub fn fast_surface_color(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    hit: Option<&SceneHit>,
    screen: impl FnOnce() -> Vec2,
    cyclopean: Option<Vec3>,
) -> Vec4 {
    fast_surface::<false>(scene, settings, ray, hit, screen, cyclopean).color
}

/// [`fast_surface_color`] with the hit's details for the channels other than colour: what
/// [`shade_primary_at`](super::integrator::shade_primary_at) gives the fast renderer in a
/// scene without volumes.
pub fn fast_surface_sample(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    hit: Option<&SceneHit>,
    screen: impl FnOnce() -> Vec2,
    cyclopean: Option<Vec3>,
) -> Sample {
    fast_surface::<true>(scene, settings, ray, hit, screen, cyclopean)
}

/// The fast renderer's primary sample; the hit's details only when `DETAILS` (the colour-only
/// path skips building them).
#[inline(always)]
fn fast_surface<const DETAILS: bool>(
    scene: &SceneSnapshot,
    settings: &RendererSettings,
    ray: &Ray,
    hit: Option<&SceneHit>,
    screen: impl FnOnce() -> Vec2,
    cyclopean: Option<Vec3>,
) -> Sample {
    debug_assert!(settings.fast && scene.volumes.is_empty());
    // Cluster hook: a primary sample of a render across MPI ranks is shaded by its hit's rank.
    let screen = match cluster::fast_primary_sample(scene, ray, hit, screen, cyclopean) {
        Ok(screen) => screen,
        Err(sample) => return sample,
    };
    match hit {
        Some(hit) => {
            let sp = shading_point(scene, ray, hit);
            let view = settings.view_direction(ray, sp.point, cyclopean);
            Sample {
                color: eye_light(view, &sp).extend(1.0),
                hit: DETAILS.then(|| primary_hit(hit, &sp)),
            }
        }
        None => Sample {
            color: settings.background_for(Some(screen())),
            hit: None,
        },
    }
}
