//! The fast renderer's samples of a block whose rays were made together (one eye, a whole 8×8
//! block; no cluster pass): shaded straight from the block's arrays, with what does not change
//! between lanes (where the view looks from, the background, the surface hit) decided once.
//! Where every hit of the block lies on one uniform surface, the colours are computed over lane
//! arrays (several lanes per instruction), the view along the rays or from a stereo eye's
//! cyclopean point; otherwise lane by lane. Every lane's sample is bit for bit the per-ray
//! path's.

use glam::{Vec2, Vec4};

use crate::accel::SceneHit;
use crate::camera::{BLOCK_RAYS, BlockRays, EyeRays, lane_vec3};
use crate::render::integrator::{UniformSurface, fast_surface_color, fast_surface_sample};
use crate::render::renderer::RendererSettings;
use crate::scene::world::SceneSnapshot;

use super::records::TileRecords;
use super::tile::{PACKET_ORDER, PACKET_SIDE, traced_lane};

/// One sample of a traced block to shade.
pub(super) struct FastBlock<'a> {
    pub(super) scene: &'a SceneSnapshot,
    pub(super) settings: &'a RendererSettings,
    pub(super) hits: &'a [Option<SceneHit>; BLOCK_RAYS],
    pub(super) block: &'a BlockRays,
    pub(super) eye: &'a EyeRays,
    /// The tile index of the block's first pixel, and of a pixel's upper neighbour less its
    /// own (the tile's width).
    pub(super) first: usize,
    pub(super) row_stride: usize,
}

/// The normals and ray parameters `t` of a block's hits on its one surface, lane by lane
/// (lanes without a hit hold zeros; which lanes hit is the block's `hits`).
struct LaneHits {
    normal: [[f32; BLOCK_RAYS]; 3],
    t: [f32; BLOCK_RAYS],
}

impl FastBlock<'_> {
    /// Adds each lane's colour to its pixel's in `colors` and marks the pixel `covered`; with
    /// `records`, records each lane's hit there. `screen(lane)`: the sample's position in the
    /// frame, which places a background image.
    #[inline(always)]
    pub(super) fn shade(
        &self,
        screen: impl Fn(usize) -> Vec2,
        colors: &mut [Vec4],
        covered: &mut [bool],
        records: Option<&mut TileRecords>,
    ) {
        let pixel = |lane: usize| {
            let (dx, dy) = PACKET_ORDER[lane];
            self.first + dy as usize * self.row_stride + dx as usize
        };
        if let Some(background) = self.background()
            && self.hits.iter().all(Option::is_none)
        {
            // Only background (sky): row by row.
            for row in 0..PACKET_SIDE as usize {
                let start = self.first + row * self.row_stride;
                let pixels = start..start + PACKET_SIDE as usize;
                covered[pixels.clone()].fill(true);
                for color in &mut colors[pixels] {
                    *color += background;
                }
            }
            return;
        }
        match self.one_surface() {
            Some((surface, lanes)) => {
                self.shade_arrays(surface, &lanes, pixel, screen, colors, covered, records)
            }
            None => self.shade_lanes(pixel, screen, colors, covered, records),
        }
    }

    /// The stereo eye's cyclopean point per lane when shading looks from it (cyclopean
    /// lighting of a stereo pair), else `None`: the view looks along the rays.
    #[inline(always)]
    fn cyclopean_view(&self) -> Option<&[[f32; BLOCK_RAYS]; 3]> {
        self.block
            .cyclopean
            .as_ref()
            .filter(|_| self.settings.cyclopean_lighting)
    }

    /// The uniform surface every hit of the block lies on, with the hits' normals; `None` when
    /// the hits lie on several surfaces or one that is not uniform (or nothing is hit).
    #[inline(always)]
    fn one_surface(&self) -> Option<(UniformSurface<'_>, LaneHits)> {
        let mut surface: Option<UniformSurface> = None;
        let mut lanes = LaneHits {
            normal: [[0.0; BLOCK_RAYS]; 3],
            t: [0.0; BLOCK_RAYS],
        };
        for (lane, hit) in self.hits.iter().enumerate() {
            let Some(hit) = hit else {
                continue;
            };
            match surface {
                Some(s) if s.holds(hit) => {}
                Some(_) => return None,
                None => surface = Some(UniformSurface::of(self.scene, hit)?),
            }
            for (axis, value) in hit.normal.to_array().into_iter().enumerate() {
                lanes.normal[axis][lane] = value;
            }
            lanes.t[lane] = hit.t;
        }
        Some((surface?, lanes))
    }

    /// [`Self::shade`] for hits on one uniform surface `surface`: the shading normals and
    /// colours over lane arrays (the view along the rays, or from a stereo eye's cyclopean
    /// point as [`RendererSettings::view_direction`] has it), then each lane's pixel.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn shade_arrays(
        &self,
        surface: UniformSurface,
        lanes: &LaneHits,
        pixel: impl Fn(usize) -> usize,
        screen: impl Fn(usize) -> Vec2,
        colors: &mut [Vec4],
        covered: &mut [bool],
        mut records: Option<&mut TileRecords>,
    ) {
        let direction = &self.block.direction;
        let mut normal = [[0.0; BLOCK_RAYS]; 3];
        let mut color = [[0.0; BLOCK_RAYS]; 3];
        let at = lane_vec3::<BLOCK_RAYS>;
        let mut shade = |views: &[[f32; BLOCK_RAYS]; 3]| {
            for lane in 0..BLOCK_RAYS {
                let along = at(direction, lane);
                let shading = UniformSurface::normal(at(&lanes.normal, lane), along);
                let rgb = surface.color(at(views, lane), shading);
                for axis in 0..3 {
                    normal[axis][lane] = shading[axis];
                    color[axis][lane] = rgb[axis];
                }
            }
        };
        // The view looks along the rays (the block's directions, as traced), or from a stereo
        // eye's cyclopean point.
        match self.cyclopean_view() {
            Some(viewer) => {
                let mut views = [[0.0; BLOCK_RAYS]; 3];
                cyclopean_views_into(&self.block.origin, direction, &lanes.t, viewer, &mut views);
                shade(&views);
            }
            None => shade(direction),
        }
        let background = self.background();
        let depth_is_t = self.eye.depth_is_ray_parameter();
        // Only depth asked for beside colour, and depth is the ray parameter (what a VR
        // application asks of a pinhole eye): a hit's record is its `t`.
        let depth_is_all = depth_is_t && records.as_deref().is_some_and(TileRecords::depth_only);
        for lane in 0..BLOCK_RAYS {
            let k = pixel(lane);
            covered[k] = true;
            // Every hit lies on `surface` (else the block is shaded lane by lane).
            let Some(hit) = &self.hits[lane] else {
                colors[k] +=
                    background.unwrap_or_else(|| self.settings.background_at(screen(lane)));
                continue;
            };
            colors[k] += lane_vec3(&color, lane).extend(1.0);
            if depth_is_all && let Some(records) = records.as_deref_mut() {
                records.record_depth(k, hit.t);
            } else if let Some(records) = records.as_deref_mut() {
                let shading = lane_vec3(&normal, lane);
                let point = UniformSurface::point(&traced_lane(self.block, lane), hit);
                let primary = surface.primary_hit(hit, point, shading);
                let depth = |t| self.depth(lane, t, depth_is_t);
                records.record(k, Some(&primary), || self.block.ray(lane), depth, self.eye);
            }
        }
    }

    /// channel.depth of lane `lane`'s hit at `t`, which is `t` where `depth_is_t` (the eye's
    /// [`EyeRays::depth_is_ray_parameter`], asked once per block).
    #[inline(always)]
    fn depth(&self, lane: usize, t: f32, depth_is_t: bool) -> f32 {
        if depth_is_t {
            t
        } else {
            self.eye.depth(&self.block.ray(lane), t)
        }
    }

    /// The background every miss of the block sees, unless an image places it per sample.
    #[inline(always)]
    fn background(&self) -> Option<Vec4> {
        let settings = self.settings;
        settings
            .background_image
            .is_none()
            .then_some(settings.background)
    }

    /// [`Self::shade`] lane by lane.
    #[inline(always)]
    fn shade_lanes(
        &self,
        pixel: impl Fn(usize) -> usize,
        screen: impl Fn(usize) -> Vec2,
        colors: &mut [Vec4],
        covered: &mut [bool],
        mut records: Option<&mut TileRecords>,
    ) {
        let (scene, settings, block) = (self.scene, self.settings, self.block);
        let cyclopean = |lane: usize| block.cyclopean.as_ref().map(|c| lane_vec3(c, lane));
        // The view looks along the ray unless a stereo eye's shading looks from its cyclopean
        // point.
        let cyclopean_view = self.cyclopean_view().is_some();
        let background = self.background();
        let depth_is_t = self.eye.depth_is_ray_parameter();
        let mut surface: Option<UniformSurface> = None;
        for lane in 0..BLOCK_RAYS {
            let k = pixel(lane);
            covered[k] = true;
            let ray = &traced_lane(block, lane);
            let Some(hit) = &self.hits[lane] else {
                colors[k] += background.unwrap_or_else(|| settings.background_at(screen(lane)));
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
                        let depth = |t| self.depth(lane, t, depth_is_t);
                        let camera_ray = || block.ray(lane);
                        records.record(k, sample.hit.as_ref(), camera_ray, depth, self.eye);
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
            let normal = UniformSurface::normal(hit.normal, ray.direction);
            let point = UniformSurface::point(ray, hit);
            let view = if cyclopean_view {
                settings.view_direction(ray, point, cyclopean(lane))
            } else {
                ray.direction
            };
            colors[k] += uniform.color(view, normal);
            if let Some(records) = records.as_deref_mut() {
                let primary = uniform.primary_hit(hit, point, normal);
                let depth = |t| self.depth(lane, t, depth_is_t);
                records.record(k, Some(&primary), || block.ray(lane), depth, self.eye);
            }
        }
    }
}

/// Per lane, [`RendererSettings::view_direction`] of the hit at ray parameter `t` seen from
/// the cyclopean point `viewer`: `(point − viewer).try_normalize()`, else the ray's direction
/// (lanes without a hit get a view that is not used). Four lanes per vector with the scalar
/// operations in the same order (the hit point as `UniformSurface::point` has it): the same
/// bits as lane by lane, where glam's branch kept the compiler from vectorizing.
#[inline(always)]
fn cyclopean_views_into(
    origin: &[[f32; BLOCK_RAYS]; 3],
    direction: &[[f32; BLOCK_RAYS]; 3],
    t: &[f32; BLOCK_RAYS],
    viewer: &[[f32; BLOCK_RAYS]; 3],
    views: &mut [[f32; BLOCK_RAYS]; 3],
) {
    for first in (0..BLOCK_RAYS).step_by(4) {
        let lanes = first..first + 4;
        let load = |values: &[f32; BLOCK_RAYS]| Vec4::from_slice(&values[lanes.clone()]);
        let t = load(t);
        let along = direction.each_ref().map(load);
        let offset: [Vec4; 3] = std::array::from_fn(|axis| {
            (load(&origin[axis]) + along[axis] * t) - load(&viewer[axis])
        });
        let length_squared = offset[0] * offset[0] + offset[1] * offset[1] + offset[2] * offset[2];
        let scale = Vec4::ONE / length_squared.sqrt();
        let normalizable = scale.is_finite_mask() & scale.cmpgt(Vec4::ZERO);
        for axis in 0..3 {
            Vec4::select(normalizable, offset[axis] * scale, along[axis])
                .write_to_slice(&mut views[axis][lanes.clone()]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Ray;
    use glam::Vec3;

    /// A hit at ray parameter `t` (only `t` places the hit point).
    fn hit_at(t: f32) -> SceneHit {
        SceneHit {
            t,
            instance: 0,
            geometry: 0,
            primitive: 0,
            uv: Vec2::ZERO,
            normal: Vec3::Z,
            object_normal: Vec3::Z,
        }
    }

    #[test]
    fn cyclopean_views_match_the_per_ray_view_direction_bit_for_bit() {
        let settings = RendererSettings {
            cyclopean_lighting: true,
            ..RendererSettings::default()
        };
        let mut origin = [[0.0; BLOCK_RAYS]; 3];
        let mut direction = [[0.0; BLOCK_RAYS]; 3];
        let mut t = [0.0; BLOCK_RAYS];
        let mut viewer = [[0.0; BLOCK_RAYS]; 3];
        // Ordinary lanes from a fixed pseudo-random sequence.
        let mut state = 0x2545_f491_u32;
        let mut next = || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1 << 24) as f32 * 8.0 - 4.0
        };
        for lane in 0..BLOCK_RAYS {
            let along = Vec3::new(next(), next(), next()).normalize_or(Vec3::Z);
            for axis in 0..3 {
                origin[axis][lane] = next();
                direction[axis][lane] = along[axis];
                viewer[axis][lane] = next() * 0.1;
            }
            t[lane] = next().abs() * 3.0;
        }
        // Lanes where normalizing fails, one in each of several groups of four and at each
        // position in a group: the hit point on the viewer, an offset whose square underflows
        // to zero, one whose square overflows, a NaN hit point.
        let hit_point =
            |origin: &[[f32; BLOCK_RAYS]; 3], direction: &[[f32; BLOCK_RAYS]; 3], lane| {
                lane_vec3(origin, lane) + lane_vec3(direction, lane) * t[lane]
            };
        let mut place_viewer = |lane: usize, offset: Vec3| {
            let point = hit_point(&origin, &direction, lane);
            for axis in 0..3 {
                viewer[axis][lane] = point[axis] - offset[axis];
            }
        };
        place_viewer(0, Vec3::ZERO);
        place_viewer(5, Vec3::new(1e-25, 0.0, 0.0));
        place_viewer(10, Vec3::new(0.0, -1e-25, 1e-25));
        place_viewer(15, Vec3::new(0.0, 0.0, 1e25));
        place_viewer(17, Vec3::new(-1e25, 1e25, 0.0));
        t[22] = f32::NAN;
        origin[1][27] = f32::NAN;
        for (axis, lanes) in origin.iter_mut().enumerate() {
            lanes[33] = 1e30 * (axis as f32 + 1.0);
        }
        let mut views = [[0.0; BLOCK_RAYS]; 3];
        cyclopean_views_into(&origin, &direction, &t, &viewer, &mut views);
        let at = lane_vec3::<BLOCK_RAYS>;
        let mut fallbacks = 0;
        for (lane, &t) in t.iter().enumerate() {
            let ray = Ray {
                origin: at(&origin, lane),
                direction: at(&direction, lane),
                t_min: 0.0,
                t_max: f32::INFINITY,
            };
            let point = UniformSurface::point(&ray, &hit_at(t));
            let expected = settings.view_direction(&ray, point, Some(at(&viewer, lane)));
            let got = at(&views, lane);
            assert_eq!(
                got.to_array().map(f32::to_bits),
                expected.to_array().map(f32::to_bits),
                "lane {lane}: {got} vs {expected}"
            );
            fallbacks += usize::from(expected == ray.direction);
        }
        // The special lanes did take the fallback.
        assert_eq!(
            fallbacks, 8,
            "{fallbacks} lanes fell back to the ray's direction"
        );
    }
}
