//! Cameras through the device: the three ways of getting primary rays render the same image,
//! stereo halves equal separately rendered eyes, imageRegion crops, window depth matches OpenGL,
//! and invalid cameras are reported at commit.
mod common;
use cavetrace::capi::offaxis::*;
use common::*;

const SIZE: [u32; 2] = [48, 36];

/// The front wall of a 3 m CAVE (floor at y = 0), and a tracked eye off-centre.
const LL: [f32; 3] = [-1.5, 0.0, -1.5];
const LR: [f32; 3] = [1.5, 0.0, -1.5];
const UR: [f32; 3] = [1.5, 3.0, -1.5];
const EYE: [f32; 3] = [0.45, 1.62, 0.3];

/// Triangles at several depths, in front of and behind the wall, with distinct colours.
fn scene(dev: ANARIDevice) -> ANARIWorld {
    let mut positions = Vec::new();
    let mut colors = Vec::new();
    for k in 0..12 {
        let x = -1.2 + 0.22 * k as f32;
        let y = 0.4 + 0.19 * k as f32;
        let z = -0.6 - 0.35 * k as f32;
        positions.extend([[x, y, z], [x + 0.6, y, z], [x + 0.2, y + 0.7, z - 0.1]]);
        let c = [
            (k % 3) as f32 * 0.4 + 0.1,
            (k % 5) as f32 * 0.2,
            0.9 - 0.05 * k as f32,
            1.0,
        ];
        colors.extend([c, c, c]);
    }
    let geometry = anariNewGeometry(dev, c("triangle").as_ptr());
    let p = array1d(dev, ANARI_FLOAT32_VEC3, &positions);
    let col = array1d(dev, ANARI_FLOAT32_VEC4, &colors);
    set_object(dev, geometry, "vertex.position", ANARI_ARRAY1D, p);
    set_object(dev, geometry, "vertex.color", ANARI_ARRAY1D, col);
    commit(dev, geometry);
    let material = matte_colored_by(dev, "color");
    let surface = surface_of(dev, geometry, material);
    let world = world_of(dev, &[surface]);
    release_all(dev, &[geometry, p, col, material, surface]);
    world
}

struct Rendered {
    ids: Vec<u32>,
    color: Vec<[f32; 4]>,
}

fn render(dev: ANARIDevice, world: ANARIWorld, camera: ANARICamera, size: [u32; 2]) -> Rendered {
    let renderer = plain_renderer(dev, "fast");
    let frame = frame_for(dev, world, camera, renderer, size);
    add_channel(dev, frame, "channel.windowDepth", ANARI_FLOAT32);
    let (ids, w, h) = render_channel::<u32>(dev, frame, "channel.primitiveId");
    assert_eq!([w, h], size);
    let (color, _, _) = read_channel::<[f32; 4]>(dev, frame, "channel.color");
    anariRelease(dev, frame);
    anariRelease(dev, renderer);
    Rendered { ids, color }
}

fn matrices(near: f32, far: f32) -> ([f32; 16], [f32; 16]) {
    let (mut view, mut proj) = ([0f32; 16], [0f32; 16]);
    let status = cavetraceOffAxisMatrices(
        LL.as_ptr(),
        LR.as_ptr(),
        UR.as_ptr(),
        EYE.as_ptr(),
        near,
        far,
        view.as_mut_ptr(),
        proj.as_mut_ptr(),
    );
    assert_eq!(status, ANARI_STATUS_NO_ERROR);
    (view, proj)
}

fn matrix_camera(dev: ANARIDevice, view: &[f32; 16], proj: &[f32; 16]) -> ANARICamera {
    // Listing 5 of the off-axis paper.
    let camera = anariNewCamera(dev, c("matrix").as_ptr());
    set(dev, camera, "view", ANARI_FLOAT32_MAT4, view);
    set(dev, camera, "proj", ANARI_FLOAT32_MAT4, proj);
    commit(dev, camera);
    camera
}

struct Fit {
    position: [f32; 3],
    direction: [f32; 3],
    up: [f32; 3],
    fovy: f32,
    aspect: f32,
    region: [f32; 4],
}

fn fitted_camera(dev: ANARIDevice, fit: &Fit) -> ANARICamera {
    let camera = anariNewCamera(dev, c("perspective").as_ptr());
    set(dev, camera, "position", ANARI_FLOAT32_VEC3, &fit.position);
    set(dev, camera, "direction", ANARI_FLOAT32_VEC3, &fit.direction);
    set(dev, camera, "up", ANARI_FLOAT32_VEC3, &fit.up);
    set(dev, camera, "fovy", ANARI_FLOAT32, &fit.fovy);
    set(dev, camera, "aspect", ANARI_FLOAT32, &fit.aspect);
    set(dev, camera, "imageRegion", ANARI_FLOAT32_BOX2, &fit.region);
    commit(dev, camera);
    camera
}

fn empty_fit() -> Fit {
    Fit {
        position: [0.0; 3],
        direction: [0.0; 3],
        up: [0.0; 3],
        fovy: 0.0,
        aspect: 0.0,
        region: [0.0; 4],
    }
}

fn off_axis_camera(dev: ANARIDevice, stereo: &str) -> ANARICamera {
    let camera = anariNewCamera(dev, c("offAxis").as_ptr());
    set(dev, camera, "screen.lowerLeft", ANARI_FLOAT32_VEC3, &LL);
    set(dev, camera, "screen.lowerRight", ANARI_FLOAT32_VEC3, &LR);
    set(dev, camera, "screen.upperRight", ANARI_FLOAT32_VEC3, &UR);
    set(dev, camera, "position", ANARI_FLOAT32_VEC3, &EYE);
    set_string(dev, camera, "stereoMode", stereo);
    commit(dev, camera);
    camera
}

fn assert_same_image(a: &Rendered, b: &Rendered, what: &str) {
    let differing = a.ids.iter().zip(&b.ids).filter(|(x, y)| x != y).count();
    assert_eq!(
        differing, 0,
        "{what}: {differing} pixels with different primitive ids"
    );
    for (i, (x, y)) in a.color.iter().zip(&b.color).enumerate() {
        for k in 0..4 {
            assert!(
                (x[k] - y[k]).abs() <= 1.0 / 255.0,
                "{what}: pixel {i} colour {x:?} vs {y:?}"
            );
        }
    }
}

#[test]
fn the_three_strategies_and_the_off_axis_camera_render_the_same_image() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = scene(dev);
    let (view, proj) = matrices(0.05, 100.0);

    let camera = matrix_camera(dev, &view, &proj);
    let by_matrix = render(dev, world, camera, SIZE);
    anariRelease(dev, camera);
    let hits = by_matrix.ids.iter().filter(|i| **i != u32::MAX).count();
    assert!(
        hits > 100 && hits < (SIZE[0] * SIZE[1]) as usize,
        "the scene must be partly visible: {hits}"
    );

    let mut fit = empty_fit();
    assert_eq!(
        cavetraceOffAxisPerspective(
            LL.as_ptr(),
            LR.as_ptr(),
            UR.as_ptr(),
            EYE.as_ptr(),
            fit.position.as_mut_ptr(),
            fit.direction.as_mut_ptr(),
            fit.up.as_mut_ptr(),
            &mut fit.fovy,
            &mut fit.aspect,
            fit.region.as_mut_ptr(),
        ),
        ANARI_STATUS_NO_ERROR
    );
    let camera = fitted_camera(dev, &fit);
    let by_perspective = render(dev, world, camera, SIZE);
    anariRelease(dev, camera);

    let mut recovered = empty_fit();
    assert_eq!(
        cavetracePerspectiveFromMatrices(
            view.as_ptr(),
            proj.as_ptr(),
            recovered.position.as_mut_ptr(),
            recovered.direction.as_mut_ptr(),
            recovered.up.as_mut_ptr(),
            &mut recovered.fovy,
            &mut recovered.aspect,
            recovered.region.as_mut_ptr(),
        ),
        ANARI_STATUS_NO_ERROR
    );
    for (got, want) in recovered.position.iter().zip(EYE) {
        assert!((got - want).abs() < 1e-4, "{:?}", recovered.position);
    }
    let camera = fitted_camera(dev, &recovered);
    let by_recovery = render(dev, world, camera, SIZE);
    anariRelease(dev, camera);

    let camera = off_axis_camera(dev, "none");
    let by_off_axis = render(dev, world, camera, SIZE);
    anariRelease(dev, camera);

    assert_same_image(
        &by_matrix,
        &by_perspective,
        "matrix vs perspective+imageRegion",
    );
    assert_same_image(
        &by_matrix,
        &by_recovery,
        "matrix vs perspective from matrices",
    );
    assert_same_image(&by_matrix, &by_off_axis, "matrix vs offAxis");
    anariRelease(dev, world);
    release_device(lib, dev);
    let errors = log.errors();
    assert!(errors.is_empty(), "{errors:?}");
}

#[test]
fn window_depth_is_what_opengl_writes() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = scene(dev);
    let (near, far) = (0.1, 20.0);
    let (view, proj) = matrices(near, far);
    let camera = matrix_camera(dev, &view, &proj);
    let renderer = plain_renderer(dev, "fast");
    let frame = frame_for(dev, world, camera, renderer, SIZE);
    add_channel(dev, frame, "channel.windowDepth", ANARI_FLOAT32);
    let (depth, _, _) = render_channel::<f32>(dev, frame, "channel.depth");
    let (window, _, _) = read_channel::<f32>(dev, frame, "channel.windowDepth");
    let view_m = glam::Mat4::from_cols_array(&view);
    let proj_m = glam::Mat4::from_cols_array(&proj);
    let inverse = (proj_m * view_m).inverse();
    let eye = glam::Vec3::from(EYE);
    let mut checked = 0;
    for y in 0..SIZE[1] {
        for x in 0..SIZE[0] {
            let i = (y * SIZE[0] + x) as usize;
            if depth[i].is_infinite() {
                assert_eq!(window[i], 1.0);
                continue;
            }
            // Reconstruct the hit from the pixel's ray and the depth channel (distance from eye).
            let u = 2.0 * (x as f32 + 0.5) / SIZE[0] as f32 - 1.0;
            let v = 2.0 * (y as f32 + 0.5) / SIZE[1] as f32 - 1.0;
            let far_point = inverse.project_point3(glam::Vec3::new(u, v, 1.0));
            let hit = eye + (far_point - eye).normalize() * depth[i];
            let clip = proj_m * view_m * hit.extend(1.0);
            let gl = 0.5 * clip.z / clip.w + 0.5;
            assert!(
                (window[i] - gl).abs() < 2e-5,
                "pixel {x},{y}: {} vs {gl}",
                window[i]
            );
            checked += 1;
        }
    }
    assert!(checked > 100);
    release_all(dev, &[camera, renderer, frame, world]);
    release_device(lib, dev);
}

#[test]
fn side_by_side_equals_the_eyes_rendered_separately_and_regions_crop() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = scene(dev);
    let pair = {
        let camera = off_axis_camera(dev, "sideBySide");
        let r = render(dev, world, camera, [2 * SIZE[0], SIZE[1]]);
        anariRelease(dev, camera);
        r
    };
    for (eye, offset) in [("left", 0), ("right", SIZE[0])] {
        let camera = off_axis_camera(dev, eye);
        let single = render(dev, world, camera, SIZE);
        anariRelease(dev, camera);
        for y in 0..SIZE[1] {
            for x in 0..SIZE[0] {
                let a = single.ids[(y * SIZE[0] + x) as usize];
                let b = pair.ids[(y * 2 * SIZE[0] + x + offset) as usize];
                assert_eq!(a, b, "{eye} eye pixel {x},{y}");
            }
        }
    }
    // The two eyes differ (parallax), so the comparison above is not vacuous.
    let left: Vec<u32> = (0..SIZE[1])
        .flat_map(|y| (0..SIZE[0]).map(move |x| (y, x)))
        .map(|(y, x)| pair.ids[(y * 2 * SIZE[0] + x) as usize])
        .collect();
    let right: Vec<u32> = (0..SIZE[1])
        .flat_map(|y| (0..SIZE[0]).map(move |x| (y, x)))
        .map(|(y, x)| pair.ids[(y * 2 * SIZE[0] + x + SIZE[0]) as usize])
        .collect();
    assert_ne!(left, right);

    // imageRegion: the centre half of a 64×64 frame equals a 32×32 frame of that region.
    let camera = anariNewCamera(dev, c("perspective").as_ptr());
    set(dev, camera, "position", ANARI_FLOAT32_VEC3, &EYE);
    commit(dev, camera);
    let full = render(dev, world, camera, [64, 64]);
    set(
        dev,
        camera,
        "imageRegion",
        ANARI_FLOAT32_BOX2,
        &[0.25f32, 0.25, 0.75, 0.75],
    );
    set(dev, camera, "aspect", ANARI_FLOAT32, &1.0f32);
    commit(dev, camera);
    let crop = render(dev, world, camera, [32, 32]);
    for y in 0..32 {
        for x in 0..32 {
            assert_eq!(
                crop.ids[y * 32 + x],
                full.ids[(y + 16) * 64 + x + 16],
                "pixel {x},{y}"
            );
        }
    }
    anariRelease(dev, camera);
    anariRelease(dev, world);
    release_device(lib, dev);
    let errors = log.errors();
    assert!(errors.is_empty(), "{errors:?}");
}

#[test]
fn invalid_cameras_are_reported_at_commit_and_render_background() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = scene(dev);
    let singular = [0f32; 16];
    let (view, _) = matrices(0.1, 10.0);
    let camera = matrix_camera(dev, &view, &singular);
    let e = log.errors();
    assert_eq!(e.len(), 1, "{e:?}");
    assert!(
        e[0].1.contains("'proj'") && e[0].1.contains("camera 'matrix'"),
        "{}",
        e[0].1
    );
    let r = render(dev, world, camera, SIZE);
    assert!(r.ids.iter().all(|i| *i == u32::MAX));
    assert!(
        log.errors()
            .iter()
            .any(|(_, t)| t.contains("no valid committed 'camera'"))
    );
    anariRelease(dev, camera);

    // An eye behind the wall.
    let camera = anariNewCamera(dev, c("offAxis").as_ptr());
    set(dev, camera, "screen.lowerLeft", ANARI_FLOAT32_VEC3, &LL);
    set(dev, camera, "screen.lowerRight", ANARI_FLOAT32_VEC3, &LR);
    set(dev, camera, "screen.upperRight", ANARI_FLOAT32_VEC3, &UR);
    set(
        dev,
        camera,
        "position",
        ANARI_FLOAT32_VEC3,
        &[0.0f32, 1.5, -2.0],
    );
    commit(dev, camera);
    let e = log.errors();
    assert!(e.len() == 1 && e[0].1.contains("'position'"), "{e:?}");
    // Collinear corners.
    set(
        dev,
        camera,
        "screen.upperRight",
        ANARI_FLOAT32_VEC3,
        &[3.0f32, 0.0, -1.5],
    );
    set(dev, camera, "position", ANARI_FLOAT32_VEC3, &EYE);
    commit(dev, camera);
    let e = log.errors();
    assert!(e.len() == 1 && e[0].1.contains("screen."), "{e:?}");
    anariRelease(dev, camera);

    // The C helpers reject NULL and degenerate input.
    let (mut v, mut p) = ([0f32; 16], [0f32; 16]);
    assert_eq!(
        cavetraceOffAxisMatrices(
            std::ptr::null(),
            LR.as_ptr(),
            UR.as_ptr(),
            EYE.as_ptr(),
            0.1,
            10.0,
            v.as_mut_ptr(),
            p.as_mut_ptr()
        ),
        ANARI_STATUS_INVALID_ARGUMENT
    );
    assert_eq!(
        cavetraceOffAxisMatrices(
            LL.as_ptr(),
            LL.as_ptr(),
            UR.as_ptr(),
            EYE.as_ptr(),
            0.1,
            10.0,
            v.as_mut_ptr(),
            p.as_mut_ptr()
        ),
        ANARI_STATUS_INVALID_ARGUMENT
    );
    let mut fit = empty_fit();
    let ortho: [f32; 16] = [
        1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -0.2, 0.0, 0.0, 0.0, -1.0, 1.0,
    ];
    assert_eq!(
        cavetracePerspectiveFromMatrices(
            view.as_ptr(),
            ortho.as_ptr(),
            fit.position.as_mut_ptr(),
            fit.direction.as_mut_ptr(),
            fit.up.as_mut_ptr(),
            &mut fit.fovy,
            &mut fit.aspect,
            fit.region.as_mut_ptr()
        ),
        ANARI_STATUS_INVALID_ARGUMENT
    );
    anariRelease(dev, world);
    release_device(lib, dev);
}

#[test]
/// 8x8 pixel blocks that straddle the two eyes' viewports (frame sizes not multiples of 8).
fn stereo_blocks_straddling_two_eyes_render_each_eye_as_alone() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let world = scene(dev);
    let (w, h) = (45u32, 37u32);
    for (mode, size) in [("sideBySide", [2 * w, h]), ("topBottom", [w, 2 * h])] {
        let camera = off_axis_camera(dev, mode);
        let pair = render(dev, world, camera, size);
        anariRelease(dev, camera);
        for eye in ["left", "right"] {
            let camera = off_axis_camera(dev, eye);
            let single = render(dev, world, camera, [w, h]);
            anariRelease(dev, camera);
            let (ox, oy) = match (mode, eye) {
                ("sideBySide", "left") => (0, 0),
                ("sideBySide", _) => (w, 0),
                (_, "left") => (0, h),
                _ => (0, 0),
            };
            let mut nonbg = 0;
            for y in 0..h {
                for x in 0..w {
                    let a = single.ids[(y * w + x) as usize];
                    let i = ((y + oy) * size[0] + x + ox) as usize;
                    assert_eq!(a, pair.ids[i], "{mode} {eye} ids {x},{y}");
                    assert_eq!(
                        single.color[(y * w + x) as usize],
                        pair.color[i],
                        "{mode} {eye} colour {x},{y}"
                    );
                    nonbg += usize::from(a != u32::MAX);
                }
            }
            assert!(nonbg > 50, "{mode} {eye}: {nonbg}");
        }
    }
    anariRelease(dev, world);
    release_device(lib, dev);
    assert!(log.errors().is_empty(), "{:?}", log.errors());
}
