//! Cameras: validated camera descriptions and primary-ray generation.
//!
//! Conventions used throughout:
//! - World space is right-handed, in meters (CAVE space).
//! - Matrices are column-major like OpenGL/glm; NDC is `[-1, 1]³`.
//! - Frames store rows bottom-to-top (ANARI): `t = 0` is the bottom edge.
//! - Geometry is computed in f64 and rounded to f32 only in the outputs.

pub mod anari;
pub mod fisheye;
pub mod light_field;
pub mod matrix;
pub mod offaxis;
pub mod omnidirectional;
pub mod orthographic;
pub mod perspective;
mod rays;
pub mod screen;
pub mod specs;
mod validate;
pub mod viewers;

#[cfg(test)]
mod equivalence_tests;
#[cfg(test)]
mod test_support;
#[cfg(test)]
mod viewer_tests;

pub use anari::camera_from_params;
pub use fisheye::FisheyeDesc;
pub use matrix::MatrixDesc;
pub use offaxis::{OffAxisError, PerspectiveFit};
pub use omnidirectional::{OmnidirectionalDesc, OmnidirectionalLayout};
pub use orthographic::OrthographicDesc;
pub use perspective::PerspectiveDesc;
pub(crate) use rays::{BLOCK_RAYS, lane_vec3};
pub use rays::{
    BlockCyclopean, BlockRays, DEFAULT_ORTHOGRAPHIC_WINDOW_DEPTH_FAR, DEFAULT_WINDOW_DEPTH_NEAR,
    EyeRays,
};
pub use screen::OffAxisDesc;
pub use specs::SPECS;
pub use viewers::{ViewerDesc, ViewerMode, ViewerWeighting};

use std::fmt;

/// Default interpupillary distance in meters (KHR_CAMERA_STEREO).
pub const DEFAULT_INTERPUPILLARY_DISTANCE: f32 = 0.0635;

/// One primary ray. The visible segment is `origin + t·direction` for `t` in `[t_min, t_max]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraRay {
    pub origin: glam::Vec3,
    /// Unit length.
    pub direction: glam::Vec3,
    pub t_min: f32,
    pub t_max: f32,
    /// For an eye of a stereo pair (left or right), the point midway between the pair's two
    /// eyes (with several viewers, this pixel's blended head): where view-dependent shading looks
    /// from under cyclopean lighting. `None` for a mono eye and for cameras without stereo.
    pub cyclopean: Option<glam::Vec3>,
}

/// Which eye a viewport or a ray generator belongs to.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Eye {
    Mono,
    Left,
    Right,
    /// View k of a light-field quilt.
    View(u32),
}

impl Eye {
    /// Offset of this eye from the head centre along the head's right vector, in units of the
    /// interpupillary distance.
    pub(crate) fn ipd_fraction(self) -> f64 {
        match self {
            Eye::Mono | Eye::View(_) => 0.0,
            Eye::Left => -0.5,
            Eye::Right => 0.5,
        }
    }
}

/// KHR_CAMERA_STEREO `stereoMode`, and cavetrace's interleaved modes for passive 3D displays
/// (`ANARI_CAVETRACE_STEREO_INTERLEAVED`): every pixel is traced from the eye its row, column or
/// checkerboard square belongs to. `right_first` (`interleaveStartRight`): the first row,
/// column or the bottom-left pixel belongs to the right eye instead of the left.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub enum StereoMode {
    #[default]
    None,
    Left,
    Right,
    SideBySide,
    TopBottom,
    RowInterleaved {
        right_first: bool,
    },
    ColumnInterleaved {
        right_first: bool,
    },
    Checkerboard {
        right_first: bool,
    },
    /// Both eyes traced for every pixel, their colours combined for red-cyan glasses.
    Anaglyph,
}

/// Which pixels of its rectangle an eye's viewport holds.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub enum PixelSet {
    #[default]
    All,
    /// Pixels whose row (y), column (x) or x + y has this parity.
    Rows(u32),
    Columns(u32),
    Checkerboard(u32),
    /// Every pixel, combined with the other eye's colour for red-cyan glasses.
    Anaglyph,
}

impl PixelSet {
    /// Whether frame pixel (x, y) belongs to the set.
    #[inline]
    pub fn holds(self, x: u32, y: u32) -> bool {
        match self {
            PixelSet::All | PixelSet::Anaglyph => true,
            PixelSet::Rows(parity) => y % 2 == parity,
            PixelSet::Columns(parity) => x % 2 == parity,
            PixelSet::Checkerboard(parity) => (x + y) % 2 == parity,
        }
    }
}

impl StereoMode {
    /// Parses the ANARI string value; `None` for anything not in the extension's value list.
    pub fn parse(s: &str) -> Option<StereoMode> {
        match s {
            "none" => Some(StereoMode::None),
            "left" => Some(StereoMode::Left),
            "right" => Some(StereoMode::Right),
            "sideBySide" => Some(StereoMode::SideBySide),
            "topBottom" => Some(StereoMode::TopBottom),
            "rowInterleaved" => Some(StereoMode::RowInterleaved { right_first: false }),
            "columnInterleaved" => Some(StereoMode::ColumnInterleaved { right_first: false }),
            "checkerboard" => Some(StereoMode::Checkerboard { right_first: false }),
            "anaglyph" => Some(StereoMode::Anaglyph),
            _ => None,
        }
    }

    /// The ANARI string value.
    pub fn as_str(self) -> &'static str {
        match self {
            StereoMode::None => "none",
            StereoMode::Left => "left",
            StereoMode::Right => "right",
            StereoMode::SideBySide => "sideBySide",
            StereoMode::TopBottom => "topBottom",
            StereoMode::RowInterleaved { .. } => "rowInterleaved",
            StereoMode::ColumnInterleaved { .. } => "columnInterleaved",
            StereoMode::Checkerboard { .. } => "checkerboard",
            StereoMode::Anaglyph => "anaglyph",
        }
    }

    /// The eyes this mode renders.
    pub fn eyes(self) -> &'static [Eye] {
        match self {
            StereoMode::None => &[Eye::Mono],
            StereoMode::Left => &[Eye::Left],
            StereoMode::Right => &[Eye::Right],
            _ => &[Eye::Left, Eye::Right],
        }
    }

    /// The mode with `interleaveStartRight` applied (interleaved modes only).
    pub fn starting_right(self, right_first: bool) -> StereoMode {
        match self {
            StereoMode::RowInterleaved { .. } => StereoMode::RowInterleaved { right_first },
            StereoMode::ColumnInterleaved { .. } => StereoMode::ColumnInterleaved { right_first },
            StereoMode::Checkerboard { .. } => StereoMode::Checkerboard { right_first },
            other => other,
        }
    }

    /// Splits a `width`×`height` frame among the eyes of this mode.
    ///
    /// `sideBySide`: left eye in the left half (`x` in `[0, width/2)`), right eye in the rest.
    /// `topBottom`: left eye in the top half, i.e. the upper rows (rows count from the bottom),
    /// right eye in the bottom `height/2` rows. With odd sizes the second half gets the extra
    /// column (sideBySide) and the top half the extra row (topBottom), so the viewports always
    /// tile the frame exactly. Zero-sized viewports are returned as they are.
    pub fn viewports(self, width: u32, height: u32) -> Vec<EyeViewport> {
        let whole = |eye| EyeViewport {
            eye,
            x: 0,
            y: 0,
            width,
            height,
            pixels: PixelSet::All,
        };
        // Interleaved: both eyes span the frame; the left eye holds parity 0 unless the right
        // eye comes first.
        let interleaved = |set: fn(u32) -> PixelSet, right_first: bool| {
            let left = u32::from(right_first);
            vec![
                EyeViewport {
                    pixels: set(left),
                    ..whole(Eye::Left)
                },
                EyeViewport {
                    pixels: set(1 - left),
                    ..whole(Eye::Right)
                },
            ]
        };
        match self {
            StereoMode::Anaglyph => vec![
                EyeViewport {
                    pixels: PixelSet::Anaglyph,
                    ..whole(Eye::Left)
                },
                EyeViewport {
                    pixels: PixelSet::Anaglyph,
                    ..whole(Eye::Right)
                },
            ],
            StereoMode::RowInterleaved { right_first } => interleaved(PixelSet::Rows, right_first),
            StereoMode::ColumnInterleaved { right_first } => {
                interleaved(PixelSet::Columns, right_first)
            }
            StereoMode::Checkerboard { right_first } => {
                interleaved(PixelSet::Checkerboard, right_first)
            }
            StereoMode::None => vec![whole(Eye::Mono)],
            StereoMode::Left => vec![whole(Eye::Left)],
            StereoMode::Right => vec![whole(Eye::Right)],
            StereoMode::SideBySide => {
                let left_width = width / 2;
                vec![
                    EyeViewport {
                        eye: Eye::Left,
                        x: 0,
                        y: 0,
                        width: left_width,
                        height,
                        pixels: PixelSet::All,
                    },
                    EyeViewport {
                        eye: Eye::Right,
                        x: left_width,
                        y: 0,
                        width: width - left_width,
                        height,
                        pixels: PixelSet::All,
                    },
                ]
            }
            StereoMode::TopBottom => {
                let bottom_height = height / 2;
                vec![
                    EyeViewport {
                        eye: Eye::Left,
                        x: 0,
                        y: bottom_height,
                        width,
                        height: height - bottom_height,
                        pixels: PixelSet::All,
                    },
                    EyeViewport {
                        eye: Eye::Right,
                        x: 0,
                        y: 0,
                        width,
                        height: bottom_height,
                        pixels: PixelSet::All,
                    },
                ]
            }
        }
    }
}

/// A rectangle of the frame rendered by one eye. y counts rows from the bottom (ANARI row order).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EyeViewport {
    pub eye: Eye,
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
    /// The pixels of the rectangle this eye renders (all but for interleaved modes); rays are
    /// made over the whole rectangle either way.
    pub pixels: PixelSet,
}

impl EyeViewport {
    /// Whether the eye renders every pixel of `[x0, x1) × [y0, y1)`, a block whose pixels are
    /// all drawn from `set`.
    #[inline]
    pub fn holds_block(&self, x0: u32, y0: u32, x1: u32, y1: u32, set: PixelSet) -> bool {
        let inside =
            x0 >= self.x && y0 >= self.y && x1 <= self.x + self.width && y1 <= self.y + self.height;
        inside
            && match self.pixels {
                PixelSet::All | PixelSet::Anaglyph => true,
                own => own == set || (x1 == x0 + 1 && y1 == y0 + 1 && own.holds(x0, y0)),
            }
    }

    /// Whether the eye renders every pixel of `[x0, x1) × [y0, y1)`.
    #[inline]
    pub fn holds(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> bool {
        let inside =
            x0 >= self.x && y0 >= self.y && x1 <= self.x + self.width && y1 <= self.y + self.height;
        match self.pixels {
            PixelSet::All | PixelSet::Anaglyph => inside,
            // An interleaved eye holds single pixels of its parity, never a whole block.
            set => inside && x1 == x0 + 1 && y1 == y0 + 1 && set.holds(x0, y0),
        }
    }
}

/// A camera validated at commit time, usable for any frame size; Send + Sync, shared by render
/// threads.
pub trait Camera: Send + Sync + fmt::Debug {
    /// How a width×height frame is split among eyes (one viewport for mono/left/right; two for
    /// sideBySide/topBottom).
    fn viewports(&self, width: u32, height: u32) -> Vec<EyeViewport>;
    /// Per-frame, per-eye precomputation for a viewport of the given pixel size.
    ///
    /// The requested eye is honoured even if the stereo mode does not use it (a mono camera
    /// asked for `Eye::Left` renders the left eye); cameras without stereo (orthographic,
    /// matrix) render the same rays for every eye.
    fn prepare(&self, eye: Eye, viewport_width: u32, viewport_height: u32) -> EyeRays;
}

/// A rejected camera parameter: `parameter` is the ANARI parameter name.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraError {
    pub parameter: String,
    pub message: String,
}

impl CameraError {
    pub fn new(parameter: impl Into<String>, message: impl Into<String>) -> CameraError {
        CameraError {
            parameter: parameter.into(),
            message: message.into(),
        }
    }
}

impl fmt::Display for CameraError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "camera parameter '{}': {}", self.parameter, self.message)
    }
}

impl std::error::Error for CameraError {}

/// The aspect ratio a viewport implies when the camera's `aspect` is unset (1 for an empty
/// viewport, so that no NaN reaches the ray generator).
pub(crate) fn viewport_aspect(width: u32, height: u32) -> f64 {
    if width == 0 || height == 0 {
        1.0
    } else {
        f64::from(width) / f64::from(height)
    }
}

/// A committed camera, as the frame finds it on the camera object.
pub struct CameraModel(pub std::sync::Arc<dyn Camera>);

/// Validates a camera's committed parameters; problems are reported naming the parameter and
/// leave the camera without a model (frames using it render only the background).
pub fn commit(device: &crate::device::Device, object: &crate::device::object::Object) {
    match camera_from_params(&object.subtype, &object.committed()) {
        Ok(camera) => object.set_derived(Some(std::sync::Arc::new(CameraModel(camera)))),
        Err(error) => {
            device.error(
                crate::device::status::ANARI_STATUS_INVALID_ARGUMENT,
                Some(object),
                format!(
                    "anariCommitParameters: {} parameter '{}': {}; frames using this camera \
                     render only the background",
                    object.describe(),
                    error.parameter,
                    error.message
                ),
            );
            object.set_derived(None);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stereo_mode_parses_every_anari_value_and_nothing_else() {
        for mode in [
            StereoMode::None,
            StereoMode::Left,
            StereoMode::Right,
            StereoMode::SideBySide,
            StereoMode::TopBottom,
        ] {
            assert_eq!(StereoMode::parse(mode.as_str()), Some(mode));
        }
        assert_eq!(
            StereoMode::parse("sideBySide"),
            Some(StereoMode::SideBySide)
        );
        assert_eq!(StereoMode::parse("topBottom"), Some(StereoMode::TopBottom));
        assert_eq!(StereoMode::parse("sidebyside"), None);
        assert_eq!(StereoMode::parse("both"), None);
        assert_eq!(StereoMode::parse(""), None);
    }

    #[test]
    fn side_by_side_puts_left_eye_in_left_half() {
        let v = StereoMode::SideBySide.viewports(101, 40);
        assert_eq!(
            v,
            vec![
                EyeViewport {
                    eye: Eye::Left,
                    x: 0,
                    y: 0,
                    width: 50,
                    height: 40,
                    pixels: PixelSet::All,
                },
                EyeViewport {
                    eye: Eye::Right,
                    x: 50,
                    y: 0,
                    width: 51,
                    height: 40,
                    pixels: PixelSet::All,
                },
            ]
        );
    }

    #[test]
    fn top_bottom_puts_left_eye_in_upper_rows() {
        let v = StereoMode::TopBottom.viewports(64, 31);
        assert_eq!(
            v,
            vec![
                EyeViewport {
                    eye: Eye::Left,
                    x: 0,
                    y: 15,
                    width: 64,
                    height: 16,
                    pixels: PixelSet::All,
                },
                EyeViewport {
                    eye: Eye::Right,
                    x: 0,
                    y: 0,
                    width: 64,
                    height: 15,
                    pixels: PixelSet::All,
                },
            ]
        );
        // Rows count from the bottom, so the left eye's first row is above every right-eye row.
        assert!(v[0].y >= v[1].y + v[1].height);
    }

    #[test]
    fn single_eye_modes_cover_the_whole_frame() {
        for (mode, eye) in [
            (StereoMode::None, Eye::Mono),
            (StereoMode::Left, Eye::Left),
            (StereoMode::Right, Eye::Right),
        ] {
            assert_eq!(
                mode.viewports(7, 5),
                vec![EyeViewport {
                    eye,
                    x: 0,
                    y: 0,
                    width: 7,
                    height: 5,
                    pixels: PixelSet::All,
                }]
            );
        }
    }
}
