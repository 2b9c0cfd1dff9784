//! Samplers image3D and primitive (ANARI_KHR_SAMPLER_IMAGE3D, ANARI_KHR_SAMPLER_PRIMITIVE):
//! texel values read back through the albedo channel, and bad input reported by the status
//! callback.
mod common;
use common::*;

/// A unit quad [0,1]² at z = 0 seen head-on by an orthographic camera that frames it exactly, so
/// pixel (x, y) of a w×h frame shows the quad point ((x+½)/w, (y+½)/h). Triangle 0 is the lower
/// left half (vertices 0, 1, 2), triangle 1 the upper right (2, 1, 3).
struct QuadScene {
    lib: ANARILibrary,
    dev: ANARIDevice,
    geometry: ANARIGeometry,
}

const CORNERS: [[f32; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [1.0, 1.0, 0.0],
];

impl QuadScene {
    /// `attribute0` holds one value per corner (in `CORNERS` order), interpolated over the quad.
    fn new(log: &Log, attribute0: [[f32; 3]; 4]) -> QuadScene {
        let (lib, dev) = device_with_log(log);
        let geometry = anariNewGeometry(dev, c("triangle").as_ptr());
        let positions = array1d(dev, ANARI_FLOAT32_VEC3, &CORNERS);
        let indices = array1d(dev, ANARI_UINT32_VEC3, &[[0u32, 1, 2], [2, 1, 3]]);
        let attribute = array1d(dev, ANARI_FLOAT32_VEC3, &attribute0);
        set_object(dev, geometry, "vertex.position", ANARI_ARRAY1D, positions);
        set_object(dev, geometry, "primitive.index", ANARI_ARRAY1D, indices);
        set_object(dev, geometry, "vertex.attribute0", ANARI_ARRAY1D, attribute);
        commit(dev, geometry);
        release_all(dev, &[positions, indices, attribute]);
        QuadScene { lib, dev, geometry }
    }

    /// The albedo (the sampler's value) and primitive id of every pixel of a `size` frame with
    /// the quad coloured by `sampler`.
    fn render(&self, sampler: ANARISampler, size: [u32; 2]) -> (Vec<[f32; 3]>, Vec<u32>) {
        let dev = self.dev;
        let material = anariNewMaterial(dev, c("matte").as_ptr());
        set_object(dev, material, "color", ANARI_SAMPLER, sampler);
        commit(dev, material);
        let surface = surface_of(dev, self.geometry, material);
        let world = world_of(dev, &[surface]);
        // The 1×1 view (aspect 1) stretches over any frame size, so pixels need not be square.
        let camera = orthographic_camera(dev, [0.5, 0.5, 1.0], 1.0);
        let renderer = plain_renderer(dev, "default");
        let frame = frame_for(dev, world, camera, renderer, size);
        add_channel(dev, frame, "channel.albedo", ANARI_FLOAT32_VEC3);
        render_and_wait(dev, frame);
        let (albedo, w, h) = read_channel::<[f32; 3]>(dev, frame, "channel.albedo");
        let (ids, _, _) = read_channel::<u32>(dev, frame, "channel.primitiveId");
        assert_eq!((w, h), (size[0], size[1]));
        release_all(dev, &[material, surface, world, camera, renderer, frame]);
        (albedo, ids)
    }
}

impl Drop for QuadScene {
    fn drop(&mut self) {
        anariRelease(self.dev, self.geometry);
        release_device(self.lib, self.dev);
    }
}

/// The 2×2×2 texture whose texel (i, j, k) is (i·j·k, j, k): trilinear filtering makes the red
/// channel the product of the three axis weights, so every axis shows in it.
fn product_texture(dev: ANARIDevice) -> ANARIArray3D {
    let mut texels = Vec::new();
    for k in 0..2 {
        for j in 0..2 {
            for i in 0..2 {
                texels.push([(i * j * k) as f32, j as f32, k as f32]);
            }
        }
    }
    array3d(dev, ANARI_FLOAT32_VEC3, &texels, [2, 2, 2])
}

fn image3d(dev: ANARIDevice, image: ANARIArray3D, filter: &str) -> ANARISampler {
    let sampler = anariNewSampler(dev, c("image3D").as_ptr());
    set_object(dev, sampler, "image", ANARI_ARRAY3D, image);
    set_string(dev, sampler, "filter", filter);
    sampler
}

/// attribute0 = (x, y, z) over the quad with a constant third coordinate.
fn planar_coordinates(z: f32) -> [[f32; 3]; 4] {
    CORNERS.map(|[x, y, _]| [x, y, z])
}

#[test]
fn image3d_filters_trilinearly_or_to_the_nearest_texel() {
    let log = Log::new();
    let scene = QuadScene::new(&log, planar_coordinates(0.375));
    let dev = scene.dev;
    let image = product_texture(dev);
    // 4×4 pixels: centres at 0.125, 0.375, 0.625, 0.875 on both axes; texel centres at 0.25 and
    // 0.75, so the linear weights of the upper texel are 0, 0.25, 0.75, 1 (and 0.25 along z).
    let weight = [0.0f32, 0.25, 0.75, 1.0];
    let linear = image3d(dev, image, "linear");
    commit(dev, linear);
    let (albedo, _) = scene.render(linear, [4, 4]);
    for y in 0..4 {
        for x in 0..4 {
            let expected = [weight[x] * weight[y] * 0.25, weight[y], 0.25];
            assert_near(albedo[y * 4 + x], expected, &format!("linear ({x}, {y})"));
        }
    }
    let nearest = image3d(dev, image, "nearest");
    commit(dev, nearest);
    let (albedo, _) = scene.render(nearest, [4, 4]);
    for y in 0..4 {
        for x in 0..4 {
            // z = 0.375 lies in texel 0, so the red product is always 0.
            let j = (y >= 2) as u32 as f32;
            assert_near(
                albedo[y * 4 + x],
                [0.0, j, 0.0],
                &format!("nearest ({x}, {y})"),
            );
        }
    }
    release_all(dev, &[image, linear, nearest]);
    assert!(log.errors().is_empty());
}

#[test]
fn image3d_wraps_each_axis_by_its_own_mode() {
    // Along the tested axis the coordinate runs from −0.5 to 1.5 over the quad's width, so the
    // 8 pixel columns fall in texels −2 … 5 of a 4-texel axis (nearest filtering).
    let expected = [
        ("clampToEdge", [0, 0, 0, 1, 2, 3, 3, 3]),
        ("repeat", [2, 3, 0, 1, 2, 3, 0, 1]),
        ("mirrorRepeat", [1, 0, 0, 1, 2, 3, 3, 2]),
    ];
    for axis in 0..3 {
        let coordinates = CORNERS.map(|[x, _, _]| {
            let mut c = [0.5f32; 3];
            c[axis] = 2.0 * x - 0.5;
            c
        });
        let log = Log::new();
        let scene = QuadScene::new(&log, coordinates);
        let dev = scene.dev;
        let mut size = [1u64; 3];
        size[axis] = 4;
        let texels: Vec<[f32; 3]> = (0..4).map(|t| [t as f32 / 3.0, 0.0, 1.0]).collect();
        let image = array3d(dev, ANARI_FLOAT32_VEC3, &texels, size);
        for (mode, texel) in expected {
            let sampler = image3d(dev, image, "nearest");
            // The other two axes get the other modes: with one texel they must not matter.
            for (k, name) in ["wrapMode1", "wrapMode2", "wrapMode3"].iter().enumerate() {
                let other = if k == axis { mode } else { "repeat" };
                set_string(dev, sampler, name, other);
            }
            commit(dev, sampler);
            let (albedo, _) = scene.render(sampler, [8, 1]);
            for (x, t) in texel.iter().enumerate() {
                let what = format!("axis {axis} {mode} column {x}");
                assert_near(albedo[x], [*t as f32 / 3.0, 0.0, 1.0], &what);
            }
            anariRelease(dev, sampler);
        }
        anariRelease(dev, image);
        assert!(log.errors().is_empty());
    }
}

#[test]
fn image3d_applies_input_and_output_transforms() {
    let log = Log::new();
    let scene = QuadScene::new(&log, planar_coordinates(0.25));
    let dev = scene.dev;
    let image = product_texture(dev);
    let sampler = image3d(dev, image, "nearest");
    // Column-major: swaps the first and third coordinates.
    #[rustfmt::skip]
    let swap_x_z: [f32; 16] = [
        0.0, 0.0, 1.0, 0.0,
        0.0, 1.0, 0.0, 0.0,
        1.0, 0.0, 0.0, 0.0,
        0.0, 0.0, 0.0, 1.0,
    ];
    let half: [f32; 16] = [
        0.5, 0.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0, 1.0,
    ];
    set(dev, sampler, "inTransform", ANARI_FLOAT32_MAT4, &swap_x_z);
    set(
        dev,
        sampler,
        "inOffset",
        ANARI_FLOAT32_VEC4,
        &[0.5f32, 0.0, 0.0, 0.0],
    );
    set(dev, sampler, "outTransform", ANARI_FLOAT32_MAT4, &half);
    set(
        dev,
        sampler,
        "outOffset",
        ANARI_FLOAT32_VEC4,
        &[0.25f32, 0.0, 0.1, 0.0],
    );
    commit(dev, sampler);
    let (albedo, _) = scene.render(sampler, [4, 4]);
    // Pixel (x, 3) reads texel coordinate (0.25 + 0.5, 0.875, (x+½)/4): texel (1, 1, x ≥ 2),
    // value (k, 1, k), halved, plus the offset.
    for x in 0..4 {
        let k = (x >= 2) as u32 as f32;
        let expected = [0.5 * k + 0.25, 0.5, 0.5 * k + 0.1];
        assert_near(albedo[12 + x], expected, &format!("column {x}"));
    }
    release_all(dev, &[image, sampler]);
    assert!(log.errors().is_empty());
}

fn primitive_sampler(dev: ANARIDevice, values: ANARIArray1D) -> ANARISampler {
    let sampler = anariNewSampler(dev, c("primitive").as_ptr());
    set_object(dev, sampler, "array", ANARI_ARRAY1D, values);
    sampler
}

#[test]
fn the_primitive_sampler_colours_each_primitive_from_its_offset_index() {
    let log = Log::new();
    let scene = QuadScene::new(&log, planar_coordinates(0.0));
    let dev = scene.dev;
    let red = [1.0f32, 0.0, 0.0];
    let green = [0.0f32, 1.0, 0.0];
    let blue = [0.0f32, 0.0, 1.0];
    let values = array1d(dev, ANARI_FLOAT32_VEC3, &[red, green, blue]);
    // Pixel (0, 0) lies on triangle 0 and pixel (3, 3) on triangle 1; past the array's end the
    // value is the attribute default (0, 0, 0, 1).
    let cases: [(Option<u64>, [f32; 3], [f32; 3]); 4] = [
        (None, red, green),
        (Some(1), green, blue),
        (Some(2), blue, [0.0; 3]),
        (Some(u64::MAX), [0.0; 3], [0.0; 3]),
    ];
    for (offset, first, second) in cases {
        let sampler = primitive_sampler(dev, values);
        if let Some(offset) = offset {
            set(dev, sampler, "inOffset", ANARI_UINT64, &offset);
        }
        commit(dev, sampler);
        let (albedo, ids) = scene.render(sampler, [4, 4]);
        assert_eq!((ids[0], ids[15]), (0, 1));
        assert_near(albedo[0], first, &format!("offset {offset:?}, primitive 0"));
        assert_near(
            albedo[15],
            second,
            &format!("offset {offset:?}, primitive 1"),
        );
        anariRelease(dev, sampler);
    }
    // A UINT32 offset and one-component values: (v, 0, 0).
    let scalars = array1d(dev, ANARI_FLOAT32, &[0.25f32, 0.5, 0.75]);
    let sampler = primitive_sampler(dev, scalars);
    set(dev, sampler, "inOffset", ANARI_UINT32, &1u32);
    commit(dev, sampler);
    let (albedo, _) = scene.render(sampler, [4, 4]);
    assert_near(albedo[0], [0.5, 0.0, 0.0], "UINT32 offset, primitive 0");
    assert_near(albedo[15], [0.75, 0.0, 0.0], "UINT32 offset, primitive 1");
    release_all(dev, &[values, scalars, sampler]);
    assert!(log.errors().is_empty());
}

/// The errors logged, as (code, text), each required to mention every word of `words`.
fn expect_error(log: &Log, words: &[&str]) {
    let errors = log.errors();
    assert!(
        errors
            .iter()
            .any(|(code, text)| *code == ANARI_STATUS_INVALID_ARGUMENT
                && words.iter().all(|w| text.contains(w))),
        "no error mentioning {words:?} in {errors:?}"
    );
}

#[test]
fn bad_sampler_input_is_reported_and_the_material_falls_back() {
    let log = Log::new();
    let scene = QuadScene::new(&log, planar_coordinates(0.5));
    let dev = scene.dev;
    // A 2D array where image3D needs a 3D one: refused at anariSetParameter.
    let flat = unfilled_array2d(dev, ANARI_FLOAT32_VEC3, [2, 2]);
    let sampler = anariNewSampler(dev, c("image3D").as_ptr());
    set_object(dev, sampler, "image", ANARI_ARRAY2D, flat);
    expect_error(&log, &["anariSetParameter", "'image'", "ANARI_ARRAY3D"]);
    // Declaring the 2D array as ANARI_ARRAY3D does not get it through either.
    set_object(dev, sampler, "image", ANARI_ARRAY3D, flat);
    expect_error(&log, &["'image'", "ANARI_ARRAY3D"]);
    // Committed without an image: reported, and the matte colour keeps its default 0.8.
    commit(dev, sampler);
    expect_error(
        &log,
        &["anariCommitParameters", "image3D", "'image'", "not set"],
    );
    let (albedo, _) = scene.render(sampler, [2, 2]);
    assert_near(albedo[0], [0.8; 3], "sampler without image");
    log.take();

    // Primitive sampler: integer elements, a non-integer offset and no array at all.
    let integers = array1d(dev, ANARI_INT32, &[1i32, 2]);
    let primitive = anariNewSampler(dev, c("primitive").as_ptr());
    set_object(dev, primitive, "array", ANARI_ARRAY1D, integers);
    expect_error(&log, &["'array'", "ANARI_INT32"]);
    set(dev, primitive, "inOffset", ANARI_FLOAT32, &1.0f32);
    expect_error(&log, &["'inOffset'", "ANARI_UINT64"]);
    commit(dev, primitive);
    expect_error(&log, &["anariCommitParameters", "primitive", "'array'"]);
    let (albedo, _) = scene.render(primitive, [2, 2]);
    assert_near(albedo[0], [0.8; 3], "primitive sampler without array");
    release_all(dev, &[flat, sampler, integers, primitive]);
}

#[test]
fn the_new_samplers_and_their_extensions_are_advertised() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let subtypes = c_strings(anariGetObjectSubtypes(dev, ANARI_SAMPLER) as *const _);
    for subtype in ["image1D", "image2D", "image3D", "primitive", "transform"] {
        assert!(subtypes.iter().any(|s| s == subtype), "{subtypes:?}");
    }
    let extensions = device_extensions(dev);
    for extension in ["ANARI_KHR_SAMPLER_IMAGE3D", "ANARI_KHR_SAMPLER_PRIMITIVE"] {
        assert!(extensions.iter().any(|e| e == extension), "{extensions:?}");
    }
    release_device(lib, dev);
}

const RED: [f32; 4] = [1.0, 0.0, 0.0, 1.0];
const GREEN: [f32; 4] = [0.0, 1.0, 0.0, 1.0];
const BLUE: [f32; 4] = [0.0, 0.0, 1.0, 1.0];
const HALF_WHITE: [f32; 4] = [1.0, 1.0, 1.0, 0.5];

/// The colour channel of a `size` frame of `world` (None: an empty world) seen by the
/// orthographic camera of `QuadScene`, with a 2×2 background image: red, green along the first
/// row, blue, half-transparent white along the second.
fn render_over_background(
    dev: ANARIDevice,
    world: Option<ANARIWorld>,
    size: [u32; 2],
) -> Vec<[f32; 4]> {
    let image = array2d(
        dev,
        ANARI_FLOAT32_VEC4,
        &[RED, GREEN, BLUE, HALF_WHITE],
        [2, 2],
    );
    let renderer = anariNewRenderer(dev, c("default").as_ptr());
    set_object(dev, renderer, "background", ANARI_ARRAY2D, image);
    commit(dev, renderer);
    let world = world.unwrap_or_else(|| world_of(dev, &[]));
    let camera = orthographic_camera(dev, [0.5, 0.5, 1.0], 1.0);
    let frame = frame_for(dev, world, camera, renderer, size);
    let (color, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    release_all(dev, &[image, renderer, world, camera, frame]);
    color
}

#[test]
fn a_background_image_stretches_over_the_frame() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // 5×5 pixels over 2×2 texels: the corner pixels lie outside the texel centres (clamped),
    // the centre pixel is the mean of all four texels.
    let color = render_over_background(dev, None, [5, 5]);
    assert_near(color[0], RED, "bottom left");
    assert_near(color[4], GREEN, "bottom right");
    assert_near(color[20], BLUE, "top left");
    assert_near(color[24], HALF_WHITE, "top right");
    assert_near(color[12], [0.5, 0.5, 0.5, 0.875], "centre");
    // Pixel (1, 2): x = 0.3 lies 0.1 texel past the first texel centre, y = 0.5 halfway.
    assert_near(color[11], [0.5, 0.1, 0.5, 0.975], "pixel (1, 2)");
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn a_see_through_surface_shows_the_background_image_behind_it() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // A black matte quad of opacity 0.5 (blend) over the whole view, no light: each pixel is
    // half the background behind it.
    let geometry = anariNewGeometry(dev, c("triangle").as_ptr());
    let positions = array1d(dev, ANARI_FLOAT32_VEC3, &CORNERS);
    let indices = array1d(dev, ANARI_UINT32_VEC3, &[[0u32, 1, 2], [2, 1, 3]]);
    set_object(dev, geometry, "vertex.position", ANARI_ARRAY1D, positions);
    set_object(dev, geometry, "primitive.index", ANARI_ARRAY1D, indices);
    commit(dev, geometry);
    let material = anariNewMaterial(dev, c("matte").as_ptr());
    set(dev, material, "color", ANARI_FLOAT32_VEC3, &[0.0f32; 3]);
    set(dev, material, "opacity", ANARI_FLOAT32, &0.5f32);
    set_string(dev, material, "alphaMode", "blend");
    commit(dev, material);
    let surface = anariNewSurface(dev);
    set_object(dev, surface, "geometry", ANARI_GEOMETRY, geometry);
    set_object(dev, surface, "material", ANARI_MATERIAL, material);
    commit(dev, surface);
    let world = world_of(dev, &[surface]);
    let color = render_over_background(dev, Some(world), [5, 5]);
    let half = |c: [f32; 4]| [c[0] * 0.5, c[1] * 0.5, c[2] * 0.5, 1.0];
    assert_near(color[0], half(RED), "bottom left");
    assert_near(color[4], half(GREEN), "bottom right");
    assert_near(color[20], half(BLUE), "top left");
    assert_near(color[12], [0.25, 0.25, 0.25, 1.0], "centre");
    release_all(dev, &[geometry, positions, indices, material, surface]);
    release_device(lib, dev);
    assert!(log.errors().is_empty());
}

#[test]
fn bad_background_images_are_reported() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let renderer = anariNewRenderer(dev, c("default").as_ptr());
    let row = array1d(dev, ANARI_FLOAT32_VEC4, &[RED, GREEN]);
    set_object(dev, renderer, "background", ANARI_ARRAY1D, row);
    expect_error(&log, &["'background'", "ANARI_ARRAY1D", "ANARI_ARRAY2D"]);
    let integers = unfilled_array2d(dev, ANARI_INT32, [2, 2]);
    set_object(dev, renderer, "background", ANARI_ARRAY2D, integers);
    expect_error(&log, &["'background'", "ANARI_INT32"]);
    let empty = unfilled_array2d(dev, ANARI_FLOAT32_VEC4, [0, 3]);
    set_object(dev, renderer, "background", ANARI_ARRAY2D, empty);
    commit(dev, renderer);
    expect_error(
        &log,
        &["anariCommitParameters", "'background'", "no texels"],
    );
    release_all(dev, &[renderer, row, integers, empty]);
    release_device(lib, dev);
}

#[test]
fn the_normal_channel_maps_as_float32_or_fixed16() {
    let log = Log::new();
    let scene = QuadScene::new(&log, planar_coordinates(0.0));
    let dev = scene.dev;
    let material = anariNewMaterial(dev, c("matte").as_ptr());
    commit(dev, material);
    let surface = surface_of(dev, scene.geometry, material);
    let world = world_of(dev, &[surface]);
    // Looking down −z from above the quad's left edge: the right half of the frame sees the
    // quad (normal +z, towards the camera), the left half nothing.
    let camera = orthographic_camera(dev, [0.0, 0.5, 1.0], 1.0);
    let renderer = plain_renderer(dev, "default");
    let frame = frame_for(dev, world, camera, renderer, [4, 4]);
    add_channel(dev, frame, "channel.normal", ANARI_FIXED16_VEC3);
    let (fixed, _, _) = render_channel::<[i16; 3]>(dev, frame, "channel.normal");
    assert_eq!(fixed[4 * 2 + 2], [0, 0, 32767], "quad");
    assert_eq!(fixed[4 * 2 + 1], [0, 0, 0], "background");
    add_channel(dev, frame, "channel.normal", ANARI_FLOAT32_VEC3);
    let (float, _, _) = render_channel::<[f32; 3]>(dev, frame, "channel.normal");
    assert_eq!(float[4 * 2 + 2], [0.0, 0.0, 1.0], "quad");
    assert_eq!(float[4 * 2 + 1], [0.0, 0.0, 0.0], "background");
    release_all(dev, &[material, surface, world, camera, renderer, frame]);
    assert!(log.errors().is_empty());
}

#[test]
fn the_background_image_and_normal_channel_extensions_are_advertised() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let extensions = device_extensions(dev);
    for extension in [
        "ANARI_KHR_RENDERER_BACKGROUND_IMAGE",
        "ANARI_KHR_FRAME_CHANNEL_NORMAL",
        "ANARI_KHR_FRAME_CHANNEL_ALBEDO",
    ] {
        assert!(extensions.iter().any(|e| e == extension), "{extensions:?}");
    }
    release_device(lib, dev);
}
