//! What a frame's pixels need done, decided once per frame from the scene, the renderer and
//! the requested channels rather than per pixel.

use std::sync::atomic::{AtomicBool, Ordering};

use super::RenderSetup;
use super::channels::ChannelFormat;
use super::records::HitChannels;

/// Renders every pixel by the plain path instead of the block pipeline: its ray made alone,
/// traced alone and shaded by the general primary shading. For tests that compare the two;
/// never set by the device.
#[doc(hidden)]
pub static PLAIN_PER_PIXEL_PATH: AtomicBool = AtomicBool::new(false);

/// The per-frame choices of the tile loop.
#[derive(Clone, Copy, Debug)]
pub(super) struct PixelWork {
    /// The fast renderer in a scene without volumes: a hit's colour is its surface's, shaded
    /// once, with no volume integration, light sampling or secondary rays.
    pub(super) fast_surfaces: bool,
    /// Which values the channels other than colour read from each pixel's first hit.
    pub(super) hit_channels: HitChannels,
    /// [`PLAIN_PER_PIXEL_PATH`] was set when the frame started.
    pub(super) plain_pixels: bool,
    /// The default renderer's shadow rays from a block's camera hits are traced as packets
    /// before the block is shaded: shadows on, lights present, one process.
    pub(super) block_shadows: bool,
}

impl PixelWork {
    pub(super) fn of(setup: &RenderSetup, formats: &[ChannelFormat]) -> PixelWork {
        let plain_pixels = PLAIN_PER_PIXEL_PATH.load(Ordering::Relaxed);
        let (settings, scene) = (&setup.settings, &setup.scene);
        PixelWork {
            fast_surfaces: !plain_pixels && settings.fast && scene.volumes.is_empty(),
            block_shadows: !plain_pixels
                && !settings.fast
                && settings.shadows
                && !scene.lights.is_empty()
                && scene.cluster.is_none(),
            hit_channels: HitChannels::of(formats),
            plain_pixels,
        }
    }
}
