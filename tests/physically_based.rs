//! physicallyBased layers in the default renderer, against closed forms on a square facing an
//! orthographic camera (normal incidence): specular and specularColor (glTF
//! KHR_materials_specular), clearcoat with its roughness and normal map (_clearcoat), sheen
//! (_sheen), iridescence (_iridescence), the normal and occlusion maps; no combination returns
//! more light than arrives (a white furnace), bad values are reported.

mod common;
use std::f32::consts::FRAC_1_PI;

use common::*;

const SIZE: u32 = 16;
/// A background that tells reflections of it apart from the surface's own colour.
const SKY: [f32; 4] = [0.2, 0.4, 0.6, 1.0];

/// A 4 m square in the plane z = 0 facing +z (the camera), wider than the view.
fn square(dev: ANARIDevice, tangent: Option<[f32; 4]>) -> ANARIGeometry {
    let geometry = anariNewGeometry(dev, c("triangle").as_ptr());
    let (a, b, c_, d) = (
        [-2.0f32, -2.0, 0.0],
        [2.0, -2.0, 0.0],
        [2.0, 2.0, 0.0],
        [-2.0, 2.0, 0.0],
    );
    set_array(
        dev,
        geometry,
        "vertex.position",
        ANARI_FLOAT32_VEC3,
        &[a, b, c_, a, c_, d],
    );
    if let Some(tangent) = tangent {
        set_array(
            dev,
            geometry,
            "vertex.tangent",
            ANARI_FLOAT32_VEC4,
            &[tangent; 6],
        );
    }
    commit(dev, geometry);
    geometry
}

enum Value {
    Float(f32),
    Color([f32; 3]),
    /// A sampler that gives this value everywhere.
    Sampler([f32; 4]),
}

/// A `transform` sampler that gives `value` everywhere (a zero matrix plus an offset).
fn constant_sampler(dev: ANARIDevice, value: [f32; 4]) -> ANARISampler {
    let sampler = anariNewSampler(dev, c("transform").as_ptr());
    set(
        dev,
        sampler,
        "outTransform",
        ANARI_FLOAT32_MAT4,
        &[0.0f32; 16],
    );
    set(dev, sampler, "outOffset", ANARI_FLOAT32_VEC4, &value);
    commit(dev, sampler);
    sampler
}

/// A physicallyBased material: non-metallic, rough, grey 0.5, then `params`.
fn material(dev: ANARIDevice, params: &[(&str, Value)]) -> ANARIMaterial {
    let material = anariNewMaterial(dev, c("physicallyBased").as_ptr());
    set(dev, material, "metallic", ANARI_FLOAT32, &0.0f32);
    set(dev, material, "roughness", ANARI_FLOAT32, &1.0f32);
    set(
        dev,
        material,
        "baseColor",
        ANARI_FLOAT32_VEC3,
        &[0.5f32, 0.5, 0.5],
    );
    for (name, value) in params {
        match value {
            Value::Float(v) => set(dev, material, name, ANARI_FLOAT32, v),
            Value::Color(v) => set(dev, material, name, ANARI_FLOAT32_VEC3, v),
            Value::Sampler(v) => {
                let sampler = constant_sampler(dev, *v);
                set_object(dev, material, name, ANARI_SAMPLER, sampler);
                anariRelease(dev, sampler);
            }
        }
    }
    commit(dev, material);
    material
}

/// A directional light whose light arrives from `to_light` with irradiance 1.
fn light_from(dev: ANARIDevice, to_light: [f32; 3]) -> ANARILight {
    let light = anariNewLight(dev, c("directional").as_ptr());
    let direction = to_light.map(|v| -v);
    set(dev, light, "direction", ANARI_FLOAT32_VEC3, &direction);
    set(dev, light, "irradiance", ANARI_FLOAT32, &1.0f32);
    commit(dev, light);
    light
}

/// The default renderer's colour at the centre pixel of `surface` seen from +z, with ambient
/// radiance `ambient`, background `background` and `lights`.
fn centre(
    dev: ANARIDevice,
    surface: ANARISurface,
    ambient: f32,
    background: [f32; 4],
    lights: &[ANARILight],
) -> [f32; 3] {
    let world = world_of(dev, &[surface]);
    if !lights.is_empty() {
        let array = object_array(dev, ANARI_LIGHT, lights);
        set_object(dev, world, "light", ANARI_ARRAY1D, array);
        anariRelease(dev, array);
        commit(dev, world);
    }
    let camera = orthographic_camera(dev, [0.0, 0.0, 5.0], 2.0);
    let renderer = anariNewRenderer(dev, c("default").as_ptr());
    set(dev, renderer, "ambientRadiance", ANARI_FLOAT32, &ambient);
    set(dev, renderer, "background", ANARI_FLOAT32_VEC4, &background);
    commit(dev, renderer);
    let frame = frame_for(dev, world, camera, renderer, [SIZE, SIZE]);
    let (colors, _, _) = render_channel::<[f32; 4]>(dev, frame, "channel.color");
    release_all(dev, &[world, camera, renderer, frame]);
    let p = colors[(SIZE / 2 * SIZE + SIZE / 2) as usize];
    [p[0], p[1], p[2]]
}

/// The centre pixel of the square with `params`, under ambient radiance 1 before `SKY`.
fn render_with(dev: ANARIDevice, params: &[(&str, Value)]) -> [f32; 3] {
    let geometry = square(dev, None);
    let material = material(dev, params);
    let surface = surface_of(dev, geometry, material);
    let pixel = centre(dev, surface, 1.0, SKY, &[]);
    release_all(dev, &[geometry, material, surface]);
    pixel
}

/// What a layer of normal-incidence reflectance `f` over the grey 0.5 base shows: the base
/// (albedo 0.5 under ambient 1) keeps 1 − max(f), the mirror image of the sky gets f.
fn over_base(f: [f32; 3]) -> [f32; 3] {
    let keep = 1.0 - f.iter().copied().fold(0.0, f32::max);
    std::array::from_fn(|i| 0.5 * keep + f[i] * SKY[i])
}

#[test]
fn specular_and_its_colour_weight_a_fresnel_reflection_over_the_base() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let mirror_like = |extra: Vec<(&'static str, Value)>| {
        let mut params = vec![("roughness", Value::Float(0.0))];
        params.extend(extra);
        render_with(dev, &params)
    };
    // The default specular 0: the diffuse base alone.
    assert_near(mirror_like(vec![]), [0.5; 3], "specular 0");
    // ((1.5 − 1)/(1.5 + 1))² = 0.04 at normal incidence.
    let full = mirror_like(vec![("specular", Value::Float(1.0))]);
    assert_near(full, over_base([0.04; 3]), "specular 1");
    let half = mirror_like(vec![("specular", Value::Float(0.5))]);
    assert_near(half, over_base([0.02; 3]), "specular 0.5");
    // ior 2: (1/3)².
    let dense = mirror_like(vec![
        ("specular", Value::Float(1.0)),
        ("ior", Value::Float(2.0)),
    ]);
    assert_near(dense, over_base([1.0 / 9.0; 3]), "ior 2");
    // The colour scales F0 per channel; the base loses its largest component.
    let red = mirror_like(vec![
        ("specular", Value::Float(1.0)),
        ("specularColor", Value::Color([1.0, 0.0, 0.5])),
    ]);
    assert_near(red, over_base([0.04, 0.0, 0.02]), "specularColor");
    // As a sampler.
    let sampled = mirror_like(vec![
        ("specular", Value::Sampler([0.5, 0.0, 0.0, 1.0])),
        ("specularColor", Value::Sampler([1.0, 0.0, 0.5, 1.0])),
    ]);
    assert_near(sampled, over_base([0.02, 0.0, 0.01]), "sampled specular");
    // A rough reflection is diffuse-like: the ambient light (1) instead of the sky.
    let rough = render_with(dev, &[("specular", Value::Float(1.0))]);
    assert_near(rough, [0.5 * 0.96 + 0.04; 3], "rough specular");
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}

#[test]
fn a_clearcoat_reflects_four_percent_over_everything_along_its_own_normal() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let coat = |roughness: f32, normal: Option<[f32; 4]>| {
        let mut params = vec![
            ("clearcoat", Value::Float(1.0)),
            ("clearcoatRoughness", Value::Float(roughness)),
        ];
        if let Some(normal) = normal {
            params.push(("clearcoatNormal", Value::Sampler(normal)));
        }
        render_with(dev, &params)
    };
    assert_near(coat(0.0, None), over_base([0.04; 3]), "smooth coat");
    assert_near(coat(1.0, None), [0.5 * 0.96 + 0.04; 3], "rough coat");
    let half = render_with(
        dev,
        &[
            ("clearcoat", Value::Float(0.5)),
            ("clearcoatRoughness", Value::Float(0.0)),
        ],
    );
    assert_near(half, over_base([0.02; 3]), "clearcoat 0.5");
    // The coat's normal tilted 60° towards +x: seen at 60°, Schlick's F = 0.04 + 0.96·0.5⁵; its
    // mirror image still shows the sky.
    let (s, c60) = (60f32.to_radians().sin(), 60f32.to_radians().cos());
    let tilted = coat(0.0, Some([0.5 + 0.5 * s, 0.5, 0.5 + 0.5 * c60, 1.0]));
    let f = 0.04 + 0.96 * 0.5f32.powi(5);
    assert_near(tilted, over_base([f; 3]), "tilted coat normal");
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}

/// The square with `params` lit only by a light from `to_light`: radiance base/π · cos.
fn lit(dev: ANARIDevice, tangent: Option<[f32; 4]>, params: &[(&str, Value)]) -> f32 {
    let geometry = square(dev, tangent);
    let material = material(dev, params);
    let surface = surface_of(dev, geometry, material);
    let light = light_from(
        dev,
        [30f32.to_radians().sin(), 0.0, 30f32.to_radians().cos()],
    );
    let pixel = centre(dev, surface, 0.0, [0.0, 0.0, 0.0, 1.0], &[light]);
    release_all(dev, &[geometry, material, surface, light]);
    pixel[0]
}

#[test]
fn a_normal_map_turns_the_normal_in_the_tangent_frame() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // The light is 30° from the square's normal, towards +x.
    let plain = lit(dev, None, &[]);
    let cos30 = 30f32.to_radians().cos();
    assert!((plain - 0.5 * FRAC_1_PI * cos30).abs() < 1e-4, "{plain}");
    // The map turns the normal 30° towards the tangent: without vertex.tangent the object's x
    // axis, so it faces the light.
    let s = 0.5 + 0.5 * 30f32.to_radians().sin();
    let c = 0.5 + 0.5 * cos30;
    let map = [s, 0.5, c, 1.0];
    let facing = lit(dev, None, &[("normal", Value::Sampler(map))]);
    assert!((facing - 0.5 * FRAC_1_PI).abs() < 1e-4, "{facing}");
    // With the tangent along +y the normal turns towards +y: cos = cos²30°.
    let across = lit(
        dev,
        Some([0.0, 1.0, 0.0, 1.0]),
        &[("normal", Value::Sampler(map))],
    );
    assert!(
        (across - 0.5 * FRAC_1_PI * cos30 * cos30).abs() < 1e-4,
        "{across}"
    );
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}

#[test]
fn occlusion_darkens_the_ambient_light_only() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let occluded = render_with(dev, &[("occlusion", Value::Sampler([0.25, 1.0, 1.0, 1.0]))]);
    assert_near(occluded, [0.5 * 0.25; 3], "ambient only");
    // Straight-on light (irradiance 1) is not occluded: 0.5/π + 0.5·0.25.
    let geometry = square(dev, None);
    let material = material(dev, &[("occlusion", Value::Sampler([0.25, 1.0, 1.0, 1.0]))]);
    let surface = surface_of(dev, geometry, material);
    let light = light_from(dev, [0.0, 0.0, 1.0]);
    let pixel = centre(dev, surface, 1.0, SKY, &[light]);
    assert_near(pixel, [0.5 * FRAC_1_PI + 0.125; 3], "light and ambient");
    release_all(dev, &[geometry, material, surface, light]);
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}

/// The sheen's directional albedo at normal incidence for `roughness`, integrated here
/// independently (double precision, fine grid): Charlie distribution with α = roughness²,
/// Ashikhmin visibility.
fn sheen_albedo_facing(roughness: f64) -> f64 {
    let alpha = roughness * roughness;
    let rings = 4000;
    let mut sum = 0.0;
    for i in 0..rings {
        let cos_l = (f64::from(i) + 0.5) / f64::from(rings);
        // Viewed along the normal the half vector lies halfway to the light, whatever its
        // azimuth.
        let cos_h = ((1.0 + cos_l) / 2.0).sqrt();
        let sin_h = (1.0 - cos_h * cos_h).sqrt();
        let d = (2.0 + 1.0 / alpha) * sin_h.powf(1.0 / alpha) / (2.0 * std::f64::consts::PI);
        let v = 0.25 / (cos_l + 1.0 - cos_l);
        sum += d * v * cos_l;
    }
    // dω = d(cos θ) dφ, the azimuth giving 2π.
    sum / f64::from(rings) * 2.0 * std::f64::consts::PI
}

#[test]
fn sheen_reflects_its_albedo_and_the_base_below_loses_as_much() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let roughness = 0.8;
    let albedo = sheen_albedo_facing(f64::from(roughness)) as f32;
    assert!(albedo > 0.03 && albedo < 1.0, "{albedo}");
    // On a white base a red sheen keeps red at 1 (what the sheen takes it gives back) and
    // takes its albedo from green and blue.
    let pixel = render_with(
        dev,
        &[
            ("baseColor", Value::Color([1.0, 1.0, 1.0])),
            ("sheenColor", Value::Color([1.0, 0.0, 0.0])),
            ("sheenRoughness", Value::Float(roughness)),
        ],
    );
    assert_near(pixel, [1.0, 1.0 - albedo, 1.0 - albedo], "red sheen");
    // On black only the sheen shows, its albedo by its roughness.
    for roughness in [0.3f32, 0.8] {
        let albedo = sheen_albedo_facing(f64::from(roughness)) as f32;
        let pixel = render_with(
            dev,
            &[
                ("baseColor", Value::Color([0.0, 0.0, 0.0])),
                ("sheenColor", Value::Color([1.0, 1.0, 1.0])),
                ("sheenRoughness", Value::Float(roughness)),
            ],
        );
        assert!(
            (pixel[0] - albedo).abs() < 0.003,
            "roughness {roughness}: {pixel:?} vs {albedo}"
        );
    }
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}

#[test]
fn iridescence_colours_a_metal_by_the_film_thickness() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    // A smooth grey metal mirroring a white sky (no ambient light).
    let metal_in = |iridescence: f32, thickness: f32, ior: f32| {
        let geometry = square(dev, None);
        let material = material(
            dev,
            &[
                ("metallic", Value::Float(1.0)),
                ("roughness", Value::Float(0.0)),
                ("iridescence", Value::Float(iridescence)),
                ("iridescenceThickness", Value::Float(thickness)),
                ("iridescenceIor", Value::Float(ior)),
            ],
        );
        let surface = surface_of(dev, geometry, material);
        let pixel = centre(dev, surface, 0.0, [1.0; 4], &[]);
        release_all(dev, &[geometry, material, surface]);
        pixel
    };
    let metal = |iridescence: f32, thickness: f32| metal_in(iridescence, thickness, 1.3);
    assert_near(metal(0.0, 400.0), [0.5; 3], "no iridescence");
    assert_near(metal(1.0, 0.0), [0.5; 3], "no film");
    let film = metal(1.0, 400.0);
    let spread =
        film.iter().copied().fold(0.0, f32::max) - film.iter().copied().fold(1.0, f32::min);
    assert!(spread > 0.05, "{film:?}");
    let other = metal(1.0, 250.0);
    assert!(
        (0..3).any(|i| (film[i] - other[i]).abs() > 0.05),
        "{film:?} {other:?}"
    );
    let denser = metal_in(1.0, 400.0, 1.8);
    assert!(
        (0..3).any(|i| (film[i] - denser[i]).abs() > 0.05),
        "{film:?} {denser:?}"
    );
    // The factor mixes linearly.
    let half = metal(0.5, 400.0);
    assert_near(
        half,
        std::array::from_fn(|i| 0.5 * (0.5 + film[i])),
        "iridescence 0.5",
    );
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}

#[test]
fn no_combination_of_layers_returns_more_light_than_arrives() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let ball = sphere_geometry(dev, &[[0.0, 0.0, 0.0]], 0.9);
    let mut cases = 0;
    for metallic in [0.0f32, 1.0] {
        for roughness in [0.0f32, 0.6] {
            for transmission in [0.0f32, 1.0] {
                for specular in [0.0f32, 1.0] {
                    for (clearcoat, coat_roughness) in [(0.0f32, 0.0f32), (1.0, 0.0), (1.0, 0.5)] {
                        for (sheen, sheen_roughness) in [(0.0f32, 0.0f32), (1.0, 0.3), (1.0, 1.0)] {
                            for iridescence in [0.0f32, 1.0] {
                                let material = anariNewMaterial(dev, c("physicallyBased").as_ptr());
                                for (name, value) in [
                                    ("metallic", metallic),
                                    ("roughness", roughness),
                                    ("transmission", transmission),
                                    ("thickness", 1.0),
                                    ("specular", specular),
                                    ("clearcoat", clearcoat),
                                    ("clearcoatRoughness", coat_roughness),
                                    ("sheenRoughness", sheen_roughness),
                                    ("iridescence", iridescence),
                                    ("iridescenceThickness", 400.0),
                                ] {
                                    set(dev, material, name, ANARI_FLOAT32, &value);
                                }
                                set(dev, material, "sheenColor", ANARI_FLOAT32_VEC3, &[sheen; 3]);
                                commit(dev, material);
                                let surface = surface_of(dev, ball, material);
                                let world = world_of(dev, &[surface]);
                                let camera = orthographic_camera(dev, [0.0, 0.0, 5.0], 2.0);
                                let renderer = anariNewRenderer(dev, c("default").as_ptr());
                                set(dev, renderer, "ambientRadiance", ANARI_FLOAT32, &1.0f32);
                                set(
                                    dev,
                                    renderer,
                                    "background",
                                    ANARI_FLOAT32_VEC4,
                                    &[1.0f32; 4],
                                );
                                set(dev, renderer, "maxRayDepth", ANARI_INT32, &8i32);
                                commit(dev, renderer);
                                let frame = frame_for(dev, world, camera, renderer, [SIZE, SIZE]);
                                let (image, _, _) =
                                    render_channel::<[f32; 4]>(dev, frame, "channel.color");
                                let what = format!(
                                    "metallic {metallic} roughness {roughness} transmission \
                                     {transmission} specular {specular} clearcoat {clearcoat}/\
                                     {coat_roughness} sheen {sheen}/{sheen_roughness} \
                                     iridescence {iridescence}"
                                );
                                let brightest = image
                                    .iter()
                                    .map(|p| p[0].max(p[1]).max(p[2]))
                                    .fold(0.0, f32::max);
                                assert!(brightest <= 1.0 + 1e-4, "{what}: {brightest}");
                                // Without the film's colour nothing absorbs: all that arrives
                                // leaves (inside the rim, where every bounce is traced).
                                if iridescence == 0.0 {
                                    let centre = image[(SIZE / 2 * SIZE + SIZE / 2) as usize];
                                    assert!(centre[0] >= 0.98, "{what}: {centre:?}");
                                }
                                release_all(
                                    dev,
                                    &[material, surface, world, camera, renderer, frame],
                                );
                                cases += 1;
                            }
                        }
                    }
                }
            }
        }
    }
    assert_eq!(cases, 288);
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    anariRelease(dev, ball);
    release_device(lib, dev);
}

#[test]
fn out_of_range_values_are_reported_by_name_with_the_range() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let cases: [(&str, Value, &str); 5] = [
        ("ior", Value::Float(0.5), "≥ 1"),
        ("specular", Value::Float(-1.0), "[0, 1]"),
        ("clearcoatRoughness", Value::Float(2.0), "[0, 1]"),
        ("iridescenceThickness", Value::Float(-5.0), "≥ 0"),
        (
            "sheenColor",
            Value::Color([2.0, 0.0, 0.0]),
            "components in [0, 1]",
        ),
    ];
    for (name, value, expected) in cases {
        let m = material(dev, &[(name, value)]);
        let errors = log.errors();
        let quoted = format!("'{name}'");
        assert!(
            errors
                .iter()
                .any(|(code, text)| *code == ANARI_STATUS_INVALID_ARGUMENT
                    && text.contains("material 'physicallyBased'")
                    && text.contains(&quoted)
                    && text.contains(expected)),
            "{name}: {errors:?}"
        );
        anariRelease(dev, m);
    }
    release_device(lib, dev);
}

#[test]
fn every_parameter_of_the_extension_is_introspectable_with_its_default() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let float_default = |name: &str| {
        let value = anariGetParameterInfo(
            dev,
            ANARI_MATERIAL,
            c("physicallyBased").as_ptr(),
            c(name).as_ptr(),
            ANARI_FLOAT32,
            c("default").as_ptr(),
            ANARI_FLOAT32,
        ) as *const f32;
        assert!(!value.is_null(), "{name}");
        // SAFETY: the default of a FLOAT32 parameter is one float.
        unsafe { *value }
    };
    for (name, default) in [
        ("specular", 0.0),
        ("clearcoat", 0.0),
        ("clearcoatRoughness", 0.0),
        ("transmission", 0.0),
        ("ior", 1.5),
        ("thickness", 0.0),
        ("sheenRoughness", 0.0),
        ("iridescence", 0.0),
        ("iridescenceIor", 1.3),
        ("iridescenceThickness", 0.0),
        ("alphaCutoff", 0.5),
        ("attenuationDistance", f32::INFINITY),
    ] {
        assert_eq!(float_default(name), default, "{name}");
    }
    for name in ["normal", "occlusion", "clearcoatNormal"] {
        let kind = anariGetParameterInfo(
            dev,
            ANARI_MATERIAL,
            c("physicallyBased").as_ptr(),
            c(name).as_ptr(),
            ANARI_SAMPLER,
            c("description").as_ptr(),
            ANARI_STRING,
        );
        assert!(!kind.is_null(), "{name}");
    }
    assert!(device_extensions(dev).contains(&"ANARI_KHR_MATERIAL_PHYSICALLY_BASED".to_string()));
    release_device(lib, dev);
}

#[test]
fn alpha_mode_mask_cuts_out_below_the_cutoff() {
    let log = Log::new();
    let (lib, dev) = device_with_log(&log);
    let masked = |cutoff: Option<f32>| {
        let geometry = square(dev, None);
        let material = material(dev, &[("opacity", Value::Float(0.3))]);
        set_string(dev, material, "alphaMode", "mask");
        if let Some(cutoff) = cutoff {
            set(dev, material, "alphaCutoff", ANARI_FLOAT32, &cutoff);
        }
        commit(dev, material);
        let surface = surface_of(dev, geometry, material);
        let pixel = centre(dev, surface, 1.0, SKY, &[]);
        release_all(dev, &[geometry, material, surface]);
        pixel
    };
    // Opacity 0.3 is below the default cutoff 0.5: the sky shows through.
    assert_near(masked(None), [SKY[0], SKY[1], SKY[2]], "default cutoff");
    // Above a cutoff of 0.2 the surface is whole (the grey base under ambient 1).
    assert_near(masked(Some(0.2)), [0.5; 3], "cutoff 0.2");
    assert!(log.errors().is_empty(), "{:?}", log.errors());
    release_device(lib, dev);
}
