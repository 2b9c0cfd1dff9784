use super::*;

#[test]
fn tiles_without_costs_are_dealt_out_in_turn() {
    let split = TileSplit::new(7, 3, 1, None);
    let owners: Vec<u32> = (0..7).map(|t| split.owner(t)).collect();
    assert_eq!(owners, [0, 1, 2, 0, 1, 2, 0]);
    let mine: Vec<usize> = (0..7).filter(|t| split.owns(*t)).collect();
    assert_eq!(mine, [1, 4]);
}

#[test]
fn tiles_with_costs_balance_the_ranks_work() {
    // One tile as costly as all the others together: it gets a rank of its own.
    let mut costs = vec![1.0; 9];
    costs[4] = 8.0;
    let split = TileSplit::new(9, 2, 0, Some(&costs));
    let owner_of_costly = split.owner(4);
    let load = |rank: u32| -> f64 {
        (0..9)
            .filter(|t| split.owner(*t) == rank)
            .map(|t| costs[t])
            .sum()
    };
    assert_eq!(load(owner_of_costly), 8.0);
    assert_eq!(load(1 - owner_of_costly), 8.0);
    // Every rank computes the same split from the same costs.
    let other = TileSplit::new(9, 2, 1, Some(&costs));
    assert!((0..9).all(|t| split.owner(t) == other.owner(t)));
    assert!((0..9).all(|t| split.owns(t) != other.owns(t)));
}

#[test]
fn a_tiles_time_is_kept_for_the_next_split() {
    let split = TileSplit::new(3, 2, 0, None);
    split.record(2, Duration::from_micros(5));
    assert_eq!(split.times(), [0.0, 0.0, 5000.0]);
}

#[test]
fn samples_and_trace_keys_survive_their_encoding() {
    let sample = Sample {
        color: Vec4::new(0.25, 0.5, -0.0, 1.0),
        hit: Some(PrimaryHit {
            t: 2.5,
            point: Vec3::new(1.0, -2.0, 3.0),
            primitive_id: 7,
            object_id: 11,
            instance_id: u32::MAX,
            albedo: Vec3::new(0.1, 0.2, 0.3),
            normal: Vec3::new(0.0, 1.0, 0.0),
        }),
    };
    let mut words = Vec::new();
    encode_sample(&sample, &mut words);
    encode_sample(
        &Sample {
            color: Vec4::ONE,
            hit: None,
        },
        &mut words,
    );
    assert_eq!(words.len(), 2 * SAMPLE_WORDS);
    let back = decode_sample(&words[..SAMPLE_WORDS]);
    assert_eq!(
        back.color.to_array().map(f32::to_bits),
        sample.color.to_array().map(f32::to_bits)
    );
    let (hit, want) = (back.hit.unwrap(), sample.hit.unwrap());
    assert_eq!(
        (
            hit.t,
            hit.point,
            hit.primitive_id,
            hit.object_id,
            hit.instance_id
        ),
        (
            want.t,
            want.point,
            want.primitive_id,
            want.object_id,
            want.instance_id
        )
    );
    assert_eq!((hit.albedo, hit.normal), (want.albedo, want.normal));
    assert!(decode_sample(&words[SAMPLE_WORDS..]).hit.is_none());

    let ray = Ray {
        origin: Vec3::new(0.5, 1.5, -2.0),
        direction: Vec3::new(0.0, -0.6, 0.8),
        t_min: 1e-4,
        t_max: f32::INFINITY,
    };
    let sampling = LightSampling {
        index: 3,
        scramble: Vec2::new(0.125, 0.75),
    };
    let (r, depth, from_camera, screen, s) = trace_inputs(&trace_key(
        &ray,
        2,
        true,
        Some(Vec2::new(0.3, 0.7)),
        &sampling,
    ));
    assert_eq!(ray_key(&r), ray_key(&ray));
    assert_eq!(
        (depth, from_camera, screen),
        (2, true, Some(Vec2::new(0.3, 0.7)))
    );
    assert_eq!((s.index, s.scramble), (3, sampling.scramble));
    let (_, depth, from_camera, screen, _) =
        trace_inputs(&trace_key(&ray, 5, false, None, &sampling));
    assert_eq!((depth, from_camera, screen), (5, false, None));
}

#[test]
fn outside_a_render_across_ranks_the_hooks_ask_the_scene_itself() {
    let scene = SceneSnapshot::empty();
    let ray = Ray {
        origin: Vec3::ZERO,
        direction: Vec3::Z,
        t_min: 0.0,
        t_max: f32::INFINITY,
    };
    let sampling = LightSampling::for_pixel(0, 1, 2);
    assert!(!occluded(&scene, &ray));
    assert_eq!(closest(&scene, &ray, 0, false, None, &sampling), Ok(None));
    assert!(primary(&scene, &ray, None, None, None, &sampling).is_none());
    assert!(fast_primary_sample(&scene, &ray, None, || Vec2::ZERO, None).is_ok());
}

#[test]
fn a_data_parallel_pass_keeps_each_sample_in_its_slot_and_replays_it() {
    // A 2×1 frame, one ray per pixel: slot 1 is pixel (1, 0).
    let pass = Arc::new(PrimaryPass::new(2, 1, 1, false).unwrap());
    let mut scene = SceneSnapshot::empty();
    scene.cluster = Some(Arc::clone(&pass) as _);
    let ray = Ray {
        origin: Vec3::ZERO,
        direction: Vec3::Z,
        t_min: 0.0,
        t_max: f32::INFINITY,
    };
    let hit = SceneHit {
        t: 2.5,
        instance: 0,
        geometry: 0,
        primitive: 4,
        uv: Vec2::ZERO,
        normal: Vec3::Z,
        object_normal: Vec3::Z,
    };
    let sampling = LightSampling::for_pixel(0, 1, 0);
    let untouched = pass.digest();
    at_slot(1);
    // Shading waits for the compositing: the first pass gives a blank sample.
    let first = primary(&scene, &ray, Some(&hit), None, None, &sampling).unwrap();
    assert_eq!(first.color, Vec4::ZERO);
    assert_eq!(
        (pass.local(0), pass.local(1)),
        (UNVISITED, 2.5f32.to_bits() + 1)
    );
    assert_ne!(pass.digest(), untouched);
    assert_eq!(key_ray(&pass.record(1).key).direction, Vec3::Z);
    at_slot(0);
    primary(&scene, &ray, None, None, None, &sampling);
    assert_eq!(pass.local(0), MISSED);
    // The replay gives each slot its own sample, and a blank one to a slot without.
    let shaded = Sample {
        color: Vec4::new(0.5, 0.25, 1.0, 1.0),
        hit: None,
    };
    pass.set_replay(Replay {
        index: vec![NO_SAMPLE, 0],
        samples: vec![shaded],
    });
    at_slot(1);
    let replayed = primary(&scene, &ray, Some(&hit), None, None, &sampling).unwrap();
    assert_eq!(replayed.color, shaded.color);
    at_slot(0);
    let blank = fast_primary_sample(&scene, &ray, None, || Vec2::ZERO, None);
    assert!(matches!(blank, Err(s) if s.color == Vec4::ZERO));
}
