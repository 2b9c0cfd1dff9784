//! Hit records of a tile: per pixel, the values of the requested channels other than colour,
//! taken from its first sample's hit as the block is shaded. Only the requested channels are
//! kept (one array each), so a frame asking for depth beside colour writes one float per pixel.

use glam::Vec3;

use crate::camera::{CameraRay, EyeRays};
use crate::render::integrator::PrimaryHit;

use super::channels::{ChannelFormat, ChannelKind};

/// Which values the frame's channels read from a pixel's hit, decided once per frame.
#[derive(Clone, Copy, Default, Debug)]
pub(super) struct HitChannels {
    depth: bool,
    window_depth: bool,
    parallax: bool,
    primitive_id: bool,
    object_id: bool,
    instance_id: bool,
    albedo: bool,
    normal: bool,
}

impl HitChannels {
    pub(super) fn of(formats: &[ChannelFormat]) -> HitChannels {
        let mut wanted = HitChannels::default();
        for format in formats {
            match format.kind {
                ChannelKind::Color => {}
                ChannelKind::Depth => wanted.depth = true,
                ChannelKind::WindowDepth => wanted.window_depth = true,
                ChannelKind::Parallax => wanted.parallax = true,
                ChannelKind::PrimitiveId => wanted.primitive_id = true,
                ChannelKind::ObjectId => wanted.object_id = true,
                ChannelKind::InstanceId => wanted.instance_id = true,
                ChannelKind::Albedo => wanted.albedo = true,
                ChannelKind::Normal => wanted.normal = true,
            }
        }
        wanted
    }

    /// Whether any channel reads the hits.
    pub(super) fn any(&self) -> bool {
        self.depth
            || self.window_depth
            || self.parallax
            || self.primitive_id
            || self.object_id
            || self.instance_id
            || self.albedo
            || self.normal
    }
}

/// The requested channels' values of a tile's pixels, in tile order; pixels without a hit
/// (or not seen by any eye) hold each channel's "nothing" value.
#[derive(Default)]
pub(super) struct TileRecords {
    pub(super) depth: Vec<f32>,
    pub(super) window_depth: Vec<f32>,
    pub(super) parallax: Vec<f32>,
    pub(super) primitive_id: Vec<u32>,
    pub(super) object_id: Vec<u32>,
    pub(super) instance_id: Vec<u32>,
    pub(super) albedo: Vec<Vec3>,
    pub(super) normal: Vec<Vec3>,
    /// No channel but depth is wanted (what a VR application asks for beside colour).
    depth_only: bool,
}

/// Resets `values` to `pixels` copies of `nothing` when `wanted`, else leaves it empty.
fn reset<T: Copy>(values: &mut Vec<T>, wanted: bool, pixels: usize, nothing: T) {
    values.clear();
    if wanted {
        values.resize(pixels, nothing);
    }
}

impl TileRecords {
    /// Makes room for `pixels` pixels of the wanted channels, each holding "nothing".
    pub(super) fn reset(&mut self, wanted: &HitChannels, pixels: usize) {
        reset(&mut self.depth, wanted.depth, pixels, f32::INFINITY);
        reset(&mut self.window_depth, wanted.window_depth, pixels, 1.0);
        reset(&mut self.parallax, wanted.parallax, pixels, f32::NAN);
        reset(
            &mut self.primitive_id,
            wanted.primitive_id,
            pixels,
            u32::MAX,
        );
        reset(&mut self.object_id, wanted.object_id, pixels, u32::MAX);
        reset(&mut self.instance_id, wanted.instance_id, pixels, u32::MAX);
        reset(&mut self.albedo, wanted.albedo, pixels, Vec3::ZERO);
        reset(&mut self.normal, wanted.normal, pixels, Vec3::ZERO);
        self.depth_only = wanted.any()
            && !HitChannels {
                depth: false,
                ..*wanted
            }
            .any();
    }

    /// Whether no channel but depth is wanted.
    pub(super) fn depth_only(&self) -> bool {
        self.depth_only
    }

    /// The tile's channel.depth records where only depth is wanted ([`Self::depth_only`]), to
    /// record a whole block's depths at once as [`Self::record_depth`] would one by one; else
    /// `None`.
    #[inline(always)]
    pub(super) fn depths_mut(&mut self) -> Option<&mut [f32]> {
        self.depth_only.then_some(&mut self.depth[..])
    }

    /// Records depth `depth` of pixel `k`'s first hit where only depth is wanted
    /// ([`TileRecords::depth_only`]): what [`TileRecords::record`] records then.
    #[inline(always)]
    pub(super) fn record_depth(&mut self, k: usize, depth: f32) {
        debug_assert!(self.depth_only);
        if let Some(slot) = self.depth.get_mut(k) {
            *slot = depth;
        }
    }

    /// Records pixel `k`'s first hit seen along the camera ray `ray()` of `eye` (a channel
    /// not wanted has no values to set; the ray is made only for the channels that read it),
    /// `depth(t)` being [`EyeRays::depth`] of the hit. A pixel is recorded at most once after
    /// [`TileRecords::reset`], so a miss leaves the "nothing" values in place.
    #[inline(always)]
    pub(super) fn record(
        &mut self,
        k: usize,
        hit: Option<&PrimaryHit>,
        ray: impl Fn() -> CameraRay,
        depth: impl FnOnce(f32) -> f32,
        eye: &EyeRays,
    ) {
        let Some(hit) = hit else {
            return;
        };
        if let Some(slot) = self.depth.get_mut(k) {
            *slot = depth(hit.t);
        }
        if self.depth_only {
            return;
        }
        if let Some(slot) = self.window_depth.get_mut(k) {
            *slot = eye.window_depth(&ray(), hit.point);
        }
        if let Some(slot) = self.parallax.get_mut(k) {
            *slot = eye.parallax(&ray(), hit.point);
        }
        if let Some(slot) = self.primitive_id.get_mut(k) {
            *slot = hit.primitive_id;
        }
        if let Some(slot) = self.object_id.get_mut(k) {
            *slot = hit.object_id;
        }
        if let Some(slot) = self.instance_id.get_mut(k) {
            *slot = hit.instance_id;
        }
        if let Some(slot) = self.albedo.get_mut(k) {
            *slot = hit.albedo;
        }
        if let Some(slot) = self.normal.get_mut(k) {
            *slot = hit.normal;
        }
    }
}
