//! The introspection tables of the camera subtypes: every parameter `anari.rs` reads, with
//! its types, default and description, and the extensions each subtype belongs to.

use crate::device::datatype::*;
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};

use super::omnidirectional::OmnidirectionalLayout;
use super::viewers::{DEFAULT_CUTOFF_ANGLE, DEFAULT_TILES, MAX_VIEWERS};
use super::{DEFAULT_INTERPUPILLARY_DISTANCE, ViewerMode, ViewerWeighting};

const POSITION: ParamSpec = ParamSpec::new("position", &[ANARI_FLOAT32_VEC3], "camera position")
    .default(SpecValue::Floats(&[0.0, 0.0, 0.0]));
const DIRECTION: ParamSpec =
    ParamSpec::new("direction", &[ANARI_FLOAT32_VEC3], "main viewing direction")
        .default(SpecValue::Floats(&[0.0, 0.0, -1.0]));
const UP: ParamSpec = ParamSpec::new("up", &[ANARI_FLOAT32_VEC3], "camera up direction")
    .default(SpecValue::Floats(&[0.0, 1.0, 0.0]));
const IMAGE_REGION: ParamSpec = ParamSpec::new(
    "imageRegion",
    &[ANARI_FLOAT32_BOX2],
    "region of the camera's full image mapped to the frame, [lo.x, lo.y, hi.x, hi.y]; may reach \
     beyond [0,1]² (the image plane continues) and run backwards (hi < lo flips)",
)
.default(SpecValue::Floats(&[0.0, 0.0, 1.0, 1.0]));
const ASPECT: ParamSpec = ParamSpec::new(
    "aspect",
    &[ANARI_FLOAT32],
    "width / height of the image plane (unset: the viewport's aspect)",
);
const NEAR: ParamSpec = ParamSpec::new(
    "near",
    &[ANARI_FLOAT32],
    "near clip distance along the view axis",
);
const FAR: ParamSpec = ParamSpec::new(
    "far",
    &[ANARI_FLOAT32],
    "far clip distance along the view axis",
);
const STEREO_MODE: ParamSpec = ParamSpec::new(
    "stereoMode",
    &[ANARI_STRING],
    "stereo mode; rowInterleaved, columnInterleaved and checkerboard (passive 3D displays) \
     trace each pixel from the eye its row, column or checkerboard square belongs to; \
     anaglyph traces both eyes and combines them for red-cyan glasses (Dubois)",
)
.default(SpecValue::Str("none"))
.values(&[
    "none",
    "left",
    "right",
    "sideBySide",
    "topBottom",
    "rowInterleaved",
    "columnInterleaved",
    "checkerboard",
    "anaglyph",
]);
const INTERLEAVE_START_RIGHT: ParamSpec = ParamSpec::new(
    "interleaveStartRight",
    &[ANARI_BOOL],
    "interleaved stereo modes: the first row (bottom), first column (left) or bottom-left \
     pixel belongs to the right eye instead of the left",
)
.default(SpecValue::Bool(false));
const INTERPUPILLARY_DISTANCE: ParamSpec = ParamSpec::new(
    "interpupillaryDistance",
    &[ANARI_FLOAT32],
    "distance between the eyes, which sit at ±half of it along the camera's right vector",
)
.default(SpecValue::Float(DEFAULT_INTERPUPILLARY_DISTANCE));

pub const PERSPECTIVE: ObjectSpec = ObjectSpec::new(
    ANARI_CAMERA,
    "perspective",
    "perspective camera with parallel-axis off-axis stereo and thin-lens depth of field",
    &[
        POSITION,
        DIRECTION,
        UP,
        IMAGE_REGION,
        ParamSpec::new(
            "fovy",
            &[ANARI_FLOAT32],
            "vertical field of view in radians",
        )
        .default(SpecValue::Float(std::f32::consts::FRAC_PI_3)),
        ASPECT,
        NEAR,
        FAR,
        STEREO_MODE,
        INTERLEAVE_START_RIGHT,
        INTERPUPILLARY_DISTANCE,
        ParamSpec::new("apertureRadius", &[ANARI_FLOAT32], "aperture radius")
            .default(SpecValue::Float(0.0)),
        ParamSpec::new(
            "focusDistance",
            &[ANARI_FLOAT32],
            "distance of the focus plane, also the zero-parallax plane in stereo",
        )
        .default(SpecValue::Float(1.0)),
    ],
)
.extensions(&[
    "ANARI_KHR_CAMERA_PERSPECTIVE",
    "ANARI_KHR_CAMERA_STEREO",
    "ANARI_CAVETRACE_STEREO_INTERLEAVED",
    "ANARI_KHR_CAMERA_DEPTH_OF_FIELD",
]);

pub const ORTHOGRAPHIC: ObjectSpec = ObjectSpec::new(
    ANARI_CAMERA,
    "orthographic",
    "orthographic camera",
    &[
        POSITION,
        DIRECTION,
        UP,
        IMAGE_REGION,
        ASPECT,
        ParamSpec::new("height", &[ANARI_FLOAT32], "height of the image plane")
            .default(SpecValue::Float(1.0)),
        NEAR,
        FAR,
    ],
)
.extensions(&["ANARI_KHR_CAMERA_ORTHOGRAPHIC"]);

pub const MATRIX: ObjectSpec = ObjectSpec::new(
    ANARI_CAMERA,
    "matrix",
    "camera given by OpenGL view and projection matrices (column-major, NDC z in [-1,1])",
    &[
        ParamSpec::new(
            "view",
            &[ANARI_FLOAT32_MAT4],
            "world to eye space (default identity)",
        )
        .default(SpecValue::Floats(&IDENTITY)),
        ParamSpec::new(
            "proj",
            &[ANARI_FLOAT32_MAT4],
            "eye to clip space: any glFrustum, glOrtho or infinite-far projection (default identity)",
        )
        .default(SpecValue::Floats(&IDENTITY)),
        IMAGE_REGION,
    ],
)
.extensions(&["ANARI_VSNRAY_CAMERA_MATRIX"]);

pub(super) const IDENTITY: [f32; 16] = [
    1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
];

// A physical screen rectangle (offAxis and lightField cameras).
const SCREEN_LOWER_LEFT: ParamSpec = ParamSpec::new(
    "screen.lowerLeft",
    &[ANARI_FLOAT32_VEC3],
    "lower-left screen corner in world space",
)
.required();
const SCREEN_LOWER_RIGHT: ParamSpec = ParamSpec::new(
    "screen.lowerRight",
    &[ANARI_FLOAT32_VEC3],
    "lower-right screen corner in world space",
)
.required();
const SCREEN_UPPER_RIGHT: ParamSpec = ParamSpec::new(
    "screen.upperRight",
    &[ANARI_FLOAT32_VEC3],
    "upper-right screen corner in world space",
)
.required();

pub const LIGHT_FIELD: ObjectSpec = ObjectSpec::new(
    ANARI_CAMERA,
    "lightField",
    "a slanted-lenticular light-field display: one ray per R, G and B subpixel, from the eye of \
     the view the display's calibration gives that subpixel, through the subpixel's centre",
    &[
        SCREEN_LOWER_LEFT,
        SCREEN_LOWER_RIGHT,
        SCREEN_UPPER_RIGHT,
        ParamSpec::new(
            "pitch",
            &[ANARI_FLOAT32],
            "lenticules per inch (calibration)",
        )
        .default(SpecValue::Float(49.82)),
        ParamSpec::new("slope", &[ANARI_FLOAT32], "lenticule slope (calibration)")
            .default(SpecValue::Float(5.04)),
        ParamSpec::new(
            "center",
            &[ANARI_FLOAT32],
            "lenticular phase offset (calibration)",
        )
        .default(SpecValue::Float(0.177)),
        ParamSpec::new(
            "dpi",
            &[ANARI_FLOAT32],
            "panel pixels per inch (calibration)",
        )
        .default(SpecValue::Float(338.0)),
        ParamSpec::new(
            "invView",
            &[ANARI_BOOL],
            "views run the other way (calibration)",
        )
        .default(SpecValue::Bool(false)),
        ParamSpec::new(
            "viewCone",
            &[ANARI_FLOAT32],
            "angle the views span, in degrees (calibration)",
        )
        .default(SpecValue::Float(40.0)),
        ParamSpec::new(
            "flipImageX",
            &[ANARI_BOOL],
            "mirror the image left to right",
        )
        .default(SpecValue::Bool(false)),
        ParamSpec::new(
            "flipImageY",
            &[ANARI_BOOL],
            "mirror the image top to bottom",
        )
        .default(SpecValue::Bool(false)),
        ParamSpec::new(
            "flipSubpixels",
            &[ANARI_BOOL],
            "subpixels are B, G, R from the left (calibration flipSubp)",
        )
        .default(SpecValue::Bool(false)),
        ParamSpec::new(
            "viewingDistance",
            &[ANARI_FLOAT32],
            "distance of the views' eyes from the screen (default: the screen's height spans \
             14°)",
        ),
        ParamSpec::new(
            "views",
            &[ANARI_UINT32],
            "0: every subpixel its own view fraction; N: snapped to the nearest of N views, as \
             quilt-based drivers do",
        )
        .default(SpecValue::UInt(0)),
        ParamSpec::new(
            "quilt",
            &[ANARI_UINT32_VEC2],
            "columns × rows: render a quilt of that many whole views instead (view 0 at the \
             bottom left, rows bottom to top); 0 × 0: one ray per subpixel",
        )
        .default(SpecValue::UInts(&[0, 0])),
    ],
)
.extensions(&["ANARI_CAVETRACE_CAMERA_LIGHT_FIELD"]);

pub const OFF_AXIS: ObjectSpec = ObjectSpec::new(
    ANARI_CAMERA,
    "offAxis",
    "tracked eye looking at a physical screen rectangle (CAVE wall, powerwall): each eye gets \
     its exact off-axis frustum, the screen is the zero-parallax plane",
    &[
        SCREEN_LOWER_LEFT,
        SCREEN_LOWER_RIGHT,
        SCREEN_UPPER_RIGHT,
        ParamSpec::new(
            "position",
            &[ANARI_FLOAT32_VEC3],
            "tracked eye, or the head centre between the eyes in stereo; must be in front of the screen",
        )
        .default(SpecValue::Floats(&[0.0, 0.0, 0.0])),
        ParamSpec::new(
            "right",
            &[ANARI_FLOAT32_VEC3],
            "the head's right vector for stereo (unset: the screen's lower edge direction)",
        ),
        STEREO_MODE,
        INTERLEAVE_START_RIGHT,
        INTERPUPILLARY_DISTANCE,
        ParamSpec::new(
            "near",
            &[ANARI_FLOAT32],
            "near clip distance from the eye, perpendicular to the screen",
        ),
        ParamSpec::new(
            "far",
            &[ANARI_FLOAT32],
            "far clip distance from the eye, perpendicular to the screen",
        ),
        IMAGE_REGION,
        ParamSpec::new(
            "viewer.position",
            &[ANARI_ARRAY1D],
            "several tracked viewers: one head position per viewer (FLOAT32_VEC3, at most 64); \
             when set, position and right are not used",
        ),
        ParamSpec::new(
            "viewer.direction",
            &[ANARI_ARRAY1D],
            "each viewer's gaze direction (FLOAT32_VEC3, need not be unit length)",
        ),
        ParamSpec::new(
            "viewer.right",
            &[ANARI_ARRAY1D],
            "each viewer's right vector for stereo (FLOAT32_VEC3; unset: the screen's lower edge direction)",
        ),
        ParamSpec::new(
            "viewerMode",
            &[ANARI_STRING],
            "which screen point's viewer weights choose a pixel's camera position",
        )
        .default(SpecValue::Str("perPixel"))
        .values(&ViewerMode::VALUES),
        ParamSpec::new(
            "viewerWeighting",
            &[ANARI_STRING],
            "fall-off of a viewer's weight with the angle between its gaze and the screen point",
        )
        .default(SpecValue::Str("linear"))
        .values(&ViewerWeighting::VALUES),
        ParamSpec::new(
            "viewerCutoffAngle",
            &[ANARI_FLOAT32],
            "angle in radians at which a viewer's linear weight reaches 0 (its zone's cone)",
        )
        .default(SpecValue::Float(DEFAULT_CUTOFF_ANGLE)),
        ParamSpec::new(
            "viewerTiles",
            &[ANARI_UINT32_VEC2],
            "tiles across and up the screen for viewerMode tiles",
        )
        .default(SpecValue::UInts(&DEFAULT_TILES)),
    ],
)
.extensions(&[
    "ANARI_CAVETRACE_CAMERA_OFF_AXIS",
    "ANARI_CAVETRACE_CAMERA_MULTI_VIEWER",
    "ANARI_KHR_CAMERA_STEREO",
    "ANARI_CAVETRACE_STEREO_INTERLEAVED",
]);

pub const OMNIDIRECTIONAL: ObjectSpec = ObjectSpec::new(
    ANARI_CAMERA,
    "omnidirectional",
    "360° camera: equirectangular panorama, longitude 2π(s−½) to the right and latitude π(t−½) \
     upwards, the centre along direction; stereo is omni-directional stereo (ODS) for 360° \
     video",
    &[
        POSITION,
        DIRECTION,
        UP,
        ParamSpec::new(
            "imageRegion",
            &[ANARI_FLOAT32_BOX2],
            "region of the panorama mapped to the frame, [lo.x, lo.y, hi.x, hi.y]; may reach \
             beyond [0,1]² (the mapping continues round and over the poles) and run backwards \
             (hi < lo flips)",
        )
        .default(SpecValue::Floats(&[0.0, 0.0, 1.0, 1.0])),
        ParamSpec::new("layout", &[ANARI_STRING], "pixel layout")
            .default(SpecValue::Str("equirectangular"))
            .values(&OmnidirectionalLayout::VALUES),
        STEREO_MODE,
        INTERLEAVE_START_RIGHT,
        ParamSpec::new(
            "interpupillaryDistance",
            &[ANARI_FLOAT32],
            "diameter of the ODS circle: each column's eyes sit at ±half of it around position, \
             perpendicular to the column's longitude",
        )
        .default(SpecValue::Float(DEFAULT_INTERPUPILLARY_DISTANCE)),
    ],
)
.extensions(&[
    "ANARI_KHR_CAMERA_OMNIDIRECTIONAL",
    "ANARI_KHR_CAMERA_STEREO",
    "ANARI_CAVETRACE_STEREO_INTERLEAVED",
]);

pub const FISHEYE: ObjectSpec = ObjectSpec::new(
    ANARI_CAMERA,
    "fisheye",
    "dome camera (planetariums, fulldome): azimuthal equidistant image circle inscribed in the \
     frame, angle from dome.direction = (r/R)·fov/2; each pixel maps to a fixed dome point, rays \
     start at the tracked eye and pass through it; pixels outside the circle show the \
     renderer's background",
    &[
        ParamSpec::new(
            "position",
            &[ANARI_FLOAT32_VEC3],
            "tracked viewer, or the head centre between the eyes in stereo; must be inside the \
             dome when dome.radius is set",
        )
        .default(SpecValue::Floats(&[0.0, 0.0, 0.0])),
        ParamSpec::new(
            "dome.center",
            &[ANARI_FLOAT32_VEC3],
            "centre of the dome sphere in world space",
        )
        .default(SpecValue::Floats(&[0.0, 0.0, 0.0])),
        ParamSpec::new(
            "dome.radius",
            &[ANARI_FLOAT32],
            "radius of the dome sphere in meters (unset: infinitely far, every eye looks along \
             the pixel's direction from the centre)",
        ),
        ParamSpec::new(
            "dome.direction",
            &[ANARI_FLOAT32_VEC3],
            "dome axis from the centre: where the image centre looks (the zenith of a flat dome)",
        )
        .default(SpecValue::Floats(&[0.0, 1.0, 0.0])),
        ParamSpec::new(
            "dome.up",
            &[ANARI_FLOAT32_VEC3],
            "dome direction towards the image's top edge (made perpendicular to dome.direction); \
             the image's right is dome.direction × dome.up",
        )
        .default(SpecValue::Floats(&[0.0, 0.0, 1.0])),
        ParamSpec::new(
            "dome.tilt",
            &[ANARI_FLOAT32],
            "dome tilt in radians: dome.direction and dome.up turn about the image's right \
             vector, the axis towards the image's bottom edge (the audience's front)",
        )
        .default(SpecValue::Float(0.0)),
        ParamSpec::new(
            "fov",
            &[ANARI_FLOAT32],
            "full angle of the image circle in radians, in (0, 2π]",
        )
        .default(SpecValue::Float(std::f32::consts::PI)),
        ParamSpec::new(
            "right",
            &[ANARI_FLOAT32_VEC3],
            "the head's right vector for stereo (unset: the image's right vector)",
        ),
        IMAGE_REGION,
        STEREO_MODE,
        INTERLEAVE_START_RIGHT,
        INTERPUPILLARY_DISTANCE,
    ],
)
.extensions(&[
    "ANARI_CAVETRACE_CAMERA_FISHEYE",
    "ANARI_KHR_CAMERA_STEREO",
    "ANARI_CAVETRACE_STEREO_INTERLEAVED",
]);

const _: () = assert!(MAX_VIEWERS == 64, "the viewer.position description says 64");

/// The camera subtypes this module implements.
pub const SPECS: &[ObjectSpec] = &[
    PERSPECTIVE,
    ORTHOGRAPHIC,
    MATRIX,
    OFF_AXIS,
    LIGHT_FIELD,
    OMNIDIRECTIONAL,
    FISHEYE,
];
