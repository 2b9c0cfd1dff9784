//! TEMPORARY stand-in until the camera module lands.
use crate::device::Device;
use crate::device::object::Object;
use crate::device::spec::ObjectSpec;
use glam::{Vec2, Vec3};
use std::sync::Arc;

pub const SPECS: &[ObjectSpec] = &[ObjectSpec::new(
    crate::device::datatype::ANARI_CAMERA,
    "perspective",
    "stub",
    &[crate::device::spec::ParamSpec::new(
        "position",
        &[crate::device::datatype::ANARI_FLOAT32_VEC3],
        "p",
    )],
)];
pub struct CameraRay {
    pub origin: Vec3,
    pub direction: Vec3,
    pub t_min: f32,
    pub t_max: f32,
}
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Eye {
    Mono,
    Left,
    Right,
}
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EyeViewport {
    pub eye: Eye,
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}
pub trait Camera: Send + Sync + std::fmt::Debug {
    fn viewports(&self, width: u32, height: u32) -> Vec<EyeViewport>;
    fn prepare(&self, eye: Eye, w: u32, h: u32) -> EyeRays;
}
pub struct EyeRays {
    pos: Vec3,
    aspect: f32,
}
impl EyeRays {
    pub fn ray(&self, s: f32, t: f32, _lens: Vec2) -> CameraRay {
        let h = (std::f32::consts::FRAC_PI_3 / 2.0).tan();
        let d = Vec3::new((2.0 * s - 1.0) * h * self.aspect, (2.0 * t - 1.0) * h, -1.0).normalize();
        CameraRay {
            origin: self.pos,
            direction: d,
            t_min: 0.0,
            t_max: f32::INFINITY,
        }
    }
    pub fn depth(&self, _ray: &CameraRay, t: f32) -> f32 {
        t
    }
    pub fn window_depth(&self, _p: Vec3) -> f32 {
        0.5
    }
}
#[derive(Debug)]
struct Persp {
    pos: Vec3,
}
impl Camera for Persp {
    fn viewports(&self, width: u32, height: u32) -> Vec<EyeViewport> {
        vec![EyeViewport {
            eye: Eye::Mono,
            x: 0,
            y: 0,
            width,
            height,
        }]
    }
    fn prepare(&self, _eye: Eye, w: u32, h: u32) -> EyeRays {
        EyeRays {
            pos: self.pos,
            aspect: w as f32 / h as f32,
        }
    }
}
pub struct CameraModel(pub Arc<dyn Camera>);
pub fn commit(_device: &Device, object: &Object) {
    let p = object.committed();
    let pos = p.get_vec3("position").unwrap_or(Vec3::ZERO);
    object.set_derived(Some(Arc::new(CameraModel(Arc::new(Persp { pos })))));
}
