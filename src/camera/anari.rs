//! ANARI glue: camera objects from committed parameter sets (the subtypes' introspection
//! tables, which declare these parameters, are in `specs.rs`).

use std::sync::Arc;

use crate::device::params::ParamSet;

use super::fisheye::FisheyeDesc;
use super::light_field::LightFieldDesc;
use super::omnidirectional::{OmnidirectionalDesc, OmnidirectionalLayout};
use super::viewers::{DEFAULT_CUTOFF_ANGLE, DEFAULT_TILES};
use super::{
    Camera, CameraError, MatrixDesc, OffAxisDesc, OrthographicDesc, PerspectiveDesc, StereoMode,
    ViewerDesc, ViewerMode, ViewerWeighting,
};

/// Builds and validates the camera of `subtype` ("perspective", "orthographic", "matrix",
/// "offAxis", "lightField", "omnidirectional", "fisheye") from its committed parameters. Unset parameters (and parameters of another type,
/// which the getters report as unset) take their defaults.
pub fn camera_from_params(
    subtype: &str,
    params: &ParamSet,
) -> Result<Arc<dyn Camera>, CameraError> {
    match subtype {
        "perspective" => perspective_desc(params)?.build(),
        "orthographic" => orthographic_desc(params).build(),
        "matrix" => matrix_desc(params).build(),
        "offAxis" => offaxis_desc(params)?.build(),
        "lightField" => light_field_desc(params).build(),
        "omnidirectional" => omnidirectional_desc(params)?.build(),
        "fisheye" => fisheye_desc(params)?.build(),
        other => Err(CameraError::new(
            "subtype",
            format!("unknown camera subtype '{other}'"),
        )),
    }
}

fn stereo_mode(params: &ParamSet) -> Result<StereoMode, CameraError> {
    let right_first = params.get_bool("interleaveStartRight").unwrap_or(false);
    match params.get_string("stereoMode") {
        None => Ok(StereoMode::None),
        Some(value) => StereoMode::parse(value)
            .map(|mode| mode.starting_right(right_first))
            .ok_or_else(|| {
                CameraError::new(
                    "stereoMode",
                    format!(
                        "unknown value '{value}' (expected none, left, right, sideBySide, \
                         topBottom, rowInterleaved, columnInterleaved, checkerboard or anaglyph)"
                    ),
                )
            }),
    }
}

fn perspective_desc(params: &ParamSet) -> Result<PerspectiveDesc, CameraError> {
    let defaults = PerspectiveDesc::default();
    Ok(PerspectiveDesc {
        position: params.get_vec3("position").unwrap_or(defaults.position),
        direction: params.get_vec3("direction").unwrap_or(defaults.direction),
        up: params.get_vec3("up").unwrap_or(defaults.up),
        fovy: params.get_f32("fovy").unwrap_or(defaults.fovy),
        aspect: params.get_f32("aspect"),
        image_region: params
            .get_box2("imageRegion")
            .unwrap_or(defaults.image_region),
        near: params.get_f32("near"),
        far: params.get_f32("far"),
        stereo_mode: stereo_mode(params)?,
        interpupillary_distance: params
            .get_f32("interpupillaryDistance")
            .unwrap_or(defaults.interpupillary_distance),
        aperture_radius: params
            .get_f32("apertureRadius")
            .unwrap_or(defaults.aperture_radius),
        focus_distance: params
            .get_f32("focusDistance")
            .unwrap_or(defaults.focus_distance),
    })
}

fn orthographic_desc(params: &ParamSet) -> OrthographicDesc {
    let defaults = OrthographicDesc::default();
    OrthographicDesc {
        position: params.get_vec3("position").unwrap_or(defaults.position),
        direction: params.get_vec3("direction").unwrap_or(defaults.direction),
        up: params.get_vec3("up").unwrap_or(defaults.up),
        height: params.get_f32("height").unwrap_or(defaults.height),
        aspect: params.get_f32("aspect"),
        image_region: params
            .get_box2("imageRegion")
            .unwrap_or(defaults.image_region),
        near: params.get_f32("near"),
        far: params.get_f32("far"),
    }
}

fn matrix_desc(params: &ParamSet) -> MatrixDesc {
    let defaults = MatrixDesc::default();
    MatrixDesc {
        view: params.get_mat4("view").unwrap_or(defaults.view),
        proj: params.get_mat4("proj").unwrap_or(defaults.proj),
        image_region: params
            .get_box2("imageRegion")
            .unwrap_or(defaults.image_region),
    }
}

fn offaxis_desc(params: &ParamSet) -> Result<OffAxisDesc, CameraError> {
    let defaults = OffAxisDesc::default();
    Ok(OffAxisDesc {
        lower_left: params.get_vec3("screen.lowerLeft"),
        lower_right: params.get_vec3("screen.lowerRight"),
        upper_right: params.get_vec3("screen.upperRight"),
        position: params.get_vec3("position").unwrap_or(defaults.position),
        right: params.get_vec3("right"),
        stereo_mode: stereo_mode(params)?,
        interpupillary_distance: params
            .get_f32("interpupillaryDistance")
            .unwrap_or(defaults.interpupillary_distance),
        near: params.get_f32("near"),
        far: params.get_f32("far"),
        image_region: params
            .get_box2("imageRegion")
            .unwrap_or(defaults.image_region),
        viewers: viewer_desc(params)?,
    })
}

fn omnidirectional_desc(params: &ParamSet) -> Result<OmnidirectionalDesc, CameraError> {
    let defaults = OmnidirectionalDesc::default();
    let layout = match params.get_string("layout") {
        None => defaults.layout,
        Some(value) => OmnidirectionalLayout::parse(value).ok_or_else(|| {
            CameraError::new(
                "layout",
                format!("unknown value '{value}' (expected equirectangular)"),
            )
        })?,
    };
    Ok(OmnidirectionalDesc {
        position: params.get_vec3("position").unwrap_or(defaults.position),
        direction: params.get_vec3("direction").unwrap_or(defaults.direction),
        up: params.get_vec3("up").unwrap_or(defaults.up),
        image_region: params
            .get_box2("imageRegion")
            .unwrap_or(defaults.image_region),
        layout,
        stereo_mode: stereo_mode(params)?,
        interpupillary_distance: params
            .get_f32("interpupillaryDistance")
            .unwrap_or(defaults.interpupillary_distance),
    })
}

fn fisheye_desc(params: &ParamSet) -> Result<FisheyeDesc, CameraError> {
    let defaults = FisheyeDesc::default();
    Ok(FisheyeDesc {
        position: params.get_vec3("position").unwrap_or(defaults.position),
        dome_center: params
            .get_vec3("dome.center")
            .unwrap_or(defaults.dome_center),
        dome_radius: params.get_f32("dome.radius"),
        dome_direction: params
            .get_vec3("dome.direction")
            .unwrap_or(defaults.dome_direction),
        dome_up: params.get_vec3("dome.up").unwrap_or(defaults.dome_up),
        dome_tilt: params.get_f32("dome.tilt").unwrap_or(defaults.dome_tilt),
        fov: params.get_f32("fov").unwrap_or(defaults.fov),
        right: params.get_vec3("right"),
        image_region: params
            .get_box2("imageRegion")
            .unwrap_or(defaults.image_region),
        stereo_mode: stereo_mode(params)?,
        interpupillary_distance: params
            .get_f32("interpupillaryDistance")
            .unwrap_or(defaults.interpupillary_distance),
    })
}

fn light_field_desc(params: &ParamSet) -> LightFieldDesc {
    let defaults = LightFieldDesc::default();
    let float = |name: &str, default: f32| params.get_f32(name).unwrap_or(default);
    let flag = |name: &str| params.get_bool(name).unwrap_or(false);
    LightFieldDesc {
        lower_left: params.get_vec3("screen.lowerLeft"),
        lower_right: params.get_vec3("screen.lowerRight"),
        upper_right: params.get_vec3("screen.upperRight"),
        pitch: float("pitch", defaults.pitch),
        slope: float("slope", defaults.slope),
        center: float("center", defaults.center),
        dpi: float("dpi", defaults.dpi),
        inv_view: flag("invView"),
        view_cone: float("viewCone", defaults.view_cone),
        flip_image_x: flag("flipImageX"),
        flip_image_y: flag("flipImageY"),
        flip_subpixels: flag("flipSubpixels"),
        viewing_distance: params.get_f32("viewingDistance"),
        views: params.get_u32("views").unwrap_or(0),
        quilt: params
            .get_uvec2("quilt")
            .map_or([0, 0], |quilt| quilt.to_array()),
    }
}

/// The `viewer*` parameters of an offAxis camera; `None` without `viewer.position`.
fn viewer_desc(params: &ParamSet) -> Result<Option<ViewerDesc>, CameraError> {
    let vectors = |name: &str| -> Result<Option<Vec<glam::Vec3>>, CameraError> {
        if !params.contains(name) {
            return Ok(None);
        }
        params
            .get_object(name)
            .and_then(|object| object.array.as_ref())
            .filter(|array| array.dims[1] <= 1 && array.dims[2] <= 1)
            .and_then(|array| array.read_vec3())
            .map(Some)
            .ok_or_else(|| {
                CameraError::new(
                    name,
                    "must be an ARRAY1D of FLOAT32_VEC3, one element per viewer",
                )
            })
    };
    let Some(positions) = vectors("viewer.position")? else {
        return Ok(None);
    };
    let directions = vectors("viewer.direction")?.ok_or_else(|| {
        CameraError::new(
            "viewer.direction",
            "is required with viewer.position (one gaze direction per viewer)",
        )
    })?;
    let choice = |name: &str, values: &[&str]| -> Result<Option<String>, CameraError> {
        match params.get_string(name) {
            None => Ok(None),
            Some(value) if values.contains(&value) => Ok(Some(value.to_string())),
            Some(value) => Err(CameraError::new(
                name,
                format!("unknown value '{value}' (expected {})", values.join(", ")),
            )),
        }
    };
    let mode = choice("viewerMode", &ViewerMode::VALUES)?
        .and_then(|value| ViewerMode::parse(&value))
        .unwrap_or_default();
    let weighting = choice("viewerWeighting", &ViewerWeighting::VALUES)?
        .and_then(|value| ViewerWeighting::parse(&value))
        .unwrap_or_default();
    Ok(Some(ViewerDesc {
        positions,
        directions,
        rights: vectors("viewer.right")?,
        mode,
        weighting,
        cutoff_angle: params
            .get_f32("viewerCutoffAngle")
            .unwrap_or(DEFAULT_CUTOFF_ANGLE),
        tiles: params
            .get_uvec2("viewerTiles")
            .map_or(DEFAULT_TILES, |tiles| tiles.to_array()),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::specs::{IDENTITY, SPECS};
    use crate::camera::{Eye, EyeViewport};
    use crate::device::datatype::*;
    use crate::device::params::ParamValue;
    use crate::device::spec::SpecValue;
    use glam::{Mat4, Vec2, Vec3};

    fn floats(set: &mut ParamSet, name: &str, data_type: ANARIDataType, values: &[f32]) {
        set.set(name, ParamValue::from_f32s(data_type, values));
    }

    fn same_rays(a: &dyn Camera, b: &dyn Camera) {
        assert_eq!(a.viewports(40, 30), b.viewports(40, 30));
        for viewport in a.viewports(40, 30) {
            let ra = a.prepare(viewport.eye, viewport.width, viewport.height);
            let rb = b.prepare(viewport.eye, viewport.width, viewport.height);
            for (s, t) in [(0.1, 0.2), (0.5, 0.5), (0.95, 0.7)] {
                assert_eq!(
                    ra.ray(s, t, Vec2::splat(0.3)),
                    rb.ray(s, t, Vec2::splat(0.3))
                );
            }
        }
    }

    #[test]
    fn perspective_parameters_reach_the_camera() {
        let mut set = ParamSet::default();
        floats(&mut set, "position", ANARI_FLOAT32_VEC3, &[1.0, 2.0, 3.0]);
        floats(&mut set, "direction", ANARI_FLOAT32_VEC3, &[0.0, 0.0, 1.0]);
        floats(&mut set, "up", ANARI_FLOAT32_VEC3, &[0.0, 1.0, 0.2]);
        floats(&mut set, "fovy", ANARI_FLOAT32, &[0.7]);
        floats(&mut set, "aspect", ANARI_FLOAT32, &[1.25]);
        floats(
            &mut set,
            "imageRegion",
            ANARI_FLOAT32_BOX2,
            &[0.1, 0.2, 0.9, 0.8],
        );
        floats(&mut set, "near", ANARI_FLOAT32, &[0.1]);
        floats(&mut set, "far", ANARI_FLOAT32, &[100.0]);
        floats(&mut set, "interpupillaryDistance", ANARI_FLOAT32, &[0.07]);
        floats(&mut set, "apertureRadius", ANARI_FLOAT32, &[0.02]);
        floats(&mut set, "focusDistance", ANARI_FLOAT32, &[3.0]);
        set.set("stereoMode", ParamValue::String("topBottom".into()));
        let from_params = camera_from_params("perspective", &set).unwrap();
        let expected = PerspectiveDesc {
            position: Vec3::new(1.0, 2.0, 3.0),
            direction: Vec3::Z,
            up: Vec3::new(0.0, 1.0, 0.2),
            fovy: 0.7,
            aspect: Some(1.25),
            image_region: [0.1, 0.2, 0.9, 0.8],
            near: Some(0.1),
            far: Some(100.0),
            stereo_mode: StereoMode::TopBottom,
            interpupillary_distance: 0.07,
            aperture_radius: 0.02,
            focus_distance: 3.0,
        }
        .build()
        .unwrap();
        same_rays(&*from_params, &*expected);
        // And not the default camera.
        let default = PerspectiveDesc::default().build().unwrap();
        let ray = |c: &dyn Camera| c.prepare(Eye::Left, 4, 4).ray(0.5, 0.5, Vec2::ZERO);
        assert_ne!(ray(&*from_params).origin, ray(&*default).origin);
    }

    #[test]
    fn empty_parameter_sets_give_the_default_cameras() {
        let empty = ParamSet::default();
        let defaults = [
            ("perspective", PerspectiveDesc::default().build()),
            ("orthographic", OrthographicDesc::default().build()),
            ("matrix", MatrixDesc::default().build()),
            ("omnidirectional", OmnidirectionalDesc::default().build()),
            ("fisheye", FisheyeDesc::default().build()),
        ];
        for (subtype, default) in defaults {
            same_rays(
                &*camera_from_params(subtype, &empty).unwrap(),
                &*default.unwrap(),
            );
        }
        let error = camera_from_params("offAxis", &empty).unwrap_err();
        assert_eq!(error.parameter, "screen.lowerLeft");
    }

    #[test]
    fn orthographic_matrix_and_off_axis_parameters_reach_the_camera() {
        let mut set = ParamSet::default();
        floats(&mut set, "position", ANARI_FLOAT32_VEC3, &[0.0, 5.0, 0.0]);
        floats(&mut set, "direction", ANARI_FLOAT32_VEC3, &[0.0, -1.0, 0.0]);
        floats(&mut set, "up", ANARI_FLOAT32_VEC3, &[0.0, 0.0, -1.0]);
        floats(&mut set, "height", ANARI_FLOAT32, &[4.0]);
        floats(&mut set, "near", ANARI_FLOAT32, &[1.0]);
        let ortho = camera_from_params("orthographic", &set).unwrap();
        let ray = ortho.prepare(Eye::Mono, 2, 1).ray(1.0, 1.0, Vec2::ZERO);
        assert_eq!(ray.origin, Vec3::new(4.0, 5.0, -2.0));
        assert_eq!(ray.direction, Vec3::NEG_Y);
        assert_eq!(ray.t_min, 1.0);

        let view =
            glam::camera::rh::view::look_at_mat4(Vec3::new(0.0, 1.0, 2.0), Vec3::ZERO, Vec3::Y);
        let proj = glam::camera::rh::proj::opengl::perspective(1.0, 1.5, 0.1, 10.0);
        let mut set = ParamSet::default();
        floats(&mut set, "view", ANARI_FLOAT32_MAT4, &view.to_cols_array());
        floats(&mut set, "proj", ANARI_FLOAT32_MAT4, &proj.to_cols_array());
        let matrix = camera_from_params("matrix", &set).unwrap();
        same_rays(
            &*matrix,
            &*MatrixDesc {
                view,
                proj,
                ..MatrixDesc::default()
            }
            .build()
            .unwrap(),
        );

        let mut set = ParamSet::default();
        floats(
            &mut set,
            "screen.lowerLeft",
            ANARI_FLOAT32_VEC3,
            &[-1.5, 0.0, -1.5],
        );
        floats(
            &mut set,
            "screen.lowerRight",
            ANARI_FLOAT32_VEC3,
            &[1.5, 0.0, -1.5],
        );
        floats(
            &mut set,
            "screen.upperRight",
            ANARI_FLOAT32_VEC3,
            &[1.5, 3.0, -1.5],
        );
        floats(&mut set, "position", ANARI_FLOAT32_VEC3, &[0.2, 1.7, 0.5]);
        floats(&mut set, "right", ANARI_FLOAT32_VEC3, &[1.0, 0.1, 0.0]);
        floats(&mut set, "near", ANARI_FLOAT32, &[0.05]);
        set.set("stereoMode", ParamValue::String("sideBySide".into()));
        let offaxis = camera_from_params("offAxis", &set).unwrap();
        same_rays(
            &*offaxis,
            &*OffAxisDesc {
                lower_left: Some(Vec3::new(-1.5, 0.0, -1.5)),
                lower_right: Some(Vec3::new(1.5, 0.0, -1.5)),
                upper_right: Some(Vec3::new(1.5, 3.0, -1.5)),
                position: Vec3::new(0.2, 1.7, 0.5),
                right: Some(Vec3::new(1.0, 0.1, 0.0)),
                near: Some(0.05),
                stereo_mode: StereoMode::SideBySide,
                ..OffAxisDesc::default()
            }
            .build()
            .unwrap(),
        );
        assert_eq!(
            offaxis.viewports(10, 4)[1],
            EyeViewport {
                eye: Eye::Right,
                x: 5,
                y: 0,
                width: 5,
                height: 4,
                pixels: crate::camera::PixelSet::All,
            }
        );
    }

    #[test]
    fn omnidirectional_and_fisheye_parameters_reach_the_camera() {
        let mut set = ParamSet::default();
        floats(&mut set, "position", ANARI_FLOAT32_VEC3, &[1.0, 2.0, 3.0]);
        floats(&mut set, "direction", ANARI_FLOAT32_VEC3, &[1.0, 0.0, 0.0]);
        floats(&mut set, "up", ANARI_FLOAT32_VEC3, &[0.0, 0.0, 1.0]);
        floats(
            &mut set,
            "imageRegion",
            ANARI_FLOAT32_BOX2,
            &[0.1, 0.2, 0.9, 0.8],
        );
        floats(&mut set, "interpupillaryDistance", ANARI_FLOAT32, &[0.07]);
        set.set("layout", ParamValue::String("equirectangular".into()));
        set.set("stereoMode", ParamValue::String("topBottom".into()));
        same_rays(
            &*camera_from_params("omnidirectional", &set).unwrap(),
            &*OmnidirectionalDesc {
                position: Vec3::new(1.0, 2.0, 3.0),
                direction: Vec3::X,
                up: Vec3::Z,
                image_region: [0.1, 0.2, 0.9, 0.8],
                stereo_mode: StereoMode::TopBottom,
                interpupillary_distance: 0.07,
                ..OmnidirectionalDesc::default()
            }
            .build()
            .unwrap(),
        );

        let mut set = ParamSet::default();
        floats(&mut set, "position", ANARI_FLOAT32_VEC3, &[0.5, 1.0, 0.2]);
        floats(
            &mut set,
            "dome.center",
            ANARI_FLOAT32_VEC3,
            &[0.0, 0.5, 0.0],
        );
        floats(&mut set, "dome.radius", ANARI_FLOAT32, &[4.0]);
        floats(
            &mut set,
            "dome.direction",
            ANARI_FLOAT32_VEC3,
            &[0.0, 1.0, 0.1],
        );
        floats(&mut set, "dome.up", ANARI_FLOAT32_VEC3, &[0.0, 0.0, -1.0]);
        floats(&mut set, "dome.tilt", ANARI_FLOAT32, &[0.3]);
        floats(&mut set, "fov", ANARI_FLOAT32, &[4.0]);
        floats(&mut set, "right", ANARI_FLOAT32_VEC3, &[1.0, 0.0, 0.5]);
        floats(
            &mut set,
            "imageRegion",
            ANARI_FLOAT32_BOX2,
            &[0.0, 0.5, 0.5, 1.0],
        );
        floats(&mut set, "interpupillaryDistance", ANARI_FLOAT32, &[0.05]);
        set.set("stereoMode", ParamValue::String("sideBySide".into()));
        let fisheye = camera_from_params("fisheye", &set).unwrap();
        same_rays(
            &*fisheye,
            &*FisheyeDesc {
                position: Vec3::new(0.5, 1.0, 0.2),
                dome_center: Vec3::new(0.0, 0.5, 0.0),
                dome_radius: Some(4.0),
                dome_direction: Vec3::new(0.0, 1.0, 0.1),
                dome_up: Vec3::NEG_Z,
                dome_tilt: 0.3,
                fov: 4.0,
                right: Some(Vec3::new(1.0, 0.0, 0.5)),
                image_region: [0.0, 0.5, 0.5, 1.0],
                stereo_mode: StereoMode::SideBySide,
                interpupillary_distance: 0.05,
            }
            .build()
            .unwrap(),
        );
        // And the parameters changed something.
        let ray = |c: &dyn Camera| c.prepare(Eye::Left, 4, 4).ray(0.4, 0.6, Vec2::ZERO);
        let default = FisheyeDesc::default().build().unwrap();
        assert_ne!(ray(&*fisheye).origin, ray(&*default).origin);
        assert_ne!(ray(&*fisheye).direction, ray(&*default).direction);
    }

    #[test]
    fn bad_values_are_reported_with_their_parameter() {
        let mut set = ParamSet::default();
        set.set("stereoMode", ParamValue::String("hologram".into()));
        assert_eq!(
            camera_from_params("perspective", &set)
                .unwrap_err()
                .parameter,
            "stereoMode"
        );
        let mut set = ParamSet::default();
        floats(&mut set, "fovy", ANARI_FLOAT32, &[4.0]);
        assert_eq!(
            camera_from_params("perspective", &set)
                .unwrap_err()
                .parameter,
            "fovy"
        );
        let mut set = ParamSet::default();
        floats(&mut set, "proj", ANARI_FLOAT32_MAT4, &[0.0; 16]);
        assert_eq!(
            camera_from_params("matrix", &set).unwrap_err().parameter,
            "proj"
        );
        let error = camera_from_params("cylindrical", &ParamSet::default()).unwrap_err();
        assert_eq!(error.parameter, "subtype");
        let mut set = ParamSet::default();
        set.set("layout", ParamValue::String("cubemap".into()));
        assert_eq!(
            camera_from_params("omnidirectional", &set)
                .unwrap_err()
                .parameter,
            "layout"
        );
        let mut set = ParamSet::default();
        floats(&mut set, "dome.radius", ANARI_FLOAT32, &[-2.0]);
        assert_eq!(
            camera_from_params("fisheye", &set).unwrap_err().parameter,
            "dome.radius"
        );
    }

    #[test]
    fn specs_declare_every_parameter_read_with_the_descriptions_defaults() {
        let spec = |subtype: &str| SPECS.iter().find(|s| s.subtype == subtype).unwrap();
        let read = [
            (
                "perspective",
                &[
                    "position",
                    "direction",
                    "up",
                    "fovy",
                    "aspect",
                    "imageRegion",
                    "near",
                    "far",
                    "stereoMode",
                    "interleaveStartRight",
                    "interpupillaryDistance",
                    "apertureRadius",
                    "focusDistance",
                ][..],
            ),
            (
                "orthographic",
                &[
                    "position",
                    "direction",
                    "up",
                    "height",
                    "aspect",
                    "imageRegion",
                    "near",
                    "far",
                ][..],
            ),
            ("matrix", &["view", "proj", "imageRegion"][..]),
            (
                "omnidirectional",
                &[
                    "position",
                    "direction",
                    "up",
                    "imageRegion",
                    "layout",
                    "stereoMode",
                    "interleaveStartRight",
                    "interpupillaryDistance",
                ][..],
            ),
            (
                "fisheye",
                &[
                    "position",
                    "dome.center",
                    "dome.radius",
                    "dome.direction",
                    "dome.up",
                    "dome.tilt",
                    "fov",
                    "right",
                    "imageRegion",
                    "stereoMode",
                    "interleaveStartRight",
                    "interpupillaryDistance",
                ][..],
            ),
            (
                "offAxis",
                &[
                    "screen.lowerLeft",
                    "screen.lowerRight",
                    "screen.upperRight",
                    "position",
                    "right",
                    "stereoMode",
                    "interleaveStartRight",
                    "interpupillaryDistance",
                    "near",
                    "far",
                    "imageRegion",
                    "viewer.position",
                    "viewer.direction",
                    "viewer.right",
                    "viewerMode",
                    "viewerWeighting",
                    "viewerCutoffAngle",
                    "viewerTiles",
                ][..],
            ),
        ];
        for (subtype, names) in read {
            let spec = spec(subtype);
            assert_eq!(spec.kind, ANARI_CAMERA);
            assert_eq!(spec.params.len(), names.len(), "{subtype}");
            for name in names {
                assert!(spec.param(name).is_some(), "{subtype} lacks {name}");
            }
        }
        let perspective = PerspectiveDesc::default();
        assert_eq!(
            spec("perspective").param("fovy").unwrap().default,
            SpecValue::Float(perspective.fovy)
        );
        assert_eq!(
            spec("perspective").param("focusDistance").unwrap().default,
            SpecValue::Float(perspective.focus_distance)
        );
        assert_eq!(
            spec("offAxis")
                .param("interpupillaryDistance")
                .unwrap()
                .default,
            SpecValue::Float(OffAxisDesc::default().interpupillary_distance)
        );
        assert_eq!(IDENTITY, Mat4::IDENTITY.to_cols_array());
        assert_eq!(
            spec("matrix").param("view").unwrap().default,
            SpecValue::Floats(&IDENTITY)
        );
        assert!(spec("offAxis").param("screen.lowerLeft").unwrap().required);
        assert_eq!(spec("matrix").extensions, &["ANARI_VSNRAY_CAMERA_MATRIX"]);
        let omni = OmnidirectionalDesc::default();
        assert_eq!(
            spec("omnidirectional").param("direction").unwrap().default,
            SpecValue::Floats(&[0.0, 0.0, -1.0])
        );
        assert_eq!(omni.direction, Vec3::NEG_Z);
        let fisheye = FisheyeDesc::default();
        assert_eq!(
            spec("fisheye").param("fov").unwrap().default,
            SpecValue::Float(fisheye.fov)
        );
        assert_eq!(
            spec("fisheye").param("dome.direction").unwrap().default,
            SpecValue::Floats(&[0.0, 1.0, 0.0])
        );
        assert_eq!(fisheye.dome_direction, Vec3::Y);
        assert_eq!(
            spec("fisheye").param("dome.up").unwrap().default,
            SpecValue::Floats(&[0.0, 0.0, 1.0])
        );
        assert_eq!(fisheye.dome_up, Vec3::Z);
        assert!(
            spec("offAxis")
                .extensions
                .contains(&"ANARI_CAVETRACE_CAMERA_OFF_AXIS")
        );
    }
}
