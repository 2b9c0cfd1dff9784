//! The fast renderer's samples of a block whose rays were made together (one eye, a whole 8×8
//! block; no cluster pass): shaded straight from the block's arrays, with what does not change
//! between lanes (where the view looks from, the background, the surface hit) decided once.
//! Where every hit of the block lies on one uniform surface, the colours are computed over lane
//! arrays (several lanes per instruction), the view along the rays or from a stereo eye's
//! cyclopean point; otherwise lane by lane. Every lane's sample is bit for bit the per-ray
//! path's.

use glam::{Mat4, Vec2, Vec4};

use crate::accel::SceneHit;
use crate::camera::{BLOCK_RAYS, BlockRays, EyeRays, lane_vec3};
use crate::render::eye_light::{UniformSurface, fast_surface_color, fast_surface_sample};
use crate::render::renderer::RendererSettings;
use crate::scene::world::SceneSnapshot;

use super::cyclopean_views::{ViewPoints, cyclopean_views_into};
use super::records::TileRecords;
use super::tile::{PACKET_ORDER, PACKET_SIDE, traced_lane};
use super::uniform_shading_avx2::{ShadingLanes, shade_uniform_avx2};

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
    /// Every lane hit.
    all_hit: bool,
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

    /// Where the rays start and the views look from when shading looks from a stereo eye's
    /// cyclopean point (cyclopean lighting of a stereo pair), else `None`: the view looks
    /// along the rays.
    #[inline(always)]
    fn cyclopean_view(&self) -> Option<ViewPoints<'_>> {
        ViewPoints::of(self.block).filter(|_| self.settings.cyclopean_lighting)
    }

    /// The uniform surface every hit of the block lies on, with the hits' normals; `None` when
    /// the hits lie on several surfaces or one that is not uniform (or nothing is hit).
    #[inline(always)]
    fn one_surface(&self) -> Option<(UniformSurface<'_>, LaneHits)> {
        let mut surface: Option<UniformSurface> = None;
        let mut lanes = LaneHits {
            normal: [[0.0; BLOCK_RAYS]; 3],
            t: [0.0; BLOCK_RAYS],
            all_hit: true,
        };
        for (lane, hit) in self.hits.iter().enumerate() {
            let Some(hit) = hit else {
                lanes.all_hit = false;
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
        let viewer = self.cyclopean_view();
        // With AVX2 the normals and colours (and a stereo eye's views, kept in registers) go
        // eight lanes per vector.
        let inputs = ShadingLanes {
            view_from: viewer,
            direction,
            t: &lanes.t,
            normal: &lanes.normal,
        };
        let lit = surface.base_and_emissive();
        let vectorized = shade_uniform_avx2(&inputs, lit, &mut normal, &mut color);
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
        match viewer {
            _ if vectorized => {}
            Some(points) => {
                let mut views = [[0.0; BLOCK_RAYS]; 3];
                cyclopean_views_into(points, direction, &lanes.t, &mut views);
                shade(&views);
            }
            None => shade(direction),
        }
        let background = self.background();
        let depth_is_t = self.eye.depth_is_ray_parameter();
        // Only depth asked for beside colour, and depth is the ray parameter (what a VR
        // application asks of a pinhole eye): a hit's record is its `t`.
        let depth_is_all = depth_is_t && records.as_deref().is_some_and(TileRecords::depth_only);
        if lanes.all_hit && (records.is_none() || depth_is_all) {
            // No background and nothing recorded but `t`: quad by quad.
            let depths = records.and_then(TileRecords::depths_mut);
            self.add_quads(&color, &lanes.t, colors, covered, depths);
            return;
        }
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

    /// Adds the colours `color` (alpha 1) of a block whose every lane hit to its pixels'
    /// `colors`, marks them `covered` and, with `depths` (the tile's channel.depth records),
    /// records each lane's `t` there: what the lane-by-lane loop of [`Self::shade_arrays`] does
    /// for such a block, four lanes (a 2×2 quad of pixels, [`PACKET_ORDER`]) at a time, the
    /// quad's colours transposed from the lane arrays into four pixels.
    #[inline(always)]
    fn add_quads(
        &self,
        color: &[[f32; BLOCK_RAYS]; 3],
        t: &[f32; BLOCK_RAYS],
        colors: &mut [Vec4],
        covered: &mut [bool],
        mut depths: Option<&mut [f32]>,
    ) {
        let (side, stride) = (PACKET_SIDE as usize, self.row_stride);
        for row in 0..side {
            covered[self.first + row * stride..][..side].fill(true);
        }
        for (quad, &(x, y)) in PACKET_ORDER.iter().step_by(4).enumerate() {
            let lane = 4 * quad;
            let k = self.first + y as usize * stride + x as usize;
            let [r, g, b] = color.each_ref().map(|axis| Vec4::from_slice(&axis[lane..]));
            // Columns: the quad's lanes as (r, g, b, 1).
            let pixels = Mat4::from_cols(r, g, b, Vec4::ONE).transpose();
            let rows = [k, k + stride];
            for (row, pair) in rows.into_iter().zip([0, 2]) {
                let two = &mut colors[row..row + 2];
                two[0] += pixels.col(pair);
                two[1] += pixels.col(pair + 1);
                if let Some(depths) = depths.as_deref_mut() {
                    depths[row..row + 2].copy_from_slice(&t[lane + pair..lane + pair + 2]);
                }
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
        let cyclopean = |lane: usize| block.cyclopean.lane(lane);
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
