//! Geometry attributes (color, attribute0..3): uniform, per-vertex, per-corner (faceVarying) or
//! per-primitive values, evaluated at a hit point.

use glam::{Vec2, Vec4};

use crate::device::array::ArrayStore;
use crate::device::datatype::*;

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

/// Element types ANARI allows for arrays of values read as attributes (the specification's
/// Color types): what [`read_values`] reads.
pub const VALUE_ELEMENT_TYPES: &[ANARIDataType] = crate::device::spec::ATTRIBUTE_ELEMENT_TYPES;

/// Reads an array of any type in `VALUE_ELEMENT_TYPES` as attribute values: missing components
/// are (·, 0, 0, 1), fixed-point is normalised to [0, 1] and sRGB colour components are decoded
/// to linear (alpha stays linear). `None` for other element types.
pub fn read_values(store: &ArrayStore) -> Option<Vec<Vec4>> {
    if let Some(values) = store.read_attribute() {
        return Some(values);
    }
    // The types `read_attribute` does not cover.
    let (components, scalar_bytes, srgb) = match store.element_type {
        ANARI_UFIXED8_R_SRGB => (1, 1, true),
        ANARI_UFIXED8_RA_SRGB => (2, 1, true),
        ANARI_UFIXED8_RGB_SRGB => (3, 1, true),
        ANARI_UFIXED32 => (1, 4, false),
        ANARI_UFIXED32_VEC2 => (2, 4, false),
        ANARI_UFIXED32_VEC3 => (3, 4, false),
        ANARI_UFIXED32_VEC4 => (4, 4, false),
        _ => return None,
    };
    // RA: the second component is alpha, which sRGB leaves linear.
    let colour_components = if components == 2 {
        1
    } else {
        components.min(3)
    };
    Some(store.with_bytes(|bytes| {
        bytes
            .chunks_exact(components * scalar_bytes)
            .map(|element| {
                let mut value = ATTRIBUTE_DEFAULT;
                for (k, scalar) in element.chunks_exact(scalar_bytes).enumerate() {
                    let v = match scalar_bytes {
                        1 => scalar[0] as f32 / 255.0,
                        _ => {
                            let raw = u32::from_ne_bytes(scalar.try_into().unwrap_or([0; 4]));
                            (raw as f64 / u32::MAX as f64) as f32
                        }
                    };
                    value[k] = if srgb && k < colour_components {
                        crate::device::array::srgb_to_linear(v)
                    } else {
                        v
                    };
                }
                value
            })
            .collect()
    }))
}

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

    fn store(element_type: ANARIDataType, bytes: &[u8], count: u64) -> ArrayStore {
        let store = ArrayStore::new(
            element_type,
            [count, 1, 1],
            std::ptr::null(),
            None,
            std::ptr::null(),
        )
        .unwrap();
        // SAFETY: the managed store holds `count` elements, exactly `bytes.len()` bytes.
        unsafe {
            std::ptr::copy_nonoverlapping(
                bytes.as_ptr(),
                store.data_pointer() as *mut u8,
                bytes.len(),
            )
        };
        store
    }

    #[test]
    fn value_arrays_of_every_fixed_point_kind_read_as_attributes() {
        let half = u32::MAX / 2;
        let mut bytes = Vec::new();
        for v in [u32::MAX, half, 0] {
            bytes.extend_from_slice(&v.to_ne_bytes());
        }
        let values = read_values(&store(ANARI_UFIXED32_VEC3, &bytes, 1)).unwrap();
        assert_eq!(values[0].x, 1.0);
        assert!((values[0].y - 0.5).abs() < 1e-6);
        assert_eq!((values[0].z, values[0].w), (0.0, 1.0));
        // 188 is sRGB for linear 0.5029; alpha 128 stays 128/255.
        let values = read_values(&store(ANARI_UFIXED8_RA_SRGB, &[188, 128], 1)).unwrap();
        assert!((values[0].x - 0.5029).abs() < 2e-3, "{}", values[0].x);
        assert!((values[0].y - 128.0 / 255.0).abs() < 1e-6);
        assert_eq!((values[0].z, values[0].w), (0.0, 1.0));
        let values = read_values(&store(ANARI_UFIXED8_R_SRGB, &[255, 0], 2)).unwrap();
        assert_eq!(
            values,
            vec![Vec4::new(1.0, 0.0, 0.0, 1.0), ATTRIBUTE_DEFAULT]
        );
        let values = read_values(&store(ANARI_UFIXED8_RGB_SRGB, &[255, 0, 188], 1)).unwrap();
        assert!((values[0].z - 0.5029).abs() < 2e-3 && values[0].x == 1.0);
        assert!(read_values(&store(ANARI_INT32, &[0; 4], 1)).is_none());
        for t in VALUE_ELEMENT_TYPES {
            let size = crate::device::datatype::element_size(*t).unwrap();
            assert!(read_values(&store(*t, &vec![0; size], 1)).is_some(), "{t}");
        }
    }

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
