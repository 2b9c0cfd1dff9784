//! Volumes through the C API: structuredRegular fields seen through transferFunction1D volumes,
//! placed in worlds and instances, composited with surfaces and reported in the id channels.
//!
//! Every scene is seen by an orthographic camera at z = 5 looking down −z over the square
//! [−2, 2]² with 16 × 16 pixels: pixel (i, j) looks along x = −2 + (i + ½)/4, y = −2 + (j + ½)/4.
mod common;
use common::*;

const SIZE: u32 = 16;

fn pixel(i: u32, j: u32) -> usize {
    (j * SIZE + i) as usize
}

/// The x (or y) a pixel column (or row) looks along.
fn coordinate(i: u32) -> f32 {
    -2.0 + (i as f32 + 0.5) * 0.25
}

fn renderer(dev: ANARIDevice, subtype: &str, background: [f32; 4]) -> ANARIRenderer {
    let renderer = anariNewRenderer(dev, c(subtype).as_ptr());
    set(dev, renderer, "background", ANARI_FLOAT32_VEC4, &background);
    if subtype == "default" {
        set(dev, renderer, "ambientRadiance", ANARI_FLOAT32, &1.0f32);
        // Unoccluded ambient light: the emission–absorption model these scenes are checked
        // against.
        set(
            dev,
            renderer,
            "ambientOcclusionDistance",
            ANARI_FLOAT32,
            &0.0f32,
        );
    }
    commit(dev, renderer);
    renderer
}

/// A structuredRegular field of FLOAT32 values (x fastest).
fn field(
    dev: ANARIDevice,
    dims: [u64; 3],
    values: &[f32],
    origin: [f32; 3],
    spacing: [f32; 3],
    filter: Option<&str>,
) -> ANARISpatialField {
    let data = array3d(dev, ANARI_FLOAT32, values, dims);
    let field = anariNewSpatialField(dev, c("structuredRegular").as_ptr());
    set_object(dev, field, "data", ANARI_ARRAY3D, data);
    set(dev, field, "origin", ANARI_FLOAT32_VEC3, &origin);
    set(dev, field, "spacing", ANARI_FLOAT32_VEC3, &spacing);
    if let Some(filter) = filter {
        set_string(dev, field, "filter", filter);
    }
    commit(dev, field);
    anariRelease(dev, data);
    field
}

/// The box [−1, 1]³ filled with one value.
fn constant_field(dev: ANARIDevice, value: f32) -> ANARISpatialField {
    field(dev, [2, 2, 2], &[value; 8], [-1.0; 3], [2.0; 3], None)
}

/// A transferFunction1D volume over `field` with a uniform colour and opacity.
fn uniform_volume(
    dev: ANARIDevice,
    field: ANARISpatialField,
    color: [f32; 3],
    opacity: f32,
    unit_distance: f32,
    id: u32,
) -> ANARIVolume {
    let volume = anariNewVolume(dev, c("transferFunction1D").as_ptr());
    set_object(dev, volume, "value", ANARI_SPATIAL_FIELD, field);
    set(dev, volume, "color", ANARI_FLOAT32_VEC3, &color);
    set(dev, volume, "opacity", ANARI_FLOAT32, &opacity);
    set(dev, volume, "unitDistance", ANARI_FLOAT32, &unit_distance);
    set(dev, volume, "id", ANARI_UINT32, &id);
    commit(dev, volume);
    volume
}

fn world_with(dev: ANARIDevice, volumes: &[ANARIVolume], surfaces: &[ANARISurface]) -> ANARIWorld {
    let world = anariNewWorld(dev);
    if !volumes.is_empty() {
        let array = object_array(dev, ANARI_VOLUME, volumes);
        set_object(dev, world, "volume", ANARI_ARRAY1D, array);
        anariRelease(dev, array);
    }
    if !surfaces.is_empty() {
        let array = object_array(dev, ANARI_SURFACE, surfaces);
        set_object(dev, world, "surface", ANARI_ARRAY1D, array);
        anariRelease(dev, array);
    }
    commit(dev, world);
    world
}

/// An axis-aligned rectangle at depth z facing +z, as a matte triangle soup with an id.
fn rectangle(
    dev: ANARIDevice,
    x: [f32; 2],
    y: [f32; 2],
    z: f32,
    grey: f32,
    id: u32,
) -> ANARISurface {
    let [x0, x1] = x;
    let [y0, y1] = y;
    let positions = [
        [x0, y0, z],
        [x1, y0, z],
        [x1, y1, z],
        [x0, y0, z],
        [x1, y1, z],
        [x0, y1, z],
    ];
    let geometry = triangle_geometry(dev, &positions);
    let surface = matte_surface(dev, geometry, [grey; 3]);
    set(dev, surface, "id", ANARI_UINT32, &id);
    commit(dev, surface);
    anariRelease(dev, geometry);
    surface
}

struct Channels {
    color: Vec<[f32; 4]>,
    depth: Vec<f32>,
    primitive: Vec<u32>,
    object: Vec<u32>,
    instance: Vec<u32>,
}

fn render(dev: ANARIDevice, world: ANARIWorld, renderer: ANARIRenderer) -> Channels {
    let camera = orthographic_camera(dev, [0.0, 0.0, 5.0], 4.0);
    let frame = frame_for(dev, world, camera, renderer, [SIZE, SIZE]);
    let (color, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    let channels = Channels {
        color,
        depth: read_channel::<f32>(dev, frame, "channel.depth").0,
        primitive: read_channel::<u32>(dev, frame, "channel.primitiveId").0,
        object: read_channel::<u32>(dev, frame, "channel.objectId").0,
        instance: read_channel::<u32>(dev, frame, "channel.instanceId").0,
    };
    anariRelease(dev, frame);
    anariRelease(dev, camera);
    channels
}

#[test]
fn both_extensions_are_advertised_and_objects_are_real() {
    use cavetrace::device::catalog::Kinds;
    let extensions = cavetrace::kinds::KINDS.extensions();
    assert!(extensions.contains(&"ANARI_KHR_SPATIAL_FIELD_STRUCTURED_REGULAR"));
    assert!(extensions.contains(&"ANARI_KHR_VOLUME_TRANSFER_FUNCTION1D"));
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let field = constant_field(dev, 0.5);
    let volume = uniform_volume(dev, field, [1.0; 3], 0.5, 1.0, 0);
    // No "unknown subtype" warning, no error: both objects are implemented.
    let complaints: Vec<_> = log
        .take()
        .into_iter()
        .filter(|(severity, _, _)| *severity <= ANARI_SEVERITY_WARNING)
        .collect();
    assert!(complaints.is_empty(), "{complaints:?}");
    release_all(dev, &[volume, field]);
    release_device(lib, dev);
}

#[test]
fn a_constant_box_composites_by_the_emission_absorption_formula() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let field = constant_field(dev, 0.5);
    // Opacity 0.5 per unit distance 0.5; the box is 2 deep: 4 unit distances.
    let volume = uniform_volume(dev, field, [1.0, 0.5, 0.25], 0.5, 0.5, 17);
    let world = world_with(dev, &[volume], &[]);
    let transmittance = 0.5f32.powi(4);
    let background = [0.0, 0.0, 1.0, 0.5];
    for subtype in ["default", "fast"] {
        let r = renderer(dev, subtype, background);
        let out = render(dev, world, r);
        let inside = pixel(8, 8);
        let emitted = 1.0 - transmittance;
        assert_near(
            out.color[inside],
            [
                1.0 * emitted,
                0.5 * emitted,
                0.25 * emitted + transmittance,
                emitted + transmittance * 0.5,
            ],
            subtype,
        );
        // The volume starts being visible on its front face, 4 from the camera.
        assert!(
            (out.depth[inside] - 4.0).abs() < 1e-4,
            "{}",
            out.depth[inside]
        );
        assert_eq!(out.object[inside], 17);
        assert_eq!(out.primitive[inside], u32::MAX);
        assert_eq!(out.instance[inside], u32::MAX);
        // Outside the box: the background and no hit.
        let outside = pixel(1, 14);
        assert_near(out.color[outside], background, subtype);
        assert_eq!(out.object[outside], u32::MAX);
        assert_eq!(out.depth[outside], f32::INFINITY);
        anariRelease(dev, r);
    }
    // The world's bounds are the volume's box.
    let bounds = bounds_of(dev, world);
    assert_eq!(bounds, [-1.0, -1.0, -1.0, 1.0, 1.0, 1.0]);
    release_all(dev, &[world, volume, field]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn nearest_and_linear_filters_reconstruct_differently() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // Value = x index: 0 on the face x = −1, 1 on the face x = 1.
    let values: Vec<f32> = (0..8).map(|i| (i % 2) as f32).collect();
    // Black to white over the value range; opaque, so a pixel shows the colour on the face.
    let colors = array1d(dev, ANARI_FLOAT32_VEC3, &[[0.0f32; 3], [1.0f32; 3]]);
    let r = renderer(dev, "default", [0.0, 0.0, 0.0, 1.0]);
    let mut shown = Vec::new();
    for filter in ["linear", "nearest"] {
        let f = field(dev, [2, 2, 2], &values, [-1.0; 3], [2.0; 3], Some(filter));
        let volume = anariNewVolume(dev, c("transferFunction1D").as_ptr());
        set_object(dev, volume, "value", ANARI_SPATIAL_FIELD, f);
        set_object(dev, volume, "color", ANARI_ARRAY1D, colors);
        commit(dev, volume);
        let world = world_with(dev, &[volume], &[]);
        let out = render(dev, world, r);
        shown.push([out.color[pixel(5, 8)][0], out.color[pixel(10, 8)][0]]);
        release_all(dev, &[world, volume, f]);
    }
    // Pixel columns 5 and 10 look along x = −0.625 and 0.625: field values 0.1875 and 0.8125
    // between the vertices, 0 and 1 at the nearest vertex.
    let (left, right) = ((coordinate(5) + 1.0) / 2.0, (coordinate(10) + 1.0) / 2.0);
    assert!((shown[0][0] - left).abs() < 1e-5, "{shown:?}");
    assert!((shown[0][1] - right).abs() < 1e-5, "{shown:?}");
    assert_eq!(shown[1], [0.0, 1.0]);
    release_all(dev, &[colors, r]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn a_surface_inside_the_volume_ends_the_march() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let field = constant_field(dev, 0.5);
    let volume = uniform_volume(dev, field, [1.0, 1.0, 1.0], 0.5, 0.5, 4);
    // A grey rectangle at z = 0, the middle of the box, over the left half (x < 0).
    let surface = rectangle(dev, [-1.5, 0.0], [-1.5, 1.5], 0.0, 0.5, 9);
    let world = world_with(dev, &[volume], &[surface]);
    let r = renderer(dev, "default", [0.0, 0.0, 0.0, 1.0]);
    let out = render(dev, world, r);
    // Left: 2 unit distances of volume, then the surface (albedo 0.5 under ambient radiance 1).
    let cut = 0.5f32.powi(2);
    let left = out.color[pixel(5, 8)];
    assert_near(
        left,
        [
            1.0 - cut + cut * 0.5,
            1.0 - cut + cut * 0.5,
            1.0 - cut + cut * 0.5,
            1.0,
        ],
        "surface behind half the volume",
    );
    // Right: the whole box, then the black background.
    let full = 0.5f32.powi(4);
    assert_near(
        out.color[pixel(10, 8)],
        [1.0 - full, 1.0 - full, 1.0 - full, 1.0],
        "whole box",
    );
    // The volume is in front of the surface: it owns the id and depth channels.
    assert_eq!(out.object[pixel(5, 8)], 4);
    assert!((out.depth[pixel(5, 8)] - 4.0).abs() < 1e-4);
    // Outside the box the surface is the first thing seen.
    assert_eq!(out.object[pixel(5, 2)], 9);
    assert_eq!(out.primitive[pixel(5, 2)], 0);
    assert!((out.depth[pixel(5, 2)] - 5.0).abs() < 1e-4);
    release_all(dev, &[world, volume, field, surface, r]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn object_ids_name_the_first_volume_or_surface_seen() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // Volume A: opaque box over x ∈ [−2, −0.5].
    let a_field = field(
        dev,
        [2, 2, 2],
        &[1.0; 8],
        [-2.0, -1.0, -1.0],
        [1.5, 2.0, 2.0],
        None,
    );
    let a = uniform_volume(dev, a_field, [1.0, 0.0, 0.0], 1.0, 1.0, 5);
    // Volume B over x ∈ [0.5, 2]: value 0 (transparent) for z ≥ 0, rising to 1 at z = −1.
    let mut b_values = vec![0.0f32; 12];
    b_values[..4].fill(1.0);
    let b_field = field(
        dev,
        [2, 2, 3],
        &b_values,
        [0.5, -1.0, -1.0],
        [1.5, 2.0, 1.0],
        None,
    );
    let b = anariNewVolume(dev, c("transferFunction1D").as_ptr());
    set_object(dev, b, "value", ANARI_SPATIAL_FIELD, b_field);
    let ramp = array1d(dev, ANARI_FLOAT32, &[0.0f32, 1.0]);
    set_object(dev, b, "opacity", ANARI_ARRAY1D, ramp);
    set(dev, b, "id", ANARI_UINT32, &9u32);
    commit(dev, b);
    // A surface in front of the upper part of A.
    let s = rectangle(dev, [-2.0, -0.5], [0.0, 2.0], 3.0, 0.5, 3);
    let world = world_with(dev, &[a, b], &[s]);
    let r = renderer(dev, "fast", [0.0, 0.0, 0.0, 1.0]);
    let out = render(dev, world, r);
    assert_eq!(out.object[pixel(2, 4)], 5, "volume A");
    assert!((out.depth[pixel(2, 4)] - 4.0).abs() < 1e-4);
    assert_eq!(out.object[pixel(2, 10)], 3, "surface in front of A");
    assert!((out.depth[pixel(2, 10)] - 2.0).abs() < 1e-4);
    assert_eq!(out.object[pixel(8, 8)], u32::MAX, "between the volumes");
    // B is seen where it starts absorbing (the first sample past z = 0), not on its box face.
    assert_eq!(out.object[pixel(12, 8)], 9, "volume B");
    let depth = out.depth[pixel(12, 8)];
    assert!(depth > 5.0 && depth <= 5.5 + 1e-4, "{depth}");
    release_all(dev, &[world, a, a_field, b, b_field, ramp, s, r]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn an_instanced_volume_moves_and_stretches_with_its_transform() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // The box [−0.5, 0.5]³.
    let f = field(dev, [2, 2, 2], &[0.5; 8], [-0.5; 3], [1.0; 3], None);
    let volume = uniform_volume(dev, f, [1.0; 3], 0.5, 1.0, 6);
    let group = anariNewGroup(dev);
    let volumes = object_array(dev, ANARI_VOLUME, &[volume]);
    set_object(dev, group, "volume", ANARI_ARRAY1D, volumes);
    commit(dev, group);
    let instance = anariNewInstance(dev, c("transform").as_ptr());
    set_object(dev, instance, "group", ANARI_GROUP, group);
    set(dev, instance, "id", ANARI_UINT32, &42u32);
    // Moved to x = 1 and stretched to depth 2 along z (column-major).
    let transform: [f32; 16] = [
        1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 1.0, 0.0, 0.0, 1.0,
    ];
    set(dev, instance, "transform", ANARI_FLOAT32_MAT4, &transform);
    commit(dev, instance);
    let world = anariNewWorld(dev);
    let instances = object_array(dev, ANARI_INSTANCE, &[instance]);
    set_object(dev, world, "instance", ANARI_ARRAY1D, instances);
    commit(dev, world);
    let r = renderer(dev, "default", [0.0, 0.0, 0.0, 1.0]);
    let out = render(dev, world, r);
    // Pixel column 12 looks along x = 1.125, inside the moved box; opacity counts world
    // distance, so the stretched box (2 deep) passes 0.5² of the light.
    let inside = pixel(12, 8);
    let t = 0.25f32;
    assert_near(
        out.color[inside],
        [1.0 - t, 1.0 - t, 1.0 - t, 1.0],
        "moved box",
    );
    assert_eq!((out.object[inside], out.instance[inside]), (6, 42));
    assert!((out.depth[inside] - 4.0).abs() < 1e-4);
    // Where the box was before the transform there is nothing.
    assert_eq!(out.object[pixel(7, 8)], u32::MAX);
    assert_near(out.color[pixel(7, 8)], [0.0, 0.0, 0.0, 1.0], "old place");
    let bounds = bounds_of(dev, world);
    assert_eq!(bounds, [0.5, -0.5, -1.0, 1.5, 0.5, 1.0]);
    let group_bounds = bounds_of(dev, group);
    assert_eq!(group_bounds, [-0.5, -0.5, -0.5, 0.5, 0.5, 0.5]);
    release_all(
        dev,
        &[world, instances, instance, volumes, group, volume, f, r],
    );
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

fn messages_with(log: &Log, needle: &str) -> Vec<(i32, i32, String)> {
    log.take()
        .into_iter()
        .filter(|(_, _, text)| text.contains(needle))
        .collect()
}

#[test]
fn bad_volume_input_is_reported_and_rendered_as_nothing() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);

    // A 2D array as 'data' is refused at anariSetParameter.
    let flat = unfilled_array2d(dev, ANARI_FLOAT32, [2, 2]);
    let bad_field = anariNewSpatialField(dev, c("structuredRegular").as_ptr());
    set_object(dev, bad_field, "data", ANARI_ARRAY2D, flat);
    let refused = messages_with(&log, "'data'");
    assert_eq!(refused.len(), 1, "{refused:?}");
    assert_eq!(refused[0].0, ANARI_SEVERITY_ERROR);
    assert_eq!(refused[0].1, ANARI_STATUS_INVALID_ARGUMENT);
    assert!(refused[0].2.contains("ANARI_ARRAY3D"), "{}", refused[0].2);
    commit(dev, bad_field);
    let missing = messages_with(&log, "required parameter 'data'");
    assert_eq!(missing.len(), 1, "{missing:?}");

    // A 3D array of vectors is not a scalar field.
    let vectors = anariNewArray3D(
        dev,
        std::ptr::null(),
        None,
        std::ptr::null(),
        ANARI_FLOAT32_VEC3,
        2,
        2,
        2,
    );
    set_object(dev, bad_field, "data", ANARI_ARRAY3D, vectors);
    let refused = messages_with(&log, "ANARI_FLOAT32_VEC3");
    assert_eq!(refused.len(), 1, "{refused:?}");

    // Non-positive spacing.
    let field = constant_field(dev, 0.5);
    set(
        dev,
        field,
        "spacing",
        ANARI_FLOAT32_VEC3,
        &[1.0f32, 0.0, 1.0],
    );
    commit(dev, field);
    let spacing = messages_with(&log, "'spacing'");
    assert_eq!(spacing.len(), 1, "{spacing:?}");
    assert_eq!(spacing[0].0, ANARI_SEVERITY_ERROR);
    set(dev, field, "spacing", ANARI_FLOAT32_VEC3, &[2.0f32; 3]);
    commit(dev, field);

    // Reversed valueRange: a reversed mapping, said in a warning.
    let reversed = uniform_volume(dev, field, [1.0; 3], 1.0, 1.0, 1);
    set(
        dev,
        reversed,
        "valueRange",
        ANARI_FLOAT32_BOX1,
        &[1.0f32, 0.0],
    );
    commit(dev, reversed);
    let range = messages_with(&log, "'valueRange'");
    assert_eq!(range.len(), 1, "{range:?}");
    assert_eq!(
        (range[0].0, range[0].1),
        (ANARI_SEVERITY_WARNING, ANARI_STATUS_NO_ERROR)
    );
    assert!(range[0].2.contains("reversed mapping"), "{}", range[0].2);

    // Non-positive unitDistance.
    let thin = uniform_volume(dev, field, [1.0; 3], 1.0, 0.0, 2);
    let unit = messages_with(&log, "'unitDistance'");
    assert_eq!(unit.len(), 1, "{unit:?}");

    // No field at all.
    let empty = anariNewVolume(dev, c("transferFunction1D").as_ptr());
    commit(dev, empty);
    let missing = messages_with(&log, "required parameter 'value'");
    assert_eq!(missing.len(), 1, "{missing:?}");

    // A volume whose field never committed successfully.
    let unusable = anariNewVolume(dev, c("transferFunction1D").as_ptr());
    set_object(dev, unusable, "value", ANARI_SPATIAL_FIELD, bad_field);
    commit(dev, unusable);
    let unusable_field = messages_with(&log, "not a usable committed field");
    assert_eq!(unusable_field.len(), 1, "{unusable_field:?}");

    // Unknown filter: the default (linear) is used, with a warning.
    set_string(dev, field, "filter", "cubic");
    commit(dev, field);
    let filter = messages_with(&log, "'cubic'");
    assert_eq!(filter.len(), 1, "{filter:?}");
    assert_eq!(filter[0].0, ANARI_SEVERITY_WARNING);

    // None of them renders, and rendering them is harmless.
    let world = world_with(dev, &[thin, empty, unusable], &[]);
    let r = renderer(dev, "default", [0.0, 0.0, 0.0, 1.0]);
    let out = render(dev, world, r);
    assert!(out.object.iter().all(|&id| id == u32::MAX));
    assert!(out.color.iter().all(|c| *c == [0.0, 0.0, 0.0, 1.0]));
    assert!(log.errors().is_empty(), "rendering reported errors");

    // The reversed volume renders.
    let array = object_array(dev, ANARI_VOLUME, &[reversed, thin, empty, unusable]);
    set_object(dev, world, "volume", ANARI_ARRAY1D, array);
    anariRelease(dev, array);
    commit(dev, world);
    let out = render(dev, world, r);
    assert_eq!(out.object[pixel(8, 8)], 1);
    release_all(
        dev,
        &[
            world, r, reversed, thin, empty, unusable, field, bad_field, flat, vectors,
        ],
    );
    release_device(lib, dev);
}

/// The default renderer with no ambient light, `samples` samples per pixel and a black
/// background.
fn lit_renderer(dev: ANARIDevice, samples: i32) -> ANARIRenderer {
    let renderer = anariNewRenderer(dev, c("default").as_ptr());
    set(
        dev,
        renderer,
        "background",
        ANARI_FLOAT32_VEC4,
        &[0.0f32, 0.0, 0.0, 1.0],
    );
    set(dev, renderer, "ambientRadiance", ANARI_FLOAT32, &0.0f32);
    set(dev, renderer, "pixelSamples", ANARI_INT32, &samples);
    commit(dev, renderer);
    renderer
}

/// Whether every channel of `actual` is within `relative` of `expected` (and 1e-7 of 0).
fn assert_relative(actual: [f32; 4], expected: [f32; 3], relative: f32, what: &str) {
    for k in 0..3 {
        let tolerance = expected[k].abs() * relative + 1e-7;
        assert!(
            (actual[k] - expected[k]).abs() <= tolerance,
            "{what}: got {actual:?}, expected {expected:?}"
        );
    }
}

#[test]
fn a_slab_lit_along_its_normal_scatters_the_single_scattering_closed_form() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let field = constant_field(dev, 0.5);
    // Opacity 0.5 per unit distance 0.5: σ = 2 ln 2 per unit; the box is d = 2 deep.
    let albedo = [1.0f32, 0.5, 0.25];
    let volume = uniform_volume(dev, field, albedo, 0.5, 0.5, 3);
    let (sigma, depth) = (2.0 * 2f32.ln(), 2.0f32);
    let through = (-sigma * depth).exp();
    let four_pi = 4.0 * std::f32::consts::PI;
    let r = lit_renderer(dev, 256);

    // Light from the camera's side (irradiance 1 travelling −z), seen along the normal: at
    // depth s the light has crossed s and the scattered light crosses s back, so
    // L = ∫₀ᵈ σ·albedo·(1/4π)·E·e^{−2σs} ds = albedo·E·(1 − e^{−2σd}) / 8π.
    let front = world_with(dev, &[volume], &[]);
    light_world(dev, front, [0.0, 0.0, -1.0]);
    let out = render(dev, front, r);
    let expected = albedo.map(|a| a * (1.0 - through * through) / (2.0 * four_pi));
    assert_relative(out.color[pixel(8, 8)], expected, 2e-3, "lit from the front");
    assert_relative(
        out.color[pixel(5, 10)],
        expected,
        2e-3,
        "lit from the front",
    );
    assert!((out.color[pixel(8, 8)][3] - 1.0).abs() < 1e-6);

    // Light from behind (travelling +z): the light crosses d − s, the scattered light s, so
    // L = σ·albedo·E·d·e^{−σd} / 4π. An opaque rectangle behind the left half (x < 0) keeps
    // the light from that half of the volume: it scatters nothing, and the rectangle's side
    // facing the camera is unlit.
    let shade = rectangle(dev, [-2.5, 0.0], [-2.5, 2.5], -1.5, 0.5, 9);
    let behind = world_with(dev, &[volume], &[shade]);
    light_world(dev, behind, [0.0, 0.0, 1.0]);
    let out = render(dev, behind, r);
    let expected = albedo.map(|a| a * sigma * depth * through / four_pi);
    assert_relative(out.color[pixel(10, 8)], expected, 2e-3, "lit from behind");
    assert_relative(out.color[pixel(10, 5)], expected, 2e-3, "lit from behind");
    assert_relative(
        out.color[pixel(5, 8)],
        [0.0; 3],
        0.0,
        "in the rectangle's shadow",
    );
    assert_relative(
        out.color[pixel(6, 10)],
        [0.0; 3],
        0.0,
        "in the rectangle's shadow",
    );
    release_all(dev, &[front, behind, shade, volume, field, r]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn a_surface_behind_a_volume_is_shadowed_by_its_transmittance() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let field = constant_field(dev, 0.5);
    // σ = −ln(1 − 0.2) per unit.
    let volume = uniform_volume(dev, field, [1.0; 3], 0.2, 1.0, 3);
    let sigma = -(0.8f32.ln());
    let floor = rectangle(dev, [-2.5, 2.5], [-2.5, 2.5], -1.5, 0.5, 9);
    let world = world_with(dev, &[volume], &[floor]);
    // Light at 45° travelling −x and −z (irradiance 1 across its direction).
    light_world(dev, world, [-1.0, 0.0, -1.0]);
    let r = lit_renderer(dev, 1);
    let out = render(dev, world, r);
    // Column 2 looks at x = −1.375, left of the box. Towards the light, (1, 0, 1)/√2, the
    // floor at y = 0.125 sees the box from z = −1 (x = −0.875) to x = 1 (z = 0.875): a path
    // of 1.875·√2; at y = 1.625 the path passes beside the box.
    let lambert = 0.5 / std::f32::consts::PI * std::f32::consts::FRAC_1_SQRT_2;
    let shadowed = lambert * (-sigma * 1.875 * std::f32::consts::SQRT_2).exp();
    assert_relative(
        out.color[pixel(2, 14)],
        [lambert; 3],
        1e-4,
        "beside the shadow",
    );
    assert_relative(
        out.color[pixel(2, 8)],
        [shadowed; 3],
        1e-4,
        "in the volume's shadow",
    );
    assert_eq!(out.object[pixel(2, 8)], 9);
    release_all(dev, &[world, floor, volume, field, r]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

/// The mean over the sphere of the light reaching a point inside a slab along its normal
/// axis, `above` below its top and `below` above its bottom: each ray crosses the slab with
/// extinction σ for at most `reach`, and, with `floor_below`, rays going down meet an opaque
/// floor (within reach). Half the sphere goes up, half down; over each half the cosine μ to
/// the axis is uniform, and the path to the face at distance a is a/μ:
/// ½·∫₀¹ e^{−σ·min(a/μ, reach)} dμ per half (midpoint rule).
fn slab_ambient_share(sigma: f64, above: f64, below: f64, reach: f64, floor_below: bool) -> f64 {
    let n = 2000;
    let half = |a: f64| {
        (0..n)
            .map(|k| {
                let mu = (k as f64 + 0.5) / n as f64;
                (-sigma * (a / mu).min(reach)).exp()
            })
            .sum::<f64>()
            / n as f64
    };
    0.5 * half(above) + if floor_below { 0.0 } else { 0.5 * half(below) }
}

#[test]
fn ambient_light_in_and_under_a_slab_is_occluded_by_its_transmittance() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // A slab 2 deep (z in [−1, 1]) and 100 wide, opacity 0.5 per unit distance 1: σ = ln 2.
    let slab = field(
        dev,
        [2, 2, 2],
        &[0.5; 8],
        [-50.0, -50.0, -1.0],
        [100.0, 100.0, 2.0],
        None,
    );
    let albedo = [1.0f32, 0.5, 0.25];
    let volume = uniform_volume(dev, slab, albedo, 0.5, 1.0, 3);
    let (sigma, depth) = (2f64.ln(), 2.0f64);
    // A black floor below the slab: it hides the ambient light from below and adds nothing.
    let floor = rectangle(dev, [-50.0, 50.0], [-50.0, 50.0], -1.2, 0.0, 9);
    let open_world = world_with(dev, &[volume], &[]);
    let floored_world = world_with(dev, &[volume], &[floor]);
    let grey_floor = rectangle(dev, [-50.0, 50.0], [-50.0, 50.0], -1.2, 0.5, 9);
    let grey_floored_world = world_with(dev, &[volume], &[grey_floor]);
    let r = lit_renderer(dev, 64);
    set(dev, r, "ambientRadiance", ANARI_FLOAT32, &1.0f32);

    // Seen along the normal from above: L = A·albedo·∫₀ᵈ σ·e^{−σs}·V(s) ds, V(s) the share of
    // the ambient light reaching depth s (quadrature over s, midpoint rule).
    let expected_share = |reach: f64, floor_below: bool| {
        let n = 400;
        (0..n)
            .map(|k| {
                let s = (k as f64 + 0.5) / n as f64 * depth;
                let v = slab_ambient_share(sigma, s, depth - s, reach, floor_below);
                sigma * (-sigma * s).exp() * v * depth / n as f64
            })
            .sum::<f64>()
    };
    let mean_red = |world: ANARIWorld| {
        let out = render(dev, world, r);
        out.color.iter().map(|c| c[0] as f64).sum::<f64>() / out.color.len() as f64
    };
    for (what, world, reach, floor_below) in [
        ("open, unbounded", open_world, f64::INFINITY, false),
        ("open, reach 0.5", open_world, 0.5, false),
        ("on a floor, unbounded", floored_world, f64::INFINITY, true),
    ] {
        let distance = reach.min(1e30) as f32;
        set(dev, r, "ambientOcclusionDistance", ANARI_FLOAT32, &distance);
        commit(dev, r);
        let got = mean_red(world);
        let expected = expected_share(reach, floor_below);
        let unoccluded = 1.0 - (-sigma * depth).exp();
        println!("{what}: {got:.5} against {expected:.5} (unoccluded {unoccluded:.5})");
        assert!(
            (got - expected).abs() < 0.01 * expected,
            "{what}: {got} vs {expected}"
        );
    }
    // A grey floor (albedo 0.5) under the slab gathers the ambient light through it: the
    // cosine-weighted mean of e^{−σd/μ}, 2·∫₀¹ μ·e^{−σd/μ} dμ; seen through the slab's
    // transmittance, behind the light the slab scatters.
    set(dev, r, "ambientOcclusionDistance", ANARI_FLOAT32, &1e30f32);
    commit(dev, r);
    let n = 4000;
    let floor_share = 2.0
        * (0..n)
            .map(|k| {
                let mu = (k as f64 + 0.5) / n as f64;
                mu * (-sigma * depth / mu).exp()
            })
            .sum::<f64>()
        / n as f64;
    let through = (-sigma * depth).exp();
    let expected = expected_share(f64::INFINITY, true) + through * 0.5 * floor_share;
    let got = mean_red(grey_floored_world);
    println!(
        "grey floor under the slab: {got:.5} against {expected:.5} (unoccluded floor {:.5})",
        expected_share(f64::INFINITY, true) + through * 0.5
    );
    assert!(
        (got - expected).abs() < 0.01 * expected,
        "grey floor: {got} vs {expected}"
    );
    // Distance 0: not occluded, the emission–absorption value exactly (up to rounding).
    set(dev, r, "ambientOcclusionDistance", ANARI_FLOAT32, &0.0f32);
    commit(dev, r);
    let out = render(dev, open_world, r);
    let unoccluded = 1.0 - (-sigma * depth).exp() as f32;
    for color in &out.color {
        assert_relative(*color, albedo.map(|a| a * unoccluded), 1e-4, "unoccluded");
    }
    release_all(
        dev,
        &[
            open_world,
            floored_world,
            grey_floored_world,
            floor,
            grey_floor,
            volume,
            slab,
            r,
        ],
    );
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}
