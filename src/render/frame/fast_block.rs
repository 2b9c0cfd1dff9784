//! The fast renderer's samples of a block whose rays were made together (one eye, a whole 8×8
//! block; no cluster pass): shaded lane by lane straight from the block's arrays, with what
//! does not change between lanes (where the view looks from, the background, the surface of
//! the last hit) decided once. Every lane's sample is bit for bit the per-ray path's.

use glam::{Vec2, Vec3, Vec4};

use crate::accel::{Ray, SceneHit};
use crate::camera::{BLOCK_RAYS, BlockRays, EyeRays};
use crate::render::integrator::{UniformSurface, fast_surface_color, fast_surface_sample};
use crate::render::renderer::RendererSettings;
use crate::scene::world::SceneSnapshot;

use super::records::TileRecords;

/// One sample of a traced block to shade.
pub(super) struct FastBlock<'a> {
    pub(super) scene: &'a SceneSnapshot,
    pub(super) settings: &'a RendererSettings,
    pub(super) rays: &'a [Ray; BLOCK_RAYS],
    pub(super) hits: &'a [Option<SceneHit>; BLOCK_RAYS],
    pub(super) block: &'a BlockRays,
    pub(super) eye: &'a EyeRays,
}

impl FastBlock<'_> {
    /// Adds each lane's colour to `colors[pixel(lane)]` and marks the pixel `covered`; with
    /// `records`, records each lane's hit there. `screen(lane)`: the sample's position in the
    /// frame, which places a background image.
    #[inline(always)]
    pub(super) fn shade(
        &self,
        pixel: impl Fn(usize) -> usize,
        screen: impl Fn(usize) -> Vec2,
        colors: &mut [Vec4],
        covered: &mut [bool],
        mut records: Option<&mut TileRecords>,
    ) {
        let (scene, settings, block) = (self.scene, self.settings, self.block);
        let cyclopean = |lane: usize| {
            block
                .cyclopean
                .as_ref()
                .map(|c| Vec3::new(c[0][lane], c[1][lane], c[2][lane]))
        };
        // The view looks along the ray unless a stereo eye's shading looks from its cyclopean
        // point.
        let cyclopean_view = settings.cyclopean_lighting && block.cyclopean.is_some();
        let background = settings
            .background_image
            .is_none()
            .then_some(settings.background);
        let mut surface: Option<UniformSurface> = None;
        for lane in 0..BLOCK_RAYS {
            let k = pixel(lane);
            covered[k] = true;
            let ray = &self.rays[lane];
            let Some(hit) = &self.hits[lane] else {
                colors[k] += match background {
                    Some(color) => color,
                    None => settings.background_at(screen(lane)),
                };
                continue;
            };
            if !surface.is_some_and(|s| s.holds(hit)) {
                surface = UniformSurface::of(scene, hit);
            }
            let Some(uniform) = surface else {
                // Attributes or shading normals: the per-ray shading.
                let screen = || screen(lane);
                match records.as_deref_mut() {
                    Some(records) => {
                        let sample = fast_surface_sample(
                            scene,
                            settings,
                            ray,
                            Some(hit),
                            screen,
                            cyclopean(lane),
                        );
                        colors[k] += sample.color;
                        let camera_ray = || block.ray(lane);
                        records.record(k, sample.hit.as_ref(), camera_ray, self.eye);
                    }
                    None => {
                        colors[k] += fast_surface_color(
                            scene,
                            settings,
                            ray,
                            Some(hit),
                            screen,
                            cyclopean(lane),
                        );
                    }
                }
                continue;
            };
            let normal = UniformSurface::normal(ray, hit);
            let point = UniformSurface::point(ray, hit);
            let view = if cyclopean_view {
                settings.view_direction(ray, point, cyclopean(lane))
            } else {
                ray.direction
            };
            colors[k] += uniform.color(view, normal);
            if let Some(records) = records.as_deref_mut() {
                let primary = uniform.primary_hit(hit, point, normal);
                records.record(k, Some(&primary), || block.ray(lane), self.eye);
            }
        }
    }
}
