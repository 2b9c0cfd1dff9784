//! A scene shared by the tests of stereo frames and of the block pipeline.

use super::*;

pub fn geometry_with(
    dev: ANARIDevice,
    subtype: &str,
    build: impl FnOnce(ANARIGeometry),
) -> ANARIGeometry {
    let geometry = anariNewGeometry(dev, c(subtype).as_ptr());
    build(geometry);
    commit(dev, geometry);
    geometry
}

pub fn material(dev: ANARIDevice, color: [f32; 3], metallic: f32, roughness: f32) -> ANARIMaterial {
    let material = anariNewMaterial(dev, c("physicallyBased").as_ptr());
    set(dev, material, "baseColor", ANARI_FLOAT32_VEC3, &color);
    set(dev, material, "metallic", ANARI_FLOAT32, &metallic);
    set(dev, material, "roughness", ANARI_FLOAT32, &roughness);
    commit(dev, material);
    material
}

/// A surface with an id; the geometry and material stay the caller's.
pub fn surface(
    dev: ANARIDevice,
    geometry: ANARIGeometry,
    material: ANARIMaterial,
    id: u32,
) -> ANARISurface {
    let surface = surface_of(dev, geometry, material);
    set(dev, surface, "id", ANARI_UINT32, &id);
    commit(dev, surface);
    surface
}

/// Triangles, quads, spheres (one in front of the screen, one a mirror), a tube, an instance
/// and a volume, with a light, between 0.3 m in front of the screen and 1.5 m behind it.
pub fn mixed_world(dev: ANARIDevice) -> ANARIWorld {
    let matte = material(dev, [0.7, 0.6, 0.5], 0.0, 1.0);
    let mirror = material(dev, [0.9, 0.9, 0.9], 1.0, 0.0);
    let floor = triangle_geometry(
        dev,
        &[
            [-2.0, -0.5, 0.5],
            [2.0, -0.5, 0.5],
            [2.0, -0.5, -1.5],
            [-2.0, -0.5, 0.5],
            [2.0, -0.5, -1.5],
            [-2.0, -0.5, -1.5],
        ],
    );
    let quad = geometry_with(dev, "quad", |g| {
        let corners = [
            [-0.7f32, 0.0, -0.5],
            [-0.2, 0.0, -0.5],
            [-0.2, 0.5, -0.5],
            [-0.7, 0.5, -0.5],
        ];
        set_array(dev, g, "vertex.position", ANARI_FLOAT32_VEC3, &corners);
    });
    let spheres = sphere_geometry(
        dev,
        &[[0.3, 0.0, -0.6], [-0.3, -0.3, 0.3], [0.5, 0.3, -1.2]],
        0.2,
    );
    let mirror_ball = sphere_geometry(dev, &[[0.0, 0.1, -0.3]], 0.15);
    let tube = geometry_with(dev, "curve", |g| {
        let points = [[-0.6f32, -0.4, -0.2], [0.6, -0.3, -0.9], [0.6, 0.4, -0.9]];
        set_array(dev, g, "vertex.position", ANARI_FLOAT32_VEC3, &points);
        set(dev, g, "radius", ANARI_FLOAT32, &0.04f32);
    });
    let surfaces: Vec<ANARISurface> = [
        (floor, matte),
        (quad, matte),
        (spheres, matte),
        (mirror_ball, mirror),
        (tube, matte),
    ]
    .iter()
    .enumerate()
    .map(|(id, &(geometry, material))| surface(dev, geometry, material, id as u32 + 1))
    .collect();

    // An instanced triangle, moved up and back.
    let instanced = triangle_geometry(dev, &[[-0.2, 0.0, 0.0], [0.2, 0.0, 0.0], [0.0, 0.3, 0.0]]);
    let instanced_surface = surface(dev, instanced, matte, 9);
    let group = anariNewGroup(dev);
    let group_surfaces = object_array(dev, ANARI_SURFACE, &[instanced_surface]);
    set_object(dev, group, "surface", ANARI_ARRAY1D, group_surfaces);
    commit(dev, group);
    let instance = anariNewInstance(dev, c("transform").as_ptr());
    set_object(dev, instance, "group", ANARI_GROUP, group);
    set(dev, instance, "id", ANARI_UINT32, &7u32);
    let transform: [f32; 16] = [
        1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.3, 0.25, -0.3, 1.0,
    ];
    set(dev, instance, "transform", ANARI_FLOAT32_MAT4, &transform);
    commit(dev, instance);

    // A faint volume over the left part of the scene.
    let data = array3d(dev, ANARI_FLOAT32, &[1.0f32; 8], [2, 2, 2]);
    let field = anariNewSpatialField(dev, c("structuredRegular").as_ptr());
    set_object(dev, field, "data", ANARI_ARRAY3D, data);
    set(
        dev,
        field,
        "origin",
        ANARI_FLOAT32_VEC3,
        &[-0.8f32, -0.5, -1.0],
    );
    set(
        dev,
        field,
        "spacing",
        ANARI_FLOAT32_VEC3,
        &[0.5f32, 0.8, 0.8],
    );
    commit(dev, field);
    let volume = anariNewVolume(dev, c("transferFunction1D").as_ptr());
    set_object(dev, volume, "value", ANARI_SPATIAL_FIELD, field);
    set(
        dev,
        volume,
        "color",
        ANARI_FLOAT32_VEC3,
        &[0.2f32, 0.4, 1.0],
    );
    set(dev, volume, "opacity", ANARI_FLOAT32, &0.3f32);
    set(dev, volume, "unitDistance", ANARI_FLOAT32, &1.0f32);
    commit(dev, volume);

    let light = directional_light(dev, [-0.3, -1.0, -0.5]);

    let world = anariNewWorld(dev);
    for (name, kind, objects) in [
        ("surface", ANARI_SURFACE, surfaces.clone()),
        ("instance", ANARI_INSTANCE, vec![instance]),
        ("volume", ANARI_VOLUME, vec![volume]),
        ("light", ANARI_LIGHT, vec![light]),
    ] {
        let array = object_array(dev, kind, &objects);
        set_object(dev, world, name, ANARI_ARRAY1D, array);
        anariRelease(dev, array);
    }
    commit(dev, world);
    release_all(dev, &surfaces);
    release_all(
        dev,
        &[
            matte,
            mirror,
            floor,
            quad,
            spheres,
            mirror_ball,
            tube,
            instanced,
            instanced_surface,
        ],
    );
    release_all(
        dev,
        &[group, group_surfaces, instance, data, field, volume, light],
    );
    world
}
