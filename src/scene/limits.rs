//! Size limits of a geometry commit, checked before any array is read: element counts against
//! what a geometry can index (the device property "geometryMaxIndex"), and the memory the
//! commit will take (copies of the arrays, primitive lists, the BVH and its build) against the
//! memory available.

use crate::device::memory::{self, TooBig};
use crate::device::params::ParamSet;
use crate::device::property::GEOMETRY_MAX_INDEX;
use crate::device::status::{ANARI_STATUS_INVALID_ARGUMENT, ANARI_STATUS_OUT_OF_MEMORY};

/// The arrays whose element counts are indexed by 32-bit vertex indices and primitive ids.
const INDEXED: &[&str] = &["vertex.position", "primitive.index"];

/// Bytes a commit takes per array element read (arrays are read into at most 16-byte values).
const BYTES_PER_ELEMENT: u64 = 16;
/// Bytes a commit takes per primitive: kept primitive data and ids, the BVH (about 66 bytes per
/// triangle) and the build's temporary copies.
const BYTES_PER_PRIMITIVE: u64 = 160;

/// Why a geometry cannot be committed: a status code and the reason.
pub struct Refusal {
    pub code: i32,
    pub reason: String,
}

/// Checks a geometry's committed arrays before they are read.
pub fn check_geometry(params: &ParamSet) -> Result<(), Refusal> {
    let limit = GEOMETRY_MAX_INDEX + 1;
    let count = |name: &str| {
        params
            .get_object(name)
            .and_then(|o| o.array.as_ref())
            .map(|a| a.dims.iter().product::<u64>())
    };
    for name in INDEXED {
        if let Some(elements) = count(name)
            && elements > limit
        {
            return Err(Refusal {
                code: ANARI_STATUS_INVALID_ARGUMENT,
                reason: format!(
                    "'{name}' has {elements} elements; a geometry indexes at most \
                     geometryMaxIndex + 1 = {limit}"
                ),
            });
        }
    }
    let primitives = count("primitive.index")
        .or_else(|| count("vertex.position"))
        .unwrap_or(0);
    let elements: u64 = params.names().filter_map(count).sum();
    let needed = elements
        .saturating_mul(BYTES_PER_ELEMENT)
        .saturating_add(primitives.saturating_mul(BYTES_PER_PRIMITIVE));
    memory::check(needed).map_err(|TooBig { needed, available }| Refusal {
        code: ANARI_STATUS_OUT_OF_MEMORY,
        reason: format!(
            "has {primitives} primitives and {elements} array elements: its commit would {}",
            TooBig { needed, available }
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::array::ArrayStore;
    use crate::device::datatype::*;
    use crate::device::object::Object;
    use crate::device::params::ParamValue;
    use std::sync::Arc;

    /// A shared array that claims `count` elements of `element_type` (never read).
    fn claimed(element_type: ANARIDataType, count: u64) -> ParamValue {
        static BYTES: [u64; 4] = [0; 4];
        let store = ArrayStore::new(
            element_type,
            [count, 1, 1],
            BYTES.as_ptr().cast(),
            None,
            std::ptr::null(),
        )
        .unwrap();
        ParamValue::Object {
            data_type: ANARI_ARRAY1D,
            object: Arc::new(Object::new(16, ANARI_ARRAY1D, "", None, Some(store), None)),
        }
    }

    #[test]
    fn counts_beyond_the_max_index_are_refused_before_reading() {
        let mut params = ParamSet::default();
        params.set("vertex.position", claimed(ANARI_FLOAT32_VEC3, 3));
        assert!(check_geometry(&params).is_ok());
        params.set(
            "primitive.index",
            claimed(ANARI_UINT32_VEC3, GEOMETRY_MAX_INDEX + 2),
        );
        let refusal = check_geometry(&params).unwrap_err();
        assert_eq!(refusal.code, ANARI_STATUS_INVALID_ARGUMENT);
        assert!(
            refusal
                .reason
                .contains("'primitive.index' has 4294967296 elements"),
            "{}",
            refusal.reason
        );
    }
}
