//! The offAxis camera with several viewers: ray origins per mode, the CAVE invariant, seams
//! between walls, continuity, and the single-viewer case against today's camera.

use glam::{DVec3, Vec2, Vec3};

use super::rays::BLOCK_RAYS;
use super::test_support::{
    HEIGHT, Screen, WIDTH, max_screen_error, pixel_centres, screens, unit_sequence,
};
use super::viewers::{ViewerDesc, ViewerMode, ViewerWeighting};
use super::{BlockRays, Camera, CameraRay, Eye, EyeRays, OffAxisDesc, StereoMode};

const MODES: [ViewerMode; 3] = [ViewerMode::PerPixel, ViewerMode::Tiles, ViewerMode::Zones];
const WEIGHTINGS: [ViewerWeighting; 3] = [
    ViewerWeighting::Linear,
    ViewerWeighting::Cosine,
    ViewerWeighting::Gaussian,
];

fn camera(screen: &Screen, viewers: ViewerDesc, stereo_mode: StereoMode) -> Box<dyn Camera> {
    Box::new(
        super::screen::OffAxisCamera::new(&OffAxisDesc {
            lower_left: Some(screen.ll.as_vec3()),
            lower_right: Some(screen.lr.as_vec3()),
            upper_right: Some(screen.ur.as_vec3()),
            stereo_mode,
            viewers: Some(viewers),
            ..OffAxisDesc::default()
        })
        .unwrap(),
    )
}

fn rays(camera: &dyn Camera, eye: Eye) -> EyeRays {
    camera.prepare(eye, WIDTH, HEIGHT)
}

fn ray_at(rays: &EyeRays, s: f32, t: f32) -> CameraRay {
    rays.ray(s, t, Vec2::ZERO)
}

/// Two viewers in the CAVE: one looking at the left part of the front wall, one at the right
/// wall, heads 0.9 m apart.
fn two_viewers(screen: &Screen) -> ViewerDesc {
    let a = screen.local(-0.15, -0.05, 1.4);
    let b = screen.local(0.15, 0.0, 1.3);
    ViewerDesc {
        cutoff_angle: 0.5,
        ..ViewerDesc::new(
            vec![a.as_vec3(), b.as_vec3()],
            vec![
                (screen.local(-0.3, 0.1, 0.0) - a).as_vec3(),
                (screen.local(0.45, -0.2, 0.0) - b).as_vec3(),
            ],
        )
    }
}

/// The angle of viewer `i` of `desc` to point `p`, in f64.
fn angle(desc: &ViewerDesc, i: usize, p: DVec3) -> f64 {
    let gaze = desc.directions[i].as_dvec3().normalize();
    gaze.dot((p - desc.positions[i].as_dvec3()).normalize())
        .clamp(-1.0, 1.0)
        .acos()
}

#[test]
fn one_viewer_gives_todays_rays_bit_for_bit() {
    for screen in [screens()[0], screens()[3], screens()[5], screens()[7]] {
        for (k, head) in screen.eyes().into_iter().enumerate() {
            let gaze = screen.local(0.1 * k as f64, -0.2, 0.0) - head;
            for stereo_mode in [StereoMode::None, StereoMode::SideBySide] {
                let today = super::screen::OffAxisCamera::new(&OffAxisDesc {
                    lower_left: Some(screen.ll.as_vec3()),
                    lower_right: Some(screen.lr.as_vec3()),
                    upper_right: Some(screen.ur.as_vec3()),
                    position: head.as_vec3(),
                    stereo_mode,
                    near: Some(0.05),
                    ..OffAxisDesc::default()
                });
                let Ok(today) = today else {
                    continue; // an eye of this head is behind the screen
                };
                for (mode, weighting) in MODES.into_iter().zip(WEIGHTINGS) {
                    let viewers = ViewerDesc {
                        mode,
                        weighting,
                        cutoff_angle: 0.3,
                        tiles: [5, 3],
                        ..ViewerDesc::new(vec![head.as_vec3()], vec![gaze.as_vec3()])
                    };
                    let blended = super::screen::OffAxisCamera::new(&OffAxisDesc {
                        lower_left: Some(screen.ll.as_vec3()),
                        lower_right: Some(screen.lr.as_vec3()),
                        upper_right: Some(screen.ur.as_vec3()),
                        stereo_mode,
                        near: Some(0.05),
                        viewers: Some(viewers),
                        ..OffAxisDesc::default()
                    })
                    .unwrap();
                    for eye in stereo_mode.eyes() {
                        let (a, b) = (rays(&today, *eye), rays(&blended, *eye));
                        for (_, _, s, t) in pixel_centres(WIDTH, HEIGHT) {
                            assert_eq!(
                                ray_at(&a, s, t),
                                ray_at(&b, s, t),
                                "{} {mode:?} {eye:?}",
                                screen.name
                            );
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn the_invariant_holds_for_every_mode_weighting_and_eye() {
    for screen in screens() {
        for mode in MODES {
            for weighting in WEIGHTINGS {
                let viewers = ViewerDesc {
                    mode,
                    weighting,
                    ..two_viewers(&screen)
                };
                let camera = camera(&screen, viewers, StereoMode::SideBySide);
                for eye in [Eye::Left, Eye::Right] {
                    let error = max_screen_error(&rays(&*camera, eye), &screen);
                    assert!(error < 1e-5, "{} {mode:?} {eye:?}: {error}", screen.name);
                }
            }
        }
    }
}

#[test]
fn a_point_in_one_viewers_cone_alone_is_seen_from_exactly_that_viewers_eyes() {
    let screen = screens()[0];
    let desc = two_viewers(&screen);
    let ipd = f64::from(super::DEFAULT_INTERPUPILLARY_DISTANCE);
    let mut checked = 0;
    for weighting in WEIGHTINGS {
        for mode in [ViewerMode::PerPixel, ViewerMode::Zones] {
            let viewers = ViewerDesc {
                mode,
                weighting,
                ..desc.clone()
            };
            let camera = camera(&screen, viewers, StereoMode::SideBySide);
            let [mono, left] = [Eye::Mono, Eye::Left].map(|eye| rays(&*camera, eye));
            for (_, _, s, t) in pixel_centres(WIDTH, HEIGHT) {
                let p = screen.point(f64::from(s), f64::from(t));
                // Inside A's cone (for the cosine weighting, its reach c·π/2), outside B's.
                let reach = |weighting| match (mode, weighting) {
                    (ViewerMode::PerPixel, ViewerWeighting::Cosine) => {
                        0.5 * std::f64::consts::FRAC_PI_2
                    }
                    _ => 0.5,
                };
                let only_a = angle(&desc, 0, p) < reach(weighting) - 1e-3
                    && angle(&desc, 1, p) > reach(weighting) + 1e-3;
                if !only_a || weighting == ViewerWeighting::Gaussian && mode != ViewerMode::Zones {
                    continue;
                }
                let head = desc.positions[0];
                assert_eq!(ray_at(&mono, s, t).origin, head, "{mode:?} {weighting:?}");
                let left_eye =
                    (head.as_dvec3() - screen.width_axis().normalize() * (ipd / 2.0)).as_vec3();
                assert_eq!(ray_at(&left, s, t).origin, left_eye);
                checked += 1;
            }
        }
    }
    assert!(checked > 100, "{checked}");
    // The pixel nearest A's gaze line: A looks at (−0.3, 0.1) in screen units from the centre.
    let (s, t) = (0.2f32, 0.6f32);
    let camera = camera(&screen, desc.clone(), StereoMode::None);
    assert_eq!(
        ray_at(&rays(&*camera, Eye::Mono), s, t).origin,
        desc.positions[0]
    );
}

#[test]
fn stereo_eyes_straddle_the_blended_head_by_the_interpupillary_distance() {
    let screen = screens()[1];
    let ipd = f64::from(super::DEFAULT_INTERPUPILLARY_DISTANCE);
    for weighting in WEIGHTINGS {
        let viewers = ViewerDesc {
            weighting,
            rights: Some(vec![Vec3::new(0.0, 0.0, -1.0), Vec3::new(0.2, 0.0, -1.0)]),
            ..two_viewers(&screen)
        };
        let camera = camera(&screen, viewers, StereoMode::TopBottom);
        let [mono, left, right] = [Eye::Mono, Eye::Left, Eye::Right].map(|e| rays(&*camera, e));
        for (_, _, s, t) in pixel_centres(WIDTH, HEIGHT) {
            let origin = |r: &EyeRays| ray_at(r, s, t).origin.as_dvec3();
            let (l, r, m) = (origin(&left), origin(&right), origin(&mono));
            assert!(((r - l).length() - ipd).abs() < 1e-6, "{weighting:?}");
            assert!(((l + r) / 2.0 - m).length() < 1e-6, "{weighting:?}");
        }
    }
}

#[test]
fn per_pixel_camera_positions_vary_continuously() {
    // With linear weights w_i = 1 − a_i/c, the camera C = Σ w_i H_i / W moves by
    // dC = (1/W) Σ dw_i (H_i − C), and |dw_i| ≤ δ/(c·d_i) for a step δ along the screen at
    // distance d_i from head i (an angle changes at most by δ/d_i). So neighbouring pixels'
    // positions differ by at most δ·Σ_i |H_i − C| / (c·d_i) / W (W, d_i: the smaller of the two
    // pixels'; twice that for the finite step). Where all weights vanish C jumps to the mean of
    // the heads: that is the method, and those pixels are left out.
    let screen = screens()[0];
    let desc = ViewerDesc {
        cutoff_angle: 0.9,
        ..two_viewers(&screen)
    };
    let c = f64::from(desc.cutoff_angle);
    let camera = camera(&screen, desc.clone(), StereoMode::None);
    let mono = rays(&*camera, Eye::Mono);
    let heads: Vec<DVec3> = desc.positions.iter().map(|h| h.as_dvec3()).collect();
    let total_weight = |p: DVec3| -> f64 {
        (0..2)
            .map(|i| (1.0 - angle(&desc, i, p) / c).max(0.0))
            .sum()
    };
    let (mut compared, mut moving) = (0, 0);
    for (x, y, s, t) in pixel_centres(WIDTH, HEIGHT) {
        for (nx, ny) in [(x + 1, y), (x, y + 1)] {
            if nx >= WIDTH || ny >= HEIGHT {
                continue;
            }
            let ns = (nx as f32 + 0.5) / WIDTH as f32;
            let nt = (ny as f32 + 0.5) / HEIGHT as f32;
            let (p, q) = (
                screen.point(f64::from(s), f64::from(t)),
                screen.point(f64::from(ns), f64::from(nt)),
            );
            let w = total_weight(p).min(total_weight(q));
            if w < 0.05 {
                continue;
            }
            let (a, b) = (
                ray_at(&mono, s, t).origin.as_dvec3(),
                ray_at(&mono, ns, nt).origin.as_dvec3(),
            );
            let step = (q - p).length();
            let bound = 2.0 * step / w
                * heads
                    .iter()
                    .map(|h| {
                        let spread = (*h - a).length().max((*h - b).length());
                        let distance = (p - *h).length().min((q - *h).length());
                        spread / (c * distance)
                    })
                    .sum::<f64>();
            let moved = (a - b).length();
            assert!(moved <= bound, "({x}, {y}): moved {moved}, bound {bound}");
            compared += 1;
            moving += usize::from(moved > 1e-4);
        }
    }
    assert!(compared > 300 && moving > 50, "{compared} {moving}");
}

#[test]
fn walls_sharing_an_edge_give_the_same_camera_on_the_edge() {
    let [front, left] = [screens()[0], screens()[1]];
    // The shared edge: the front wall's left edge (s = 0), the left wall's right edge (s = 1).
    assert!((front.ll - left.lr).length() < 1e-12);
    let a = front.local(-0.2, -0.05, 1.3);
    let b = front.local(0.1, 0.0, 1.5);
    let corner = front.ll + front.height_axis() * 0.5;
    // The heads' tracked right vectors: the default (each screen's X axis) differs between
    // walls, so seamless stereo across walls needs them.
    let desc = ViewerDesc {
        cutoff_angle: 0.7,
        rights: Some(vec![Vec3::new(0.8, 0.0, -0.6), Vec3::X]),
        ..ViewerDesc::new(
            vec![a.as_vec3(), b.as_vec3()],
            vec![(corner - a).as_vec3(), (front.centre() - b).as_vec3()],
        )
    };
    let mut moved = 0.0f64;
    for mode in [ViewerMode::PerPixel, ViewerMode::Zones] {
        for weighting in WEIGHTINGS {
            let viewers = ViewerDesc {
                mode,
                weighting,
                ..desc.clone()
            };
            let on = |screen: &Screen, eye| {
                rays(
                    &*camera(screen, viewers.clone(), StereoMode::SideBySide),
                    eye,
                )
            };
            for eye in [Eye::Left, Eye::Right] {
                let (f, l) = (on(&front, eye), on(&left, eye));
                let first = ray_at(&f, 0.0, 0.0).origin;
                for k in 0..=40 {
                    let t = k as f32 / 40.0;
                    let (from_front, from_left) = (ray_at(&f, 0.0, t), ray_at(&l, 1.0, t));
                    assert!(
                        (from_front.origin - from_left.origin).length() < 1e-6,
                        "{mode:?} {weighting:?} {eye:?} t {t}: {from_front:?} vs {from_left:?}"
                    );
                    moved = moved.max(f64::from((from_front.origin - first).length()));
                }
            }
        }
    }
    // The edge is seen from different positions along it (so the check compares something).
    assert!(moved > 0.1, "{moved}");
}

#[test]
fn one_tile_per_pixel_equals_per_pixel() {
    for screen in [screens()[0], screens()[5]] {
        for weighting in WEIGHTINGS {
            let per_pixel = camera(
                &screen,
                ViewerDesc {
                    weighting,
                    ..two_viewers(&screen)
                },
                StereoMode::None,
            );
            let tiles = camera(
                &screen,
                ViewerDesc {
                    weighting,
                    mode: ViewerMode::Tiles,
                    tiles: [WIDTH, HEIGHT],
                    ..two_viewers(&screen)
                },
                StereoMode::None,
            );
            let (a, b) = (rays(&*per_pixel, Eye::Mono), rays(&*tiles, Eye::Mono));
            for (_, _, s, t) in pixel_centres(WIDTH, HEIGHT) {
                assert_eq!(ray_at(&a, s, t), ray_at(&b, s, t), "{weighting:?}");
            }
        }
    }
}

#[test]
fn tiles_share_one_camera_per_tile() {
    let screen = screens()[0];
    let per_pixel = rays(
        &*camera(&screen, two_viewers(&screen), StereoMode::None),
        Eye::Mono,
    );
    // A grid small enough to be computed at commit, and one computed pixel by pixel.
    for [columns, rows] in [[4u32, 3u32], [200, 100]] {
        let camera = camera(
            &screen,
            ViewerDesc {
                mode: ViewerMode::Tiles,
                tiles: [columns, rows],
                ..two_viewers(&screen)
            },
            StereoMode::None,
        );
        let mono = rays(&*camera, Eye::Mono);
        let mut distinct = Vec::new();
        for (_, _, s, t) in pixel_centres(WIDTH, HEIGHT) {
            let tile = |c: f32, n: u32| ((c * n as f32) as u32 as f32 + 0.5) / n as f32;
            let centre = (tile(s, columns), tile(t, rows));
            let origin = ray_at(&mono, s, t).origin;
            // The tile centre's own perPixel camera.
            assert_eq!(origin, ray_at(&per_pixel, centre.0, centre.1).origin);
            if !distinct.contains(&origin) {
                distinct.push(origin);
            }
        }
        assert!(distinct.len() >= 3, "{distinct:?}");
    }
}

#[test]
fn zones_follow_cone_membership() {
    let screen = screens()[0];
    let heads = [
        screen.local(-0.2, 0.0, 1.2),
        screen.local(0.2, 0.05, 1.4),
        screen.local(0.0, -0.1, 1.0),
    ];
    let targets = [
        screen.local(-0.1, 0.05, 0.0),
        screen.local(0.05, 0.05, 0.0),
        screen.local(0.0, -0.1, 0.0),
    ];
    let desc = ViewerDesc {
        mode: ViewerMode::Zones,
        cutoff_angle: 0.6,
        ..ViewerDesc::new(
            heads.iter().map(|h| h.as_vec3()).collect(),
            heads
                .iter()
                .zip(&targets)
                .map(|(h, t)| (*t - *h).as_vec3())
                .collect(),
        )
    };
    let c = f64::from(desc.cutoff_angle);
    let camera = camera(&screen, desc.clone(), StereoMode::None);
    let mono = rays(&*camera, Eye::Mono);
    let mut seen = [0usize; 4];
    for (_, _, s, t) in pixel_centres(WIDTH, HEIGHT) {
        let p = screen.point(f64::from(s), f64::from(t));
        let angles: Vec<f64> = (0..3).map(|i| angle(&desc, i, p)).collect();
        if angles.iter().any(|a| (a - c).abs() < 1e-4) {
            continue; // on a cone's boundary: f32 may fall either way
        }
        let members: Vec<DVec3> = (0..3)
            .filter(|i| angles[*i] < c)
            .map(|i| heads[i])
            .collect();
        let expected = if members.is_empty() {
            heads.iter().sum::<DVec3>() / 3.0
        } else {
            members.iter().sum::<DVec3>() / members.len() as f64
        };
        let origin = ray_at(&mono, s, t).origin.as_dvec3();
        assert!(
            (origin - expected).length() < 1e-6,
            "{p}: {origin} vs {expected}"
        );
        seen[members.len()] += 1;
    }
    // Pixels in no cone, in one, in two and in all three.
    assert!(seen.iter().all(|count| *count > 0), "{seen:?}");
}

#[test]
fn window_depth_is_each_pixels_own_frustum() {
    // With near 0.1 and far 20, a screen point lies at eye-space depth z = the pixel's eye's
    // distance to the screen: glFrustum depth f(z − n) / (z(f − n)), different per pixel.
    let screen = screens()[0];
    let camera = super::screen::OffAxisCamera::new(&OffAxisDesc {
        lower_left: Some(screen.ll.as_vec3()),
        lower_right: Some(screen.lr.as_vec3()),
        upper_right: Some(screen.ur.as_vec3()),
        near: Some(0.1),
        far: Some(20.0),
        viewers: Some(two_viewers(&screen)),
        ..OffAxisDesc::default()
    })
    .unwrap();
    let mono = rays(&camera, Eye::Mono);
    let (n, f) = (0.1, 20.0);
    let mut depths = Vec::new();
    for (_, _, s, t) in pixel_centres(WIDTH, HEIGHT) {
        let ray = ray_at(&mono, s, t);
        let point = screen.point(f64::from(s), f64::from(t));
        let z = (ray.origin.as_dvec3() - point).dot(screen.normal());
        let expected = f * (z - n) / (z * (f - n));
        let got = f64::from(mono.window_depth(&ray, point.as_vec3()));
        assert!((got - expected).abs() < 1e-6, "{got} vs {expected}");
        depths.push((got * 1e4).round() as i64);
    }
    depths.sort_unstable();
    depths.dedup();
    assert!(depths.len() >= 3, "{depths:?}");
}

#[test]
fn rays_made_four_at_a_time_equal_rays_made_one_by_one() {
    // Whatever the other three points of a batch are (in other cones, in none, in several),
    // each ray is the one `ray` makes alone.
    let screen = screens()[0];
    let centres: Vec<(f32, f32)> = pixel_centres(WIDTH, HEIGHT)
        .map(|(_, _, s, t)| (s, t))
        .collect();
    let mut state = 7u64;
    let mut pick = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        centres[(state >> 33) as usize % centres.len()]
    };
    for mode in MODES {
        for weighting in WEIGHTINGS {
            let viewers = ViewerDesc {
                mode,
                weighting,
                ..two_viewers(&screen)
            };
            let camera = camera(&screen, viewers, StereoMode::SideBySide);
            for eye in [Eye::Mono, Eye::Left] {
                let rays = rays(&*camera, eye);
                assert!(rays.batches_rays());
                for _ in 0..300 {
                    let points = [pick(), pick(), pick(), pick()];
                    let batch = rays.rays4(points.map(|p| p.0), points.map(|p| p.1), Vec2::ZERO);
                    for (ray, (s, t)) in batch.iter().zip(points) {
                        assert_eq!(*ray, ray_at(&rays, s, t), "{mode:?} {weighting:?}");
                    }
                }
                // A whole block's rays, made together (on every instruction-set path this CPU
                // has), are the same rays.
                assert!(rays.makes_block_rays());
                let mut block = BlockRays::default();
                for _ in 0..10 {
                    let points: [(f32, f32); BLOCK_RAYS] = std::array::from_fn(|_| pick());
                    let (s, t) = (points.map(|p| p.0), points.map(|p| p.1));
                    for isa in crate::isa::test_paths() {
                        assert!(rays.block_rays_on_path(isa, &s, &t, &mut block));
                        for (i, (s, t)) in points.into_iter().enumerate() {
                            let one = ray_at(&rays, s, t);
                            let bits = |ray: &CameraRay| {
                                [
                                    ray.origin,
                                    ray.direction,
                                    ray.cyclopean.unwrap_or(Vec3::NAN),
                                ]
                                .map(|v| v.to_array().map(f32::to_bits))
                            };
                            assert_eq!(
                                bits(&block.ray(i)),
                                bits(&one),
                                "{mode:?} {weighting:?} {eye:?} {isa:?}"
                            );
                            assert_eq!(
                                (block.ray(i).t_min, block.ray(i).t_max),
                                (one.t_min, one.t_max)
                            );
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn any_number_of_viewers_blends_by_the_definition() {
    // 3, 6 and 20 viewers (each size has working memory of its own) against the weighted mean
    // of the heads computed here in f64.
    let screen = screens()[0];
    let mut unit = unit_sequence(11);
    for count in [3, 6, 20] {
        let heads: Vec<DVec3> = (0..count)
            .map(|_| screen.local(unit() - 0.5, 0.3 * unit() - 0.15, 0.8 + unit()))
            .collect();
        let gazes: Vec<DVec3> = heads
            .iter()
            .map(|h| screen.local(0.8 * unit() - 0.4, 0.8 * unit() - 0.4, 0.0) - *h)
            .collect();
        let desc = ViewerDesc {
            cutoff_angle: 0.6,
            ..ViewerDesc::new(
                heads.iter().map(|h| h.as_vec3()).collect(),
                gazes.iter().map(|g| g.as_vec3()).collect(),
            )
        };
        let camera = camera(&screen, desc.clone(), StereoMode::None);
        let mono = rays(&*camera, Eye::Mono);
        let mut blended = 0;
        for (_, _, s, t) in pixel_centres(WIDTH, HEIGHT) {
            let p = screen.point(f64::from(s), f64::from(t));
            let weights: Vec<f64> = (0..count)
                .map(|i| (1.0 - angle(&desc, i, p) / 0.6).max(0.0))
                .collect();
            let total: f64 = weights.iter().sum();
            if weights.iter().any(|w| *w > 0.0 && *w < 1e-4) {
                continue; // at a cone's edge f32 may fall either way
            }
            let expected = if total > 0.0 {
                heads
                    .iter()
                    .zip(&weights)
                    .map(|(h, w)| *h * (w / total))
                    .sum()
            } else {
                heads.iter().sum::<DVec3>() / count as f64
            };
            let origin = ray_at(&mono, s, t).origin.as_dvec3();
            assert!(
                (origin - expected).length() < 2e-5,
                "{count}: {origin} vs {expected}"
            );
            blended += usize::from(weights.iter().filter(|w| **w > 0.0).count() > 1);
        }
        assert!(blended > 50, "{count}: {blended}");
    }
}

#[test]
fn block_rays_of_any_number_of_viewers_are_the_rays_made_one_by_one() {
    // Near and far planes and a cropped imageRegion (the clip and region arithmetic of the
    // block), 2, 6 and 20 viewers (each size has working memory of its own), mono and stereo
    // eyes, on every instruction-set path this CPU has; every field compared as bits.
    let screen = screens()[0];
    let mut sequence = unit_sequence(5);
    let mut unit = || sequence() as f32;
    let bits = |ray: &CameraRay| {
        let [o, d, c] = [
            ray.origin,
            ray.direction,
            ray.cyclopean.unwrap_or(Vec3::NAN),
        ]
        .map(|v| v.to_array().map(f32::to_bits));
        (o, d, c, ray.t_min.to_bits(), ray.t_max.to_bits())
    };
    let mut block = BlockRays::default();
    let mut checked = 0;
    for count in [2usize, 6, 20] {
        let heads: Vec<Vec3> = (0..count)
            .map(|i| {
                screen
                    .local(-0.3 + 0.6 * i as f64 / count as f64, 0.05, 1.2)
                    .as_vec3()
            })
            .collect();
        let gazes: Vec<Vec3> = heads
            .iter()
            .enumerate()
            .map(|(i, head)| {
                let target = screen.local(0.4 - 0.8 * i as f64 / count as f64, 0.1, 0.0);
                (target - head.as_dvec3()).as_vec3()
            })
            .collect();
        for weighting in WEIGHTINGS {
            let desc = OffAxisDesc {
                lower_left: Some(screen.ll.as_vec3()),
                lower_right: Some(screen.lr.as_vec3()),
                upper_right: Some(screen.ur.as_vec3()),
                stereo_mode: StereoMode::SideBySide,
                near: Some(0.05),
                far: Some(40.0),
                image_region: [0.1, 0.05, 0.8, 0.9],
                viewers: Some(ViewerDesc {
                    weighting,
                    cutoff_angle: 0.6,
                    ..ViewerDesc::new(heads.clone(), gazes.clone())
                }),
                ..OffAxisDesc::default()
            };
            let camera = super::screen::OffAxisCamera::new(&desc).unwrap();
            for eye in [Eye::Mono, Eye::Right] {
                let rays = rays(&camera, eye);
                let s: [f32; BLOCK_RAYS] = std::array::from_fn(|_| unit());
                let t: [f32; BLOCK_RAYS] = std::array::from_fn(|_| unit());
                for isa in crate::isa::test_paths() {
                    assert!(rays.block_rays_on_path(isa, &s, &t, &mut block));
                    for i in 0..BLOCK_RAYS {
                        let one = ray_at(&rays, s[i], t[i]);
                        assert!(one.t_min > 0.0 && one.t_max.is_finite());
                        assert_eq!(
                            bits(&block.ray(i)),
                            bits(&one),
                            "{count} viewers {weighting:?} {eye:?} {isa:?}"
                        );
                        checked += 1;
                    }
                }
            }
        }
    }
    assert!(checked >= 3 * 3 * 2 * BLOCK_RAYS, "{checked}");
}
