//! Per-eye ray generators: the concrete `EyeRays` type shared by every camera model.

use std::sync::Arc;

use glam::{DMat4, DVec2, DVec3, DVec4, Vec2, Vec3};

use super::CameraRay;
use super::fisheye::DomeRays;
use super::light_field::LightFieldRays;
use super::light_field::light_field_block;
use super::offaxis::ScreenFrame;
use super::omnidirectional::EquirectangularRays;
use super::viewers::{CameraLanes, ViewerSet};
use crate::isa::Isa;

/// Near plane used by `EyeRays::window_depth` for perspective-like cameras whose `near` is
/// unset or 0 (a zero near plane has no OpenGL depth mapping), in meters.
pub const DEFAULT_WINDOW_DEPTH_NEAR: f64 = 0.01;

/// Far plane used by `EyeRays::window_depth` for orthographic cameras whose `far` is unset, in
/// meters. Perspective-like cameras use an infinite far plane instead.
pub const DEFAULT_ORTHOGRAPHIC_WINDOW_DEPTH_FAR: f64 = 1000.0;

/// The imageRegion box `[lo.x, lo.y, hi.x, hi.y]` as an affine map from the viewport's `[0,1]²`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ImageRegion {
    lo: DVec2,
    extent: DVec2,
}

impl ImageRegion {
    /// `region` must already be validated (finite, non-empty).
    pub(crate) fn from_box(region: [f32; 4]) -> ImageRegion {
        let lo = DVec2::new(f64::from(region[0]), f64::from(region[1]));
        let hi = DVec2::new(f64::from(region[2]), f64::from(region[3]));
        ImageRegion {
            lo,
            extent: hi - lo,
        }
    }

    #[inline]
    pub(super) fn apply(&self, s: f32, t: f32) -> DVec2 {
        self.lo + DVec2::new(f64::from(s), f64::from(t)) * self.extent
    }

    /// The region's width and height as fractions of the whole image.
    pub(crate) fn extent(&self) -> DVec2 {
        self.extent
    }
}

/// Optional near/far clip distances, measured perpendicular to the clip planes.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct ClipRange {
    pub near: Option<f64>,
    pub far: Option<f64>,
}

/// Rays from one point (eye, or a point on the lens) through a window rectangle:
/// perspective and offAxis cameras.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Pinhole {
    pub eye: DVec3,
    /// Window point of `(s', t') = (0, 0)`; the window is `origin + s'·right + t'·up`.
    pub window_origin: DVec3,
    pub window_right: DVec3,
    pub window_up: DVec3,
    /// Unit normal of the near/far planes, pointing from the eye into the scene.
    pub forward: DVec3,
    /// Lens disk axes scaled by the aperture radius; zero for a pinhole.
    pub lens_right: DVec3,
    pub lens_up: DVec3,
    pub clip: ClipRange,
}

impl Pinhole {
    /// The lensless pinhole at `eye` whose window is `screen` (offAxis eyes, quilt views).
    pub(crate) fn through_screen(eye: DVec3, screen: &ScreenFrame, clip: ClipRange) -> Pinhole {
        Pinhole {
            eye,
            window_origin: screen.lower_left,
            window_right: screen.lower_right - screen.lower_left,
            window_up: screen.upper_right - screen.lower_right,
            forward: -screen.z,
            lens_right: DVec3::ZERO,
            lens_up: DVec3::ZERO,
            clip,
        }
    }
}

/// Parallel rays starting on a rectangle: orthographic camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Parallel {
    pub plane_origin: DVec3,
    pub plane_right: DVec3,
    pub plane_up: DVec3,
    /// Unit ray direction, also the normal of the image and near/far planes.
    pub forward: DVec3,
    pub clip: ClipRange,
}

/// Rays from a camera position of their own through a window rectangle (offAxis camera with
/// several viewers): each window point's position is blended from the viewers' heads.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Blended {
    /// The window (the screen) as for [`Pinhole`]; no lens.
    pub window_origin: DVec3,
    pub window_right: DVec3,
    pub window_up: DVec3,
    pub forward: DVec3,
    pub clip: ClipRange,
    pub viewers: Arc<ViewerSet>,
    /// This eye's offset from the blended head along the blended right vector, in meters.
    pub eye_offset: f64,
}

/// Rays unprojected from NDC through proj⁻¹ then view⁻¹: matrix camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Unproject {
    pub view: DMat4,
    pub proj: DMat4,
    pub inv_view: DMat4,
    pub inv_proj: DMat4,
    /// World-space centre of projection for perspective matrices, `None` for parallel ones.
    pub eye: Option<DVec3>,
}

impl Unproject {
    /// Homogeneous world point of an NDC point; proj⁻¹ and view⁻¹ are applied one after the
    /// other (never premultiplied) so that a tiny near plane keeps its precision.
    #[inline]
    pub(crate) fn unproject(&self, ndc: DVec3) -> DVec4 {
        self.inv_view * (self.inv_proj * ndc.extend(1.0))
    }

    /// The near point, the (unnormalized) direction to the far point, and the distance to the
    /// far point (infinite when the far plane is at infinity) for NDC `(u, v)`.
    #[inline]
    pub(crate) fn segment(&self, u: f64, v: f64) -> (DVec3, DVec3, f64) {
        let near = self.unproject(DVec3::new(u, v, -1.0));
        let far = self.unproject(DVec3::new(u, v, 1.0));
        let near_point = near.truncate() / near.w;
        // (far_point − near_point)·near.w·far.w, still finite when far.w is 0 (far plane at
        // infinity). Validation guarantees near.w and far.w do not have opposite signs, so the
        // scale factor is non-negative and the direction is right.
        let scaled = far.truncate() * near.w - near.truncate() * far.w;
        let weight = (near.w * far.w).abs();
        let length = if weight > 0.0 {
            scaled.length() / weight
        } else {
            f64::INFINITY
        };
        (near_point, scaled, length)
    }

    /// The pinhole tracing this projection's rays, for perspective projections whose near
    /// plane is unprojected affinely and whose far plane is parallel to it (every glFrustum and
    /// infinite-far projection): rays from the centre of projection through the near plane,
    /// clipped at the two planes. Its rays differ from the unprojected ones only by rounding,
    /// and are generated at the cost of the offAxis camera's.
    fn as_pinhole(&self) -> Option<Pinhole> {
        let eye = self.eye?;
        let near = |u: f64, v: f64| {
            let p = self.unproject(DVec3::new(u, v, -1.0));
            p.truncate() / p.w
        };
        let origin = near(-1.0, -1.0);
        let right = near(1.0, -1.0) - origin;
        let up = near(-1.0, 1.0) - origin;
        let forward = right.cross(up).try_normalize()?;
        let forward = if forward.dot(origin - eye) < 0.0 {
            -forward
        } else {
            forward
        };
        let scale = right.length().max(up.length()) + (origin - eye).length();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * scale;
        let flat = [(0.0, 0.0), (1.0, 1.0), (0.3, -0.7)].iter().all(|&(u, v)| {
            let expected = origin + right * (0.5 * (u + 1.0)) + up * (0.5 * (v + 1.0));
            (near(u, v) - expected).length() <= 1e-9 * scale
        });
        let near_distance = (origin - eye).dot(forward);
        if !flat || near_distance <= 0.0 {
            return None;
        }
        let far_distances: Vec<Option<f64>> = [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)]
            .iter()
            .map(|&(u, v)| {
                let p = self.unproject(DVec3::new(u, v, 1.0));
                (p.w != 0.0).then(|| (p.truncate() / p.w - eye).dot(forward))
            })
            .collect();
        let far = match far_distances[..] {
            [None, None, None, None] => None,
            [Some(first), ..]
                if far_distances
                    .iter()
                    .all(|d| d.is_some_and(|d| close(d, first))) =>
            {
                Some(first)
            }
            _ => return None,
        };
        Some(Pinhole {
            eye,
            window_origin: origin,
            window_right: right,
            window_up: up,
            forward,
            lens_right: DVec3::ZERO,
            lens_up: DVec3::ZERO,
            clip: ClipRange {
                near: Some(near_distance),
                far,
            },
        })
    }
}

// EyeRays is built once per eye and frame and then read for every ray: keeping the matrices
// inline avoids a pointer chase per ray, the size difference costs nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
enum Generator {
    Pinhole(Pinhole),
    Blended(Blended),
    LightField(LightFieldRays),
    Parallel(Parallel),
    /// With the pinhole that traces the same rays, for perspective projections.
    Unproject(Unproject, Option<Pinhole>),
    Equirectangular(EquirectangularRays),
    Dome(DomeRays),
}

/// Precomputed ray generator for one eye and one viewport size.
#[derive(Clone, Debug, PartialEq)]
pub struct EyeRays {
    region: ImageRegion,
    generator: Generator,
    /// The stereo pair this eye belongs to (perspective and offAxis cameras).
    stereo: Option<StereoGeometry>,
}

/// What screen parallax and cyclopean shading need to know of an eye's stereo pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct StereoGeometry {
    /// This eye's offset from the point midway between the eyes, in interpupillary distances:
    /// −½ left, +½ right, 0 mono (the eye between them).
    pub ipd_fraction: f64,
    /// From the left eye to the right eye (interpupillary distance × the head's right vector).
    /// With several viewers each pixel has its own right vector; only the length is used.
    pub baseline: DVec3,
    /// The zero-parallax plane (a point of it and its unit normal) and the unit horizontal axis
    /// parallax is measured along (the screen's or the camera's right vector).
    pub plane_point: DVec3,
    pub plane_normal: DVec3,
    pub horizontal: DVec3,
}

impl EyeRays {
    pub(crate) fn pinhole(region: ImageRegion, pinhole: Pinhole) -> EyeRays {
        EyeRays {
            region,
            generator: Generator::Pinhole(pinhole),
            stereo: None,
        }
    }

    pub(crate) fn blended(region: ImageRegion, blended: Blended) -> EyeRays {
        EyeRays {
            region,
            generator: Generator::Blended(blended),
            stereo: None,
        }
    }

    pub(crate) fn light_field(region: ImageRegion, rays: LightFieldRays) -> EyeRays {
        EyeRays {
            region,
            generator: Generator::LightField(rays),
            stereo: None,
        }
    }

    /// For a light-field display: the colour channel each of a pixel's three subpixels (left
    /// to right) shows; `None` for every other camera (one ray per pixel).
    pub fn subpixel_channels(&self) -> Option<[usize; 3]> {
        match &self.generator {
            Generator::LightField(l) if l.flip_subpixels => Some([2, 1, 0]),
            Generator::LightField(_) => Some([0, 1, 2]),
            _ => None,
        }
    }

    pub(crate) fn equirectangular(region: ImageRegion, rays: EquirectangularRays) -> EyeRays {
        EyeRays {
            region,
            generator: Generator::Equirectangular(rays),
            stereo: None,
        }
    }

    pub(crate) fn dome(region: ImageRegion, rays: DomeRays) -> EyeRays {
        EyeRays {
            region,
            generator: Generator::Dome(rays),
            stereo: None,
        }
    }

    pub(crate) fn parallel(region: ImageRegion, parallel: Parallel) -> EyeRays {
        EyeRays {
            region,
            generator: Generator::Parallel(parallel),
            stereo: None,
        }
    }

    pub(crate) fn unproject(region: ImageRegion, unproject: Unproject) -> EyeRays {
        EyeRays {
            region,
            generator: Generator::Unproject(unproject, unproject.as_pinhole()),
            stereo: None,
        }
    }

    /// This generator as one eye of the stereo pair `stereo`.
    pub(crate) fn with_stereo(mut self, stereo: StereoGeometry) -> EyeRays {
        self.stereo = Some(stereo);
        self
    }

    /// The point midway between the eyes of this pinhole eye's pair, when it is one of a pair.
    #[inline]
    fn pinhole_cyclopean(&self, eye: DVec3) -> Option<Vec3> {
        self.stereo
            .filter(|stereo| stereo.ipd_fraction != 0.0)
            .map(|stereo| (eye - stereo.baseline * stereo.ipd_fraction).as_vec3())
    }

    /// (s, t) in `[0,1]²` across the viewport (s rightwards, t upwards; a pixel centre is
    /// ((x+½)/w, (y+½)/h)), BEFORE imageRegion — the camera applies imageRegion itself:
    /// s' = lo.x + s·(hi.x−lo.x), t' = lo.y + t·(hi.y−lo.y).
    /// lens in `[0,1)²` is the depth-of-field sample (ignored when apertureRadius is 0).
    /// t_min/t_max implement near/far clipping: the clip planes are perpendicular to the view
    /// axis (OpenGL style), so for perspective rays `t_min = near / cos θ`. Unset near/far give
    /// t_min 0 and t_max +inf. A perspective matrix camera's ray starts at the centre of
    /// projection with `t_min` on the near plane (so rays of neighbouring pixels share their
    /// origin and trace as packets); an orthographic one's starts on the near plane. Both end on
    /// the far plane.
    // Inlined into the frame's loop: returned through memory, its ray waited on a store that
    // could not be forwarded (the whole fast frame of a small scene 9 % slower).
    #[inline(always)]
    pub fn ray(&self, s: f32, t: f32, lens: Vec2) -> CameraRay {
        let st = self.region.apply(s, t);
        match &self.generator {
            Generator::Pinhole(p) => {
                let target = window_point(p, st);
                let origin = if p.lens_right == DVec3::ZERO && p.lens_up == DVec3::ZERO {
                    p.eye
                } else {
                    let disk = concentric_disk(lens);
                    p.eye + disk.x * p.lens_right + disk.y * p.lens_up
                };
                // The lens disk lies in the plane through the eye perpendicular to `forward`,
                // so plane distances from the origin along `forward` equal those from the eye.
                let mut ray = clipped_ray(origin, target, p.forward, &p.clip);
                ray.cyclopean = self.pinhole_cyclopean(p.eye);
                ray
            }
            Generator::Blended(_) => self.rays4([s; 4], [t; 4], lens)[0],
            Generator::LightField(l) => {
                clipped_ray(l.eye(st.x, st.y), l.target(st), l.forward, &l.clip)
            }
            Generator::Parallel(p) => CameraRay {
                origin: (p.plane_origin + st.x * p.plane_right + st.y * p.plane_up).as_vec3(),
                direction: p.forward.as_vec3(),
                t_min: p.clip.near.map_or(0.0, |near| near as f32),
                t_max: p.clip.far.map_or(f32::INFINITY, |far| far as f32),
                cyclopean: None,
            },
            Generator::Unproject(_, Some(p)) => {
                let target = window_point(p, st);
                clipped_ray(p.eye, target, p.forward, &p.clip)
            }
            Generator::Equirectangular(e) => e.ray(st),
            Generator::Dome(d) => d.ray(st),
            Generator::Unproject(m, None) => {
                let (near_point, towards_far, length) =
                    m.segment(2.0 * st.x - 1.0, 2.0 * st.y - 1.0);
                match m.eye {
                    // Every ray of a perspective projection passes through its centre.
                    Some(eye) => {
                        let to_near = near_point - eye;
                        let near_distance = to_near.length();
                        let direction = to_near / near_distance;
                        CameraRay {
                            origin: eye.as_vec3(),
                            direction: direction.as_vec3(),
                            t_min: near_distance as f32,
                            t_max: (near_distance + length) as f32,
                            cyclopean: None,
                        }
                    }
                    None => CameraRay {
                        origin: near_point.as_vec3(),
                        direction: towards_far.normalize().as_vec3(),
                        t_min: 0.0,
                        t_max: length as f32,
                        cyclopean: None,
                    },
                }
            }
        }
    }

    /// [`Self::ray`] for four viewport points at once. Cameras with several viewers blend four
    /// camera positions at a time (a ray gets the same origin whichever rays it comes with).
    #[inline]
    pub fn rays4(&self, s: [f32; 4], t: [f32; 4], lens: Vec2) -> [CameraRay; 4] {
        let Generator::Blended(b) = &self.generator else {
            return std::array::from_fn(|i| self.ray(s[i], t[i], lens));
        };
        let st: [DVec2; 4] = std::array::from_fn(|i| self.region.apply(s[i], t[i]));
        let targets = st.map(|st| b.window_origin + st.x * b.window_right + st.y * b.window_up);
        let cameras = b
            .viewers
            .cameras(&targets, &st, b.eye_offset != 0.0, Isa::Baseline);
        std::array::from_fn(|i| {
            let (head, right) = cameras[i];
            if b.eye_offset == 0.0 {
                return clipped_ray(head, targets[i], b.forward, &b.clip);
            }
            let mut ray = clipped_ray(head + right * b.eye_offset, targets[i], b.forward, &b.clip);
            ray.cyclopean = Some(head.as_vec3());
            ray
        })
    }

    /// The lensless pinhole this eye's rays come from (perspective and offAxis cameras without
    /// depth of field, perspective matrices), with the cyclopean point its rays carry.
    #[inline]
    fn lensless_pinhole(&self) -> Option<(&Pinhole, Option<Vec3>)> {
        match &self.generator {
            Generator::Pinhole(p) if p.lens_right == DVec3::ZERO && p.lens_up == DVec3::ZERO => {
                Some((p, self.pinhole_cyclopean(p.eye)))
            }
            Generator::Unproject(_, Some(p)) => Some((p, None)),
            _ => None,
        }
    }

    /// Whether [`Self::block_rays`] makes this eye's rays: a lensless pinhole, several
    /// viewers' blended camera positions, or a light-field display's subpixels.
    #[inline]
    pub fn makes_block_rays(&self) -> bool {
        self.lensless_pinhole().is_some()
            || matches!(
                self.generator,
                Generator::Blended(_) | Generator::LightField(_)
            )
    }

    /// Writes into `block` the rays of viewport points `(s[i], t[i])` (as for [`Self::ray`],
    /// lens ignored) for an eye that [`Self::makes_block_rays`] (else returns false): bit for
    /// bit the rays [`Self::ray`] makes, computed lane by lane over arrays so that several are
    /// made per instruction (four f64 lanes on the AVX2 and AVX-512 paths).
    #[inline]
    pub fn block_rays(&self, s: &Lanes, t: &Lanes, block: &mut BlockRays) -> bool {
        // SAFETY: a path is selected only on CPUs that have it (`crate::isa`).
        unsafe { self.block_rays_on(crate::isa::selected(), s, t, block) }
    }

    /// [`Self::block_rays`] on path `isa`.
    ///
    /// # Safety
    /// This CPU has the path `isa`.
    #[inline(always)]
    unsafe fn block_rays_on(&self, isa: Isa, s: &Lanes, t: &Lanes, block: &mut BlockRays) -> bool {
        match isa {
            // SAFETY: the caller's promise.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => unsafe { self.block_rays_avx512(isa, s, t, block) },
            // SAFETY: the caller's promise.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => unsafe { self.block_rays_avx2(isa, s, t, block) },
            _ => self.block_rays_with(Isa::Baseline, s, t, block),
        }
    }

    crate::isa::avx2_and_avx512! {
        /// [`Self::block_rays_with`] compiled for the path `isa` (four f64 lanes per
        /// instruction).
        fn [block_rays_avx2, block_rays_avx512](
            &self,
            isa: Isa,
            s: &Lanes,
            t: &Lanes,
            block: &mut BlockRays,
        ) -> bool {
            self.block_rays_with(isa, s, t, block)
        }
    }

    /// [`Self::block_rays`] by generator; `isa` the path it is compiled for
    /// ([`Self::block_rays_avx2`], [`Self::block_rays_avx512`], else the baseline), whose
    /// build of the viewers' blend it takes.
    #[inline(always)]
    fn block_rays_with(&self, isa: Isa, s: &Lanes, t: &Lanes, block: &mut BlockRays) -> bool {
        match &self.generator {
            Generator::Blended(b) => blended_block(&self.region, b, s, t, block, isa),
            Generator::LightField(l) => light_field_block(&self.region, l, s, t, block),
            _ => {
                let Some((pinhole, cyclopean)) = self.lensless_pinhole() else {
                    return false;
                };
                pinhole_block(&self.region, pinhole, s, t, block);
                match cyclopean {
                    Some(cyclopean) => block.cyclopean = BlockCyclopean::Shared(cyclopean.into()),
                    None => block.clear_cyclopean(),
                }
            }
        }
        true
    }

    /// Whether [`Self::rays4`] is cheaper than four calls of [`Self::ray`].
    #[inline]
    pub fn batches_rays(&self) -> bool {
        matches!(self.generator, Generator::Blended(_))
    }

    /// channel.depth of a hit at parameter `t` along `ray`: the world-space distance from this
    /// eye's point (perspective, offAxis — with several viewers the pixel's own eye —,
    /// perspective matrix; for depth of field the lens centre); for the orthographic camera the
    /// distance from the image plane through `position` (where its rays start, so simply `t`);
    /// for an orthographic matrix the distance from the near plane (again `t`).
    #[inline]
    pub fn depth(&self, ray: &CameraRay, t: f32) -> f32 {
        match &self.generator {
            Generator::Pinhole(p) if !self.depth_is_ray_parameter() => {
                let hit = ray.origin.as_dvec3() + ray.direction.as_dvec3() * f64::from(t);
                (hit - p.eye).length() as f32
            }
            _ => t,
        }
    }

    /// Whether [`Self::depth`] of a hit is its ray parameter `t`: for every generator but a
    /// pinhole with a lens (without a lens its rays start at the eye and `t` already is the
    /// distance). Asked once per block of hits rather than per hit.
    #[inline]
    pub fn depth_is_ray_parameter(&self) -> bool {
        match &self.generator {
            Generator::Pinhole(p) => p.lens_right == DVec3::ZERO && p.lens_up == DVec3::ZERO,
            Generator::Blended(_)
            | Generator::LightField(_)
            | Generator::Parallel(_)
            | Generator::Unproject(..)
            | Generator::Equirectangular(_)
            | Generator::Dome(_) => true,
        }
    }

    /// OpenGL window-space depth in `[0,1]` (glDepthRange 0..1) of world point p, seen by
    /// `ray`, under this camera's projection, clamped to `[0,1]`.
    ///
    /// - matrix camera: exactly `((proj·view·p).z / w)·½ + ½`.
    /// - perspective and offAxis: the glFrustum depth mapping of this eye's frustum with the
    ///   camera's near/far; when near is unset (or 0) [`DEFAULT_WINDOW_DEPTH_NEAR`] is used and
    ///   when far is unset the far plane is at infinity (depth = 1 − near/z). With several
    ///   viewers each pixel has a frustum of its own: the one from the ray's origin onto the
    ///   screen.
    /// - orthographic: the glOrtho depth mapping with near/far; unset near means 0 and unset
    ///   far means [`DEFAULT_ORTHOGRAPHIC_WINDOW_DEPTH_FAR`].
    /// - omnidirectional and fisheye (no plane projection): 1 − near/d for the distance d from
    ///   the ray's eye, with near [`DEFAULT_WINDOW_DEPTH_NEAR`].
    pub fn window_depth(&self, ray: &CameraRay, p: Vec3) -> f32 {
        let p = p.as_dvec3();
        let frustum_depth = |eye: DVec3, forward: DVec3, clip: &ClipRange| {
            let z = (p - eye).dot(forward);
            let near = clip
                .near
                .filter(|near| *near > 0.0)
                .unwrap_or(DEFAULT_WINDOW_DEPTH_NEAR);
            perspective_window_depth(z, near, clip.far)
        };
        let depth = match &self.generator {
            Generator::Pinhole(pinhole) => {
                frustum_depth(pinhole.eye, pinhole.forward, &pinhole.clip)
            }
            Generator::Blended(b) => frustum_depth(ray.origin.as_dvec3(), b.forward, &b.clip),
            Generator::LightField(l) => frustum_depth(ray.origin.as_dvec3(), l.forward, &l.clip),
            Generator::Parallel(parallel) => {
                let z = (p - parallel.plane_origin).dot(parallel.forward);
                let near = parallel.clip.near.unwrap_or(0.0);
                let far = parallel
                    .clip
                    .far
                    .unwrap_or(DEFAULT_ORTHOGRAPHIC_WINDOW_DEPTH_FAR);
                (z - near) / (far - near)
            }
            Generator::Unproject(m, _) => {
                let clip = m.proj * (m.view * p.extend(1.0));
                0.5 * (clip.z / clip.w) + 0.5
            }
            // No plane projection: the glFrustum mapping of the distance from the eye.
            Generator::Equirectangular(_) | Generator::Dome(_) => perspective_window_depth(
                (p - ray.origin.as_dvec3()).length(),
                DEFAULT_WINDOW_DEPTH_NEAR,
                None,
            ),
        };
        if depth.is_nan() {
            0.0
        } else {
            depth.clamp(0.0, 1.0) as f32
        }
    }
}

impl EyeRays {
    /// Signed horizontal screen parallax of world point `p` seen by `ray`, in meters on the
    /// zero-parallax plane (the offAxis screen; the perspective camera's focus plane): where the
    /// right eye sees `p` on that plane minus where the left eye sees it, along the plane's
    /// horizontal axis. 0 on the plane, positive behind it, negative in front; for eyes level
    /// with the screen it is ipd·(z − z₀)/z. The eyes are this ray's pair (with several viewers
    /// the pixel's own). NaN for cameras without a stereo pair and for points not in front of
    /// both eyes.
    pub fn parallax(&self, ray: &CameraRay, p: Vec3) -> f32 {
        let Some(stereo) = &self.stereo else {
            return f32::NAN;
        };
        let Some((left, right)) = self.eye_pair(ray, stereo) else {
            return f32::NAN;
        };
        let p = p.as_dvec3();
        let on_plane = |eye: DVec3| {
            let towards = p - eye;
            let along = towards.dot(stereo.plane_normal);
            let to_plane = (stereo.plane_point - eye).dot(stereo.plane_normal);
            // The point must lie on the plane's side of the eye, away from it.
            (along * to_plane > 0.0).then(|| eye + towards * (to_plane / along))
        };
        match (on_plane(left), on_plane(right)) {
            (Some(l), Some(r)) => (r - l).dot(stereo.horizontal) as f32,
            _ => f32::NAN,
        }
    }

    /// The (left, right) eyes of `ray`'s stereo pair.
    fn eye_pair(&self, ray: &CameraRay, stereo: &StereoGeometry) -> Option<(DVec3, DVec3)> {
        let half = 0.5 * stereo.baseline;
        match &self.generator {
            Generator::Pinhole(p) => {
                let centre = p.eye - stereo.baseline * stereo.ipd_fraction;
                Some((centre - half, centre + half))
            }
            Generator::Blended(b) => {
                let (head, right) = match ray.cyclopean {
                    // A stereo eye: the other eye mirrors this one about the blended head.
                    Some(head) => {
                        let head = head.as_dvec3();
                        let offset = ray.origin.as_dvec3() - head;
                        (head, offset / stereo.ipd_fraction)
                    }
                    // A mono eye is the blended head; the pair needs its right vector.
                    None => {
                        let target = self.screen_point(b, ray)?;
                        let st = DVec2::new(
                            (target - b.window_origin).dot(b.window_right)
                                / b.window_right.length_squared(),
                            (target - b.window_origin).dot(b.window_up)
                                / b.window_up.length_squared(),
                        );
                        let (head, right) =
                            b.viewers.cameras(&[target], &[st], true, Isa::Baseline)[0];
                        (head, right * stereo.baseline.length())
                    }
                };
                Some((head - 0.5 * right, head + 0.5 * right))
            }
            Generator::LightField(_)
            | Generator::Parallel(_)
            | Generator::Unproject(..)
            | Generator::Equirectangular(_)
            | Generator::Dome(_) => None,
        }
    }

    /// Where `ray` crosses the screen of a several-viewers camera.
    fn screen_point(&self, b: &Blended, ray: &CameraRay) -> Option<DVec3> {
        let origin = ray.origin.as_dvec3();
        let direction = ray.direction.as_dvec3();
        let normal = b.window_right.cross(b.window_up);
        let along = direction.dot(normal);
        (along != 0.0)
            .then(|| origin + direction * ((b.window_origin - origin).dot(normal) / along))
    }
}

#[cfg(test)]
impl EyeRays {
    /// A matrix camera's rays unprojected pixel by pixel, without the pinhole shortcut.
    pub(crate) fn unproject_exactly(region: ImageRegion, unproject: Unproject) -> EyeRays {
        EyeRays {
            region,
            generator: Generator::Unproject(unproject, None),
            stereo: None,
        }
    }

    /// [`EyeRays::block_rays`] on the instruction-set path chosen here (one the CPU has), not
    /// the process's.
    pub(crate) fn block_rays_on_path(
        &self,
        isa: Isa,
        s: &Lanes,
        t: &Lanes,
        block: &mut BlockRays,
    ) -> bool {
        assert!(
            isa.supported(),
            "{isa:?} path asked for on a CPU without it"
        );
        // SAFETY: this CPU has the path (asserted just above).
        unsafe { self.block_rays_on(isa, s, t, block) }
    }

    /// Whether a matrix camera's rays are traced by the pinhole shortcut.
    pub(crate) fn traces_as_pinhole(&self) -> bool {
        matches!(self.generator, Generator::Unproject(_, Some(_)))
    }

    /// [`EyeRays::window_depth`] for generators whose depth does not depend on the ray (all but
    /// several viewers).
    pub(crate) fn window_depth_at(&self, p: Vec3) -> f32 {
        assert!(!matches!(self.generator, Generator::Blended(_)));
        let unused = CameraRay {
            origin: Vec3::ZERO,
            direction: Vec3::Z,
            t_min: 0.0,
            t_max: 0.0,
            cyclopean: None,
        };
        self.window_depth(&unused, p)
    }
}

/// The ray from `origin` through `target`, clipped to the planes at `clip` distances along
/// `forward` from the origin: a plane at distance `z` is reached at `t = z / cos θ`. One
/// division serves both planes (it runs for every primary ray).
#[inline]
fn clipped_ray(origin: DVec3, target: DVec3, forward: DVec3, clip: &ClipRange) -> CameraRay {
    let (direction, t_min, t_max) = unit_ray(origin.to_array(), target.to_array(), forward, clip);
    CameraRay {
        origin: origin.as_vec3(),
        direction: DVec3::from_array(direction).as_vec3(),
        t_min,
        t_max,
        cyclopean: None,
    }
}

/// The unit direction from `origin` to `target` (glam's `normalize`: times the reciprocal of
/// the length) and the ray parameters of the clip planes at `clip` distances along `forward`.
/// Written on plain f64 triples so that the block generators, which run it lane by lane, and
/// [`clipped_ray`] share these exact operations.
#[inline(always)]
fn unit_ray(
    origin: [f64; 3],
    target: [f64; 3],
    forward: DVec3,
    clip: &ClipRange,
) -> ([f64; 3], f32, f32) {
    let x = target[0] - origin[0];
    let y = target[1] - origin[1];
    let z = target[2] - origin[2];
    let recip = 1.0 / (x * x + y * y + z * z).sqrt();
    let (x, y, z) = (x * recip, y * recip, z * recip);
    if clip.near.is_none() && clip.far.is_none() {
        return ([x, y, z], 0.0, f32::INFINITY);
    }
    // One division serves both planes.
    let per_distance = 1.0 / (x * forward.x + y * forward.y + z * forward.z);
    (
        [x, y, z],
        clip.near.map_or(0.0, |near| (near * per_distance) as f32),
        clip.far
            .map_or(f32::INFINITY, |far| (far * per_distance) as f32),
    )
}

/// The window point `origin + s·right + t·up` of a pinhole, as [`EyeRays::ray`] and the block
/// generator both compute it.
#[inline(always)]
fn window_point(pinhole: &Pinhole, st: DVec2) -> DVec3 {
    pinhole.window_origin + st.x * pinhole.window_right + st.y * pinhole.window_up
}

/// Rays a block of pixels traces together (an 8×8 packet).
pub(crate) const BLOCK_RAYS: usize = 64;

/// One value per ray of a block: a viewport coordinate `s` or `t` of each of its points.
type Lanes = [f32; BLOCK_RAYS];

/// Lane `lane` of x, y and z lane arrays as a vector.
#[inline(always)]
pub(crate) fn lane_vec3<const N: usize>(v: &[[f32; N]; 3], lane: usize) -> Vec3 {
    Vec3::new(v[0][lane], v[1][lane], v[2][lane])
}

/// The rays of a block ([`EyeRays::block_rays`]), x, y and z by lane.
#[derive(Clone, Debug, PartialEq)]
pub struct BlockRays {
    pub origin: [[f32; BLOCK_RAYS]; 3],
    /// Unit directions.
    pub direction: [[f32; BLOCK_RAYS]; 3],
    pub t_min: [f32; BLOCK_RAYS],
    pub t_max: [f32; BLOCK_RAYS],
    /// As [`CameraRay::cyclopean`].
    pub cyclopean: BlockCyclopean,
}

/// The cyclopean points of a block's rays ([`CameraRay::cyclopean`]).
// The lanes stay inline: a block is made tens of thousands of times per frame, without
// allocating.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BlockCyclopean {
    /// The rays have none (mono eyes, cameras without stereo).
    None,
    /// A pinhole stereo eye's block: every ray has this cyclopean point and starts where lane
    /// 0 does, so that shading can take both once for the block.
    Shared([f32; 3]),
    /// Lane by lane, x, y and z (several viewers' blended heads).
    Lanes([[f32; BLOCK_RAYS]; 3]),
}

impl BlockCyclopean {
    /// Lane `i`'s cyclopean point.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> Option<Vec3> {
        match self {
            BlockCyclopean::None => None,
            BlockCyclopean::Shared(cyclopean) => Some(Vec3::from_array(*cyclopean)),
            BlockCyclopean::Lanes(lanes) => Some(lane_vec3(lanes, i)),
        }
    }
}

impl Default for BlockRays {
    fn default() -> BlockRays {
        BlockRays {
            origin: [[0.0; BLOCK_RAYS]; 3],
            direction: [[0.0; BLOCK_RAYS]; 3],
            t_min: [0.0; BLOCK_RAYS],
            t_max: [f32::INFINITY; BLOCK_RAYS],
            cyclopean: BlockCyclopean::None,
        }
    }
}

impl BlockRays {
    /// Lane `i`'s ray.
    #[inline(always)]
    pub fn ray(&self, i: usize) -> CameraRay {
        let lane = |v: &[[f32; BLOCK_RAYS]; 3]| lane_vec3(v, i);
        CameraRay {
            origin: lane(&self.origin),
            direction: lane(&self.direction),
            t_min: self.t_min[i],
            t_max: self.t_max[i],
            cyclopean: self.cyclopean.lane(i),
        }
    }

    /// Rays without a cyclopean point.
    pub(super) fn clear_cyclopean(&mut self) {
        // Only the tag changes: assigning over the lanes variant wrote all its bytes per block.
        if !matches!(self.cyclopean, BlockCyclopean::None) {
            self.cyclopean = BlockCyclopean::None;
        }
    }

    /// Lane `i`: the ray from `eye` through `target` that [`clipped_ray`] makes.
    #[inline(always)]
    pub(super) fn set(
        &mut self,
        i: usize,
        eye: [f64; 3],
        target: [f64; 3],
        forward: DVec3,
        clip: &ClipRange,
    ) {
        let (direction, t_min, t_max) = unit_ray(eye, target, forward, clip);
        for (axis, (value, start)) in direction.into_iter().zip(eye).enumerate() {
            self.direction[axis][i] = value as f32;
            self.origin[axis][i] = start as f32;
        }
        self.t_min[i] = t_min;
        self.t_max[i] = t_max;
    }
}

/// `$lanes` with `$clip` bound to the clip range `$range`, written out twice so that a range
/// without planes is one known to be empty when compiled: over lane arrays the compiler
/// otherwise computes the planes' division for every lane and drops it. A macro, not a
/// function taking a closure: a closure called from two arms may stay out of line, where it
/// loses both the known range and the caller's target features.
macro_rules! with_clip {
    ($range:expr, $clip:ident => $lanes:expr) => {
        match $range {
            ClipRange {
                near: None,
                far: None,
            } => {
                let $clip = &ClipRange::default();
                $lanes
            }
            range => {
                let $clip = &range;
                $lanes
            }
        }
    };
}
pub(super) use with_clip;

/// [`clipped_ray`] from the pinhole's eye through the window points of `(s, t)`, lane by lane
/// with the functions [`EyeRays::ray`] uses, so that every lane is bit for bit its ray (and no
/// fused multiply-adds in the AVX2 and AVX-512 builds: the compiler never contracts them on its
/// own).
#[inline(always)]
fn pinhole_block(
    region: &ImageRegion,
    pinhole: &Pinhole,
    s: &Lanes,
    t: &Lanes,
    block: &mut BlockRays,
) {
    with_clip!(pinhole.clip, clip => pinhole_lanes(region, pinhole, clip, s, t, block));
}

/// [`pinhole_block`]'s lanes with the pinhole's clip range `clip`.
#[inline(always)]
fn pinhole_lanes(
    region: &ImageRegion,
    pinhole: &Pinhole,
    clip: &ClipRange,
    s: &Lanes,
    t: &Lanes,
    block: &mut BlockRays,
) {
    let eye = pinhole.eye.to_array();
    for i in 0..BLOCK_RAYS {
        let target = window_point(pinhole, region.apply(s[i], t[i]));
        block.set(i, eye, target.to_array(), pinhole.forward, clip);
    }
}

/// [`EyeRays::rays4`]'s rays for a whole block: the camera positions for all its points at
/// once (the same bits as four at a time), the rays from them lane by lane, each from its own
/// eye (the blended head, in stereo moved along the blended right vector) through its window
/// point (on the AVX2 and AVX-512 paths four f64 lanes per instruction, the same bits).
#[inline(always)]
fn blended_block(
    region: &ImageRegion,
    b: &Blended,
    s: &Lanes,
    t: &Lanes,
    block: &mut BlockRays,
    isa: Isa,
) {
    let st: [DVec2; BLOCK_RAYS] = std::array::from_fn(|i| region.apply(s[i], t[i]));
    let targets = st.map(|st| b.window_origin + st.x * b.window_right + st.y * b.window_up);
    let stereo = b.eye_offset != 0.0;
    let mut cameras = CameraLanes::<BLOCK_RAYS>::default();
    b.viewers
        .cameras_into(&targets, &st, stereo, isa, &mut cameras);
    if !stereo {
        with_clip!(b.clip, clip => head_lanes(&cameras, &targets, b.forward, clip, block));
        block.clear_cyclopean();
        return;
    }
    let mut cyclopean = [[0.0; BLOCK_RAYS]; 3];
    for (i, target) in targets.iter().enumerate() {
        let eye =
            [0, 1, 2].map(|axis| cameras.head[axis][i] + cameras.right[axis][i] * b.eye_offset);
        block.set(i, eye, target.to_array(), b.forward, &b.clip);
        for (lanes, heads) in cyclopean.iter_mut().zip(&cameras.head) {
            lanes[i] = heads[i] as f32;
        }
    }
    block.cyclopean = BlockCyclopean::Lanes(cyclopean);
}

/// [`blended_block`]'s lanes from the blended heads (no stereo offset) with clip range `clip`.
#[inline(always)]
fn head_lanes(
    cameras: &CameraLanes<BLOCK_RAYS>,
    targets: &[DVec3; BLOCK_RAYS],
    forward: DVec3,
    clip: &ClipRange,
    block: &mut BlockRays,
) {
    for (i, target) in targets.iter().enumerate() {
        let eye = [0, 1, 2].map(|axis| cameras.head[axis][i]);
        block.set(i, eye, target.to_array(), forward, clip);
    }
}

/// Window depth of eye-space distance `z` for a glFrustum-style projection; `far = None` is the
/// infinite far plane.
fn perspective_window_depth(z: f64, near: f64, far: Option<f64>) -> f64 {
    if z <= 0.0 {
        return 0.0;
    }
    let ndc = match far {
        Some(far) => (far + near) / (far - near) - 2.0 * far * near / ((far - near) * z),
        None => 1.0 - 2.0 * near / z,
    };
    0.5 * ndc + 0.5
}

/// Shirley–Chiu concentric mapping of the unit square onto the unit disk (area preserving, so
/// uniform lens samples stay uniform).
fn concentric_disk(sample: Vec2) -> DVec2 {
    let a = 2.0 * f64::from(sample.x) - 1.0;
    let b = 2.0 * f64::from(sample.y) - 1.0;
    if a == 0.0 && b == 0.0 {
        return DVec2::ZERO;
    }
    let quarter_pi = std::f64::consts::FRAC_PI_4;
    let (radius, angle) = if a.abs() > b.abs() {
        (a, quarter_pi * (b / a))
    } else {
        (b, 2.0 * quarter_pi - quarter_pi * (a / b))
    };
    DVec2::new(radius * angle.cos(), radius * angle.sin())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn concentric_disk_maps_square_edges_onto_the_unit_circle() {
        for sample in [
            Vec2::new(1.0, 0.5),
            Vec2::new(0.0, 0.5),
            Vec2::new(0.5, 1.0),
            Vec2::new(0.5, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 0.3),
        ] {
            let p = concentric_disk(sample);
            assert!((p.length() - 1.0).abs() < 1e-12, "{sample:?} -> {p:?}");
        }
        assert_eq!(concentric_disk(Vec2::splat(0.5)), DVec2::ZERO);
        let p = concentric_disk(Vec2::new(0.75, 0.5));
        assert!((p - DVec2::new(0.5, 0.0)).length() < 1e-12);
        let p = concentric_disk(Vec2::new(0.5, 0.25));
        assert!((p - DVec2::new(0.0, -0.5)).length() < 1e-12);
    }

    #[test]
    fn perspective_window_depth_matches_gl_frustum_values() {
        // glFrustum with n = 0.5, f = 10: near plane → 0, far plane → 1.
        assert!((perspective_window_depth(0.5, 0.5, Some(10.0)) - 0.0).abs() < 1e-12);
        assert!((perspective_window_depth(10.0, 0.5, Some(10.0)) - 1.0).abs() < 1e-12);
        // In between: f(z − n) / (z(f − n)).
        let expected = 10.0 * (2.0 - 0.5) / (2.0 * 9.5);
        assert!((perspective_window_depth(2.0, 0.5, Some(10.0)) - expected).abs() < 1e-12);
        // Infinite far plane: 1 − n/z.
        assert!((perspective_window_depth(4.0, 0.5, None) - 0.875).abs() < 1e-12);
        assert_eq!(perspective_window_depth(-1.0, 0.5, None), 0.0);
    }
}
