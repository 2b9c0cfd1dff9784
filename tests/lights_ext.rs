//! KHR_LIGHT_DIRECTIONAL / POINT / SPOT: power and radiance as alternative strengths, soft
//! shadows from a directional light's angularDiameter and a point light's radius, and bad
//! values ignored. Scenes are seen from straight above by an orthographic camera, so pixel
//! (i, j) of the 32×32 frame sees the floor point x = −1 + (i+½)/16, z = 1 − (j+½)/16.
mod common;
use common::*;
use std::f32::consts::PI;

const SIZE: u32 = 32;

fn quad(dev: ANARIDevice, half: f32, y: f32) -> ANARIGeometry {
    let g = anariNewGeometry(dev, c("triangle").as_ptr());
    let positions = [
        [-half, y, -half],
        [half, y, half],
        [half, y, -half],
        [-half, y, -half],
        [-half, y, half],
        [half, y, half],
    ];
    let a = array1d(dev, ANARI_FLOAT32_VEC3, &positions);
    set_object(dev, g, "vertex.position", ANARI_ARRAY1D, a);
    commit(dev, g);
    anariRelease(dev, a);
    g
}

/// A device with a white floor (y = 0) and, optionally, a black square blocker of half-size
/// 0.25 at y = 1 (seen from above, it covers the floor pixels under it, which are umbra).
struct Scene {
    lib: ANARILibrary,
    dev: ANARIDevice,
    world: ANARIWorld,
    objects: Vec<ANARIObject>,
}

impl Scene {
    fn new(log: &Log, blocker: bool) -> Scene {
        let (lib, dev) = device_with_log(log);
        let floor = quad(dev, 2.0, 0.0);
        let floor_surface = matte_surface(dev, floor, [1.0, 1.0, 1.0]);
        let mut objects = vec![floor, floor_surface];
        let mut surfaces = vec![floor_surface];
        if blocker {
            let square = quad(dev, 0.25, 1.0);
            let surface = matte_surface(dev, square, [1.0, 1.0, 1.0]);
            // The blocker is seen from above; make it black so only the floor shows light.
            let material = anariNewMaterial(dev, c("matte").as_ptr());
            set(
                dev,
                material,
                "color",
                ANARI_FLOAT32_VEC3,
                &[0.0f32, 0.0, 0.0],
            );
            commit(dev, material);
            set_object(dev, surface, "material", ANARI_MATERIAL, material);
            commit(dev, surface);
            objects.extend([square, surface, material]);
            surfaces.push(surface);
        }
        let world = world_of(dev, &surfaces);
        Scene {
            lib,
            dev,
            world,
            objects,
        }
    }

    fn light(
        &self,
        subtype: &str,
        floats: &[(&str, f32)],
        vectors: &[(&str, [f32; 3])],
    ) -> ANARILight {
        let dev = self.dev;
        let light = anariNewLight(dev, c(subtype).as_ptr());
        for (name, value) in floats {
            set(dev, light, name, ANARI_FLOAT32, value);
        }
        for (name, value) in vectors {
            set(dev, light, name, ANARI_FLOAT32_VEC3, value);
        }
        // The camera looks at the floor past the lights: only their light is measured.
        set(dev, light, "visible", ANARI_BOOL, &0u8);
        commit(dev, light);
        light
    }

    /// Renders the world lit by `light` `frames` times with accumulation; the red channel.
    fn render(&self, light: ANARILight, frames: u32, pixel_samples: i32) -> Vec<f32> {
        let dev = self.dev;
        let lights = object_array(dev, ANARI_LIGHT, &[light]);
        set_object(dev, self.world, "light", ANARI_ARRAY1D, lights);
        commit(dev, self.world);
        let camera = anariNewCamera(dev, c("orthographic").as_ptr());
        set(
            dev,
            camera,
            "position",
            ANARI_FLOAT32_VEC3,
            &[0.0f32, 3.0, 0.0],
        );
        set(
            dev,
            camera,
            "direction",
            ANARI_FLOAT32_VEC3,
            &[0.0f32, -1.0, 0.0],
        );
        set(dev, camera, "up", ANARI_FLOAT32_VEC3, &[0.0f32, 0.0, -1.0]);
        set(dev, camera, "height", ANARI_FLOAT32, &2.0f32);
        set(dev, camera, "aspect", ANARI_FLOAT32, &1.0f32);
        commit(dev, camera);
        let renderer = anariNewRenderer(dev, c("default").as_ptr());
        set(dev, renderer, "ambientRadiance", ANARI_FLOAT32, &0.0f32);
        set(dev, renderer, "pixelSamples", ANARI_INT32, &pixel_samples);
        commit(dev, renderer);
        let frame = frame_for(dev, self.world, camera, renderer, [SIZE, SIZE]);
        set(dev, frame, "accumulation", ANARI_BOOL, &1u8);
        commit(dev, frame);
        let mut color = Vec::new();
        for _ in 0..frames {
            color = render_channel::<[f32; 4]>(dev, frame, "channel.color").0;
        }
        release_all(dev, &[lights, camera, renderer, frame]);
        color.iter().map(|p| p[0]).collect()
    }

    fn finish(self, log: &Log) {
        release_all(self.dev, &self.objects);
        anariRelease(self.dev, self.world);
        anariRelease(self.dev, self.dev);
        anariUnloadLibrary(self.lib);
        let errors = log.errors();
        assert!(errors.is_empty(), "{errors:?}");
    }
}

/// The floor point pixel (i, j) sees.
fn floor_point(i: u32, j: u32) -> (f32, f32) {
    let x = -1.0 + (i as f32 + 0.5) / 16.0;
    let z = 1.0 - (j as f32 + 0.5) / 16.0;
    (x, z)
}

fn pixel(image: &[f32], i: u32, j: u32) -> f32 {
    image[(j * SIZE + i) as usize]
}

/// Bit-identical images (reported by the first differing pixel, not the whole image).
fn assert_same(a: &[f32], b: &[f32], what: &str) {
    assert_eq!(a.len(), b.len());
    if let Some(k) = (0..a.len()).find(|&k| a[k].to_bits() != b[k].to_bits()) {
        let differing = (0..a.len()).filter(|&k| a[k] != b[k]).count();
        panic!(
            "{what}: {differing} pixels differ, first {k}: {} vs {}",
            a[k], b[k]
        );
    }
}

fn assert_close(a: &[f32], b: &[f32], tolerance: f32) {
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        assert!(
            (x - y).abs() <= tolerance * y.abs().max(1e-3),
            "pixel {k}: {x} vs {y}"
        );
    }
}

const DOWN: [f32; 3] = [0.0, -1.0, 0.0];

#[test]
fn point_power_and_spot_power_light_like_the_matching_intensity() {
    let log = Log::new();
    let scene = Scene::new(&log, false);
    let position = ("position", [0.3f32, 1.5, -0.2]);
    let by_intensity = scene.light("point", &[("intensity", 2.0)], &[position]);
    let by_power = scene.light("point", &[("power", 8.0 * PI)], &[position]);
    // power overrides intensity.
    let both = scene.light(
        "point",
        &[("intensity", 5.0), ("power", 8.0 * PI)],
        &[position],
    );
    let reference = scene.render(by_intensity, 1, 1);
    assert!(pixel(&reference, 16, 16) > 0.1);
    assert_close(&scene.render(by_power, 1, 1), &reference, 1e-5);
    assert_close(&scene.render(both, 1, 1), &reference, 1e-5);

    // Spot: power spreads over the cone, weighted by the smooth falloff (smooth in cos θ, so
    // the falloff band counts half): Ω = 2π(1 − (cos inner + cos outer)/2).
    let (opening, falloff) = (1.2f32, 0.3f32);
    let cos_outer = (opening as f64 / 2.0).cos();
    let cos_inner = (opening as f64 / 2.0 - falloff as f64).cos();
    let solid_angle = 2.0 * std::f64::consts::PI * (1.0 - 0.5 * (cos_inner + cos_outer));
    let spot = |strength: (&str, f32)| {
        scene.light(
            "spot",
            &[
                ("openingAngle", opening),
                ("falloffAngle", falloff),
                strength,
            ],
            &[("position", [0.0, 1.5, 0.0]), ("direction", DOWN)],
        )
    };
    let by_intensity = spot(("intensity", 3.0));
    let by_power = spot(("power", (3.0 * solid_angle) as f32));
    let reference = scene.render(by_intensity, 1, 1);
    // Lit under the spot, dark outside its cone (tan 0.6 × 1.5 ≈ 1.03 from the axis).
    assert!(pixel(&reference, 16, 16) > 0.1);
    assert_eq!(pixel(&reference, 0, 0), 0.0);
    assert_close(&scene.render(by_power, 1, 1), &reference, 1e-5);
    release_all(scene.dev, &[by_intensity, by_power, both]);
    scene.finish(&log);
}

#[test]
fn directional_radiance_is_irradiance_over_the_disks_projected_solid_angle() {
    let log = Log::new();
    let scene = Scene::new(&log, false);
    let diameter = 0.2f32;
    let radiance = 50.0f32;
    // A disk of radiance L and angular radius θ gives a facing surface L·π·sin²θ.
    let irradiance = radiance * PI * (diameter / 2.0).sin().powi(2);
    let direction = [0.0f32, -1.0, -0.3];
    let by_irradiance = scene.light(
        "directional",
        &[("angularDiameter", diameter), ("irradiance", irradiance)],
        &[("direction", direction)],
    );
    let by_radiance = scene.light(
        "directional",
        &[
            ("angularDiameter", diameter),
            ("radiance", radiance),
            ("irradiance", 7.0),
        ],
        &[("direction", direction)],
    );
    let reference = scene.render(by_irradiance, 16, 16);
    assert_close(&scene.render(by_radiance, 16, 16), &reference, 1e-5);
    // And it is that irradiance: albedo 1/π × E × cos(light, normal), up to sampling noise.
    let cos = 1.0 / (1.0f32 + 0.09).sqrt();
    let expected = irradiance / PI * cos;
    assert!(
        (pixel(&reference, 16, 16) - expected).abs() < 1e-3 * expected,
        "{} vs {expected}",
        pixel(&reference, 16, 16)
    );
    release_all(scene.dev, &[by_irradiance, by_radiance]);
    scene.finish(&log);
}

/// Checks a soft shadow against the hard one: deep inside the umbra dark, in the penumbra
/// strictly between, and lit pixels as lit as with the hard shadow.
fn check_penumbra(
    soft: &[f32],
    hard: &[f32],
    umbra: impl Fn(f32, f32) -> bool,
    penumbra: impl Fn(f32, f32) -> bool,
    lit: impl Fn(f32, f32) -> bool,
    tolerance: f32,
) -> (u32, u32, u32) {
    let mut counts = (0, 0, 0);
    for j in 0..SIZE {
        for i in 0..SIZE {
            let (x, z) = floor_point(i, j);
            let (s, h) = (pixel(soft, i, j), pixel(hard, i, j));
            if umbra(x, z) {
                counts.0 += 1;
                assert_eq!(s, 0.0, "umbra pixel {i},{j} at {x},{z}");
            } else if penumbra(x, z) {
                counts.1 += 1;
                assert!(
                    s > 0.02 * h && s < 0.98 * h,
                    "penumbra pixel {i},{j} at {x},{z}: {s} (lit {h})"
                );
            } else if lit(x, z) {
                counts.2 += 1;
                assert!(
                    h > 0.0,
                    "lit pixel {i},{j} at {x},{z} is dark with a hard shadow"
                );
                assert!(
                    (s - h).abs() <= tolerance * h,
                    "lit pixel {i},{j} at {x},{z}: {s} vs hard {h}"
                );
            }
        }
    }
    counts
}

#[test]
fn a_directional_disk_light_casts_a_penumbra_that_converges() {
    let log = Log::new();
    let scene = Scene::new(&log, true);
    let light = |diameter: Option<f32>| {
        let mut floats = vec![("irradiance", PI)];
        floats.extend(diameter.map(|d| ("angularDiameter", d)));
        scene.light("directional", &floats, &[("direction", DOWN)])
    };
    let (unset, zero, soft) = (light(None), light(Some(0.0)), light(Some(0.3)));
    // angularDiameter 0 is the hard shadow, bit for bit, for one sample and accumulated.
    assert_same(
        &scene.render(zero, 1, 1),
        &scene.render(unset, 1, 1),
        "1 sample",
    );
    let hard = scene.render(unset, 16, 4);
    assert_same(&scene.render(zero, 16, 4), &hard, "accumulated");
    // The blocker (half-size 0.25, 1 above the floor) shadows |x|,|z| < 0.25 with a hard
    // light; a disk of angular radius 0.15 widens that edge by ±tan 0.15 ≈ 0.151. Pixels are
    // 1/16 wide, so a margin of more than half a pixel keeps whole pixels inside a region.
    let soft_image = scene.render(soft, 16, 4);
    let margin = 0.1511 + 0.04;
    let counts = check_penumbra(
        &soft_image,
        &hard,
        |x, z| x.abs().max(z.abs()) < 0.25 - margin,
        // Just outside the blocker's footprint along an axis: part of the disk is hidden.
        |x, z| z.abs() < 0.1 && (x.abs() - 0.28).abs() < 0.05,
        |x, z| x.abs().max(z.abs()) > 0.25 + margin,
        1e-3,
    );
    assert!(
        counts.0 >= 4 && counts.1 >= 8 && counts.2 > 500,
        "{counts:?}"
    );
    // Hard lit pixels are 1 (albedo 1 × irradiance π / π).
    assert_eq!(pixel(&hard, 31, 31), 1.0);
    release_all(scene.dev, &[unset, zero, soft]);
    scene.finish(&log);
}

#[test]
fn a_sphere_light_casts_a_penumbra_and_radius_zero_is_the_point_light() {
    let log = Log::new();
    let scene = Scene::new(&log, true);
    let light = |radius: Option<f32>| {
        let mut floats = vec![("intensity", 4.0)];
        floats.extend(radius.map(|r| ("radius", r)));
        scene.light("point", &floats, &[("position", [0.0, 2.0, 0.0])])
    };
    let (unset, zero, soft) = (light(None), light(Some(0.0)), light(Some(0.3)));
    assert_same(
        &scene.render(zero, 1, 1),
        &scene.render(unset, 1, 1),
        "1 sample",
    );
    let hard = scene.render(unset, 16, 4);
    assert_same(&scene.render(zero, 16, 4), &hard, "accumulated");
    // From (0, 2, 0) the blocker's edge at 0.25 projects to 0.5 on the floor; a sphere of
    // radius 0.3 blurs that over about 0.5 ± 0.33 (its silhouette seen past the edge).
    let soft_image = scene.render(soft, 16, 4);
    let counts = check_penumbra(
        &soft_image,
        &hard,
        |x, z| x.abs().max(z.abs()) < 0.1,
        |x, z| z.abs() < 0.1 && (x.abs() - 0.55).abs() < 0.06,
        |x, z| x.abs().max(z.abs()) > 0.9,
        5e-3,
    );
    assert!(
        counts.0 >= 4 && counts.1 >= 4 && counts.2 > 50,
        "{counts:?}"
    );
    // A sphere light's radiance sets its intensity: I = L·π·r².
    let by_radiance = scene.light(
        "point",
        &[
            ("radius", 0.3),
            ("radiance", 4.0 / (PI * 0.09)),
            ("intensity", 9.0),
        ],
        &[("position", [0.0, 2.0, 0.0])],
    );
    assert_close(&scene.render(by_radiance, 16, 4), &soft_image, 1e-4);
    release_all(scene.dev, &[unset, zero, soft, by_radiance]);
    scene.finish(&log);
}

#[test]
fn bad_strengths_and_sizes_are_ignored() {
    let log = Log::new();
    let scene = Scene::new(&log, true);
    let position = ("position", [0.0f32, 2.0, 0.0]);
    let good = scene.light("point", &[("intensity", 4.0)], &[position]);
    let reference = scene.render(good, 1, 1);
    for (name, value) in [
        ("power", -1.0),
        ("power", f32::NAN),
        ("radius", -0.5),
        ("radius", f32::NAN),
        ("radius", f32::INFINITY),
    ] {
        let bad = scene.light("point", &[("intensity", 4.0), (name, value)], &[position]);
        assert_same(
            &scene.render(bad, 1, 1),
            &reference,
            &format!("point {name} {value}"),
        );
        anariRelease(scene.dev, bad);
    }
    let good = scene.light("directional", &[], &[("direction", DOWN)]);
    let reference = scene.render(good, 1, 1);
    for value in [-0.1, f32::NAN, 4.0] {
        let bad = scene.light(
            "directional",
            &[("angularDiameter", value)],
            &[("direction", DOWN)],
        );
        assert_eq!(
            scene.render(bad, 1, 1),
            reference,
            "angularDiameter {value}"
        );
        anariRelease(scene.dev, bad);
    }
    let good = scene.light(
        "spot",
        &[],
        &[("position", [0.0, 2.0, 0.0]), ("direction", DOWN)],
    );
    let reference = scene.render(good, 1, 1);
    let bad = scene.light(
        "spot",
        &[("power", -3.0)],
        &[("position", [0.0, 2.0, 0.0]), ("direction", DOWN)],
    );
    assert_same(&scene.render(bad, 1, 1), &reference, "spot power");
    release_all(scene.dev, &[good, bad]);
    // What commit reports for them is checked in the test below.
    log.take();
    scene.finish(&log);
}

/// Bad values reach the application through the status callback at commit.
#[test]
fn bad_values_are_reported_through_the_status_callback() {
    let log = Log::new();
    let scene = Scene::new(&log, false);
    let bad = scene.light(
        "point",
        &[("power", -1.0), ("radius", f32::NAN)],
        &[("position", [0.0, 2.0, 0.0])],
    );
    let errors = log.errors();
    for name in ["'power'", "'radius'"] {
        assert!(
            errors
                .iter()
                .any(|(code, text)| *code == ANARI_STATUS_INVALID_ARGUMENT
                    && text.contains("light 'point'")
                    && text.contains(name)),
            "{name}: {errors:?}"
        );
    }
    anariRelease(scene.dev, bad);
    scene.finish(&log);
}

#[test]
fn unsupported_parameters_of_the_light_extensions_are_reported_as_such() {
    let log = Log::new();
    let scene = Scene::new(&log, false);
    let ring = anariNewLight(scene.dev, c("ring").as_ptr());
    set(scene.dev, ring, "c0", ANARI_FLOAT32, &0.5f32);
    set(scene.dev, ring, "colour", ANARI_FLOAT32, &0.5f32);
    let messages = log.take();
    let text_for = |name: &str| {
        messages
            .iter()
            .find(|(_, _, text)| text.contains(&format!("'{name}'")))
            .map(|(_, _, text)| text.clone())
            .unwrap_or_default()
    };
    let c0 = text_for("c0");
    assert!(
        c0.contains("ANARI_KHR_LIGHT_RING") && c0.contains("does not support"),
        "{c0}"
    );
    assert!(text_for("colour").contains("not a parameter of this object"));
    anariRelease(scene.dev, ring);
    scene.finish(&log);
}

#[test]
fn the_light_extensions_are_advertised() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let mut list: *const *const std::ffi::c_char = std::ptr::null();
    assert_eq!(
        anariGetProperty(
            dev,
            dev,
            c("extension").as_ptr(),
            ANARI_STRING_LIST,
            &mut list as *mut _ as _,
            8,
            ANARI_WAIT
        ),
        1
    );
    let mut extensions = Vec::new();
    // SAFETY: the device returns a NULL-terminated list of C strings.
    unsafe {
        let mut p = list;
        while !p.is_null() && !(*p).is_null() {
            extensions.push(std::ffi::CStr::from_ptr(*p).to_string_lossy().into_owned());
            p = p.add(1);
        }
    }
    for name in [
        "ANARI_KHR_LIGHT_DIRECTIONAL",
        "ANARI_KHR_LIGHT_POINT",
        "ANARI_KHR_LIGHT_SPOT",
        "ANARI_KHR_LIGHT_QUAD",
        "ANARI_KHR_LIGHT_HDRI",
        "ANARI_KHR_LIGHT_RING",
    ] {
        assert!(
            extensions.iter().any(|e| e == name),
            "{name} in {extensions:?}"
        );
    }
    anariRelease(dev, dev);
    anariUnloadLibrary(lib);
}

/// Irradiance at floor point (x, 0, z) (normal +y) from a diffuse polygon of radiance
/// `radiance` with `corners` (Lambert's formula: half the radiance times the sum over the edges
/// of the angle each subtends times the normal's share of that edge's plane).
fn polygon_irradiance(corners: &[[f64; 3]], x: f64, z: f64, radiance: f64) -> f64 {
    let to = |c: &[f64; 3]| {
        let v = [c[0] - x, c[1], c[2] - z];
        let length = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|component| component / length)
    };
    let mut sum = 0.0;
    for k in 0..corners.len() {
        let (a, b) = (to(&corners[k]), to(&corners[(k + 1) % corners.len()]));
        let cross = [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ];
        let sin = (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt();
        let cos = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        sum += sin.atan2(cos) * cross[1] / sin;
    }
    0.5 * radiance * sum.abs()
}

#[test]
fn a_quad_light_gives_the_irradiance_of_lamberts_polygon_formula() {
    let log = Log::new();
    let scene = Scene::new(&log, false);
    // A 0.5 m square 1 m above the floor, its front (edge1 × edge2) facing down.
    let (position, edge1, edge2) = (
        [-0.25f32, 1.0, -0.25],
        [0.5f32, 0.0, 0.0],
        [0.0f32, 0.0, 0.5],
    );
    let corners = [
        [-0.25, 1.0, -0.25],
        [0.25, 1.0, -0.25],
        [0.25, 1.0, 0.25],
        [-0.25, 1.0, 0.25],
    ];
    let quad_light = |floats: &[(&str, f32)], side: &str| {
        let light = scene.light(
            "quad",
            floats,
            &[("position", position), ("edge1", edge1), ("edge2", edge2)],
        );
        set_string(scene.dev, light, "side", side);
        commit(scene.dev, light);
        light
    };
    let front = quad_light(&[("radiance", 2.0)], "front");
    let image = scene.render(front, 4, 64);
    for (i, j) in [(16, 16), (8, 20), (2, 2), (30, 12), (16, 0)] {
        let (x, z) = floor_point(i, j);
        // A white matte floor: radiance albedo/π × irradiance.
        let expected =
            polygon_irradiance(&corners, f64::from(x), f64::from(z), 2.0) / std::f64::consts::PI;
        let got = f64::from(pixel(&image, i, j));
        assert!(
            (got - expected).abs() <= 0.02 * expected,
            "pixel ({i}, {j}) at ({x}, {z}): {got} vs {expected}"
        );
    }
    // Both sides light the floor as the front does; the back alone leaves it dark.
    let both = quad_light(&[("radiance", 2.0)], "both");
    assert_same(&scene.render(both, 4, 64), &image, "both sides");
    let back = quad_light(&[("radiance", 2.0)], "back");
    assert!(scene.render(back, 1, 4).iter().all(|v| *v == 0.0));
    // power = π·A·L per side and intensity = A·L give the same light.
    let area = 0.25f32;
    let by_power = quad_light(&[("power", PI * area * 2.0)], "front");
    assert_close(&scene.render(by_power, 4, 64), &image, 1e-5);
    let by_intensity = quad_light(&[("intensity", area * 2.0)], "front");
    assert_close(&scene.render(by_intensity, 4, 64), &image, 1e-5);
    release_all(scene.dev, &[front, both, back, by_power, by_intensity]);

    // Edges that span no area are reported.
    let flat = scene.light(
        "quad",
        &[],
        &[("edge1", [1.0, 0.0, 0.0]), ("edge2", [2.0, 0.0, 0.0])],
    );
    let errors = log.errors();
    assert!(
        errors
            .iter()
            .any(|e| e.1.contains("'edge1'") && e.1.contains("no area")),
        "{errors:?}"
    );
    anariRelease(scene.dev, flat);
    scene.finish(&log);
}

#[test]
fn an_hdri_light_gives_a_diffuse_floor_the_radiance_of_its_sky() {
    let log = Log::new();
    let scene = Scene::new(&log, false);
    let dev = scene.dev;
    let (width, height) = (16u64, 8u64);
    let sky = |bright_rows: u64| {
        let texels: Vec<[f32; 3]> = (0..width * height)
            .map(|k| {
                if k / width < bright_rows {
                    [0.5, 0.5, 0.5]
                } else {
                    [0.0; 3]
                }
            })
            .collect();
        array2d(dev, ANARI_FLOAT32_VEC3, &texels, [width, height])
    };
    let hdri = |image: ANARIArray2D, up: [f32; 3], scale: f32| {
        let light = scene.light(
            "hdri",
            &[("scale", scale)],
            &[("up", up), ("direction", [1.0, 0.0, 0.0])],
        );
        set_object(dev, light, "radiance", ANARI_ARRAY2D, image);
        commit(dev, light);
        light
    };
    let (uniform, upper_half) = (sky(height), sky(height / 2));
    // A uniform sky of radiance L: a white matte floor sees πL and shows L.
    let lit = hdri(uniform, [0.0, 1.0, 0.0], 1.0);
    let image = scene.render(lit, 16, 64);
    // Unbiased (the mean over the floor), and each pixel converged to a few per cent after
    // 1024 samples of the whole sphere.
    let mean = image.iter().sum::<f32>() / image.len() as f32;
    assert!((mean - 0.5).abs() < 0.0025, "mean {mean}");
    for (k, value) in image.iter().enumerate() {
        assert!((value - 0.5).abs() < 0.015, "pixel {k}: {value}");
    }
    // Only the sky above the floor lights it: the upper half alone gives the same, the same
    // half turned below the floor (up = −y) nothing.
    let above = hdri(upper_half, [0.0, 1.0, 0.0], 1.0);
    assert_close(&scene.render(above, 16, 64), &image, 0.04);
    let below = hdri(upper_half, [0.0, -1.0, 0.0], 1.0);
    assert!(scene.render(below, 1, 16).iter().all(|v| *v == 0.0));
    // scale multiplies the radiance.
    let doubled = hdri(uniform, [0.0, 1.0, 0.0], 2.0);
    let twice: Vec<f32> = image.iter().map(|v| 2.0 * v).collect();
    assert_close(&scene.render(doubled, 16, 64), &twice, 1e-5);
    release_all(dev, &[lit, above, below, doubled, uniform, upper_half]);

    // Without an image, or with up along direction, it is reported and emits nothing.
    let empty = scene.light("hdri", &[], &[]);
    let errors = log.errors();
    assert!(
        errors
            .iter()
            .any(|e| e.1.contains("hdri") && e.1.contains("'radiance'")),
        "{errors:?}"
    );
    anariRelease(dev, empty);
    scene.finish(&log);
}

#[test]
fn a_ring_light_is_a_spot_spread_over_its_ring() {
    let log = Log::new();
    let scene = Scene::new(&log, false);
    let dev = scene.dev;
    let (x, z) = floor_point(16, 16);
    let above = [x, 1.0, z];
    let spot_like = |subtype: &str, floats: &[(&str, f32)]| {
        let mut all = vec![("openingAngle", 2.0f32), ("falloffAngle", 0.2)];
        all.extend_from_slice(floats);
        scene.light(subtype, &all, &[("position", above), ("direction", DOWN)])
    };
    // Radius 0: the spot light, bit for bit (and power means what it means for the spot).
    let (ring, spot) = (
        spot_like("ring", &[("intensity", 3.0)]),
        spot_like("spot", &[("intensity", 3.0)]),
    );
    assert_same(
        &scene.render(ring, 1, 1),
        &scene.render(spot, 1, 1),
        "ring of radius 0",
    );
    let (ring_power, spot_power) = (
        spot_like("ring", &[("power", 5.0)]),
        spot_like("spot", &[("power", 5.0)]),
    );
    assert_same(
        &scene.render(ring_power, 1, 1),
        &scene.render(spot_power, 1, 1),
        "power",
    );
    // A thin ring of radius R at height h: every point is √(h² + R²) away, so the floor point
    // below its centre gets I·h / (h² + R²)^(3/2) from any one sample (the first pixel sample
    // is the pixel's centre; later ones move across the pixel).
    let (radius, height, intensity) = (0.5f32, 1.0f32, 3.0f32);
    let thin = spot_like(
        "ring",
        &[
            ("intensity", intensity),
            ("radius", radius),
            ("innerRadius", radius),
        ],
    );
    let image = scene.render(thin, 1, 1);
    let expected = intensity * height / (height * height + radius * radius).powf(1.5) / PI;
    let got = pixel(&image, 16, 16);
    assert!(
        (got - expected).abs() < 1e-4 * expected,
        "{got} vs {expected}"
    );
    // Radiance L over a disk of radius R is the intensity L·πR².
    let by_radiance = spot_like("ring", &[("radiance", 2.0), ("radius", radius)]);
    let by_intensity = spot_like(
        "ring",
        &[
            ("intensity", 2.0 * PI * radius * radius),
            ("radius", radius),
        ],
    );
    assert_close(
        &scene.render(by_radiance, 2, 16),
        &scene.render(by_intensity, 2, 16),
        1e-5,
    );
    release_all(
        dev,
        &[
            ring,
            spot,
            ring_power,
            spot_power,
            thin,
            by_radiance,
            by_intensity,
        ],
    );
    scene.finish(&log);
}
