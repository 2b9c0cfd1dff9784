//! Isosurfaces and unstructured fields through the C API.
//!
//! Every scene is seen by an orthographic camera at z = 5 looking down −z over the square
//! [−2, 2]² with 16 × 16 pixels: pixel (i, j) looks along x = −2 + (i + ½)/4, y = −2 + (j + ½)/4.
mod common;
use common::*;

const SIZE: u32 = 16;
/// Grid spacing of the radial field.
const H: f32 = 0.1;

fn pixel(i: u32, j: u32) -> usize {
    (j * SIZE + i) as usize
}

fn coordinate(i: u32) -> f32 {
    -2.0 + (i as f32 + 0.5) * 0.25
}

struct Channels {
    color: Vec<[f32; 4]>,
    depth: Vec<f32>,
    primitive: Vec<u32>,
    object: Vec<u32>,
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
    };
    release_all(dev, &[frame, camera]);
    channels
}

fn renderer(dev: ANARIDevice) -> ANARIRenderer {
    let renderer = anariNewRenderer(dev, c("default").as_ptr());
    set(
        dev,
        renderer,
        "background",
        ANARI_FLOAT32_VEC4,
        &[0.0f32, 0.0, 0.0, 1.0],
    );
    set(dev, renderer, "ambientRadiance", ANARI_FLOAT32, &1.0f32);
    commit(dev, renderer);
    renderer
}

/// f = |x|² on a grid of spacing H over [−1, 1]³.
fn radial_field(dev: ANARIDevice) -> ANARISpatialField {
    let field = anariNewSpatialField(dev, c("structuredRegular").as_ptr());
    set_radial_data(dev, field, 1.0);
    set(dev, field, "origin", ANARI_FLOAT32_VEC3, &[-1.0f32; 3]);
    set(dev, field, "spacing", ANARI_FLOAT32_VEC3, &[H; 3]);
    commit(dev, field);
    field
}

/// Gives `field` the data f = scale · |x|² on a grid of spacing H over [−1, 1]³ (uncommitted).
fn set_radial_data(dev: ANARIDevice, field: ANARISpatialField, scale: f32) {
    let n = 21usize;
    let mut values = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let p = [i, j, k].map(|v| v as f32 * H - 1.0);
                values.push(scale * (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]));
            }
        }
    }
    let data = array3d(dev, ANARI_FLOAT32, &values, [n as u64; 3]);
    set_object(dev, field, "data", ANARI_ARRAY3D, data);
    anariRelease(dev, data);
}

fn isosurface(dev: ANARIDevice, field: ANARISpatialField, isovalues: &[f32]) -> ANARIGeometry {
    let geometry = anariNewGeometry(dev, c("isosurface").as_ptr());
    set_object(dev, geometry, "field", ANARI_SPATIAL_FIELD, field);
    set_array(dev, geometry, "isovalue", ANARI_FLOAT32, isovalues);
    commit(dev, geometry);
    geometry
}

fn complaints(log: &Log) -> Vec<(i32, i32, String)> {
    log.take()
        .into_iter()
        .filter(|(severity, _, _)| *severity <= ANARI_SEVERITY_WARNING)
        .collect()
}

fn messages_with(log: &Log, needle: &str) -> Vec<(i32, i32, String)> {
    log.take()
        .into_iter()
        .filter(|(_, _, text)| text.contains(needle))
        .collect()
}

#[test]
fn isosurfaces_of_a_radial_field_render_their_shells_with_isovalue_ids_and_colours() {
    use cavetrace::device::catalog::Kinds;
    let extensions = cavetrace::kinds::KINDS.extensions();
    assert!(extensions.contains(&"ANARI_KHR_GEOMETRY_ISOSURFACE"));
    assert!(extensions.contains(&"ANARI_KHR_SPATIAL_FIELD_UNSTRUCTURED"));
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let field = radial_field(dev);
    // Two shells, radius 0.5 (isovalue 0) inside radius 0.9 (isovalue 1), coloured per isovalue.
    let geometry = isosurface(dev, field, &[0.25, 0.81]);
    set_array(
        dev,
        geometry,
        "primitive.color",
        ANARI_FLOAT32_VEC3,
        &[[1.0f32, 0.0, 0.0], [0.0, 0.0, 1.0]],
    );
    commit(dev, geometry);
    let material = matte_colored_by(dev, "color");
    let surface = surface_of(dev, geometry, material);
    set(dev, surface, "id", ANARI_UINT32, &9u32);
    commit(dev, surface);
    let world = world_of(dev, &[surface]);
    let r = renderer(dev);
    let out = render(dev, world, r);
    assert!(complaints(&log).is_empty());
    for j in 0..SIZE {
        for i in 0..SIZE {
            let (x, y) = (coordinate(i), coordinate(j));
            let p = pixel(i, j);
            let lateral = x * x + y * y;
            if lateral >= 0.8 {
                // Beside (or grazing) the outer shell: checked where the answer is clear-cut.
                if lateral > 0.83 {
                    assert_eq!(out.primitive[p], u32::MAX, "({x}, {y})");
                }
                continue;
            }
            // The outer shell is in front: its isovalue index, its colour, the surface id.
            assert_eq!(out.primitive[p], 1, "({x}, {y})");
            assert_eq!(out.object[p], 9);
            let [red, _, blue, alpha] = out.color[p];
            assert!(
                blue > 0.05 && red == 0.0 && alpha == 1.0,
                "{:?}",
                out.color[p]
            );
            // The interpolant exceeds |x|² by between 0 and 3H²/4, so the surface lies inside
            // the true sphere by at most 3H²/4 / (z_sphere + z) ≤ 3H²/(4 z) along the ray.
            let z = (0.81 - lateral).sqrt();
            let depth = out.depth[p];
            let bound = 0.75 * H * H / (z - 0.01);
            assert!(
                depth >= 5.0 - z - 1e-5 && depth <= 5.0 - z + bound,
                "{depth} {z}"
            );
        }
    }
    // Only the inner shell: the same pixels, its index and colour.
    set_array(dev, geometry, "isovalue", ANARI_FLOAT32, &[0.25f32]);
    commit(dev, geometry);
    let out = render(dev, world, r);
    let centre = pixel(8, 8);
    assert_eq!(out.primitive[centre], 0);
    assert!(out.color[centre][0] > 0.05 && out.color[centre][2] == 0.0);
    let z = (0.25f32 - 2.0 * 0.125 * 0.125).sqrt();
    assert!((out.depth[centre] - (5.0 - z)).abs() < 0.75 * H * H / (z - 0.01));
    release_all(dev, &[world, r, surface, material, geometry, field]);
    release_device(lib, dev);
}

/// The BVH the device holds for a committed geometry (to tell a rebuild from a reuse).
fn geometry_bvh(dev: ANARIDevice, geometry: ANARIGeometry) -> Option<usize> {
    let device = cavetrace::device::registry::device(dev as usize)?;
    let object = device.lookup(geometry as usize)?;
    cavetrace::scene::geometry::current(&device, &object)
        .map(|g| std::sync::Arc::as_ptr(&g.bvh) as usize)
}

#[test]
fn an_isosurface_follows_its_field_recommitted_with_new_data() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let field = radial_field(dev);
    // The shell f = 0.25: radius 0.5 for f = |x|², radius 0.7 for f = (0.25 / 0.49)|x|².
    let geometry = isosurface(dev, field, &[0.25]);
    let material = matte_colored_by(dev, "color");
    let surface = surface_of(dev, geometry, material);
    set(dev, surface, "id", ANARI_UINT32, &9u32);
    commit(dev, surface);
    let world = world_of(dev, &[surface]);
    let r = renderer(dev);
    let (centre, between) = (pixel(8, 8), pixel(10, 8));
    // Pixel (10, 8) looks down x = 0.625, y = 0.125: outside radius 0.5, inside radius 0.7.
    let depth_at = |radius: f32, i: u32| {
        let (x, y) = (coordinate(i), coordinate(8));
        5.0 - (radius * radius - x * x - y * y).sqrt()
    };
    let first = render(dev, world, r);
    assert_eq!(first.object[centre], 9);
    assert!((first.depth[centre] - depth_at(0.5, 8)).abs() < 0.01);
    assert_eq!(first.primitive[between], u32::MAX);
    let built = geometry_bvh(dev, geometry);
    assert!(built.is_some());
    // Nothing changed: the next frame renders the same build.
    render(dev, world, r);
    assert_eq!(geometry_bvh(dev, geometry), built);

    // A new time step: only the field is committed.
    set_radial_data(dev, field, 0.25 / 0.49);
    commit(dev, field);
    let second = render(dev, world, r);
    assert!(complaints(&log).is_empty());
    assert_eq!(second.object[centre], 9);
    assert!(
        (second.depth[centre] - depth_at(0.7, 8)).abs() < 0.01,
        "{} vs {}",
        second.depth[centre],
        depth_at(0.7, 8)
    );
    assert_eq!(second.primitive[between], 0);
    assert_eq!(second.object[between], 9);
    assert!((second.depth[between] - depth_at(0.7, 10)).abs() < 0.01);
    let rebuilt = geometry_bvh(dev, geometry);
    assert_ne!(rebuilt, built);
    render(dev, world, r);
    assert_eq!(geometry_bvh(dev, geometry), rebuilt);

    // A field whose recommit fails leaves nothing to isosurface: the frame says why, and the
    // surface comes back with the next good commit.
    anariUnsetParameter(dev, field, c("data").as_ptr());
    commit(dev, field);
    log.take();
    let broken = render(dev, world, r);
    assert_eq!(broken.object[centre], u32::MAX);
    let refused = messages_with(&log, "not a usable committed spatial field");
    assert_eq!(refused.len(), 1, "{refused:?}");
    assert!(
        refused[0].2.contains("anariRenderFrame"),
        "{}",
        refused[0].2
    );
    render(dev, world, r);
    assert!(messages_with(&log, "spatial field").is_empty());
    set_radial_data(dev, field, 1.0);
    commit(dev, field);
    let restored = render(dev, world, r);
    assert!((restored.depth[centre] - depth_at(0.5, 8)).abs() < 0.01);
    assert!(complaints(&log).is_empty());
    release_all(dev, &[world, r, surface, material, geometry, field]);
    release_device(lib, dev);
}

/// Positions, index, cell types and vertex values of an unstructured mesh.
struct Mesh {
    positions: Vec<[f32; 3]>,
    index: Vec<u32>,
    types: Vec<u8>,
    values: Vec<f32>,
}

/// The cells of an n³ grid over [x0, x0 + 1] × [−1, 1] × [−0.5, 0.5] as hexahedra (or six
/// tetrahedra each): positions, index, cell types and the vertex values of `f`.
fn mesh(n: usize, f: impl Fn([f32; 3]) -> f32, tetrahedra: bool) -> Mesh {
    let step = |i: usize| i as f32 / (n - 1) as f32;
    let mut positions = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                positions.push([step(i) - 0.5, 2.0 * step(j) - 1.0, step(k) - 0.5]);
            }
        }
    }
    let values = positions.iter().map(|p| f(*p)).collect();
    let vertex = |i: usize, j: usize, k: usize| (i + n * (j + n * k)) as u32;
    let (mut index, mut types) = (Vec::new(), Vec::new());
    for k in 0..n - 1 {
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let hex = [
                    vertex(i, j, k),
                    vertex(i + 1, j, k),
                    vertex(i + 1, j + 1, k),
                    vertex(i, j + 1, k),
                    vertex(i, j, k + 1),
                    vertex(i + 1, j, k + 1),
                    vertex(i + 1, j + 1, k + 1),
                    vertex(i, j + 1, k + 1),
                ];
                if tetrahedra {
                    for [a, b] in [[1, 2], [2, 3], [3, 7], [7, 4], [4, 5], [5, 1]] {
                        index.extend([hex[0], hex[a], hex[b], hex[6]]);
                        types.push(10);
                    }
                } else {
                    index.extend(hex);
                    types.push(12);
                }
            }
        }
    }
    Mesh {
        positions,
        index,
        types,
        values,
    }
}

fn unstructured_field(
    dev: ANARIDevice,
    Mesh {
        positions,
        index,
        types,
        values,
    }: &Mesh,
) -> ANARISpatialField {
    let field = anariNewSpatialField(dev, c("unstructured").as_ptr());
    set_array(dev, field, "vertex.position", ANARI_FLOAT32_VEC3, positions);
    set_array(dev, field, "index", ANARI_UINT32, index);
    set_array(dev, field, "cell.type", ANARI_UINT8, types);
    let firsts: Vec<u32> = types
        .iter()
        .scan(0u32, |first, t| {
            let here = *first;
            *first += if *t == 10 { 4 } else { 8 };
            Some(here)
        })
        .collect();
    set_array(dev, field, "cell.index", ANARI_UINT32, &firsts);
    set_array(dev, field, "vertex.data", ANARI_FLOAT32, values);
    commit(dev, field);
    field
}

fn volume_world(dev: ANARIDevice, field: ANARISpatialField) -> (ANARIVolume, ANARIWorld) {
    let volume = anariNewVolume(dev, c("transferFunction1D").as_ptr());
    set_object(dev, volume, "value", ANARI_SPATIAL_FIELD, field);
    set_array(
        dev,
        volume,
        "color",
        ANARI_FLOAT32_VEC3,
        &[[1.0f32, 0.2, 0.0], [0.0, 0.4, 1.0]],
    );
    set_array(dev, volume, "opacity", ANARI_FLOAT32, &[0.1f32, 0.8, 0.4]);
    set(dev, volume, "unitDistance", ANARI_FLOAT32, &0.5f32);
    set(dev, volume, "id", ANARI_UINT32, &4u32);
    commit(dev, volume);
    let world = anariNewWorld(dev);
    let array = object_array(dev, ANARI_VOLUME, &[volume]);
    set_object(dev, world, "volume", ANARI_ARRAY1D, array);
    anariRelease(dev, array);
    commit(dev, world);
    (volume, world)
}

#[test]
fn an_unstructured_volume_renders_what_the_same_structured_grid_does() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let n = 5;
    let wavy = |p: [f32; 3]| 0.5 + 0.45 * (3.0 * p[0]).sin() * (2.0 * p[1] + p[2]).cos();
    let cells = mesh(n, wavy, false);
    // The same vertices and values as a structured grid.
    let data = array3d(dev, ANARI_FLOAT32, &cells.values, [n as u64; 3]);
    let grid = anariNewSpatialField(dev, c("structuredRegular").as_ptr());
    set_object(dev, grid, "data", ANARI_ARRAY3D, data);
    set(
        dev,
        grid,
        "origin",
        ANARI_FLOAT32_VEC3,
        &[-0.5f32, -1.0, -0.5],
    );
    let spacing = 1.0 / (n - 1) as f32;
    set(
        dev,
        grid,
        "spacing",
        ANARI_FLOAT32_VEC3,
        &[spacing, 2.0 * spacing, spacing],
    );
    commit(dev, grid);
    let hexahedra = unstructured_field(dev, &cells);
    assert!(complaints(&log).is_empty());
    let r = renderer(dev);
    let (grid_volume, grid_world) = volume_world(dev, grid);
    let (mesh_volume, mesh_world) = volume_world(dev, hexahedra);
    let expected = render(dev, grid_world, r);
    let out = render(dev, mesh_world, r);
    let mut covered = 0;
    for p in 0..(SIZE * SIZE) as usize {
        assert_near(out.color[p], expected.color[p], "hexahedra vs grid");
        assert_eq!(out.object[p], expected.object[p]);
        covered += usize::from(out.object[p] == 4);
    }
    // The slab covers x ∈ [−0.5, 0.5], y ∈ [−1, 1]: 4 × 8 pixels.
    assert_eq!(covered, 32);
    assert!(log.errors().is_empty());
    release_all(
        dev,
        &[
            grid_world,
            mesh_world,
            grid_volume,
            mesh_volume,
            r,
            hexahedra,
            grid,
            data,
        ],
    );
    release_device(lib, dev);
}

#[test]
fn an_isosurface_of_tetrahedra_is_the_plane_of_their_linear_field() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // f = 0.2x − 0.1y + z over the tetrahedra: the isosurface f = 0.1 is a plane.
    let linear = |p: [f32; 3]| 0.2 * p[0] - 0.1 * p[1] + p[2];
    let field = unstructured_field(dev, &mesh(3, linear, true));
    let geometry = isosurface(dev, field, &[0.1]);
    set(
        dev,
        geometry,
        "color",
        ANARI_FLOAT32_VEC4,
        &[0.0f32, 1.0, 0.0, 1.0],
    );
    commit(dev, geometry);
    let material = matte_colored_by(dev, "color");
    let surface = surface_of(dev, geometry, material);
    let world = world_of(dev, &[surface]);
    let r = renderer(dev);
    let out = render(dev, world, r);
    assert!(complaints(&log).is_empty());
    let mut hits = 0;
    for j in 0..SIZE {
        for i in 0..SIZE {
            let (x, y) = (coordinate(i), coordinate(j));
            let p = pixel(i, j);
            if x.abs() < 0.5 && y.abs() < 1.0 {
                let z = 0.1 - 0.2 * x + 0.1 * y;
                assert!(
                    (out.depth[p] - (5.0 - z)).abs() < 1e-5,
                    "({x}, {y}) {}",
                    out.depth[p]
                );
                assert_eq!(out.primitive[p], 0);
                assert!(out.color[p][1] > 0.05 && out.color[p][0] == 0.0);
                hits += 1;
            } else {
                assert_eq!(out.primitive[p], u32::MAX);
            }
        }
    }
    assert_eq!(hits, 32);
    release_all(dev, &[world, r, surface, material, geometry, field]);
    release_device(lib, dev);
}

#[test]
fn bad_field_and_isosurface_input_is_reported() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let positions = [
        [0.0f32, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];

    // A cell type outside 10, 12, 13, 14 and an index out of range: those cells are skipped.
    let field = anariNewSpatialField(dev, c("unstructured").as_ptr());
    set_array(
        dev,
        field,
        "vertex.position",
        ANARI_FLOAT32_VEC3,
        &positions,
    );
    set_array(
        dev,
        field,
        "index",
        ANARI_UINT32,
        &[0u32, 1, 2, 3, 0, 1, 2, 9, 0, 1, 2, 3],
    );
    set_array(dev, field, "cell.type", ANARI_UINT8, &[10u8, 10, 11]);
    set_array(dev, field, "cell.index", ANARI_UINT32, &[0u32, 4, 8]);
    set_array(
        dev,
        field,
        "vertex.data",
        ANARI_FLOAT32,
        &[0.0f32, 1.0, 2.0, 3.0],
    );
    commit(dev, field);
    let skipped = messages_with(&log, "is skipped");
    assert_eq!(skipped.len(), 2, "{skipped:?}");
    assert!(skipped[0].2.contains("cell 1") && skipped[0].2.contains("out of range"));
    assert!(skipped[1].2.contains("cell 2") && skipped[1].2.contains("10, 12, 13, 14"));

    // No values at all.
    let empty = anariNewSpatialField(dev, c("unstructured").as_ptr());
    set_array(
        dev,
        empty,
        "vertex.position",
        ANARI_FLOAT32_VEC3,
        &positions,
    );
    set_array(dev, empty, "cell.type", ANARI_UINT8, &[10u8]);
    commit(dev, empty);
    let no_values = messages_with(&log, "neither 'vertex.data' nor 'cell.data'");
    assert_eq!(no_values.len(), 1, "{no_values:?}");
    assert_eq!(no_values[0].0, ANARI_SEVERITY_ERROR);

    // An isosurface over a field that did not commit, and one over cell-centred values.
    let unusable = isosurface(dev, empty, &[0.5]);
    let refused = messages_with(&log, "not a usable committed spatial field");
    assert_eq!(refused.len(), 1, "{refused:?}");
    let cell_data = anariNewSpatialField(dev, c("unstructured").as_ptr());
    set_array(
        dev,
        cell_data,
        "vertex.position",
        ANARI_FLOAT32_VEC3,
        &positions,
    );
    set_array(dev, cell_data, "cell.type", ANARI_UINT8, &[10u8]);
    set_array(dev, cell_data, "cell.data", ANARI_FLOAT32, &[0.5f32]);
    commit(dev, cell_data);
    assert!(complaints(&log).is_empty());
    let flat = isosurface(dev, cell_data, &[0.5]);
    let constant = messages_with(&log, "cell-centred");
    assert_eq!(constant.len(), 1, "{constant:?}");

    // A reversed valueRange is a reversed mapping, said in a warning.
    let volume = anariNewVolume(dev, c("transferFunction1D").as_ptr());
    set_object(dev, volume, "value", ANARI_SPATIAL_FIELD, field);
    set(
        dev,
        volume,
        "valueRange",
        ANARI_FLOAT32_BOX1,
        &[3.0f32, 0.0],
    );
    commit(dev, volume);
    let reversed = messages_with(&log, "'valueRange'");
    assert_eq!(reversed.len(), 1, "{reversed:?}");
    assert_eq!(reversed[0].0, ANARI_SEVERITY_WARNING);
    assert!(
        reversed[0].2.contains("reversed mapping"),
        "{}",
        reversed[0].2
    );
    release_all(dev, &[volume, flat, cell_data, unusable, empty, field]);
    release_device(lib, dev);
}
