//! Rays towards the renderer's ambient light: a uniform surrounding that surfaces hide, as
//! seen from a surface (ambient occlusion) or from a particle inside a volume.

use crate::accel::{Ray, surface_epsilon};
use crate::render::cluster;
use crate::scene::world::SceneSnapshot;

/// Most surfaces that let light through an ambient-occlusion ray looks past.
const MAX_SEE_THROUGH: u32 = 16;

/// Whether `ray` reaches its end (the occlusion distance) without meeting an opaque surface.
/// Surfaces that let light through do not hide the ambient light: it stands for light from
/// everywhere, which fills what they enclose.
pub fn reaches_ambient(scene: &SceneSnapshot, ray: &Ray) -> bool {
    if !scene.see_through {
        // Cluster hook: ambient-occlusion rays see every rank's surfaces.
        return !cluster::occluded(scene, ray);
    }
    let mut ray = *ray;
    for _ in 0..MAX_SEE_THROUGH {
        let Some(hit) = scene.bvh.intersect(&ray) else {
            return true;
        };
        let instance = &scene.instances[hit.instance as usize];
        if !instance.surfaces[hit.geometry as usize]
            .material
            .lets_light_through()
        {
            return false;
        }
        let at = ray.origin + ray.direction * hit.t;
        ray.t_min = hit.t + surface_epsilon(at);
    }
    true
}
