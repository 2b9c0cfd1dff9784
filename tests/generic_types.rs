//! What applications written for other devices send: the generic handle types `ANARI_ARRAY` and
//! `ANARI_OBJECT` where a parameter takes an array or an object, and object arrays whose
//! elements are `ANARI_OBJECT`. Each is checked by what the handle really is.

mod common;
use common::*;

const SIZE: u32 = 16;

/// A triangle over the middle of the view, its surface with an id, and a directional light.
struct Scene {
    geometry: ANARIGeometry,
    material: ANARIMaterial,
    surface: ANARISurface,
    light: ANARILight,
}

impl Scene {
    fn new(dev: ANARIDevice) -> Scene {
        let geometry =
            triangle_geometry(dev, &[[-2.0, -2.0, 0.0], [2.0, -2.0, 0.0], [0.0, 2.0, 0.0]]);
        let material = anariNewMaterial(dev, c("matte").as_ptr());
        commit(dev, material);
        let surface = surface_of(dev, geometry, material);
        set(dev, surface, "id", ANARI_UINT32, &5u32);
        commit(dev, surface);
        let light = directional_light(dev, [0.0, 0.0, -1.0]);
        Scene {
            geometry,
            material,
            surface,
            light,
        }
    }

    fn release(&self, dev: ANARIDevice) {
        release_all(
            dev,
            &[self.geometry, self.material, self.surface, self.light],
        );
    }
}

/// The centre pixel's (objectId, red) of `world` under the default renderer (no ambient light,
/// so red is 0 without the light).
fn centre(dev: ANARIDevice, world: ANARIWorld) -> (u32, f32) {
    commit(dev, world);
    let camera = orthographic_camera(dev, [0.0, 0.0, 5.0], 4.0);
    let renderer = plain_renderer(dev, "default");
    let frame = frame_for(dev, world, camera, renderer, [SIZE, SIZE]);
    let (colors, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    let (ids, _, _) = read_channel::<u32>(dev, frame, "channel.objectId");
    release_all(dev, &[camera, renderer, frame]);
    let i = (SIZE / 2 * SIZE + SIZE / 2) as usize;
    (ids[i], colors[i][0])
}

fn set_declared(
    dev: ANARIDevice,
    object: ANARIObject,
    name: &str,
    declared: ANARIDataType,
    value: ANARIObject,
) {
    set_object(dev, object, name, declared, value);
}

/// The error messages reported since the last call (reading the log drains it).
fn new_errors(log: &Log) -> Vec<String> {
    log.errors().into_iter().map(|e| e.1).collect()
}

#[test]
fn world_arrays_given_as_anari_array_and_with_anari_object_elements_render() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let scene = Scene::new(dev);
    for (declared, element) in [
        (ANARI_ARRAY1D, ANARI_SURFACE),
        (ANARI_ARRAY, ANARI_SURFACE),
        (ANARI_ARRAY1D, ANARI_OBJECT),
        (ANARI_ARRAY, ANARI_OBJECT),
        (ANARI_OBJECT, ANARI_OBJECT),
    ] {
        let what = format!("declared {declared}, elements {element}");
        new_errors(&log);
        let world = anariNewWorld(dev);
        let surfaces = object_array(dev, element, &[scene.surface]);
        let lights = object_array(
            dev,
            if element == ANARI_OBJECT {
                ANARI_OBJECT
            } else {
                ANARI_LIGHT
            },
            &[scene.light],
        );
        set_declared(dev, world, "surface", declared, surfaces);
        set_declared(dev, world, "light", declared, lights);
        let (id, red) = centre(dev, world);
        assert_eq!(id, 5, "{what}");
        assert!(red > 0.1, "{what}: lit {red}");
        let errors = new_errors(&log);
        assert!(errors.is_empty(), "{what}: {errors:?}");
        release_all(dev, &[world, surfaces, lights]);
    }
    scene.release(dev);
    release_device(lib, dev);
}

#[test]
fn generic_elements_of_the_wrong_kind_are_reported_by_index_and_the_rest_render() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let scene = Scene::new(dev);
    let world = anariNewWorld(dev);
    // A light among the surfaces, a surface among the lights.
    let surfaces = object_array(dev, ANARI_OBJECT, &[scene.light, scene.surface]);
    let lights = object_array(dev, ANARI_OBJECT, &[scene.surface, scene.light]);
    set_object(dev, world, "surface", ANARI_ARRAY1D, surfaces);
    set_object(dev, world, "light", ANARI_ARRAY1D, lights);
    let errors = new_errors(&log);
    assert_eq!(errors.len(), 2, "{errors:?}");
    assert!(
        errors[0].contains("'surface'")
            && errors[0].contains("element 0")
            && errors[0].contains("ANARI_LIGHT"),
        "{errors:?}"
    );
    assert!(
        errors[1].contains("'light'")
            && errors[1].contains("element 0")
            && errors[1].contains("ANARI_SURFACE"),
        "{errors:?}"
    );
    let (id, red) = centre(dev, world);
    assert_eq!(id, 5);
    assert!(red > 0.1, "lit {red}");
    release_all(dev, &[world, surfaces, lights]);
    scene.release(dev);
    release_device(lib, dev);
}

#[test]
fn generic_handles_are_checked_by_what_they_really_are() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let scene = Scene::new(dev);

    // A geometry's vertex array and a surface's geometry and material given as ANARI_OBJECT,
    // a group's surfaces and an instance's group too.
    let positions = array1d(
        dev,
        ANARI_FLOAT32_VEC3,
        &[[-2.0f32, -2.0, 0.0], [2.0, -2.0, 0.0], [0.0, 2.0, 0.0]],
    );
    let geometry = anariNewGeometry(dev, c("triangle").as_ptr());
    set_declared(dev, geometry, "vertex.position", ANARI_OBJECT, positions);
    commit(dev, geometry);
    let surface = anariNewSurface(dev);
    set_declared(dev, surface, "geometry", ANARI_OBJECT, geometry);
    set_declared(dev, surface, "material", ANARI_OBJECT, scene.material);
    set(dev, surface, "id", ANARI_UINT32, &8u32);
    commit(dev, surface);
    let group = anariNewGroup(dev);
    let group_surfaces = object_array(dev, ANARI_OBJECT, &[surface]);
    set_declared(dev, group, "surface", ANARI_ARRAY, group_surfaces);
    commit(dev, group);
    let instance = anariNewInstance(dev, c("transform").as_ptr());
    set_declared(dev, instance, "group", ANARI_OBJECT, group);
    commit(dev, instance);
    let world = anariNewWorld(dev);
    let instances = object_array(dev, ANARI_OBJECT, &[instance]);
    set_declared(dev, world, "instance", ANARI_OBJECT, instances);
    let lights = object_array(dev, ANARI_OBJECT, &[scene.light]);
    set_declared(dev, world, "light", ANARI_ARRAY, lights);
    let errors = new_errors(&log);
    assert!(errors.is_empty(), "{errors:?}");
    let (id, red) = centre(dev, world);
    assert_eq!(id, 8);
    assert!(red > 0.1, "lit {red}");

    // Wrong real kinds are still reported and ignored.
    let image = array2d(dev, ANARI_FLOAT32_VEC3, &[[0.0f32; 3]; 4], [2, 2]);
    for (object, name, declared, value, real) in [
        (
            geometry,
            "vertex.position",
            ANARI_ARRAY,
            image,
            "ANARI_ARRAY2D",
        ),
        (
            geometry,
            "vertex.position",
            ANARI_OBJECT,
            scene.light,
            "ANARI_LIGHT",
        ),
        (
            surface,
            "material",
            ANARI_OBJECT,
            geometry,
            "ANARI_GEOMETRY",
        ),
        (world, "surface", ANARI_ARRAY, image, "ANARI_ARRAY2D"),
    ] {
        new_errors(&log);
        set_declared(dev, object, name, declared, value);
        let errors = new_errors(&log);
        assert_eq!(errors.len(), 1, "{name}: {errors:?}");
        assert!(
            errors[0].contains(&format!("'{name}'")) && errors[0].contains(real),
            "{errors:?}"
        );
    }
    // Nothing was replaced: the world still renders as before.
    commit(dev, geometry);
    commit(dev, surface);
    let (id, _) = centre(dev, world);
    assert_eq!(id, 8);

    // A parameter array mapped with ANARI_OBJECT elements.
    let world2 = anariNewWorld(dev);
    let mut stride = 0u64;
    let name = c("surface");
    let elements =
        anariMapParameterArray1D(dev, world2, name.as_ptr(), ANARI_OBJECT, 2, &mut stride)
            as *mut ANARIObject;
    assert!(!elements.is_null());
    assert_eq!(stride, std::mem::size_of::<ANARIObject>() as u64);
    // SAFETY: the device mapped two ANARIObject elements for us.
    unsafe {
        *elements = scene.surface;
        *elements.add(1) = scene.light;
    }
    new_errors(&log);
    anariUnmapParameterArray(dev, world2, name.as_ptr());
    let errors = new_errors(&log);
    assert!(
        errors.len() == 1 && errors[0].contains("element 1"),
        "{errors:?}"
    );
    let (id, _) = centre(dev, world2);
    assert_eq!(id, 5);

    release_all(
        dev,
        &[
            positions,
            geometry,
            surface,
            group,
            group_surfaces,
            instance,
            world,
            instances,
            lights,
            image,
            world2,
        ],
    );
    scene.release(dev);
    release_device(lib, dev);
}
