//! Shared test fixtures: CAVE screens of every orientation, eyes in front of them, and
//! ray/plane helpers.

use glam::{DMat4, DQuat, DVec3, EulerRot, Vec2};

use super::{CameraRay, EyeRays};

/// Frame size used by the per-pixel tests: odd and non-square on purpose.
pub(crate) const WIDTH: u32 = 37;
pub(crate) const HEIGHT: u32 = 23;

#[derive(Clone, Copy, Debug)]
pub(crate) struct Screen {
    pub name: &'static str,
    pub ll: DVec3,
    pub lr: DVec3,
    pub ur: DVec3,
}

impl Screen {
    pub fn width_axis(&self) -> DVec3 {
        self.lr - self.ll
    }

    pub fn height_axis(&self) -> DVec3 {
        self.ur - self.lr
    }

    /// Unit normal towards the viewer (X × Y).
    pub fn normal(&self) -> DVec3 {
        self.width_axis().cross(self.height_axis()).normalize()
    }

    pub fn centre(&self) -> DVec3 {
        self.ll + 0.5 * (self.width_axis() + self.height_axis())
    }

    /// The point that the invariant says pixel coordinate (s, t) maps to.
    pub fn point(&self, s: f64, t: f64) -> DVec3 {
        self.ll + s * self.width_axis() + t * self.height_axis()
    }

    /// A point given in screen units: `a` screen widths right of the centre, `b` screen heights
    /// above it, `d` meters in front of the plane.
    pub fn local(&self, a: f64, b: f64, d: f64) -> DVec3 {
        self.centre() + a * self.width_axis() + b * self.height_axis() + d * self.normal()
    }

    /// Eyes in front of the screen: centred, near a corner, far off to the side (the screen
    /// lies entirely on one side of the view axis), and off-centre both ways.
    pub fn eyes(&self) -> Vec<DVec3> {
        vec![
            self.local(0.0, 0.0, 2.0),
            self.local(0.45, 0.4, 0.3),
            self.local(-2.5, 0.1, 0.8),
            self.local(1.3, -1.1, 3.0),
            self.local(0.2, 2.0, 0.5),
        ]
    }
}

/// CAVE walls (3 m cube, floor at y = 0, centred on the origin), plus a tilted and two
/// non-square screens. Corner order is always ll, lr, ur as seen from inside.
pub(crate) fn screens() -> Vec<Screen> {
    let v = DVec3::new;
    let rotation = DQuat::from_euler(EulerRot::YXZ, 0.7, -0.45, 0.3);
    let offset = v(0.4, 1.3, -0.9);
    let tilt = |p: DVec3| rotation * p + offset;
    vec![
        Screen {
            name: "front",
            ll: v(-1.5, 0.0, -1.5),
            lr: v(1.5, 0.0, -1.5),
            ur: v(1.5, 3.0, -1.5),
        },
        Screen {
            name: "left",
            ll: v(-1.5, 0.0, 1.5),
            lr: v(-1.5, 0.0, -1.5),
            ur: v(-1.5, 3.0, -1.5),
        },
        Screen {
            name: "right",
            ll: v(1.5, 0.0, -1.5),
            lr: v(1.5, 0.0, 1.5),
            ur: v(1.5, 3.0, 1.5),
        },
        Screen {
            name: "floor",
            ll: v(-1.5, 0.0, 1.5),
            lr: v(1.5, 0.0, 1.5),
            ur: v(1.5, 0.0, -1.5),
        },
        Screen {
            name: "ceiling",
            ll: v(-1.5, 3.0, -1.5),
            lr: v(1.5, 3.0, -1.5),
            ur: v(1.5, 3.0, 1.5),
        },
        Screen {
            name: "tilted",
            ll: tilt(v(-1.2, -0.8, 0.0)),
            lr: tilt(v(1.2, -0.8, 0.0)),
            ur: tilt(v(1.2, 0.8, 0.0)),
        },
        Screen {
            name: "wide powerwall",
            ll: v(-2.0, 0.5, -2.0),
            lr: v(2.0, 0.5, -2.0),
            ur: v(2.0, 2.75, -2.0),
        },
        Screen {
            name: "tall, far from the origin",
            ll: v(101.0, 50.0, 30.0),
            lr: v(101.0, 50.0, 29.2),
            ur: v(101.0, 52.1, 29.2),
        },
    ]
}

/// Pixel centres of a `width`×`height` frame as (x, y, s, t).
pub(crate) fn pixel_centres(width: u32, height: u32) -> impl Iterator<Item = (u32, u32, f32, f32)> {
    (0..height).flat_map(move |y| {
        (0..width).map(move |x| {
            let s = (x as f32 + 0.5) / width as f32;
            let t = (y as f32 + 0.5) / height as f32;
            (x, y, s, t)
        })
    })
}

/// Where `ray` meets the plane through `point` with normal `normal`, and the ray parameter.
pub(crate) fn hit_plane(ray: &CameraRay, point: DVec3, normal: DVec3) -> (DVec3, f64) {
    let origin = ray.origin.as_dvec3();
    let direction = ray.direction.as_dvec3();
    let t = (point - origin).dot(normal) / direction.dot(normal);
    (origin + t * direction, t)
}

pub(crate) fn angle_between(a: glam::Vec3, b: glam::Vec3) -> f64 {
    let a = a.as_dvec3().normalize();
    let b = b.as_dvec3().normalize();
    // atan2 of |a×b| and a·b stays accurate for tiny angles, unlike acos.
    a.cross(b).length().atan2(a.dot(b))
}

/// Checks the CAVE invariant for every pixel centre of a `WIDTH`×`HEIGHT` frame and returns the
/// largest deviation from the expected screen point (meters).
pub(crate) fn max_screen_error(rays: &EyeRays, screen: &Screen) -> f64 {
    let mut worst: f64 = 0.0;
    for (_, _, s, t) in pixel_centres(WIDTH, HEIGHT) {
        let ray = rays.ray(s, t, Vec2::ZERO);
        assert!(
            (ray.direction.length() - 1.0).abs() < 1e-6,
            "direction not unit: {ray:?}"
        );
        let (hit, t_hit) = hit_plane(&ray, screen.ll, screen.normal());
        assert!(
            t_hit > 0.0,
            "{}: screen behind the ray {ray:?}",
            screen.name
        );
        let expected = screen.point(f64::from(s), f64::from(t));
        worst = worst.max((hit - expected).length());
    }
    worst
}

/// The OpenGL window depth that `proj·view` gives `p` (reference for the tests).
pub(crate) fn gl_window_depth(view: DMat4, proj: DMat4, p: DVec3) -> f64 {
    let clip = proj * view * p.extend(1.0);
    0.5 * clip.z / clip.w + 0.5
}

/// A deterministic sequence of numbers in [0, 1) (a linear congruential generator's top 24
/// bits), for tests that sample many points.
pub(crate) fn unit_sequence(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 40) as f64 / (1u64 << 24) as f64
    }
}
