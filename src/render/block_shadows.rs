//! Shadow rays of a block's primary hits, traced together as packets before the block is
//! shaded: the default renderer's shading then finds each camera hit's shadow-ray answers here
//! instead of tracing its rays one by one.
//!
//! A known answer is used only for a ray equal bit for bit to the one it was traced for, so
//! shading gives what it gives without them; packets find a hit exactly where a single ray
//! does (`SceneBvh::intersect_packet`), and a ray is occluded exactly when it hits something.

use std::cell::Cell;

use glam::Vec3;

use crate::accel::{PacketScratch, Ray, SceneHit};
use crate::render::cluster;
use crate::render::integrator::shadow_ray;
use crate::scene::light::LightSampling;
use crate::scene::world::SceneSnapshot;

/// Lights whose shadow rays a block traces ahead (the first ones of the scene's list).
pub(crate) const BLOCK_LIGHTS: usize = 4;

/// Rays of a block.
const BLOCK: usize = 64;

/// One pixel's known shadow-ray answers: per light, the ray and whether it is blocked.
type PixelAnswers = [Option<(Ray, bool)>; BLOCK_LIGHTS];

thread_local! {
    /// The answers of the pixel this thread is shading.
    static KNOWN: Cell<PixelAnswers> = const { Cell::new([None; BLOCK_LIGHTS]) };
}

/// Whether `ray` towards light `light` is blocked: the known answer when it is for this very
/// ray, otherwise traced.
pub(crate) fn occluded(scene: &SceneSnapshot, light: usize, ray: &Ray) -> bool {
    if let Some(Some((known, answer))) = KNOWN.with(Cell::get).get(light)
        && same_ray(known, ray)
    {
        return *answer;
    }
    cluster::occluded(scene, ray)
}

fn same_ray(a: &Ray, b: &Ray) -> bool {
    a.origin.to_array().map(f32::to_bits) == b.origin.to_array().map(f32::to_bits)
        && a.direction.to_array().map(f32::to_bits) == b.direction.to_array().map(f32::to_bits)
        && a.t_min.to_bits() == b.t_min.to_bits()
        && a.t_max.to_bits() == b.t_max.to_bits()
}

/// A block's shadow-ray answers, per lane and light.
pub(crate) struct BlockShadows {
    answers: [PixelAnswers; BLOCK],
    rays: [Ray; BLOCK],
    hits: [Option<SceneHit>; BLOCK],
}

impl Default for BlockShadows {
    fn default() -> BlockShadows {
        BlockShadows {
            answers: [[None; BLOCK_LIGHTS]; BLOCK],
            rays: [NO_SHADOW_RAY; BLOCK],
            hits: [None; BLOCK],
        }
    }
}

/// Fills a lane that casts no shadow ray (it hits nothing).
const NO_SHADOW_RAY: Ray = Ray {
    origin: Vec3::ZERO,
    direction: Vec3::ZERO,
    t_min: 0.0,
    t_max: 0.0,
};

impl BlockShadows {
    /// Traces, light by light, the shadow rays the shading of each lane's camera hit will
    /// cast: from the hit point of `camera_rays[lane]` at `hits[lane]`, towards the light's
    /// sample `sampling(lane)` picks. Lanes without a hit get no answers.
    pub(crate) fn trace(
        &mut self,
        scene: &SceneSnapshot,
        packets: &mut PacketScratch,
        camera_rays: &[Ray; BLOCK],
        hits: &[Option<SceneHit>; BLOCK],
        sampling: impl Fn(usize) -> LightSampling,
    ) {
        self.answers = [[None; BLOCK_LIGHTS]; BLOCK];
        let samplings: [Option<LightSampling>; BLOCK] =
            std::array::from_fn(|lane| hits[lane].as_ref().map(|_| sampling(lane)));
        for (light_index, light) in scene.lights.iter().take(BLOCK_LIGHTS).enumerate() {
            let mut any = false;
            for lane in 0..BLOCK {
                self.rays[lane] = NO_SHADOW_RAY;
                let (Some(hit), Some(sampling)) = (hits[lane].as_ref(), samplings[lane]) else {
                    continue;
                };
                let ray = &camera_rays[lane];
                // As the shading point places it.
                let point = ray.origin + ray.direction * hit.t;
                if let Some(incoming) = light.incoming_sampled(point, &sampling) {
                    self.rays[lane] = shadow_ray(point, &incoming);
                    any = true;
                }
            }
            if !any {
                continue;
            }
            scene
                .bvh
                .intersect_packet_with(packets, &self.rays, &mut self.hits);
            for lane in 0..BLOCK {
                if self.rays[lane].direction != Vec3::ZERO {
                    self.answers[lane][light_index] =
                        Some((self.rays[lane], self.hits[lane].is_some()));
                }
            }
        }
    }

    /// Makes lane `lane`'s answers the known ones of this thread while `shade` runs.
    pub(crate) fn shading<R>(&self, lane: usize, shade: impl FnOnce() -> R) -> R {
        KNOWN.with(|known| known.set(self.answers[lane]));
        let _forget = ForgetAnswers;
        shade()
    }
}

/// Clears the thread's known answers when shading ends, also when it unwinds, so no later
/// frame on this thread can meet them.
struct ForgetAnswers;

impl Drop for ForgetAnswers {
    fn drop(&mut self) {
        KNOWN.with(|known| known.set([None; BLOCK_LIGHTS]));
    }
}
