//! Commit diagnostics: a render warns, once per object and change, about objects it uses whose
//! parameters were set or unset after their last commit, and about objects never committed.

mod common;

use common::*;

/// Warnings received so far (clearing the log); errors fail the test.
fn warnings(log: &Log) -> Vec<String> {
    let all = log.take();
    assert!(
        all.iter().all(|(s, _, _)| *s > ANARI_SEVERITY_ERROR),
        "{all:?}"
    );
    all.into_iter()
        .filter(|(s, code, _)| *s == ANARI_SEVERITY_WARNING && *code == ANARI_STATUS_NO_ERROR)
        .map(|(_, _, text)| text)
        .collect()
}

struct Scene {
    geometry: ANARIGeometry,
    surface: ANARISurface,
    world: ANARIWorld,
    frame: ANARIFrame,
}

/// A committed triangle in a committed world, seen by a committed frame (camera and renderer
/// committed too): a correct program.
fn scene(dev: ANARIDevice) -> Scene {
    let geometry = triangle_geometry(
        dev,
        &[[-1.0, -1.0, -2.0], [1.0, -1.0, -2.0], [0.0, 1.0, -2.0]],
    );
    let surface = matte_surface(dev, geometry, [1.0, 1.0, 1.0]);
    let world = world_of(dev, &[surface]);
    let camera = anariNewCamera(dev, c("perspective").as_ptr());
    commit(dev, camera);
    let renderer = lit_renderer(dev);
    let frame = frame_for(dev, world, camera, renderer, [8, 8]);
    release_all(dev, &[camera, renderer]);
    Scene {
        geometry,
        surface,
        world,
        frame,
    }
}

/// A committed default renderer with ambient light, so that an unlit world is not black.
fn lit_renderer(dev: ANARIDevice) -> ANARIRenderer {
    let renderer = anariNewRenderer(dev, c("default").as_ptr());
    set(dev, renderer, "ambientRadiance", ANARI_FLOAT32, &1.0f32);
    commit(dev, renderer);
    renderer
}

impl Scene {
    fn release(self, dev: ANARIDevice) {
        release_all(dev, &[self.geometry, self.surface, self.world, self.frame]);
    }
}

#[test]
fn a_light_set_after_the_world_commit_warns_once_until_committed() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let s = scene(dev);
    render_and_wait(dev, s.frame);
    assert_eq!(warnings(&log), Vec::<String>::new());

    // The third-party off-axis sample's mistake: the world's light set after its commit.
    let light = directional_light(dev, [0.0, 0.0, -1.0]);
    let lights = object_array(dev, ANARI_LIGHT, &[light]);
    set_object(dev, s.world, "light", ANARI_ARRAY1D, lights);
    render_and_wait(dev, s.frame);
    render_and_wait(dev, s.frame);
    let seen = warnings(&log);
    assert_eq!(
        seen,
        [
            "anariRenderFrame: world: 'light' set after the last commit; this render uses the \
          committed state (call anariCommitParameters on it)"
        ],
    );

    // A further change is a new warning, naming what differs from the committed state now.
    anariUnsetParameter(dev, s.world, c("surface").as_ptr());
    render_and_wait(dev, s.frame);
    let seen = warnings(&log);
    assert_eq!(seen.len(), 1, "{seen:?}");
    assert!(
        seen[0].contains("world: 'light' set and 'surface' unset after the last commit"),
        "{seen:?}"
    );

    // Committing silences it.
    let surfaces = object_array(dev, ANARI_SURFACE, &[s.surface]);
    set_object(dev, s.world, "surface", ANARI_ARRAY1D, surfaces);
    anariRelease(dev, surfaces);
    commit(dev, s.world);
    render_and_wait(dev, s.frame);
    render_and_wait(dev, s.frame);
    assert_eq!(warnings(&log), Vec::<String>::new());
    release_all(dev, &[light, lights]);
    s.release(dev);
    release_device(lib, dev);
}

#[test]
fn the_warning_names_the_object_and_its_handle() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let s = scene(dev);
    // Deeper in the scene: the surface's material, reached through world → surface.
    let material = anariNewMaterial(dev, c("matte").as_ptr());
    commit(dev, material);
    set_object(dev, s.surface, "material", ANARI_MATERIAL, material);
    commit(dev, s.surface);
    set(
        dev,
        material,
        "color",
        ANARI_FLOAT32_VEC3,
        &[0.0f32, 1.0, 0.0],
    );
    set(dev, s.frame, "size", ANARI_UINT32_VEC2, &[4u32, 4]);
    render_and_wait(dev, s.frame);
    let mut seen = warnings(&log);
    seen.sort();
    assert_eq!(
        seen,
        [
            "anariRenderFrame: frame: 'size' set after the last commit; this render uses the \
             committed state (call anariCommitParameters on it)",
            "anariRenderFrame: material 'matte': 'color' set after the last commit; this render \
             uses the committed state (call anariCommitParameters on it)",
        ]
    );
    release_all(dev, &[material]);
    s.release(dev);
    release_device(lib, dev);
}

#[test]
fn a_never_committed_geometry_warns_once() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let s = scene(dev);
    let uncommitted = anariNewGeometry(dev, c("sphere").as_ptr());
    set_array(
        dev,
        uncommitted,
        "vertex.position",
        ANARI_FLOAT32_VEC3,
        &[[0.0f32, 0.0, -3.0]],
    );
    let surface = matte_surface(dev, uncommitted, [1.0, 0.0, 0.0]);
    let surfaces = object_array(dev, ANARI_SURFACE, &[s.surface, surface]);
    set_object(dev, s.world, "surface", ANARI_ARRAY1D, surfaces);
    commit(dev, s.world);
    assert_eq!(warnings(&log), Vec::<String>::new());
    render_and_wait(dev, s.frame);
    render_and_wait(dev, s.frame);
    assert_eq!(
        warnings(&log),
        [
            "anariRenderFrame: geometry 'sphere' is used by this frame but was never committed; \
          this render ignores its parameters (call anariCommitParameters on it)"
        ]
    );
    commit(dev, uncommitted);
    render_and_wait(dev, s.frame);
    assert_eq!(warnings(&log), Vec::<String>::new());
    release_all(dev, &[uncommitted, surface, surfaces]);
    s.release(dev);
    release_device(lib, dev);
}

#[test]
fn setting_the_committed_value_again_is_not_a_change() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let s = scene(dev);
    // The frame's own parameters, set to what they already are (an application that sets
    // everything every frame but commits only what changed).
    set(dev, s.frame, "size", ANARI_UINT32_VEC2, &[8u32, 8]);
    set_object(dev, s.frame, "world", ANARI_WORLD, s.world);
    // Set, then unset again: nothing differs from the committed state.
    set(
        dev,
        s.geometry,
        "color",
        ANARI_FLOAT32_VEC4,
        &[1.0f32, 0.0, 0.0, 1.0],
    );
    anariUnsetParameter(dev, s.geometry, c("color").as_ptr());
    render_and_wait(dev, s.frame);
    assert_eq!(warnings(&log), Vec::<String>::new());
    s.release(dev);
    release_device(lib, dev);
}

const UNLIT: &str = "anariRenderFrame: frame: renderer 'default' has 'ambientRadiance' 0 and \
     the world has no lights, so its surfaces are unlit and render black (apart from emission \
     and reflections of the background); add a light to the world's 'light' array or set the \
     renderer's 'ambientRadiance' > 0";

#[test]
fn an_unlit_world_under_the_default_renderer_warns_once() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let s = scene(dev);
    let unlit = plain_renderer(dev, "default");
    set_object(dev, s.frame, "renderer", ANARI_RENDERER, unlit);
    commit(dev, s.frame);
    render_and_wait(dev, s.frame);
    render_and_wait(dev, s.frame);
    render_and_wait(dev, s.frame);
    assert_eq!(warnings(&log), [UNLIT]);
    // The image is black where the triangle is, as the warning says.
    let (color, _, _) = render_channel::<[f32; 4]>(dev, s.frame, "channel.color");
    assert_eq!(color[4 * 8 + 4], [0.0, 0.0, 0.0, 1.0]);
    assert_eq!(warnings(&log), Vec::<String>::new());

    // Ambient light fixes it: no warning.
    set(dev, unlit, "ambientRadiance", ANARI_FLOAT32, &0.5f32);
    commit(dev, unlit);
    render_and_wait(dev, s.frame);
    assert_eq!(warnings(&log), Vec::<String>::new());
    // A light in the world does too.
    set(dev, unlit, "ambientRadiance", ANARI_FLOAT32, &0.0f32);
    commit(dev, unlit);
    light_world(dev, s.world, [0.0, 0.0, -1.0]);
    render_and_wait(dev, s.frame);
    assert_eq!(warnings(&log), Vec::<String>::new());

    // The fast renderer lights what it sees from the eye: no warning either.
    let fast = plain_renderer(dev, "fast");
    let dark = world_of(dev, &[s.surface]);
    set_object(dev, s.frame, "renderer", ANARI_RENDERER, fast);
    set_object(dev, s.frame, "world", ANARI_WORLD, dark);
    commit(dev, s.frame);
    render_and_wait(dev, s.frame);
    assert_eq!(warnings(&log), Vec::<String>::new());
    release_all(dev, &[unlit, fast, dark]);
    s.release(dev);
    release_device(lib, dev);
}
