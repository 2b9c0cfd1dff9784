//! TEMPORARY brute-force stand-in until the accel module lands.
#![allow(clippy::collapsible_if)]
use glam::{Affine3A, UVec3, UVec4, Vec2, Vec3};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
static BUILDS: AtomicU64 = AtomicU64::new(0);
pub fn geometry_build_count() -> u64 {
    BUILDS.load(Ordering::SeqCst)
}
pub struct Ray {
    pub origin: Vec3,
    pub direction: Vec3,
    pub t_min: f32,
    pub t_max: f32,
}
pub enum GeometryPrims {
    Triangles {
        positions: Vec<Vec3>,
        indices: Vec<UVec3>,
    },
    Quads {
        positions: Vec<Vec3>,
        indices: Vec<UVec4>,
    },
    Spheres {
        centers: Vec<Vec3>,
        radii: Vec<f32>,
    },
    Cylinders {
        starts: Vec<Vec3>,
        ends: Vec<Vec3>,
        radii: Vec<f32>,
        caps: bool,
    },
}
pub struct PrimHit {
    pub t: f32,
    pub primitive: u32,
    pub uv: Vec2,
    pub normal: Vec3,
}
#[derive(Debug)]
pub struct GeometryBvh {
    tris: Vec<[Vec3; 3]>,
    ids: Vec<u32>,
}
impl GeometryBvh {
    pub fn build(prims: GeometryPrims) -> GeometryBvh {
        BUILDS.fetch_add(1, Ordering::SeqCst);
        let mut tris = Vec::new();
        let mut ids = Vec::new();
        if let GeometryPrims::Triangles { positions, indices } = prims {
            for (i, t) in indices.iter().enumerate() {
                tris.push([
                    positions[t.x as usize],
                    positions[t.y as usize],
                    positions[t.z as usize],
                ]);
                ids.push(i as u32);
            }
        }
        GeometryBvh { tris, ids }
    }
    pub fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        let mut best: Option<PrimHit> = None;
        for (k, t) in self.tris.iter().enumerate() {
            let e1 = t[1] - t[0];
            let e2 = t[2] - t[0];
            let p = ray.direction.cross(e2);
            let det = e1.dot(p);
            if det.abs() < 1e-12 {
                continue;
            }
            let inv = 1.0 / det;
            let s = ray.origin - t[0];
            let u = s.dot(p) * inv;
            if !(0.0..=1.0).contains(&u) {
                continue;
            }
            let q = s.cross(e1);
            let v = ray.direction.dot(q) * inv;
            if v < 0.0 || u + v > 1.0 {
                continue;
            }
            let d = e2.dot(q) * inv;
            if d >= ray.t_min && d <= ray.t_max && best.as_ref().is_none_or(|b| d < b.t) {
                best = Some(PrimHit {
                    t: d,
                    primitive: self.ids[k],
                    uv: Vec2::new(u, v),
                    normal: e1.cross(e2).normalize(),
                });
            }
        }
        best
    }
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.intersect(ray).is_some()
    }
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::INFINITY;
        let mut hi = Vec3::NEG_INFINITY;
        for t in &self.tris {
            for v in t {
                lo = lo.min(*v);
                hi = hi.max(*v);
            }
        }
        (lo, hi)
    }
    pub fn primitive_count(&self) -> usize {
        self.tris.len()
    }
    pub fn memory_bytes(&self) -> usize {
        self.tris.len() * 40
    }
}
pub struct InstanceDesc {
    pub transform: Affine3A,
    pub geometries: Vec<Arc<GeometryBvh>>,
}
pub struct SceneHit {
    pub t: f32,
    pub instance: u32,
    pub geometry: u32,
    pub primitive: u32,
    pub uv: Vec2,
    pub normal: Vec3,
    pub object_normal: Vec3,
}
pub struct SceneBvh {
    instances: Vec<InstanceDesc>,
}
impl SceneBvh {
    pub fn build(instances: Vec<InstanceDesc>) -> SceneBvh {
        SceneBvh { instances }
    }
    pub fn intersect(&self, ray: &Ray) -> Option<SceneHit> {
        let mut best: Option<SceneHit> = None;
        for (i, inst) in self.instances.iter().enumerate() {
            let inv = inst.transform.inverse();
            let o = inv.transform_point3(ray.origin);
            let d = inv.transform_vector3(ray.direction);
            for (g, geo) in inst.geometries.iter().enumerate() {
                if let Some(h) = geo.intersect(&Ray {
                    origin: o,
                    direction: d,
                    t_min: ray.t_min,
                    t_max: ray.t_max,
                }) {
                    if best.as_ref().is_none_or(|b| h.t < b.t) {
                        let n = (inst.transform.matrix3.inverse().transpose()
                            * glam::Vec3A::from(h.normal))
                        .normalize();
                        best = Some(SceneHit {
                            t: h.t,
                            instance: i as u32,
                            geometry: g as u32,
                            primitive: h.primitive,
                            uv: h.uv,
                            normal: n.into(),
                            object_normal: h.normal,
                        });
                    }
                }
            }
        }
        best
    }
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.intersect(ray).is_some()
    }
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::INFINITY;
        let mut hi = Vec3::NEG_INFINITY;
        for inst in &self.instances {
            for g in &inst.geometries {
                let (a, b) = g.bounds();
                if a.x <= b.x {
                    lo = lo.min(inst.transform.transform_point3(a));
                    hi = hi.max(inst.transform.transform_point3(b));
                }
            }
        }
        (lo, hi)
    }
}
