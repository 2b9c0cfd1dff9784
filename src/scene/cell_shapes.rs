//! The four linear cell shapes of unstructured fields, with VTK's vertex order and parametric
//! coordinates: tetrahedron (VTK 10), hexahedron (12), wedge (13) and pyramid (14). A cell maps
//! parametric coordinates ξ to space by its shape functions, `x(ξ) = Σ wᵢ(ξ) pᵢ`, and a
//! vertex-centred field inside it is `Σ wᵢ(ξ) vᵢ`. Locating a point means inverting that map
//! (Newton's method, exact in one step for tetrahedra, whose map is affine). Everything here
//! runs in f64.

use glam::{DMat3, DVec3};

/// A cell shape, numbered as VTK numbers it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CellShape {
    Tetrahedron,
    Hexahedron,
    Wedge,
    Pyramid,
}

/// The most vertices a cell has (hexahedra).
pub(crate) const MAX_CELL_VERTICES: usize = 8;

/// Parametric slack when deciding whether a point is inside a cell: points on a shared face
/// belong to both cells, and rounding must not open a crack between them.
const INSIDE_TOLERANCE: f64 = 1e-7;
const NEWTON_ITERATIONS: usize = 24;

impl CellShape {
    /// The VTK cell type codes the extension names; `None` for any other.
    pub fn from_vtk(code: u8) -> Option<CellShape> {
        match code {
            10 => Some(CellShape::Tetrahedron),
            12 => Some(CellShape::Hexahedron),
            13 => Some(CellShape::Wedge),
            14 => Some(CellShape::Pyramid),
            _ => None,
        }
    }

    pub fn vertex_count(self) -> usize {
        match self {
            CellShape::Tetrahedron => 4,
            CellShape::Hexahedron => 8,
            CellShape::Wedge => 6,
            CellShape::Pyramid => 5,
        }
    }

    /// Faces as vertex lists (for clipping rays to the cell).
    pub fn faces(self) -> &'static [&'static [usize]] {
        match self {
            CellShape::Tetrahedron => &[&[0, 1, 2], &[0, 1, 3], &[1, 2, 3], &[0, 2, 3]],
            CellShape::Hexahedron => &[
                &[0, 1, 2, 3],
                &[4, 5, 6, 7],
                &[0, 1, 5, 4],
                &[1, 2, 6, 5],
                &[2, 3, 7, 6],
                &[3, 0, 4, 7],
            ],
            CellShape::Wedge => &[
                &[0, 1, 2],
                &[3, 4, 5],
                &[0, 1, 4, 3],
                &[1, 2, 5, 4],
                &[2, 0, 3, 5],
            ],
            CellShape::Pyramid => &[
                &[0, 1, 2, 3],
                &[0, 1, 4],
                &[1, 2, 4],
                &[2, 3, 4],
                &[3, 0, 4],
            ],
        }
    }

    /// Shape-function weights at ξ (VTK's interpolation functions), and their derivatives.
    pub fn weights(self, xi: DVec3) -> ([f64; MAX_CELL_VERTICES], [DVec3; MAX_CELL_VERTICES]) {
        let (r, s, t) = (xi.x, xi.y, xi.z);
        let mut w = [0.0; MAX_CELL_VERTICES];
        let mut d = [DVec3::ZERO; MAX_CELL_VERTICES];
        match self {
            CellShape::Tetrahedron => {
                w[..4].copy_from_slice(&[1.0 - r - s - t, r, s, t]);
                d[..4].copy_from_slice(&[DVec3::splat(-1.0), DVec3::X, DVec3::Y, DVec3::Z]);
            }
            CellShape::Hexahedron => {
                for (i, corner) in HEX_CORNERS.iter().enumerate() {
                    let f = |c: f64, x: f64| if c == 0.0 { 1.0 - x } else { x };
                    let g = |c: f64| if c == 0.0 { -1.0 } else { 1.0 };
                    let (fr, fs, ft) = (f(corner[0], r), f(corner[1], s), f(corner[2], t));
                    w[i] = fr * fs * ft;
                    d[i] = DVec3::new(
                        g(corner[0]) * fs * ft,
                        fr * g(corner[1]) * ft,
                        fr * fs * g(corner[2]),
                    );
                }
            }
            CellShape::Wedge => {
                let tri = [1.0 - r - s, r, s];
                let tri_d = [DVec3::new(-1.0, -1.0, 0.0), DVec3::X, DVec3::Y];
                for k in 0..3 {
                    w[k] = tri[k] * (1.0 - t);
                    w[k + 3] = tri[k] * t;
                    d[k] = tri_d[k] * (1.0 - t) - DVec3::Z * tri[k];
                    d[k + 3] = tri_d[k] * t + DVec3::Z * tri[k];
                }
            }
            CellShape::Pyramid => {
                let (rm, sm, tm) = (1.0 - r, 1.0 - s, 1.0 - t);
                w[..5].copy_from_slice(&[rm * sm * tm, r * sm * tm, r * s * tm, rm * s * tm, t]);
                d[..5].copy_from_slice(&[
                    DVec3::new(-sm * tm, -rm * tm, -rm * sm),
                    DVec3::new(sm * tm, -r * tm, -r * sm),
                    DVec3::new(s * tm, r * tm, -r * s),
                    DVec3::new(-s * tm, rm * tm, -rm * s),
                    DVec3::Z,
                ]);
            }
        }
        (w, d)
    }

    /// Whether ξ lies in the cell's parametric domain (with a little slack).
    pub fn contains(self, xi: DVec3) -> bool {
        let e = INSIDE_TOLERANCE;
        let unit = |x: f64| (-e..=1.0 + e).contains(&x);
        match self {
            CellShape::Tetrahedron => xi.min_element() >= -e && xi.element_sum() <= 1.0 + e,
            CellShape::Hexahedron | CellShape::Pyramid => unit(xi.x) && unit(xi.y) && unit(xi.z),
            CellShape::Wedge => xi.x >= -e && xi.y >= -e && xi.x + xi.y <= 1.0 + e && unit(xi.z),
        }
    }

    /// A point well inside the parametric domain, where Newton's method starts.
    fn centre(self) -> DVec3 {
        match self {
            CellShape::Tetrahedron => DVec3::splat(0.25),
            CellShape::Hexahedron => DVec3::splat(0.5),
            CellShape::Wedge => DVec3::new(1.0 / 3.0, 1.0 / 3.0, 0.5),
            CellShape::Pyramid => DVec3::new(0.5, 0.5, 0.2),
        }
    }
}

/// Parametric corners of the hexahedron in VTK order.
const HEX_CORNERS: [[f64; 3]; 8] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, 1.0],
    [1.0, 0.0, 1.0],
    [1.0, 1.0, 1.0],
    [0.0, 1.0, 1.0],
];

/// One cell's geometry, gathered from the field's arrays.
#[derive(Clone, Copy, Debug)]
pub struct CellGeometry {
    pub shape: CellShape,
    pub points: [DVec3; MAX_CELL_VERTICES],
}

impl CellGeometry {
    fn vertices(&self) -> &[DVec3] {
        &self.points[..self.shape.vertex_count()]
    }

    /// The point at ξ and the Jacobian ∂x/∂ξ there (columns: ∂x/∂r, ∂x/∂s, ∂x/∂t).
    pub fn map(&self, xi: DVec3) -> (DVec3, DMat3) {
        let (w, d) = self.shape.weights(xi);
        let mut x = DVec3::ZERO;
        let mut jacobian = DMat3::ZERO;
        for (i, p) in self.vertices().iter().enumerate() {
            x += *p * w[i];
            jacobian.x_axis += *p * d[i].x;
            jacobian.y_axis += *p * d[i].y;
            jacobian.z_axis += *p * d[i].z;
        }
        (x, jacobian)
    }

    /// Parametric coordinates of `point` when it lies in the cell.
    pub fn locate(&self, point: DVec3) -> Option<DVec3> {
        self.parametric(point).filter(|xi| self.shape.contains(*xi))
    }

    /// Parametric coordinates of `point` by Newton's method, inside the cell or not.
    pub fn parametric(&self, point: DVec3) -> Option<DVec3> {
        let scale = self
            .vertices()
            .iter()
            .map(|p| (*p - self.points[0]).abs().max_element())
            .fold(0.0, f64::max);
        let mut xi = self.shape.centre();
        for _ in 0..NEWTON_ITERATIONS {
            let (x, jacobian) = self.map(xi);
            let residual = point - x;
            let determinant = jacobian.determinant();
            if determinant.abs() <= f64::MIN_POSITIVE || !determinant.is_finite() {
                return None;
            }
            let step = jacobian.inverse() * residual;
            xi += step;
            if step.abs().max_element() < 1e-13 || residual.abs().max_element() <= scale * 1e-15 {
                break;
            }
        }
        xi.is_finite().then_some(xi)
    }

    /// Gradient in space of the interpolant of `values` at ξ (`J⁻ᵀ ∇ξ`).
    pub fn gradient(&self, xi: DVec3, values: &[f64]) -> DVec3 {
        let (_, d) = self.shape.weights(xi);
        let (_, jacobian) = self.map(xi);
        let parametric: DVec3 = values.iter().zip(d).map(|(v, d)| d * *v).sum();
        jacobian.inverse().transpose() * parametric
    }

    /// The interval of `origin + t direction` inside the cell, faces taken as planes (each
    /// quadrilateral's best-fit plane); `None` when the ray misses.
    pub fn clip(&self, origin: DVec3, direction: DVec3) -> Option<(f64, f64)> {
        let centroid = self.vertices().iter().sum::<DVec3>() / self.shape.vertex_count() as f64;
        let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
        for face in self.shape.faces() {
            // Newell's normal, oriented away from the centroid.
            let mut normal = DVec3::ZERO;
            let mut middle = DVec3::ZERO;
            for (k, &a) in face.iter().enumerate() {
                let (p, q) = (self.points[a], self.points[face[(k + 1) % face.len()]]);
                normal += p.cross(q);
                middle += p;
            }
            middle /= face.len() as f64;
            if normal.dot(middle - centroid) < 0.0 {
                normal = -normal;
            }
            let distance = normal.dot(middle - origin);
            let speed = normal.dot(direction);
            if speed == 0.0 {
                if distance < 0.0 {
                    return None;
                }
                continue;
            }
            let t = distance / speed;
            if speed > 0.0 {
                t1 = t1.min(t);
            } else {
                t0 = t0.max(t);
            }
        }
        (t0 <= t1).then_some((t0, t1))
    }

    /// The cell's edges are an affine image of its parametric domain (a parallelepiped for
    /// hexahedra): then its trilinear interpolant is a polynomial in the ray parameter.
    pub fn affine_frame(&self) -> Option<(DVec3, DMat3)> {
        if self.shape != CellShape::Hexahedron {
            return None;
        }
        let origin = self.points[0];
        let frame = DMat3::from_cols(
            self.points[1] - origin,
            self.points[3] - origin,
            self.points[4] - origin,
        );
        let size = frame.x_axis.length() + frame.y_axis.length() + frame.z_axis.length();
        let affine = HEX_CORNERS.iter().zip(self.points).all(|(corner, p)| {
            let expected = origin + frame * DVec3::from_array(*corner);
            (expected - p).length() <= size * 1e-9
        });
        (affine && frame.determinant().abs() > 0.0).then_some((origin, frame))
    }
}

/// Reorders the eight values of a hexahedron from VTK order to the bit order `x + 2y + 4z`.
pub fn hex_values_in_bit_order(values: &[f64]) -> [f64; 8] {
    [
        values[0], values[1], values[3], values[2], values[4], values[5], values[7], values[6],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_sum_to_one_and_vertices_map_to_themselves() {
        for shape in [
            CellShape::Tetrahedron,
            CellShape::Hexahedron,
            CellShape::Wedge,
            CellShape::Pyramid,
        ] {
            let xi = DVec3::new(0.21, 0.13, 0.37);
            let (w, d) = shape.weights(xi);
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-14, "{shape:?}");
            assert!(d.iter().sum::<DVec3>().length() < 1e-14, "{shape:?}");
            // Numerical derivative agrees with the analytic one.
            let h = 1e-6;
            for axis in 0..3 {
                let mut step = DVec3::ZERO;
                step[axis] = h;
                let (wp, _) = shape.weights(xi + step);
                for i in 0..shape.vertex_count() {
                    assert!(
                        ((wp[i] - w[i]) / h - d[i][axis]).abs() < 1e-5,
                        "{shape:?} {i}"
                    );
                }
            }
        }
    }
}
