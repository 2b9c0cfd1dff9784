//! ANARI data types: the numeric values of the Khronos ANARI 1.0 `ANARIDataType` enum, their
//! names and element sizes. One table serves validation, array sizing and introspection.

use std::os::raw::c_int;

/// `ANARIDataType` in C: a plain `int`.
pub type ANARIDataType = c_int;

pub const ANARI_UNKNOWN: ANARIDataType = 0;
pub const ANARI_DATA_TYPE: ANARIDataType = 100;
pub const ANARI_STRING: ANARIDataType = 101;
pub const ANARI_VOID_POINTER: ANARIDataType = 102;
pub const ANARI_BOOL: ANARIDataType = 103;
pub const ANARI_STRING_LIST: ANARIDataType = 150;
pub const ANARI_DATA_TYPE_LIST: ANARIDataType = 151;
pub const ANARI_PARAMETER_LIST: ANARIDataType = 152;
pub const ANARI_FUNCTION_POINTER: ANARIDataType = 200;
pub const ANARI_MEMORY_DELETER: ANARIDataType = 201;
pub const ANARI_STATUS_CALLBACK: ANARIDataType = 202;
/// From KHR_FRAME_COMPLETION_CALLBACK.
pub const ANARI_FRAME_COMPLETION_CALLBACK: ANARIDataType = 203;
pub const ANARI_LIBRARY: ANARIDataType = 500;
pub const ANARI_DEVICE: ANARIDataType = 501;
pub const ANARI_OBJECT: ANARIDataType = 502;
pub const ANARI_ARRAY: ANARIDataType = 503;
pub const ANARI_ARRAY1D: ANARIDataType = 504;
pub const ANARI_ARRAY2D: ANARIDataType = 505;
pub const ANARI_ARRAY3D: ANARIDataType = 506;
pub const ANARI_CAMERA: ANARIDataType = 507;
pub const ANARI_FRAME: ANARIDataType = 508;
pub const ANARI_GEOMETRY: ANARIDataType = 509;
pub const ANARI_GROUP: ANARIDataType = 510;
pub const ANARI_INSTANCE: ANARIDataType = 511;
pub const ANARI_LIGHT: ANARIDataType = 512;
pub const ANARI_MATERIAL: ANARIDataType = 513;
pub const ANARI_RENDERER: ANARIDataType = 514;
pub const ANARI_SURFACE: ANARIDataType = 515;
pub const ANARI_SAMPLER: ANARIDataType = 516;
pub const ANARI_SPATIAL_FIELD: ANARIDataType = 517;
pub const ANARI_VOLUME: ANARIDataType = 518;
pub const ANARI_WORLD: ANARIDataType = 519;
pub const ANARI_INT8: ANARIDataType = 1000;
pub const ANARI_INT8_VEC2: ANARIDataType = 1001;
pub const ANARI_INT8_VEC3: ANARIDataType = 1002;
pub const ANARI_INT8_VEC4: ANARIDataType = 1003;
pub const ANARI_UINT8: ANARIDataType = 1004;
pub const ANARI_UINT8_VEC2: ANARIDataType = 1005;
pub const ANARI_UINT8_VEC3: ANARIDataType = 1006;
pub const ANARI_UINT8_VEC4: ANARIDataType = 1007;
pub const ANARI_INT16: ANARIDataType = 1008;
pub const ANARI_INT16_VEC2: ANARIDataType = 1009;
pub const ANARI_INT16_VEC3: ANARIDataType = 1010;
pub const ANARI_INT16_VEC4: ANARIDataType = 1011;
pub const ANARI_UINT16: ANARIDataType = 1012;
pub const ANARI_UINT16_VEC2: ANARIDataType = 1013;
pub const ANARI_UINT16_VEC3: ANARIDataType = 1014;
pub const ANARI_UINT16_VEC4: ANARIDataType = 1015;
pub const ANARI_INT32: ANARIDataType = 1016;
pub const ANARI_INT32_VEC2: ANARIDataType = 1017;
pub const ANARI_INT32_VEC3: ANARIDataType = 1018;
pub const ANARI_INT32_VEC4: ANARIDataType = 1019;
pub const ANARI_UINT32: ANARIDataType = 1020;
pub const ANARI_UINT32_VEC2: ANARIDataType = 1021;
pub const ANARI_UINT32_VEC3: ANARIDataType = 1022;
pub const ANARI_UINT32_VEC4: ANARIDataType = 1023;
pub const ANARI_INT64: ANARIDataType = 1024;
pub const ANARI_INT64_VEC2: ANARIDataType = 1025;
pub const ANARI_INT64_VEC3: ANARIDataType = 1026;
pub const ANARI_INT64_VEC4: ANARIDataType = 1027;
pub const ANARI_UINT64: ANARIDataType = 1028;
pub const ANARI_UINT64_VEC2: ANARIDataType = 1029;
pub const ANARI_UINT64_VEC3: ANARIDataType = 1030;
pub const ANARI_UINT64_VEC4: ANARIDataType = 1031;
pub const ANARI_FIXED8: ANARIDataType = 1032;
pub const ANARI_FIXED8_VEC2: ANARIDataType = 1033;
pub const ANARI_FIXED8_VEC3: ANARIDataType = 1034;
pub const ANARI_FIXED8_VEC4: ANARIDataType = 1035;
pub const ANARI_UFIXED8: ANARIDataType = 1036;
pub const ANARI_UFIXED8_VEC2: ANARIDataType = 1037;
pub const ANARI_UFIXED8_VEC3: ANARIDataType = 1038;
pub const ANARI_UFIXED8_VEC4: ANARIDataType = 1039;
pub const ANARI_FIXED16: ANARIDataType = 1040;
pub const ANARI_FIXED16_VEC2: ANARIDataType = 1041;
pub const ANARI_FIXED16_VEC3: ANARIDataType = 1042;
pub const ANARI_FIXED16_VEC4: ANARIDataType = 1043;
pub const ANARI_UFIXED16: ANARIDataType = 1044;
pub const ANARI_UFIXED16_VEC2: ANARIDataType = 1045;
pub const ANARI_UFIXED16_VEC3: ANARIDataType = 1046;
pub const ANARI_UFIXED16_VEC4: ANARIDataType = 1047;
pub const ANARI_FIXED32: ANARIDataType = 1048;
pub const ANARI_FIXED32_VEC2: ANARIDataType = 1049;
pub const ANARI_FIXED32_VEC3: ANARIDataType = 1050;
pub const ANARI_FIXED32_VEC4: ANARIDataType = 1051;
pub const ANARI_UFIXED32: ANARIDataType = 1052;
pub const ANARI_UFIXED32_VEC2: ANARIDataType = 1053;
pub const ANARI_UFIXED32_VEC3: ANARIDataType = 1054;
pub const ANARI_UFIXED32_VEC4: ANARIDataType = 1055;
pub const ANARI_FIXED64: ANARIDataType = 1056;
pub const ANARI_FIXED64_VEC2: ANARIDataType = 1057;
pub const ANARI_FIXED64_VEC3: ANARIDataType = 1058;
pub const ANARI_FIXED64_VEC4: ANARIDataType = 1059;
pub const ANARI_UFIXED64: ANARIDataType = 1060;
pub const ANARI_UFIXED64_VEC2: ANARIDataType = 1061;
pub const ANARI_UFIXED64_VEC3: ANARIDataType = 1062;
pub const ANARI_UFIXED64_VEC4: ANARIDataType = 1063;
pub const ANARI_FLOAT16: ANARIDataType = 1064;
pub const ANARI_FLOAT16_VEC2: ANARIDataType = 1065;
pub const ANARI_FLOAT16_VEC3: ANARIDataType = 1066;
pub const ANARI_FLOAT16_VEC4: ANARIDataType = 1067;
pub const ANARI_FLOAT32: ANARIDataType = 1068;
pub const ANARI_FLOAT32_VEC2: ANARIDataType = 1069;
pub const ANARI_FLOAT32_VEC3: ANARIDataType = 1070;
pub const ANARI_FLOAT32_VEC4: ANARIDataType = 1071;
pub const ANARI_FLOAT64: ANARIDataType = 1072;
pub const ANARI_FLOAT64_VEC2: ANARIDataType = 1073;
pub const ANARI_FLOAT64_VEC3: ANARIDataType = 1074;
pub const ANARI_FLOAT64_VEC4: ANARIDataType = 1075;
pub const ANARI_UFIXED8_RGBA_SRGB: ANARIDataType = 2003;
pub const ANARI_UFIXED8_RGB_SRGB: ANARIDataType = 2002;
pub const ANARI_UFIXED8_RA_SRGB: ANARIDataType = 2001;
pub const ANARI_UFIXED8_R_SRGB: ANARIDataType = 2000;
pub const ANARI_INT32_BOX1: ANARIDataType = 2004;
pub const ANARI_INT32_BOX2: ANARIDataType = 2005;
pub const ANARI_INT32_BOX3: ANARIDataType = 2006;
pub const ANARI_INT32_BOX4: ANARIDataType = 2007;
pub const ANARI_FLOAT32_BOX1: ANARIDataType = 2008;
pub const ANARI_FLOAT32_BOX2: ANARIDataType = 2009;
pub const ANARI_FLOAT32_BOX3: ANARIDataType = 2010;
pub const ANARI_FLOAT32_BOX4: ANARIDataType = 2011;
pub const ANARI_FLOAT64_BOX1: ANARIDataType = 2208;
pub const ANARI_FLOAT64_BOX2: ANARIDataType = 2209;
pub const ANARI_FLOAT64_BOX3: ANARIDataType = 2210;
pub const ANARI_FLOAT64_BOX4: ANARIDataType = 2211;
pub const ANARI_UINT64_REGION1: ANARIDataType = 2104;
pub const ANARI_UINT64_REGION2: ANARIDataType = 2105;
pub const ANARI_UINT64_REGION3: ANARIDataType = 2106;
pub const ANARI_UINT64_REGION4: ANARIDataType = 2107;
pub const ANARI_FLOAT32_MAT2: ANARIDataType = 2012;
pub const ANARI_FLOAT32_MAT3: ANARIDataType = 2013;
pub const ANARI_FLOAT32_MAT4: ANARIDataType = 2014;
#[allow(non_upper_case_globals)] // Khronos spelling
pub const ANARI_FLOAT32_MAT2x3: ANARIDataType = 2015;
#[allow(non_upper_case_globals)] // Khronos spelling
pub const ANARI_FLOAT32_MAT3x4: ANARIDataType = 2016;
pub const ANARI_FLOAT32_QUAT_IJKW: ANARIDataType = 2017;

const POINTER_SIZE: usize = std::mem::size_of::<usize>();

/// (value, name, element size in bytes) for every data type of the API.
const TABLE: &[(ANARIDataType, &str, usize)] = &[
    (ANARI_DATA_TYPE, "ANARI_DATA_TYPE", 4),
    (ANARI_STRING, "ANARI_STRING", POINTER_SIZE),
    (ANARI_VOID_POINTER, "ANARI_VOID_POINTER", POINTER_SIZE),
    (ANARI_BOOL, "ANARI_BOOL", 1),
    (ANARI_STRING_LIST, "ANARI_STRING_LIST", POINTER_SIZE),
    (ANARI_DATA_TYPE_LIST, "ANARI_DATA_TYPE_LIST", POINTER_SIZE),
    (ANARI_PARAMETER_LIST, "ANARI_PARAMETER_LIST", POINTER_SIZE),
    (
        ANARI_FUNCTION_POINTER,
        "ANARI_FUNCTION_POINTER",
        POINTER_SIZE,
    ),
    (ANARI_MEMORY_DELETER, "ANARI_MEMORY_DELETER", POINTER_SIZE),
    (ANARI_STATUS_CALLBACK, "ANARI_STATUS_CALLBACK", POINTER_SIZE),
    (
        ANARI_FRAME_COMPLETION_CALLBACK,
        "ANARI_FRAME_COMPLETION_CALLBACK",
        POINTER_SIZE,
    ),
    (ANARI_LIBRARY, "ANARI_LIBRARY", POINTER_SIZE),
    (ANARI_DEVICE, "ANARI_DEVICE", POINTER_SIZE),
    (ANARI_OBJECT, "ANARI_OBJECT", POINTER_SIZE),
    (ANARI_ARRAY, "ANARI_ARRAY", POINTER_SIZE),
    (ANARI_ARRAY1D, "ANARI_ARRAY1D", POINTER_SIZE),
    (ANARI_ARRAY2D, "ANARI_ARRAY2D", POINTER_SIZE),
    (ANARI_ARRAY3D, "ANARI_ARRAY3D", POINTER_SIZE),
    (ANARI_CAMERA, "ANARI_CAMERA", POINTER_SIZE),
    (ANARI_FRAME, "ANARI_FRAME", POINTER_SIZE),
    (ANARI_GEOMETRY, "ANARI_GEOMETRY", POINTER_SIZE),
    (ANARI_GROUP, "ANARI_GROUP", POINTER_SIZE),
    (ANARI_INSTANCE, "ANARI_INSTANCE", POINTER_SIZE),
    (ANARI_LIGHT, "ANARI_LIGHT", POINTER_SIZE),
    (ANARI_MATERIAL, "ANARI_MATERIAL", POINTER_SIZE),
    (ANARI_RENDERER, "ANARI_RENDERER", POINTER_SIZE),
    (ANARI_SURFACE, "ANARI_SURFACE", POINTER_SIZE),
    (ANARI_SAMPLER, "ANARI_SAMPLER", POINTER_SIZE),
    (ANARI_SPATIAL_FIELD, "ANARI_SPATIAL_FIELD", POINTER_SIZE),
    (ANARI_VOLUME, "ANARI_VOLUME", POINTER_SIZE),
    (ANARI_WORLD, "ANARI_WORLD", POINTER_SIZE),
    (ANARI_INT8, "ANARI_INT8", 1),
    (ANARI_INT8_VEC2, "ANARI_INT8_VEC2", 2),
    (ANARI_INT8_VEC3, "ANARI_INT8_VEC3", 3),
    (ANARI_INT8_VEC4, "ANARI_INT8_VEC4", 4),
    (ANARI_UINT8, "ANARI_UINT8", 1),
    (ANARI_UINT8_VEC2, "ANARI_UINT8_VEC2", 2),
    (ANARI_UINT8_VEC3, "ANARI_UINT8_VEC3", 3),
    (ANARI_UINT8_VEC4, "ANARI_UINT8_VEC4", 4),
    (ANARI_INT16, "ANARI_INT16", 2),
    (ANARI_INT16_VEC2, "ANARI_INT16_VEC2", 4),
    (ANARI_INT16_VEC3, "ANARI_INT16_VEC3", 6),
    (ANARI_INT16_VEC4, "ANARI_INT16_VEC4", 8),
    (ANARI_UINT16, "ANARI_UINT16", 2),
    (ANARI_UINT16_VEC2, "ANARI_UINT16_VEC2", 4),
    (ANARI_UINT16_VEC3, "ANARI_UINT16_VEC3", 6),
    (ANARI_UINT16_VEC4, "ANARI_UINT16_VEC4", 8),
    (ANARI_INT32, "ANARI_INT32", 4),
    (ANARI_INT32_VEC2, "ANARI_INT32_VEC2", 8),
    (ANARI_INT32_VEC3, "ANARI_INT32_VEC3", 12),
    (ANARI_INT32_VEC4, "ANARI_INT32_VEC4", 16),
    (ANARI_UINT32, "ANARI_UINT32", 4),
    (ANARI_UINT32_VEC2, "ANARI_UINT32_VEC2", 8),
    (ANARI_UINT32_VEC3, "ANARI_UINT32_VEC3", 12),
    (ANARI_UINT32_VEC4, "ANARI_UINT32_VEC4", 16),
    (ANARI_INT64, "ANARI_INT64", 8),
    (ANARI_INT64_VEC2, "ANARI_INT64_VEC2", 16),
    (ANARI_INT64_VEC3, "ANARI_INT64_VEC3", 24),
    (ANARI_INT64_VEC4, "ANARI_INT64_VEC4", 32),
    (ANARI_UINT64, "ANARI_UINT64", 8),
    (ANARI_UINT64_VEC2, "ANARI_UINT64_VEC2", 16),
    (ANARI_UINT64_VEC3, "ANARI_UINT64_VEC3", 24),
    (ANARI_UINT64_VEC4, "ANARI_UINT64_VEC4", 32),
    (ANARI_FIXED8, "ANARI_FIXED8", 1),
    (ANARI_FIXED8_VEC2, "ANARI_FIXED8_VEC2", 2),
    (ANARI_FIXED8_VEC3, "ANARI_FIXED8_VEC3", 3),
    (ANARI_FIXED8_VEC4, "ANARI_FIXED8_VEC4", 4),
    (ANARI_UFIXED8, "ANARI_UFIXED8", 1),
    (ANARI_UFIXED8_VEC2, "ANARI_UFIXED8_VEC2", 2),
    (ANARI_UFIXED8_VEC3, "ANARI_UFIXED8_VEC3", 3),
    (ANARI_UFIXED8_VEC4, "ANARI_UFIXED8_VEC4", 4),
    (ANARI_FIXED16, "ANARI_FIXED16", 2),
    (ANARI_FIXED16_VEC2, "ANARI_FIXED16_VEC2", 4),
    (ANARI_FIXED16_VEC3, "ANARI_FIXED16_VEC3", 6),
    (ANARI_FIXED16_VEC4, "ANARI_FIXED16_VEC4", 8),
    (ANARI_UFIXED16, "ANARI_UFIXED16", 2),
    (ANARI_UFIXED16_VEC2, "ANARI_UFIXED16_VEC2", 4),
    (ANARI_UFIXED16_VEC3, "ANARI_UFIXED16_VEC3", 6),
    (ANARI_UFIXED16_VEC4, "ANARI_UFIXED16_VEC4", 8),
    (ANARI_FIXED32, "ANARI_FIXED32", 4),
    (ANARI_FIXED32_VEC2, "ANARI_FIXED32_VEC2", 8),
    (ANARI_FIXED32_VEC3, "ANARI_FIXED32_VEC3", 12),
    (ANARI_FIXED32_VEC4, "ANARI_FIXED32_VEC4", 16),
    (ANARI_UFIXED32, "ANARI_UFIXED32", 4),
    (ANARI_UFIXED32_VEC2, "ANARI_UFIXED32_VEC2", 8),
    (ANARI_UFIXED32_VEC3, "ANARI_UFIXED32_VEC3", 12),
    (ANARI_UFIXED32_VEC4, "ANARI_UFIXED32_VEC4", 16),
    (ANARI_FIXED64, "ANARI_FIXED64", 8),
    (ANARI_FIXED64_VEC2, "ANARI_FIXED64_VEC2", 16),
    (ANARI_FIXED64_VEC3, "ANARI_FIXED64_VEC3", 24),
    (ANARI_FIXED64_VEC4, "ANARI_FIXED64_VEC4", 32),
    (ANARI_UFIXED64, "ANARI_UFIXED64", 8),
    (ANARI_UFIXED64_VEC2, "ANARI_UFIXED64_VEC2", 16),
    (ANARI_UFIXED64_VEC3, "ANARI_UFIXED64_VEC3", 24),
    (ANARI_UFIXED64_VEC4, "ANARI_UFIXED64_VEC4", 32),
    (ANARI_FLOAT16, "ANARI_FLOAT16", 2),
    (ANARI_FLOAT16_VEC2, "ANARI_FLOAT16_VEC2", 4),
    (ANARI_FLOAT16_VEC3, "ANARI_FLOAT16_VEC3", 6),
    (ANARI_FLOAT16_VEC4, "ANARI_FLOAT16_VEC4", 8),
    (ANARI_FLOAT32, "ANARI_FLOAT32", 4),
    (ANARI_FLOAT32_VEC2, "ANARI_FLOAT32_VEC2", 8),
    (ANARI_FLOAT32_VEC3, "ANARI_FLOAT32_VEC3", 12),
    (ANARI_FLOAT32_VEC4, "ANARI_FLOAT32_VEC4", 16),
    (ANARI_FLOAT64, "ANARI_FLOAT64", 8),
    (ANARI_FLOAT64_VEC2, "ANARI_FLOAT64_VEC2", 16),
    (ANARI_FLOAT64_VEC3, "ANARI_FLOAT64_VEC3", 24),
    (ANARI_FLOAT64_VEC4, "ANARI_FLOAT64_VEC4", 32),
    (ANARI_UFIXED8_RGBA_SRGB, "ANARI_UFIXED8_RGBA_SRGB", 4),
    (ANARI_UFIXED8_RGB_SRGB, "ANARI_UFIXED8_RGB_SRGB", 3),
    (ANARI_UFIXED8_RA_SRGB, "ANARI_UFIXED8_RA_SRGB", 2),
    (ANARI_UFIXED8_R_SRGB, "ANARI_UFIXED8_R_SRGB", 1),
    (ANARI_INT32_BOX1, "ANARI_INT32_BOX1", 8),
    (ANARI_INT32_BOX2, "ANARI_INT32_BOX2", 16),
    (ANARI_INT32_BOX3, "ANARI_INT32_BOX3", 24),
    (ANARI_INT32_BOX4, "ANARI_INT32_BOX4", 32),
    (ANARI_FLOAT32_BOX1, "ANARI_FLOAT32_BOX1", 8),
    (ANARI_FLOAT32_BOX2, "ANARI_FLOAT32_BOX2", 16),
    (ANARI_FLOAT32_BOX3, "ANARI_FLOAT32_BOX3", 24),
    (ANARI_FLOAT32_BOX4, "ANARI_FLOAT32_BOX4", 32),
    (ANARI_FLOAT64_BOX1, "ANARI_FLOAT64_BOX1", 16),
    (ANARI_FLOAT64_BOX2, "ANARI_FLOAT64_BOX2", 32),
    (ANARI_FLOAT64_BOX3, "ANARI_FLOAT64_BOX3", 48),
    (ANARI_FLOAT64_BOX4, "ANARI_FLOAT64_BOX4", 64),
    (ANARI_UINT64_REGION1, "ANARI_UINT64_REGION1", 16),
    (ANARI_UINT64_REGION2, "ANARI_UINT64_REGION2", 32),
    (ANARI_UINT64_REGION3, "ANARI_UINT64_REGION3", 48),
    (ANARI_UINT64_REGION4, "ANARI_UINT64_REGION4", 64),
    (ANARI_FLOAT32_MAT2, "ANARI_FLOAT32_MAT2", 16),
    (ANARI_FLOAT32_MAT3, "ANARI_FLOAT32_MAT3", 36),
    (ANARI_FLOAT32_MAT4, "ANARI_FLOAT32_MAT4", 64),
    (ANARI_FLOAT32_MAT2x3, "ANARI_FLOAT32_MAT2x3", 24),
    (ANARI_FLOAT32_MAT3x4, "ANARI_FLOAT32_MAT3x4", 48),
    (ANARI_FLOAT32_QUAT_IJKW, "ANARI_FLOAT32_QUAT_IJKW", 16),
];

/// Size in bytes of one element of `data_type`, or `None` for `ANARI_UNKNOWN` and values that
/// are not ANARI data types.
pub fn element_size(data_type: ANARIDataType) -> Option<usize> {
    TABLE
        .iter()
        .find(|(value, _, _)| *value == data_type)
        .map(|(_, _, size)| *size)
}

/// The Khronos name of `data_type` ("ANARI_FLOAT32_VEC3"), or "ANARI_UNKNOWN" for unknown values.
pub fn type_name(data_type: ANARIDataType) -> &'static str {
    TABLE
        .iter()
        .find(|(value, _, _)| *value == data_type)
        .map(|(_, name, _)| *name)
        .unwrap_or("ANARI_UNKNOWN")
}

/// Whether `data_type` is a valid ANARI data type value (ANARI_UNKNOWN excluded).
pub fn is_valid(data_type: ANARIDataType) -> bool {
    element_size(data_type).is_some()
}

/// Whether values of this type are object handles (arrays, geometries, …, but not the library).
pub fn is_object(data_type: ANARIDataType) -> bool {
    (ANARI_DEVICE..=ANARI_WORLD).contains(&data_type)
}

/// Whether values of this type are array handles.
pub fn is_array(data_type: ANARIDataType) -> bool {
    matches!(
        data_type,
        ANARI_ARRAY | ANARI_ARRAY1D | ANARI_ARRAY2D | ANARI_ARRAY3D
    )
}

/// Whether a handle of kind `actual` may be passed where `expected` is declared
/// (`ANARI_OBJECT` accepts any object, `ANARI_ARRAY` any array).
pub fn object_kind_matches(expected: ANARIDataType, actual: ANARIDataType) -> bool {
    expected == actual
        || (expected == ANARI_OBJECT && is_object(actual))
        || (expected == ANARI_ARRAY && is_array(actual))
}

/// Whether elements are plain bytes that can be copied (no handles, strings or pointers).
pub fn is_plain_data(data_type: ANARIDataType) -> bool {
    data_type == ANARI_BOOL || data_type == ANARI_DATA_TYPE || data_type >= ANARI_INT8
}

/// Looks a type up by its Khronos name.
pub fn type_from_name(name: &str) -> Option<ANARIDataType> {
    TABLE
        .iter()
        .find(|(_, n, _)| *n == name)
        .map(|(value, _, _)| *value)
}

/// Number of float components of float vector types (FLOAT32..FLOAT32_VEC4), else None.
pub fn float32_components(data_type: ANARIDataType) -> Option<usize> {
    match data_type {
        ANARI_FLOAT32 => Some(1),
        ANARI_FLOAT32_VEC2 => Some(2),
        ANARI_FLOAT32_VEC3 => Some(3),
        ANARI_FLOAT32_VEC4 => Some(4),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_match_the_c_layouts() {
        assert_eq!(element_size(ANARI_BOOL), Some(1));
        assert_eq!(element_size(ANARI_FLOAT32_VEC3), Some(12));
        assert_eq!(element_size(ANARI_UINT32_VEC3), Some(12));
        assert_eq!(element_size(ANARI_FLOAT32_MAT4), Some(64));
        assert_eq!(element_size(ANARI_FLOAT32_MAT3x4), Some(48));
        assert_eq!(element_size(ANARI_FLOAT32_BOX2), Some(16));
        assert_eq!(element_size(ANARI_FLOAT64_BOX3), Some(48));
        assert_eq!(element_size(ANARI_UINT64_REGION2), Some(32));
        assert_eq!(element_size(ANARI_UFIXED8_RGBA_SRGB), Some(4));
        assert_eq!(element_size(ANARI_UFIXED8_RGB_SRGB), Some(3));
        assert_eq!(element_size(ANARI_FLOAT16_VEC2), Some(4));
        assert_eq!(element_size(ANARI_FIXED64_VEC4), Some(32));
        assert_eq!(element_size(ANARI_GEOMETRY), Some(POINTER_SIZE));
        assert_eq!(element_size(ANARI_STRING), Some(POINTER_SIZE));
        assert_eq!(element_size(ANARI_UNKNOWN), None);
        assert_eq!(element_size(12345), None);
    }

    #[test]
    fn names_round_trip() {
        assert_eq!(type_name(ANARI_FLOAT32_MAT4), "ANARI_FLOAT32_MAT4");
        assert_eq!(type_from_name("ANARI_UINT32_VEC2"), Some(ANARI_UINT32_VEC2));
        assert_eq!(type_name(-7), "ANARI_UNKNOWN");
        assert!(TABLE.len() >= 132);
    }

    #[test]
    fn object_kinds() {
        assert!(is_object(ANARI_WORLD) && is_object(ANARI_ARRAY1D));
        assert!(!is_object(ANARI_LIBRARY) && !is_object(ANARI_FLOAT32));
        assert!(object_kind_matches(ANARI_ARRAY, ANARI_ARRAY2D));
        assert!(object_kind_matches(ANARI_OBJECT, ANARI_CAMERA));
        assert!(!object_kind_matches(ANARI_ARRAY1D, ANARI_ARRAY2D));
    }
}
