//! End-to-end through the C API in-process: a triangle rendered and read back.
mod common;
use common::*;

#[test]
fn a_triangle_covers_the_centre_and_misses_the_corners() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let positions: [[f32; 3]; 3] = [[-1.0, -1.0, -3.0], [1.0, -1.0, -3.0], [0.0, 1.0, -3.0]];
    let geometry = anariNewGeometry(dev, c("triangle").as_ptr());
    let array = array1d(dev, ANARI_FLOAT32_VEC3, &positions);
    set_object(dev, geometry, "vertex.position", ANARI_ARRAY1D, array);
    commit(dev, geometry);
    let surface = matte_surface(dev, geometry, [1.0, 0.0, 0.0]);
    let world = world_of(dev, &[surface]);
    let camera = anariNewCamera(dev, c("perspective").as_ptr());
    commit(dev, camera);
    let renderer = anariNewRenderer(dev, c("fast").as_ptr());
    commit(dev, renderer);
    let frame = frame_for(dev, world, camera, renderer, [64, 48]);
    let (ids, w, h) = render_channel::<u32>(dev, frame, "channel.primitiveId");
    assert_eq!((w, h), (64, 48));
    assert_eq!(ids[(24 * 64 + 32) as usize], 0);
    assert_eq!(ids[0], u32::MAX);
    let (depth, _, _) = read_channel::<f32>(dev, frame, "channel.depth");
    assert!((depth[(24 * 64 + 32) as usize] - 3.0).abs() < 0.01);
    assert!(depth[0].is_infinite());
    let (color, _, _) = read_channel::<[f32; 4]>(dev, frame, "channel.color");
    let centre = color[(24 * 64 + 32) as usize];
    assert!(centre[0] > 0.5 && centre[1] == 0.0, "{centre:?}");
    for o in [array, geometry, surface, world, camera, renderer, frame] {
        anariRelease(dev, o);
    }
    anariRelease(dev, dev);
    anariUnloadLibrary(lib);
    let errors = log.errors();
    assert!(errors.is_empty(), "{errors:?}");
}
