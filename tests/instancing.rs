//! Moving instances and cameras must not rebuild any geometry BVH. In its own test binary so
//! that the process-wide build counter sees no other test's geometry.
mod common;
use common::*;

#[test]
fn instances_move_without_rebuilding_geometry_and_report_ids() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let g = triangle_geometry(dev, &[[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.0, 0.5, 0.0]]);
    let s = matte_surface(dev, g, [1.0, 1.0, 1.0]);
    set(dev, s, "id", ANARI_UINT32, &11u32);
    commit(dev, s);
    let group = anariNewGroup(dev);
    let surfaces = object_array(dev, ANARI_SURFACE, &[s]);
    set_object(dev, group, "surface", ANARI_ARRAY1D, surfaces);
    commit(dev, group);
    let instance = anariNewInstance(dev, c("transform").as_ptr());
    set_object(dev, instance, "group", ANARI_GROUP, group);
    set(dev, instance, "id", ANARI_UINT32, &42u32);
    let place = |x: f32| -> [f32; 16] {
        [
            1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, x, 0.0, -3.0, 1.0,
        ]
    };
    set(dev, instance, "transform", ANARI_FLOAT32_MAT4, &place(0.0));
    commit(dev, instance);
    let world = anariNewWorld(dev);
    let instances = object_array(dev, ANARI_INSTANCE, &[instance]);
    set_object(dev, world, "instance", ANARI_ARRAY1D, instances);
    commit(dev, world);
    let camera = perspective_camera(dev, [0.0; 3], [0.0, 0.0, -1.0], 1.0);
    let r = plain_renderer(dev, "fast");
    let frame = frame_for(dev, world, camera, r, [32, 32]);
    let builds = cavetrace::accel::geometry_build_count();
    let (ids, _, _) = render_channel::<u32>(dev, frame, "channel.instanceId");
    let (objects, _, _) = read_channel::<u32>(dev, frame, "channel.objectId");
    let (depth, _, _) = read_channel::<f32>(dev, frame, "channel.depth");
    let centre = 16 * 32 + 16;
    assert_eq!((ids[centre], objects[centre]), (42, 11));
    assert!((depth[centre] - 3.0).abs() < 0.01);
    assert_eq!(ids[0], u32::MAX);
    // Move the instance away from the centre, and move the camera: no geometry BVH is rebuilt.
    set(dev, instance, "transform", ANARI_FLOAT32_MAT4, &place(5.0));
    commit(dev, instance);
    set(
        dev,
        camera,
        "position",
        ANARI_FLOAT32_VEC3,
        &[0.1f32, 0.0, 0.0],
    );
    commit(dev, camera);
    let (ids, _, _) = render_channel::<u32>(dev, frame, "channel.instanceId");
    assert_eq!(ids[centre], u32::MAX);
    assert_eq!(
        cavetrace::accel::geometry_build_count(),
        builds,
        "moving things must not rebuild BVHs"
    );
    // World bounds follow the instance.
    let bounds = bounds_of(dev, world);
    assert_eq!(bounds, [4.5, -0.5, -3.0, 5.5, 0.5, -3.0]);
    release_all(
        dev,
        &[
            g, s, group, surfaces, instance, world, instances, camera, r, frame,
        ],
    );
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}
