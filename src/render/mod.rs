//! Rendering: renderers (shading), frames (tiles, threads, channels) and colour encoding.

pub mod ambient;
mod block_shadows;
pub mod bsdf;
pub mod cluster;
pub mod color;
pub mod diagnostics;
pub mod eye_light;
pub mod frame;
pub mod integrator;
pub mod interleave;
pub mod progressive;
pub mod renderer;
pub mod surface_model;
pub mod volume_lighting;

use std::collections::HashMap;
use std::sync::Arc;

use crate::device::datatype::*;
use crate::device::object::Object;
use crate::device::spec::{ObjectSpec, ParamSpec, SpecValue};
use crate::device::status::*;
use crate::device::{Device, source_of};
use crate::render::frame::{CHANNELS, FrameState, RenderSetup};
use crate::render::renderer::RendererSettings;
use crate::scene::world::SceneSnapshot;

const DATA_TYPE: &[ANARIDataType] = &[ANARI_DATA_TYPE];

pub const FRAME: ObjectSpec = ObjectSpec::new(
    ANARI_FRAME,
    "",
    "an image of a world seen by a camera, rendered by a renderer",
    &[
        ParamSpec::new("world", &[ANARI_WORLD], "world to render").required(),
        ParamSpec::new(
            "renderer",
            &[ANARI_RENDERER],
            "renderer that renders the frame",
        )
        .required(),
        ParamSpec::new("camera", &[ANARI_CAMERA], "camera the world is seen by").required(),
        ParamSpec::new("size", &[ANARI_UINT32_VEC2], "width and height in pixels").required(),
        ParamSpec::new("channel.color", DATA_TYPE, "colour channel type").values(&[
            "ANARI_UFIXED8_RGBA_SRGB",
            "ANARI_UFIXED8_VEC4",
            "ANARI_FLOAT32_VEC4",
        ]),
        ParamSpec::new(
            "channel.depth",
            DATA_TYPE,
            "distance from the eye along the primary ray (+inf on miss)",
        )
        .values(&["ANARI_FLOAT32"]),
        ParamSpec::new(
            "channel.primitiveId",
            DATA_TYPE,
            "primitive index of the hit",
        )
        .values(&["ANARI_UINT32"]),
        ParamSpec::new("channel.objectId", DATA_TYPE, "surface 'id' of the hit")
            .values(&["ANARI_UINT32"]),
        ParamSpec::new("channel.instanceId", DATA_TYPE, "instance 'id' of the hit")
            .values(&["ANARI_UINT32"]),
        ParamSpec::new("channel.albedo", DATA_TYPE, "base colour of the hit").values(&[
            "ANARI_UFIXED8_VEC3",
            "ANARI_UFIXED8_RGB_SRGB",
            "ANARI_FLOAT32_VEC3",
        ]),
        ParamSpec::new(
            "channel.normal",
            DATA_TYPE,
            "world-space shading normal of the hit",
        )
        .values(&["ANARI_FLOAT32_VEC3", "ANARI_FIXED16_VEC3"]),
        ParamSpec::new(
            "channel.windowDepth",
            DATA_TYPE,
            "OpenGL window-space depth in [0,1] under the camera's projection (1 on miss), \
             for compositing with rasterised content",
        )
        .values(&["ANARI_FLOAT32"]),
        ParamSpec::new(
            "channel.parallax",
            DATA_TYPE,
            "signed horizontal screen parallax of the hit in meters on the zero-parallax plane \
             (the offAxis screen, the perspective camera's focus plane): right eye's image point \
             minus left eye's; 0 on the plane, positive behind it, negative in front; NaN on \
             miss and for cameras without stereo; the frame property 'parallaxRange' holds the \
             last render's smallest and largest value",
        )
        .values(&["ANARI_FLOAT32"]),
        ParamSpec::new(
            "accumulation",
            &[ANARI_BOOL],
            "refine progressively over repeated renders while nothing changes",
        ),
        ParamSpec::new(
            "budget",
            &[ANARI_FLOAT32],
            "seconds a render may take: a render traces as many pixels as fit, spread evenly, \
             fills the rest from traced neighbours, and later renders of the unchanged frame \
             refine it until it equals the unbudgeted image (0: every pixel, every render)",
        )
        .default(SpecValue::Float(0.0))
        .range(SpecValue::Float(0.0), SpecValue::Float(3600.0)),
        ParamSpec::new(
            "budgetPixels",
            &[ANARI_UINT32],
            "with a budget: pixels to trace per render instead of what the measured speed \
             allows (reproducible progressive renders); 0 or unset: from the measured speed",
        )
        .default(SpecValue::UInt(0)),
        ParamSpec::new(
            "frameCompletionCallback",
            &[ANARI_FRAME_COMPLETION_CALLBACK],
            "called on a render thread when a render completes",
        ),
        ParamSpec::new(
            "frameCompletionCallbackUserData",
            &[ANARI_VOID_POINTER],
            "first argument of frameCompletionCallback",
        ),
        // Cluster hook: rendering across MPI ranks (docs/cluster.md).
        #[cfg(feature = "mpi")]
        cluster::MPI_COMMUNICATOR,
        #[cfg(feature = "mpi")]
        cluster::MPI_MODE,
        #[cfg(feature = "mpi")]
        cluster::MPI_TIMEOUT,
        #[cfg(feature = "mpi")]
        cluster::MPI_IMAGE_ON_EVERY_RANK,
    ],
)
.channels(&[
    "channel.color",
    "channel.depth",
    "channel.primitiveId",
    "channel.objectId",
    "channel.instanceId",
    "channel.albedo",
    "channel.normal",
    "channel.windowDepth",
    "channel.parallax",
])
.extensions(&[
    "ANARI_KHR_FRAME_CHANNEL_PRIMITIVE_ID",
    "ANARI_KHR_FRAME_CHANNEL_ALBEDO",
    "ANARI_KHR_FRAME_CHANNEL_NORMAL",
    "ANARI_KHR_FRAME_ACCUMULATION",
    "ANARI_KHR_FRAME_COMPLETION_CALLBACK",
    "ANARI_CAVETRACE_FRAME_CHANNEL_WINDOW_DEPTH",
    "ANARI_CAVETRACE_FRAME_BUDGET",
    "ANARI_CAVETRACE_FRAME_CHANNEL_PARALLAX",
    // Cluster hook: rendering across MPI ranks.
    #[cfg(feature = "mpi")]
    "ANARI_KHR_DATA_PARALLEL_MPI",
]);

pub const SPECS: &[ObjectSpec] = &[renderer::DEFAULT, renderer::FAST, FRAME];

/// Largest frame side accepted (beyond this, sizes are reported as out of memory).
pub const MAX_FRAME_SIDE: u32 = 1 << 15;

pub fn commit(device: &Device, object: &Object) {
    match object.kind {
        ANARI_RENDERER => {
            object.set_derived(Some(Arc::new(renderer::commit(device, object))));
        }
        ANARI_FRAME => {
            let params = object.committed();
            for (name, accepted) in CHANNELS {
                if let Some(t) = params.get_data_type(name)
                    && !accepted.contains(&t)
                {
                    device.error(
                        ANARI_STATUS_INVALID_ARGUMENT,
                        Some(object),
                        format!(
                            "anariCommitParameters: frame parameter '{name}': {} is not a type \
                             this channel can be mapped as (accepted: {})",
                            type_name(t),
                            accepted
                                .iter()
                                .map(|t| type_name(*t))
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    );
                }
            }
            if let Some(budget) = params.get_f32("budget")
                && !(budget.is_finite() && budget >= 0.0)
            {
                device.error(
                    ANARI_STATUS_INVALID_ARGUMENT,
                    Some(object),
                    format!(
                        "anariCommitParameters: frame parameter 'budget': {budget} is not a \
                         finite number of seconds ≥ 0; every pixel is rendered"
                    ),
                );
            }
            if let Some(size) = params.get_uvec2("size")
                && (size.x == 0 || size.y == 0)
            {
                device.error(
                    ANARI_STATUS_INVALID_ARGUMENT,
                    Some(object),
                    format!(
                        "anariCommitParameters: frame 'size' {}×{} is empty; nothing can be rendered",
                        size.x, size.y
                    ),
                );
            }
        }
        _ => {}
    }
    // Cluster hook: the frame's MPI communicator is duplicated at its commit.
    #[cfg(feature = "mpi")]
    if object.kind == ANARI_FRAME {
        cluster::commit_frame(device, object);
    }
}

/// The frame's budget: a finite positive `budget` (seconds), with `budgetPixels` if non-zero.
fn budget(params: &crate::device::params::ParamSet) -> Option<frame::Budget> {
    let seconds = params
        .get_f32("budget")
        .filter(|s| s.is_finite() && *s > 0.0)?;
    Some(frame::Budget {
        seconds,
        pixels: params.get_u32("budgetPixels").filter(|p| *p > 0),
    })
}

/// anariRenderFrame: snapshots the committed scene and starts rendering on the device's threads.
pub fn render_frame(device: &Device, frame: &Object) {
    let requested = std::time::Instant::now();
    let Some(state) = frame
        .frame
        .clone()
        .and_then(|state| state.into_any().downcast::<FrameState>().ok())
    else {
        return;
    };
    diagnostics::report_uncommitted(device, frame);
    let params = frame.committed();
    let fail = |code, text: String| {
        device.error(code, Some(frame), format!("anariRenderFrame: {text}"));
    };
    let Some(size) = params.get_uvec2("size") else {
        fail(
            ANARI_STATUS_INVALID_OPERATION,
            "frame has no committed 'size' (ANARI_UINT32_VEC2); nothing is rendered".into(),
        );
        return;
    };
    if size.x == 0 || size.y == 0 {
        fail(
            ANARI_STATUS_INVALID_ARGUMENT,
            format!(
                "frame 'size' {}×{} is empty; nothing is rendered",
                size.x, size.y
            ),
        );
        return;
    }
    if size.x > MAX_FRAME_SIDE || size.y > MAX_FRAME_SIDE {
        fail(
            ANARI_STATUS_OUT_OF_MEMORY,
            format!(
                "frame 'size' {}×{} exceeds {MAX_FRAME_SIDE} pixels per side; nothing is rendered",
                size.x, size.y
            ),
        );
        return;
    }
    let camera = params
        .get_object("camera")
        .and_then(|c| c.derived_as::<crate::camera::CameraModel>())
        .map(|c| Arc::clone(&c.0));
    if camera.is_none() {
        fail(
            ANARI_STATUS_INVALID_OPERATION,
            "frame has no valid committed 'camera'; only the background is rendered".into(),
        );
    }
    let settings = params
        .get_object("renderer")
        .and_then(|r| r.derived_as::<RendererSettings>())
        .map(|s| (*s).clone())
        .unwrap_or_default();
    let scene = match params.get_object("world") {
        Some(world) => crate::scene::world::snapshot(device, world),
        None => {
            fail(
                ANARI_STATUS_INVALID_OPERATION,
                "frame has no committed 'world'; only the background is rendered".into(),
            );
            SceneSnapshot::empty()
        }
    };
    diagnostics::report_unlit(device, frame, &state, &settings, &scene);
    let mut channels = HashMap::new();
    for (name, accepted) in CHANNELS {
        if let Some(t) = params.get_data_type(name)
            && accepted.contains(&t)
        {
            channels.insert(*name, t);
        }
    }
    let completion = params
        .get_pointer("frameCompletionCallback", ANARI_FRAME_COMPLETION_CALLBACK)
        .map(|address| {
            // SAFETY: the application passed this address as an ANARIFrameCompletionCallback.
            let callback: frame::ANARIFrameCompletionCallback =
                unsafe { std::mem::transmute(address) };
            let user = params
                .get_pointer("frameCompletionCallbackUserData", ANARI_VOID_POINTER)
                .unwrap_or(0);
            (callback, user, device.handle, frame.handle)
        });
    let setup = RenderSetup {
        width: size.x,
        height: size.y,
        scene: Arc::new(scene),
        camera,
        settings,
        channels,
        accumulate: params.get_bool("accumulation").unwrap_or(false),
        scene_version: device.commit_epoch(),
        completion,
        budget: budget(&params),
        requested,
        tile_split: None,
        status: Some((Arc::clone(&device.status), source_of(Some(frame)))),
    };
    // Cluster hook: a frame rendered across MPI ranks renders here, collectively.
    #[cfg(feature = "mpi")]
    let Some(setup) = cluster::render(device, frame, &state, setup) else {
        return;
    };
    match state.start(setup, &device.pool()) {
        Ok(()) => {}
        Err(frame::StartError::Exceeds(too_big)) => fail(
            ANARI_STATUS_OUT_OF_MEMORY,
            format!(
                "the buffers of a {}×{} frame (its channels and accumulation) {too_big}; \
                 nothing is rendered",
                size.x, size.y
            ),
        ),
        Err(frame::StartError::OutOfMemory) => fail(
            ANARI_STATUS_OUT_OF_MEMORY,
            format!(
                "cannot allocate the buffers of a {}×{} frame; nothing is rendered",
                size.x, size.y
            ),
        ),
    }
}
