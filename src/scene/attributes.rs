//! Geometry attributes (color, attribute0..3): uniform, per-vertex, per-corner (faceVarying) or
//! per-primitive values, evaluated at a hit point.

use glam::{Vec2, Vec4};

/// The five attribute slots a geometry carries, in this order.
pub const ATTRIBUTE_NAMES: [&str; 5] = [
    "color",
    "attribute0",
    "attribute1",
    "attribute2",
    "attribute3",
];

/// Index of a named attribute slot ("color" → 0, "attribute3" → 4).
pub fn attribute_slot(name: &str) -> Option<usize> {
    ATTRIBUTE_NAMES.iter().position(|n| *n == name)
}

/// The value an unset attribute reads as (ANARI: (0,0,0,1)).
pub const ATTRIBUTE_DEFAULT: Vec4 = Vec4::new(0.0, 0.0, 0.0, 1.0);

/// Where one attribute's values come from. More specific sources win: per-vertex or
/// per-corner values are interpolated; otherwise per-primitive, otherwise the uniform value.
#[derive(Clone, Debug, Default)]
pub struct Attribute {
    pub uniform: Option<Vec4>,
    pub per_vertex: Option<Vec<Vec4>>,
    pub per_corner: Option<Vec<Vec4>>,
    pub per_primitive: Option<Vec<Vec4>>,
}

/// Which vertices (and corners) a hit interpolates between, with weights.
#[derive(Clone, Copy, Debug)]
pub struct Interpolation {
    pub vertices: [u32; 4],
    /// Corner numbers (primitive × corners + k) for faceVarying data.
    pub corners: [u32; 4],
    pub weights: [f32; 4],
    pub count: usize,
}

impl Interpolation {
    pub fn single(vertex: u32) -> Interpolation {
        Interpolation {
            vertices: [vertex, 0, 0, 0],
            corners: [vertex, 0, 0, 0],
            weights: [1.0, 0.0, 0.0, 0.0],
            count: 1,
        }
    }

    fn blend(&self, values: &[Vec4], indices: &[u32; 4]) -> Option<Vec4> {
        let mut sum = Vec4::ZERO;
        for (index, weight) in indices.iter().zip(self.weights).take(self.count) {
            sum += *values.get(*index as usize)? * weight;
        }
        Some(sum)
    }
}

impl Attribute {
    pub fn is_set(&self) -> bool {
        self.uniform.is_some()
            || self.per_vertex.is_some()
            || self.per_corner.is_some()
            || self.per_primitive.is_some()
    }

    /// The attribute at a hit on `primitive`; `None` when the attribute is not set.
    pub fn evaluate(&self, primitive: u32, at: &Interpolation) -> Option<Vec4> {
        if let Some(values) = &self.per_corner
            && let Some(v) = at.blend(values, &at.corners)
        {
            return Some(v);
        }
        if let Some(values) = &self.per_vertex
            && let Some(v) = at.blend(values, &at.vertices)
        {
            return Some(v);
        }
        if let Some(v) = self
            .per_primitive
            .as_ref()
            .and_then(|values| values.get(primitive as usize))
        {
            return Some(*v);
        }
        self.uniform
    }

    pub fn memory_bytes(&self) -> usize {
        [&self.per_vertex, &self.per_corner, &self.per_primitive]
            .iter()
            .map(|v| v.as_ref().map_or(0, |v| v.len() * 16))
            .sum()
    }
}

/// Barycentric weights for a triangle hit with coordinates (b1, b2).
pub fn triangle_weights(uv: Vec2) -> [f32; 3] {
    [1.0 - uv.x - uv.y, uv.x, uv.y]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertex_values_interpolate_and_primitive_values_fall_back() {
        let attribute = Attribute {
            uniform: Some(Vec4::splat(9.0)),
            per_vertex: Some(vec![Vec4::X, Vec4::Y, Vec4::Z]),
            per_corner: None,
            per_primitive: Some(vec![Vec4::W]),
        };
        let w = triangle_weights(Vec2::new(0.25, 0.5));
        let at = Interpolation {
            vertices: [0, 1, 2, 0],
            corners: [0, 1, 2, 0],
            weights: [w[0], w[1], w[2], 0.0],
            count: 3,
        };
        assert_eq!(
            attribute.evaluate(0, &at),
            Some(Vec4::new(0.25, 0.25, 0.5, 0.0))
        );
        let only_primitive = Attribute {
            per_primitive: Some(vec![Vec4::W, Vec4::X]),
            ..Default::default()
        };
        assert_eq!(only_primitive.evaluate(1, &at), Some(Vec4::X));
        assert_eq!(Attribute::default().evaluate(0, &at), None);
        assert_eq!(attribute_slot("attribute2"), Some(3));
    }
}
